"""Compensation model and file: round trip, validation naming the key, inversion of the output
model, and verification on a second run over a different temperature profile."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.analysis.thermal import QuantityPoints, calibrate_over_temperature, verify_compensation
from bench.analysis.thermal._compensation import (
    CompensationModel,
    QuantityCompensation,
    compensate,
    compensation_model,
    model_output,
)
from bench.analysis.thermal._compensation_file import compensation_from_toml, compensation_to_toml
from bench.app.files import read_compensation, write_compensation
from bench.testing.generators.thermal_truth import poly, sweep_points

SWEEP_C = (-40.0, -20.0, 0.0, 25.0, 45.0, 60.0, 70.0)
VERIFY_C = (-35.0, -10.0, 10.0, 35.0, 55.0, 65.0)  # a different profile inside the calibrated range
# QA-2000-class unit: bias (g), scale factor (mA/g), K2 (g/g²), δo (rad) over temperature.
TRUTH = {"k0": (0.9e-3, 12e-6, 4e-8, 2e-10), "k1": (1.31, 1.31 * 45e-6, 1.31 * 5e-8),
         "k2": (8e-6, 5e-8), "delta_o": (20e-6, 0.2e-6)}
STD = {"k0": 1.5e-6, "k1": 1.31 * 3e-6, "k2": 0.5e-6, "delta_o": 1e-6}
META = {"k0": ("bias", "g", None, 1.0), "k1": ("scale_factor", "mA/g", None, 1.0),
        "k2": ("k2", "1/g", None, 1.0), "delta_o": ("cross_axis", "rad", "a_p", 1.0)}


def run_points(temps, seed: int, hysteresis_g: float = 0.0) -> list[QuantityPoints]:
    out = []
    for i, (name, coef) in enumerate(TRUTH.items()):
        role, unit, cross, sign = META[name]
        p = sweep_points(coef, temps, STD[name], 0.05, seed * 10 + i, offset=hysteresis_g if name == "k0" else 0.0)
        out.append(QuantityPoints(name, role, unit, p.temperature_c, p.value, p.std,
                                  temperature_std_c=p.temperature_std_c, cross_input=cross, sign=sign))
    return out


def model_for(seed: int = 1) -> CompensationModel:
    cal = calibrate_over_temperature(run_points(SWEEP_C, seed))
    return compensation_model(cal, unit_serial="QA-SIM-0005", unit_model="QA-2000-SIM", input_unit="g",
                              output_unit="mA", created="run 20261124-000000-test", notes="drawn by the tests")


def test_the_file_reads_back_bit_for_bit(tmp_path):
    model = model_for()
    path = tmp_path / "compensation.toml"
    write_compensation(model, path)
    back = read_compensation(path)
    assert compensation_to_toml(back) == path.read_text(encoding="utf-8")
    assert back.to_dict() == model.to_dict()
    for q, r in zip(model.quantities, back.quantities):
        np.testing.assert_array_equal(q.coefficients, r.coefficients)
        np.testing.assert_array_equal(q.covariance, r.covariance)
    text = path.read_text(encoding="utf-8")
    assert 'format = "inertial-bench-thermal-compensation"' in text and "version = 1" in text
    assert "[quantities.delta_o]" in text and 'cross_input = "a_p"' in text


def test_file_figures_describe_the_fit():
    model = model_for()
    cal = calibrate_over_temperature(run_points(SWEEP_C, 1))
    k0 = model["k0"]
    assert k0.n_points == 7 and k0.order_selection == "bic"
    assert k0.residual_rms == pytest.approx(float(np.sqrt(np.mean(cal["k0"].fit.residuals ** 2))))
    assert model.valid_range_c[0] == pytest.approx(min(cal["k0"].fit.temperature_c), abs=0.31)
    grid = np.linspace(*model.valid_range_c, 201)
    assert k0.prediction_std_max == pytest.approx(float(cal["k0"].fit.std(grid).max()))


def replace_line(text: str, key: str, new: str, table: str | None = None) -> str:
    lines = text.splitlines()
    inside = table is None
    for i, line in enumerate(lines):
        if line.startswith("["):
            inside = line.strip() == f"[{table}]"
        if inside and line.startswith(f"{key} ="):
            lines[i] = new
            return "\n".join(lines) + "\n"
    raise AssertionError(f"{key} not found")


@pytest.mark.parametrize("table, key, new, message", [
    (None, "version", "version = 2", "version = 2: this reader supports versions 1"),
    (None, "format", 'format = "other"', "format = 'other': allowed 'inertial-bench-thermal-compensation'"),
    (None, "reference_c", "reference_c = 400.0", "reference_c = 400.0 outside the allowed range [-100, 200]"),
    (None, "valid_range_c", "valid_range_c = [70.0, -40.0]", "valid_range_c = [70.0, -40.0]: allowed [low, high]"),
    (None, "temperature_source", 'temperature_source = "air"', "temperature_source = 'air' must be one of"),
    (None, "unit_serial", 'unit_serial = ""', "unit_serial = '': allowed a non-empty string"),
    ("quantities.k0", "role", 'role = "offset"', "quantities.k0.role = 'offset' must be one of"),
    ("quantities.k0", "coefficients", "coefficients = [1.0, 2.0, 3.0, 4.0, 5.0]",
     "quantities.k0.coefficients = [1.0, 2.0, 3.0, 4.0, 5.0]: allowed 1 to 4 finite numbers"),
    ("quantities.k0", "coefficients", 'coefficients = ["a"]', "quantities.k0.coefficients = ['a']"),
    ("quantities.k0", "covariance", "covariance = [[1.0]]", "quantities.k0.covariance = [[1.0]]: allowed a"),
    ("quantities.k0", "residual_rms", "residual_rms = -1.0",
     "quantities.k0.residual_rms = -1.0 outside the allowed range [0, inf]"),
    ("quantities.k0", "n_points", "n_points = 2.5", "quantities.k0.n_points = 2.5 must be an integer"),
    ("quantities.k0", "order_selection", 'order_selection = "aic"', "quantities.k0.order_selection = 'aic'"),
    ("quantities.delta_o", "sign", "sign = 2.0", "quantities.delta_o.sign = 2.0: allowed 1.0 or -1.0"),
    ("quantities.delta_o", "cross_input", 'cross_input = "a p"', "quantities.delta_o.cross_input = 'a p'"),
    ("quantities.k1", "coefficients", "coefficients = [1.0, 0.05, 0.0]", "the scale factor crosses zero"),
])
def test_a_bad_file_names_the_key_and_what_is_allowed(table, key, new, message):
    text = replace_line(compensation_to_toml(model_for()), key, new, table)
    with pytest.raises(ValueError) as err:
        compensation_from_toml(text)
    assert message in str(err.value)


def test_unknown_missing_and_unreadable(tmp_path):
    text = compensation_to_toml(model_for())
    with pytest.raises(ValueError, match="^colour: unknown key; allowed format, version"):
        compensation_from_toml('colour = "red"\n' + text)
    with pytest.raises(ValueError, match="quantities.k0.slope: unknown key"):
        compensation_from_toml(text.replace("[quantities.k0]\n", "[quantities.k0]\nslope = 1.0\n"))
    with pytest.raises(ValueError, match="^input_unit: missing"):
        compensation_from_toml(replace_line(text, "input_unit", ""))
    with pytest.raises(ValueError, match="not valid TOML"):
        compensation_from_toml("version = = 1")
    with pytest.raises(ValueError, match="cannot read compensation file"):
        read_compensation(tmp_path / "absent.toml")


def test_model_checks_hold_for_models_built_in_code():
    q = QuantityCompensation("b", "bias", "g", np.array([1e-3]), np.array([[1e-12]]), 0.0, 0.0, 0.0, 3, "fixed")
    with pytest.raises(ValueError, match="no quantity has role 'scale_factor'"):
        CompensationModel("SN", "M", "unit_sensor", 25.0, (-40.0, 70.0), "g", "mA", (q,))
    ok = CompensationModel("SN", "M", "unit_sensor", 25.0, (-40.0, 70.0), "g", "g", (q,))
    assert ok.quantity("scale_factor") is None
    with pytest.raises(ValueError, match="quantities.b appears twice"):
        CompensationModel("SN", "M", "unit_sensor", 25.0, (-40.0, 70.0), "g", "g", (q, q))
    with pytest.raises(ValueError, match="symmetric positive semi-definite"):
        QuantityCompensation("b", "bias", "g", np.array([1e-3, 1e-5]), np.array([[1.0, 2.0], [2.0, 1.0]]),
                             0.0, 0.0, 0.0, 3, "fixed")


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-1.5, 1.5), min_size=1, max_size=20), st.floats(-39.0, 69.0),
       st.floats(-1.0, 1.0), st.booleans())
def test_compensation_inverts_the_output_model(inputs, temp, cross, with_cross):
    model = model_for()
    x = np.array(inputs)
    cross_inputs = {"a_p": np.full(x.size, cross)} if with_cross else None
    raw = model_output(model, x, temp, cross_inputs=cross_inputs)
    back = compensate(model, raw, temp, cross_inputs=cross_inputs)
    np.testing.assert_allclose(back.input_estimate, x, atol=1e-12)
    assert set(back.applied) == {"k0", "k1", "k2"} | ({"delta_o"} if with_cross else set())
    assert ("delta_o" in back.not_applied) != with_cross


def test_compensation_undoes_the_generators_temperature_dependence():
    """Raw output of the true unit (the generator's polynomials), compensated with the model
    fitted from a noisy sweep: the residual input error stays within a few σ of the model."""
    model = model_for()
    temps = np.linspace(-38.0, 68.0, 50)
    x = np.tile([1.0, -1.0, 0.0], temps.size)[: temps.size]
    k0, k1, k2 = (poly(TRUTH[n], temps) for n in ("k0", "k1", "k2"))
    raw = k1 * (x + k0 + k2 * x**2)
    raw_uncompensated_error = raw / TRUTH["k1"][0] - TRUTH["k0"][0] - x
    out = compensate(model, raw, temps)
    err = out.input_estimate - x
    assert np.abs(err).max() < 12e-6  # g: bias σ 1.5 µg, SF σ 3 ppm of 1 g at every point
    assert np.abs(raw_uncompensated_error).max() > 3e-3  # 45 ppm/°C over 50 °C, and the bias TC


def test_outside_the_valid_range():
    model = model_for()
    lo, hi = model.valid_range_c
    with pytest.raises(ValueError, match=r"temperature_c\[1\] = 90 °C outside the model's valid range"):
        compensate(model, [1.31, 1.31], [25.0, 90.0])
    clamped = compensate(model, [1.31, 1.31], [hi, 90.0], outside="clamp")
    assert clamped.input_estimate[0] == clamped.input_estimate[1]
    assert list(clamped.in_range) == [True, False]
    far = compensate(model, [1.31], [90.0], outside="extrapolate")
    assert far.input_estimate[0] != clamped.input_estimate[1]
    with pytest.raises(ValueError, match="cross_inputs names a_x; the model's cross-axis inputs are a_p"):
        compensate(model, [1.31], 25.0, cross_inputs={"a_x": [0.0]})


def test_verification_on_a_different_profile_is_at_the_noise_level():
    """Calibrate on one sweep, verify on another (different temperatures, new noise): the
    compensated errors are consistent with zero given their uncertainties (χ² over the
    full covariance, p > 0.001 on every quantity), the uncompensated ones are not."""
    model = model_for(seed=3)
    ver = verify_compensation(model, run_points(VERIFY_C, seed=4))
    assert ver.not_verified == ()
    for q in ver.quantities:
        assert q.p_value > 1e-3, (q.name, q.chi2, q.dof)
        assert q.compensated_rms < 3.0 * q.noise_rms, q.name
    bias, sf = ver["k0"], ver["k1"]
    assert bias.error_unit == "g" and sf.error_unit == "ppm"
    assert bias.uncompensated_max_abs > 50 * bias.compensated_rms  # 12 µg/°C over ±45 °C
    assert sf.uncompensated_max_abs > 1000.0  # ppm: 45 ppm/°C over 40 °C
    assert sf.compensated_rms < 10.0  # ppm: SF σ 3 ppm per point


@settings(max_examples=12, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_compensated_residual_over_drawn_noise_stays_at_the_noise_level(seed):
    model = model_for(seed=seed % 1000)
    ver = verify_compensation(model, run_points(VERIFY_C, seed=seed % 1000 + 1000))
    for q in ver.quantities:
        assert q.p_value > 1e-4, (q.name, q.chi2)


def test_hysteresis_shows_as_a_constant_offset_on_a_descending_verification():
    """The sweep went up (the unit on its up branch); a verification descending from the hot
    end finds the bias shifted by −h at every temperature: the compensation cannot hold it."""
    h = 15e-6
    model = model_for(seed=5)
    ver = verify_compensation(model, run_points(VERIFY_C, seed=6, hysteresis_g=-h))
    err = ver["k0"].compensated_error
    assert float(np.mean(err)) == pytest.approx(-h, abs=3e-6)
    assert ver["k0"].p_value < 1e-6


def test_verification_checks_names_roles_and_range():
    model = model_for()
    run = run_points(VERIFY_C, seed=2)
    with pytest.raises(ValueError, match="run quantity 'k9' is not in the model"):
        verify_compensation(model, [QuantityPoints("k9", "bias", "g", [0, 10], [0, 0], [1, 1])])
    with pytest.raises(ValueError, match="k0: role 'k2' in the run, 'bias' in the model"):
        verify_compensation(model, [QuantityPoints("k0", "k2", "g", [0, 10], [0, 0], [1, 1])])
    hot = QuantityPoints("k0", "bias", "g", [0.0, 10.0, 85.0], [0.0, 0.0, 0.0], [1e-6] * 3)
    with pytest.raises(ValueError, match=r"k0.temperature_c\[2\] = 85 °C outside the model's valid range"):
        verify_compensation(model, [hot])
    skipped = verify_compensation(model, [hot], outside="skip")
    assert list(skipped["k0"].skipped_temperatures_c) == [85.0]
    partial = verify_compensation(model, run[:1])
    assert partial.not_verified == ("k1", "k2", "delta_o")
    assert math.isfinite(partial["k0"].chi2)
