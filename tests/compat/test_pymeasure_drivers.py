"""PyMeasure's drivers, unchanged, against the simulated station served by `bench sim serve`:
the Keysight E36312A supply driver, and the 34465A's predecessors whose language it speaks
(Agilent 34410A, HP 34401A).  Every property is either read (and, if settable, set and read
back) or, where the driver asks for something a DC-volts 34465A lacks, refused with the
standard error — never answered wrongly.  Every test that opens a driver runs twice: over the
raw socket (``...::SOCKET``, LF terminations set, as a user sets them) and over HiSLIP
(``...::hislip0,PORT::INSTR``, the drivers' default terminations)."""

from __future__ import annotations

import inspect
import warnings

import pytest
from pymeasure.instruments.agilent import Agilent34410A
from pymeasure.instruments.hp import HP34401A
from pymeasure.instruments.keysight import KeysightE36312A

from tests.compat.serving import pymeasure_options

RATED = {1: (6.0, 5.0), 2: (25.0, 1.0), 3: (25.0, 1.0)}  # E36312A: volts, amps per output


def _properties(cls) -> set[str]:
    return {name for name, member in inspect.getmembers(cls) if isinstance(member, property)}


def _refused(instrument, command: str) -> str:
    """Send what a property would send; return the error it left (no reply is expected)."""
    instrument.write(command)
    return instrument.ask("SYST:ERR?").strip()


@pytest.fixture(scope="module")
def visa(transport):
    """PyMeasure's adapter options for the address form under test."""
    return pymeasure_options(transport)


@pytest.fixture(scope="module")
def supply(addresses, visa):
    psu = KeysightE36312A(addresses["supply"], **visa)
    yield psu
    psu.adapter.close()


@pytest.fixture
def fresh_supply(supply):
    supply.reset()
    supply.clear()
    yield supply
    assert supply.check_errors() == []


def test_e36312a_every_channel_property_round_trips(fresh_supply):
    channel_props = _properties(type(fresh_supply.ch_1))
    assert {"voltage_setpoint", "current_limit", "output_enabled", "voltage", "current"} <= channel_props
    for number, (v_max, i_max) in RATED.items():
        ch = getattr(fresh_supply, f"ch_{number}")
        assert ch.voltage_setpoint == 0.0 and ch.current_limit == i_max  # *RST
        for volts in (v_max, v_max / 3, 0.0):
            ch.voltage_setpoint = volts
            assert ch.voltage_setpoint == pytest.approx(volts)
        for amps in (0.001, i_max / 2, i_max):
            ch.current_limit = amps
            assert ch.current_limit == pytest.approx(amps)
        for state in (True, False):
            ch.output_enabled = state
            assert ch.output_enabled is state
        assert (ch.voltage, ch.current) == (0.0, 0.0)  # output off


def test_e36312a_powers_the_accelerometer_and_measures_its_draw(fresh_supply):
    for ch in (fresh_supply.ch_2, fresh_supply.ch_3):
        ch.voltage_setpoint = 15
        ch.current_limit = 0.1
        ch.output_enabled = True
    assert fresh_supply.ch_2.voltage == pytest.approx(15.0)
    assert fresh_supply.ch_3.current == pytest.approx(0.016)  # the unit's quiescent draw
    fresh_supply.ch_3.current_limit = 0.005                  # below the draw: constant current
    assert fresh_supply.ch_3.current == pytest.approx(0.005) and fresh_supply.ch_3.voltage < 13
    fresh_supply.ch_2.output_enabled = False


def test_scpi_mixin_properties_of_every_driver(fresh_supply, addresses, visa):
    assert fresh_supply.id.startswith("Keysight Technologies,E36312A,")
    assert fresh_supply.complete == "1"
    assert fresh_supply.status == "+0" and fresh_supply.options == "0"
    assert fresh_supply.next_error[0] == 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)  # HP34401A: SCPI support "unknown"
        meters = [Agilent34410A(addresses["dmm"], **visa), HP34401A(addresses["dmm"], **visa)]
    for meter in meters:
        meter.reset()
        meter.clear()
        assert meter.id.startswith("Keysight Technologies,34465A,")
        assert meter.complete == "1" and meter.options == ["DIG", "MEM"]
        assert meter.check_errors() == []
        meter.adapter.close()


@pytest.fixture(scope="module")
def hp34401a(addresses, visa):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        dmm = HP34401A(addresses["dmm"], **visa)
    yield dmm
    dmm.adapter.close()


@pytest.fixture
def fresh_hp(hp34401a):
    hp34401a.reset()
    hp34401a.clear()
    yield hp34401a
    assert hp34401a.check_errors() == []


#: HP34401A properties, set -> read back, in the 34465A's language (DC volts)
HP_ROUND_TRIPS = {
    "function_": [("DCV", "DCV")],
    "range_": [(0.1, 0.1), (1000, 1000.0), (10, 10.0)],
    "autorange": [(True, True), (False, False)],
    "resolution": [(3e-5, 3e-5), (1e-6, 1e-6), (3e-7, 3e-7)],  # "%g": the driver sends no MIN/MAX
    "nplc": [(0.02, 0.02), (0.2, 0.2), (1, 1.0), (100, 100.0), ("MIN", 0.001), ("MAX", 100.0), (10, 10.0)],
    "trigger_source": [("BUS", "BUS"), ("EXT", "EXT"), ("IMM", "IMM")],
    "trigger_delay": [(0.5, 0.5), ("MAX", 3600.0), ("MIN", 0.0)],
    "trigger_auto_delay_enabled": [(False, False), (True, True)],
    "sample_count": [(500, 500), ("MAX", 1e9), ("MIN", 1)],
    "trigger_count": [(3, 3), ("MAX", 1e9), ("MIN", 1)],
    "display_enabled": [(False, False), (True, True)],
    "displayed_text": [("SIM", "SIM"), ("", "")],
    "beeper_enabled": [(False, False), (True, True)],
}
#: read-only HP34401A properties and what they read on the simulated meter after *RST
HP_READS = {"terminals_used": "FRONT", "scpi_version": 1999.0, "stored_readings_count": 0,
            "self_test_result": 0}
#: HP34401A properties a DC-volts 34465A refuses: the command they send, the error it leaves
HP_REFUSED = {
    "gate_time": ("FREQ:APER 0.1", -113),           # frequency function: not simulated
    "detector_bandwidth": ("DET:BAND 20", -113),    # AC detector: not simulated
    "autozero_enabled": ("ZERO:AUTO 1", -113),      # 34401A header; 34465A: VOLT:ZERO:AUTO
    "auto_input_impedance_enabled": ("INP:IMP:AUTO 1", -113),  # 34401A header; 34465A: VOLT:IMP:AUTO
    "remote_control_enabled": ("SYST:REM", -113),   # RS-232 commands: the 34465A has none
    "remote_lock_enabled": ("SYST:RWL", -113),
    "voltage_ac": ("MEAS:VOLT:AC? DEF,DEF", -113),  # deprecated measurements of other functions
    "current_dc": ("MEAS:CURR:DC? DEF,DEF", -113),
    "current_ac": ("MEAS:CURR:AC? DEF,DEF", -113),
    "resistance": ("MEAS:RES? DEF,DEF", -113),
    "resistance_4w": ("MEAS:FRES? DEF,DEF", -113),
}
HP_MEASUREMENTS = {"reading", "stored_reading"}


INHERITED = {"complete", "status", "options", "id", "next_error"}  # SCPIMixin: tested above


def test_hp34401a_every_property_is_covered():
    covered = set(HP_ROUND_TRIPS) | set(HP_READS) | set(HP_REFUSED) | HP_MEASUREMENTS
    assert _properties(HP34401A) - INHERITED == covered


def test_hp34401a_settings_round_trip(fresh_hp):
    for name, cases in HP_ROUND_TRIPS.items():
        for value, expected in cases:
            setattr(fresh_hp, name, value)
            got = getattr(fresh_hp, name)
            assert got == (pytest.approx(expected) if isinstance(expected, float) else expected), (name, value)
            assert fresh_hp.check_errors() == [], (name, value)


def test_hp34401a_reads(fresh_hp, powered):
    for name, expected in HP_READS.items():
        assert getattr(fresh_hp, name) == expected, name
    fresh_hp.function_ = "DCV"
    fresh_hp.nplc = 1
    assert fresh_hp.reading == pytest.approx(6.6, rel=0.05)
    fresh_hp.sample_count = 5
    fresh_hp.init_trigger()
    assert len(fresh_hp.stored_reading) == 5 and fresh_hp.stored_readings_count == 5


@pytest.mark.parametrize("name", sorted(HP_REFUSED))
def test_hp34401a_what_a_dc_volts_34465a_lacks_is_refused(fresh_hp, name):
    command, code = HP_REFUSED[name]
    assert _refused(fresh_hp, command).startswith(f"{code},")


def test_hp34401a_other_functions_are_refused_not_faked(fresh_hp):
    for function in ("ACV", "DCI", "R2W", "FREQ"):
        fresh_hp.function_ = function
        assert fresh_hp.next_error[0] == -224
    assert fresh_hp.function_ == "DCV"


def test_agilent34410a_reads_dc_volts_and_refuses_the_rest(addresses, visa, powered):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        dmm = Agilent34410A(addresses["dmm"], **visa)
    try:
        assert dmm.voltage_dc == pytest.approx(6.6, rel=0.05)
        assert _properties(Agilent34410A) - INHERITED == {
            "voltage_dc", "voltage_ac", "current_dc", "current_ac", "resistance", "resistance_4w"}
        for command in ("MEAS:VOLT:AC? DEF,DEF", "MEAS:CURR:DC? DEF,DEF", "MEAS:CURR:AC? DEF,DEF",
                        "MEAS:RES? DEF,DEF", "MEAS:FRES? DEF,DEF"):
            assert _refused(dmm, command).startswith("-113,")
        assert dmm.check_errors() == []
    finally:
        dmm.adapter.close()
