"""Paced time (``sim.world``, ``World(seed, pace=N)``; ``bench sim serve --pace realtime|N``).

Event-driven (the default), simulated time moves only when a client waits, and the same seed
gives the same bytes.  Paced, it also follows the wall clock at N simulated seconds per wall
second, so a client that polls sees readings arrive, and a blocking query waits in wall time.

The paced checks bracket wall instants rather than time them: a message is handled somewhere
between the client's send and its reply, so a count or a state read at a poll lies between
what the physics gives for ``N · (poll sent − INIT answered)`` and ``N · (poll answered − INIT
sent)`` of simulated time.  Those bounds hold however loaded the machine is; the only slack is
1e-6 of a step, for a reading that ends exactly at a bracket's edge (float rounding).
"""

from __future__ import annotations

import json
import math
import os
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import pytest
import pyvisa

from bench.app.cli import main
from bench.app.commands.sim import time_banner
from bench.app.station import StationError, check_simulation, load_station
from sim.station import SimStationConfig, SimulatedStation
from sim.world import World

#: the DMM over 40 s of simulated time: one reading each second (the timer dominates the
#: 0.4 ms aperture at NPLC 0.02), no trigger delay, so reading k ends at k s + aperture
DMM_TIMED = "*RST;:CONF:VOLT:DC 10;:VOLT:NPLC 0.02;:TRIG:DEL 0;:SAMP:SOUR TIM;:SAMP:TIM 1;:SAMP:COUN 40"
DMM_STEP_S, DMM_READINGS = 1.0, 40
#: the issue's case: ten readings back to back at NPLC 0.02 (about 10 ms on a real 34465A)
DMM_FAST = "*RST;:CONF:VOLT:DC 10;:VOLT:NPLC 0.02;:SAMP:COUN 10"
#: the DAQ: 100 sweeps of four channels (its duration is asked of an event-driven twin)
DAQ_SCAN = "*RST;:CONF:VOLT:DC 10,(@101:104);:TRIG:COUN 100"
SLACK = 1e-6

#: a fixed session over several instruments and the sim-control endpoint: (instrument, message)
SCRIPT = [
    ("sim", "SIM:TIME?"),
    ("supply", "APPL CH2,15,0.1;APPL CH3,15,0.1;:OUTP ON,(@2,3)"),
    ("dmm", "*RST;:CONF:VOLT:DC 10;:VOLT:NPLC 0.02;:TRIG:COUN 2;:SAMP:COUN 5"),
    ("dmm", "INIT"),
    ("dmm", "DATA:POIN?"),
    ("dmm", "FETC?"),
    ("dmm", "DATA:POIN?"),
    ("sim", "SIM:TIME?"),
    ("sim", "SIM:TIME:ADV 2.5;*OPC?"),
    ("daq", "*RST;:CONF:VOLT:DC 10,(@101:104);:TRIG:COUN 3"),
    ("daq", "INIT"),
    ("daq", "ROUT:DONE?"),
    ("daq", "*OPC?"),
    ("daq", "ROUT:DONE?;:DATA:POIN?"),
    ("daq", "FETC?"),
    ("dmm_temp", "READ?"),
    ("sim", "SIM:TIME?"),
    ("dmm", "SYST:ERR?"),
]


# -- helpers -----------------------------------------------------------------------------------
@pytest.fixture
def rm() -> Iterator[pyvisa.ResourceManager]:
    manager = pyvisa.ResourceManager("@py")
    yield manager
    manager.close()


def _open(rm: pyvisa.ResourceManager, resource: str):
    return rm.open_resource(resource, read_termination="\n", write_termination="\n", timeout=20_000)


@contextmanager
def paced(pace: float, seed: int = 0) -> Iterator[SimulatedStation]:
    """A served station whose clock follows the wall, stopped when the test ends (its clock
    would otherwise keep running the world on both cores)."""
    with SimulatedStation(SimStationConfig(seed=seed, pace=pace)) as station:
        yield station


def timed_query(resource, message: str) -> tuple[float, str, float]:
    """(wall before sending, reply, wall after the reply): the message was handled in between."""
    before = time.monotonic()
    reply = resource.query(message)
    return before, reply, time.monotonic()


def event_duration(device, setup: str, start: str = "INIT;*OPC?") -> float:
    """How long ``start`` keeps ``device`` (on an unserved, event-driven station) busy, in
    simulated s: its acquisition's duration as the physics gives it."""
    world = device.world
    device.process(setup.encode())
    t0 = world.now
    assert device.process(start.encode()) == b"1\n"
    return world.now - t0


def readings_due_between(lo_s: float, hi_s: float) -> tuple[int, int]:
    """Bounds on the timed DMM's readings in memory after ``lo_s``..``hi_s`` simulated s: reading k
    ends at k·step + aperture, the aperture in (0, step), so floor(e/step) ≤ count(e) ≤ floor(e/step) + 1."""
    low = max(0, math.floor(lo_s / DMM_STEP_S - SLACK))
    high = math.floor(hi_s / DMM_STEP_S + SLACK) + 1
    return min(low, DMM_READINGS), min(high, DMM_READINGS)


def served_exchange(rm: pyvisa.ResourceManager, resources: dict[str, str]) -> list[str]:
    """:data:`SCRIPT` over the wire: each query's reply, as ``instrument<message>reply``."""
    sessions = {name: _open(rm, resources[name]) for name in {n for n, _ in SCRIPT}}
    replies = []
    for name, message in SCRIPT:
        if "?" in message:
            replies.append(f"{name}<{message}>{sessions[name].query(message)}")
        else:
            sessions[name].write(message)
    for s in sessions.values():
        s.close()
    return replies


def in_process_exchange(station: SimulatedStation) -> list[str]:
    """:data:`SCRIPT` straight into the devices: no transport, no server loop, no pacing path."""
    devices: dict[str, Any] = {**station.devices, "sim": station.sim_control}  # each a SCPI device here
    replies = []
    for name, message in SCRIPT:
        reply = devices[name].process(message.encode())
        if "?" in message:
            assert reply is not None
            replies.append(f"{name}<{message}>{reply.decode('latin-1').removesuffix(chr(10))}")
    return replies


# -- the setting -----------------------------------------------------------------------------
@pytest.mark.parametrize("pace", [0, -1.0, 2e6, float("nan"), float("inf"), True, "realtime"])
def test_a_pace_out_of_range_is_refused_naming_it_and_the_range(pace):
    with pytest.raises(ValueError, match=r"pace = .* not in 0\.001\.\.1e\+06 simulated seconds per wall second"):
        SimStationConfig(pace=pace).validate()
    with pytest.raises(ValueError, match=r"pace = "):
        World(0, pace=pace)


@pytest.mark.parametrize("pace", [None, 1e-3, 1, 50.0, 1e6])
def test_a_pace_in_range_or_none_is_taken(pace):
    SimStationConfig(pace=pace).validate()
    assert World(0, pace=pace).pace == (None if pace is None else float(pace))


def test_a_station_files_simulation_table_sets_the_pace(tmp_path):
    station = tmp_path / "paced.toml"
    station.write_text("[simulation]\nseed = 4\npace = 20\n")
    options = load_station(station).simulation
    assert options is not None and SimStationConfig(**options).pace == 20
    with pytest.raises(StationError, match=r"\[simulation\] pace = 0 not in 0\.001\.\.1e\+06"):
        check_simulation({"pace": 0})


@pytest.mark.parametrize("value,fragment", [("fast", "--pace 'fast' is neither realtime nor a number"),
                                            ("0", "pace = 0.0 not in 0.001..1e+06")])
def test_sim_serve_refuses_a_bad_pace_in_one_line(capsys, value, fragment):
    assert main(["sim", "serve", "--only", "dmm", "--pace", value]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and fragment in err, err


def test_sim_serve_states_its_time_on_stderr_and_keeps_stdout_json_lines():
    assert "event-driven" in time_banner(None) and "same seed gives the same bytes" in time_banner(None)
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen([sys.executable, "-m", "bench.app.cli", "sim", "serve", "--only", "dmm",
                             "--pace", "realtime"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=env)
    try:
        lines = [json.loads(proc.stdout.readline()) for _ in range(2)]  # the meter, then sim-control
        assert [d["name"] for d in lines] == ["dmm", "sim"]
        assert "paced at real time" in proc.stderr.readline()
    finally:
        proc.terminate()
        proc.wait(10)


# -- the clock itself ------------------------------------------------------------------------------
def test_the_event_driven_clock_stands_still_between_waits():
    world = World(3)
    time.sleep(0.02)
    world.catch_up()
    assert world.now == world.paced_now() == 0.0 and world.wall_delay(5.0) == 0.0
    world.advance(5.0)  # at once: nothing to wait for
    assert world.now == 5.0


def test_a_paced_clock_follows_the_wall_and_a_wait_ahead_of_it_sleeps_for_it():
    pace = 100.0
    world = World(3, pace=pace)
    before = time.monotonic()
    world.anchor_pace()
    anchored = time.monotonic()
    time.sleep(0.02)
    ask = time.monotonic()
    world.catch_up()
    answered = time.monotonic()
    assert pace * (ask - anchored) <= world.now <= pace * (answered - before)
    start = time.monotonic()
    target = world.now + 3.0
    # the paced clock has run on since catch_up: the wait is what it still lacks, read after start
    due = (target - world.paced_now()) / pace
    world.advance_to(target)  # ≈ 3 simulated s ahead: ≈ 30 ms of wall, never ahead of the clock
    assert time.monotonic() - start >= due * (1 - SLACK)
    assert due > 0.5 * 3.0 / pace and world.now == target <= world.paced_now()


# -- paced, over the wire --------------------------------------------------------------------------
def test_paced_dmm_readings_arrive_with_the_wall_for_a_client_that_polls(rm):
    pace = 50.0
    with paced(pace) as station:
        dmm = _open(rm, station.resources()["dmm"])
        dmm.write(DMM_TIMED)
        init_sent, reply, init_answered = timed_query(dmm, "INIT;:DATA:POIN?")
        polls = [(init_sent, int(reply), init_answered)]
        deadline = init_sent + 10 * DMM_READINGS * DMM_STEP_S / pace  # ten times the acquisition
        while polls[-1][1] < DMM_READINGS and time.monotonic() < deadline:
            time.sleep(DMM_STEP_S / pace / 2)
            sent, reply, answered = timed_query(dmm, "DATA:POIN?")
            polls.append((sent, int(reply), answered))
        dmm.close()
    counts = [c for _, c, _ in polls]
    for sent, count, answered in polls[1:]:
        low, high = readings_due_between(pace * (sent - init_answered), pace * (answered - init_sent))
        assert low <= count <= high, (sent - init_answered, answered - init_sent, count)
    assert counts == sorted(counts) and counts[-1] == DMM_READINGS
    assert any(0 < c < DMM_READINGS for c in counts)  # seen filling, not all at once


def test_realtime_the_issues_ten_fast_readings_are_there_after_a_fifth_of_a_second(rm, station_factory):
    duration_s = event_duration(station_factory(seed=0).dmm, DMM_FAST)
    assert duration_s < 0.05  # ~10 ms on the real meter: a fifth of a second is ample
    with paced(1.0) as station:
        dmm, sim = _open(rm, station.resources()["dmm"]), _open(rm, station.resources()["sim"])
        dmm.write(DMM_FAST)
        t0 = float(sim.query("SIM:TIME?"))
        assert dmm.query("INIT;:DATA:POIN?") in {f"{n:+d}" for n in range(11)}
        time.sleep(0.2)
        assert dmm.query("DATA:POIN?") == "+10"
        assert float(sim.query("SIM:TIME?")) >= t0 + 0.2  # time moved by itself, at least the wall's
        dmm.close()
        sim.close()


def test_paced_daq_scan_is_done_after_its_duration_over_the_pace(rm, station_factory):
    pace = 50.0
    duration_s = event_duration(station_factory(seed=0).devices["daq"], DAQ_SCAN)
    with paced(pace) as station:
        daq = _open(rm, station.resources()["daq"])
        daq.write(DAQ_SCAN)
        init_sent, reply, init_answered = timed_query(daq, "INIT;:ROUT:DONE?")
        polls = [(init_sent, reply, init_answered)]
        deadline = init_sent + 10 * duration_s / pace
        while polls[-1][1] != "1" and time.monotonic() < deadline:
            time.sleep(duration_s / pace / 20)
            polls.append(timed_query(daq, "ROUT:DONE?"))
        daq.close()
    for sent, done, answered in polls:
        if pace * (answered - init_sent) < duration_s * (1 - SLACK):
            assert done == "0"  # the world never runs ahead of the wall
        if pace * (sent - init_answered) > duration_s * (1 + SLACK):
            assert done == "1"
    assert polls[0][1] == "0" and polls[-1][1] == "1"


def test_a_paced_blocking_query_waits_for_the_wall_while_the_loop_serves_others(rm, station_factory):
    pace = 50.0
    duration_s = event_duration(station_factory(seed=0).devices["daq"], DAQ_SCAN)
    with paced(pace) as station:
        daq, sim = _open(rm, station.resources()["daq"]), _open(rm, station.resources()["sim"])
        daq.write(DAQ_SCAN)
        t_before = float(sim.query("SIM:TIME?"))
        arrived: list[tuple[str, float]] = []
        sent = time.monotonic()
        daq.write("INIT;*OPC?")
        reader = threading.Thread(target=lambda: arrived.append((daq.read(), time.monotonic())))
        reader.start()
        polls = []
        while reader.is_alive():
            _, now_s, answered = timed_query(sim, "SIM:TIME?")
            polls.append((float(now_s), answered, station.world.paced_now()))
            time.sleep(duration_s / pace / 20)
        reader.join()
        t_after = float(sim.query("SIM:TIME?"))
        daq.close()
        sim.close()
    (opc, opc_at), = arrived
    assert opc == "1" and opc_at - sent >= duration_s / pace * (1 - SLACK)  # waited in wall time
    assert t_after >= t_before + duration_s * (1 - SLACK)
    during = [t for t, answered, _ in polls if answered < opc_at]
    assert during and during == sorted(during) and during[-1] > during[0]  # served, time moving
    assert all(t <= clock for t, _, clock in polls)  # never ahead of the paced clock


def test_paced_sim_control_waits_are_wall_waits_and_a_passed_time_is_no_wait(rm):
    pace = 100.0
    with paced(pace) as station:
        sim = _open(rm, station.resources()["sim"])
        t_before = float(sim.query("SIM:TIME?"))
        sent, reply, answered = timed_query(sim, "SIM:TIME:ADV 5;*OPC?")
        assert reply == "1" and answered - sent >= 5 / pace * (1 - SLACK)
        assert float(sim.query("SIM:TIME?")) >= t_before + 5
        assert sim.query(f"SIM:TIME:UNT {t_before!r};*OPC?") == "1"  # passed on its own: nothing to do
        assert sim.query("SYST:ERR?") == '+0,"No error"'
        sim.close()


def test_paced_frames_flow_to_a_client_that_only_reads(rm):
    rate_hz, sync = 2000, b"\xfe\x81\xffG"  # the FOG's default frame rate and sync word (docs/FOG_SERIAL.md)
    with paced(1.0) as station:
        supply = _open(rm, station.resources()["supply"])
        supply.write("APPL CH1,5,1;:OUTP ON,(@1)")
        assert supply.query("SYST:ERR?") == '+0,"No error"'
        port = int(station.resources()["gyro"].rsplit(":", 1)[1])
        with socket.create_connection(("127.0.0.1", port)) as line:
            line.settimeout(0.05)
            sent = time.monotonic()
            line.sendall(b"$START\r\n")  # the last message: from here on the client only reads
            data, last = b"", sent
            while time.monotonic() - sent < 0.3:
                try:
                    chunk = line.recv(1 << 16)
                except TimeoutError:
                    continue
                data, last = data + chunk, time.monotonic()
        supply.close()
    frames = (len(data) - data.find(sync)) // 20 if sync in data else 0
    assert 10 < frames <= rate_hz * (last - sent) + 1  # flowing, and none before its time


# -- event-driven, the default: unchanged -----------------------------------------------------
def test_event_driven_time_moves_only_when_a_client_waits(rm, station_factory):
    station = station_factory(seed=0, serve=True)
    dmm, sim = _open(rm, station.resources()["dmm"]), _open(rm, station.resources()["sim"])
    dmm.write(DMM_FAST)
    t0 = sim.query("SIM:TIME?")
    assert dmm.query("INIT;:DATA:POIN?") == "+0"  # answered at once, nothing taken yet
    time.sleep(0.2)
    assert dmm.query("DATA:POIN?") == "+0" and sim.query("SIM:TIME?") == t0
    assert dmm.query("FETC?").count(",") == 9 and dmm.query("DATA:POIN?") == "+10"  # the wait moved it
    dmm.close()
    sim.close()


def test_event_driven_bytes_are_the_same_twice_and_the_same_as_without_the_server(rm, station_factory):
    first = served_exchange(rm, station_factory(seed=3, serve=True).resources())
    second = served_exchange(rm, station_factory(seed=3, serve=True).resources())
    direct = in_process_exchange(station_factory(seed=3))
    assert first == second == direct
    assert any(line.startswith("dmm<FETC?>+") for line in first)  # the exchange holds readings
