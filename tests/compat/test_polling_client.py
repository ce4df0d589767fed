"""A client that polls instead of waiting — ``INIT``, then ``DATA:POIN?`` in a loop with a sleep,
as a LabVIEW status loop or PyMeasure's HP34401A "stored readings" pattern does — against
``bench sim serve --pace 20``: the world follows the wall clock twenty times faster, so the
readings accumulate while the client sleeps and the loop ends.  On the default, event-driven
server the same loop would never end: time moves only when a client waits (a blocking query
such as ``*OPC?`` or ``FETC?``), so ``DATA:POIN?`` stays ``+0`` ("The simulated world"
in docs/ARCHITECTURE.md; "Simulated time" in docs/howto/real-instruments.md).

Paced replies depend on when they are asked, so nothing here is timed beyond generous bounds:
the counts a loop sees only have to grow, and end at the count asked for."""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable

import numpy as np
import pytest
import pyvisa
from pymeasure.instruments.hp import HP34401A

from tests.compat.serving import PYVISA_OPTIONS, pymeasure_options, serve

PACE = 20
POLL_S = 0.05
DEADLINE_S = 60.0  # the acquisitions below take about 2 s of wall time at PACE


@pytest.fixture(scope="module")
def paced():
    """``bench sim serve --pace 20`` beside the suite's own (event-driven) server."""
    with serve("--pace", str(PACE)) as resources:
        yield resources


@pytest.fixture(scope="module")
def paced_raw(paced):
    """Plain pyvisa sessions on the paced server, by name, in the address form named."""
    rm = pyvisa.ResourceManager("@py")
    opened = []

    def open_(name, transport):
        opened.append(rm.open_resource(paced[(name, transport)], **PYVISA_OPTIONS[transport]))
        return opened[-1]

    yield open_
    for session in opened:
        session.close()  # not rm.close(): it would close the suite's other sessions too


def _poll_until(count: Callable[[], float], target: int) -> list[int]:
    """The status loop: every count read, in order, until ``target`` (or the deadline)."""
    seen = [int(count())]
    deadline = time.monotonic() + DEADLINE_S
    while seen[-1] < target:
        assert time.monotonic() < deadline, f"DATA:POIN? stuck at {seen[-1]} of {target}"
        time.sleep(POLL_S)
        seen.append(int(count()))
    return seen


def _grew_to(seen: list[int], target: int) -> None:
    assert seen == sorted(seen) and seen[-1] == target, seen
    assert 0 < seen[0] < target, seen  # readings arrived while the client slept, and more came
    assert len(set(seen)) >= 3, seen


def test_init_sleep_then_poll_data_points_over_hislip(paced_raw):
    """Plain pyvisa over HiSLIP: 40 readings on the meter's sample timer, 1 s apart (40 s of
    world time, about 2 s of wall time at 20x)."""
    dmm, sim = paced_raw("dmm", "hislip"), paced_raw("sim", "hislip")
    dmm.write("*RST;*CLS;:CONF:VOLT:DC 10;:SAMP:COUN 40;:SAMP:SOUR TIM;:SAMP:TIM 1")
    assert dmm.query("SYST:ERR?") == '+0,"No error"\n'
    started = float(sim.query("SIM:TIME?"))
    dmm.write("INIT")
    time.sleep(0.25)  # the script does something else meanwhile
    seen = _poll_until(lambda: float(dmm.query("DATA:POIN?")), 40)
    _grew_to(seen, 40)
    assert float(sim.query("SIM:TIME?")) - started >= 39.0  # the world ran the acquisition through
    readings = dmm.query_ascii_values("FETC?")
    assert len(readings) == 40 and np.all(np.isfinite(readings))
    assert dmm.query("SYST:ERR?") == '+0,"No error"\n'


def test_pymeasure_stored_readings_pattern_over_the_socket(paced, paced_raw):
    """PyMeasure's HP34401A as its users poll a 34401A: ``init_trigger()``, then
    ``stored_readings_count`` until it is there, then ``stored_reading``.  The 34401A has no
    sample timer: 20 triggers, each after a 2 s trigger delay, take a reading each."""
    supply = paced_raw("supply", "scpi")
    supply.write("*RST;:APPL CH2,15,0.1;APPL CH3,15,0.1;:OUTP ON,(@2,3)")  # the accelerometer on
    assert supply.query("SYST:ERR?") == '+0,"No error"'
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)  # HP34401A: SCPI support "unknown"
        hp = HP34401A(paced[("dmm", "scpi")], **pymeasure_options("scpi"))
    try:
        hp.reset()
        hp.clear()
        hp.function_ = "DCV"
        hp.nplc = 1
        hp.sample_count = 1
        hp.trigger_count = 20
        hp.trigger_auto_delay_enabled = False
        hp.trigger_delay = 2
        assert hp.check_errors() == []
        hp.init_trigger()
        time.sleep(0.25)
        seen = _poll_until(lambda: hp.stored_readings_count, 20)
        _grew_to(seen, 20)
        readings = hp.stored_reading
        assert len(readings) == 20
        assert np.mean(readings) == pytest.approx(6.6, rel=0.05)  # the unit's output at 1 g
        assert hp.check_errors() == []
    finally:
        hp.adapter.close()
        supply.write("OUTP OFF,(@1:3)")


def test_the_default_server_moves_only_when_a_client_waits(addresses, transport):
    """The suite's own server is event-driven (the default): the same loop sees ``+0`` however
    long it sleeps, until a blocking query lets the world run the acquisition through."""
    rm = pyvisa.ResourceManager("@py")
    dmm = rm.open_resource(addresses["dmm"], **PYVISA_OPTIONS[transport])
    try:
        dmm.write("*RST;*CLS;:SAMP:COUN 40;:SAMP:SOUR TIM;:SAMP:TIM 1;:INIT")
        for _ in range(4):
            time.sleep(POLL_S)
            assert dmm.query("DATA:POIN?").strip() == "+0"
        assert dmm.query("*OPC?").strip() == "1"  # waits: 40 s of world time, at once
        assert dmm.query("DATA:POIN?").strip() == "+40"
        assert dmm.query("SYST:ERR?").strip() == '+0,"No error"'
    finally:
        dmm.close()
