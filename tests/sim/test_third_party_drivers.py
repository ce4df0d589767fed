"""Drivers written for the real instruments, unchanged, against the simulators (PyMeasure),
checked against the simulated unit's true parameters (in-process station; the full
compatibility suite, against `bench sim serve`, is tests/compat/)."""

from __future__ import annotations

import pytest
from pymeasure.instruments.agilent import Agilent34410A
from pymeasure.instruments.hp import HP34401A
from pymeasure.instruments.keysight import KeysightE36312A

# PyMeasure warns that it does not know whether a 34401A/34410A speaks SCPI: it does
pytestmark = pytest.mark.filterwarnings("ignore:It is not known whether this device:FutureWarning")

VISA = dict(visa_library="@py", read_termination="\n", write_termination="\n", timeout=10000)


def _powered(sim_station):
    supply = KeysightE36312A(sim_station.resources()["supply"], **VISA)
    for ch in (supply.ch_2, supply.ch_3):
        ch.voltage_setpoint = 15
        ch.current_limit = 0.1
        ch.output_enabled = True
    return supply


def test_pymeasure_e36312a_drives_the_simulated_supply(sim_station):
    supply = _powered(sim_station)
    assert supply.ch_2.voltage_setpoint == pytest.approx(15.0)
    assert supply.ch_2.output_enabled is True
    assert supply.ch_2.voltage == pytest.approx(15.0)
    assert supply.ch_3.current == pytest.approx(0.016)  # the accelerometer's quiescent draw
    assert "E36312A" in supply.id
    supply.ch_2.output_enabled = False
    assert supply.ch_2.current == 0.0
    assert not bool(sim_station.accel.powered(sim_station.world.now))  # one rail gone


def test_pymeasure_34410a_reads_the_accelerometer_output(sim_station):
    _powered(sim_station)
    dmm = Agilent34410A(sim_station.resources()["dmm"], **VISA)
    volts = dmm.voltage_dc
    truth = sim_station.truth()
    expected = (truth["k1_a_per_g"] * truth["sampling_resistor_ohm"]
                * (truth["g_local_over_g0"] + truth["k0_g"]))  # the drawn unit's bias too
    assert volts == pytest.approx(expected, rel=2e-3)
    assert dmm.ask("SYST:ERR?").strip() == '+0,"No error"'


def test_pymeasure_hp34401a_configures_and_reads(sim_station):
    _powered(sim_station)
    dmm = HP34401A(sim_station.resources()["dmm"], **VISA)
    dmm.function_ = "DCV"
    dmm.range_ = 10
    dmm.nplc = 1
    assert dmm.nplc == pytest.approx(1.0)
    value = dmm.reading
    assert value == pytest.approx(6.6, rel=0.05)
    assert dmm.ask("SYST:ERR?").strip() == '+0,"No error"'
