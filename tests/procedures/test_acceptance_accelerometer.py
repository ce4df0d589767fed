"""Acceptance of simulated accelerometers end to end: spec → steps → station → store →
verdict → report; calibration recovers the simulated truth within its stated uncertainty."""

from __future__ import annotations

import json

import pytest
from hypothesis import Phase, given, settings
from hypothesis import strategies as st

from bench.app.cli import main
from bench.app.station import Station, builtin_sim_config
from bench.core.procedure import execute
from bench.core.spec import parse_spec
from bench.core.store import RunStore
from bench.core.store.central import spec_identity
from bench.core.store.forward import package
from bench.testing.reports import assert_pdf, assert_self_contained, assert_signable
from procedures.acceptance import AcceptanceTest
from procedures.catalogue import CATALOGUE
from procedures.running import alone
from procedures.tumble import TumbleCalibration

SHORT_SPEC = """
[unit]
model = "QA-TEST"
kind = "accelerometer"
serial_pattern = "QA-SIM-*"

[procedures.turn_on]
duration_s = 400.0
rate_hz = 10.0
off_wait_s = 0.0
settled_window_s = 100.0

[procedures.tumble]
positions = 8
planes = 2
warmup_s = 60.0
settle_s = 2.0
average_s = 4.0

[[measurements]]
name = "k0"
procedure = "tumble"
unit = "mg"
low = -4.0
high = 4.0

[[measurements]]
name = "k1"
procedure = "tumble"
unit = "mA/g"
low = 1.2
high = 1.46

[[measurements]]
name = "turn_on_time"
procedure = "turn_on"
unit = "s"
high = 390.0
"""


@pytest.fixture
def spec_file(tmp_path):
    path = tmp_path / "spec.toml"
    path.write_text(SHORT_SPEC)
    return path


def test_a_unit_inside_its_spec_passes_with_record_and_report(tmp_path, spec_file, capsys):
    store = str(tmp_path / "b.sqlite")
    code = main(["--store", store, "acceptance", "--unit", "QA-SIM-0002", "--spec", str(spec_file),
                 "--seed", "3", "--json", "--report", str(tmp_path / "rep")])
    doc = json.loads(capsys.readouterr().out)
    assert code == 0 and doc["verdict"] == "PASS" and doc["status"] == "passed"
    names = [m["name"] for m in doc["measurements"]]
    assert {"k0", "k1", "turn_on_time"} <= set(names)
    k1 = next(m for m in doc["measurements"] if m["name"] == "k1")
    assert 0 < k1["uncertainty"] < 1e-3 and k1["unit"] == "mA/g"
    report = tmp_path / "rep" / doc["run_id"]
    html = (report / "acceptance_report.html").read_text()
    assert "QA-SIM-0002" in html and assert_self_contained(html, figures=2)
    # what a signature needs: the spec by its content's SHA-256, an approval block, the record's digest
    with RunStore(store) as s:
        spec = s.results(doc["run_id"])["acceptance.spec"]
        digest = package(s, doc["run_id"]).digest
    assert spec_identity(spec)[0] in html and str(spec_file) not in html  # the spec by name, not its path
    assert_signable(html, digest)
    # the PDF beside it: its pages render and its text names the unit, the spec's hash and the digest
    assert_pdf(report / "acceptance_report.pdf", pages=2,
               text=["QA-SIM-0002", spec_identity(spec)[0], digest, "reviewed by"])
    assert (report / "acceptance_tumble.png").stat().st_size > 10_000
    with RunStore(store) as s:
        assert {"output", "temperature", "tumble"} <= set(s.streams(doc["run_id"]))
        assert any(a.name == "analysis/acceptance/acceptance_report.html"
                   for a in s.attachments(doc["run_id"]))
    assert main(["--store", store, "runs", "show", doc["run_id"], "--json"]) == 0
    shown = json.loads(capsys.readouterr().out)
    assert shown["digest"] == digest  # a printed report is matched to the stored run by it
    assert shown["verdict"] == "PASS" and len(shown["measurements"]) == len(names)


def test_a_unit_clearly_outside_fails_exit_1(tmp_path, spec_file, capsys):
    station = tmp_path / "st.toml"
    station.write_text("[simulation]\nseed = 4\n[simulation.accelerometer]\nk0_g = 0.008\n")
    code = main(["--store", str(tmp_path / "b.sqlite"), "acceptance", "--unit", "QA-SIM-0002",
                 "--spec", str(spec_file), "--station", str(station), "--json",
                 "--report", str(tmp_path / "rep")])
    doc = json.loads(capsys.readouterr().out)
    assert code == 1 and doc["verdict"] == "FAIL" and "k0" in doc["reason"]
    k0 = next(m for m in doc["measurements"] if m["name"] == "k0")
    assert k0["outcome"] == "fail" and k0["value"] == pytest.approx(8.0, abs=0.2)


def test_bad_arguments_exit_2_with_one_line(tmp_path, capsys):
    assert main(["--store", str(tmp_path / "b.sqlite"), "acceptance", "--unit", "ZZ-1"]) == 2
    assert "no built-in spec matches unit 'ZZ-1'" in capsys.readouterr().err
    assert main(["--store", str(tmp_path / "b.sqlite"), "acceptance", "--spec",
                 str(tmp_path / "none.toml")]) == 2
    assert "not found" in capsys.readouterr().err


TUMBLE_ONLY = {
    "unit": {"model": "QA-TEST", "kind": "accelerometer"},
    "procedures": {"tumble": {"positions": 8, "planes": 2, "warmup_s": 3000.0, "settle_s": 2.0,
                              "average_s": 5.0}},
    "measurements": [{"name": n, "procedure": "tumble", "unit": u, "low": lo, "high": hi}
                     for n, u, lo, hi in (("k0", "mg", -4, 4), ("k1", "mA/g", 1.2, 1.46),
                                          ("k2", "ug/g^2", -20, 20), ("delta_o", "urad", -70, 70),
                                          ("delta_p", "urad", -70, 70))],
}
#: the scale factor's temperature terms off: these tests judge the room-temperature calibration
#: (the thermal series judges the rest); the self-heated element would move K1 by s₁·ΔT
NO_THERMAL_SCALE_FACTOR = {"sf_tc_ppm_per_c": 0.0, "sf_tc2_ppm_per_c2": 0.0, "sf_tc3_ppm_per_c3": 0.0}
PARAM = {"k0": ("k0_g", 1e3), "k1": ("k1_ma_per_g", 1.0), "k2": ("k2_g_per_g2", 1e6),
         "delta_o": ("delta_o_rad", 1e6), "delta_p": ("delta_p_rad", 1e6)}


# no shrinking: each draw is a whole station run
@settings(max_examples=4, deadline=None, phases=[Phase.explicit, Phase.generate])
@given(k0=st.floats(-3e-3, 3e-3), k1=st.floats(1.25, 1.41), k2=st.floats(-15e-6, 15e-6),
       delta=st.floats(-60e-6, 60e-6), outside=st.sampled_from(["", "k0", "k1", "k2"]))
def test_tumble_recovers_drawn_units_and_judges_them(tmp_path_factory, k0, k1, k2, delta, outside):
    """Inside the spec → pass; one parameter clearly outside → that one fails; every estimate
    within 4 stated standard errors of the truth (the bias as the unit has it when warm)."""
    overrides = {"k0_g": k0, "k1_ma_per_g": k1, "k2_g_per_g2": k2, "delta_o_rad": delta,
                 "delta_p_rad": -delta, **NO_THERMAL_SCALE_FACTOR}
    overrides.update({"k0": {"k0_g": 6e-3}, "k1": {"k1_ma_per_g": 1.55},
                      "k2": {"k2_g_per_g2": 40e-6}, "": {}}[outside])
    config = builtin_sim_config()
    config.simulation = {"accelerometer": overrides}
    store = RunStore(tmp_path_factory.mktemp("acc") / "b.sqlite")
    spec = parse_spec(TUMBLE_ONLY, CATALOGUE)
    with Station(config, seed=5, unit_serial="QA-SIM-0100") as station:
        outcome = execute(AcceptanceTest(spec), station, store, unit_serial="QA-SIM-0100", seed=5)
        truth = station.sim.truth()
        t_tumble = store.load(outcome.run_id, "tumble")["t_s"]  # bench clock = sim time
        # the bias a warm unit shows: K0 + what is left of the warm-up + drift + its turn-on bias +
        # the thermal terms of its self-heated element (the model's truth over the tumble)
        warm_bias = float(station.sim.accel.bias_truth_g(t_tumble).mean())
    truth["k0_g"] += warm_bias
    by_name = {m.name: m for m in outcome.measurements}
    for name, (key, scale) in PARAM.items():
        m = by_name[name]
        z = (m.value - truth[key] * scale) / m.uncertainty
        assert abs(z) < 4.0, (name, m.value, truth[key] * scale, m.uncertainty)
    expected_fail = {outside} if outside else set()
    assert {m.name for m in outcome.measurements if m.outcome == "fail"} == expected_fail
    assert outcome.status == ("failed" if outside else "passed")


def test_noiseless_unit_on_ideal_meters_calibrates_exactly_through_the_whole_station(tmp_path):
    """Issue 6: K0, K1, K2, K3 and δ to 1e-9 relative — here end to end (table geometry,
    local gravity, mount, sampling resistor, DMM, wire, fit), not only in the estimator."""
    quiet = {"white_density_g_per_rthz": 0.0, "gm_sigma_g": (), "gm_tau_s": (),
             "warmup_amplitude_g": 0.0, "drift_g_per_s": 0.0, "bias_tc_g_per_c": 0.0,
             "k3_g_per_g3": 3e-6, "kip_g_per_g2": 4e-6, "kio_g_per_g2": -6e-6,
             # and the thermal terms of the drawn unit (issue 14)
             "bias_tc2_g_per_c2": 0.0, "bias_tc3_g_per_c3": 0.0, "bias_hysteresis_g": 0.0,
             "bias_gradient_g_per_c": 0.0, "bias_repeatability_g": 0.0, **NO_THERMAL_SCALE_FACTOR}
    config = builtin_sim_config()
    config.simulation = {"ideal_meters": True, "line_pickup_v": 0.0, "accelerometer": quiet}
    store = RunStore(tmp_path / "b.sqlite")
    step = TumbleCalibration(positions=12, planes=2, warmup_s=10.0, settle_s=5.0, average_s=2.0)
    with Station(config, seed=1, unit_serial="QA-SIM-0009") as station:
        outcome = execute(alone(step), station, store, unit_serial="QA-SIM-0009", seed=1)
        truth = station.sim.truth()
    assert outcome.status == "passed", outcome.reason
    by_name = {m.name: m.value for m in outcome.measurements}
    for name, key in (("k0", "k0_g"), ("k1", "k1_ma_per_g"), ("k2", "k2_g_per_g2"),
                      ("k3", "k3_g_per_g3"), ("delta_o", "delta_o_rad"), ("delta_p", "delta_p_rad"),
                      ("kip", "kip_g_per_g2"), ("kio", "kio_g_per_g2")):
        assert by_name[name] == pytest.approx(truth[key], rel=1e-9), name


def test_noise_after_the_tumble_is_measured_level_and_the_site_reaches_the_steps(tmp_path):
    """The noise step sets its own orientation (after a tumble that ends tilted), and a
    station's site (here 39.9° N, 44 m) gives the tumble its gravity."""
    spec = parse_spec({
        "unit": {"model": "QA-TEST", "kind": "accelerometer"},
        "procedures": {"tumble": {"positions": 8, "planes": 2, "warmup_s": 600.0, "settle_s": 2.0,
                                  "average_s": 4.0},
                       "accelerometer_noise": {"duration_s": 900.0, "warmup_s": 0.0}},
        "measurements": [
            {"name": "k1", "procedure": "tumble", "unit": "mA/g", "low": 1.2, "high": 1.46},
            {"name": "noise_density", "procedure": "accelerometer_noise", "unit": "ug/rtHz", "high": 2.2}],
    }, CATALOGUE)
    config = builtin_sim_config()
    config.simulation = {"latitude_deg": 39.9, "height_m": 44.0, "accelerometer": NO_THERMAL_SCALE_FACTOR}
    config.site = {"latitude_deg": 39.9, "height_m": 44.0}
    store = RunStore(tmp_path / "b.sqlite")
    with Station(config, seed=2, unit_serial="QA-SIM-0003") as station:
        outcome = execute(AcceptanceTest(spec), station, store, unit_serial="QA-SIM-0003", seed=2)
        truth = station.sim.truth()
    assert outcome.status == "passed", outcome.reason
    m = {x.name: x for x in outcome.measurements}
    assert abs(m["k1"].value - truth["k1_ma_per_g"]) < 4 * m["k1"].uncertainty
    fit = store.results(outcome.run_id)["tumble.fit"]
    assert fit["g_mps2"] == pytest.approx(truth["g_mps2"], rel=1e-9)
    # one-sided density; the level record reads the truth within the DMM's few per cent
    expected = truth["white_density_g_per_rthz"] * 1e6
    assert expected * 0.95 < m["noise_density"].value < expected * 1.12


def test_a_measurement_not_produced_is_null_in_json_and_fails(tmp_path, capsys):
    spec = tmp_path / "s.toml"
    spec.write_text('[unit]\nmodel = "QA-TEST"\nkind = "accelerometer"\n'
                    "[procedures.turn_on]\nduration_s = 300.0\nrate_hz = 10.0\noff_wait_s = 0.0\n"
                    "settled_window_s = 60.0\n"
                    '[[measurements]]\nname = "turn_on_time"\nprocedure = "turn_on"\nunit = "s"\n'
                    "high = 900.0\n")
    station = tmp_path / "st.toml"  # the fixture's resistor is not the one the wiring states
    station.write_text("[simulation]\nsampling_resistor_ohm = 2500.0\n")
    code = main(["--store", str(tmp_path / "b.sqlite"), "acceptance", "--unit", "QA-SIM-0002",
                 "--spec", str(spec), "--station", str(station), "--json",
                 "--report", str(tmp_path / "rep")])
    doc = json.loads(capsys.readouterr().out)  # valid JSON: no NaN
    assert code == 1 and doc["verdict"] == "FAIL"
    turn_on = next(m for m in doc["measurements"] if m["name"] == "turn_on_time")
    assert turn_on["value"] is None and turn_on["outcome"] == "fail"
