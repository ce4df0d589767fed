"""Gyro rate-table calibration and acceptance end to end on the simulated station: frames
over the serial line, whole revolutions per rate, IEEE 952 figures against the truth."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import Phase, given, settings
from hypothesis import strategies as st

from bench.analysis.ratetable import fit_rate_table
from bench.app.cli import main
from bench.app.station import Station, builtin_sim_config
from bench.core.procedure import execute
from bench.core.spec import parse_spec
from bench.core.store import RunStore
from procedures.acceptance import AcceptanceTest
from procedures.catalogue import CATALOGUE
from procedures.running import alone
from procedures.turn_on import GyroTurnOnTest
from sim.physics.gyro import indicated_rate_dps

RATETABLE = {"rates_per_sign": 4, "min_record_s": 10.0, "warmup_s": 300.0, "frame_rate_hz": 500}
SPEC = {
    "unit": {"model": "FOG-TEST", "kind": "gyro", "serial_pattern": "FOG-SIM-*"},
    "procedures": {"ratetable": RATETABLE},
    "measurements": [
        {"name": "scale_factor_error", "procedure": "ratetable", "unit": "ppm", "low": -500, "high": 500},
        {"name": "asymmetry", "procedure": "ratetable", "unit": "ppm", "low": -100, "high": 100},
        {"name": "nonlinearity", "procedure": "ratetable", "unit": "ppm", "high": 60},
        {"name": "bias", "procedure": "ratetable", "unit": "deg/h", "low": -3, "high": 3},
    ],
}


def run_acceptance(tmp_path, serial, overrides=None, seed=2):
    config = builtin_sim_config()
    config.simulation = {"gyro": overrides or {}}
    store = RunStore(tmp_path / f"{serial}.sqlite")
    with Station(config, seed=seed, unit_serial=serial, unit_kind="gyro") as station:
        outcome = execute(AcceptanceTest(parse_spec(SPEC, CATALOGUE)), station, store,
                          unit_serial=serial, seed=seed)
        params = station.sim.gyro.params
        safe = ([ch.output for ch in station.sim.supply.channels.values()],
                [float(a.rate_dps(station.sim.world.now)) for a in station.sim.table.axes],
                station.sim.table.inner.rate_limit_dps)
    return store, outcome, params, safe


@settings(max_examples=3, deadline=None, phases=[Phase.explicit, Phase.generate])
@given(eps=st.floats(-400, 400), asym=st.floats(-80, 80), cubic=st.floats(-90, 90),
       outside=st.sampled_from(["", "scale_factor_error", "asymmetry"]))
def test_rate_table_recovers_the_unit_and_judges_it(tmp_path_factory, eps, asym, cubic, outside):
    # the scale factor's temperature terms off: the rate-table reduction is judged on the room model
    overrides = {"scale_factor_error_ppm": eps, "asymmetry_ppm": asym, "nonlinearity_ppm": cubic,
                 "sf_tc_ppm_per_c": 0.0, "sf_tc2_ppm_per_c2": 0.0, "sf_tc3_ppm_per_c3": 0.0}
    overrides.update({"scale_factor_error": {"scale_factor_error_ppm": 800.0},
                      "asymmetry": {"asymmetry_ppm": -160.0}, "": {}}[outside])
    store, outcome, params, safe = run_acceptance(tmp_path_factory.mktemp("g"), "FOG-SIM-0100", overrides)
    assert outcome.status in ("passed", "failed"), outcome.reason
    # truth: the same IEEE 952 reduction of the noiseless model at the rates that were run
    rows = store.load(outcome.run_id, "ratetable")
    w = rows["input_rate_dps"]
    truth = fit_rate_table(w, indicated_rate_dps(params, w), np.ones(w.size),
                           full_scale_dps=params.full_scale_dps)
    by_name = {m.name: m for m in outcome.measurements}
    for name, key in (("scale_factor_error", "scale_factor_error_ppm"), ("asymmetry", "asymmetry_ppm"),
                      ("nonlinearity", "nonlinearity_ppm")):
        m, expected = by_name[name], getattr(truth, key).value
        assert abs(m.value - expected) < 4 * m.uncertainty + 0.05, (name, m.value, expected, m.uncertainty)
    assert store.results(outcome.run_id)["ratetable.fit"]["latitude_deg"] == 32.06  # the site's
    failed = {m.name for m in outcome.measurements if m.outcome == "fail"}
    assert failed == ({outside} if outside else set())
    assert safe[0] == [False, False, False]  # supply off
    assert max(abs(r) for r in safe[1]) < 0.05  # table at rest (servo settling left)
    assert safe[2] == 30.0  # the user rate limit the calibration raised is put back
    frames = store.load(outcome.run_id, "ratetable_frames")
    assert frames["t_s"].size == int(rows["frames"].sum())  # every frame kept


def test_gyro_acceptance_cli_json_and_report(tmp_path, capsys):
    spec = tmp_path / "fog.toml"
    spec.write_text(
        '[unit]\nmodel = "FOG-TEST"\nkind = "gyro"\nserial_pattern = "FOG-SIM-*"\n'
        "[procedures.ratetable]\nrates_per_sign = 3\nmin_record_s = 5.0\nwarmup_s = 60.0\n"
        "frame_rate_hz = 200\n"
        '[[measurements]]\nname = "scale_factor_error"\nprocedure = "ratetable"\nunit = "%"\n'
        "low = -0.05\nhigh = 0.05\n")
    code = main(["--store", str(tmp_path / "b.sqlite"), "acceptance", "--unit", "FOG-SIM-0002",
                 "--spec", str(spec), "--json", "--report", str(tmp_path / "rep")])
    doc = json.loads(capsys.readouterr().out)
    assert code == 0 and doc["verdict"] == "PASS" and doc["kind"] == "gyro"
    (m,) = doc["measurements"]
    assert m["unit"] == "%" and abs(m["value"]) < 0.05
    assert (tmp_path / "rep" / doc["run_id"] / "acceptance_ratetable.png").stat().st_size > 10_000


def test_a_gyro_spec_refuses_accelerometer_steps():
    bad = dict(SPEC, procedures={"tumble": {}})
    with pytest.raises(ValueError, match="applies to \\['accelerometer'\\], not to a gyro"):
        parse_spec(bad, CATALOGUE)


def test_gyro_start_up_turn_on_time_and_warm_up_drift(tmp_path):
    """A unit with a clear warm-up: turn-on time = boot + the exponential's time into the band
    (+ about half the averaging window); the drift is the warm-up's change over the record."""
    amp, tau, band, smooth = 20.0, 200.0, 3.0, 120.0  # band ≫ the 120-s noise (ARW, flicker)
    config = builtin_sim_config()
    # slow terms quiet (flicker, RRW, thermal bias), so the warm-up is what the test sees
    config.simulation = {"gyro": {"warmup_amplitude_dph": amp, "warmup_tau_s": tau,
                                  "bias_instability_dph": 0.02, "rrw_dph_per_rh": 0.002,
                                  "bias_tc_dph_per_c": 0.0}}
    store = RunStore(tmp_path / "b.sqlite")
    step = GyroTurnOnTest(duration_s=2400.0, off_wait_s=60.0, band_dph=band, smooth_s=smooth,
                          settled_window_s=600.0)
    with Station(config, seed=4, unit_serial="FOG-SIM-0003", unit_kind="gyro") as station:
        outcome = execute(alone(step), station, store, unit_serial="FOG-SIM-0003", seed=4)
        truth = station.sim.gyro_truth()
    assert outcome.status == "passed", outcome.reason
    m = {x.name: x for x in outcome.measurements}
    expected = truth["boot_time_s"] + tau * math.log(amp / band)
    assert expected - 10 < m["turn_on_time"].value < expected + smooth, (m["turn_on_time"].value, expected)
    assert m["turn_on_time"].bound is None  # measured: the average left the band first
    first = store.results(outcome.run_id)["gyro_startup.turn_on"]["first_valid_s"]
    drift = amp * (math.exp(-2400.0 / tau) - math.exp(-max(first, smooth) / tau))
    assert abs(m["warmup_drift"].value - drift) < 0.15 * abs(drift) + 4 * m["warmup_drift"].uncertainty


def test_a_unit_in_the_band_from_the_first_average_has_an_upper_bound_for_its_turn_on_time(tmp_path, capsys):
    """A warm-up smaller than the band: the output is inside it at the first full average, so
    the turn-on time is only an upper bound (the first average's time) — stored as such and
    printed "≤" by `bench runs show`."""
    config = builtin_sim_config()
    config.simulation = {"gyro": {"warmup_amplitude_dph": 0.5, "warmup_tau_s": 100.0,
                                  "bias_instability_dph": 0.02, "rrw_dph_per_rh": 0.002,
                                  "bias_tc_dph_per_c": 0.0}}
    store = RunStore(tmp_path / "b.sqlite")
    step = GyroTurnOnTest(duration_s=900.0, off_wait_s=30.0, band_dph=3.0, smooth_s=60.0,
                          settled_window_s=300.0)
    with Station(config, seed=5, unit_serial="FOG-SIM-0003", unit_kind="gyro") as station:
        outcome = execute(alone(step), station, store, unit_serial="FOG-SIM-0003", seed=5)
    assert outcome.status == "passed", outcome.reason
    m = {x.name: x for x in outcome.measurements}
    r = store.results(outcome.run_id)["gyro_startup.turn_on"]
    assert r["resolved"] is False and m["turn_on_time"].bound == "upper"
    assert m["turn_on_time"].value == pytest.approx(r["turn_on_time_s"])
    assert store.results(outcome.run_id)["measurement.turn_on_time"]["bound"] == "upper"
    store.close()
    assert main(["--store", str(tmp_path / "b.sqlite"), "runs", "show", outcome.run_id]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.strip().startswith("turn_on_time"))
    assert f"≤{m['turn_on_time'].value:.6g}" in line.replace(" ", ""), line
