"""HiSLIP (IVI-6.1) beside the raw socket: every SCPI instrument of the simulated station
answers at ``TCPIP::127.0.0.1::hislip0,PORT::INSTR`` with the same device.

The clients are independent of the server's codec (``sim.hislip_wire``): pyvisa with the
``@py`` backend (and its protocol client ``pyvisa_py.protocols.hislip`` where pyvisa-py 0.8
offers no VISA call: locks, trigger), and a raw client below that packs headers itself, for
the byte-exact and the malformed cases.
"""

from __future__ import annotations

import json
import os
import random
import socket
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import pytest
import pyvisa
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pyvisa.resources import MessageBasedResource
from pyvisa_py.protocols import hislip as pyhislip

from bench.testing.fuzz_wire import ERROR_LINE, PROBE, Tally, scpi_message
from instruments import Keysight34465A, open_resource
from instruments.power_supply import KeysightE36312A
from sim.hislip import HISLIP
from sim.server import SCPI
from sim.station import INSTRUMENTS, SimulatedStation

# message types and codes as IVI-6.1 Table 4, 7 and 9 number them (written here, not imported)
INITIALIZE, INITIALIZE_RESPONSE, FATAL_ERROR, ERROR = 0, 1, 2, 3
ASYNC_LOCK, ASYNC_LOCK_RESPONSE, DATA, DATA_END = 4, 5, 6, 7
DEVICE_CLEAR_COMPLETE, DEVICE_CLEAR_ACKNOWLEDGE = 8, 9
ASYNC_REMOTE_LOCAL_CONTROL, ASYNC_REMOTE_LOCAL_RESPONSE, TRIGGER, INTERRUPTED, ASYNC_INTERRUPTED = 10, 11, 12, 13, 14
ASYNC_MAXIMUM_MESSAGE_SIZE, ASYNC_MAXIMUM_MESSAGE_SIZE_RESPONSE = 15, 16
ASYNC_INITIALIZE, ASYNC_INITIALIZE_RESPONSE, ASYNC_DEVICE_CLEAR = 17, 18, 19
ASYNC_STATUS_QUERY, ASYNC_STATUS_RESPONSE, ASYNC_DEVICE_CLEAR_ACKNOWLEDGE = 21, 22, 23
ASYNC_LOCK_INFO, ASYNC_LOCK_INFO_RESPONSE = 24, 25
FIRST_ID = 0xFFFF_FF00
MAV, EAV = 0x10, 0x04
HEADER = struct.Struct("!2sBBIQ")
SCPI_NAMES = [row.name for row in INSTRUMENTS if row.transport is SCPI] + ["sim"]


def frame(kind: int, control: int = 0, parameter: int = 0, payload: bytes = b"", prologue: bytes = b"HS") -> bytes:
    return HEADER.pack(prologue, kind, control, parameter, len(payload)) + payload


def read_message(sock: socket.socket) -> tuple[int, int, int, bytes]:
    """(type, control code, parameter, payload) of the next message on ``sock``."""
    _, kind, control, parameter, length = HEADER.unpack(pyhislip.receive_exact(sock, HEADER.size))
    return kind, control, parameter, bytes(pyhislip.receive_exact(sock, length))


def connect(port: int) -> socket.socket:
    """A client channel, each message sent at once (TCP_NODELAY, as VISA clients set it)."""
    sock = socket.create_connection(("127.0.0.1", port), timeout=5)
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    return sock


def closed_after(sock: socket.socket) -> bool:
    """True when the server closes ``sock`` (EOF) before 5 s."""
    sock.settimeout(5)
    try:
        while sock.recv(4096):
            pass
    except ConnectionResetError:
        pass
    return True


class RawSession:
    """A HiSLIP session opened by hand: both channels, MessageIDs and RMT-delivered kept as
    a client keeps them (§3.1.2): the first message after a whole reply reports it."""

    def __init__(self, port: int, sub_address: bytes = b"hislip0") -> None:
        self.port = port
        self.sync = connect(port)
        self.sync.sendall(frame(INITIALIZE, 0, 0x0100 << 16 | 0x5858, sub_address))
        kind, control, parameter, _ = read_message(self.sync)
        assert (kind, control, parameter >> 16) == (INITIALIZE_RESPONSE, 0, 0x0100)  # synchronized, 1.0
        self.session_id = parameter & 0xFFFF
        self.asynchronous = connect(port)
        self.asynchronous.sendall(frame(ASYNC_INITIALIZE, 0, self.session_id))
        assert read_message(self.asynchronous)[0] == ASYNC_INITIALIZE_RESPONSE
        self.next_id = FIRST_ID
        self.last_id = FIRST_ID - 2
        self.delivered = 0  # RMT-delivered, to report with the next message

    def _rmt(self, rmt: int | None) -> int:
        flag, self.delivered = (self.delivered if rmt is None else rmt), 0
        return flag

    def send(self, payload: bytes, kind: int = DATA_END, rmt: int | None = None) -> int:
        message_id, self.last_id = self.next_id, self.next_id
        self.next_id = (self.next_id + 2) & 0xFFFF_FFFF
        self.sync.sendall(frame(kind, self._rmt(rmt), message_id, payload))
        return message_id

    def reply(self, message_id: int) -> bytes:
        """The response to ``message_id``: Data... DataEnd with that id (others skipped)."""
        out = b""
        while True:
            kind, _, parameter, payload = read_message(self.sync)
            if kind in (DATA, DATA_END) and parameter in (message_id, 0xFFFF_FFFF):
                out += payload
                if kind == DATA_END and parameter == message_id:
                    self.delivered = 1
                    return out
            elif kind in (DATA, DATA_END):
                out = b""  # a stale response (§3.1.2 rule 1)

    def ask(self, text: bytes, rmt: int | None = None) -> bytes:
        return self.reply(self.send(text + b"\n", rmt=rmt))

    def status(self, rmt: int | None = None) -> int:
        self.asynchronous.sendall(frame(ASYNC_STATUS_QUERY, self._rmt(rmt), self.last_id))
        kind, control, _, _ = read_message(self.asynchronous)
        assert kind == ASYNC_STATUS_RESPONSE
        return control

    def close(self) -> None:
        self.sync.close()
        self.asynchronous.close()


@pytest.fixture(scope="module")
def station(served_station: SimulatedStation) -> SimulatedStation:
    return served_station


@pytest.fixture(scope="module")
def rm() -> Iterator[pyvisa.ResourceManager]:
    manager = pyvisa.ResourceManager("@py")
    yield manager
    manager.close()


def open_visa(rm: pyvisa.ResourceManager, address: str, **options: Any) -> MessageBasedResource:
    resource = rm.open_resource(address, **options)
    assert isinstance(resource, MessageBasedResource)
    return resource


def port_of(station: SimulatedStation, name: str) -> int:
    return next(e.also["hislip"].port for e in station.endpoints if e.name == name)


@pytest.fixture
def raw(station: SimulatedStation) -> Iterator[RawSession]:
    session = RawSession(port_of(station, "dmm"))
    yield session
    session.close()


# -- addresses -------------------------------------------------------------------------------
def test_every_scpi_instrument_has_a_hislip_address_beside_its_unchanged_socket(station: SimulatedStation) -> None:
    hislip = station.resources("hislip")
    assert list(hislip) == SCPI_NAMES
    for name, resource in hislip.items():
        assert resource == f"TCPIP::127.0.0.1::hislip0,{port_of(station, name)}::INSTR"
    primary = station.resources()
    assert [e.name for e in station.endpoints] == [row.name for row in INSTRUMENTS] + ["sim"]
    assert all(e.transport is row.transport for e, row in zip(station.endpoints, INSTRUMENTS))
    assert all(primary[n].endswith("::SOCKET") for n in SCPI_NAMES)
    assert station.resources("scpi") == {n: primary[n] for n in SCPI_NAMES}
    assert HISLIP.resource("10.0.0.5", 4880) == "TCPIP::10.0.0.5::hislip0::INSTR"  # the IANA port
    bound = [s.getsockname()[0] for server in station.server._also_servers
             for s in getattr(server, "sockets", ())]
    assert len(bound) == len(SCPI_NAMES) and set(bound) == {"127.0.0.1"}


def test_sim_serve_lists_the_hislip_addresses_after_the_sockets(rm: pyvisa.ResourceManager) -> None:
    proc = subprocess.Popen([sys.executable, "-m", "bench.app.cli", "sim", "serve", "--seed", "1", "--only", "dmm"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONUNBUFFERED": "1"})
    try:
        lines = [json.loads(proc.stdout.readline()) for _ in range(4)]  # type: ignore[union-attr]  # stdout=PIPE: never None
        assert [(d["name"], d["transport"]) for d in lines] == [
            ("dmm", "scpi"), ("sim", "scpi"), ("dmm", "hislip"), ("sim", "hislip")]
        assert lines[2]["kind"] == "multimeter" and lines[2]["driver"] == "keysight_34465a"
        dmm = open_visa(rm, lines[2]["resource"], timeout=5000)
        assert dmm.query("*IDN?").startswith("Keysight Technologies,34465A,")
        dmm.close()
    finally:
        proc.terminate()
        proc.wait(10)


# -- pyvisa, no termination settings ------------------------------------------------------------
@pytest.mark.parametrize("name, model, setting, query, answer", [
    ("dmm", "34465A", "VOLT:NPLC 1", "VOLT:NPLC?", "+1.00000000E+00\n"),
    ("supply", "E36312A", "VOLT 2.5,(@1)", "VOLT? (@1)", "+2.50000000E+00\n"),
])
def test_pyvisa_reads_whole_replies_ended_by_dataend(station: SimulatedStation, rm: pyvisa.ResourceManager,
                                                     name: str, model: str, setting: str, query: str,
                                                     answer: str) -> None:
    res = open_visa(rm, station.resources("hislip")[name], timeout=5000)
    sock = open_visa(rm, station.resources()[name], read_termination="\n", write_termination="\n",
                            timeout=5000)
    try:
        idn = res.query("*IDN?")
        assert idn.startswith(f"Keysight Technologies,{model},") and idn.endswith("\n") and idn.count("\n") == 1
        res.write(setting)
        assert res.query(query) == answer
        assert res.query("*OPC?") == "1\n"
        assert sock.query(query) == answer.rstrip("\n")  # one device behind both wires
        assert res.query("SYST:ERR?") == '+0,"No error"\n'
    finally:
        res.close()
        sock.close()


def test_definite_length_blocks_read_by_byte_count(station: SimulatedStation, rm: pyvisa.ResourceManager) -> None:
    res = open_visa(rm, station.resources("hislip")["dmm"], timeout=10_000)
    sock = open_visa(rm, station.resources()["dmm"], read_termination="\n", write_termination="\n",
                            timeout=10_000)
    try:
        res.write("CONF:VOLT:DC 10;:FORM REAL,64;:FORM:BORD SWAP;:TRIG:SOUR IMM;:SAMP:COUN 40")
        assert res.query("*OPC?") == "1\n"
        res.write("INIT")
        assert res.query("*OPC?") == "1\n"
        values = np.asarray(res.query_binary_values("FETC?", datatype="d", is_big_endian=False))
        assert values.shape == (40,) and np.all(np.isfinite(values))
        res.write("FETC?")
        raw = res.read_raw()
        assert raw[:5] == b"#3320" and len(raw) == 5 + 320 + 1 and raw.endswith(b"\n")
        over_socket = np.asarray(sock.query_binary_values("FETC?", datatype="d", is_big_endian=False))
        np.testing.assert_array_equal(over_socket, values)  # the same memory behind both wires
        removed = np.asarray(res.query_binary_values("R? 15", datatype="d", is_big_endian=False))
        np.testing.assert_array_equal(removed, values[:15])
        assert res.query("DATA:POIN?") == "+25\n"
    finally:
        res.write("FORM ASC")
        res.close()
        sock.close()


def test_device_clear_keeps_settings_and_errors_and_the_session_goes_on(
        station: SimulatedStation, rm: pyvisa.ResourceManager) -> None:
    res = open_visa(rm, station.resources("hislip")["supply"], timeout=5000)
    try:
        res.write("*ESE 60;ZQXUNDEFINED")
        res.clear()
        assert res.query("*ESE?") == "+60\n"
        assert res.query("SYST:ERR?") == '-113,"Undefined header"\n'
        assert res.query("*OPC?") == "1\n"
    finally:
        res.write("*ESE 0")
        res.close()


def test_status_byte_has_mav_until_the_reply_is_read_and_eav_per_session(
        station: SimulatedStation, rm: pyvisa.ResourceManager) -> None:
    res = open_visa(rm, station.resources("hislip")["dmm"], timeout=5000)
    other = open_visa(rm, station.resources("hislip")["dmm"], timeout=5000)
    try:
        assert res.read_stb() & (MAV | EAV) == 0
        res.write("*IDN?")
        deadline = time.monotonic() + 5
        while not res.read_stb() & MAV:
            assert time.monotonic() < deadline, "MAV never set"
        assert res.read().startswith("Keysight Technologies,34465A,")
        assert res.read_stb() & MAV == 0
        res.write("ZQXUNDEFINED")
        assert res.read_stb() & EAV and not other.read_stb() & EAV  # each session its own queue
        assert other.query("SYST:ERR?") == '+0,"No error"\n'
        assert res.query("SYST:ERR?") == '-113,"Undefined header"\n'
        assert res.read_stb() & (MAV | EAV) == 0
    finally:
        res.close()
        other.close()


def test_two_sessions_at_once_share_the_instrument_not_the_queue(
        station: SimulatedStation, rm: pyvisa.ResourceManager) -> None:
    first = open_visa(rm, station.resources("hislip")["dmm"], timeout=5000)
    second = open_visa(rm, station.resources("hislip")["dmm"], timeout=5000)
    try:
        first.write("VOLT:NPLC 10")
        second.write("ZQXUNDEFINED")
        for _ in range(20):
            assert first.query("*OPC?") == "1\n" and second.query("VOLT:NPLC?") == "+1.00000000E+01\n"
        assert first.query("SYST:ERR?") == '+0,"No error"\n'
        assert second.query("SYST:ERR?") == '-113,"Undefined header"\n'
    finally:
        first.write("VOLT:NPLC 1")
        first.close()
        second.close()


def test_the_bench_drivers_run_unchanged_over_hislip(station: SimulatedStation) -> None:
    res = station.resources("hislip")
    supply = KeysightE36312A(open_resource(res["supply"]))
    dmm = Keysight34465A(open_resource(res["dmm"]))
    try:
        assert dmm.idn.model == "34465A" and supply.idn.model == "E36312A"
        supply.ch[2].apply(15.0, 0.1)
        supply.ch[3].apply(15.0, 0.1)
        supply.set_outputs([2, 3], True)
        dmm.configure_dc_voltage(10, 1)
        assert 1.0 < abs(dmm.measure_dc_voltage()) < 10.0  # the powered unit's output
        dmm.configure_timed_trace(500, 0.001, nplc=0.02)
        dmm.initiate()
        trace = dmm.fetch_all()
        assert trace.shape == (500,) and np.all(np.isfinite(trace))
        assert supply.measure_voltages_v([2, 3]) == pytest.approx((15.0, 15.0), abs=0.1)
        dmm.check_errors("trace")
        supply.check_errors("rails")
    finally:
        supply.make_safe()
        dmm.make_safe()
        dmm.resource.close()
        supply.resource.close()


# -- the protocol, byte by byte -------------------------------------------------------------------
def test_replies_carry_the_message_id_of_their_dataend_and_respect_the_size_limit(raw: RawSession) -> None:
    raw.asynchronous.sendall(frame(ASYNC_MAXIMUM_MESSAGE_SIZE, 0, 0, struct.pack("!Q", 16 + 7)))
    kind, _, _, payload = read_message(raw.asynchronous)
    assert kind == ASYNC_MAXIMUM_MESSAGE_SIZE_RESPONSE and struct.unpack("!Q", payload)[0] >= 1 << 20
    raw.send(b"*ID", kind=DATA)
    message_id = raw.send(b"N?\n")
    pieces = [read_message(raw.sync) for _ in range(11)]  # 72 bytes in messages of 7 at most
    assert [p[0] for p in pieces] == [DATA] * 10 + [DATA_END]
    assert {p[2] for p in pieces} == {message_id} and all(len(p[3]) <= 7 for p in pieces)
    assert b"".join(p[3] for p in pieces).startswith(b"Keysight Technologies,34465A,")
    raw.asynchronous.sendall(frame(ASYNC_MAXIMUM_MESSAGE_SIZE, 0, 0, struct.pack("!Q", 1 << 20)))
    read_message(raw.asynchronous)
    assert raw.ask(b"*OPC?") == b"1\n"


def test_mav_follows_rmt_delivered(raw: RawSession) -> None:
    message_id = raw.send(b"*IDN?\n")
    assert raw.status() & MAV  # the query named in the status query is processed first
    raw.reply(message_id)
    assert raw.status(rmt=0) & MAV  # read, but RMT-delivered not reported yet
    assert not raw.status(rmt=1) & MAV
    assert not raw.status() & MAV


def test_a_query_overtaken_by_the_next_message_is_interrupted(raw: RawSession) -> None:
    """§3.1.1 rule 1: the reply is ready while the next message already waits."""
    first, second = FIRST_ID, FIRST_ID + 2
    raw.sync.sendall(frame(DATA_END, 0, first, b"*IDN?\n") + frame(DATA_END, 0, second, b"*OPC?\n"))
    raw.next_id, raw.last_id = FIRST_ID + 4, second
    assert read_message(raw.asynchronous) == (ASYNC_INTERRUPTED, 0, second, b"")
    assert read_message(raw.sync) == (INTERRUPTED, 0, second, b"")
    assert read_message(raw.sync) == (DATA_END, 0, second, b"1\n")
    raw.delivered = 1
    assert raw.ask(b"SYST:ERR?").startswith(b'-410,"Query INTERRUPTED')
    assert raw.ask(b"*IDN?;*OPC?").endswith(b";1\n")  # one message, one reply: fine
    assert raw.ask(b"SYST:ERR?") == b'+0,"No error"\n'


def test_a_reply_not_reported_delivered_is_an_interrupted_query_without_messages(raw: RawSession) -> None:
    """§3.1.1 rule 2: -410 queued, nothing sent on either channel."""
    raw.ask(b"*IDN?")
    assert raw.ask(b"*OPC?", rmt=0) == b"1\n"  # RMT-delivered not set although the reply was read
    assert raw.ask(b"SYST:ERR?").startswith(b'-410,"Query INTERRUPTED')
    raw.asynchronous.settimeout(0.2)
    with pytest.raises(TimeoutError):
        raw.asynchronous.recv(1)


def test_device_clear_abandons_what_is_pending_and_negotiates_synchronized_mode(raw: RawSession) -> None:
    stale = raw.send(b"*IDN?\n")
    raw.asynchronous.sendall(frame(ASYNC_DEVICE_CLEAR))
    assert read_message(raw.asynchronous) == (ASYNC_DEVICE_CLEAR_ACKNOWLEDGE, 0, 0, b"")
    raw.send(b"*ESE 255\n")  # between the clear and its completion: ignored
    raw.sync.sendall(frame(DEVICE_CLEAR_COMPLETE, 1))  # the client would like overlapped mode
    assert read_message(raw.sync)[:3] == (DATA_END, 0, stale)  # sent before the clear
    assert read_message(raw.sync) == (DEVICE_CLEAR_ACKNOWLEDGE, 0, 0, b"")  # synchronized
    raw.next_id = FIRST_ID
    assert raw.ask(b"*ESE?") == b"+0\n"


def test_trigger_is_a_group_execute_trigger(station: SimulatedStation) -> None:
    client = pyhislip.Instrument("127.0.0.1", port=port_of(station, "dmm"), timeout=5)
    try:
        client.send(b"CONF:VOLT:DC 10;:TRIG:SOUR BUS;:SAMP:COUN 3;:INIT\n")
        client.trigger()
        client.send(b"*OPC?;DATA:POIN?\n")
        assert bytes(client.receive(100)) == b"1;+3\n"
        client.trigger()  # not waiting for a trigger any more
        client.send(b"SYST:ERR?;:TRIG:SOUR IMM\n")
        assert bytes(client.receive(100)).startswith(b'-211,"Trigger ignored"')
    finally:
        client.close()


def test_remote_local_requests_are_confirmed_and_unknown_ones_refused(raw: RawSession) -> None:
    for request in range(7):
        raw.asynchronous.sendall(frame(ASYNC_REMOTE_LOCAL_CONTROL, request, raw.last_id))
        assert read_message(raw.asynchronous) == (ASYNC_REMOTE_LOCAL_RESPONSE, 0, 0, b"")
    raw.asynchronous.sendall(frame(ASYNC_REMOTE_LOCAL_CONTROL, 7, raw.last_id))
    kind, code, _, _ = read_message(raw.asynchronous)
    assert (kind, code) == (ERROR, 2)  # unrecognized control code
    assert raw.ask(b"*OPC?") == b"1\n"


# -- locks (pyvisa-py 0.8 offers no VISA lock over HiSLIP: its protocol client) ----------------
@pytest.fixture
def clients(station) -> Iterator[list[pyhislip.Instrument]]:
    made: list[pyhislip.Instrument] = []
    yield made
    for client in made:
        client.close()


def _client(station, made: list[pyhislip.Instrument], timeout: float = 5.0) -> pyhislip.Instrument:
    made.append(pyhislip.Instrument("127.0.0.1", port=port_of(station, "supply"), timeout=timeout))
    return made[-1]


def test_an_exclusive_lock_holds_other_sessions_until_released(
        station: SimulatedStation, clients: list[pyhislip.Instrument]) -> None:
    a, b = _client(station, clients), _client(station, clients)
    assert a.async_lock_request(0.0) == "success"
    assert a.async_lock_info() == 1
    assert a.async_lock_request(0.0) == "error"  # already held
    assert b.async_lock_request(0.0) == "failure" and b.async_lock_request(0.2) == "failure"
    b.send(b"*IDN?\n")
    b.timeout = 0.3
    with pytest.raises(TimeoutError):
        b.receive(200)  # left unread by the server while a holds the lock
    b.timeout = 5.0
    a.send(b"*OPC?\n")
    assert bytes(a.receive(10)) == b"1\n"  # the holder is served
    assert a.async_lock_release() == "success"
    assert bytes(b.receive(200)).startswith(b"Keysight Technologies,E36312A,")
    assert b.async_lock_release() == "error"  # not held


def test_a_waiting_lock_request_is_granted_when_the_holder_lets_go(
        station: SimulatedStation, clients: list[pyhislip.Instrument]) -> None:
    a, b = _client(station, clients), _client(station, clients)
    assert a.async_lock_request(0.0) == "success"
    outcome: list[str] = []
    waiter = threading.Thread(target=lambda: outcome.append(b.async_lock_request(5.0)))
    waiter.start()
    time.sleep(0.2)
    a.close()  # a closed session's locks go at once
    waiter.join(5)
    assert outcome == ["success"]
    assert b.async_lock_info() == 1
    assert b.async_lock_release() == "success" and b.async_lock_info() == 0


def test_shared_locks_take_the_same_key_and_exclude_others(
        station: SimulatedStation, clients: list[pyhislip.Instrument]) -> None:
    a, b, c = (_client(station, clients) for _ in range(3))
    assert a.async_lock_request(0.0, "bench") == "success"
    assert b.async_lock_request(0.0, "bench") == "success"
    assert c.async_lock_request(0.0, "other") == "failure"
    assert c.async_lock_request(0.0) == "failure"  # exclusive: only for a shared holder
    assert a.async_lock_request(0.0) == "success"  # a now holds both
    pyhislip.send_msg(c._async, "AsyncLockInfo", 0, 0)  # its lock_info() drops the holder count
    header = pyhislip.AsyncLockInfoResponse(c._async)
    assert (header.exclusive_lock, header.clients_holding_locks) == (1, 2)
    assert a.async_lock_release() == "success"  # the exclusive one first
    assert a.async_lock_release() == "success shared"
    assert b.async_lock_release() == "success shared"
    assert c.async_lock_info() == 0


# -- faults ---------------------------------------------------------------------------------------
def test_wire_faults_act_on_hislip_sessions_too(
        station_factory: Callable[..., SimulatedStation], rm: pyvisa.ResourceManager) -> None:
    station = station_factory(seed=3, serve=True)
    address = station.resources("hislip")["dmm"]
    res = open_visa(rm, address, timeout=300)
    station.faults.inject("error", "dmm", count=1, code=-300)
    with pytest.raises(pyvisa.VisaIOError):
        res.query("*IDN?")  # refused: no reply
    assert res.query("SYST:ERR?").startswith("-300,")
    station.faults.inject("drop", "dmm")
    with pytest.raises(Exception):  # noqa: B017 - the connection is gone, however pyvisa-py says it
        res.query("*IDN?")
    res.close()
    again = open_visa(rm, address, timeout=2000)
    assert again.query("*IDN?").startswith("Keysight Technologies,34465A,")
    again.close()


# -- malformed input ------------------------------------------------------------------------------
def _fatal(sock: socket.socket) -> int:
    kind, code, _, _ = read_message(sock)
    assert kind == FATAL_ERROR
    assert closed_after(sock)
    return code


@pytest.mark.parametrize("first, code", [
    (frame(INITIALIZE, prologue=b"XS"), 1),          # poorly formed header
    (frame(DATA_END, 0, FIRST_ID, b"*IDN?\n"), 3),   # data before Initialize
    (frame(ASYNC_INITIALIZE, 0, 0xBEEF), 3),         # no such session
    (frame(INITIALIZE, 0, 0x0100 << 16, b"x" * 300), 3),  # sub-address over 256 characters
    (frame(INITIALIZE, 0, 0x0100 << 16, b"hislip7"), 0),  # not this instrument
])
def test_a_bad_opening_gets_a_fatal_error_and_the_connection_closed(
        station: SimulatedStation, first: bytes, code: int) -> None:
    with socket.create_connection(("127.0.0.1", port_of(station, "dmm")), timeout=5) as sock:
        sock.sendall(first)
        assert _fatal(sock) == code


@pytest.mark.parametrize("message, channel, code", [
    (frame(50, 0, 0, b"xyz"), "sync", 1),            # a reserved message type
    (frame(200, 7, 7, b"vendor"), "sync", 3),        # a vendor-defined one
    (frame(ASYNC_STATUS_RESPONSE), "async", 1),      # a server's message
    (frame(DATA_END, 0, 0, b"*IDN?"), "async", 1),   # a synchronous message on the other channel
    (frame(ASYNC_LOCK, 9, 0), "async", 2),           # unknown control code
    (frame(ASYNC_MAXIMUM_MESSAGE_SIZE, 0, 0, b"1234"), "async", 0),  # not 8 bytes
    (frame(ASYNC_LOCK, 1, 0, b"k" * 5000), "async", 4),  # too large
])
def test_a_well_formed_message_that_cannot_be_used_gets_error_and_the_session_goes_on(
        raw: RawSession, message: bytes, channel: str, code: int) -> None:
    sock = raw.sync if channel == "sync" else raw.asynchronous
    sock.sendall(message)
    kind, got, _, _ = read_message(sock)
    assert (kind, got) == (ERROR, code)
    assert raw.ask(b"*IDN?").startswith(b"Keysight Technologies,34465A,")


def test_a_data_message_over_the_limit_is_refused_and_its_program_message_discarded(raw: RawSession) -> None:
    raw.send(b"*ESE 1;" + b" " * 600_000, kind=DATA)
    raw.send(b"x" * (1 << 20) + b"y", kind=DATA)  # above the device's message limit
    raw.send(b";*ESE 255\n")
    kind, code, _, _ = read_message(raw.sync)
    assert (kind, code) == (ERROR, 4)
    assert raw.ask(b"*ESE?") == b"+0\n"
    assert raw.ask(b"SYST:ERR?").startswith(b'-223,"Too much data')


def test_a_bad_prologue_inside_a_session_is_fatal_on_both_channels(raw: RawSession, station: SimulatedStation) -> None:
    raw.sync.sendall(b"GARBAGE!" * 2)
    assert _fatal(raw.sync) == 1
    assert _fatal(raw.asynchronous) == 1
    fresh = RawSession(port_of(station, "dmm"))
    try:
        assert fresh.ask(b"*OPC?") == b"1\n"
    finally:
        fresh.close()


# -- fuzzing --------------------------------------------------------------------------------------
def test_scpi_fuzz_over_hislip_queues_the_standard_errors_and_every_probe_is_answered(
        station: SimulatedStation) -> None:
    """bench.testing's SCPI fuzz messages, each as one DataEnd, then the probe
    ``SYST:ERR?;*CLS``: END closes every message (a block declared and never sent included),
    so unlike the raw socket no probe is ever swallowed."""
    rng, tally = random.Random("fuzz:hislip"), Tally()
    valid = [("*IDN?", 1), ("*ESR?", 1), ("*OPC?", 1), ("*ESE 4", 0), ("VOLT:NPLC 10", 0),
             ("VOLT:NPLC?", 1), ("SAMP:COUN?", 1), ("SYST:ERR?", 1)]
    session = RawSession(port_of(station, "dmm"))
    try:
        for _ in range(150):
            message, expect, replies = scpi_message(rng, valid, big=False)
            tally.sent += 1
            message_id = session.send(message + b"\n")
            for _ in range(replies if expect == "ok" else 0):
                session.reply(message_id)
            answer = session.ask(PROBE).rstrip(b"\n")
            tally.answered += 1
            m = ERROR_LINE.match(answer)
            code = int(m.group(1)) if m else None
            if expect in ("command", "undefined"):
                tally.invalid += 1
                good = code is not None and (code == -113 if expect == "undefined" else -199 <= code <= -100)
                tally.invalid_standard_error += good
            if expect == "ok" and code != 0 or code is None:
                tally.wrong.append((message[:40], answer[:80]))
        assert session.ask(b"*IDN?").startswith(b"Keysight Technologies,34465A,")
    finally:
        session.send(b"*RST;VOLT:NPLC 1\n")
        session.close()
    assert tally.wrong == []
    assert tally.invalid > 30 and tally.invalid_standard_error == tally.invalid
    assert tally.answered == tally.sent


HEADERS = st.tuples(
    st.sampled_from([b"HS", b"HS", b"HS", b"SH", b"\x00\x00"]),
    st.one_of(st.integers(0, 30), st.integers(0, 255)),
    st.integers(0, 255),
    st.one_of(st.sampled_from([0, FIRST_ID, 0xFFFF_FFFF]), st.integers(0, 2**32 - 1)),
    st.one_of(st.none(), st.integers(0, 2**64 - 1)),  # None: the payload's own length
    st.binary(max_size=40),
)
CHUNKS = st.lists(st.one_of(st.binary(min_size=1, max_size=48), HEADERS), min_size=1, max_size=8)


def _bytes_of(chunks: list) -> bytes:
    out = b""
    for chunk in chunks:
        if isinstance(chunk, bytes):
            out += chunk
        else:
            prologue, kind, control, parameter, length, payload = chunk
            out += HEADER.pack(prologue, kind, control, parameter,
                               len(payload) if length is None else length) + payload
    return out


def _drain(*socks: socket.socket) -> None:
    for sock in socks:
        sock.settimeout(0.02)
        try:
            while sock.recv(1 << 16):
                pass
        except OSError:
            pass


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(where=st.sampled_from(["fresh", "sync", "async"]), chunks=CHUNKS)
def test_the_server_survives_arbitrary_bytes_on_either_channel(
        station: SimulatedStation, where: str, chunks: list) -> None:
    """Junk, malformed and well-formed headers with any lengths, before or after the
    handshake, on either channel; then a good client is served and no session is left open."""
    port = port_of(station, "dmm")
    opened = len(station.dmm.sessions)
    data = _bytes_of(chunks)
    if where == "fresh":
        with socket.create_connection(("127.0.0.1", port), timeout=5) as sock:
            sock.sendall(data)
            _drain(sock)
    else:
        victim = RawSession(port)
        try:
            (victim.sync if where == "sync" else victim.asynchronous).sendall(data)
            _drain(victim.sync, victim.asynchronous)
        finally:
            victim.close()
    good = RawSession(port)
    try:
        assert good.ask(b"*IDN?").startswith(b"Keysight Technologies,34465A,")
    finally:
        good.close()
    deadline = time.monotonic() + 5
    while len(station.dmm.sessions) > opened:  # every session closed with its connections
        assert time.monotonic() < deadline, "a HiSLIP session outlived its connections"
        time.sleep(0.01)
