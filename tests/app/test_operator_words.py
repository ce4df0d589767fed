"""What the operator page says, without a browser: the spec's labels, units as a person writes
them, numbers to the digits they carry, limits on one line, the products a station tests and
the refusal of a serial in the operator's words, the seed of every batch, and a time-left
estimate that is steady (never up within a batch, never a jump)."""

from __future__ import annotations

import math
import re
import threading

import pytest
from hypothesis import given
from hypothesis import strategies as st

from bench.app.labels import SEED_RANGE
from bench.app.operator.live import LiveBatch
from bench.app.operator.products import Products
from bench.app.operator.server import DRAWN_SEED_BITS, batch_seed
from bench.app.operator.time_left import TAU_S, TimeLeft, next_shown, raw_time_left
from bench.app.wording import limits_text, measurement_row, number_text, plain_name, time_left_text
from bench.core.spec import MAX_LABEL_CHARS, UNITS, SpecError, load_spec, parse_spec, plain_unit
from bench.specs import builtin_specs
from bench.testing.specs import SHORT_ACCEPTANCE_SPEC
from procedures.catalogue import CATALOGUE

SPEC = {
    "unit": {"model": "M", "kind": "accelerometer", "serial_pattern": "M-*"},
    "procedures": {"tumble": {"positions": 8, "planes": 1}},
    "measurements": [{"name": "k0", "procedure": "tumble", "unit": "mg", "low": -4, "high": 4},
                     {"name": "k1", "procedure": "tumble", "unit": "mA/g", "low": 1.2, "high": 1.46,
                      "label": "Scale factor (K1)"}],
}


# -- labels and units from the spec -------------------------------------------------------------
def test_a_label_names_a_measurement_for_the_operator_and_falls_back_to_its_name():
    spec = parse_spec(SPEC, CATALOGUE)
    assert [m.label for m in spec.measurements] == ["k0", "Scale factor (K1)"]
    assert spec.to_dict()["measurements"][1]["label"] == "Scale factor (K1)"  # kept in the record


@pytest.mark.parametrize("label", [42, True, "", "   ", "line one\nline two", "x" * (MAX_LABEL_CHARS + 1),
                                   ["Bias"]])
def test_a_bad_label_is_a_spec_error_naming_the_measurement(label):
    data = {**SPEC, "measurements": [dict(SPEC["measurements"][0], label=label)]}
    with pytest.raises(SpecError, match=r"measurement 'k0': label .* must be text of 1\.\.60"):
        parse_spec(data, CATALOGUE, "unit.toml")


def test_every_shipped_measurement_has_a_label_of_its_own():
    for path in builtin_specs():
        for m in load_spec(path, CATALOGUE).measurements:
            assert m.label != m.name and "_" not in m.label, (path.name, m.name)


@pytest.mark.parametrize("unit", list(UNITS))
def test_every_unit_is_written_as_a_person_reads_it(unit):
    text = plain_unit(unit)
    assert not re.search(r"\^|rt[Hh]|\bu(g|rad)\b|deg", text), text
    assert text.count("/") == unit.count("/")  # the same quotient, only its parts rewritten


def test_plain_units_of_the_engineers_spellings():
    assert [plain_unit(u) for u in ("ug/g^2", "ug/rtHz", "urad", "deg/h", "deg/rth", "ug/degC", "m/s^2")] \
        == ["µg/g²", "µg/√Hz", "µrad", "°/h", "°/√h", "µg/°C", "m/s²"]
    with pytest.raises(ValueError, match="unit 'furlong' unknown"):
        plain_unit("furlong")


# -- numbers and limits -------------------------------------------------------------------------
def _parse(text: str) -> float:
    number, _, power = text.replace("−", "-").partition("×10")
    exponent = power.translate(str.maketrans("⁻⁰¹²³⁴⁵⁶⁷⁸⁹", "-0123456789"))
    return float(number) * (10.0 ** int(exponent) if exponent else 1.0)


finite = st.floats(min_value=-1e9, max_value=1e9, allow_nan=False).filter(lambda v: abs(v) > 1e-12)


@given(finite, st.floats(min_value=1e-9, max_value=1e6))
def test_a_value_carries_the_digits_of_its_uncertainty(value, uncertainty):
    text = number_text(value, "ug", uncertainty)
    decimals = 1 - math.floor(math.log10(uncertainty))  # at its second significant digit
    digits = math.floor(math.log10(abs(value))) + 1 + decimals
    if 1 <= digits <= 4 and "×" not in text:
        assert abs(_parse(text) - value) <= 0.5 * 10.0 ** -decimals * (1 + 1e-9) + 1e-9 * abs(value)
        assert (len(text.split(".")[1]) if "." in text else 0) == max(decimals, 0)
    else:  # one to four significant digits, whatever the uncertainty
        assert abs(_parse(text) - value) <= 0.5 * abs(value)


@given(finite)
def test_a_value_without_uncertainty_has_four_significant_digits(value):
    text = number_text(value, "ug")
    assert abs(_parse(text) - value) <= 5e-4 * abs(value) * (1 + 1e-9)
    mantissa = re.sub(r"×.*$", "", text)
    shown = re.sub(r"^[−0.]*", "", mantissa).replace(".", "")
    if "." in mantissa or "×" in text:
        assert len(shown) == 4
    else:  # a whole number: its trailing zeros hold places (10000 is 1.000×10⁴ read to 4 digits)
        assert len(shown.rstrip("0")) <= 4


def test_counts_are_whole_and_missing_values_a_dash():
    assert number_text(0.0, "readings") == "0" and number_text(3.0, "frames") == "3"
    assert number_text(None, "mg") == number_text(float("nan"), "mg") == "—"
    row = measurement_row({"name": "readings_lost", "value": 0, "unit": "readings", "low": 0, "high": 0,
                           "outcome": "pass", "description": "output readings expected minus stored"}, {})
    assert (row["label"], row["value_text"], row["unit_text"], row["limits_text"]) == \
        ("Readings lost", "0", "readings", "= 0")
    assert plain_name("level_check_g") == "Level check" and plain_name("turn_on") == "Turn on"


def test_limits_on_one_line():
    assert limits_text(-4.0, 4.0) == "−4 … 4"
    assert limits_text(None, 2.2) == "≤ 2.2" and limits_text(1.2, None) == "≥ 1.2"
    assert limits_text(1.2, 1.46) == "1.2 … 1.46" and limits_text(None, None) == ""
    assert "\n" not in limits_text(-1e-7, 1.5e-7)


def test_a_judged_measurement_is_shown_by_its_label_and_plain_unit():
    row = measurement_row({"name": "noise_density", "value": 1.83456, "unit": "ug/rtHz", "low": None,
                           "high": 2.2, "outcome": "pass", "uncertainty": 0.0412}, {"noise_density": "Noise density"})
    assert (row["label"], row["value_text"], row["unit_text"], row["limits_text"]) == \
        ("Noise density", "1.835", "µg/√Hz", "≤ 2.2")
    assert row["uncertainty_text"] == "± 0.04120 µg/√Hz"
    small = measurement_row({"name": "k0", "value": 0.920987, "unit": "mg", "outcome": "pass",
                             "uncertainty": 2e-5}, {})
    assert small["value_text"] == "0.9210"  # four digits at most: the rest is the report's
    spec = parse_spec(SPEC, CATALOGUE)  # k0 has no label: the spec's name for it is its name
    row = measurement_row({"name": "k0", "value": 1.3, "unit": "mg", "outcome": "pass"},
                          {m.name: m.label for m in spec.measurements})
    assert row["label"] == "k0"


# -- products and the refusal of a serial ------------------------------------------------------
def test_an_unknown_serial_is_refused_in_the_operators_words():
    products = Products()
    with pytest.raises(ValueError) as err:
        products.spec_for({1: "QA-SIM-0001", 2: "XQ-17"})
    text = str(err.value)
    assert text.startswith("Serial XQ-17 (socket 2) matches no product this station tests")
    assert "QA-SIM-*" in text and "FOG-SIM-*" in text and "Check the label, or ask the test engineer" in text
    assert "None" not in text and "--" not in text and "spec" not in text.lower()


def test_one_product_per_batch_and_a_served_spec_tests_its_own_serials(tmp_path):
    mixed = r"Socket 2 holds a FOG-T-SIM \(serial FOG-SIM-0001\) but socket 1 a QA-2000-SIM: test one product"
    with pytest.raises(ValueError, match=mixed):
        Products().spec_for({1: "QA-SIM-0001", 2: "FOG-SIM-0001"})
    path = tmp_path / "short.toml"
    path.write_text(SHORT_ACCEPTANCE_SPEC)
    products = Products(str(path))
    assert products.spec_for({3: "QA-SIM-0009"}).model == "QA-2000-SIM"
    with pytest.raises(ValueError, match=r"Serial FOG-SIM-0001 \(socket 1\) matches no product .*"
                                         r"QA-2000-SIM: serials QA-SIM-\*"):
        products.spec_for({1: "FOG-SIM-0001"})


# -- the seed of every batch -------------------------------------------------------------------
def test_every_batch_on_a_simulated_station_has_a_seed():
    assert batch_seed("  17 ", None, {}) == 17 and batch_seed(5, 3, {}) == 5      # the operator's
    assert batch_seed("", 3, {"seed": 9}) == 3 and batch_seed(None, None, {"seed": 9}) == 9
    drawn = {batch_seed("", None, {}) for _ in range(8)}                        # the system's
    assert None not in drawn and len(drawn) > 1                                 # 8 draws of 2**32: all alike < 1e-60
    assert all(0 <= s < 2**DRAWN_SEED_BITS for s in drawn)
    for bad in ("abc", "-1", "1.5", str(SEED_RANGE[1]), True, 2.0):
        with pytest.raises(ValueError, match="must be a whole number from 0 to"):
            batch_seed(bad, None, {})
    assert batch_seed("", 3, None) is None                                      # a real station
    with pytest.raises(ValueError, match="real station, it takes no seed"):
        batch_seed("7", None, None)


# -- the time left ----------------------------------------------------------------------------
def test_the_time_left_in_words():
    assert [time_left_text(s) for s in (None, 0.4, 5.2, 84.0, 95.0, 5340.0, 6732.0)] == \
        ["", "finishing", "about 6 s left", "about 84 s left", "about 2 min left", "about 89 min left",
         "about 1 h 53 min left"]


def test_the_raw_estimate_reads_the_pace_from_the_run():
    assert raw_time_left(10.0, 100.0, 1000.0) == pytest.approx(90.0)        # 0.1 s a planned s
    assert raw_time_left(5.0, 1.0, 1000.0) is None                          # < 1 %: no pace yet
    assert raw_time_left(5.0, 1.0, 1000.0, prior_wall_per_planned=1.0) == 995.0  # a wall clock: the plan
    assert raw_time_left(5.0, 0.0, 0.0) is None


updates = st.lists(st.tuples(st.floats(0.0, 30.0), st.floats(0.0, 1e4)), min_size=1, max_size=60)


@given(st.floats(0.0, 1e4), updates)
def test_the_shown_estimate_never_rises_and_never_jumps(start, steps):
    shown = start
    for dt, raw in steps:
        after = next_shown(shown, dt, raw)
        assert 0.0 <= after <= shown
        assert shown - after <= dt + (1 - math.exp(-dt / TAU_S)) * shown + 1e-9
        shown = after


def test_the_issues_84_s_then_5_s_is_a_steady_count_down():
    # shown 84 s; 1.2 s later the raw estimate says 5 s: the page moves by a tenth of the gap
    assert next_shown(84.0, 1.2, 5.0) > 84.0 - 1.2 - 0.12 * (84.0 - 1.2 - 5.0)
    assert next_shown(84.0, 1.2, 5.0) > 70.0


@given(st.floats(0.01, 10.0), st.floats(60.0, 1e4), st.sampled_from([1.0, 30.0, 300.0]))
def test_at_a_steady_pace_the_estimate_is_the_truth_and_counts_down_between_reports(pace, total, every):
    # wall = pace × planned; progress reported every `every` planned seconds
    estimate = TimeLeft(None)
    for k in range(0, 60):
        wall = k * every * pace / 4
        done = min(math.floor(wall / pace / every) * every, total)
        estimate.report(done * pace, done, total)
        shown = estimate.at(wall)
        if done >= 0.01 * total and done < total:
            assert shown == pytest.approx(max(total * pace - wall, 0.0), rel=1e-6, abs=1e-6)


def test_a_retest_starts_a_new_estimate_and_a_prompt_is_not_the_stations_pace():
    now = [0.0]
    live = LiveBatch(clock=lambda: now[0])
    live.begin("Ann", "QA-2000-SIM", {1: "QA-SIM-0001"}, [("turn_on", 100.0)], seed=5,
               wall_per_planned_s=1.0)
    live.running()
    assert live.snapshot()["time_left"] == "about 2 min left" and live.snapshot()["seed_text"] == "5"
    seen = []
    for t in range(1, 60):
        now[0] = float(t)
        if t % 10 == 0:
            live.progress(t, 100.0, "turn_on")
        seen.append(live.snapshot()["wall_left_s"])
    assert all(b <= a for a, b in zip(seen, seen[1:]))
    assert seen[-1] == pytest.approx(100.0 - 59.0, abs=1.0)
    live.begin("Ann", "QA-2000-SIM", {1: "QA-SIM-0001"}, [("turn_on", 100.0)], wall_per_planned_s=1.0)
    live.running()
    assert live.snapshot()["wall_left_s"] == pytest.approx(100.0)  # up again: a new batch
    now[0] += 20.0
    live.progress(20.0, 100.0)
    answers: list[bool] = []
    asking = threading.Thread(target=lambda: answers.append(live.ask("Close the cover")),
                              daemon=True)
    asking.start()
    while not live.snapshot()["prompt"]:
        asking.join(0.01)
    now[0] += 1000.0  # the operator takes a while: the estimate holds, the pace is not changed
    assert live.snapshot()["wall_left_s"] == pytest.approx(80.0)
    live.answer(True)
    asking.join(5)
    now[0] += 1.0  # one second of the station's own time after the answer
    live.progress(21.0, 100.0)
    assert answers == [True] and live.snapshot()["wall_left_s"] == pytest.approx(79.0)


def test_a_bound_is_written_as_one():
    row = measurement_row({"name": "turn_on_time", "value": 125.0, "unit": "s", "uncertainty": None,
                           "low": None, "high": 600.0, "bound": "upper"}, {})
    assert row["value_text"] == "≤ 125.0"
    assert measurement_row({"name": "x", "value": 2.0, "unit": "s", "bound": "lower"}, {})["value_text"] == "≥ 2.000"
    assert not measurement_row({"name": "x", "value": 2.0, "unit": "s"}, {})["value_text"].startswith(("≤", "≥"))
