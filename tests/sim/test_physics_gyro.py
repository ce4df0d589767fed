"""Fibre-optic gyro model: quantisation with carry, IEEE 952 rate model, noise statistics,
determinism, manufacturing spread, power gating and parameter validation."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad

from sim.physics.gyro import (
    LIMITS,
    NAVIGATION,
    STATUS_BOOTING,
    STATUS_OVER_RANGE,
    STATUS_READY,
    STATUS_TEMPERATURE,
    STATUS_WARMING_UP,
    TACTICAL,
    FiberOpticGyro,
    GyroParams,
    adev_model_dph,
    draw_gyro,
    indicated_rate_dps,
    out_of_limits,
)
from sim.physics.gyro_noise import KnotBias

QUIET = dict(arw_deg_per_rh=0.0, bias_instability_dph=0.0, rrw_dph_per_rh=0.0, warmup_amplitude_dph=0.0,
             bias_tc_dph_per_c=0.0, g_sensitivity_dph_per_g=(0.0, 0.0, 0.0), bias_repeatability_dph=0.0,
             boot_time_s=0.0)


def quiet(**overrides) -> GyroParams:
    """A noiseless unit: only the static rate model and the constant bias act."""
    return TACTICAL.replace(**{**QUIET, **overrides})


def unit(params=TACTICAL, seed=1, t_on=0.0, volts=12.0):
    g = FiberOpticGyro(params, np.random.default_rng(seed))
    g.set_supply(t_on, volts)
    return g


def rows(values, n=None):
    """(n, 3) rows: a (3,) vector repeated, or per-interval IA values."""
    v = np.asarray(values, dtype=float)
    if v.ndim == 1 and n is not None and v.size == 3:
        return np.tile(v, (n, 1))
    out = np.zeros((v.size, 3))
    out[:, 0] = v
    return out


def run(g, edges, omega_ia=0.0, f=(0.0, 0.0, 1.0), vib=0.0):
    n = edges.size - 1
    om = rows(np.broadcast_to(omega_ia, (n,)))
    return g.pulses(edges, om, rows(f, n), vib)


def true_pulses(p, edges, omega_ia):
    """Integrated angle (pulses) of a noiseless unit: static model + constant bias."""
    rate = indicated_rate_dps(p, omega_ia) + p.bias_dph / 3600.0
    return rate * np.diff(edges) * 3600.0 * p.scale_factor_pulses_per_arcsec


def oadev(angle, tau0, m):
    """Overlapping Allan deviation of the rate whose integral is ``angle`` (samples every tau0)."""
    tau = m * tau0
    d = angle[2 * m:] - 2.0 * angle[m:-m] + angle[:-2 * m]
    return math.sqrt(np.mean(d * d) / (2.0 * tau * tau))


# ---- quantisation with carry ----------------------------------------------------------------
@settings(max_examples=60, deadline=None)
@given(data=st.data(), n=st.integers(1, 200), sf=st.floats(0.5, 100.0))
def test_carry_conserves_the_integrated_angle_at_every_prefix_across_calls(data, n, sf):
    p = quiet(scale_factor_pulses_per_arcsec=sf)
    dt = np.array(data.draw(st.lists(st.floats(1e-4, 0.2), min_size=n, max_size=n)))
    edges = np.concatenate(([0.0], np.cumsum(dt)))
    rates = np.array(data.draw(st.lists(st.floats(-600.0, 600.0), min_size=n, max_size=n)))
    cuts = sorted(set(data.draw(st.lists(st.integers(0, n), max_size=4))) | {0, n})
    g = unit(p)
    counts = np.concatenate([run(g, edges[a:b + 1], rates[a:b]) for a, b in zip(cuts[:-1], cuts[1:])])
    expected = np.cumsum(true_pulses(p, edges, rates))
    # the accumulator starts at half a pulse: every prefix sum is the rounded true angle
    assert np.all(np.abs(np.cumsum(counts) - expected) <= 0.5 + 1e-6)
    assert counts.dtype == np.int64


def test_large_spans_are_quantised_without_overflow():
    p = quiet(scale_factor_pulses_per_arcsec=1000.0)
    edges = np.arange(0.0, 200_001.0, 100.0)  # 100 s intervals at full scale: 1.8e11 pulses each
    counts = run(unit(p), edges, 490.0)
    assert abs(counts.sum() - true_pulses(p, edges, np.full(edges.size - 1, 490.0)).sum()) <= 1.0


# ---- the rate model -------------------------------------------------------------------------
@pytest.mark.parametrize("omega", [-300.0, -1.0, 0.0, 0.37, 45.0, 489.0])
def test_noiseless_unit_at_constant_rate_gives_the_model_rate(omega):
    p = quiet()
    edges = np.arange(0, 20_001) * 5e-4  # 10 s at 2 kHz
    counts = run(unit(p), edges, omega)
    model_dps = float(indicated_rate_dps(p, omega)) + p.bias_dph / 3600.0
    k = 3600.0 * p.scale_factor_pulses_per_arcsec
    assert counts.sum() == pytest.approx(model_dps * 10.0 * k, abs=1.0)
    per_interval = model_dps * 5e-4 * k
    assert set(np.unique(counts)) <= {math.floor(per_interval), math.ceil(per_interval)}


def test_misalignment_g_sensitivity_and_clipping_enter_as_specified():
    p = quiet(misalignment_rad=(2e-3, -1e-3), g_sensitivity_dph_per_g=(3.0, -2.0, 5.0))
    g = unit(p)
    edges = np.arange(0, 10_001) * 1e-3
    omega = rows([100.0, 50.0, 20.0], 10_000)
    force = rows([0.5, -0.2, 0.9], 10_000)
    k = 3600.0 * p.scale_factor_pulses_per_arcsec * 10.0
    w_ia = 100.0 + 2e-3 * 50.0 - 1e-3 * 20.0
    gsens = (3.0 * 0.5 + 2.0 * 0.2 + 5.0 * 0.9) / 3600.0
    assert g.pulses(edges, omega, force).sum() == pytest.approx(
        (float(indicated_rate_dps(p, w_ia)) + p.bias_dph / 3600.0 + gsens) * k, abs=1.0)
    over = g.pulses(edges + 10.0, rows([800.0, 0.0, 0.0], 10_000), force)  # beyond FS: saturates
    assert over.sum() == pytest.approx((float(indicated_rate_dps(p, 490.0)) + p.bias_dph / 3600 + gsens) * k,
                                       abs=1.0)
    assert g.status(20.0) & STATUS_OVER_RANGE
    g.pulses(np.array([20.0, 20.001]), rows([10.0, 0, 0], 1), force[:1])
    assert not g.status(20.001) & STATUS_OVER_RANGE


@settings(max_examples=30, deadline=None)
@given(eps=st.floats(-1e3, 1e3), asym=st.floats(-500.0, 500.0), omega=st.floats(0.01, 490.0))
def test_asymmetry_is_the_difference_of_the_positive_and_negative_scale_factors(eps, asym, omega):
    p = quiet(scale_factor_error_ppm=eps, asymmetry_ppm=asym, nonlinearity_ppm=0.0)
    sf_pos = indicated_rate_dps(p, omega) / omega
    sf_neg = indicated_rate_dps(p, -omega) / -omega
    assert (sf_pos - sf_neg) * 1e6 == pytest.approx(asym, abs=1e-6)
    assert ((sf_pos + sf_neg) / 2 - 1) * 1e6 == pytest.approx(eps, abs=1e-6)


@settings(max_examples=30, deadline=None)
@given(nl=st.floats(-1e3, 1e3).filter(lambda v: abs(v) > 1.0), x=st.floats(0.05, 0.5))
def test_nonlinearity_is_an_odd_cubic_in_units_of_full_scale(nl, x):
    p = quiet(scale_factor_error_ppm=0.0, asymmetry_ppm=0.0, nonlinearity_ppm=nl)
    fs = p.full_scale_dps
    dev = lambda w: float(indicated_rate_dps(p, w)) - w
    assert dev(fs) == pytest.approx(nl * 1e-6 * fs, rel=1e-9)
    assert dev(2 * x * fs) == pytest.approx(8 * dev(x * fs), rel=1e-6)
    assert dev(-x * fs) == pytest.approx(-dev(x * fs), rel=1e-9)


def test_rate_table_like_run_through_pulses_shows_the_asymmetry_and_the_cubic():
    p = quiet(scale_factor_error_ppm=0.0, asymmetry_ppm=200.0, nonlinearity_ppm=300.0)
    g = unit(p)
    t0, span, k = 0.0, 100.0, 3600.0 * p.scale_factor_pulses_per_arcsec
    m = {}
    for w in (-100.0, 100.0, 400.0):
        m[w] = run(g, t0 + np.linspace(0.0, span, 1001), w).sum() / (k * span) - p.bias_dph / 3600
        t0 += span
    # SF(ω) = out(ω)/ω: the cubic is even in SF, so SF+ − SF− is the asymmetry alone
    assert (m[100.0] / 100.0 - m[-100.0] / -100.0) * 1e6 == pytest.approx(200.0, abs=0.01)
    # out(4ω) − 4·out(ω) cancels the linear terms and leaves n·FS·(x₄³ − 4x₁³)
    x1, x4 = 100.0 / 490.0, 400.0 / 490.0
    assert m[400.0] - 4 * m[100.0] == pytest.approx(300e-6 * 490.0 * (x4**3 - 4 * x1**3), rel=1e-4)


# ---- deterministic start-up terms -------------------------------------------------------------
def test_warm_up_and_temperature_bias_are_integrated_exactly():
    p = quiet(bias_dph=0.0, warmup_amplitude_dph=36.0, warmup_tau_s=50.0, bias_tc_dph_per_c=9.0,
              self_heating_delta_c=5.0, thermal_tau_s=200.0, scale_factor_pulses_per_arcsec=100.0)
    g = unit(p, t_on=3.0)
    edges = 3.0 + np.arange(0, 400_001) * 1e-3  # 400 s
    counts = run(g, edges, 0.0)
    span = 400.0
    k = 3600.0 * p.scale_factor_pulses_per_arcsec
    warm_deg = 36.0 / 3600 * 50.0 * (1 - math.exp(-span / 50.0))
    # the coil of the two-node model (sim/physics/thermal_unit.py), integrated independently
    rise_c_s, _ = quad(lambda t: g.body_temperature_c(t) - 23.0, 3.0, 403.0, epsabs=1e-10, limit=200)
    temp_deg = 9.0 / 3600 * rise_c_s
    assert counts.sum() == pytest.approx((warm_deg + temp_deg) * k, abs=1.0)
    # the case (where the frame's sensor sits) warms with the unit's dominant 200-s mode
    assert g.case_temperature_c(403.0) == pytest.approx(23.0 + 5.0 * (1 - math.exp(-2.0)), abs=0.3)


# ---- noise statistics -----------------------------------------------------------------------
def test_arw_angle_increments_have_sigma_n_sqrt_dt_and_are_white():
    # a fine pulse (1000/″) makes quantisation negligible next to N·√dt
    p = quiet(bias_dph=0.0, arw_deg_per_rh=0.05, scale_factor_pulses_per_arcsec=1000.0)
    rng = np.random.default_rng(5)
    dt = rng.choice([2e-4, 5e-4, 1e-3, 4e-3], size=200_000)
    edges = np.concatenate(([0.0], np.cumsum(dt)))
    angle_deg = run(unit(p, seed=3), edges, 0.0) / (3600.0 * 1000.0)
    z = angle_deg / (0.05 / 60.0 * np.sqrt(dt))
    assert z.std() == pytest.approx(1.0, abs=0.01)  # SE 0.0016
    assert abs(z.mean()) < 0.01
    assert abs(np.corrcoef(z[:-1], z[1:])[0, 1]) < 0.01  # 4.5 standard errors


def test_rate_random_walk_allan_slope_and_level():
    p = quiet(bias_dph=0.0, rrw_dph_per_rh=2.0, scale_factor_pulses_per_arcsec=100.0)
    edges = np.arange(0.0, 400_001.0, 1.0)
    angle = np.concatenate(([0.0], np.cumsum(run(unit(p, seed=11), edges, 0.0)))) / 360_000.0
    taus = np.array([300.0, 1000.0, 3000.0])
    adev = np.array([oadev(angle, 1.0, int(t)) for t in taus]) * 3600.0
    slope = np.polyfit(np.log(taus), np.log(adev), 1)[0]
    assert slope == pytest.approx(0.5, abs=0.12)
    assert np.all(np.abs(adev / adev_model_dph(p, taus) - 1.0) < 0.2)


def test_bias_instability_gives_a_flat_allan_floor_at_0p664_b():
    p = quiet(bias_dph=0.0, bias_instability_dph=1.0, flicker_tau_min_s=10.0, flicker_tau_max_s=1e4,
              scale_factor_pulses_per_arcsec=100.0)
    edges = np.arange(0.0, 200_001.0, 1.0)
    taus = np.array([30.0, 100.0, 300.0, 1000.0])
    ratios = []
    for seed in (21, 22, 23):
        angle = np.concatenate(([0.0], np.cumsum(run(unit(p, seed=seed), edges, 0.0)))) / 360_000.0
        adev = np.array([oadev(angle, 1.0, int(t)) for t in taus]) * 3600.0
        assert abs(np.polyfit(np.log(taus), np.log(adev), 1)[0]) < 0.12  # flat
        ratios.append(adev / adev_model_dph(p, taus))
    assert np.all(np.abs(np.mean(ratios, axis=0) - 1.0) < 0.1)
    assert np.allclose(adev_model_dph(p, taus), 0.664, rtol=0.06)


def test_vibration_rectification_resonance_and_noise_scale_with_level():
    base = quiet(bias_dph=0.0, scale_factor_pulses_per_arcsec=1000.0)
    k = 3600.0 * 1000.0
    edges = np.arange(0, 200_001) * 5e-4  # 100 s at 2 kHz
    rect = base.replace(vib_resonance_dps_per_grms=(0, 0, 0), vib_noise_dps_per_grms=(0, 0, 0),
                        vib_rectification_dph_per_g2=(0.5, 2.0, 0.0))
    assert run(unit(rect), edges, 0.0, vib=4.0).sum() / (k * 100.0) * 3600 == pytest.approx(0.5 * 16, rel=1e-4)
    per_axis = np.tile([0.0, 3.0, 0.0], (edges.size - 1, 1))
    shifted_dph = run(unit(rect), edges, 0.0, vib=per_axis).sum() / (k * 100.0) * 3600
    assert shifted_dph == pytest.approx(2.0 * 9, rel=1e-4)

    res = base.replace(vib_rectification_dph_per_g2=(0, 0, 0), vib_noise_dps_per_grms=(0, 0, 0),
                       vib_resonance_hz=317.0, vib_resonance_dps_per_grms=(0.01, 0, 0))
    rate = run(unit(res), edges, 0.0, vib=3.0) / (k * 5e-4)
    spectrum = np.abs(np.fft.rfft(rate)) * 2 / rate.size
    freq = np.fft.rfftfreq(rate.size, 5e-4)
    peak = int(np.argmax(spectrum))
    assert freq[peak] == pytest.approx(317.0, abs=0.02)
    sinc = math.sin(math.pi * 317 * 5e-4) / (math.pi * 317 * 5e-4)  # interval averaging
    assert spectrum[peak] == pytest.approx(0.03 * sinc, rel=0.02)

    noisy = base.replace(vib_rectification_dph_per_g2=(0, 0, 0), vib_resonance_dps_per_grms=(0, 0, 0))
    stds = [np.std(run(unit(noisy, seed=4), edges, 0.0, vib=v) / (k * 5e-4)) for v in (1.0, 4.0)]
    assert stds[0] == pytest.approx(0.003, rel=0.05)
    assert stds[1] / stds[0] == pytest.approx(4.0, rel=0.05)


def test_knot_process_is_stationary_gauss_markov_across_steps_and_gaps():
    # one term σ = 2, τ = 10 s: corr over Δ is exp(−Δ/τ), also across a skipped gap
    before, after_step, after_gap = [], [], []
    for seed in range(1500):
        kb = KnotBias([2.0], [10.0], 0.0, 0.5, np.random.default_rng(seed))
        before.append(kb.values(np.array([3.0]))[0])  # on a knot: no interpolation
        after_step.append(kb.values(np.array([8.0]))[0])
        after_gap.append(kb.values(np.array([18.0]), contiguous=False)[0])
    before, after_step, after_gap = map(np.array, (before, after_step, after_gap))
    for x in (before, after_step, after_gap):
        assert x.std() == pytest.approx(2.0, rel=0.06)
    assert np.corrcoef(before, after_step)[0, 1] == pytest.approx(math.exp(-0.5), abs=0.05)
    assert np.corrcoef(after_step, after_gap)[0, 1] == pytest.approx(math.exp(-1.0), abs=0.05)


def test_frame_line_pattern_coarse_steps_then_frames():
    # the serial line steps an idle gyro in 1 s intervals, then streams 2 kHz frames
    p = quiet(arw_deg_per_rh=0.05, bias_instability_dph=0.5)
    g = unit(p)
    run(g, np.arange(0.0, 11.0, 1.0), 0.0)
    edges = 10.0 + np.arange(0, 40_001) * 5e-4
    counts = run(g, edges, 20.0, vib=1.0)
    rate = counts.sum() / (3600.0 * p.scale_factor_pulses_per_arcsec * 20.0)
    # ARW over 20 s: 0.05/60/√20 = 1.9e-4 °/s; flicker and vibration noise smaller
    assert rate == pytest.approx(float(indicated_rate_dps(p, 20.0)) + p.bias_dph / 3600.0, abs=1e-3)


# ---- determinism ------------------------------------------------------------------------------
def noisy_run(seed, cuts, edges, vib=2.0):
    g = unit(TACTICAL, seed=seed)
    n = edges.size - 1
    om, f = rows(np.linspace(-5, 5, n)), rows([0.0, 0.0, 1.0], n)
    return np.concatenate([g.pulses(edges[a:b + 1], om[a:b], f[a:b], vib) for a, b in zip(cuts[:-1], cuts[1:])])


@settings(max_examples=15, deadline=None)
@given(cuts=st.lists(st.integers(1, 59_999), max_size=5))
def test_split_calls_on_a_uniform_grid_give_identical_pulses_noise_included(cuts):
    edges = np.arange(60_001) * 5e-4
    points = sorted(set(cuts) | {0, 60_000})
    assert np.array_equal(noisy_run(8, points, edges), noisy_run(8, [0, 60_000], edges))


@settings(max_examples=15, deadline=None)
@given(cuts=st.lists(st.integers(1, 19_999), max_size=5), seed=st.integers(0, 2**32 - 1))
def test_split_calls_on_any_grid_give_identical_pulses_without_vibration(cuts, seed):
    edges = np.concatenate(([0.0], np.cumsum(np.random.default_rng(seed).uniform(1e-4, 2e-3, 20_000))))
    points = sorted(set(cuts) | {0, 20_000})
    assert np.array_equal(noisy_run(9, points, edges, vib=0.0), noisy_run(9, [0, 20_000], edges, vib=0.0))


def test_same_seed_same_pulses_different_seed_different_pulses():
    edges = np.arange(20_001) * 5e-4
    a, b, c = (noisy_run(s, [0, 20_000], edges) for s in (5, 5, 6))
    assert np.array_equal(a, b) and not np.array_equal(a, c)


# ---- manufacturing spread -----------------------------------------------------------------------
def test_draw_gyro_is_a_function_of_the_serial():
    assert draw_gyro("FOG-0001") == draw_gyro("FOG-0001")
    assert draw_gyro("FOG-0001") != draw_gyro("FOG-0002")
    assert draw_gyro("FOG-0001", "navigation") != draw_gyro("FOG-0001")
    assert draw_gyro("FOG-0001", "navigation").full_scale_dps == NAVIGATION.full_scale_dps


@pytest.mark.parametrize("grade", ["tactical", "navigation"])
def test_between_5_and_15_percent_of_units_fall_outside_the_datasheet_limits(grade):
    units = [draw_gyro(f"SN{i:06d}", grade) for i in range(2000)]
    failing = [u for u in units if out_of_limits(u, grade)]
    assert 0.05 <= len(failing) / len(units) <= 0.15
    assert out_of_limits(TACTICAL if grade == "tactical" else NAVIGATION, grade) == ()
    assert set(LIMITS[grade]) >= {name for u in failing for name in out_of_limits(u, grade)}


def test_draw_gyro_rejects_bad_serials_and_grades():
    with pytest.raises(ValueError, match="grade='strategic'"):
        draw_gyro("SN1", "strategic")
    with pytest.raises(ValueError, match="serial=''"):
        draw_gyro("")


# ---- power gating and boot -------------------------------------------------------------------
def test_unpowered_and_booting_units_output_nothing_and_a_power_cycle_reboots():
    p = TACTICAL.replace(boot_time_s=1.0)
    g = FiberOpticGyro(p, np.random.default_rng(0))
    edges = np.arange(0, 2001) * 5e-3  # 10 s
    assert not run(g, edges[:401], 10.0).any()  # never powered
    assert g.status(2.0) == 0 and not g.powered(2.0)
    g.set_supply(2.0, 40.0)  # above the range: still off
    assert not g.powered(2.0)
    g.set_supply(2.0, 12.0)
    assert g.status(2.0) == STATUS_BOOTING and g.powered(2.0) and not g.ready(2.5)
    counts = run(g, edges[400:], 10.0)
    assert not counts[:200].any() and counts[200:].all()  # ready at 3.0 s exactly
    assert g.status(3.0) == STATUS_READY | STATUS_WARMING_UP
    assert g.ready(np.array([2.9, 3.0])).tolist() == [False, True]
    g.set_supply(10.0, 0.0)
    edges2 = 10.0 + np.arange(0, 401) * 5e-3
    assert not run(g, edges2, 10.0).any() and g.status(11.0) == 0
    assert g.supply_current_a(11.0) == 0.0
    g.set_supply(12.0, 12.0)
    edges3 = 12.0 + np.arange(0, 401) * 5e-3
    counts3 = run(g, edges3, 10.0)
    assert not counts3[:200].any() and counts3[200:].all()
    assert g.truth()["power_on_time_s"] == 12.0
    with pytest.raises(ValueError, match="last processed interval edge"):
        g.set_supply(13.0, 0.0)


def test_a_supply_change_inside_a_call_zeroes_the_interval_it_cuts():
    g = unit(quiet(), t_on=0.0)
    g.pulses(np.array([0.0, 1.0]), rows([10.0]), rows([0, 0, 1.0], 1))
    g.set_supply(1.25, 0.0)  # between the next edges
    counts = g.pulses(np.array([1.0, 1.5, 2.0]), rows([10.0, 10.0]), rows([0, 0, 1.0], 2))
    assert counts.tolist() == [0, 0]


def test_temperature_sensor_reads_the_case_plus_its_offset_and_flags_the_range():
    p = TACTICAL.replace(temp_sensor_offset_c=0.7, ambient_c=70.0, self_heating_delta_c=6.0)
    g = unit(p)
    t = np.array([0.0, 900.0, 5000.0])
    assert np.allclose(g.temperature_c(t) - g.case_temperature_c(t), 0.7)
    assert not g.status(0.0) & STATUS_TEMPERATURE
    assert g.status(5000.0) & STATUS_TEMPERATURE  # coil above 71 °C


# ---- validation -----------------------------------------------------------------------------
@pytest.mark.parametrize("field, value", [
    ("scale_factor_pulses_per_arcsec", 0.0), ("full_scale_dps", -1.0), ("arw_deg_per_rh", -0.1),
    ("bias_instability_dph", math.nan), ("boot_time_s", 1e4), ("supply_max_v", 100.0),
    ("vib_noise_tau_s", 0.0), ("bias_dph", True),
])
def test_bad_parameters_raise_naming_the_value_and_range(field, value):
    with pytest.raises(ValueError, match=rf"{field}={value!r} outside the allowed range \["):
        TACTICAL.replace(**{field: value})


@pytest.mark.parametrize("changes, pattern", [
    (dict(misalignment_rad=(0.0, 0.0, 0.0)), r"misalignment_rad=.* must be 2 numbers in \[-0.05, 0.05\]"),
    (dict(g_sensitivity_dph_per_g=(0.0, 1e3, 0.0)), r"g_sensitivity_dph_per_g=.* must be 3 numbers"),
    (dict(supply_min_v=40.0, supply_max_v=20.0), r"supply_min_v=40.0 must be < supply_max_v=20.0"),
    (dict(flicker_tau_min_s=5.0, flicker_tau_max_s=10.0), r"flicker_tau_max_s/flicker_tau_min_s=2.0 outside"),
    (dict(colour="red"), r"unknown GyroParams fields \['colour'\]"),
])
def test_inconsistent_parameters_raise(changes, pattern):
    with pytest.raises(ValueError, match=pattern):
        TACTICAL.replace(**changes)


def test_bad_pulse_inputs_raise():
    g = unit()
    with pytest.raises(ValueError, match="strictly increasing"):
        g.pulses(np.array([0.0, 1.0, 1.0]), np.zeros((2, 3)), np.zeros((2, 3)))
    with pytest.raises(ValueError, match=r"omega_sensor_dps must have shape \(2, 3\)"):
        g.pulses(np.array([0.0, 1.0, 2.0]), np.zeros((2, 2)), np.zeros((2, 3)))
    with pytest.raises(ValueError, match="vibration_g_rms must be finite and ≥ 0"):
        g.pulses(np.array([0.0, 1.0]), np.zeros((1, 3)), np.zeros((1, 3)), -1.0)
    g.pulses(np.array([0.0, 1.0]), np.zeros((1, 3)), np.zeros((1, 3)))
    with pytest.raises(ValueError, match="precedes the previous call's last edge"):
        g.pulses(np.array([0.5, 2.0]), np.zeros((1, 3)), np.zeros((1, 3)))
