"""Thermal record: bias TC, SF TC and the element's lag from one chamber record with the logged
sensor on the case — recovered within their stated 2σ at the stated rate over drawn units (the
chamber-record population, on the generator's own RK4 physics), the compensation file carrying the
lag and transferring to a second record, and every bad input refused with its value named."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import Phase, given, settings
from hypothesis import strategies as st
from scipy import stats

from bench.analysis.thermal import (
    analyze_thermal_record,
    compensation_from_toml,
    compensation_to_toml,
    verify_thermal_record,
)
from bench.testing.generators.thermal_truth import (
    ChamberUnit,
    Program,
    chamber_program,
    draw_chamber_case,
    rate_table,
    simulate_chamber_record,
)

#: The rate the docs state (docs/METHODS.md): each of bias TC, SF TC and the lag lies within its
#: stated 2σ for ≥ 90 % of units. A run of N draws fails only below the binomial 1 % quantile at
#: exactly 90 % — a count that a method meeting the statement gives less than once in 100 runs.
CLAIMED_RATE = 0.90
FALSE_ALARM = 0.01
N_UNITS = 30
DT_S = 2.0


def _record(unit: ChamberUnit, program: Program, rates, dwell: float, seed: int) -> dict:
    return simulate_chamber_record(unit, program, lambda t: rate_table(t, rates, dwell), DT_S, seed=seed)


def _covered(est, truth: float) -> bool:
    return est.std is not None and abs(est.value - truth) <= 2.0 * est.std


def test_drawn_chamber_records_give_bias_tc_sf_tc_and_lag_within_their_stated_2_sigma():
    """≥ 90 % of drawn units within 2σ, each of bias TC, SF TC and lag (the count judged by the
    binomial allowance above; measured over 200 units in tests/analysis/thermal_coverage.py)."""
    rng = np.random.default_rng(41)
    hits = {"bias_tc": 0, "sf_tc": 0, "lag": 0}
    for i in range(N_UNITS):
        unit, program, rates, dwell = draw_chamber_case(rng)
        d = _record(unit, program, rates, dwell, seed=4100 + i)
        r = analyze_thermal_record(d["t"], d["output"], d["sensor"], d["applied"])
        hits["bias_tc"] += _covered(r.bias_tc, unit.bias_coef[1])
        hits["sf_tc"] += _covered(r.scale_factor_tc_ppm_per_c, unit.sf_ppm_coef[0])
        hits["lag"] += _covered(r.lag_s, unit.tau_element_s)
    floor = stats.binom.ppf(FALSE_ALARM, N_UNITS, CLAIMED_RATE)
    assert all(h >= floor for h in hits.values()), (hits, floor)


def test_the_issue_case_fixed_lag_zero_is_what_misreads_the_element():
    """The user's unit (bias TC 2.0e-3 °/s/°C, SF TC 150 ppm/°C, sensor 600 s behind the air,
    element 400 s behind the sensor): the fitted lag is the element's, and fixing it at 0 (plain
    least squares against the logged temperature) leaves a residual the lag explains."""
    unit = ChamberUnit(bias_coef=(0.05, 2.0e-3), sf0=1.0, sf_ppm_coef=(150.0,), tau_case_s=600.0,
                       tau_element_s=400.0, white_sd=5e-3, ar1_sd=2e-4, ar1_phi=0.995)
    d = _record(unit, chamber_program(np.random.default_rng(7)), (0.0, 10.0, -10.0, 50.0, -50.0, 100.0, -100.0),
                90.0, seed=7)
    r = analyze_thermal_record(d["t"], d["output"], d["sensor"], d["applied"])
    plain = analyze_thermal_record(d["t"], d["output"], d["sensor"], d["applied"], lag_s=0.0)
    assert _covered(r.lag_s, 400.0) and r.lag_s.std < 40.0
    assert abs(r.bias_tc.value - 2.0e-3) <= 4 * r.bias_tc.std
    assert abs(r.scale_factor_tc_ppm_per_c.value - 150.0) <= 4 * r.scale_factor_tc_ppm_per_c.std
    assert plain.lag_s.std is None and plain.noise_sigma > 1.5 * r.noise_sigma
    assert r.warnings == () and r.not_separable == {}


def test_the_compensation_file_carries_the_lag_and_transfers_to_a_second_record():
    rng = np.random.default_rng(11)
    unit, program, rates, dwell = draw_chamber_case(rng)
    d = _record(unit, program, rates, dwell, seed=11)
    r = analyze_thermal_record(d["t"], d["output"], d["sensor"], d["applied"])
    model = r.compensation_model(unit_serial="G-0011", unit_model="FOG-1", input_unit="deg/s",
                                 output_unit="deg/s", created="test")
    again = compensation_from_toml(compensation_to_toml(model))
    assert again.to_dict() == model.to_dict() and again.element_lag_s == pytest.approx(r.lag_s.value)
    assert again.temperature_source == "element" and {q.role for q in again.quantities} == {"bias", "scale_factor"}
    second = _record(unit, chamber_program(rng), rates, dwell, seed=12)  # another profile
    v = verify_thermal_record(r, second["t"], second["output"], second["sensor"], second["applied"])
    assert v.compensated_rms < 2.0 * v.noise_rms < v.uncompensated_rms
    assert v.to_dict()["n_blocks"] == v.n_blocks > 40


def test_a_static_unit_gives_the_bias_curve_alone():
    unit = ChamberUnit(bias_coef=(0.05, -1.5e-3), sf_ppm_coef=(0.0,), tau_case_s=600.0, tau_element_s=500.0,
                       white_sd=5e-3)
    d = _record(unit, chamber_program(np.random.default_rng(3)), (0.0,), 60.0, seed=3)
    r = analyze_thermal_record(d["t"], d["output"], d["sensor"])
    assert r.scale_factor_curve is None and r.scale_factor_tc_ppm_per_c is None and r.scale_factor_order == 0
    assert abs(r.bias_tc.value + 1.5e-3) <= 4 * r.bias_tc.std and abs(r.lag_s.value - 500.0) <= 4 * r.lag_s.std
    d_ = r.to_dict()
    assert d_["block_applied"] is None and d_["scale_factor_curve"] is None and d_["lag_s"]["std"] > 0
    with pytest.raises(ValueError, match="output_unit = 'mV' differs from input_unit"):
        r.compensation_model(unit_serial="S", unit_model="M", input_unit="deg/s", output_unit="mV")


def _good(n: int = 3000) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    t = np.arange(n) * 6.0
    temp = 25.0 + 30.0 * np.sin(t / 4000.0)
    x = np.where((np.arange(n) // 20) % 2 == 0, 10.0, -10.0)
    return t, x + 1e-3 * (temp - 25.0), temp, x


@pytest.mark.parametrize("change, message", [
    (lambda a: {**a, "t_s": a["t_s"][:20], "output": a["output"][:20], "temperature_c": a["temperature_c"][:20],
                "applied": a["applied"][:20]}, "t_s has 20 samples: at least 40 are needed"),
    (lambda a: {**a, "output": np.where(np.arange(a["t_s"].size) == 17, np.nan, a["output"])},
     "output[17] = nan: allowed finite numbers only (1 non-finite of 3000)"),
    (lambda a: {**a, "t_s": np.where(np.arange(a["t_s"].size) == 101, 0.0, a["t_s"])},
     "t_s[101] = 0.0 s does not follow t_s[100] = 600.0 s: allowed strictly increasing times"),
    (lambda a: {**a, "temperature_c": 25.0 + 0.01 * (a["temperature_c"] - 25.0)},
     "temperature_c spans 0.593 °C (24.71 … 25.3): allowed ≥ 5 °C to read a temperature coefficient"),
    (lambda a: {**a, "temperature_c": a["temperature_c"] + 200.0}, "temperature_c[0] = 225.0 °C: allowed [-100, 200]"),
    (lambda a: {**a, "applied": np.full(a["t_s"].size, 10.0)},
     "applied is constant at 10.0: a scale factor needs two or more input levels"),
    (lambda a: {**a, "applied": a["applied"][:-1]}, "applied has shape (2999,): allowed 1-D of the length of t_s"),
    (lambda a: {**a, "block_s": 0.0}, "block_s = 0.0 outside the allowed range (0, 3600]"),
    (lambda a: {**a, "block_s": 3600.0}, "the record gives 5 blocks of 3600 s; at least 40 are needed"),
    (lambda a: {**a, "bias_order": 4}, "bias_order = 4 must be an integer in [0, 3]"),
    (lambda a: {**a, "scale_factor_order": -1}, "scale_factor_order = -1 must be an integer in [0, 3]"),
    (lambda a: {**a, "lag_s": -1.0}, "lag_s = -1.0 outside the allowed range [0, 100000]"),
    (lambda a: {**a, "lag_max_s": 0.0}, "lag_max_s = 0.0 outside the allowed range (0, 100000]"),
    (lambda a: {**a, "reference_c": 300.0}, "reference_c = 300.0 outside the allowed range [-100, 200]"),
    (lambda a: {**a, "rate_window_s": 10.0}, "rate_window_s = 10.0 outside the allowed range [60"),
    (lambda a: {**a, "min_separation": 0.0}, "min_separation = 0.0 outside the allowed range (0, 1]"),
    (lambda a: {**a, "hysteresis_width_max_c": 0.1},
     "hysteresis_width_max_c = 0.1 outside the allowed range (0.125, 50]"),
])
def test_bad_inputs_name_the_value_and_what_is_allowed(change, message):
    t, y, temp, x = _good()
    args = change({"t_s": t, "output": y, "temperature_c": temp, "applied": x})
    with pytest.raises(ValueError) as err:
        analyze_thermal_record(args.pop("t_s"), args.pop("output"), args.pop("temperature_c"), args.pop("applied"),
                               **args)
    assert message in str(err.value)


@settings(max_examples=25, deadline=None, derandomize=True, phases=[Phase.explicit, Phase.generate])
@given(st.sampled_from(["t_s", "output", "temperature_c", "applied"]), st.integers(0, 2999),
       st.sampled_from([np.nan, np.inf, -np.inf]))
def test_a_non_finite_sample_is_named_by_array_and_index(name, index, bad):
    t, y, temp, x = _good()
    arrays = {"t_s": t, "output": y, "temperature_c": temp, "applied": x}
    arrays[name] = arrays[name].copy()
    arrays[name][index] = bad
    with pytest.raises(ValueError, match=rf"^{name}\[{index}\] = {bad!r}: allowed finite numbers only"):
        analyze_thermal_record(arrays["t_s"], arrays["output"], arrays["temperature_c"], arrays["applied"])


def test_the_files_lag_key_is_checked_and_optional():
    t, y, temp, x = _good()
    r = analyze_thermal_record(t, y, temp, x)
    model = r.compensation_model(unit_serial="S", unit_model="M", input_unit="deg/s", output_unit="deg/s")
    text = compensation_to_toml(model)
    with pytest.raises(ValueError, match="element_lag_s = 12.0 is allowed only with temperature_source 'element'"):
        compensation_from_toml(text.replace('temperature_source = "element"', 'temperature_source = "unit_sensor"')
                               .replace(f"element_lag_s = {model.element_lag_s!r}", "element_lag_s = 12.0"))
    with pytest.raises(ValueError, match=r"element_lag_s = -1.0 outside the allowed range \[0, 100000\]"):
        compensation_from_toml(text.replace(f"element_lag_s = {model.element_lag_s!r}", "element_lag_s = -1.0"))
    plain = compensation_from_toml(text.replace(f"element_lag_s = {model.element_lag_s!r}\n", ""))
    assert plain.element_lag_s is None and "element_lag_s" not in plain.to_dict()


def test_a_play_hysteresis_is_fitted_beside_the_lag_when_asked():
    """A unit with a 0.01 °/s hysteresis switching over 2·4 °C: with ``hysteresis=True`` its size
    and width are read (each within 4σ) and the TCs still are."""
    rng = np.random.default_rng(102)
    unit, program, rates, dwell = draw_chamber_case(rng)
    unit = dataclasses.replace(unit, hysteresis=0.01, hysteresis_width_c=4.0)
    d = _record(unit, program, rates, dwell, seed=102)
    r = analyze_thermal_record(d["t"], d["output"], d["sensor"], d["applied"], hysteresis=True)
    assert abs(r.hysteresis.value - 0.01 * unit.sf0) <= 4 * r.hysteresis.std
    assert abs(r.hysteresis_width_c.value - 4.0) <= 4 * r.hysteresis_width_c.std
    assert abs(r.bias_tc.value - unit.bias_coef[1]) <= 4 * r.bias_tc.std
    assert abs(r.scale_factor_tc_ppm_per_c.value - unit.sf_ppm_coef[0]) <= 4 * r.scale_factor_tc_ppm_per_c.std
    assert r.to_dict()["hysteresis_width_interval_c"] == list(r.hysteresis_width_interval_c)
    static = analyze_thermal_record(d["t"], d["output"], d["sensor"], d["applied"])
    assert static.hysteresis is None and static.hysteresis_width_c is None
