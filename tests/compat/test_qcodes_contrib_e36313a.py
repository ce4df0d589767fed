"""qcodes_contrib_drivers' Keysight ``E36313A`` driver, unchanged, against the simulated E36312A
served by ``bench sim serve``, over the raw socket and over HiSLIP.  The E36313A is the same
triple-output supply with more current (10 A, 2 A, 2 A); the driver checks neither the model
nor any limit, so a user points it at an E36312A as it is: every parameter of every channel
is read, every settable one set and read back within the E36312A's ratings, the outputs
measured powering the accelerometer — and what only an E36313A could do is refused by the
E36312A with the standard error, never silently clamped."""

from __future__ import annotations

import pytest
from qcodes_contrib_drivers.drivers.Keysight.Keysight_E36313A import E36313A

from tests.compat.serving import qcodes_parameters

NO_ERROR = '+0,"No error"'
#: the simulated E36312A's ratings: volts, amps per output (*RST: 0 V, the full current limit)
RATED = {1: (6.0, 5.0), 2: (25.0, 1.0), 3: (25.0, 1.0)}
#: an E36313A's current ratings, which the E36312A does not have
E36313A_AMPS = {1: 10.0, 2: 2.0, 3: 2.0}
#: per channel: settable parameters, the values set (each read back as set)
ROUND_TRIPS = {
    "source_voltage": lambda v_max, i_max: [v_max, v_max / 3, 1.234, 0.0],
    "source_current": lambda v_max, i_max: [0.001, i_max / 2, i_max],
    "enable": lambda v_max, i_max: ["on", "off"],
}
MEASURED = ("voltage", "current")  # per channel, read-only


@pytest.fixture(scope="module")
def supply(addresses, transport):
    psu = E36313A(f"compat_e36313a_{transport}", addresses["supply"], visalib="@py", timeout=10)
    yield psu
    psu.close()


@pytest.fixture
def fresh(supply):
    supply.write("*RST;*CLS")  # the driver has no reset of its own: what a user sends
    assert supply.ask("*OPC?") == "1"
    yield supply
    assert supply.ask("SYST:ERR?") == NO_ERROR


def test_the_driver_connects_to_the_e36312a_it_is_pointed_at(fresh):
    idn = fresh.IDN()
    assert (idn["vendor"], idn["model"]) == ("Keysight Technologies", "E36312A")
    assert idn["serial"] and idn["firmware"]


def test_every_parameter_is_covered(fresh):
    per_channel = {*ROUND_TRIPS, *MEASURED}
    assert set(qcodes_parameters(fresh)) == {"IDN", "timeout", *(f"ch{n}.{p}" for n in RATED for p in per_channel)}


def test_every_channel_parameter_reads_its_reset_state(fresh):
    for number, (_, i_max) in RATED.items():
        ch = getattr(fresh, f"ch{number}")
        assert (ch.source_voltage(), ch.source_current(), ch.enable()) == (0.0, i_max, "off"), number
        assert (ch.voltage(), ch.current()) == (0.0, 0.0), number  # output off


def test_every_settable_channel_parameter_round_trips(fresh):
    round_trips = 0
    for number, (v_max, i_max) in RATED.items():
        ch = getattr(fresh, f"ch{number}")
        for name, values in ROUND_TRIPS.items():
            param = ch.parameters[name]
            for value in values(v_max, i_max):
                param.set(value)
                got = param.get()
                assert got == (pytest.approx(value) if isinstance(value, float) else value), (number, name, value)
                assert fresh.ask("SYST:ERR?") == NO_ERROR, (number, name, value)
                round_trips += 1
    assert round_trips == 3 * (4 + 3 + 2)


def test_the_outputs_power_the_accelerometer_and_measure_its_draw(fresh, raw):
    for ch in (fresh.ch2, fresh.ch3):
        ch.source_voltage(15)
        ch.source_current(0.1)
        ch.enable("on")
    assert fresh.ch2.voltage() == pytest.approx(15.0)
    assert fresh.ch3.current() == pytest.approx(0.016)  # the unit's quiescent draw
    assert raw["dmm"].query("MEAS:VOLT:DC?").startswith("+6.")  # its output reaches the meter
    fresh.ch3.source_current(0.005)                     # below the draw: constant current
    assert fresh.ch3.current() == pytest.approx(0.005) and fresh.ch3.voltage() < 13
    assert (fresh.ch1.voltage(), fresh.ch1.current()) == (0.0, 0.0)
    fresh.write("OUTP OFF,(@1:3)")


@pytest.mark.parametrize("number", sorted(RATED))
def test_an_e36313a_current_is_refused_by_the_e36312a(fresh, number):
    ch = getattr(fresh, f"ch{number}")
    ch.source_current(E36313A_AMPS[number])  # QCoDeS does not read the error queue after a set
    assert fresh.ask("SYST:ERR?").startswith("-222,")
    assert ch.source_current() == RATED[number][1]  # unchanged: refused, not clamped
