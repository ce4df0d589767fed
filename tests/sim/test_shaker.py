"""The shaker: profile integrals, the shaped control signal, the envelope, and the vibration
controller on the wire (SCPI over TCP, read by the VibrationTable driver)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import pyvisa
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad
from scipy.signal import welch

from instruments.base import InstrumentError, open_resource
from instruments.shaker import (
    RandomProfileSpec,
    SineProfileSpec,
    VibrationAbortedError,
    VibrationTable,
    random_profile_grms,
)
from sim.devices.shaker import ShakerController
from sim.devices.sim_control import SimControl
from sim.physics.gravity import STANDARD_GRAVITY_MPS2 as G0
from sim.physics.shaker import Shaker
from sim.physics.shaker_profile import RandomProfile, ShakerLimits, SineProfile
from sim.physics.shaker_signal import CONTROL_RATE_HZ, ShapedNoise
from sim.server import InstrumentServer
from sim.world import World

NAVMAT = RandomProfile((20.0, 80.0, 350.0, 2000.0), (0.01, 0.04, 0.04, 0.007))


def breakpoint_profiles(max_points: int = 8):
    """Random profiles within the shaker's band: increasing frequencies, ASD 1e-4..1 g²/Hz."""
    @st.composite
    def build(draw):
        n = draw(st.integers(2, max_points))
        logs = draw(st.lists(st.floats(math.log(10.0), math.log(2900.0)), min_size=n, max_size=n))
        freqs = sorted({round(math.exp(x), 3) for x in logs})
        if len(freqs) < 2:
            freqs = [20.0, 2000.0]
        psd = draw(st.lists(st.floats(1e-4, 1.0), min_size=len(freqs), max_size=len(freqs)))
        return RandomProfile(tuple(freqs), tuple(psd))
    return build()


# ---- profile integrals --------------------------------------------------------------------
@settings(max_examples=60)
@given(psd=st.floats(1e-5, 5.0), f_lo=st.floats(5.0, 1000.0), width=st.floats(1.0, 2000.0))
def test_flat_profile_grms_is_exact(psd, f_lo, width):
    p = RandomProfile.flat(psd, f_lo, f_lo + width)
    assert p.grms**2 == pytest.approx(psd * width, rel=1e-12)
    # displacement² = g0² P ∫ (2πf)^-4 df, velocity² = g0² P ∫ (2πf)^-2 df, closed forms
    f1, f2 = f_lo, f_lo + width
    assert p.velocity_rms_mps**2 == pytest.approx(G0**2 * psd * (1 / f1 - 1 / f2) / (2 * math.pi) ** 2, rel=1e-9)
    assert p.displacement_rms_m**2 == pytest.approx(
        G0**2 * psd * (f1**-3 - f2**-3) / 3 / (2 * math.pi) ** 4, rel=1e-9)
    assert RandomProfile.flat_grms(p.grms, f1, f2).psd_g2hz[0] == pytest.approx(psd, rel=1e-12)


def test_navmat_profile_is_6_06_grms():
    # NAVMAT P-9492: +3 dB/oct 20-80 Hz, 0.04 g²/Hz 80-350 Hz, −3 dB/oct to 2000 Hz: 6.06 g rms
    assert NAVMAT.grms == pytest.approx(6.06, abs=0.005)
    assert np.allclose(NAVMAT.slopes * 10 * math.log10(2), [3.0103, 0.0, -3.0103], atol=0.02)


@settings(max_examples=40)
@given(profile=breakpoint_profiles())
def test_breakpoint_grms_equals_quadrature_and_the_drivers_own_integral(profile):
    edges = profile.freqs_hz
    numeric = sum(quad(lambda f: float(profile.psd(f)), a, b, epsrel=1e-12, limit=200)[0]
                  for a, b in zip(edges, edges[1:]))
    assert profile.grms**2 == pytest.approx(numeric, rel=1e-8)
    assert random_profile_grms(profile.freqs_hz, profile.psd_g2hz) == pytest.approx(profile.grms, rel=1e-12)


def test_profiles_refuse_bad_breakpoints():
    with pytest.raises(ValueError, match=r"freqs_hz\[1\] = 20.0 must be above"):
        RandomProfile((20.0, 20.0), (0.01, 0.01))
    with pytest.raises(ValueError, match=r"psd_g2hz\[0\] = -1"):
        RandomProfile((20.0, 200.0), (-1, 0.01))
    with pytest.raises(ValueError, match="2..32 breakpoints"):
        RandomProfile((20.0,), (0.01,))


def test_limits_name_the_value_and_the_range():
    lim = ShakerLimits()
    assert lim.violation(NAVMAT) is None
    assert "displacement peak 49.68" in lim.violation(SineProfile(5.0, 5.0))
    assert "0..25.4 mm" in lim.violation(SineProfile(5.0, 5.0))
    assert "velocity 3 sigma peak" in lim.violation(RandomProfile.flat_grms(5.0, 5.0, 20.0))
    assert lim.violation(RandomProfile.flat_grms(20.0, 20.0, 2000.0), 6.0) == \
        "level 39.9052 g rms not in 0..30 g rms"
    assert "frequency 2 Hz not in 5..3000 Hz" == lim.violation(RandomProfile.flat(0.01, 2.0, 100.0))


# ---- the control signal -------------------------------------------------------------------
@pytest.mark.parametrize("profile", [RandomProfile.flat_grms(6.0, 20.0, 2000.0), NAVMAT])
def test_series_psd_matches_the_profile(profile):
    x = ShapedNoise(profile, seed=123).samples(0, 60 * CONTROL_RATE_HZ)
    assert x.std() == pytest.approx(profile.grms, rel=0.02)
    f, p = welch(x, fs=CONTROL_RATE_HZ, nperseg=4096)
    edges = 40.0 * 2 ** (np.arange(0, 17) / 3)  # third-octave bands 40..1600 Hz
    for a, b in zip(edges, edges[1:]):
        band = (f >= a) & (f < b)
        assert p[band].mean() / profile.psd(f[band]).mean() == pytest.approx(1.0, abs=0.12), (a, b)
    outside = (f > 2200) | ((f > 4) & (f < 12))  # beyond the edges' ±8 Hz smear
    assert p[outside].max() < 1e-3 * max(profile.psd_g2hz)


def test_series_is_deterministic_per_seed_and_random_access():
    prof = RandomProfile.flat_grms(6.0, 20.0, 2000.0)
    a, b = ShapedNoise(prof, 7), ShapedNoise(prof, 7)
    whole = a.samples(0, 50_000)
    assert np.array_equal(whole, b.samples(0, 50_000))
    # any window, asked in any order, is the same samples
    assert np.allclose(b.samples(30_000, 7_000), whole[30_000:37_000], rtol=0, atol=1e-12)
    assert np.allclose(b.samples(123, 10), whole[123:133], rtol=0, atol=1e-12)
    assert not np.allclose(ShapedNoise(prof, 8).samples(0, 1000), whole[:1000])


# ---- the envelope -------------------------------------------------------------------------
def test_envelope_ramps_runs_stops_and_aborts():
    sh = Shaker(np.random.default_rng(1))
    sh.set_profile(0.0, RandomProfile.flat_grms(6.0, 20.0, 2000.0))
    sh.set_ramp(2.0)
    assert sh.state(0.0) == "IDLE" and sh.quiet_between(0.0, 100.0)
    sh.start(10.0)
    assert sh.envelope_grms(np.array([9.0, 10.0, 11.0, 12.0, 50.0])) == pytest.approx([0, 0, 3, 6, 6])
    assert [sh.state(t) for t in (11.0, 12.0)] == ["RAMP", "RUN"]
    assert not sh.quiet_between(0.0, 10.5) and sh.quiet_between(0.0, 10.0)
    sh.set_level(20.0, -6.0)  # ramps to half the amplitude
    assert sh.envelope_grms(22.0) == pytest.approx(6.0 * 10 ** (-6 / 20))
    sh.stop(30.0)
    assert sh.envelope_grms(31.0) == pytest.approx(0.5 * 6.0 * 10 ** (-6 / 20))
    assert sh.state(32.0) == "IDLE"
    g = sh.grms_sensor(np.array([25.0]), np.array([[0, 0, 1.0], [1.0, 0, 0], [0.6, 0, 0.8]]))
    assert g == pytest.approx(np.array([[1.0, 0.0, 0.8]]) * 6.0 * 10 ** (-6 / 20))
    sh.start(40.0)
    sh.abort(41.0)
    assert sh.state(41.0) == "ABORT" and sh.envelope_grms(41.02) == 0.0
    with pytest.raises(RuntimeError, match="aborted"):
        sh.start(42.0)
    sh.reset_abort(42.0)
    assert sh.state(42.0) == "IDLE"
    sh.start(50.0)
    sh.stop(50.0)  # stopped before it rose: at rest at once, not a ramp of zero height
    assert sh.state(50.0) == "IDLE" and sh.quiet_between(49.0, 60.0)


def test_measured_level_follows_the_envelope():
    sh = Shaker(np.random.default_rng(2))
    sh.set_profile(0.0, NAVMAT)
    sh.start(1.0)
    assert sh.measured_grms(1.0) == 0.0
    assert sh.measured_grms(20.0) == pytest.approx(NAVMAT.grms, rel=0.05)
    sine = Shaker(np.random.default_rng(2))
    sine.set_profile(0.0, SineProfile(100.0, 2.0))
    sine.start(0.0)
    assert sine.measured_grms(10.0) == pytest.approx(2.0 / math.sqrt(2), rel=1e-3)


# ---- on the wire --------------------------------------------------------------------------
class Rig:
    """World + shaker controller + sim-control served on loopback, read through pyvisa."""

    def __init__(self) -> None:
        self.world = World(5)
        self.table_still = True
        self.shaker = Shaker(self.world.rng("shaker"))
        self.device = ShakerController(self.world, self.shaker, table_at_rest=lambda t: self.table_still)
        self.server = InstrumentServer()
        self.server.add("shaker", "shaker", self.device)
        self.server.add("sim", "sim_control", SimControl(self.world, ["shaker"]))
        self.server.start()
        res = {e.name: e.resource for e in self.server.endpoints}
        self.rm = pyvisa.ResourceManager("@py")
        self.res = open_resource(res["shaker"], resource_manager=self.rm, timeout_ms=10000)
        self.clock = open_resource(res["sim"], resource_manager=self.rm, timeout_ms=10000)
        self.vt = VibrationTable(self.res, name="shaker")

    def wait(self, seconds: float) -> None:
        assert self.clock.query(f"SIM:TIME:ADV {seconds!r};*OPC?").strip() == "1"

    def idle(self) -> None:
        """At rest, interlock closed, level 0 dB, ramp 2 s (the profile stays)."""
        self.vt.stop()
        self.wait(self.vt.ramp_time_s + 0.1)
        self.res.write(":INT:CLOS")
        if self.vt.state == "ABORT":
            self.vt.interlock_reset()
        assert self.vt.state == "IDLE"
        with self.vt.configuring():
            self.vt.ramp_time_s = 2.0
        self.res.write(":PROF:SINE 100,1")  # a profile any level fits
        self.vt.level_db = 0.0

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


def test_profile_set_and_query_on_the_wire(rig):
    rig.idle()
    spec = rig.vt.set_random_profile(grms=6.0, f_lo_hz=20.0, f_hi_hz=2000.0)
    assert rig.res.query(":PROF?") == f"RAND,20.0,{spec.asd_g2hz[0]!r},2000.0,{spec.asd_g2hz[0]!r}"
    assert rig.vt.profile_grms == pytest.approx(6.0, rel=1e-8)
    rig.vt.level_db = -6.0
    assert rig.vt.target_grms == pytest.approx(6.0 * 10 ** (-6 / 20), rel=1e-8)
    rig.vt.level_db = 0.0


@settings(max_examples=15, deadline=None)
@given(profile=breakpoint_profiles(max_points=6))
def test_random_profile_round_trips(rig, profile):
    rig.idle()
    if profile.grms > 30.0 or ShakerLimits().violation(profile):
        with pytest.raises((ValueError, InstrumentError)):
            rig.vt.set_random_profile(profile.freqs_hz, profile.psd_g2hz)
        return
    sent = rig.vt.set_random_profile(profile.freqs_hz, profile.psd_g2hz)
    assert rig.vt.profile == RandomProfileSpec(profile.freqs_hz, profile.psd_g2hz) == sent
    assert rig.vt.profile_grms == pytest.approx(profile.grms, rel=1e-8)


@settings(max_examples=15, deadline=None)
@given(f=st.floats(5.0, 3000.0), g=st.floats(1e-3, 50.0), db=st.floats(-30.0, 0.0))
def test_sine_and_level_round_trip_or_are_refused_with_222(rig, f, g, db):
    rig.idle()
    rig.vt.level_db = 0.0
    problem = ShakerLimits().violation(SineProfile(f, g))
    if problem:
        with pytest.raises(InstrumentError) as err:
            rig.vt.set_sine(f, g)
        assert err.value.code == -222 and problem in err.value.message
        return
    rig.vt.set_sine(f, g)
    assert rig.vt.profile == SineProfileSpec(f, g)
    rig.vt.level_db = db
    assert rig.vt.level_db == pytest.approx(db, abs=1e-7)


def test_limits_and_states_refused_on_the_wire(rig):
    rig.idle()
    with pytest.raises(InstrumentError) as err:
        rig.vt.set_sine(5.0, 5.0)  # within the driver's 50 g, beyond the stroke
    assert err.value.code == -222 and "displacement peak 49.6811 mm not in 0..25.4 mm" in err.value.message
    rig.vt.set_random_profile(grms=20.0)
    with pytest.raises(InstrumentError) as err:
        rig.vt.level_db = 6.0
    assert err.value.code == -222 and "level 39.9052 g rms not in 0..30 g rms" in err.value.message
    rig.res.write(":PROF:RAND 2,0.01,100,0.01")
    assert rig.res.query("SYST:ERR?") == '-222,"Data out of range;frequency 2 Hz not in 5..3000 Hz"'
    rig.res.write(":LEV 7")
    assert rig.res.query("SYST:ERR?").startswith('-222,"Data out of range;LEV 7 not in -30..6')
    with pytest.raises(ValueError, match=r"freq_hz=4000 is outside the allowed range \[5, 3000\]"):
        rig.vt.set_sine(4000, 1.0)  # refused by the driver: nothing on the wire
    assert rig.res.query("SYST:ERR:COUN?") == "+0"
    rig.table_still = False
    with pytest.raises(InstrumentError, match="turntable moving") as err:
        rig.vt.start()
    assert err.value.code == -221
    rig.table_still = True


def test_start_run_read_level_stop(rig):
    rig.idle()
    rig.vt.set_random_profile(grms=6.0)
    rig.vt.ramp_time_s = 1.0
    rig.vt.start()
    assert rig.vt.state == "RAMP"
    with pytest.raises(InstrumentError) as err:
        rig.vt.set_sine(100.0, 1.0)
    assert err.value.code == -221
    assert rig.vt.wait_running(rig.wait, timeout_s=5.0, poll_s=0.25) == "RUN"
    rig.wait(2.0)
    assert rig.vt.level_grms == pytest.approx(6.0, rel=0.05)
    rig.vt.stop()
    assert rig.vt.wait_idle(rig.wait, timeout_s=5.0, poll_s=0.25) == "IDLE"
    rig.wait(1.0)
    assert rig.vt.level_grms == 0.0
    snap = rig.vt.snapshot()
    assert snap["settings"]["state"] == "IDLE" and snap["settings"]["axis"] == (0.0, 0.0, 1.0)


def test_interlock_aborts_and_wait_running_reports_it(rig):
    rig.idle()
    rig.vt.set_random_profile(grms=3.0)
    rig.vt.start()
    rig.res.write(":INT:OPEN")
    assert rig.vt.state == "ABORT" and rig.vt.interlock_closed is False
    with pytest.raises(VibrationAbortedError):
        rig.vt.wait_running(rig.wait, timeout_s=5.0)
    with pytest.raises(InstrumentError, match="interlock"):
        rig.vt.start()
    rig.res.write(":INT:CLOS")
    rig.wait(0.1)
    rig.vt.interlock_reset()
    assert rig.vt.state == "IDLE" and rig.vt.interlock_closed is True
