"""The angular vibration table's controller on the wire: the AngularVibrationTable driver
against AngularTableController served on loopback, read through pyvisa-py."""

from __future__ import annotations

import math
import socket

import numpy as np
import pytest
import pyvisa
from hypothesis import given, settings
from hypothesis import strategies as st

from instruments.angular_table import (
    AngularLimits,
    AngularTableAbortedError,
    AngularVibrationTable,
    SweepSpec,
    ToneSpec,
    check_tones,
)
from instruments.base import InstrumentError, open_resource
from sim.devices.angular_reference import ENCODER_COUNTS
from sim.devices.angular_table import AngularTableController
from sim.devices.sim_control import SimControl
from sim.physics.angular_table import AngularMotion
from sim.server import InstrumentServer
from sim.world import World

DEG = 180.0 / math.pi


class Rig:
    """World + table controller + sim-control served on loopback, read through pyvisa."""

    def __init__(self) -> None:
        self.world = World(11)
        self.motion = AngularMotion(rng=self.world.rng("angular_table"))
        self.device = AngularTableController(self.world, self.motion)
        self.server = InstrumentServer()
        self.server.add("table", "angular_table", self.device)
        self.server.add("sim", "sim_control", SimControl(self.world, ["table"]))
        self.server.start()
        self.endpoints = {e.name: e for e in self.server.endpoints}
        self.rm = pyvisa.ResourceManager("@py")
        self.res = open_resource(self.endpoints["table"].resource, resource_manager=self.rm, timeout_ms=10000)
        self.clock = open_resource(self.endpoints["sim"].resource, resource_manager=self.rm, timeout_ms=10000)
        self.tbl = AngularVibrationTable(self.res, name="table")

    def wait(self, seconds: float) -> None:
        assert self.clock.query(f"SIM:TIME:ADV {seconds!r};*OPC?").strip() == "1"

    def now(self) -> float:
        return float(self.clock.query("SIM:TIME?"))

    def idle(self) -> None:
        self.tbl.stop()
        self.tbl.interlock_close()
        self.wait(25.0)  # the longest ramp: 0.1 Hz tones ramp over ≥ 10 s
        if self.tbl.state == "ABORT":
            self.tbl.interlock_reset()
        assert self.tbl.state == "IDLE"
        self.tbl.ramp_time_s = 1.0
        self.res.write("*CLS")

    def close(self) -> None:
        self.res.close()
        self.clock.close()
        self.rm.close()
        self.server.stop()


@pytest.fixture(scope="module")
def rig():
    r = Rig()
    yield r
    r.close()


tones_drawn = st.lists(st.tuples(st.floats(0.01, 80.0), st.floats(math.log(0.1), math.log(1000.0)).map(math.exp),
                                 st.floats(-360.0, 360.0)), min_size=1, max_size=5)  # about 2/3 inside the limits


@settings(max_examples=12, deadline=None)
@given(tones=tones_drawn)
def test_tone_sets_round_trip_or_are_refused_before_the_wire(rig, tones):
    try:
        expected = check_tones(tones, AngularLimits())
    except ValueError as exc:
        assert "amplitude sum" in str(exc) and "is outside the allowed range [0, " in str(exc)
        with pytest.raises(ValueError):
            rig.tbl.set_tones(tones)
        return
    assert rig.tbl.set_tones(tones) == expected
    assert rig.tbl.tones() == expected == tuple(ToneSpec(*t) for t in tones)
    assert rig.tbl.mode == ("SINE" if len(tones) == 1 else "MULTI")


def test_driver_and_controller_agree_on_the_limits(rig):
    lim = rig.tbl.limits()
    assert lim == AngularLimits()
    assert lim.angle_deg == pytest.approx(28.6478898, rel=1e-8)
    assert lim.accel_dps2 == pytest.approx(1400 * DEG, rel=1e-8)
    assert rig.res.query(":LIM:DIST?") == "+3.00000000E-03,+1.00000000E-03"
    assert rig.res.query(":REF:RES?") == f"{360 / ENCODER_COUNTS:+.8E}"


def test_run_a_dwell_and_read_the_reference_block(rig):
    rig.idle()
    rig.tbl.set_tones([(20.0, 5.0, 30.0)])
    rig.tbl.configure_reference(2000.0, 6000)
    rig.tbl.start()
    assert rig.tbl.state == "RAMP"
    t0 = rig.now()
    rig.tbl.start_reference()
    assert rig.tbl.wait_running(rig.wait, timeout_s=5.0, poll_s=0.25) == "RUN"
    rig.wait(1.0)
    assert rig.tbl.reference_points == 4001 and rig.tbl.reference_running
    t1, a1, r1 = rig.tbl.read_reference(100)
    assert t1.size == 100 and rig.tbl.reference_points == 3901
    rig.wait(1.5)
    t2, a2, r2 = rig.tbl.read_reference()
    assert t2.size == 5900 and not rig.tbl.reference_running and not rig.tbl.reference_overflow
    t, angle, rate = (np.concatenate(x) for x in ((t1, t2), (a1, a2), (r1, r2)))
    assert np.array_equal(t, np.arange(6000) / 2000.0)
    truth_deg = np.degrees(rig.motion.angle_rad(t0 + t))
    assert np.all(angle <= truth_deg + 1e-9) and np.all(angle >= truth_deg - 360 / ENCODER_COUNTS - 1e-9)
    noise = rate - np.degrees(rig.motion.rate_rad_s(t0 + t))
    assert noise.std() == pytest.approx(2e-4, rel=0.1)
    # in RUN the reference shows the demanded tone (and its small harmonics)
    run = t >= 1.0
    fit = np.linalg.lstsq(np.column_stack([np.sin(2 * np.pi * 5 * t[run]), np.cos(2 * np.pi * 5 * t[run])]),
                          rate[run], rcond=None)[0]
    assert math.hypot(*fit) == pytest.approx(20.0, rel=1e-3)
    rig.tbl.stop()
    assert rig.tbl.wait_idle(rig.wait, timeout_s=5.0, poll_s=0.25) == "IDLE"


def test_sweep_on_the_wire_ends_idle(rig):
    rig.idle()
    spec = rig.tbl.configure_sweep(1.0, 50.0, 5.0, 30.0, "lin")
    assert spec == SweepSpec(1.0, 50.0, 5.0, 30.0, "LIN")
    assert rig.res.query(":SWE:STAR?;:SWE:STOP?;:SWE:TIME?;:SWE:MAGN?;:SWE:SPAC?") == "1.0;50.0;5.0;30.0;LIN"
    assert rig.tbl.mode == "SWEEP"
    rig.tbl.start()
    rig.wait(3.0)
    assert rig.tbl.state == "RUN"
    rig.wait(3.5)  # 1 s ramp + 5 s sweep + ramp down at 50 Hz (1 s)
    assert rig.tbl.state == "RAMP"
    assert rig.tbl.wait_idle(rig.wait, timeout_s=2.0, poll_s=0.25) == "IDLE"
    with pytest.raises(ValueError, match=r"angle amplitude sum=.* deg is outside the allowed range \[0, 28.6479\]"):
        rig.tbl.configure_sweep(0.1, 50.0, 5.0, 30.0)
    with pytest.raises(ValueError, match="equals start_hz"):
        rig.tbl.configure_sweep(5.0, 5.0, 5.0, 3.0)


def test_refusals_carry_the_standard_codes(rig):
    rig.idle()
    rig.res.write(":OSC1:FREQ 2000")
    assert rig.res.query("SYST:ERR?") == '-222,"Data out of range;FREQ 2000 not in 0.1..1000"'
    rig.res.write(":OSC17:MAGN 1")
    assert rig.res.query("SYST:ERR?") == '-114,"Header suffix out of range"'
    rig.res.write(":OSC:CLE;:OSC1:MAGN 2000;FREQ 1;STAT ON;:SYNT:MODE SINE;:STAR")
    assert rig.res.query("SYST:ERR?") == \
        '-222,"Data out of range;angle amplitude sum 318.31 deg not in 0..28.6479 deg"'
    rig.res.write(":OSC1:MAGN 10;:OSC2:MAGN 10;FREQ 3;STAT ON;:STAR")
    assert rig.res.query("SYST:ERR?").startswith('-221,"Settings conflict;SINE runs exactly one oscillator, 2')
    rig.res.write(":OSC:CLE;:SYNT:MODE MULTI;:STAR")
    assert rig.res.query("SYST:ERR?").startswith('-221,"Settings conflict;no oscillator enabled')
    with pytest.raises(ValueError, match=r"rate_hz=60000 is outside the allowed range \[1, 50000\]"):
        rig.tbl.configure_reference(60000, 10)
    assert rig.res.query("SYST:ERR:COUN?") == "+0"
    rig.tbl.interlock_open()
    rig.tbl.set_tones([(5.0, 10.0, 0.0)])
    with pytest.raises(InstrumentError, match="interlock") as err:
        rig.tbl.start()
    assert err.value.code == -221
    rig.tbl.interlock_close()
    rig.tbl.configure_reference(100.0, 10_000)
    rig.tbl.start_reference()
    with pytest.raises(InstrumentError) as err:
        rig.tbl.configure_reference(200.0, 10)
    assert err.value.code == -221 and "while capturing" in err.value.message
    rig.tbl.abort_reference()
    assert not rig.tbl.reference_running


def test_interlock_aborts_and_wait_running_reports_it(rig):
    rig.idle()
    rig.tbl.set_tones([(50.0, 20.0, 0.0), (5.0, 2.0, 90.0)])
    rig.tbl.start()
    rig.wait(0.3)
    rig.tbl.interlock_open()
    assert rig.tbl.state == "ABORT" and rig.tbl.interlock_closed is False
    assert rig.motion.rate_rad_s(np.array([rig.now() + 0.011]))[0] == 0.0
    with pytest.raises(AngularTableAbortedError):
        rig.tbl.wait_running(rig.wait, timeout_s=5.0)
    rig.tbl.interlock_close()
    rig.wait(0.1)
    rig.tbl.interlock_reset()
    assert rig.tbl.state == "IDLE" and rig.tbl.interlock_closed is True


def test_rst_stops_and_clears_the_demand(rig):
    rig.idle()
    rig.tbl.set_tones([(10.0, 3.0, 0.0)])
    rig.tbl.start()
    rig.wait(2.0)
    rig.tbl.reset()
    assert rig.tbl.tones() == () and rig.tbl.mode == "SINE" and rig.tbl.state == "RAMP"
    rig.wait(2.0)
    assert rig.tbl.state == "IDLE"


def test_junk_does_not_crash_the_server(rig):
    ep = rig.endpoints["table"]
    with socket.create_connection((ep.host, ep.port), timeout=5) as s:
        for junk in (b":OSC1:MAGN\n", b":OSC0:FREQ 5\n", b":SYNT:MODE BANANA\n", b":REF:DATA:REM? -3\n",
                     b":STAR 1,2,3\n", b"\xff\xfe;;::\n", b":SWE:TIME 1e999\n", b":OSC1:PHAS \"x\"\n"):
            s.sendall(junk)
        s.sendall(b"SYST:ERR:COUN?\n")
        reply = s.recv(100)
    assert int(reply) >= 8
    assert rig.tbl.idn.model == "ANGVIB-1"
    rig.res.write("*CLS")
