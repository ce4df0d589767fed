"""Protocol fuzzing of every simulated server.

(a) In process: a hypothesis state machine per SCPI device class interleaves valid
    settings, invalid messages (undefined headers, broken lexemes, truncated blocks ...),
    compound messages mixing both, random bytes, ``*ESR?``, ``SYST:ERR?`` and ``*CLS``
    against a model of the IEEE 488.2 status: every invalid unit queues exactly one
    command error (-1xx, -113 for an undefined header) and sets CME, leaves the settings
    unchanged, and ``*ESR?``/``SYST:ERR?`` read exactly what the model expects (FIFO,
    -350 on overflow).  ``process()`` never raises.
(b) Over real TCP (bench/testing/fuzz_wire.py): random bytes, over-long lines, huge declared
    blocks, unterminated strings and binary junk into every server including the gyro's
    serial line; after each burst the server answers a valid ``*IDN?`` (``$ID?``), and a
    second client on another instrument is served while the first misbehaves.
"""

from __future__ import annotations

import random
import socket
import threading
import time

import numpy as np
import pytest
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, initialize, invariant, rule

from bench.testing.fuzz_wire import GyroFuzzClient, ScpiFuzzClient, Tally, gyro_line, scpi_message
from sim.devices.dmm import Multimeter
from sim.devices.shaker import ShakerController
from sim.devices.sim_control import SimControl
from sim.devices.supply import PowerSupply
from sim.devices.turntable import TurntableController
from sim.physics.motion import DualAxisTable
from sim.physics.shaker import Shaker
from sim.scpi import ScpiDevice
from sim.scpi.errors import ERROR_MESSAGES, esr_bit_for
from sim.station import SimulatedStation
from sim.world import World


def _dmm(world):
    return Multimeter(world, "dmm", lambda t, aperture_s: np.full(np.shape(t), 1.25))


#: device kind -> (builder, valid setting commands, queries that read the settings)
DEVICES = {
    "dmm": (_dmm,
            ["VOLT:NPLC 10", "VOLT:NPLC 1", "SENS:VOLT:DC:RANG 10", "VOLT:RANG:AUTO ON",
             "TRIG:COUN 3", "TRIG:SOUR IMM", "SAMP:COUN 5", "FORM ASC", 'DISP:TEXT "fuzz"',
             "DISP:TEXT:CLE", "*ESE 60", "*SRE 32"],
            ["VOLT:NPLC?", "VOLT:RANG?", "VOLT:RANG:AUTO?", "TRIG:COUN?", "TRIG:SOUR?",
             "SAMP:COUN?", "FORM?", "DISP:TEXT?", "*ESE?", "*SRE?"]),
    "supply": (PowerSupply,
               ["VOLT 5,(@1)", "CURR 0.5,(@2)", "INST:NSEL 2", "APPL CH1,3,0.2",
                "OUTP OFF,(@1,2,3)", "VOLT 12,(@2:3)", "*ESE 4"],
               ["VOLT? (@1,2,3)", "CURR? (@1,2,3)", "OUTP? (@1,2,3)", "INST:NSEL?", "*ESE?"]),
    "turntable": (lambda world: TurntableController(world, DualAxisTable()),
                  ["LIM:RATE 1,50", "LIM:RATE 2,20", "LIM:ACC 2,100", "STOP 1", "INT:CLOS",
                   "MODE:OFF 2", "*SRE 16"],
                  ["LIM:RATE? 1", "LIM:RATE? 2", "LIM:ACC? 2", "MODE? 1", "MODE? 2",
                   "DEM:POS? 1", "DEM:RATE? 2", "STAT? 1", "*SRE?"]),
    "shaker": (lambda world: ShakerController(world, Shaker(world.rng("shaker")),
                                              table_at_rest=lambda t: True),
               ["RAMP 2", "RAMP 5", "LEV 0", "LEV -3", "INT:CLOS", "STOP", "*ESE 8"],
               ["RAMP?", "LEV?", "STAT?", "INT?", "PROF?", "*ESE?"]),
    "sim_control": (lambda world: SimControl(world, ["dmm"]),
                    ["SIM:TIME:ADV 0", "*ESE 1"],
                    ["SIM:TIME?", "SIM:SEED?", "*ESE?"]),
}

_WORD = st.text("ABCDEFGHIJKLMNOPQRSTUVWXYZ", min_size=1, max_size=8)
#: messages with exactly one command error; (message, expected code or None for any -1xx)
UNDEFINED = st.builds(lambda w, q, p: (f"ZQX{w}{q}{p}", -113), _WORD, st.sampled_from(["", "?"]),
                      st.sampled_from(["", " 1", " 1,2", ' "x"']))
UNDEFINED_COMMON = st.builds(lambda w, q: (f"*ZQ{w}{q}", -113), _WORD, st.sampled_from(["", "?"]))
LEXICAL = st.sampled_from([
    ('ZQX "abc', -151),          # unterminated string
    ("ZQX 'abc", -151),
    ("ZQX #5123", -161),         # block shorter than its declared length
    ("ZQX #9999999999", -161),   # declared length far beyond the message
    ("VOLT:NPLC 1 2 3", None),   # -121 where VOLT:NPLC exists, -113 elsewhere
    ("SYST:ERR?:", -102),
    ("::", -102),
    ("*ESE 1,", -102),
    ("*IDN? junk", -108),        # a parameter where none is allowed
    (":A" * 200, -113),
    ("ABCDEFGHIJKLMNOPQRSTUVWXYZ", -112),   # mnemonic longer than 12 characters
    ("*ABCDEFGHIJKLMN?", -112),
    ("1VOLT", -102),
    ("VOLT\x01NPLC 1", None),   # 0x01 is white space (IEEE 488.2 7.4.1.2)
])
INVALID = st.one_of(UNDEFINED, UNDEFINED_COMMON, LEXICAL)


def _code(entry: str) -> int:
    return int(entry.split(",", 1)[0])


class ScpiMachine(RuleBasedStateMachine):
    """Model: the error queue (codes, FIFO, bounded) and the ESR; the device's settings."""

    kind = "dmm"

    @initialize()
    def build(self):
        build, self.valid, self.state_queries = DEVICES[self.kind]
        self.device: ScpiDevice = build(World(11))
        self.queue: list[int] = []
        self.esr = 0x80  # PON after construction

    # -- helpers -------------------------------------------------------------------------------
    def ask(self, text: str) -> bytes | None:
        return self.device.process(text.encode("latin-1"))

    def settings(self) -> list[bytes | None]:
        n_before = len(self.device.errors)
        values = [self.ask(q) for q in self.state_queries]
        assert len(self.device.errors) == n_before, f"{self.kind}: a settings query failed"
        assert all(v is not None for v in values)
        return values

    def expect_error(self, code: int) -> None:
        self.esr |= esr_bit_for(code)
        if len(self.queue) < self.device.error_queue_size:
            self.queue.append(code)
        else:
            self.esr |= esr_bit_for(-350)
            self.queue[-1] = -350

    # -- rules -----------------------------------------------------------------------------------
    @rule(data=st.data())
    def valid_setting(self, data):
        command = data.draw(st.sampled_from(self.valid))
        n_before = len(self.device.errors)
        assert self.ask(command) is None
        assert len(self.device.errors) == n_before, (command, self.device.errors)

    @rule(case=INVALID)
    def invalid_message(self, case):
        message, expected = case
        before = self.settings()
        n_before = len(self.device.errors)
        assert self.ask(message) is None
        errors = self.device.errors
        if n_before < self.device.error_queue_size:
            assert len(errors) == n_before + 1, (message, errors)
            code = _code(errors[-1])
            assert -199 <= code <= -100, (message, errors[-1])
            if expected is not None:
                assert code == expected, (message, errors[-1])
        else:  # a full queue: the newest entry becomes -350, CME is set all the same
            code = -100
            assert _code(errors[-1]) == -350
        self.expect_error(code)
        assert self.settings() == before, message

    @rule(data=st.data(), case=UNDEFINED)
    def compound(self, data, case):
        """``valid;invalid;valid``: one error, and the good units still run."""
        good = data.draw(st.sampled_from(self.valid))
        if good.startswith("*"):
            return  # common commands have their own path; compound headers tested above
        n_before = len(self.device.errors)
        self.ask(f"{good};:{case[0]};*IDN?")
        if n_before < self.device.error_queue_size:
            assert _code(self.device.errors[-1]) == -113
            assert len(self.device.errors) == n_before + 1
        self.expect_error(-113)

    @rule(junk=st.binary(max_size=200))
    def random_bytes(self, junk):
        reply = self.device.process(junk)  # never raises
        assert reply is None or reply.endswith(b"\n")
        assert self.ask("*IDN?").count(b",") == 3
        # resynchronise the model from the device, after checking every entry is well formed
        for entry in self.device.errors:
            code = _code(entry)
            assert code in ERROR_MESSAGES or code > 0, entry
        assert self.ask("*CLS") is None
        self.queue, self.esr = [], 0

    @rule()
    def read_esr(self):
        assert int(self.ask("*ESR?")) == self.esr
        self.esr = 0

    @rule()
    def read_error(self):
        entry = self.ask("SYST:ERR?").decode().strip()
        assert _code(entry) == (self.queue.pop(0) if self.queue else 0), entry

    @rule()
    def clear_status(self):
        assert self.ask("*CLS") is None
        self.queue, self.esr = [], 0

    @rule()
    def identify(self):
        assert self.ask("*IDN?").decode().count(",") == 3

    @invariant()
    def status_byte_consistent(self):
        if not hasattr(self, "device"):
            return
        assert bool(self.device.stb & 0x04) == bool(self.queue)
        assert [_code(e) for e in self.device.errors] == self.queue


MACHINE_SETTINGS = settings(max_examples=25, stateful_step_count=30, deadline=None,
                            suppress_health_check=[HealthCheck.too_slow])


@pytest.mark.parametrize("kind", sorted(DEVICES))
def test_scpi_state_machine(kind):
    machine = type(f"ScpiMachine_{kind}", (ScpiMachine,), {"kind": kind})
    machine.TestCase.settings = MACHINE_SETTINGS
    machine.TestCase().runTest()


# -- (b) byte-level fuzzing over real TCP ------------------------------------------------------

COMMON_VALID = [("*IDN?", 1), ("*ESR?", 1), ("*STB?", 1), ("*OPC?", 1), ("*ESE 4", 0),
                ("*SRE?", 1), ("SYST:ERR?", 1)]
WIRE_KINDS = {"dmm": "dmm", "dmm_temp": "dmm", "supply": "supply", "turntable": "turntable",
              "shaker": "shaker", "sim": "sim_control"}


def wire_valid(name: str) -> list[tuple[str, int]]:
    _, sets, queries = DEVICES[WIRE_KINDS[name]]
    return COMMON_VALID + [(s, 0) for s in sets] + [(q, 1) for q in queries]


@pytest.fixture(scope="module")
def station(served_station):
    return served_station


def _power_gyro(sim) -> None:
    """Supply CH1 on: an unpowered gyro is silent by design (the supply fuzz turns it off)."""
    sim.server.call(sim.supply.process, b"APPL CH1,5,1;:OUTP ON,(@1)")


def _port(sim, name: str) -> int:
    return next(e.port for e in sim.endpoints if e.name == name)


def _client(sim, name: str) -> ScpiFuzzClient:
    return ScpiFuzzClient("127.0.0.1", _port(sim, name))


@pytest.mark.parametrize("name", sorted(WIRE_KINDS))
def test_scpi_server_survives_random_messages(station, name):
    rng = random.Random(f"fuzz:{name}")
    client, tally = _client(station, name), Tally()
    try:
        for _ in range(150):
            message, expect, replies = scpi_message(rng, wire_valid(name), big=False)
            client.send(message, expect, replies, tally)
        assert client.identify().count(b",") == 3
    finally:
        client.close()
    assert tally.wrong == []
    assert tally.invalid > 30 and tally.invalid_standard_error == tally.invalid
    assert tally.silent > 0 and tally.answered + tally.silent == tally.sent


@pytest.mark.parametrize("message,code", [
    (b"ZQX " + b"A" * ((1 << 20) + 1), -223),          # one byte over the message limit
    (b"*ESE #9999999999" + b"\xff" * 1000, -223),      # a block declared far beyond it
    (b"*ESE #800100000", None),                        # a block within it, never sent
    (b'*SRE "' + b"q" * 5000, -151),                   # an unterminated string
    (bytes(range(256)) * 64, None),                    # binary junk (holds LFs and blocks)
])
def test_hostile_inputs_leave_the_server_answering(station, message, code):
    client = _client(station, "dmm")
    try:
        expect = {None: "any", -223: "oversize", -151: "command"}[code]
        tally = Tally()
        client.send(message, expect, 0, tally)
        assert tally.wrong == [] and tally.answered + tally.silent == 1
        if code is not None:
            assert tally.invalid_standard_error == 1
        assert client.identify().startswith(b"Keysight Technologies,34465A,")
    finally:
        client.close()


def test_huge_declared_block_is_refused_at_once_without_reading_it(station):
    """A ``#9999999999`` header is answered (-223) as soon as its LF arrives; the server
    neither waits for nor buffers the ten gigabytes it announces."""
    with socket.create_connection(("127.0.0.1", _port(station, "dmm")), timeout=5) as s:
        s.sendall(b"*ESE #9999999999\nSYST:ERR?\n")
        reply = s.recv(200)
        assert reply.startswith(b'-223,"Too much data')


def test_abandoned_connections_mid_message_do_not_hurt(station):
    for tail in (b"*ESE #800100000abc", b'*SRE "open', b"ZQX " + b"B" * 300_000, b"\xff" * 10):
        with socket.create_connection(("127.0.0.1", _port(station, "supply")), timeout=5) as s:
            s.sendall(tail)  # and hang up mid-message
    client = _client(station, "supply")
    try:
        assert client.identify().startswith(b"Keysight Technologies,E36312A,")
    finally:
        client.close()


def test_gyro_line_survives_random_lines(station):
    _power_gyro(station)
    rng = random.Random("fuzz:gyro")
    client, tally = GyroFuzzClient("127.0.0.1", _port(station, "gyro")), Tally()
    try:
        for _ in range(200):
            line, expect = gyro_line(rng)
            client.send(line, expect, tally)
        client.conn.send(b"\xfe" * 5000 + b"\r\n")  # a binary line far over 64 bytes
        assert client.conn.line("overlong").startswith(b"$ERR,4,")
        assert client.identify().startswith(b"$ID,BENCHSIM,SFOG-2K,")
    finally:
        client.close()
    assert tally.wrong == []
    assert tally.invalid > 30 and tally.invalid_standard_error == tally.invalid


def test_second_client_is_served_while_the_first_misbehaves(station):
    """One client floods the dmm with junk, oversize lines and abandoned blocks; another
    keeps asking the supply (and the gyro line) and every query is answered."""
    _power_gyro(station)
    stop = threading.Event()
    failures: list[BaseException] = []

    def misbehave():
        rng = random.Random("fuzz:flood")
        client = _client(station, "dmm")
        try:
            while not stop.is_set():
                message, expect, replies = scpi_message(rng, wire_valid("dmm"))
                client.send(message, expect, replies)
        except BaseException as exc:
            failures.append(exc)
        finally:
            client.close()

    flood = threading.Thread(target=misbehave)
    flood.start()
    served = 0
    supply = _client(station, "supply")
    gyro = GyroFuzzClient("127.0.0.1", _port(station, "gyro"))
    try:
        time.sleep(0.05)
        for _ in range(40):
            assert supply.identify().startswith(b"Keysight Technologies,E36312A,")
            assert gyro.identify().startswith(b"$ID,")
            served += 1
    finally:
        stop.set()
        flood.join(30)
        supply.close()
        gyro.close()
    assert served == 40 and not failures, failures


# -- (a') the gyro line's command language, in process ---------------------------------------
BAUDS = (115200, 230400, 460800, 921600)


class _Link:
    """The server end of the line as the device sees it; collects what the unit sends."""

    def __init__(self) -> None:
        self.out = bytearray()
        self.pending_bytes = 0

    def write(self, data: bytes) -> None:
        self.out += data

    def write_frames(self, data: bytes, frame_bytes: int) -> None:
        self.out += data

    def lines(self) -> list[bytes]:
        text, self.out = bytes(self.out), bytearray()
        return [ln for ln in text.split(b"\r\n") if ln]


GYRO_COMMANDS = (b"$ID?", b"$CFG?", b"$RATE", b"$BAUD", b"$START", b"$STOP")


def _is_command(line: bytes) -> bool:
    """A line whose first word is a gyro-line command (any case): junk must not be one, or
    it may legitimately change the line's state (hypothesis draws the module's literals, such
    as b"$STOP", as binary examples); the command rules above cover them."""
    text = line.decode("ascii", errors="replace").strip()  # read as docs/FOG_SERIAL.md's server does
    head = text.replace(",", " ", 1).partition(" ")[0].upper()
    return head.encode("ascii", "replace") in GYRO_COMMANDS


class GyroLineMachine(RuleBasedStateMachine):
    """Model: RATE, BAUD and STOPPED/STREAMING.  Every line gets exactly one reply while
    stopped ($OK/$ID/$CFG or $ERR,<1..4>), a refused setting changes nothing, and while
    streaming only $STOP is answered (the world does not advance: no frames)."""

    @initialize()
    def build(self):
        self.sim = SimulatedStation()
        self.sim.supply.process(b"APPL CH1,5,1;:OUTP ON,(@1)")
        self.line, self.link = self.sim.gyro_line, _Link()
        assert self.line.connect(self.link)
        self.send(b"$CFG?")
        cfg = dict(f.split("=") for f in self.link.lines()[0].decode().split(",")[1:])
        self.rate, self.baud, self.streaming = int(cfg["RATE"]), int(cfg["BAUD"]), False

    def send(self, line: bytes) -> None:
        self.line.receive(self.link, line + b"\r\n")

    def one_reply(self) -> bytes:
        replies = self.link.lines()
        assert len(replies) == (0 if self.streaming else 1), replies
        return replies[0] if replies else b""

    @rule(rate=st.integers(-5, 12000))
    def set_rate(self, rate):
        self.send(f"$RATE {rate}".encode())
        reply = self.one_reply()
        if self.streaming:
            return
        if 1 <= rate <= 10000 and rate * 200 <= self.baud:
            assert reply == f"$OK,RATE,{rate}".encode()
            self.rate = rate
        else:
            assert reply.startswith(b"$ERR,3,"), reply

    @rule(baud=st.sampled_from(BAUDS + (9600, 0, 1000000)))
    def set_baud(self, baud):
        self.send(f"$BAUD,{baud}".encode())
        reply = self.one_reply()
        if self.streaming:
            return
        if baud in BAUDS and self.rate * 200 <= baud:
            assert reply == f"$OK,BAUD,{baud}".encode()
            self.baud = baud
        else:
            assert reply.startswith(b"$ERR,3,"), reply

    @rule(line=st.sampled_from([b"$FOO", b"$RATE abc", b"$RATE 1.5", b"$RATE", b"$ID? x",
                                b"$CFG? 1", b"$START 1", b"ID?", b"$" + b"Z" * 80,
                                b"\xff\xfe$ID?", b"$RATE nan", b"$BAUD 1e999"]))
    def invalid_line(self, line):
        self.send(line)
        reply = self.one_reply()
        if not self.streaming:
            assert reply[:5] == b"$ERR," and reply[5:6] in b"1234" and reply[6:7] == b",", reply

    @rule(junk=st.binary(max_size=100).map(lambda b: b.replace(b"\n", b"").replace(b"\r", b""))
          .filter(lambda b: not _is_command(b)))
    def junk(self, junk):
        self.send(junk)
        for reply in self.link.lines():  # an empty line gets no reply; anything else $ERR
            assert not self.streaming and reply.startswith(b"$ERR,"), reply

    @rule()
    def start(self):
        self.send(b"$START")
        assert self.one_reply() in (b"", b"$OK,START")
        self.streaming = True

    @rule()
    def stop(self):
        self.send(b"$stop")
        self.streaming = False
        assert self.one_reply() == b"$OK,STOP"

    @invariant()
    def configuration_matches_the_model(self):
        if not hasattr(self, "line") or self.streaming:
            return
        self.send(b"$CFG?")
        cfg = self.one_reply().decode()
        assert f"RATE={self.rate}," in cfg and f"BAUD={self.baud}," in cfg and "STATE=STOPPED" in cfg
        self.send(b"$ID?")
        assert self.one_reply().startswith(b"$ID,BENCHSIM,SFOG-2K,")


def test_gyro_line_state_machine():
    GyroLineMachine.TestCase.settings = settings(max_examples=15, stateful_step_count=25,
                                                 deadline=None,
                                                 suppress_health_check=[HealthCheck.too_slow])
    GyroLineMachine.TestCase().runTest()
