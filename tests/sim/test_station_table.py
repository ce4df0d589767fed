"""The station table (``sim.station.INSTRUMENTS``) is the one list of the simulated station's
instruments: the server, sim-control, the fault targets and their kinds all follow from it,
and every device has the lifecycle hooks of the fault kinds it claims."""

from __future__ import annotations

import math

import pytest
import pyvisa

from sim.faults import PARAMETERS
from sim.server import MODBUS, SCPI, SERIAL, ByteStreamDevice
from sim.station import INSTRUMENTS, StationInstrument

#: the hooks each device fault kind needs (sim.devices.lifecycle)
HOOKS = {"power": ("power_off", "power_on"), "interlock": ("trip_interlock",),
         "overload": ("overload", "end_overload", "overloaded"), "frame": ("connect", "receive", "disconnect"),
         "limit": ("trip_limit",), "alarm": ("raise_alarm",)}

#: the fault kinds of every instrument, as docs/ARCHITECTURE.md's sim-control table has them
#: (a change here is a change of the documented fault semantics)
DOCUMENTED_KINDS = {
    "dmm": "drop stall slow garble error power overload",
    "dmm_temp": "drop stall slow garble error power overload",
    "supply": "drop stall slow garble error power",
    "turntable": "drop stall slow garble error power interlock",
    "gyro": "drop stall frame power",
    "shaker": "drop stall slow garble error power",
    "angular_table": "drop stall slow garble error power interlock",
    "dmm_mhd": "drop stall slow garble error power overload",
    "lf_gyro": "drop stall frame power",
    "chamber": "drop stall power limit alarm",
    "daq": "drop stall slow garble error power overload",
}


@pytest.fixture(scope="module")
def station(station_factory):
    return station_factory()  # not started: devices and fault layer only


def test_names_are_unique_and_the_fault_targets_are_the_table(station):
    names = [row.name for row in INSTRUMENTS]
    assert len(set(names)) == len(names) and "sim" not in names
    assert list(station.devices) == names
    assert list(station.faults.devices) == names
    assert station.sim_control.names == names


@pytest.mark.parametrize("row", INSTRUMENTS, ids=lambda r: r.name)
def test_every_device_has_the_hooks_of_the_faults_it_claims(row: StationInstrument, station):
    device = station.devices[row.name]
    assert row.device(station) is device
    assert "power" in device.fault_kinds
    assert set(device.fault_kinds) <= set(HOOKS)
    assert not set(device.fault_kinds) & set(row.transport.wire_fault_kinds)
    for kind in device.fault_kinds:
        for hook in HOOKS[kind]:
            assert hasattr(device, hook), (row.name, kind, hook)
    if "frame" in device.fault_kinds:  # frames go out through the serial line's fault gate
        assert row.transport is SERIAL
    assert station.faults.kinds(row.name) == row.transport.wire_fault_kinds + device.fault_kinds
    assert set(station.faults.kinds(row.name)) <= set(PARAMETERS)


def test_the_fault_kinds_are_the_documented_ones(station):
    assert {row.name: " ".join(station.faults.kinds(row.name)) for row in INSTRUMENTS} == DOCUMENTED_KINDS


@pytest.mark.parametrize("row", INSTRUMENTS, ids=lambda r: r.name)
def test_each_wire_serves_its_kind_of_device(row: StationInstrument, station):
    device = station.devices[row.name]
    if row.transport is SCPI:
        assert callable(getattr(device, "process", None))
    elif row.transport is MODBUS:
        assert callable(getattr(device, "simdevice", None))
    else:
        assert row.transport is SERIAL
        assert all(callable(getattr(device, m, None)) for m in ByteStreamDevice.__dict__
                   if not m.startswith("_"))
    resource = row.transport.resource("127.0.0.1", 5025)
    assert resource in ("TCPIP::127.0.0.1::5025::SOCKET", "socket://127.0.0.1:5025", "modbus://127.0.0.1:5025")


def test_server_sim_control_and_listing_follow_the_table(sim_station):
    endpoints = {e.name: e for e in sim_station.endpoints}
    assert list(endpoints) == [row.name for row in INSTRUMENTS] + ["sim"]
    for row in INSTRUMENTS:
        e = endpoints[row.name]
        assert (e.kind, e.transport) == (row.kind, row.transport)
        assert e.resource == row.transport.resource(e.host, e.port)

    rm = pyvisa.ResourceManager("@py")
    try:
        sim = rm.open_resource(endpoints["sim"].resource, read_termination="\n", write_termination="\n",
                               timeout=10000)
        listed = sim.query("SIM:INST:LIST?").strip()
        sim.close()
    finally:
        rm.close()
    assert listed == ",".join(f'"{row.name}"' for row in INSTRUMENTS)


def test_power_cycles_every_device_through_its_hooks(station_factory):
    station = station_factory()
    faults = station.faults
    station.supply.process(b"APPL CH1,5,1;:OUTP ON,(@1)")  # the gyro powered
    station.supply.push_error(-222, "left over")
    station.world.advance(10.0)
    assert station.gyro_line.state == "STOPPED" and station.angular.lf_line.state == "STOPPED"
    for row in INSTRUMENTS:
        faults.inject("power", row.name)
        assert faults.active()[row.name] == ["power"]
        assert faults.gates[row.name].silent()
    assert station.gyro_line.state == "OFF" and station.angular.lf_line.state == "OFF"
    assert not any(ch.output for ch in station.supply.channels.values())
    faults.clear()
    assert faults.active() == {}
    assert station.supply.esr == 0x80 and station.supply.errors == []  # its power-on state
    # each line boots from its own supply as wired: the rig's 24 V, the station's CH1 (off: *RST)
    assert station.angular.lf_line.state == "STOPPED" and station.gyro_line.state == "OFF"


def test_overload_and_interlock_hooks_do_what_the_fault_table_says(station_factory):
    station = station_factory()
    faults = station.faults
    faults.inject("overload", "dmm_mhd", volts=-50.0)
    assert faults.active() == {"dmm_mhd": ["overload"]} and station.angular.dmm.overloaded
    faults.clear("dmm_mhd")
    assert not station.angular.dmm.overloaded and faults.active() == {}
    faults.inject("interlock", "turntable")
    assert station.turntable.tripped and math.isfinite(station.world.now)
    faults.clear("ALL")
    assert station.turntable.tripped  # latched: only :INT:RES resets it
