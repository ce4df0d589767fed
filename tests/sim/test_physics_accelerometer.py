"""Quartz flexure accelerometer: supply, start-up transient, IEEE 1293 model, noise."""

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sim.physics.accelerometer import AccelerometerParams, QuartzAccelerometer
from sim.physics.gravity import STANDARD_GRAVITY_MPS2, local_gravity_mps2
from sim.physics.motion import DualAxisTable

G_LOCAL = local_gravity_mps2(32.06, 20.0)  # Nanjing-like site
ONE_G = G_LOCAL / STANDARD_GRAVITY_MPS2


def powered_unit(seed=1, t_on=0.0, **overrides):
    unit = QuartzAccelerometer(AccelerometerParams(**overrides), np.random.default_rng(seed))
    unit.set_supply(t_on, 15.0, -15.0)
    return unit


def ia_up(n):
    f = np.zeros((n, 3))
    f[:, 0] = ONE_G
    return f


def test_unpowered_outputs_exactly_zero_and_out_of_range_rails_do_not_power():
    unit = QuartzAccelerometer(AccelerometerParams(), np.random.default_rng(0))
    t = np.linspace(0.0, 10.0, 11)
    assert np.array_equal(unit.output_current_a(t, ia_up(11), 0.1), np.zeros(11))
    for v_pos, v_neg in [(12.9, -15.0), (15.0, -18.5), (15.0, 15.0), (-15.0, -15.0)]:
        unit.set_supply(10.0, v_pos, v_neg)
        assert not unit.powered(10.0).any()
    unit.set_supply(20.0, 15.0, -15.0)
    unit.set_supply(30.0, 0.0, 0.0)
    assert np.array_equal(unit.output_current_a(np.array([30.0, 40.0]), ia_up(2), 0.1), [0.0, 0.0])
    assert unit.supply_current_a(35.0)[0] == 0.0


def test_powered_at_rest_ia_up_gives_the_model_value_within_noise():
    p = AccelerometerParams()
    unit = powered_unit(t_on=5.0)
    t = 5.0 + np.arange(0.0, 3600.0, 1.0)
    current = unit.output_current_a(t, ia_up(t.size), 0.2)
    since = t - 5.0
    temp = unit.element_temperature_c(t)  # the two-node model's element (tests/sim/test_thermal_*)
    expected_g = (ONE_G + p.k0_g + p.k2_g_per_g2 * ONE_G**2 + p.k3_g_per_g3 * ONE_G**3
                  + 60e-6 * np.exp(-since / 180.0) + 1e-9 * since + 5e-6 * (temp - 23.0))
    residual_g = current / 1.33e-3 - expected_g
    # Noise of the mean: white σ 2e-6/√0.4 over 3600 samples plus the 20 s Gauss-Markov
    # term, variance of its mean ≈ 2σ²τ/T; allow 5 standard errors.
    se = math.sqrt((2e-6 / math.sqrt(0.4)) ** 2 / t.size + 2 * (4e-6) ** 2 * 20.0 / 3600.0)
    assert abs(residual_g.mean()) < 5 * se
    assert residual_g.std() == pytest.approx(math.hypot(4e-6, 2e-6 / math.sqrt(0.4)), rel=0.25)
    assert np.array_equal(unit.powered(t[-1:]), [True])


@settings(max_examples=25, deadline=None)
@given(amplitude=st.floats(-1e-3, 1e-3).filter(lambda a: abs(a) > 1e-6), tau=st.floats(10.0, 2000.0),
       t_on=st.floats(0.0, 1e4))
def test_start_up_transient_decays_with_its_time_constant(amplitude, tau, t_on):
    unit = powered_unit(t_on=t_on, warmup_amplitude_g=amplitude, warmup_tau_s=tau, drift_g_per_s=0.0,
                        bias_tc_g_per_c=0.0)
    t = t_on + np.array([0.0, tau, 2 * tau, 50 * tau])
    g = unit.output_current_a(t, ia_up(4), 1.0, noise=False) / unit.params.k1_a_per_g
    transient = g - g[-1]  # exp(-50) is nil
    assert transient[0] == pytest.approx(amplitude, rel=1e-9)
    assert transient[1] / transient[0] == pytest.approx(math.exp(-1), rel=1e-9)
    assert transient[2] / transient[0] == pytest.approx(math.exp(-2), rel=1e-9)


def test_power_cycle_restarts_the_transient():
    unit = powered_unit(t_on=0.0, drift_g_per_s=0.0, bias_tc_g_per_c=0.0)
    unit.set_supply(1000.0, 0.0, 0.0)
    unit.set_supply(2000.0, 14.0, -14.0)
    assert unit.power_on_time_s == 2000.0
    g = unit.output_current_a(np.array([2000.0]), ia_up(1), 1.0, noise=False)[0] / unit.params.k1_a_per_g
    assert g == pytest.approx(ONE_G + 20e-6 + 10e-6 * ONE_G**2 + 1e-6 * ONE_G**3 + 60e-6, abs=1e-12)
    with pytest.raises(ValueError, match="precedes the last supply change"):
        unit.output_current_a(np.array([1500.0]), ia_up(1), 1.0)


def test_same_seed_same_output_regardless_of_chunking():
    t = 3.0 + 0.1 * np.arange(3000)
    f = ia_up(t.size)
    whole = powered_unit(seed=42, t_on=3.0).output_current_a(t, f, 0.1)
    unit = powered_unit(seed=42, t_on=3.0)
    parts = [unit.output_current_a(t[a:b], f[a:b], 0.1) for a, b in [(0, 1), (1, 700), (700, 3000)]]
    assert np.array_equal(whole, np.concatenate(parts))
    other = powered_unit(seed=43, t_on=3.0).output_current_a(t, f, 0.1)
    assert not np.allclose(whole, other, rtol=0, atol=1e-10)
    with pytest.raises(ValueError, match="precedes"):
        unit.output_current_a(t[:5], f[:5], 0.1)  # the noise cannot go back in time


def test_noise_stream_does_not_depend_on_the_power_history():
    t = np.arange(0.0, 100.0, 1.0)
    always = powered_unit(seed=5).output_current_a(t, ia_up(100), 1.0)
    unit = QuartzAccelerometer(AccelerometerParams(), np.random.default_rng(5))
    off = unit.output_current_a(t[:50], ia_up(50), 1.0)
    unit.set_supply(50.0, 15.0, -15.0)
    late = unit.output_current_a(t[50:], ia_up(50), 1.0)
    assert np.array_equal(off, np.zeros(50))
    clean_always = powered_unit(seed=5).output_current_a(t, ia_up(100), 1.0, noise=False)
    clean_late = powered_unit(seed=5, t_on=50.0).output_current_a(t[50:], ia_up(50), 1.0, noise=False)
    # Same noise samples at t >= 50 whether or not the unit was on before.
    assert np.allclose(late - clean_late, (always - clean_always)[50:], rtol=0, atol=1e-15)


def tilt_readings(unit, tilts_deg, t_start=5000.0):
    """Noise-free readings with IA = platform z, PA = platform x, OA = platform y."""
    table = DualAxisTable()
    readings, forces = [], []
    t = t_start
    for tilt in tilts_deg:
        table.outer.command_position(t, tilt)
        t += 60.0  # moved and settled
        f_platform = table.specific_force_platform_g(np.array([t]), G_LOCAL)
        f_iapo = f_platform[:, [2, 0, 1]]
        readings.append(unit.output_current_a(np.array([t]), f_iapo, 1.0, noise=False)[0])
        forces.append(f_iapo[0])
    return np.array(readings), np.array(forces)


@settings(max_examples=15, deadline=None)
@given(k2=st.floats(-50e-6, 50e-6), k3=st.floats(-5e-6, 5e-6), k0=st.floats(-1e-3, 1e-3))
def test_k2_recovered_from_a_noise_free_tumble(k2, k3, k0):
    unit = powered_unit(k0_g=k0, k2_g_per_g2=k2, k3_g_per_g3=k3, drift_g_per_s=0.0)
    readings, f = tilt_readings(unit, np.arange(0.0, 360.0, 15.0), t_start=1e5)  # warm, steady
    ai, ap, ao = f.T
    assert np.allclose(ap, 0.0, atol=1e-15)  # tilting about East keeps PA horizontal here
    design = np.column_stack([np.ones_like(ai), ai, ai**2, ai**3, ao, ai * ao])
    coef, *_ = np.linalg.lstsq(design, readings / unit.params.k1_a_per_g, rcond=None)
    warm_element_c = unit.element_temperature_c(1e5)[0]  # steady: 23 + 4 + the element's rise
    warm_bias = k0 + 5e-6 * (warm_element_c - 23.0) + 60e-6 * math.exp(-1e5 / 180.0)
    assert coef[0] == pytest.approx(warm_bias, abs=1e-10)
    assert coef[1] == pytest.approx(1.0, abs=1e-9)
    assert coef[2] == pytest.approx(k2, abs=1e-10)
    assert coef[3] == pytest.approx(k3, abs=1e-9)
    assert coef[4] == pytest.approx(-50e-6, abs=1e-10)  # -δp
    assert coef[5] == pytest.approx(5e-6, abs=1e-10)  # Kio


def test_temperature_sensor_and_supply_current():
    unit = powered_unit(t_on=100.0)
    assert unit.temperature_c(100.0)[0] == pytest.approx(23.0)
    assert unit.temp_sensor_current_a(100.0)[0] == pytest.approx(296.15e-6, rel=1e-12)
    # the case (the sensor's node) rises 4 °C in steady state; its warm-up is the dominant
    # 600-s mode plus the element's fast one (two-node model, sim/physics/thermal_unit.py)
    assert unit.temperature_c(700.0)[0] == pytest.approx(23.0 + 4.0 * (1 - math.exp(-1)), abs=0.1)
    assert unit.temp_sensor_current_a(1e6)[0] == pytest.approx(300.15e-6, rel=1e-9)
    assert np.array_equal(unit.supply_current_a(np.array([150.0, 200.0])), [0.016, 0.016])


def test_truth_reports_the_true_parameters():
    unit = powered_unit(t_on=12.0, k2_g_per_g2=17e-6)
    truth = unit.truth()
    assert truth["k2_g_per_g2"] == 17e-6 and truth["k1_a_per_g"] == pytest.approx(1.33e-3)
    assert truth["power_on_time_s"] == 12.0
    assert {f.name for f in dataclasses.fields(AccelerometerParams)} <= set(truth)


@pytest.mark.parametrize("field,value", [
    ("k1_ma_per_g", 1.8), ("k1_ma_per_g", 0.9), ("k0_g", 0.02), ("warmup_tau_s", 0.0),
    ("ambient_c", 100.0), ("white_density_g_per_rthz", -1e-6), ("delta_o_rad", math.nan),
    ("supply_min_v", 20.0), ("gm_tau_s", (20.0, 5.0)), ("gm_sigma_g", (-1e-6,)),
])
def test_params_validation_names_the_field(field, value):
    name = "gm_" if field.startswith("gm_") else field
    with pytest.raises(ValueError, match=name):
        AccelerometerParams(**{field: value})


def test_constructor_requires_a_generator():
    with pytest.raises(TypeError, match="Generator"):
        QuartzAccelerometer(AccelerometerParams(), None)
