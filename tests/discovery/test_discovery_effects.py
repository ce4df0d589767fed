"""The effect catalogue (issue 7): identity, signatures, draws, detectability, determinism."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import signal

from bench.discovery import significance as sig
from bench.discovery.data import Record
from bench.discovery.effects import CATALOGUE
from bench.discovery.effects_base import DRAW_SNR_FACTOR, KINDS, MIN_SNR
from bench.discovery.effects_terms import MAX_LINES
from bench.discovery.effects_transforms import expected_quantized
from bench.discovery.experiments import make_experiment
from bench.discovery.fitting import CandidateFitter
from bench.discovery.model import BaseModel, Model

ISSUE_IDS = ["warmup_exponential", "linear_drift", "temperature_bias", "temperature_scale_factor",
             "k2_nonlinearity", "k3_nonlinearity", "scale_factor_asymmetry", "misalignment", "g_sensitivity",
             "quantization", "dead_zone", "saturation", "sinusoidal_interference", "gauss_markov",
             "rate_random_walk", "time_delay", "lowpass_bandwidth", "highpass_rolloff", "vibration_rectification",
             "flicker_noise", "bias_jump", "angle_quantization", "thermal_two_node", "temperature_rate",
             "thermal_hysteresis", "thermal_lag"]
NOISE = {"accelerometer": 5e-6, "gyro": 3e-3, "mhd": 0.06}
# Short experiments keep the suite fast; every applicable effect must still be drawable on them.
SHORT = {"accelerometer": (3600, 1.0), "gyro": (6000, 10.0), "mhd": (20000, 500.0)}


@pytest.fixture(scope="module")
def records():
    return {k: make_experiment(k, np.random.default_rng(3), n=SHORT[k][0], rate_hz=SHORT[k][1]) for k in KINDS}


#: Applicable but not drawable on the short experiments: on the accelerometer's 1-Hz tumble a
#: sub-sample delay is a first-order low-pass exactly (what tells them apart is below 1e-6 σ for
#: every delay in range), so no delay is distinguishable from its look-alike there.
UNDRAWABLE = {("accelerometer", "time_delay")}


def _pairs():
    return [(k, e.id) for k in KINDS for e in CATALOGUE.for_kind(k) if (k, e.id) not in UNDRAWABLE]


def test_a_delay_on_the_accelerometers_1_hz_record_is_its_low_pass_look_alike(records):
    rec, d = records["accelerometer"], CATALOGUE["time_delay"]
    for delay in (1e-3, 0.1, 1.0):
        p = {"delay_s": delay}
        assert d.plain_snr(p, rec, NOISE["accelerometer"]) > 100  # a large effect ...
        assert d.snr(p, rec, NOISE["accelerometer"]) < 1e-3  # ... all of it a low-pass's
    with pytest.raises(ValueError, match="no delay_s inside .* is detectable on this record"):
        d.draw(np.random.default_rng(5), rec, kind="accelerometer", noise_sd=NOISE["accelerometer"])
    # on the gyro's 10-Hz record a delay is drawn, distinguishable from the low-pass
    g = records["gyro"]
    p = d.draw(np.random.default_rng(5), g, kind="gyro", noise_sd=NOISE["gyro"])
    assert d.snr(p, g, NOISE["gyro"]) >= DRAW_SNR_FACTOR * MIN_SNR * 0.98


def test_catalogue_has_the_issue_ids_in_order_and_complete_metadata():
    assert list(CATALOGUE) == ISSUE_IDS
    for e in CATALOGUE.values():
        assert e.description and e.form and e.signature
        assert e.main_param in e.param_names
        assert set(e.kinds) <= set(KINDS) and e.kinds
        assert set(e.inputs) <= {"t", "input", "cross_input", "temp", "t_on", "vib", "accel"}
        for kind in e.kinds:
            assert [q.name for q in e.params_for(kind)] == list(e.param_names)
            for q in e.params_for(kind):
                assert q.low < q.high and q.floor >= 0 and (q.low > 0 or not q.log)
    with pytest.raises(ValueError, match="unknown effect id 'nope'"):
        CATALOGUE.effect("nope")
    with pytest.raises(ValueError, match="does not apply to kind 'mhd'"):
        CATALOGUE["g_sensitivity"].params_for("mhd")


@pytest.mark.parametrize("kind,eid", _pairs())
def test_main_parameter_at_identity_leaves_output_unchanged(records, kind, eid):
    e, rec = CATALOGUE[eid], records[kind]
    p = e.draw(np.random.default_rng(1), rec, kind=kind, noise_sd=NOISE[kind])
    p = e.identity_params(p)
    assert p[e.main_param] == e.identity
    y0 = rec.input * 1.001 + 0.01
    out = e.apply(p, rec, y0, rng=np.random.default_rng(0))
    np.testing.assert_array_equal(out, y0)


@pytest.mark.parametrize("kind,eid", _pairs())
def test_draw_is_in_range_detectable_and_deterministic(records, kind, eid):
    e, rec, sd = CATALOGUE[eid], records[kind], NOISE[kind]
    p = e.draw(np.random.default_rng(5), rec, kind=kind, noise_sd=sd)
    assert e.check_params(p, kind) == p  # every parameter inside the kind's physical range
    assert p == e.draw(np.random.default_rng(5), rec, kind=kind, noise_sd=sd)
    assert e.snr(p, rec, sd) >= DRAW_SNR_FACTOR * MIN_SNR * 0.98
    if eid == "saturation":
        return  # drawn by clip depth; its snr is checked above
    m = e.min_effect(rec, sd, kind=kind, params=p)
    if e.increasing:
        assert abs(p[e.main_param]) >= m
    else:
        assert p[e.main_param] <= m


@pytest.mark.parametrize("eid", ["linear_drift", "k2_nonlinearity", "misalignment", "warmup_exponential"])
def test_min_effect_is_where_the_snr_reaches_the_threshold(records, eid):
    e, rec = CATALOGUE[eid], records["accelerometer"]
    m = e.min_effect(rec, 5e-6, kind="accelerometer")
    p = e.reference_params(rec, "accelerometer") | {e.main_param: m}
    assert e.snr(p, rec, 5e-6) == pytest.approx(MIN_SNR, rel=2e-3)
    assert e.min_effect(rec, 5e-5, kind="accelerometer") == pytest.approx(10 * m, rel=2e-3)  # linear in noise


def test_stochastic_effects_need_a_generator_and_repeat_with_the_seed(records):
    rec = records["gyro"]
    for eid in ("gauss_markov", "rate_random_walk"):
        e = CATALOGUE[eid]
        p = e.draw(np.random.default_rng(2), rec, kind="gyro", noise_sd=3e-3)
        with pytest.raises(ValueError, match="needs rng"):
            e.apply(p, rec, rec.input)
        a = e.apply(p, rec, rec.input, rng=np.random.default_rng(9))
        b = e.apply(p, rec, rec.input, rng=np.random.default_rng(9))
        np.testing.assert_array_equal(a, b)
        assert not np.array_equal(a, e.apply(p, rec, rec.input, rng=np.random.default_rng(10)))


def _rec(n=2000, rate=10.0, **cols):
    t = np.arange(n) / rate
    return Record(t_s=t, y=np.zeros(n), **cols)


def test_warmup_decays_with_time_since_power_on():
    rec = _rec(t_on_s=np.arange(2000) / 10.0)
    d = CATALOGUE["warmup_exponential"].apply({"amplitude": 3e-4, "tau_s": 20.0}, rec, np.zeros(2000))
    assert d[0] == pytest.approx(3e-4)
    assert np.all(np.diff(d) < 0) and d[1000] == pytest.approx(3e-4 * math.exp(-5.0))


def test_linear_drift_temperature_and_input_terms_have_their_shapes():
    rng = np.random.default_rng(4)
    u = rng.uniform(-1, 1, 2000)
    temp = 25 + 10 * np.sin(np.arange(2000) / 300.0)
    rec = _rec(input=u, temp_c=temp, cross_input=rng.uniform(-1, 1, 2000), vib_grms=rng.uniform(0, 3, 2000),
               accel_g=rng.uniform(-1, 1, 2000))
    y0 = np.zeros(2000)
    d = CATALOGUE["linear_drift"].apply({"slope_per_s": 2e-6}, rec, y0)
    assert np.polyfit(rec.t_s, d, 1)[0] == pytest.approx(2e-6)
    d = CATALOGUE["temperature_bias"].apply({"coef_per_c": -1e-5, "coef_per_c2": 0.0}, rec, y0)
    assert np.corrcoef(d, temp)[0, 1] == pytest.approx(-1.0)
    d = CATALOGUE["temperature_scale_factor"].apply({"sf_coef_per_c": 1e-4}, rec, y0)
    np.testing.assert_allclose(d, 1e-4 * (temp - 25.0) * u)
    sym = _rec(input=np.concatenate([u[:1000], -u[:1000]]))
    d2 = CATALOGUE["k2_nonlinearity"].apply({"k2_per_u": 1e-5}, sym, y0)
    d3 = CATALOGUE["k3_nonlinearity"].apply({"k3_per_u2": 1e-5}, sym, y0)
    da = CATALOGUE["scale_factor_asymmetry"].apply({"asymmetry": 1e-4}, sym, y0)
    np.testing.assert_allclose(d2[:1000], d2[1000:])  # even in the input
    np.testing.assert_allclose(d3[:1000], -d3[1000:])  # odd
    np.testing.assert_allclose(da, 0.5e-4 * np.abs(sym.input))
    assert np.corrcoef(CATALOGUE["misalignment"].apply({"angle_rad": 1e-3}, rec, y0), rec.cross_input)[0, 1] \
        == pytest.approx(1.0)
    np.testing.assert_allclose(CATALOGUE["g_sensitivity"].apply({"coef_per_g": 1e-3}, rec, y0), 1e-3 * rec.accel_g)
    np.testing.assert_allclose(CATALOGUE["vibration_rectification"].apply({"coef_per_g2": 2e-5}, rec, y0),
                               2e-5 * rec.vib_grms ** 2)


@settings(max_examples=40)
@given(step=st.floats(1e-6, 1.0), scale=st.floats(1e-3, 100.0), seed=st.integers(0, 2 ** 16))
def test_quantization_error_is_bounded_by_half_a_step_and_on_the_grid(step, scale, seed):
    y = np.random.default_rng(seed).normal(0, scale, 500)
    rec = _rec(500)
    q = CATALOGUE["quantization"].apply({"step": step}, rec, y)
    assert np.all(np.abs(q - y) <= step / 2 * (1 + 1e-9))
    np.testing.assert_allclose(q / step, np.round(q / step), atol=1e-6)


@settings(max_examples=25, deadline=None)
@given(tau=st.one_of(st.just(0.0), st.floats(1e-6, 3.0)), offset=st.floats(-50.0, 50.0), seed=st.integers(0, 2 ** 16))
def test_dithered_quantizer_is_the_monte_carlo_mean_reading(tau, offset, seed):
    step = 2e-5
    x = offset * step + np.linspace(-1.5, 1.5, 13) * step  # across several steps
    n = np.random.default_rng(seed).standard_normal((20000, 1)) * tau * step
    mc = (step * np.round((x + n) / step)).mean(axis=0)
    se = step * math.sqrt(tau ** 2 + 1 / 12) / math.sqrt(20000)  # sd of a reading: noise + rounding
    np.testing.assert_allclose(expected_quantized(x, step, tau * step), mc, rtol=0, atol=5 * se + 1e-12 * step)


def test_dithered_quantizer_limits():
    x = np.linspace(-1e-4, 1e-4, 101) + 3.3e-7
    np.testing.assert_array_equal(expected_quantized(x, 1e-5, 0.0), 1e-5 * np.round(x / 1e-5))
    np.testing.assert_allclose(expected_quantized(x, 1e-5, 1e-9), 1e-5 * np.round(x / 1e-5), atol=1e-20)
    np.testing.assert_allclose(expected_quantized(x, 1e-5, 1e-5), x, atol=1e-5 * 1e-8)  # σ = step: linear
    # the two evaluation branches meet at σ = step/5
    a, b = expected_quantized(x, 1e-5, 0.2e-5 * (1 - 1e-12)), expected_quantized(x, 1e-5, 0.2e-5)
    np.testing.assert_allclose(a, b, atol=1e-5 * 1e-9)


@settings(max_examples=15, deadline=None)
@given(tau=st.floats(0.0, 2.0), seed=st.integers(0, 2 ** 16))
def test_quantized_reading_variance_and_the_floor_without_the_quantizer(tau, seed):
    step, n = 1e-5, 200000
    rng = np.random.default_rng(seed)
    x = rng.uniform(-1e-3, 1e-3, n)  # uniform phase over the steps
    y = step * np.round((x + tau * step * rng.standard_normal(n)) / step)
    q = CATALOGUE["quantization"]
    v = q.residual_var({"step": step}, tau * step)
    # sampling sd of a mean of squared errors: ≈ v·√(2/n) (0.32 %; measured over 60 seeds: mean
    # −0.01 %, sd 0.30–0.35 % at τ = 0.3…1), and ≤ step·√(v/n) when rare edge errors of about a
    # step dominate (small τ); hypothesis hunts the seeds, so allow 6 sd of the larger. Near τ = 0
    # the edge errors are a Poisson count with a mean far below one (5e-4 at τ = 4e-9), where one
    # event is already "many sd": allow 8 of them, as the quantized-mean test does
    got = float(np.var(y - expected_quantized(x, step, tau * step)))
    tol = 6 * max(v * math.sqrt(2 / n), step * math.sqrt(v / n)) + 8 * step ** 2 / n
    assert got == pytest.approx(v, abs=tol)
    floor = float(np.std(y - x))  # what a model without the quantizer leaves
    # floor² − step²/12 is known to ±step²/(12·√(n/1.8)): its square root to ~0.02 step near 0
    assert q.pre_transform_sd({"step": step}, floor) == pytest.approx(tau * step, abs=0.05 * step)


@settings(max_examples=40)
@given(limit=st.floats(0.05, 100.0), scale=st.floats(0.01, 200.0), seed=st.integers(0, 2 ** 16))
def test_saturation_clips_exactly_at_the_limit(limit, scale, seed):
    y = np.random.default_rng(seed).normal(0, scale, 500)
    out = CATALOGUE["saturation"].apply({"limit": limit}, _rec(500), y)
    inside = np.abs(y) <= limit
    np.testing.assert_array_equal(out[inside], y[inside])
    np.testing.assert_array_equal(np.abs(out[~inside]), limit)


@settings(max_examples=40)
@given(half=st.floats(1e-5, 0.5), seed=st.integers(0, 2 ** 16))
def test_dead_zone_removes_small_inputs_and_offsets_large_ones(half, seed):
    u = np.random.default_rng(seed).uniform(-1, 1, 500)
    rec = _rec(500, input=u)
    d = CATALOGUE["dead_zone"].apply({"half_width": half}, rec, u) - u
    small = np.abs(u) <= half
    np.testing.assert_allclose(d[small], -u[small], atol=1e-15)
    np.testing.assert_allclose(d[~small], -half * np.sign(u[~small]), atol=1e-12)


def test_sinusoid_shows_a_spectral_line_at_its_frequency():
    rec = _rec(4096, 100.0)
    d = CATALOGUE["sinusoidal_interference"].apply({"amplitude": 1e-3, "freq_hz": 12.3, "phase_rad": 0.4},
                                                   rec, np.zeros(4096))
    f = np.fft.rfftfreq(4096, 0.01)
    assert abs(f[np.argmax(np.abs(np.fft.rfft(d * np.hanning(4096))))] - 12.3) <= f[1]
    start = CATALOGUE["sinusoidal_interference"].fit_starts(rec, d + 1e-4, kind="accelerometer")[0]
    assert start["freq_hz"] == pytest.approx(12.3, abs=f[1])
    assert start["amplitude"] == pytest.approx(1e-3, rel=0.1)



@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_sines_fold_starts_skip_the_fold_patterns_lines_beside_a_random_walk(seed):
    """On a fold's training blocks (the held-out ones zeroed) a random walk's level, modulated by
    the fold pattern, makes false lines at the pattern's odd harmonics; a sine fitted there is
    sign-flipped on the held-out blocks. The true line is the start's first line and none of its
    other lines sits on a pattern line; the fold fit from it finds the true line."""
    n, rate = 3000, 10.0
    rec = _rec(n, rate)
    sine = {"amplitude": 1.7e-3, "freq_hz": 0.157, "phase_rad": 0.1}
    truth = (Model(BaseModel("gyro", noise_sd=3e-3)).with_effect("sinusoidal_interference", sine)
             .with_effect("rate_random_walk", {"k_per_rs": 3.8e-4}))
    y = truth.simulate(rec, seed)
    rec = rec.replace(y=y)
    eff = CATALOGUE["sinusoidal_interference"]
    base = Model(BaseModel("gyro", noise_sd=3e-3))
    pattern_bins = {23, 24, 25, 71, 72, 73, 119, 120, 121, 168, 216}  # 48 blocks: 24, 72 … cycles a record
    for k in (0, 1):
        train = sig.block_folds(n) != k
        starts = eff.fit_starts(rec, y, kind="gyro", rows=train, held_out=~train)
        assert starts[0]["freq_hz"] == pytest.approx(0.157, abs=1.5 / (n / rate))
        others = [f"freq_{k}_hz" for k in range(2, MAX_LINES + 1) if starts[0][f"amplitude_{k}"] != 0.0]
        assert len(starts) == 1 and others
        assert not {round(starts[0][name] * n / rate) for name in others} & pattern_bins
        f = CandidateFitter(base, rec, eff, template=starts[0], rows=train)
        fit = f.fit([f.pack(p, 0.0, 1.0) for p in starts[:2]], rows=train, max_nfev=40, with_std=False)
        assert fit.params["freq_hz"] == pytest.approx(0.157, rel=0.01)

def test_gauss_markov_autocorrelation_at_tau_is_one_over_e():
    n, tau_samples = 200_000, 25
    rec = _rec(n, 1.0)
    x = CATALOGUE["gauss_markov"].apply({"sigma": 1.0, "tau_s": float(tau_samples)}, rec, np.zeros(n),
                                        rng=np.random.default_rng(11))
    x = x - x.mean()
    acf = np.dot(x[tau_samples:], x[:-tau_samples]) / np.dot(x, x)
    assert acf == pytest.approx(math.exp(-1), abs=0.03)  # sd of the estimate ≈ sqrt(2τ/n) ≈ 0.016
    assert np.std(x) == pytest.approx(1.0, rel=0.05)


def _avar(x, m):
    k = x.size // m
    means = x[: k * m].reshape(k, m).mean(axis=1)
    return 0.5 * np.mean(np.diff(means) ** 2)


def test_rate_random_walk_allan_slope_is_plus_one_half():
    n = 400_000
    rec = _rec(n, 1.0)
    x = CATALOGUE["rate_random_walk"].apply({"k_per_rs": 1e-3}, rec, np.zeros(n), rng=np.random.default_rng(2))
    m1, m2 = 10, 1000
    slope = 0.5 * math.log10(_avar(x, m2) / _avar(x, m1)) / math.log10(m2 / m1)
    assert slope == pytest.approx(0.5, abs=0.08)
    assert math.sqrt(_avar(x, m2)) == pytest.approx(1e-3 * math.sqrt(m2 / 3), rel=0.35)


def test_time_delay_shifts_the_cross_correlation_peak():
    rng = np.random.default_rng(6)
    n, rate = 20000, 100.0
    u = np.convolve(rng.standard_normal(n), np.hanning(15) / 7.5, mode="same")  # smooth random input
    rec = _rec(n, rate, input=u)
    y = CATALOGUE["time_delay"].apply({"delay_s": 0.034}, rec, u)
    lags = np.arange(-10, 11)
    xc = np.array([np.dot(y[20:-20], np.roll(u, k)[20:-20]) for k in lags])
    i = int(np.argmax(xc))
    frac = 0.5 * (xc[i - 1] - xc[i + 1]) / (xc[i - 1] - 2 * xc[i] + xc[i + 1])
    assert (lags[i] + frac) / rate == pytest.approx(0.034, abs=0.002)


def test_lowpass_and_highpass_are_the_continuous_single_pole_of_an_input_linear_between_samples():
    # the reference: scipy's lsim of ω/(s + ω), which interpolates the input linearly between samples
    n, rate, f = 400, 100.0, 2.0
    rng = np.random.default_rng(3)
    u = np.cumsum(np.where(rng.random(n) < 0.05, rng.normal(0, 1, n), 0.0))  # steps and holds
    u[:20] = 0.0
    t = np.arange(n) / rate
    rec = _rec(n, rate, input=u)
    w = 2 * math.pi * f
    _, ref, _ = signal.lsim(([w], [1.0, w]), u, t)
    lp = CATALOGUE["lowpass_bandwidth"].apply({"bandwidth_hz": f}, rec, u)
    np.testing.assert_allclose(lp, ref, atol=1e-9)
    hp = CATALOGUE["highpass_rolloff"].apply({"corner_hz": f}, rec, u)
    np.testing.assert_allclose(hp, u - ref, atol=1e-9)
    # a sampled step (a ramp over one sample): 1 − a^k·(1 − a)/(ω·dt) after it
    step = np.where(np.arange(n) >= 100, 1.0, 0.0)
    a, k = math.exp(-w / rate), np.arange(n - 100)
    lp = CATALOGUE["lowpass_bandwidth"].apply({"bandwidth_hz": f}, _rec(n, rate, input=step), step)
    np.testing.assert_allclose(lp[100:], 1 - a ** k * (1 - a) / (w / rate), atol=1e-12)
    np.testing.assert_array_equal(lp[:100], 0.0)
    with pytest.raises(ValueError, match="uniformly sampled"):
        t = np.cumsum(np.random.default_rng(0).uniform(0.5, 1.5, 50))
        r = Record(t_s=t, y=np.zeros(50), input=np.ones(50))
        CATALOGUE["lowpass_bandwidth"].apply({"bandwidth_hz": 1.0}, r, np.ones(50))


@pytest.mark.parametrize("eid,params", [("k2_nonlinearity", {"k2_per_u": 3e-5}),
                                        ("temperature_bias", {"coef_per_c": 2e-6, "coef_per_c2": -1e-8}),
                                        ("warmup_exponential", {"amplitude": -5e-5, "tau_s": 300.0})])
def test_fit_starts_recover_linear_parameters_from_a_clean_residual(records, eid, params):
    e, rec = CATALOGUE[eid], records["accelerometer"]
    resid = e.apply(params, rec, rec.input) - rec.input
    best = e.fit_starts(rec, resid + 1e-3, kind="accelerometer")[0]  # an offset the bias absorbs
    for name, v in params.items():
        if e.param(name).linear:
            assert best[name] == pytest.approx(v, rel=0.2 if eid == "warmup_exponential" else 1e-6)


@pytest.mark.parametrize("eid", ["gauss_markov", "rate_random_walk", "time_delay", "lowpass_bandwidth",
                                 "dead_zone", "quantization", "saturation"])
def test_fit_starts_are_complete_parameter_sets(records, eid):
    e, rec = CATALOGUE[eid], records["gyro"]
    p = e.draw(np.random.default_rng(3), rec, kind="gyro", noise_sd=3e-3)
    resid = e.apply(p, rec, rec.input, rng=np.random.default_rng(4)) - rec.input
    starts = e.fit_starts(rec, resid, kind="gyro")
    assert starts and all(set(s) == set(e.param_names) for s in starts)


def test_experiments_log_what_their_kind_needs_and_are_deterministic():
    for kind in KINDS:
        a = make_experiment(kind, np.random.default_rng(1), n=2000)
        b = make_experiment(kind, np.random.default_rng(1), n=2000)
        np.testing.assert_array_equal(a.input, b.input)
        assert a.t_on_s[0] == 0 and a.is_uniform()
        for e in CATALOGUE.for_kind(kind):
            e.check_inputs(a)
    g = make_experiment("gyro", np.random.default_rng(2))
    assert np.max(np.abs(g.input)) == pytest.approx(100.0) and np.min(np.abs(g.input)) == 0.0
    with pytest.raises(ValueError, match="sensor kind 'sonar'"):
        make_experiment("sonar", np.random.default_rng(0))


def test_fit_params_narrow_time_constants_and_frequencies_to_the_record(records):
    rec = records["accelerometer"]  # 3600 s at 1 Hz
    tau = CATALOGUE["warmup_exponential"].fit_params(rec, "accelerometer")[1]
    assert (tau.name, tau.low, tau.high) == ("tau_s", 1.0, 1799.5)  # half of 3599 s
    f = CATALOGUE["sinusoidal_interference"].fit_params(rec, "accelerometer")[1]
    assert f.high == 0.5 and f.low == pytest.approx(2 / 3599)
    # a Gauss–Markov τ beyond the record is a random walk on it: the fit range stops at T
    assert CATALOGUE["gauss_markov"].fit_params(rec, "accelerometer")[1].high == pytest.approx(3599)
    assert CATALOGUE["k2_nonlinearity"].fit_params(rec, "accelerometer") == \
        CATALOGUE["k2_nonlinearity"].params_for("accelerometer")


def test_short_experiments_move_within_their_dwells():
    rec = make_experiment("accelerometer", np.random.default_rng(4), n=300)  # 90 dwells of 3.3 s
    theta = np.rad2deg(np.arctan2(rec.cross_input, rec.input)) % 360
    assert np.all(np.abs(rec.input) <= 1.0)
    # every dwell reaches its position: the angles visited include the 15° grid
    assert {round(a) % 360 for a in theta} >= set(range(0, 360, 15)) - {90, 270}


@pytest.mark.parametrize("kind,eid", _pairs())
def test_a_draw_at_an_snr_has_that_snr(records, kind, eid):
    """The power curve's draws (benchmarks/discovery_scorecard.py --power): the main parameter
    where the signature's snr is the one asked for, the other parameters drawn as usual."""
    e, rec, sd = CATALOGUE[eid], records[kind], NOISE[kind]
    for ratio in (1.0, 2.0):
        try:
            p = e.draw(np.random.default_rng(9), rec, kind=kind, noise_sd=sd, at_snr=ratio * MIN_SNR)
        except ValueError as exc:  # that snr lies outside the physical range on this record
            assert "on this record" in str(exc)
            continue
        assert e.check_params(p, kind) == p
        main_only = p | ({"coef_per_c2": 0.0} if eid == "temperature_bias" else {})  # its drawn ΔT² share
        assert e.snr(main_only, rec, sd) == pytest.approx(ratio * MIN_SNR, rel=0.02)
    with pytest.raises(ValueError, match="at_snr = -1.0; allowed: > 0"):
        e.draw(np.random.default_rng(9), rec, kind=kind, noise_sd=sd, at_snr=-1.0)
