"""Drivers against injected faults over the real wire (sim/faults.py, instruments/wire.py):
errors name instrument and command, idempotent queries are retried over a reopened
connection, commands are never re-sent except those that bring the station to rest."""

from __future__ import annotations

import math

import numpy as np
import pytest
import pyvisa
import serial
from hypothesis import given, settings
from hypothesis import strategies as st

from instruments.base import (
    InstrumentConnectionError,
    InstrumentError,
    InstrumentReplyError,
    InstrumentTimeoutError,
    open_resource,
    parse_float,
)
from instruments.fog import GyroLineError, GyroTimeoutError, SerialGyro
from instruments.multimeter import Keysight34465A
from instruments.power_supply import KeysightE36312A
from instruments.shaker import VibrationTable
from instruments.turntable import AxisFaultError, DualAxisTurntable
from sim.faults import garble_reply
from sim.station import SimStationConfig, SimulatedStation

TIMEOUT_MS = 1000  # short enough for the stall tests, long enough for a loaded CI machine


class Rig:
    """A started simulated station, its SCPI drivers (short timeouts) and sim-control."""

    def __init__(self, seed: int = 7) -> None:
        self.station = SimulatedStation(SimStationConfig(seed=seed))
        self.station.start()
        res = self.station.resources()
        self.rm = pyvisa.ResourceManager("@py")
        self.sim = open_resource(res["sim"], resource_manager=self.rm, timeout_ms=20000)

        def opened(name):
            return open_resource(res[name], resource_manager=self.rm, timeout_ms=TIMEOUT_MS)
        self.dmm = Keysight34465A(opened("dmm"), name="dmm")
        self.supply = KeysightE36312A(opened("supply"), name="supply")
        self.table = DualAxisTurntable(opened("turntable"), name="turntable")
        self.shaker = VibrationTable(opened("shaker"), name="shaker")
        self.gyro_address = res["gyro"]

    def fault(self, command: str) -> None:
        self.sim.write(command)
        err = self.sim.query("SYST:ERR?")
        assert err.startswith("+0"), err

    def wait(self, seconds: float) -> None:
        assert self.sim.query(f"SIM:TIME:ADV {seconds!r};*OPC?").strip() == "1"

    def close(self) -> None:
        self.rm.close()
        self.station.stop()


@pytest.fixture
def rig():
    r = Rig()
    yield r
    r.close()


def test_a_stalled_instrument_times_out_naming_instrument_and_command(rig):
    rig.fault('SIM:FAUL:STAL "dmm"')
    with pytest.raises(InstrumentTimeoutError) as info:
        _ = rig.dmm.nplc  # a setting readback: idempotent, so retried
    text = str(info.value)
    assert "dmm" in text and "VOLT:DC:NPLC?" in text and "3 attempts" in text and "\n" not in text
    with pytest.raises(InstrumentTimeoutError, match=r"SYST:ERR\?.* after 'ABOR'.*1 attempt\)"):
        rig.dmm.abort()  # a command: sent once, its error check not repeated


def test_a_stall_for_simulated_seconds_ends_and_the_driver_reconnects(rig):
    rig.fault('SIM:FAUL:STAL "dmm",5')
    assert rig.sim.query("SIM:FAUL?").strip() == '"dmm:STALL"'
    with pytest.raises(InstrumentTimeoutError):
        rig.dmm.points_available()
    rig.wait(6)
    assert rig.sim.query("SIM:FAUL?").strip() == '""'
    assert rig.dmm.points_available() == 0


def test_one_refused_query_is_retried_on_a_fresh_session(rig):
    rig.fault('SIM:FAUL:ERR "dmm",1,-350')
    assert rig.dmm.nplc > 0  # the first attempt got no reply; the retry answered
    # The error queue is per I/O session, as on the real meter: the -350 stayed with the
    # connection the driver gave up on, and the session it reopened starts clean.
    assert rig.dmm.query("SYST:ERR?") == '+0,"No error"'


def test_a_refused_command_is_reported_as_the_instruments_error(rig):
    rig.fault('SIM:FAUL:ERR "dmm",1,-310')
    with pytest.raises(InstrumentError, match=r"dmm: -310.*NPLC 1"):
        rig.dmm.nplc = 1
    assert rig.station.dmm.fe.nplc != 1  # refused means not executed


def test_a_late_reply_is_never_taken_for_the_next_one(rig):
    rig.fault('SIM:FAUL:SLOW "dmm",2500')
    with pytest.raises(InstrumentTimeoutError, match=r"\*OPC\?.*1 attempt"):
        rig.dmm.query("*OPC?")  # not idempotent: asked once; its "1" arrives late
    rig.fault('SIM:FAUL:CLE "dmm"')
    assert rig.dmm.points_available() == 0  # a fresh connection: the late "1" is gone


def test_a_dropped_connection_is_reopened_for_an_idempotent_query(rig):
    rig.supply.ch[2].apply(12.5, 0.2)
    rig.fault('SIM:FAUL:DROP "supply"')
    assert rig.supply.ch[2].voltage_setpoint_v == 12.5


def test_reconnects_refused_for_a_while_end_in_a_named_error(rig):
    rig.fault('SIM:FAUL:DROP "supply",100')
    with pytest.raises((InstrumentTimeoutError, InstrumentConnectionError), match="supply"):
        _ = rig.supply.ch[2].voltage_setpoint_v
    rig.wait(101)
    assert rig.supply.ch[2].voltage_setpoint_v == 0.0


def test_outputs_off_is_sent_again_after_a_drop_but_output_on_never(rig):
    sim_supply = rig.station.supply
    rig.supply.ch[2].apply(12.5, 0.2)
    rig.fault('SIM:FAUL:DROP "supply"')
    with pytest.raises((InstrumentTimeoutError, InstrumentConnectionError), match="OUTP ON"):
        rig.supply.set_outputs([2], True)
    assert not sim_supply.channels[2].output  # lost with the connection, never re-sent
    rig.supply.set_outputs([2], True)
    assert sim_supply.channels[2].output
    rig.fault('SIM:FAUL:DROP "supply"')
    rig.supply.outputs_off()  # lost on the dropped connection, sent again over a new one
    assert not any(ch.output for ch in sim_supply.channels.values())


def test_a_motion_command_lost_with_the_connection_is_not_re_sent(rig):
    rig.table.interlock_close()
    rig.fault('SIM:FAUL:DROP "turntable"')
    with pytest.raises((InstrumentTimeoutError, InstrumentConnectionError), match="turntable"):
        rig.table.axis[1].move_to(30.0)
    assert rig.station.table.axes[0].position_demand_deg == 0.0
    rig.table.axis[1].stop()  # the next command goes over a reopened connection


def test_a_shaker_stop_lost_with_the_connection_is_sent_again_and_a_start_never(rig):
    rig.shaker.set_random_profile(grms=1.0)
    rig.fault('SIM:FAUL:DROP "shaker"')
    with pytest.raises((InstrumentTimeoutError, InstrumentConnectionError), match="shaker.*STAR"):
        rig.shaker.start()
    assert not rig.station.shaker.driving  # never re-sent
    rig.shaker.start()
    rig.shaker.wait_running(rig.wait, timeout_s=30)
    rig.fault('SIM:FAUL:DROP "shaker"')
    rig.shaker.stop()  # lost, then sent again over a reopened connection
    rig.shaker.wait_idle(rig.wait, timeout_s=30)
    rig.fault('SIM:FAUL:POW "shaker"')
    assert rig.station.shaker.envelope_grms(np.array([rig.station.world.now]))[0] == 0.0


def test_power_loss_drops_the_supply_outputs_and_the_instrument_comes_back_reset(rig):
    rig.supply.ch[2].apply(12.5, 0.2)
    rig.supply.set_outputs([2], True)
    rig.fault('SIM:FAUL:POW "supply"')
    assert not rig.station.supply.channels[2].output
    with pytest.raises((InstrumentTimeoutError, InstrumentConnectionError), match="supply"):
        _ = rig.supply.ch[2].output_enabled
    rig.fault('SIM:FAUL:CLE ALL')
    assert rig.supply.ch[2].voltage_setpoint_v == 0.0  # *RST state after power-up
    assert rig.supply.query("SYST:ERR?").startswith("+0")


def test_an_interlock_trip_stops_the_axes_and_latches(rig):
    rig.table.interlock_close()
    rig.table.axis[1].set_rate(20.0)
    rig.wait(5)
    rig.fault('SIM:FAUL:INT "turntable"')
    status = rig.table.axis[1].status
    assert status.interlock_open and status.fault and status.raw & 16
    with pytest.raises(AxisFaultError, match="turntable: axis 1: fault, interlock tripped"):
        rig.table.axis[1].wait_at_rate(rig.wait, timeout_s=10)
    rig.wait(30)
    assert rig.table.axis[1].rate_dps == 0.0  # coasted to rest
    with pytest.raises(InstrumentError, match="-221"):
        rig.table.axis[1].set_rate(10.0)
    rig.fault('SIM:FAUL:CLE "turntable"')
    assert not rig.table.interlock_closed  # CLEar does not reset a latched trip
    rig.table.interlock_reset()
    assert rig.table.interlock_closed


def test_dmm_overload_reads_as_nan_from_the_fault_on(rig):
    plan = rig.dmm.configure_timed_trace(20, 0.1, nplc=1.0)
    rig.dmm.initiate()
    rig.station.faults.inject("overload", "dmm", at_s=rig.station.world.now + 1.0)
    rig.wait(plan.duration_s + 0.5)
    volts = rig.dmm.fetch_all()
    assert volts.size == 20
    assert np.all(np.isfinite(volts[:9])) and np.all(np.isnan(volts[11:]))
    assert rig.station.dmm.memory.last == pytest.approx(9.9e37)


def test_sim_control_refuses_unknown_targets_and_bad_values(rig):
    for command, code in (('SIM:FAUL:STAL "nothing"', "-224"), ('SIM:FAUL:FRAM "dmm",0.1', "-224"),
                          ('SIM:FAUL:INT "supply"', "-224"), ('SIM:FAUL:SLOW "dmm",-1', "-222"),
                          ('SIM:FAUL:GARB "dmm",1.5', "-222"), ('SIM:FAUL:CLE "x"', "-224")):
        rig.sim.write(command)
        assert rig.sim.query("SYST:ERR?").startswith(code), command
    with pytest.raises(ValueError, match="probability"):
        rig.station.faults.inject("garble", "dmm", probability=2)


def _garbled_replies(seed: int) -> list[bytes]:
    r = Rig(seed)
    try:
        r.fault('SIM:FAUL:GARB "dmm",0.5')
        replies = []
        for _ in range(12):
            r.dmm.resource.write("SYST:LFR?")
            replies.append(r.dmm.resource.read_raw())
        return replies
    finally:
        r.close()


def test_garbled_replies_are_seeded_and_a_garbled_readback_is_named_or_retried():
    a, b, c = _garbled_replies(3), _garbled_replies(3), _garbled_replies(4)
    assert a == b and a != c
    assert any(r != b"50\n" for r in a) and b"50\n" in a
    r = Rig(3)
    try:
        r.fault('SIM:FAUL:GARB "dmm",1')
        values, errors = [], []
        for _ in range(6):
            try:
                values.append(r.dmm.query_value("SYST:LFR?", parse_float, retry=True))
            except InstrumentReplyError as exc:
                errors.append(str(exc))
        assert errors and all("dmm: garbled reply to 'SYST:LFR?'" in e for e in errors)
        r.fault('SIM:FAUL:CLE ALL')
        assert r.dmm.query_value("SYST:LFR?", parse_float) == 50.0  # still in step
    finally:
        r.close()


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=40), st.integers(0, 2**32 - 1))
def test_garbling_changes_one_byte_and_keeps_the_terminator(body, seed):
    reply = body.replace(b"\n", b"") + b"\n"
    out = garble_reply(reply, np.random.default_rng(seed))
    assert out.endswith(b"\n") and out.count(b"\n") == 1
    if len(out) == len(reply):
        assert sum(x != y for x, y in zip(out, reply)) == 1
    else:
        assert len(out) == len(reply) + 1
        assert any(out[:i] + out[i + 1:] == reply for i in range(len(out)))


# -- the gyro line ------------------------------------------------------------------------------

def _gyro(rig: Rig, timeout_s: float = 2.0) -> SerialGyro:
    rig.supply.ch[1].apply(5.0, 1.0)
    rig.supply.set_outputs([1], True)
    rig.wait(10.0)
    port = serial.serial_for_url(rig.gyro_address, baudrate=921600, timeout=timeout_s)
    return SerialGyro(port, name="gyro")


def test_frame_corruption_and_loss_show_in_the_line_counters(rig):
    gyro = _gyro(rig)
    gyro.configure(rate_hz=1000)
    rig.fault('SIM:FAUL:FRAM "gyro",0.02,0.03')
    gyro.start()
    frames = gyro.read_frames(4000, wait=rig.wait)
    gyro.stop()
    faults = rig.station.faults
    assert len(frames) == 4000 and frames.dropped >= faults.frames_lost > 0
    assert frames.corrupt > 0 and faults.frames_corrupted > 0
    assert np.all(np.diff(frames.index) >= 1)
    gyro.close()


def test_a_gyro_line_drop_mid_stream_keeps_the_frames_and_stop_reopens(rig):
    gyro = _gyro(rig)
    gyro.configure(rate_hz=1000)
    gyro.start()
    first = gyro.read_frames(500, wait=rig.wait)
    rig.fault('SIM:FAUL:DROP "gyro"')
    with pytest.raises(GyroLineError, match=r"gyro: line lost at 'reading 500 frames'") as info:
        gyro.read_frames(500, wait=rig.wait)
    assert info.value.frames is not None and len(first) == 500
    gyro.stop()  # reopens the line and stops the unit that kept streaming
    assert rig.station.gyro_line.state == "STOPPED"
    assert gyro.identify().model
    gyro.close()


def test_a_stalled_gyro_times_out_naming_the_command_and_recovers(rig):
    gyro = _gyro(rig, timeout_s=0.3)  # short: the stalled queries are asked four times
    rig.fault('SIM:FAUL:STAL "gyro"')
    with pytest.raises(GyroTimeoutError, match=r"gyro: no reply to '\$ID\?'"):
        gyro.identify()
    rig.fault('SIM:FAUL:CLE "gyro"')
    assert gyro.identify().serial
    rig.fault('SIM:FAUL:POW "gyro"')
    assert rig.station.gyro_line.state == "OFF"
    with pytest.raises(GyroTimeoutError):
        gyro.read_config()
    rig.fault('SIM:FAUL:CLE "gyro"')
    rig.wait(10.0)
    assert gyro.read_config().state == "STOPPED"
    gyro.close()
    assert math.isfinite(rig.station.world.now)


def test_a_gyro_losing_power_mid_stream_is_noticed_in_line_time_not_wall_time(rig):
    gyro = _gyro(rig)
    gyro.configure(rate_hz=1000)
    gyro.start()
    gyro.read_frames(200, wait=rig.wait)
    rig.station.faults.inject("power", "gyro", at_s=rig.station.world.now + 0.1)
    with pytest.raises(GyroTimeoutError, match=r"gyro: no frame in .* s of line time") as info:
        gyro.read_frames(5000, timeout_s=600, wait=rig.wait)  # the wall limit never matters
    assert 50 <= len(info.value.frames) <= 150  # the 0.1 s before the power went
    gyro.close()


def _corrupted_record(seed: int) -> tuple[bytes, int, int]:
    r = Rig(seed)
    try:
        gyro = _gyro(r)
        gyro.configure(rate_hz=1000)
        r.station.faults.inject("frame", "gyro", corrupt=0.01, loss=0.01)
        gyro.start()
        frames = gyro.read_frames(3000, wait=r.wait)
        gyro.stop()
        gyro.close()
        return frames.index.tobytes() + frames.counts.tobytes(), frames.dropped, frames.corrupt
    finally:
        r.close()


def test_same_seed_and_fault_schedule_give_the_same_frames():
    a, b, c = _corrupted_record(5), _corrupted_record(5), _corrupted_record(6)
    assert a == b and a[1] > 0 and a[2] > 0
    assert a[0] != c[0]
