"""``bench discover --run``: every mappable stored stream becomes the right record; gaps, stream
choice and unmappable runs are handled (bench.app.commands.discover_runs)."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

from bench.app.cli import main
from bench.app.commands.discover_runs import longest_stretch, power_on_time, read_run
from bench.app.station import Station, builtin_sim_config
from bench.core.procedure import execute
from bench.core.store import RunStore
from procedures.noise import AccelerometerNoise, GyroNoise
from procedures.running import alone
from procedures.thermal_ramp import GyroThermalRamp, ThermalRamp
from procedures.turn_on import GyroTurnOnTest
from procedures.vibration import VibrationTest

GYRO = {"unit": "FOG-SIM-0003", "kind": "gyro"}
ACCEL = {"unit": "QA-SIM-0003", "kind": "accelerometer"}


def _run(path, step, who, seed=3):
    with RunStore(path) as store, Station(builtin_sim_config(), seed=seed, unit_serial=who["unit"],
                                          unit_kind=who["kind"]) as station:
        outcome = execute(alone(step), station, store, unit_serial=who["unit"], seed=seed)
        events = store.events(outcome.run_id)
    assert outcome.status == "passed", outcome.reason
    return outcome.run_id, events


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    """One store with a gyro start-up, a gyro static record (after a warm-up), a short vibration
    test and an accelerometer static record."""
    path = tmp_path_factory.mktemp("runs") / "b.sqlite"
    runs = {
        "gyro_startup": _run(path, GyroTurnOnTest(duration_s=180.0, off_wait_s=10.0, frame_rate_hz=20,
                                                  smooth_s=10.0, settled_window_s=60.0, chunk_s=60.0), GYRO),
        "gyro_noise": _run(path, GyroNoise(duration_s=120.0, frame_rate_hz=20, warmup_s=30.0, chunk_s=60.0), GYRO),
        "vibration": _run(path, VibrationTest(static_s=20.0, duration_s=20.0, level_grms=2.0, warmup_s=5.0,
                                              frame_rate_hz=200, chunk_s=1.0), GYRO),
        "accelerometer_noise": _run(path, AccelerometerNoise(duration_s=120.0, rate_hz=5.0, warmup_s=30.0,
                                                             chunk_s=60.0), ACCEL),
        # the chamber ramps −10…+60 °C at two rates with the unit static (≈ 7 h of chamber time)
        "thermal_ramp": _run(path, ThermalRamp(sample_interval_s=10.0), ACCEL),
        "gyro_thermal_ramp": _run(path, GyroThermalRamp(sample_interval_s=10.0), GYRO),
    }
    return path, runs


def test_gyro_startup_counts_from_power_on_ready_frames_only(store):
    path, runs = store
    rec, kind, label = read_run(path, runs["gyro_startup"][0])
    assert kind == "gyro" and "stream gyro_startup" in label
    np.testing.assert_array_equal(rec.t_on_s, rec.t_s)  # the stream's clock starts at power-on
    assert rec.t_s[0] > 0 and rec.temp_c is not None and rec.input is None


def test_gyro_static_takes_time_since_power_on_from_the_supply_events(store):
    path, runs = store
    run_id, events = runs["gyro_noise"]
    rec, kind, label = read_run(path, run_id)
    assert kind == "gyro" and "stream gyro_static" in label
    on = [e.t_s for e in events if e.kind == "gyro_supply_on"]
    assert on, "the procedure logs its switch-on"
    np.testing.assert_allclose(rec.t_on_s, rec.t_s - on[-1])
    assert rec.t_on_s[0] >= 30.0  # the record starts after the 30-s warm-up
    assert rec.is_uniform(0.05)


def test_vibration_maps_the_level_onto_vib(store):
    path, runs = store
    rec, kind, label = read_run(path, runs["vibration"][0])
    assert kind == "gyro" and "stream gyro_frames" in label
    assert rec.vib_grms is not None and rec.vib_grms.max() == pytest.approx(2.0, rel=0.2)
    assert rec.vib_grms.min() < 0.5  # the static segments before and after


def test_accelerometer_static_record_is_in_g_with_one_g_applied(store):
    path, runs = store
    rec, kind, label = read_run(path, runs["accelerometer_noise"][0])
    assert kind == "accelerometer" and "stream noise" in label
    assert np.mean(rec.y) == pytest.approx(1.0, abs=1e-12) and np.all(rec.input == 1.0)
    assert rec.t_on_s is not None and rec.t_on_s[0] >= 30.0


@pytest.mark.parametrize("which", ["thermal_ramp", "gyro_thermal_ramp"])
def test_a_thermal_ramp_is_a_record_with_the_units_temperature(store, which):
    path, runs = store
    rec, kind, label = read_run(path, runs[which][0])
    assert kind == ("gyro" if which.startswith("gyro") else "accelerometer") and "stream thermal_ramp" in label
    assert rec.temp_c is not None and np.ptp(rec.temp_c) > 50.0  # the ramps' −10…+60 °C, at the unit's sensor
    assert rec.t_on_s is not None and np.all(rec.t_on_s > 0)  # powered before the soak
    if kind == "accelerometer":
        assert np.all(rec.input == 0.0)  # IA horizontal


def test_unmappable_run_and_unknown_stream_are_one_line_exit_2(store, tmp_path, capsys):
    path, runs = store
    rc = main(["--store", str(path), "discover", "--run", runs["gyro_noise"][0], "--stream", "nope"])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and "--stream 'nope'" in err and "gyro_static" in err
    rc = main(["discover", "--measured", __file__, "--stream", "noise"])
    assert rc == 2 and "--run only" in capsys.readouterr().err


@pytest.mark.parametrize("which", ["gyro_startup", "gyro_noise", "vibration", "accelerometer_noise", pytest.param(
    "thermal_ramp", marks=pytest.mark.xfail(strict=True, reason="the one-criterion search names a random walk for "
                                            "the thermal ramp's temperature bias (the walk absorbs the slow "
                                            "profile): an open look-alike of the rebuilt selection"))])
def test_every_run_kind_runs_through_discover(store, tmp_path, capsys, which):
    path, runs = store
    rc = main(["--store", str(path), "discover", "--run", runs[which][0], "--max-effects", "1",
               "--out", str(tmp_path / "o"), "--json"])
    assert rc == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["source"].startswith(f"run {runs[which][0]}") and doc["model_file"]
    assert np.isfinite(doc["gap"]["initial"]) and doc["gap"]["final"] <= doc["gap"]["initial"] + 1e-9
    if which == "thermal_ramp":  # the catalogue's temperature effects are tried on it, and what stays is said
        tried = [e["id"] for e in doc["effects"]] + [w.split(":")[0] for w in doc["withdrawn"]]
        assert "temperature_bias" in tried
        assert doc["effects"] or any("temp" in u for u in doc["unexplained"])


def test_power_on_time_is_the_switch_on_not_followed_by_a_switch_off():
    ev = lambda t, k: SimpleNamespace(t_s=t, kind=k)
    on_off = ("gyro_supply_on", "gyro_supply_off")
    events = [ev(0.0, "gyro_supply_on"), ev(5.0, "gyro_supply_on"), ev(10.0, "gyro_supply_off"),
              ev(20.0, "gyro_supply_on"), ev(30.0, "gyro_supply_on")]
    assert power_on_time(events, 8.0, on_off) == 0.0  # a second "on" while on does not restart it
    assert power_on_time(events, 15.0, on_off) is None  # off at 10 s
    assert power_on_time(events, 40.0, on_off) == 20.0
    assert power_on_time([], 1.0, on_off) is None


def test_longest_stretch_cuts_at_gaps():
    t = np.arange(100.0)
    assert longest_stretch(t) == (0, 100)
    t2 = np.delete(t, [10, 60])  # two lost samples: stretches 0..9, 11..59, 61..99
    lo, hi = longest_stretch(t2)
    assert (t2[lo], t2[hi - 1]) == (11.0, 59.0)
