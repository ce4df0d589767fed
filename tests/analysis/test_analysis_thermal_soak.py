"""Soak criterion: the scan agrees with the polled status, the soak time of a first-order
approach, the start time and target rules, and a soak on the tests' two-node physics."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.analysis.thermal._soak import SoakCriterion, find_soak, soak_status
from bench.testing.generators.thermal_truth import Program, ThermalUnit, simulate_ramp


def approach(t, start_c, final_c, tau_s):
    return final_c + (start_c - final_c) * np.exp(-t / tau_s)


@settings(max_examples=20, deadline=None)
@given(st.floats(-40, 70), st.floats(-40, 70), st.floats(300.0, 3000.0), st.floats(0.0, 0.02),
       st.sampled_from([10.0, 30.0, 60.0]), st.integers(0, 2**31 - 1))
def test_the_scan_finds_the_first_reading_a_poll_would_call_stable(start, final, tau, noise, dt, seed):
    t = np.arange(0.0, 6 * 3600.0, dt)
    temp = approach(t, start, final, tau) + np.random.default_rng(seed).normal(0, noise, t.size)
    crit = SoakCriterion(window_s=600.0, max_rate_c_per_min=0.02, band_c=0.15)
    result = find_soak(t, temp, crit)
    polled = [soak_status(t[: i + 1], temp[: i + 1], crit).stable for i in range(0, t.size, max(1, t.size // 200))]
    if result.stable:
        i = int(np.searchsorted(t, result.stable_at_s))
        assert soak_status(t[: i + 1], temp[: i + 1], crit).stable
        earlier = range(max(0, i - 60), i)  # the readings just before, and the polled ones below
        assert not any(soak_status(t[: j + 1], temp[: j + 1], crit).stable for j in earlier)
        assert not any(polled[: i // max(1, t.size // 200)])
        assert result.soak_time_s == result.stable_at_s - t[0] >= crit.window_s
    else:
        assert not any(polled)


def test_soak_time_of_a_noiseless_first_order_approach():
    """ΔT·e^(−t/τ): the spread over the window ending at t is ΔT·e^(−t/τ)(e^(W/τ) − 1), the
    rate ΔT/τ·e^(−t/τ); the soak ends when the later of the two conditions is met."""
    tau, delta, w = 900.0, 40.0, 600.0
    t = np.arange(0.0, 8 * 3600.0, 5.0)
    crit = SoakCriterion(window_s=w, max_rate_c_per_min=0.01, band_c=0.1)
    result = find_soak(t, approach(t, 25.0 + delta, 25.0, tau), crit)
    t_band = tau * math.log(delta * (math.exp(w / tau) - 1) / crit.band_c)
    # the least-squares slope over the window is the rate near the window's middle
    t_rate = tau * math.log(delta / tau * 60.0 / crit.max_rate_c_per_min) + w / 2
    assert result.stable_at_s == pytest.approx(max(t_band, t_rate), abs=30.0)
    assert result.final.stable and result.final.reason == ""


def test_a_unit_still_stable_at_the_old_temperature_does_not_pass_before_a_full_window():
    t = np.arange(0.0, 7200.0, 10.0)
    temp = np.where(t < 3600.0, 25.0, approach(t - 3600.0, 25.0, 70.0, 600.0))
    crit = SoakCriterion(window_s=900.0, max_rate_c_per_min=0.02, band_c=0.1)
    early = soak_status(t[:300], temp[:300], crit, start_s=2400.0)
    assert not early.stable and "window not yet covered" in early.reason
    from_command = find_soak(t, temp, crit, start_s=3600.0)
    assert not from_command.stable  # 1 h after the step the approach is still under way
    assert find_soak(t, temp, crit).stable_at_s == pytest.approx(900.0)  # the old plateau counts without start_s


def test_target_and_sample_count_rules():
    t = np.arange(0.0, 3600.0, 10.0)
    flat = np.full(t.size, 60.0)
    at_wrong = soak_status(t, flat, SoakCriterion(target_c=70.0, target_tolerance_c=2.0))
    assert not at_wrong.stable and "not within 2 of target 70" in at_wrong.reason
    assert soak_status(t, flat, SoakCriterion(target_c=61.0)).stable
    sparse = soak_status(t[::90], flat[::90], SoakCriterion(window_s=600.0, min_samples=10))
    assert not sparse.stable and "readings in the window, 10 needed" in sparse.reason
    ramp = soak_status(t, 25.0 + t / 60.0 * 0.1, SoakCriterion())
    assert not ramp.stable and ramp.rate_c_per_min == pytest.approx(0.1)
    assert "rate 0.1 °C/min beyond ±0.05" in ramp.reason


def test_soak_on_the_two_node_physics():
    """The element lags the case the sensor reads: when the sensor says stable, the element
    is within the band's order of the set point."""
    unit = ThermalUnit(tau_case_s=900.0, tau_element_s=600.0, sensor_noise_c=0.01)
    prog = Program([0.0, 3600.0, 3600.0 + 65 * 60.0, 6 * 3600.0], [25.0, 25.0, -40.0, -40.0])
    d = simulate_ramp(unit, prog, 10.0, seed=3)
    crit = SoakCriterion(window_s=900.0, max_rate_c_per_min=0.02, band_c=0.1, target_c=-40.0)
    result = find_soak(d["t"], d["sensor"], crit, start_s=3600.0)
    assert result.stable
    i = int(np.searchsorted(d["t"], result.stable_at_s))
    assert abs(d["element"][i] - (-40.0)) < 0.3
    assert 3600.0 < result.soak_time_s < 4 * 3600.0


@pytest.mark.parametrize("kwargs, message", [
    (dict(window_s=0.0), "window_s = 0.0 outside the allowed range (0, 86400]"),
    (dict(max_rate_c_per_min=-1.0), "max_rate_c_per_min = -1.0 outside the allowed range (0, 10]"),
    (dict(band_c=math.nan), "band_c = nan"),
    (dict(min_samples=2), "min_samples = 2 must be an integer in [3, 1000000]"),
    (dict(target_c=300.0), "target_c = 300.0 outside the allowed range [-100, 200]"),
    (dict(target_tolerance_c=0.0), "target_tolerance_c = 0.0"),
])
def test_criterion_checks_its_parameters(kwargs, message):
    with pytest.raises(ValueError) as err:
        SoakCriterion(**kwargs)
    assert message in str(err.value)


def test_series_checks():
    crit = SoakCriterion()
    with pytest.raises(ValueError, match=r"t_s\[2\] = 1.0 ≤ t_s\[1\] = 1.0"):
        soak_status([0.0, 1.0, 1.0], [20.0] * 3, crit)
    with pytest.raises(ValueError, match=r"temp_c\[1\] = -300.0 outside the allowed range"):
        soak_status([0.0, 1.0], [20.0, -300.0], crit)
    with pytest.raises(ValueError, match="one length"):
        find_soak([0.0, 1.0], [20.0], crit)
    with pytest.raises(ValueError, match="start_s = 5.0 must be finite and not after the last reading"):
        soak_status([0.0, 1.0], [20.0, 20.0], crit, start_s=5.0)
