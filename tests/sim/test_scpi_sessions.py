"""Per-session status of the simulated SCPI instruments (``sim.scpi.engine``, "Sessions").

A Keysight LAN instrument keeps an error queue per remote I/O session: an error appears in
the queue of the session whose message caused it.  Here: a hypothesis property over random
interleavings of good and bad messages on the default session and two or three opened
sessions of each simulated SCPI instrument, checked against a model of each session's
queue and ESR; examples of the session API; and two real TCP connections to one served
instrument through pyvisa-py.
"""

from __future__ import annotations

import re
import time
from collections.abc import Iterator

import pytest
import pyvisa
from hypothesis import given, settings
from hypothesis import strategies as st

from sim.scpi import ScpiDevice, Session
from sim.scpi.errors import esr_bit_for
from sim.station import SimulatedStation

#: units every instrument answers without an error (absolute headers, so a compound message's
#: path never depends on the unit before), and units with exactly one error of a known code
GOOD_COMMON = ["*IDN?", "*OPC?", ":SYST:VERS?", "*TST?", "*OPT?", "*OPC", "*WAI"]
BAD_COMMON = [("ZQXB", -113), ("*ZZZ?", -113), ("*ESE 256", -222), ("*IDN? 1", -108), ("1ABC", -102),
              (":SYST:ERR:COUN 5", -113), ("*SRE 1000", -222)]
#: instrument -> (its own good units, its own bad units)
DEVICES: dict[str, tuple[list[str], list[tuple[str, int]]]] = {
    "dmm": ([":VOLT:NPLC 1", ":VOLT:NPLC?", ":TRIG:COUN 2", ":SENS:VOLT:DC:RANG 10"],
            [(":VOLT:NPLC 1000", -222), (":VOLT:DC:NPLC? (@101)", -224)]),
    "supply": ([":VOLT 1,(@1)", ":VOLT? (@1)", ":CURR? (@1,2,3)"], [(":VOLT 100,(@1)", -222)]),
    "daq": ([":VOLT:DC:NPLC 1,(@101)", ":VOLT:DC:NPLC? (@101)", ":TRIG:COUN 2"],
            [(":VOLT:NPLC 1000,(@101)", -222), (":VOLT:NPLC?", -109)]),
    "turntable": ([":LIM:RATE 1,50", ":LIM:RATE? 1"], []),
    "shaker": ([":RAMP 2", ":RAMP?"], []),
    "angular_table": ([], []),
}
#: single-message status reads and clears, checked against the model
STATUS = ["SYST:ERR?", "SYST:ERR:COUN?", "SYST:ERR:ALL?", "*ESR?", "*CLS", "*STB?"]
_ENTRY = re.compile(r'([+-]\d+),"(?:[^"]|"")*"')  # one queue entry: code and quoted text


def _codes(reply: bytes | None) -> list[int]:
    """The codes of a ``SYST:ERR?``/``SYST:ERR:ALL?`` reply, ``+0`` entries dropped."""
    assert reply is not None and reply.endswith(b"\n")
    return [c for c in map(int, _ENTRY.findall(reply.decode("latin-1"))) if c != 0]


class Model:
    """What one session's queue and ESR must hold (SCPI-1999 §21.8.1, IEEE 488.2 §11.5.1)."""

    def __init__(self, capacity: int) -> None:
        self.capacity, self.esr = capacity, 0
        self.queue: list[int] = []

    def error(self, code: int) -> None:
        self.esr |= esr_bit_for(code)
        if len(self.queue) < self.capacity:
            self.queue.append(code)
        else:  # the newest entry becomes -350; the older ones stay
            self.esr |= esr_bit_for(-350)
            self.queue[-1] = -350


@pytest.fixture(scope="module")
def station(station_factory) -> SimulatedStation:
    return station_factory(seed=3)


def _step(device: ScpiDevice, session: Session | None, model: Model, message: str | list[str],
          bad: dict[str, int]) -> None:
    """Send one program message on ``session`` and check what the model says it must give;
    ``bad``: the device's bad units and their codes."""
    if isinstance(message, list):  # a compound message of good and bad units
        device.process(";".join(message).encode(), session)
        for unit in message:
            if unit == "*OPC":
                model.esr |= 0x01
            code = bad.get(unit)
            if code is not None:
                model.error(code)
        return
    reply = device.process(message.encode(), session)
    if message == "SYST:ERR?":
        assert _codes(reply) == model.queue[:1]
        model.queue[:1] = []
    elif message == "SYST:ERR:COUN?":
        assert reply == f"{len(model.queue):+d}\n".encode()
    elif message == "SYST:ERR:ALL?":
        assert _codes(reply) == model.queue
        model.queue = []
    elif message == "*ESR?":
        assert reply == f"{model.esr:+d}\n".encode()
        model.esr = 0
    elif message == "*CLS":
        model.queue, model.esr = [], 0
    else:  # *STB?: EAV (bit 2) is this session's queue, whatever the others hold
        assert reply is not None and bool(int(reply) & 0x04) == bool(model.queue)


def _units(name: str) -> st.SearchStrategy[str]:
    good, bad = DEVICES[name]
    return st.sampled_from(GOOD_COMMON + good + [u for u, _ in BAD_COMMON + bad])


@pytest.mark.parametrize("name", list(DEVICES))
@settings(max_examples=100)
@given(data=st.data())
def test_each_session_has_its_own_fifo_error_queue_and_esr(station, name, data):
    """Errors made on one session never appear in another's ``SYST:ERR?``; each queue is FIFO
    with -350 on overflow, ``*ESR?`` reads this session's bits, ``*CLS`` clears only its own."""
    device = station.devices[name]
    assert isinstance(device, ScpiDevice)
    bad = dict(BAD_COMMON + DEVICES[name][1])
    opened = [device.open_session() for _ in range(data.draw(st.integers(2, 3), label="sessions"))]
    sessions: list[Session | None] = [None, *opened]  # the default session takes part too
    try:
        for s in sessions:
            device.process(b"*CLS", s)  # a known start: the first session opened may hold PON
        models = [Model(device.error_queue_size) for _ in sessions]
        actions = st.one_of(st.lists(_units(name), min_size=1, max_size=3), st.sampled_from(STATUS))
        steps = data.draw(st.lists(st.tuples(st.integers(0, len(sessions) - 1), actions), max_size=40),
                          label="steps")
        for k, message in steps:
            _step(device, sessions[k], models[k], message, bad)
        for s, model in zip(sessions, models):
            _step(device, s, model, "*ESR?", bad)
            _step(device, s, model, "SYST:ERR:ALL?", bad)
    finally:
        for s in opened:
            device.close_session(s)
    assert not set(opened) & set(device.sessions)


# -- the session API, by example --------------------------------------------------------------
def _device() -> ScpiDevice:
    return ScpiDevice(("Keysight Technologies", "34465A", "SIM0001", "A.03.01"), error_queue_size=3)


def ask(dev: ScpiDevice, message: str, session: Session | None = None) -> str:
    reply = dev.ask(message, session)
    assert reply is not None, message
    return reply


def test_the_first_session_to_open_takes_power_on_and_later_ones_start_clear():
    dev = _device()
    first, second = dev.open_session(), dev.open_session()
    assert dev.ask("*ESR?", first) == "+128" and dev.ask("*ESR?", second) == "+0"
    assert dev.ask("*ESR?") == "+128"  # the default session had its own PON
    assert dev.sessions == (first, second)
    dev.close_session(first)
    dev.close_session(first)  # closing twice does nothing
    assert dev.sessions == (second,)


def test_an_instrument_error_reaches_every_session_and_waits_for_one_when_none_is_open():
    dev = _device()
    a = dev.open_session()
    dev.process(b"*CLS", a)
    dev.instrument_error(-240, "measurement failed")
    assert ask(dev, "SYST:ERR?", a).startswith("-240,") and ask(dev, "SYST:ERR?").startswith("-240,")
    dev.close_session(a)
    dev.push_error(-222, "left over")  # no message being processed: the instrument's own error
    b, c = dev.open_session(), dev.open_session()
    assert ask(dev, "SYST:ERR:ALL?", b).startswith('-222,"Data out of range;left over"')
    assert ask(dev, "*ESR?", b) == "+16"  # EXE (PON went to the first session, a)
    assert dev.ask("SYST:ERR?", c) == '+0,"No error"'  # taken by the first session to open


def test_an_error_queued_by_a_transport_for_a_session_stays_in_it():
    dev = _device()
    a, b = dev.open_session(), dev.open_session()
    dev.push_error(-223, "too much", session=a)
    with dev.in_session(b):
        dev.push_error(-310)  # e.g. a fault hook run while b's message is handled
        assert dev.errors == ['-310,"System error"'] and dev.stb & 0x04
    assert ask(dev, "SYST:ERR:ALL?", a).startswith("-223,") and ask(dev, "SYST:ERR:COUN?", b) == "+1"
    assert dev.errors == [] and dev.ask("SYST:ERR:COUN?") == "+0"  # the default session saw none


def test_ese_sre_and_the_status_byte_are_each_sessions_own():
    dev = _device()
    a, b = dev.open_session(), dev.open_session()
    dev.process(b"*CLS;*ESE 32;*SRE 32;ZQXB", a)
    assert dev.ask("*STB?", a) == "+100"  # EAV + ESB + MSS
    assert dev.ask("*STB?", b) == "+0" and dev.ask("*ESE?", b) == "+0" and dev.ask("*SRE?", b) == "+0"
    dev.process(b"*CLS;*OPC", b)
    assert dev.ask("*ESR?", b) == "+1" and dev.ask("*ESR?", a) == "+32"


def test_each_session_frames_its_own_byte_stream():
    dev = _device()
    a, b = dev.open_session(), dev.open_session()
    assert dev.feed(b"*ID", a) == b""
    assert dev.feed(b"SYST:ERR?\n", b) == b'+0,"No error"\n'  # a's partial message is a's alone
    assert dev.feed(b"N?\n", a).startswith(b"Keysight Technologies,34465A")


def test_power_on_resets_every_sessions_status():
    dev = _device()
    a = dev.open_session()
    dev.process(b"ZQXB;*ESR?", a)
    dev.process(b"ZQXB")
    dev.power_on_status()
    for s in (a, None):
        assert dev.ask("SYST:ERR:COUN?", s) == "+0" and dev.ask("*ESR?", s) == "+128"
    assert dev.ask("*ESR?", dev.open_session()) == "+128"  # and for the next to open


# -- over the wire --------------------------------------------------------------------------------
@pytest.fixture
def rm() -> Iterator[pyvisa.ResourceManager]:
    manager = pyvisa.ResourceManager("@py")
    yield manager
    manager.close()


def _code(reply: str) -> int:
    return int(reply.split(",", 1)[0])


def test_two_tcp_connections_to_one_instrument_read_their_own_errors(served_station, rm):
    dmm = served_station.dmm
    address = served_station.resources()["dmm"]
    a, b = (rm.open_resource(address, read_termination="\n", write_termination="\n", timeout=10000)
            for _ in range(2))
    try:
        for inst in (a, b):
            inst.write("*CLS")
        a.write("ZQXB")
        b.write("VOLT:NPLC 1000")
        assert _code(a.query("SYST:ERR?")) == -113 and _code(a.query("SYST:ERR?")) == 0
        assert _code(b.query("SYST:ERR?")) == -222 and _code(b.query("SYST:ERR?")) == 0
        a.write("ZQXB;ZQXC")
        assert a.query("*OPC?") == "1"  # a's errors are queued before b clears its own
        b.write("*CLS")
        assert b.query("SYST:ERR:COUN?") == "+0"
        assert a.query("SYST:ERR:COUN?") == "+2" and a.query("*ESR?") == "+32"
        assert served_station.server.call(lambda: len(dmm.sessions)) == 2
    finally:
        a.close()
        b.close()
    deadline = time.monotonic() + 10
    while served_station.server.call(lambda: len(dmm.sessions)) and time.monotonic() < deadline:
        time.sleep(0.01)
    assert served_station.server.call(lambda: dmm.sessions) == ()  # closed with their connections
    c = rm.open_resource(address, read_termination="\n", write_termination="\n", timeout=10000)
    try:
        assert c.query("SYST:ERR:COUN?") == "+0"  # a's errors went with a
    finally:
        c.close()
