"""The simulated Watlow F4T over its real wire: a plain pymodbus client reading and writing
registers by number, the exceptions a bad request gets, junk on the socket, and the faults
(limit trip, alarm, power, drop, stall) through sim-control's API."""

from __future__ import annotations

import math
import random
import socket
import struct

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from pymodbus.client import ModbusTcpClient

from sim.devices import chamber_map as cm
from sim.station import SimulatedStation


def _host_port(resource: str) -> tuple[str, int]:
    host, port = resource[len("modbus://"):].rsplit(":", 1)
    return host, int(port)


@pytest.fixture
def sim():
    with SimulatedStation(only={"chamber"}) as station:
        yield station


@pytest.fixture
def client(sim):
    host, port = _host_port(sim.resources()["chamber"])
    c = ModbusTcpClient(host, port=port, timeout=2.0, retries=0)
    assert c.connect()
    yield c
    c.close()


def f32(words: list[int]) -> float:
    """Independent decoding: the F4T's low word first, each word big-endian."""
    return struct.unpack(">f", bytes([words[1] >> 8, words[1] & 255, words[0] >> 8, words[0] & 255]))[0]


def words(value: float) -> list[int]:
    raw = struct.pack(">f", value)
    return [int.from_bytes(raw[2:], "big"), int.from_bytes(raw[:2], "big")]


def answers(client: ModbusTcpClient) -> bool:
    """The controller answers a read of its process value (connecting first if need be)."""
    try:
        if not client.connected and not client.connect():
            return False
        return not client.read_holding_registers(2820, count=2).isError()
    except Exception:  # pymodbus: ConnectionException, ModbusIOException
        client.close()
        return False


def advance(sim: SimulatedStation, dt_s: float) -> None:
    sim.server.call(sim.world.advance, dt_s)


# ---- codec ------------------------------------------------------------------------------------
@given(st.floats(width=32, allow_nan=False, allow_infinity=False))
def test_float_words_round_trip_in_the_f4t_word_order(value):
    w = cm.float_to_words(value)
    assert all(0 <= x < 65536 for x in w) and len(w) == 2
    assert cm.words_to_float(w) == value
    assert f32(w) == value  # an independent decoder agrees


@given(st.integers(-2**31, 2**31 - 1))
def test_int32_words_round_trip(value):
    assert cm.words_to_int32(cm.int32_to_words(value)) == value
    assert cm.int32_to_words(value)[0] == value & 0xFFFF  # low word first


def test_word_order_of_a_known_value():
    assert cm.float_to_words(70.0) == [0x0000, 0x428C]  # 0x428C0000
    assert cm.float_to_words(23.5) == [0x0000, 0x41BC]
    assert cm.float_to_words(-40.25)[1] == 0xC221


# ---- reads and writes by number ----------------------------------------------------------------
def test_plain_client_reads_and_writes_the_loop(sim, client):
    pv = client.read_holding_registers(2820, count=2)
    assert not pv.isError() and f32(pv.registers) == pytest.approx(23.0)
    assert client.read_holding_registers(27586, count=2).registers == pv.registers
    ident = client.read_holding_registers(16, count=15).registers
    assert "".join(chr(w) for w in ident if w).startswith("F4T")  # one character per register
    assert not client.write_registers(2782, words(55.5)).isError()
    assert f32(client.read_holding_registers(2782, count=2).registers) == 55.5
    assert not client.write_register(2730, 10).isError()   # Auto: run
    assert client.read_holding_registers(2814, count=1).registers == [10]
    advance(sim, 2 * 3600.0)
    assert f32(client.read_holding_registers(2820, count=2).registers) == pytest.approx(55.5, abs=1e-3)
    assert not client.write_register(2730, 62).isError()   # standby
    advance(sim, 8 * 3600.0)
    assert f32(client.read_holding_registers(2820, count=2).registers) == pytest.approx(23.0, abs=0.1)


def test_ramp_registers_drive_the_working_set_point(sim, client):
    client.write_register(2796, 57)
    client.write_registers(2798, words(0.5))                 # 0.5 °C/min
    client.write_register(2794, 85)                          # ramp on set point changes
    client.write_register(2730, 10)
    client.write_registers(2782, words(43.0))
    advance(sim, 20 * 60.0)
    wsp = f32(client.read_holding_registers(2810, count=2).registers)
    assert wsp == pytest.approx(23.0 + 10.0, abs=1e-3)       # 20 min at 0.5 °C/min
    advance(sim, 40 * 60.0)
    assert f32(client.read_holding_registers(2810, count=2).registers) == pytest.approx(43.0)


@pytest.mark.parametrize("request_, code", [
    (lambda c: c.read_holding_registers(5000, count=2), 2),          # outside the map
    (lambda c: c.read_holding_registers(2820, count=4), 2),          # runs past the map
    (lambda c: c.write_registers(2820, words(1.0)), 2),              # read-only
    (lambda c: c.write_register(2782, 0), 2),                        # half of a float
    (lambda c: c.write_registers(2783, [0, 0]), 2),                  # misaligned float
    (lambda c: c.write_registers(2782, words(500.0)), 3),            # outside the set point range
    (lambda c: c.write_registers(2782, words(math.nan)), 3),         # not a number
    (lambda c: c.write_register(2730, 54), 3),                       # Manual: not simulated
    (lambda c: c.write_register(2794, 99), 3),                       # not an option
    (lambda c: c.write_registers(2798, words(-1.0)), 3),             # a negative ramp rate
    (lambda c: c.write_register(1328, 30), 3),                       # °F
    (lambda c: c.read_coils(2730, count=1), 1),                      # not a register function
])
def test_bad_requests_get_the_modbus_exception_and_change_nothing(sim, client, request_, code):
    before = [client.read_holding_registers(a, count=2).registers for a in (2782, 2798)]
    reply = request_(client)
    assert reply.isError() and reply.exception_code == code
    assert [client.read_holding_registers(a, count=2).registers for a in (2782, 2798)] == before
    assert not client.read_holding_registers(2820, count=2).isError()  # still serving


def test_junk_on_the_socket_never_takes_the_server_down(sim, client):
    """Fuzz: random bytes, truncated and oversized frames, random function codes and addresses;
    after each batch a well-formed request still gets its answer."""
    host, port = _host_port(sim.resources()["chamber"])
    rng = random.Random(14)
    for batch in range(40):
        with socket.create_connection((host, port), timeout=1.0) as s:
            for _ in range(10):
                kind = rng.randrange(4)
                if kind == 0:
                    data = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 300)))
                elif kind == 1:  # a valid MBAP header with a random PDU
                    pdu = bytes([rng.randrange(256)]) + bytes(rng.randrange(256) for _ in range(rng.randrange(0, 12)))
                    data = struct.pack(">HHHB", rng.randrange(65536), 0, len(pdu) + 1, 1) + pdu
                elif kind == 2:  # read holding registers anywhere
                    data = struct.pack(">HHHBBHH", batch, 0, 6, 1, 3, rng.randrange(65536), rng.randrange(200))
                else:  # write multiple with a lying byte count
                    data = struct.pack(">HHHBBHHB", batch, 0, 9, 1, 16, rng.randrange(65536), 2, 9) + b"\x00\x01"
                try:
                    s.sendall(data)
                except OSError:
                    break
            s.settimeout(0.05)
            try:
                while s.recv(4096):
                    pass
            except OSError:
                pass
        reply = client.read_holding_registers(2820, count=2)
        if reply.isError() or not reply.registers:  # our own client may have been confused: reconnect
            client.close()
            assert client.connect()
            reply = client.read_holding_registers(2820, count=2)
        assert not reply.isError() and f32(reply.registers) == pytest.approx(23.0)


# ---- the limit controller, alarms and faults ------------------------------------------------------
def test_limit_trips_on_the_air_latches_and_cuts_conditioning(sim, client):
    client.write_registers(11254, words(50.0))   # limit high 50 °C
    client.write_registers(2782, words(70.0))
    client.write_register(2730, 10)
    advance(sim, 3600.0)
    assert client.read_holding_registers(11250, count=1).registers == [cm.LIMIT_HIGH]
    assert client.read_holding_registers(11264, count=1).registers == [cm.DEVICE_FAIL]
    log = [m for t, m in sim.world.log if "limit tripped" in m]
    assert log  # the trip instant was found on the air's closed form
    t_trip = [t for t, m in sim.world.log if "limit tripped" in m][0]
    assert sim.chamber_air.air_c(t_trip)[0] == pytest.approx(50.0, abs=1e-6)
    pv = f32(client.read_holding_registers(2820, count=2).registers)
    assert pv < 50.0  # heating cut: drifting back toward the lab
    client.write_register(11256, 129)             # too close to the limit still? ...
    advance(sim, 6 * 3600.0)                       # ... hours later it is far inside
    assert client.read_holding_registers(11250, count=1).registers == [cm.LIMIT_HIGH]  # latched
    client.write_register(11256, 129)
    assert client.read_holding_registers(11250, count=1).registers == [cm.LIMIT_NONE]
    advance(sim, 3600.0)  # still in Auto toward 70: it trips again at 50
    assert client.read_holding_registers(11250, count=1).registers == [cm.LIMIT_HIGH]


def test_injected_limit_and_alarm_latch_until_cleared_over_modbus(sim, client):
    client.write_registers(2782, words(40.0))
    client.write_register(2730, 10)
    advance(sim, 600.0)
    sim.faults.inject("limit", "chamber")
    sim.faults.inject("alarm", "chamber")
    assert client.read_holding_registers(11250, count=1).registers == [cm.LIMIT_HIGH]
    assert client.read_holding_registers(1456, count=1).registers == [cm.ALARM_HIGH]
    sim.faults.clear("chamber")                   # latched: a sim-control clear does not reset them
    assert client.read_holding_registers(11250, count=1).registers == [cm.LIMIT_HIGH]
    client.write_register(1452, 129)
    assert client.read_holding_registers(1456, count=1).registers == [cm.ALARM_NONE]
    client.write_register(11256, 129)
    assert client.read_holding_registers(11250, count=1).registers == [cm.LIMIT_NONE]


def test_deviation_alarm_is_blocked_while_ramping_then_watches_the_set_point(sim, client):
    client.write_registers(2782, words(80.0))
    client.write_register(2730, 10)
    advance(sim, 60.0)
    assert client.read_holding_registers(1356, count=1).registers == [cm.ALARM_BLOCKED]
    advance(sim, 3 * 3600.0)
    assert client.read_holding_registers(1356, count=1).registers == [cm.ALARM_NONE]
    client.write_registers(1334, words(-1.0))     # a high deviation set point below the air: alarm
    assert client.read_holding_registers(1356, count=1).registers == [cm.ALARM_HIGH]


def test_power_loss_silences_the_controller_and_it_comes_back_in_standby(sim, client):
    client.write_registers(2782, words(60.0))
    client.write_register(2730, 10)
    advance(sim, 600.0)
    sim.faults.inject("power", "chamber")
    assert not answers(client)
    assert not sim.chamber.conditioning
    sim.faults.clear("chamber")
    client.close()
    assert answers(client)
    assert client.read_holding_registers(2730, count=1).registers == [62]          # standby
    assert f32(client.read_holding_registers(2782, count=2).registers) == 60.0      # settings kept


def test_stall_and_drop_act_on_the_modbus_wire(sim, client):
    sim.faults.inject("stall", "chamber", duration_s=100.0)
    host, port = _host_port(sim.resources()["chamber"])
    quick = ModbusTcpClient(host, port=port, timeout=0.3, retries=0)
    assert quick.connect()
    assert not answers(quick)  # the request is lost, no reply
    quick.close()
    advance(sim, 101.0)
    assert answers(quick)
    quick.close()
    sim.faults.inject("drop", "chamber", refuse_s=50.0)
    assert not answers(client)  # the connection was closed ...
    assert not answers(client)  # ... and reconnects are refused for 50 s
    advance(sim, 51.0)
    assert answers(client)


def test_same_seed_same_bytes():
    def run() -> list[int]:
        with SimulatedStation(only={"chamber"}) as s:
            host, port = _host_port(s.resources()["chamber"])
            c = ModbusTcpClient(host, port=port, timeout=2.0, retries=0)
            c.connect()
            c.write_registers(2782, words(-20.0))
            c.write_register(2730, 10)
            out: list[int] = []
            for _ in range(20):
                advance(s, 97.0)
                out += c.read_holding_registers(2820, count=2).registers
            c.close()
            return out
    first, second = run(), run()
    assert first == second and len(set(np.array(first).tolist())) > 10
