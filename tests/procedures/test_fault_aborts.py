"""Every injected fault takes a running procedure down the abort path: the run ends
``aborted`` with a reason naming the instrument and what happened, the time of the last
good sample is recorded, everything acquired before the fault is in the store, and the
station is left safe (supply off, meters idle, table and shaker at rest) even when the
faulty instrument is gone — make_safe tries every action."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from bench.app.station import Station, builtin_sim_config
from bench.core.procedure import execute
from bench.core.store import RunStore
from instruments.base import open_resource
from procedures.ratetable import RateTableCalibration
from procedures.running import alone
from procedures.startup import StartupAcquisition, StartupParameters
from procedures.tumble import TumbleCalibration

TIMEOUT_MS = 400  # the faulty instrument's timeout in these runs (a stall costs a few of them)
#: every other instrument's: a loaded machine (CI, two test workers on two cores) must never
#: turn a slow reply of a healthy instrument into an abort the test did not ask for
HEALTHY_TIMEOUT_MS = 5000

STARTUP = StartupParameters(duration_s=40.0, rate_hz=10.0, off_wait_s=5.0, chunk_s=5.0)


def startup():
    return alone(StartupAcquisition(STARTUP))


def tumble():
    return alone(TumbleCalibration(positions=4, planes=1, warmup_s=5.0, settle_s=1.0,
                                           average_s=1.0, nplc=1.0))


#: after the first record: the ramp from +465 to -465 °/s at 20 °/s² (46.5 s), 1 s settle,
#: then the second record (≥ 10 s) — this lands in it
RECORD_2_MID_S = 53.0


def ratetable():
    return alone(RateTableCalibration(rates_per_sign=1, min_record_s=10.0, warmup_s=8.0,
                                              settle_s=1.0, boot_wait_s=5.0))


def run(tmp_path, procedure, *, at_progress: int, fault: str | None = None,
        schedule: tuple | None = None, unit_kind: str = "accelerometer", seed: int = 5):
    """Run ``procedure``; at its ``at_progress``-th progress report inject ``fault`` through
    the sim-control endpoint (SCPI) or ``schedule`` = (kind, instrument, delay_s, params)
    through the Python API at now + delay_s."""
    store = RunStore(tmp_path / "bench.sqlite")
    serial = "FOG-F-1" if unit_kind == "gyro" else "QA-F-1"
    if fault is not None:
        faulty = fault.split('"')[1]
    else:
        assert schedule is not None, "a fault or a schedule to inject"
        faulty = schedule[1]
    with Station(builtin_sim_config(), seed=seed, unit_serial=serial, unit_kind=unit_kind) as station:
        for name, inst in station.instruments.items():
            timeout_ms = TIMEOUT_MS if name == faulty else HEALTHY_TIMEOUT_MS
            if getattr(inst, "resource", None) is not None:
                inst.resource.timeout = timeout_ms
            if hasattr(inst, "reply_timeout_s"):  # the gyro's serial line
                inst.reply_timeout_s = timeout_ms / 1000
        sim: Any = station.sim  # the embedded simulated station (typed None until started)
        control = open_resource(station.config.clock, timeout_ms=20000)
        calls = []

        def progress(done, total, message=""):
            calls.append(sim.world.now)
            if len(calls) != at_progress:
                return
            if fault is not None:
                control.write(fault)
                assert control.query("SYST:ERR?").startswith("+0")
            if schedule is not None:
                kind, name, delay_s, params = schedule
                sim.faults.inject(kind, name, at_s=sim.world.now + delay_s, **params)

        outcome = execute(procedure, station, store, unit_serial=serial, seed=seed,
                          progress=progress)
        control.close()
        t_fault = calls[at_progress - 1] if len(calls) >= at_progress else None
        sim.server.call(sim.world.advance, 120.0)  # let anything coasting come to rest
        now = sim.world.now
        safe = {"outputs": [ch.output for ch in sim.supply.channels.values()],
                "dmm": (sim.dmm.state, sim.dmm_temp.state),
                "table_moving": [bool(a.moving(now)) for a in sim.table.axes],
                "table_rate": [float(a.rate_dps(now)) for a in sim.table.axes],
                "shaker_g": float(sim.shaker.envelope_grms(np.array([now]))[0]),
                "gyro_line": sim.gyro_line.state}
    assert t_fault is not None, "the procedure ended before the fault was injected"
    return store, outcome, safe


def assert_aborted(store, outcome, *words, stream=None):
    assert outcome.status == "aborted", outcome.reason
    assert "\n" not in outcome.reason
    for word in words:
        assert word in outcome.reason, (word, outcome.reason)
    info = store.get_run(outcome.run_id)
    assert info.status == "aborted" and info.reason == outcome.reason
    if stream is not None:
        kept = store.load(outcome.run_id, stream)
        assert kept["t_s"].size > 0
        assert info.last_sample_t_s == pytest.approx(float(np.nanmax(kept["t_s"])))
    return info


def assert_safe(safe, supply_reachable=True):
    if supply_reachable:
        assert safe["outputs"] == [False, False, False]
    assert safe["table_moving"] == [False, False] and safe["table_rate"] == [0.0, 0.0]
    assert safe["shaker_g"] == 0.0


# -- the start-up acquisition: faults of the output meter and of the supply ----------------------

@pytest.mark.parametrize("fault,words", [
    ('SIM:FAUL:STAL "dmm"', ("dmm", "no reply", "DATA:POIN?")),
    ('SIM:FAUL:SLOW "dmm",1000', ("dmm", "no reply", "DATA:POIN?")),
    ('SIM:FAUL:GARB "dmm",1', ("dmm", "garbled reply")),
])
def test_startup_aborts_on_a_faulty_meter_and_keeps_the_trace(tmp_path, fault, words):
    store, outcome, safe = run(tmp_path, startup(), at_progress=3, fault=fault)
    info = assert_aborted(store, outcome, *words, stream="output")
    kept = store.load(outcome.run_id, "output")
    assert 0 < kept["t_s"].size < (STARTUP.duration_s + 1) * STARTUP.rate_hz
    assert np.all(np.diff(kept["t_s"]) > 0) and info.last_sample_t_s > 0
    assert_safe(safe)
    assert safe["dmm"][1] == "IDLE"  # the temperature meter was stopped though the other failed


def test_startup_aborts_when_the_supply_loses_power_and_teardown_names_it(tmp_path):
    # the supply going dark cuts the unit's power; the run cannot power it down any more
    store, outcome, safe = run(tmp_path, startup(), at_progress=3, fault='SIM:FAUL:POW "supply"')
    assert_aborted(store, outcome, "supply", stream="output")
    events = {e.kind: e.message for e in store.events(outcome.run_id)}
    assert "supply off" in events["teardown_error"] and "supply" in events["teardown_error"]
    assert_safe(safe)  # its outputs died with it
    assert safe["dmm"] == ("IDLE", "IDLE")


def test_an_unreachable_supply_does_not_keep_the_rest_from_being_made_safe(tmp_path):
    store, outcome, safe = run(tmp_path, startup(), at_progress=3,
                               fault='SIM:FAUL:DROP "supply",1e6')
    assert_aborted(store, outcome, "teardown failed", "supply off", "supply", stream="output")
    assert safe["outputs"][1] and safe["outputs"][2]  # nobody could switch it off: reported
    assert_safe(safe, supply_reachable=False)
    assert safe["dmm"] == ("IDLE", "IDLE")


# -- the tumble: faults of the table and of the meter between and during positions ---------------

@pytest.mark.parametrize("fault,words", [
    ('SIM:FAUL:INT "turntable"', ("turntable", "interlock")),
    ('SIM:FAUL:DROP "turntable",1e6', ("turntable",)),
    ('SIM:FAUL:POW "turntable"', ("turntable",)),
    ('SIM:FAUL:ERR "turntable",1,-310', ("turntable", "-310")),
])
def test_tumble_aborts_on_a_table_fault_and_keeps_the_positions_done(tmp_path, fault, words):
    store, outcome, safe = run(tmp_path, tumble(), at_progress=3, fault=fault)
    assert_aborted(store, outcome, *words, stream="tumble")
    assert 1 <= store.load(outcome.run_id, "tumble")["t_s"].size < 4
    assert_safe(safe)


def test_tumble_aborts_on_a_meter_overload_with_the_readings_stored(tmp_path):
    store, outcome, safe = run(tmp_path, tumble(), at_progress=2,
                               schedule=("overload", "dmm", 1.5, {}))
    assert_aborted(store, outcome, "dmm overload", stream="tumble")
    readings = store.load(outcome.run_id, "tumble_readings")["voltage_v"]
    assert np.any(np.isnan(readings)) and np.any(np.isfinite(readings))
    assert_safe(safe)


# -- the rate table: faults of the gyro's serial line ----------------------------------------------

@pytest.mark.parametrize("fault,schedule,words", [
    ('SIM:FAUL:FRAM "gyro",0.001,0.002', None, ("gyro line", "dropped", "corrupt")),
    (None, ("drop", "gyro", RECORD_2_MID_S, {}), ("gyro: line lost",)),
    (None, ("power", "gyro", RECORD_2_MID_S, {}), ("gyro: no frame in",)),
])
def test_ratetable_aborts_on_a_gyro_line_fault_with_the_frames_kept(tmp_path, fault, schedule, words):
    store, outcome, safe = run(tmp_path, ratetable(), at_progress=2, fault=fault,
                               schedule=schedule, unit_kind="gyro")
    assert_aborted(store, outcome, *words, stream="ratetable_frames")
    frames = store.load(outcome.run_id, "ratetable_frames")
    per_rate = [int(np.sum(frames["table_rate_dps"] == r)) for r in np.unique(frames["table_rate_dps"])]
    assert per_rate[0] > 0 and max(per_rate) >= 10_000  # a whole record (10 s at 1 kHz) kept
    assert all(0 < n <= 10_054 for n in per_rate)  # and what arrived of the cut one
    assert_safe(safe)
    assert safe["gyro_line"] == "OFF"  # unpowered by the teardown
