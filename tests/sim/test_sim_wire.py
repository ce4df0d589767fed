"""The simulated station over the wire, with nothing but plain pyvisa-py (issue 2, Done means)."""

from __future__ import annotations

import numpy as np
import pytest
import pyvisa


@pytest.fixture
def rm():
    manager = pyvisa.ResourceManager("@py")
    yield manager
    manager.close()


def _open(rm, resource, timeout=20000):
    res = rm.open_resource(resource, read_termination="\n", write_termination="\n",
                           timeout=timeout)
    return res


def test_dmm_identifies_configures_and_streams_a_100k_real64_trace(sim_station, rm):
    dmm = _open(rm, sim_station.resources()["dmm"])
    maker, model, serial, firmware = dmm.query("*IDN?").strip().split(",")
    assert (maker, model) == ("Keysight Technologies", "34465A")
    assert firmware.count("-") >= 3  # vendor's multi-part firmware field
    dmm.write("CONF:VOLT:DC 10;:VOLT:NPLC 0.02;:SAMP:SOUR TIM;:SAMP:TIM 0.001;"
              ":SAMP:COUN 100000;:FORM REAL,64;:FORM:BORD SWAP")
    assert dmm.query("SAMP:COUN?").strip() == "+100000"
    dmm.write("INIT")
    data = dmm.query_binary_values("FETC?", datatype="d", is_big_endian=False,
                                   container=np.array)
    assert data.size == 100000
    assert np.all(np.abs(data) < 1e-3)  # the unit is unpowered: only the meter's noise
    assert dmm.query("SYST:ERR?").strip() == '+0,"No error"'
    dmm.write("FOO:BAR 1")
    assert dmm.query("SYST:ERR?").strip() == '-113,"Undefined header"'
    dmm.write("VOLT:NPLC 1000")
    err = dmm.query("SYST:ERR?").strip()
    assert err.startswith('-222,"Data out of range') and "100" in err
    dmm.close()


def test_powered_unit_reads_one_g_through_the_wire(sim_station, rm):
    supply = _open(rm, sim_station.resources()["supply"])
    dmm = _open(rm, sim_station.resources()["dmm"])
    clock = _open(rm, sim_station.resources()["sim"])
    supply.write("APPL CH2,15,0.1;APPL CH3,15,0.1")
    supply.query("OUTP ON,(@2,3);*OPC?")
    assert supply.query("OUTP? (@2,3)").strip() == "1,1"
    currents = [float(x) for x in supply.query("MEAS:CURR? (@2,3)").split(",")]
    assert currents == pytest.approx([0.016, 0.016])
    clock.query("SIM:TIME:ADV 30;*OPC?")
    volts = float(dmm.query("MEAS:VOLT:DC? 10"))
    truth = sim_station.truth()
    expected = (truth["k1_ma_per_g"] * 1e-3 * truth["sampling_resistor_ohm"]
                * (truth["g_local_over_g0"] + truth["k0_g"]))  # the drawn unit's bias too
    assert volts == pytest.approx(expected, rel=2e-3)
    assert float(clock.query("SIM:TIME?")) >= 30.0
    supply.query("OUTP OFF,(@2,3);*OPC?")
    assert abs(float(dmm.query("MEAS:VOLT:DC? 10"))) < 1e-4


def test_out_of_range_supply_voltage_is_refused_on_the_wire(sim_station, rm):
    supply = _open(rm, sim_station.resources()["supply"])
    supply.write("VOLT 30,(@2)")
    err = supply.query("SYST:ERR?").strip()
    assert err.startswith("-222") and "25" in err
    assert float(supply.query("VOLT? (@2)")) == 0.0


def test_turntable_moves_by_trapezoid_and_reports_in_position(sim_station, rm):
    table = _open(rm, sim_station.resources()["turntable"])
    clock = _open(rm, sim_station.resources()["sim"])
    table.write(":MODE:POS 2;:DEM:POS 2,90")
    assert table.query("SYST:ERR?").strip() == '+0,"No error"'
    assert int(table.query(":STAT? 2")) & 2  # moving
    clock.query("SIM:TIME:ADV 60;*OPC?")
    assert float(table.query(":READ:POS? 2")) == pytest.approx(90.0, abs=1e-3)
    assert int(table.query(":STAT? 2")) & 1  # in position
    table.write(":INT:OPEN")
    table.write(":MODE:POS 1")
    assert table.query("SYST:ERR?").startswith("-221")


def test_tilting_the_table_changes_the_reading_as_cos_theta(sim_station, rm):
    supply = _open(rm, sim_station.resources()["supply"])
    dmm = _open(rm, sim_station.resources()["dmm"])
    table = _open(rm, sim_station.resources()["turntable"])
    clock = _open(rm, sim_station.resources()["sim"])
    # Writes on different sockets are ordered only by a round trip: *OPC? after each.
    supply.query("APPL CH2,15,0.1;APPL CH3,15,0.1;OUTP ON,(@2,3);*OPC?")
    clock.query("SIM:TIME:ADV 3000;*OPC?")  # past the warm-up transient
    level = float(dmm.query("MEAS:VOLT:DC? 10"))
    table.query(":MODE:POS 2;:DEM:POS 2,60;*OPC?")
    clock.query("SIM:TIME:ADV 30;*OPC?")
    tilted = float(dmm.query("MEAS:VOLT:DC? 10"))
    assert tilted / level == pytest.approx(0.5, abs=2e-3)


def test_sim_control_refuses_going_back_in_time(sim_station, rm):
    clock = _open(rm, sim_station.resources()["sim"])
    clock.query("SIM:TIME:ADV 10;*OPC?")
    clock.write("SIM:TIME:UNT 5")
    assert clock.query("SYST:ERR?").startswith("-222")
    assert float(clock.query("SIM:TIME?")) == pytest.approx(10.0)
    assert clock.query("SIM:SEED?").strip() == "7"
