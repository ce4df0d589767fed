"""QCoDeS's ``Keysight34465A`` driver, unchanged, against the simulated meter served by
``bench sim serve``: every parameter read, every settable parameter set and read back, a
full snapshot, ``volt`` and a 10⁴-point time trace at 1 ms — over the raw socket and over
HiSLIP, the driver's own settings either way (it sets LF terminations itself)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from qcodes.instrument_drivers.Keysight import Keysight34465A
from qcodes.parameters import Parameter

from tests.compat.serving import qcodes_parameters

#: the 34465A data sheet's resolution per NPLC (ppm of range), DIG option fitted
RESOLUTION_PPM = (30, 15, 6, 3, 1.5, 0.7, 0.3, 0.1, 0.03)
MEM_DEPTH = 2_000_000  # MEM option


def _resolutions_10v():
    return [ppm * 1e-5 for ppm in RESOLUTION_PPM]  # x 10 V range x 1e-6


#: value set -> value read back (a bare value reads back as itself); "MIN"/"MAX"/"DEF" are the
#: driver's own keyword values.  Every settable parameter of the driver must be listed.
ROUND_TRIPS: dict[str, list] = {
    "timeout": [7.5, 10.0],
    "sense_function": ["DC Voltage"],  # the only simulated function (others: -224, see below)
    "NPLC": [0.001, 0.002, 0.006, 0.02, 0.06, 0.2, 1.0, 100.0, 10.0],
    "range": [0.1, 1.0, 100.0, 1000.0, 10.0],
    "resolution": [*_resolutions_10v(), ("MIN", 0.03e-5), ("MAX", 30e-5), ("DEF", 0.1e-5)],
    "autorange": ["OFF", "ON"],
    "autozero": ["OFF", ("ONCE", "OFF"), "ON"],  # ONCE zeroes once, then reads OFF (the guide)
    "aperture_mode": ["ON", "OFF"],
    "aperture_time": [2e-5, 0.5, 1.0, ("MIN", 2e-5), ("MAX", 1.0), ("DEF", 0.1)],
    "timetrace_npts": [10_000, 500],
    "timetrace_dt": [1e-3, 0.1],
    "display.enabled": [False, True],
    "display.text": ["hello from QCoDeS", ""],  # the driver does not double quotes
    "trigger.count": [250, 1e9, ("INF", 9.9e37), ("MAX", 1e9), ("MIN", 1.0), ("DEF", 1.0), 1],
    "trigger.delay": [0.25, 3600.0, ("MAX", 3600.0), ("MIN", 0.0), 0.0],
    "trigger.auto_delay_enabled": [False, True],
    "trigger.slope": ["POS", "NEG"],
    "trigger.level": [-2.5, 0.75, ("MAX", 1000.0), ("MIN", -1000.0), ("DEF", 0.0)],
    "trigger.source": ["BUS", "EXT", "INT", "IMM"],
    "sample.count": [10_000, ("MAX", 1e9), ("MIN", 1), ("DEF", 1), 1],
    "sample.pretrigger_count": [1000, ("MAX", MEM_DEPTH - 1), ("MIN", 0), 0],
    "sample.source": ["TIM", "IMM"],
    "sample.timer": [1e-3, 3600.0, ("DEF", 1.0), ("MIN", "timer_minimum"), 1.0],
}


#: measurement parameters of functions the simulated meter does not have (it is a DC voltmeter
#: on the station): each switches SENS:FUNC, which is refused with -224, then reads DC volts
NOT_SIMULATED = ("curr", "ac_volt", "ac_curr", "res", "four_wire_res")


@pytest.fixture(scope="module")
def dmm(addresses, transport):
    meter = Keysight34465A(f"compat_dmm_{transport}", addresses["dmm"], visalib="@py", timeout=10)
    yield meter
    meter.close()


@pytest.fixture
def fresh(dmm):
    dmm.reset()  # *RST, *OPC?, snapshot(update=True)
    yield dmm
    assert dmm.error() == (0, "No error")


def test_the_driver_connects_and_sees_a_34465a_with_dig_and_mem(fresh):
    idn = fresh.IDN()
    assert (idn["vendor"], idn["model"]) == ("Keysight Technologies", "34465A")
    assert fresh.has_DIG and fresh.has_MEM
    assert fresh.line_frequency() == 50


def test_every_parameter_reads_back_without_error_or_timeout(fresh):
    values = {}
    for name, param in qcodes_parameters(fresh).items():
        if name in ("timetrace", "time_axis", *NOT_SIMULATED):  # their own tests below
            continue
        values[name] = param.get()
        assert fresh.error() == (0, "No error"), name
    assert values["trigger.slope"] == "NEG" and values["trigger.level"] == 0.0
    assert values["sample.pretrigger_count"] == 0
    assert values["sense_function"] == "DC Voltage"
    assert values["sample.timer_minimum"] == pytest.approx(0.40002)  # 10 PLC, autozero: 2 x 0.2 s + 20 us


def test_a_full_snapshot_comes_back_with_every_value(fresh):
    snap = fresh.snapshot(update=True)
    assert fresh.error() == (0, "No error")
    sections = [snap["parameters"], *(s["parameters"] for s in snap["submodules"].values())]
    read = {name: entry for section in sections for name, entry in section.items()}
    for name, param in qcodes_parameters(fresh).items():
        entry = read[param.short_name]
        if param._snapshot_get and param._snapshot_value and param.gettable:
            assert "value" in entry and entry["ts"] is not None, name
    assert read["slope"]["value"] == "NEG" and read["pretrigger_count"]["value"] == 0


def test_every_settable_parameter_round_trips(fresh):
    params = qcodes_parameters(fresh)
    settable = {n for n, p in params.items() if p.settable and p.gettable}
    assert settable == set(ROUND_TRIPS), "a parameter the table does not cover, or one it lists in vain"
    for name, cases in ROUND_TRIPS.items():
        param: Parameter = params[name]
        for case in cases:
            value, expected = case if isinstance(case, tuple) else (case, case)
            param.set(value)
            if expected == "timer_minimum":
                expected = fresh.sample.timer_minimum()
            got = param.get()
            if isinstance(expected, float):
                assert math.isclose(got, expected, rel_tol=1e-9, abs_tol=1e-15), (name, value, got)
            else:
                assert got == expected, (name, value, got)
            assert fresh.error() == (0, "No error"), (name, value)


def test_time_trace_of_ten_thousand_points_at_one_millisecond(fresh, powered):
    sim = powered["sim"]
    fresh.NPLC(0.02)                 # 0.4 ms aperture, x2 with autozero: fits in 1 ms
    fresh.timetrace_npts(10_000)
    fresh.timetrace_dt(1e-3)
    t0 = float(sim.query("SIM:TIME?"))
    trace = fresh.timetrace()
    elapsed_s = float(sim.query("SIM:TIME?")) - t0
    assert trace.shape == (10_000,) and np.all(np.isfinite(trace))
    assert fresh.time_axis()[-1] == pytest.approx(9.999)
    assert 10.0 <= elapsed_s < 10.01  # the meter's timer, in the world's time: 10^4 x 1 ms
    assert np.mean(trace) == pytest.approx(6.6, rel=0.05)  # the accelerometer's output at 1 g
    assert 0 < np.std(trace) < 1e-3
    # the driver restores every setting it changed for the trace
    assert (fresh.trigger.source(), fresh.sample.count(), fresh.sample.source()) == ("IMM", 1, "IMM")
    assert fresh.display.text() == ""


def test_volt_reads_the_unit_and_an_overload_as_infinity(fresh, powered):
    assert fresh.volt() == pytest.approx(6.6, rel=0.05)
    powered["sim"].write('SIM:FAUL:OVER "dmm"')
    try:
        assert fresh.volt() == np.inf  # +9.9E37 on the wire
    finally:
        powered["sim"].write('SIM:FAUL:CLE "dmm"')
    assert powered["sim"].query("SIM:FAUL?") == '""'


def test_opc_query_answers_after_the_acquisition_it_follows(fresh):
    fresh.NPLC(0.02)
    fresh.sample.count(1000)
    fresh.init_measurement()
    assert fresh.ask("*OPC?") == "1"
    assert fresh.ask("DATA:POIN?") == "+1000"
    assert fresh.fetch().shape == (1000,)


@pytest.mark.parametrize("name", NOT_SIMULATED)
def test_functions_not_simulated_leave_the_standard_error_not_silence(fresh, name):
    getattr(fresh, name)()  # QCoDeS reads the error queue never: a script should
    code, message = fresh.error()
    assert code == -224 and "not simulated" in message


def test_what_the_simulation_lacks_is_refused_with_the_standard_error(fresh):
    fresh.sense_function("AC Voltage")  # QCoDeS does not read the error queue after a set
    code, message = fresh.error()
    assert code == -224 and "not simulated" in message
    assert fresh.sense_function() == "DC Voltage"
    fresh.write("VOLT:NPLC 7e3")
    assert fresh.error() == (-222, "Data out of range;NPLC 7000 not in 0.001..100")


def test_level_trigger_with_pretrigger_catches_the_unit_switching_on(fresh, raw):
    supply = raw["supply"]
    supply.write("OUTP OFF,(@1:3)")
    fresh.NPLC(0.02)
    fresh.autorange("OFF")
    fresh.range(10)
    fresh.sample.source("TIM")
    fresh.sample.timer(1e-3)
    fresh.sample.count(400)
    fresh.sample.pretrigger_count(100)
    fresh.trigger.delay(0)
    fresh.trigger.source("INT")
    fresh.trigger.slope("POS")
    fresh.trigger.level(3.0)
    fresh.init_measurement()
    # two connections are ordered only by a round trip: the meter armed before the supply
    # switches on (SYST:ERR?, not *OPC?, which would wait for the acquisition to end)
    assert fresh.error() == (0, "No error")
    raw["sim"].query("SIM:TIME:ADV 0.2;*OPC?")  # the script does something else for 200 ms
    supply.write("APPL CH2,15,0.1;APPL CH3,15,0.1;:OUTP ON,(@2,3)")
    assert supply.query("SYST:ERR?") == '+0,"No error"'
    try:
        trace = fresh.fetch()
    finally:
        supply.write("OUTP OFF,(@1:3)")
    assert trace.shape == (400,)
    assert np.all(np.abs(trace[:99]) < 1e-3) and np.all(trace[100:] > 6)  # off, then on
