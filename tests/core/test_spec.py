"""Unit specs: parsed completely before anything runs; every mistake named."""

from __future__ import annotations

import re

import pytest
from hypothesis import given
from hypothesis import strategies as st

from bench.core.spec import UNITS, SpecError, convert, load_spec, parse_spec
from bench.specs import builtin_specs
from procedures.catalogue import CATALOGUE

GOOD = {
    "unit": {"model": "M", "kind": "accelerometer", "serial_pattern": "M-*"},
    "procedures": {"tumble": {"positions": 8, "planes": 1}},
    "measurements": [{"name": "k0", "procedure": "tumble", "unit": "mg", "low": -4, "high": 4,
                      "marginal": 0.4}],
}


def spec_with(**changes):
    data = {k: (dict(v) if isinstance(v, dict) else [dict(m) for m in v]) for k, v in GOOD.items()}
    for path, value in changes.items():
        table, key = path.split("__")
        target = data[table][0] if table == "measurements" else data[table]
        if value is None:
            target.pop(key)
        else:
            target[key] = value
    return data


def test_builtin_specs_parse_and_match_their_serials():
    specs = [load_spec(p, CATALOGUE) for p in builtin_specs()]
    assert specs and all(s.measurements for s in specs)
    assert any(s.applies_to("QA-SIM-0001") and s.kind == "accelerometer" for s in specs)


def test_a_good_spec():
    spec = parse_spec(GOOD, CATALOGUE)
    assert spec.kind == "accelerometer" and list(spec.procedures) == ["tumble"]
    (m,) = spec.for_procedure("tumble")
    assert (m.name, m.unit, m.low, m.high, m.marginal) == ("k0", "mg", -4, 4, 0.4)
    assert m.description == "bias K0"  # from the catalogue when the spec gives none
    assert spec.applies_to("M-17") and not spec.applies_to("X-17")


@pytest.mark.parametrize("changes,message", [
    ({"unit__kind": "barometer"}, "kind = 'barometer' not in"),
    ({"unit__model": None}, "'model'"),
    ({"measurements__name": "k9"}, "produces"),
    ({"measurements__unit": "deg/h"}, "unit 'deg/h' not in"),
    ({"measurements__unit": "furlong"}, "unit 'furlong' not in"),
    ({"measurements__low": 5}, "low = 5.0 must be < high"),
    ({"measurements__marginal": 5}, "marginal = 5.0 not in"),
    ({"measurements__low": None, "measurements__high": None}, "needs 'low', 'high'"),
    ({"measurements__procedure": "ratetable"}, "not among this spec's"),
    ({"measurements__high": float("nan")}, "finite number"),
    ({"procedures__tumble": {"positions": 6}}, "multiple of 4"),
    ({"procedures__tumble": {"positionz": 8}}, "positionz"),
    ({"procedures__shake": {}}, "unknown procedure"),
])
def test_bad_specs_are_named(changes, message):
    with pytest.raises(SpecError, match=message):
        parse_spec(spec_with(**changes), CATALOGUE, "x.toml")


def test_no_measurements_is_refused():
    data = spec_with()
    data["measurements"] = []
    with pytest.raises(SpecError, match="nothing to judge"):
        parse_spec(data, CATALOGUE)


def test_missing_and_invalid_files(tmp_path):
    with pytest.raises(SpecError, match="not found"):
        load_spec(tmp_path / "none.toml", CATALOGUE)
    bad = tmp_path / "bad.toml"
    bad.write_text("[unit\n")
    with pytest.raises(SpecError, match="not valid TOML"):
        load_spec(bad, CATALOGUE)


@given(st.sampled_from(sorted(UNITS)), st.floats(-1e6, 1e6, allow_nan=False))
def test_conversion_round_trips_within_a_dimension(unit, value):
    dim = UNITS[unit][0]
    for other, (d, _) in UNITS.items():
        if d == dim:
            assert convert(convert(value, unit, other), other, unit) == pytest.approx(value, rel=1e-12, abs=1e-300)


def test_conversions_are_right_and_dimensions_checked():
    assert convert(1.0, "g", "ug") == pytest.approx(1e6)
    assert convert(1.0, "deg/s", "deg/h") == 3600
    assert convert(60.0, "deg/h/rtHz", "deg/rth") == pytest.approx(1.0)
    with pytest.raises(ValueError, match="cannot convert"):
        convert(1.0, "g", "s")


def test_a_plan_that_cannot_identify_a_term_is_refused():
    data = spec_with(measurements__name="k3", procedures__tumble={"positions": 4, "planes": 1},
                     measurements__unit="ug/g^3")
    with pytest.raises(SpecError, match="cannot produce it"):
        parse_spec(data, CATALOGUE)
    data = spec_with(measurements__name="delta_o", measurements__unit="urad")  # one plane: no a_p
    with pytest.raises(SpecError, match="cannot produce it"):
        parse_spec(data, CATALOGUE)


def test_unknown_unit_keys_and_parameters_are_named():
    with pytest.raises(SpecError, match="serial-pattern"):
        parse_spec(spec_with(**{"unit__serial-pattern": "M-*"}), CATALOGUE)
    with pytest.raises(SpecError, match="allowed: \\['positions'"):
        parse_spec(spec_with(procedures__tumble={"bogus": 1}), CATALOGUE)


@pytest.mark.parametrize("unit,base,factor", [
    ("mg", "g", 1e-3), ("ug", "g", 1e-6), ("m/s^2", "g", 1 / 9.80665), ("A/g", "mA/g", 1e3),
    ("ug/g^2", "g/g^2", 1e-6), ("ug/g^3", "g/g^3", 1e-6), ("mrad", "rad", 1e-3),
    ("urad", "rad", 1e-6), ("deg", "rad", 0.017453292519943295), ("arcsec", "rad", 4.84813681109536e-06),
    ("deg/s", "deg/h", 3600.0), ("%", "ppm", 1e4), ("min", "s", 60.0), ("ug/rtHz", "g/rtHz", 1e-6),
    ("deg/h/rtHz", "deg/rth", 1 / 60),
])
def test_every_unit_factor_is_pinned(unit, base, factor):
    assert convert(1.0, unit, base) == pytest.approx(factor, rel=1e-12)


TURN_ON = {"unit": {"model": "M", "kind": "accelerometer"},
           "procedures": {"turn_on": {"duration_s": 600.0}},
           "measurements": [{"name": "turn_on_time", "procedure": "turn_on", "unit": "s", "high": 900.0}]}


def test_a_spec_written_with_the_turn_on_tests_old_names_is_told_the_new_ones():
    assert parse_spec(TURN_ON, CATALOGUE).procedures == {"turn_on": {"duration_s": 600.0}}
    old = {**TURN_ON, "procedures": {"startup": {"duration_s": 600.0, "band_g": 2e-5}},
           "measurements": [{**TURN_ON["measurements"][0], "procedure": "startup"}]}
    # 'startup' is Document A's acquisition now: nothing a spec can judge; the test is 'turn_on'
    with pytest.raises(SpecError, match=r"\[procedures.startup\]: 'startup' produces no measurement "
                                        r"a spec can judge \(the step once named 'startup' is now 'turn_on'\)"):
        parse_spec(old, CATALOGUE, "old.toml")
    gyro = {"unit": {"model": "G", "kind": "gyro"}, "procedures": {"gyro_startup": {}},
            "measurements": [{"name": "turn_on_time", "procedure": "gyro_startup", "unit": "s", "high": 600.0}]}
    with pytest.raises(SpecError, match=r"\[procedures.gyro_startup\]: renamed 'gyro_turn_on'"):
        parse_spec(gyro, CATALOGUE)
    mixed = {**TURN_ON, "measurements": [{**TURN_ON["measurements"][0], "procedure": "gyro_startup"}]}
    with pytest.raises(SpecError, match="not among this spec's .* is now 'gyro_turn_on'"):
        parse_spec(mixed, CATALOGUE)


def test_a_step_of_another_sensor_kind_is_refused():
    data = spec_with(procedures__frf={})
    with pytest.raises(SpecError, match=r"\[procedures.frf\]: applies to \['angular'\], not to a accelerometer"):
        parse_spec(data, CATALOGUE)


def test_operator_prompts_before_a_procedure_are_parsed_and_every_mistake_named():
    data = {**GOOD, "prompts": [{"before": "tumble", "text": " Remove the shipping clamp "}]}
    spec = parse_spec(data, CATALOGUE)
    assert spec.prompts == {"tumble": "Remove the shipping clamp"}
    assert spec.to_dict()["prompts"] == [{"before": "tumble", "text": "Remove the shipping clamp"}]
    assert "prompts" not in parse_spec(GOOD, CATALOGUE).to_dict()  # records without prompts unchanged
    for prompts, message in [
        ([{"before": "ratetable", "text": "x"}], "before = 'ratetable' is not among this spec's"),
        ([{"before": "tumble"}], "prompt text None must be non-empty"),
        ([{"before": "tumble", "text": "a\nb"}], "1..200 printable characters on one line"),
        ([{"before": "tumble", "text": "x" * 201}], "got 201"),
        ([{"before": "tumble", "text": "x"}, {"before": "tumble", "text": "y"}], "a second prompt"),
        ([{"before": "tumble", "text": "x", "when": 1}], "unknown key(s) ['when']"),
        ({"before": "tumble"}, "must be [[prompts]] tables"),
    ]:
        with pytest.raises(SpecError, match=re.escape(message)):
            parse_spec({**GOOD, "prompts": prompts}, CATALOGUE)
