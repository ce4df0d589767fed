"""The simulated 34465A's level trigger and pretrigger capture (DIG option), as the
Truevolt guide describes them: SAMP:COUN:PRET newest readings before the trigger,
SAMP:COUN − SAMP:COUN:PRET after it, a level crossing in the direction of TRIG:SLOP."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sim.devices.dmm import LEVEL_WAIT_S, Multimeter
from sim.world import World

TRACE = ":VOLT:RANG 10;:VOLT:NPLC 0.02;:SAMP:SOUR TIM;:SAMP:TIM 0.001;:TRIG:DEL 0"


def ask(dev, text):
    out = dev.process(text.encode())
    return None if out is None else out.decode().strip()


def values(dev) -> np.ndarray:
    return np.array([float(x) for x in ask(dev, "FETC?").split(",")])


def ramp_meter(seed=0):
    """A meter whose input rises 1 V/s from 0 (a level it crosses at a known time)."""
    world = World(seed)
    return world, Multimeter(world, "dmm", lambda t, ap: t + ap / 2, ideal=True)


@pytest.fixture
def station(station_factory):
    return station_factory(seed=5)  # devices driven directly


def test_pretrigger_keeps_the_newest_readings_and_the_rest_follow_the_trigger():
    world, dmm = ramp_meter()
    ask(dmm, f"*RST;{TRACE};:SAMP:COUN 100;:SAMP:COUN:PRET 30;:TRIG:SOUR BUS;:INIT")
    world.advance(0.0105)
    assert ask(dmm, "DATA:POIN?") == "+11"      # readings taken while waiting
    world.advance(0.5)
    assert ask(dmm, "DATA:POIN?") == "+30"      # a ring of the pretrigger count
    t_trigger = world.now
    ask(dmm, "*TRG")
    got = values(dmm)
    assert got.size == 100 and ask(dmm, "SYST:ERR?") == '+0,"No error"'
    starts = got - 0.0002                       # the ramp reads its mid-aperture time
    assert starts[29] <= t_trigger < starts[29] + 0.001   # the reading in progress is pretrigger
    assert np.allclose(np.diff(starts), 0.001, atol=1e-5)  # one grid before and after the trigger
    assert ask(dmm, "STAT:QUES?") == "+0"       # the ring dropping old readings is no overflow


def test_an_early_trigger_saves_only_the_pretrigger_readings_taken():
    world, dmm = ramp_meter()
    ask(dmm, f"*RST;{TRACE};:SAMP:COUN 100;:SAMP:COUN:PRET 30;:TRIG:SOUR BUS;:INIT")
    world.advance(0.0045)                       # readings 0..4 started
    ask(dmm, "*TRG")
    assert values(dmm).size == 5 + 70           # memory was reserved for 30: 70 follow


def test_immediate_trigger_with_pretrigger_takes_count_minus_pretrigger():
    world, dmm = ramp_meter()
    assert len(ask(dmm, f"*RST;{TRACE};:SAMP:COUN 10;:SAMP:COUN:PRET 4;:READ?").split(",")) == 6


@pytest.mark.parametrize("slope", ["POS", "NEG"])
def test_level_trigger_fires_where_the_input_crosses_the_level(slope):
    world = World(1)
    sign = 1.0 if slope == "POS" else -1.0
    dmm = Multimeter(world, "dmm", lambda t, ap: sign * (t + ap / 2 - 2.0), ideal=True)  # 0.5 at t = 2.5
    level = 0.5 * sign
    ask(dmm, f"*RST;{TRACE};:SAMP:COUN 200;:SAMP:COUN:PRET 50;:TRIG:SOUR INT;"
             f":TRIG:LEV {level};:TRIG:SLOP {slope};:INIT")
    got = sign * values(dmm)
    assert got.size == 200
    assert np.all(got[:49] < 0.5) and np.all(got[49:] >= 0.5)  # the crossing reading is the 50th
    assert got[49] == pytest.approx(0.5, abs=0.0015)
    # FETC? let time pass in growing steps until the crossing, then to the 150th reading after
    # it: the clock may overshoot by one step (<= 1 s), the readings never do
    assert 2.5 + 150e-3 <= world.now <= 2.5 + 150e-3 + 1.0


def test_a_level_already_passed_does_not_fire_the_edge():
    world, dmm = ramp_meter()
    world.advance(1.0)                          # input at 1 V, above the level
    ask(dmm, f"*RST;{TRACE};:SAMP:COUN 10;:TRIG:SOUR INT;:TRIG:LEV 0.5;:TRIG:SLOP POS;:INIT")
    assert dmm.process(b"FETC?") is None        # no rising crossing: waits, then gives up
    assert ask(dmm, "SYST:ERR?").startswith("-230,")
    assert world.now == pytest.approx(1.0 + LEVEL_WAIT_S)


def test_level_trigger_on_the_accelerometer_switching_on(station):
    dmm, supply = station.dmm, station.supply
    ask(dmm, f"*RST;{TRACE};:SAMP:COUN 400;:SAMP:COUN:PRET 100;:TRIG:SOUR INT;:TRIG:LEV 3;"
             ":TRIG:SLOP POS;:INIT")
    station.world.advance(0.3)
    ask(supply, "APPL CH2,15,0.1;APPL CH3,15,0.1;:OUTP ON,(@2,3)")
    t_on = station.world.now
    got = values(dmm)
    assert got.size == 400 and np.all(np.abs(got[:99]) < 1e-3) and np.all(got[100:] > 6)
    assert station.world.now - t_on == pytest.approx(0.300, abs=0.002)  # 300 readings after it


def test_conflicts_are_refused_with_the_guides_codes():
    world, dmm = ramp_meter()
    ask(dmm, "*RST;:VOLT:RANG 1;:TRIG:SOUR INT;:TRIG:LEV 3;:INIT")   # outside ±120 % of 1 V
    assert ask(dmm, "SYST:ERR?").startswith("-221,") and ask(dmm, "TRIG:SOUR?") == "IMM"
    ask(dmm, "ABOR;*RST;:SAMP:COUN 10;:SAMP:COUN:PRET 10;:INIT")     # not below the sample count
    assert ask(dmm, "SYST:ERR?").startswith("-221,")
    ask(dmm, "*RST;:SAMP:COUN 10;:SAMP:COUN:PRET 2;:TRIG:COUN 2;:INIT")
    assert ask(dmm, "SYST:ERR?").startswith("-221,")
    plain = Multimeter(World(0), "dmm", lambda t, ap: t, options=("MEM",))
    for command in ("TRIG:SOUR INT", "TRIG:LEV 1", "SAMP:COUN:PRET 5"):
        ask(plain, command)
        assert ask(plain, "SYST:ERR?").startswith("-241,"), command   # DIG option needed


@settings(max_examples=15, deadline=None)
@given(st.lists(st.floats(0.001, 0.3), min_size=1, max_size=8), st.integers(0, 2**32 - 1))
def test_how_time_passes_before_the_trigger_never_changes_the_bytes(steps, seed):
    """Same seed, same bytes: a pretrigger capture advanced in arbitrary steps equals one
    advanced at once."""
    def run(chunks):
        world = World(seed)
        dmm = Multimeter(world, "dmm", lambda t, ap: np.sin(7 * t))
        ask(dmm, f"*RST;{TRACE};:SAMP:COUN 300;:SAMP:COUN:PRET 120;:TRIG:SOUR INT;:TRIG:LEV 0.5;"
                 ":FORM REAL,64;:INIT")
        for dt in chunks:
            world.advance(dt)
        return dmm.process(b"FETC?")

    assert run(steps) == run([sum(steps)])


def test_an_edge_in_the_instant_of_init_still_triggers(station):
    """INIT, then the supply switched on with no simulated time between: the comparator
    knows the input as it stood at INIT, so the first reading is the crossing."""
    dmm, supply = station.dmm, station.supply
    ask(dmm, f"*RST;{TRACE};:SAMP:COUN 400;:SAMP:COUN:PRET 100;:TRIG:SOUR INT;:TRIG:LEV 3;"
             ":TRIG:SLOP POS;:INIT")
    ask(supply, "APPL CH2,15,0.1;APPL CH3,15,0.1;:OUTP ON,(@2,3)")
    got = values(dmm)
    assert got.size == 1 + 300 and np.all(got > 6)  # the trigger came early: one pretrigger reading
