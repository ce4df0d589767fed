"""The chamber driver against the simulated F4T, against a plain Modbus client that reads and
writes registers by number (so the driver is not only tested against itself), and its errors:
every failure names the instrument and the register."""

from __future__ import annotations

import math
import struct

import pytest
from hypothesis import given
from hypothesis import strategies as st
from pymodbus.client import ModbusTcpClient

from bench.app.station import OPENERS, InstrumentConfig, parse_modbus_address
from instruments.chamber import (
    ChamberFaultError,
    ChamberRegisterError,
    WatlowF4TChamber,
    float_to_words,
    words_to_float,
)
from instruments.protocols import SafeOrder
from instruments.registry import MODBUS
from instruments.wire import InstrumentConnectionError
from sim.devices import chamber_map as cm
from sim.station import SimulatedStation


@pytest.fixture
def sim():
    with SimulatedStation(only={"chamber"}) as station:
        yield station


def open_client(sim: SimulatedStation, timeout_ms: int = 2000) -> ModbusTcpClient:
    inst = InstrumentConfig("chamber", "watlow_f4t", sim.resources()["chamber"], timeout_ms=timeout_ms)
    return OPENERS[MODBUS](inst, {}, lambda backend: None)


@pytest.fixture
def chamber(sim):
    client = open_client(sim)
    yield WatlowF4TChamber(client, name="chamber")
    client.close()


@pytest.fixture
def plain(sim):
    client = open_client(sim)
    yield client
    client.close()


def wait_of(sim: SimulatedStation):
    """The bench clock's wait on a simulated station: simulated time passes."""
    return lambda dt: sim.server.call(sim.world.advance, dt)


# ---- the codec, written apart from the simulator's --------------------------------------------
@given(st.floats(width=32, allow_nan=False, allow_infinity=False))
def test_driver_decodes_what_the_simulator_encodes_and_back(value):
    assert words_to_float(cm.float_to_words(value)) == value
    assert cm.words_to_float(float_to_words(value)) == value


def test_station_addresses():
    assert parse_modbus_address("modbus://127.0.0.1:1502") == ("127.0.0.1", 1502)
    assert parse_modbus_address("modbus://chamber-3") == ("chamber-3", 502)
    for bad in ("TCPIP::1.2.3.4::502::SOCKET", "modbus://", "modbus://h:0", "modbus://h:x"):
        with pytest.raises(ValueError, match="modbus://host"):
            parse_modbus_address(bad)


# ---- against the simulated controller ---------------------------------------------------------
def test_run_to_a_set_point_and_settle_on_the_bench_clock(sim, chamber):
    assert chamber.identify().model == "F4T" and chamber.identify().hardware_id == 124
    assert chamber.identify().part_number == "F4T1L0AA1A11AA1"  # one character per register, as read
    assert chamber.set_point_range_c == (-70.0, 180.0)
    assert not chamber.running and chamber.process_value_c == pytest.approx(23.0)
    chamber.set_ramp(2.0)
    assert chamber.ramp_rate_c_per_min == pytest.approx(2.0)
    chamber.set_set_point(-40.0)
    t0 = sim.world.now
    chamber.run()  # the ramp applies to the start from standby too (ramp action Both)
    assert chamber.running and chamber.set_point_c == -40.0
    wait_of(sim)(600.0)
    assert chamber.working_set_point_c == pytest.approx(23.0 - 20.0, abs=1e-3)
    status = chamber.wait_until_settled(wait_of(sim), tolerance_c=0.2, hold_s=300.0, timeout_s=4 * 3600)
    assert abs(status.process_value_c + 40.0) <= 0.2 and status.running and not status.alarm_active
    took = sim.world.now - t0
    assert 63 / 2.0 * 60 < took < 63 / 2.0 * 60 + 3600  # the 2 °C/min ramp, then settling
    chamber.set_ramp(None)
    assert chamber.ramp_rate_c_per_min is None


def test_settings_are_checked_before_the_wire(sim, chamber, plain):
    before = plain.read_holding_registers(2782, count=2).registers
    for bad in (181.0, -70.5, math.nan, math.inf, "20", True):
        with pytest.raises(ValueError, match=r"chamber: set point .* not in -70\.\.180 °C"):
            chamber.set_set_point(bad)  # wrong types are refused by name too
    for bad_rate in (0.0, -1.0, 1e6, math.nan):
        with pytest.raises(ValueError, match="ramp rate .* not in"):
            chamber.set_ramp(bad_rate)
    assert plain.read_holding_registers(2782, count=2).registers == before  # nothing was written


def test_what_the_driver_writes_a_plain_client_reads_by_number_and_back(sim, chamber, plain):
    chamber.set_set_point(61.25)
    words = plain.read_holding_registers(2782, count=2).registers
    assert struct.unpack(">f", struct.pack(">HH", words[1], words[0]))[0] == 61.25
    hi, lo = struct.unpack(">HH", struct.pack(">f", -12.5))
    assert not plain.write_registers(2782, [lo, hi]).isError()
    assert chamber.set_point_c == -12.5
    assert not plain.write_register(2730, 10).isError()
    assert chamber.running
    chamber.standby()
    assert plain.read_holding_registers(2814, count=1).registers == [62]


def test_make_safe_is_standby_at_the_ambient_set_point(sim, chamber):
    assert chamber.safe_order is SafeOrder.MOTION and chamber.safe_action == "standby"
    chamber.set_set_point(90.0)
    chamber.run()
    wait_of(sim)(1800.0)
    chamber.make_safe()
    assert not chamber.running and chamber.set_point_c == 23.0
    wait_of(sim)(10 * 3600.0)
    assert chamber.process_value_c == pytest.approx(23.0, abs=0.1)


# ---- faults reach procedures as errors that name what failed ----------------------------------
def test_a_tripped_limit_stops_a_wait_and_is_named(sim, chamber):
    chamber.set_set_point(100.0)
    chamber.run()
    sim.faults.inject("limit", "chamber", at_s=sim.world.now + 600.0)
    with pytest.raises(ChamberFaultError, match=r"chamber: over-temperature limit tripped \(high\)"):
        chamber.wait_until_settled(wait_of(sim), timeout_s=4 * 3600)
    assert chamber.limit_state == "high" and chamber.status().limit_tripped
    wait_of(sim)(8 * 3600.0)
    chamber.clear_limit()
    assert chamber.limit_state == "ok"


def test_a_controller_alarm_is_named(sim, chamber):
    chamber.run()
    sim.faults.inject("alarm", "chamber")
    with pytest.raises(ChamberFaultError, match="chamber: controller alarm: alarm 2 high"):
        chamber.check()
    chamber.clear_alarms()
    assert not chamber.check().alarm_active


def test_a_refused_request_names_the_register_and_the_exception(sim, chamber, plain):
    assert chamber.set_point_range_c == (-70.0, 180.0)  # read and kept by the driver
    lo, hi = struct.unpack(">HH", struct.pack(">f", 50.0))
    assert not plain.write_registers(2776, [hi, lo]).isError()  # someone narrows the range at the panel
    with pytest.raises(ChamberRegisterError, match=r"chamber: write register 2782 \(set point\) refused: "
                                                   r"Modbus exception 03 \(illegal data value\)"):
        chamber.set_set_point(60.0)


def test_a_lost_connection_names_the_instrument_and_the_register(sim):
    client = open_client(sim, timeout_ms=300)
    chamber = WatlowF4TChamber(client, name="chamber")
    assert chamber.process_value_c == pytest.approx(23.0)
    sim.faults.inject("drop", "chamber", refuse_s=3600.0)
    with pytest.raises(InstrumentConnectionError, match=r"chamber: connection lost at 'read register 2820 "
                                                        r"\(process value\)'"):
        _ = chamber.process_value_c
    with pytest.raises(RuntimeError, match="chamber: not made safe: .*standby"):
        chamber.make_safe()
    wait_of(sim)(3601.0)
    assert chamber.process_value_c == pytest.approx(23.0)  # the next transfer reconnects
    client.close()


def test_a_powered_off_controller_is_a_connection_error_then_comes_back_in_standby(sim, chamber):
    chamber.set_set_point(50.0)
    chamber.run()
    sim.faults.inject("power", "chamber")
    with pytest.raises(InstrumentConnectionError, match="chamber: .*register"):
        chamber.status()
    sim.faults.clear("chamber")
    assert not chamber.running and chamber.set_point_c == 50.0
