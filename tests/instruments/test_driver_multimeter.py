"""Keysight 34465A driver: exact wire bytes per setting, validation, trace timing,
REAL,64 reading blocks, streaming, and the pyvisa-sim vocabulary."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.testing import SIM_YAML_DIR, FakeResource, assert_conforms, pack_real64_block
from instruments import InstrumentError, InstrumentReplyError, Keysight34465A, TimedTraceMultimeter
from instruments.base import UnsupportedInstrumentError, open_resource
from instruments.multimeter import NPLC_DIG, NPLC_STANDARD, SAMPLE_OVERHEAD_S

IDN = "Keysight Technologies,34465A,MY60000001,A.03.02"
FORMAT_COMMANDS = ["FORM REAL,64", "FORM:BORD SWAP", "SYST:ERR?"]


def make_dmm(options: str = "DIG,MEM", lfr: str = "+50", idn: str = IDN,
             replies: Mapping[str, Any] | None = None) -> tuple[Keysight34465A, FakeResource]:
    """A driver on a fake resource answering the identity queries and ``replies`` (header → reply)."""
    fake = FakeResource(replies={"*IDN?": idn, "*OPT?": options, "SYST:LFR?": lfr, "*OPC?": "1",
                                 **(replies or {})})
    dmm = Keysight34465A(fake)
    fake.written.clear()
    return dmm, fake


def test_construction_identifies_the_meter() -> None:
    fake = FakeResource(replies={"*IDN?": IDN, "*OPT?": "DIG", "SYST:LFR?": "+60"})
    dmm = Keysight34465A(fake)
    assert fake.written == ["*IDN?", "*OPT?", "SYST:LFR?"]
    assert dmm.has_dig and dmm.memory_depth == 50_000
    assert make_dmm(options="MEM")[0].memory_depth == 2_000_000


def test_other_models_are_refused() -> None:
    with pytest.raises(UnsupportedInstrumentError):
        make_dmm(idn="Keysight Technologies,34461A,MY1,A.02")
    assert make_dmm(idn="Keysight Technologies,34470A,MY1,A.03")[0].idn.model == "34470A"


@pytest.mark.parametrize("attr, value, command", [
    ("nplc", 10, "VOLT:DC:NPLC 10"),
    ("nplc", 0.001, "VOLT:DC:NPLC 0.001"),
    ("nplc", 0.2, "VOLT:DC:NPLC 0.2"),
    ("range_v", 1, "VOLT:DC:RANG 1"),
    ("range_v", 0.1, "VOLT:DC:RANG 0.1"),
    ("autorange", True, "VOLT:DC:RANG:AUTO ON"),
    ("aperture_s", 0.001, "VOLT:DC:APER 0.001"),
    ("aperture_s", 2e-5, "VOLT:DC:APER 2e-05"),
    ("autozero", "once", "VOLT:DC:ZERO:AUTO ONCE"),
    ("trigger_source", "bus", "TRIG:SOUR BUS"),
    ("trigger_count", 5, "TRIG:COUN 5"),
    ("trigger_delay_s", 0.5, "TRIG:DEL 0.5"),
    ("sample_source", "TIM", "SAMP:SOUR TIM"),
    ("sample_interval_s", 0.001, "SAMP:TIM 0.001"),
    ("sample_count", 1000, "SAMP:COUN 1000"),
    ("display_text", 'Say "hi"', 'DISP:TEXT "Say ""hi"""'),
])
def test_setting_writes_exact_bytes(attr: str, value: Any, command: str) -> None:
    dmm, fake = make_dmm()
    setattr(dmm, attr, value)
    assert fake.written == [command, "SYST:ERR?"]


@pytest.mark.parametrize("attr, value", [
    ("nplc", 5), ("nplc", 0.001), ("range_v", 3), ("aperture_s", 2e-5), ("aperture_s", 1.5),
    ("autozero", "MAYBE"), ("autorange", 1), ("trigger_source", "NOW"), ("trigger_count", 0),
    ("trigger_count", 1.5), ("trigger_delay_s", -0.1), ("sample_source", "EXT"),
    ("sample_interval_s", 1e-6), ("sample_count", 0), ("display_text", "x" * 41),
    ("display_text", "caf\u00e9"),
])
def test_invalid_settings_raise_before_the_wire(attr: str, value: Any) -> None:
    dmm, fake = make_dmm(options="MEM")  # no DIG: the fastest NPLC/aperture are refused
    with pytest.raises(ValueError) as info:
        setattr(dmm, attr, value)
    assert attr in str(info.value)
    assert fake.written == []


def test_nplc_allowed_set_depends_on_dig_option() -> None:
    assert make_dmm(options="DIG")[0].nplc_values == NPLC_DIG + NPLC_STANDARD
    dmm, _ = make_dmm(options="0")
    assert dmm.nplc_values == NPLC_STANDARD
    with pytest.raises(ValueError, match=r"0\.02, 0\.06, 0\.2, 1, 10, 100"):
        dmm.nplc = 0.006


def test_getters_parse_the_documented_replies() -> None:
    dmm, fake = make_dmm(replies={
        "VOLT:DC:NPLC?": "+1.00000000E+01", "VOLT:DC:ZERO:AUTO?": "0",
        "TRIG:COUN?": "+5.00000000E+00",
        "FUNC?": '"VOLT"', "VOLT:DC:RANG:AUTO?": "1", "DISP:TEXT?": '"Hello"', "TRIG:SOUR?": "IMM",
        "SAMP:COUN?": "+1000", "DATA:POIN?": "+123", "VOLT:DC:APER:ENAB?": "0"})
    assert dmm.nplc == 10.0
    assert dmm.autozero == "OFF"
    assert dmm.trigger_count == 5
    assert dmm.function == "VOLT"
    assert dmm.autorange is True
    assert dmm.display_text == "Hello"
    assert dmm.trigger_source == "IMM"
    assert dmm.sample_count == 1000
    assert dmm.points_available() == 123
    assert dmm.aperture_enabled is False


def test_instrument_error_is_raised_with_code_and_message() -> None:
    dmm, fake = make_dmm()
    fake.error_queue.append('-222,"Data out of range"')
    with pytest.raises(InstrumentError) as info:
        dmm.trigger_delay_s = 1.0
    assert (info.value.code, info.value.message, info.value.command) == (
        -222, "Data out of range", "TRIG:DEL 1")


def test_configure_dc_voltage() -> None:
    dmm, fake = make_dmm()
    dmm.configure_dc_voltage(10)
    dmm.configure_dc_voltage()
    dmm.configure_dc_voltage(range_v=0.1, nplc=100)
    assert fake.written == ["CONF:VOLT:DC 10", "SYST:ERR?", "CONF:VOLT:DC AUTO", "SYST:ERR?",
                            "CONF:VOLT:DC 0.1", "VOLT:DC:NPLC 100", "SYST:ERR?"]
    fake.written.clear()
    for bad in (dict(range_v=5), dict(range_v=10, nplc=3)):
        with pytest.raises(ValueError):
            dmm.configure_dc_voltage(**bad)
    assert fake.written == []


def test_configure_timed_trace_writes_one_group() -> None:
    dmm, fake = make_dmm()
    plan = dmm.configure_timed_trace(1000, 0.005, nplc=0.2, range_v=10)
    assert fake.written == [
        "CONF:VOLT:DC 10", "VOLT:DC:NPLC 0.2", "VOLT:DC:ZERO:AUTO OFF", "TRIG:SOUR IMM",
        "TRIG:COUN 1", "TRIG:DEL 0", "SAMP:SOUR TIM", "SAMP:TIM 0.005", "SAMP:COUN 1000",
        "FORM REAL,64", "FORM:BORD SWAP", "SYST:ERR?"]
    assert (plan.n_samples, plan.interval_s, plan.integration_s) == (1000, 0.005, 0.2 / 50)
    assert plan.duration_s == pytest.approx(999 * 0.005)


def test_failed_trace_configuration_is_not_remembered() -> None:
    dmm, fake = make_dmm(replies={"READ?": pack_real64_block([0.5])})
    fake.error_queue.append('-221,"Settings conflict"')
    with pytest.raises(InstrumentError):
        dmm.configure_timed_trace(100, 0.1)
    assert dmm.trace_plan is None
    fake.written.clear()
    dmm.measure_dc_voltage()  # the reading format is selected again
    assert fake.written == FORMAT_COMMANDS + ["READ?"]


def test_configure_timed_trace_with_aperture() -> None:
    dmm, fake = make_dmm()
    plan = dmm.configure_timed_trace(10, 2e-4, aperture_s=5e-5, autozero="ON", range_v=1)
    assert "VOLT:DC:APER 5e-05" in fake.written and "VOLT:DC:ZERO:AUTO ON" in fake.written
    assert plan.integration_s == 5e-5


@given(nplc=st.sampled_from(NPLC_DIG + NPLC_STANDARD), lfr=st.sampled_from([50, 60]),
       autozero=st.sampled_from(["ON", "OFF"]), ratio=st.floats(0.5, 1.5))
@settings(max_examples=80, deadline=None)
def test_trace_interval_must_cover_integration_plus_overhead(
        nplc: float, lfr: int, autozero: str, ratio: float) -> None:
    dmm, fake = make_dmm(lfr=str(lfr))
    minimum = nplc / lfr * (2 if autozero == "ON" else 1) + SAMPLE_OVERHEAD_S
    interval = min(max(minimum * ratio, 20e-6), 3600.0)
    if interval >= minimum:
        dmm.configure_timed_trace(100, interval, nplc=nplc, autozero=autozero)
        assert f"SAMP:TIM {interval:.12g}" in fake.written
    else:
        with pytest.raises(ValueError, match="integration time plus overhead"):
            dmm.configure_timed_trace(100, interval, nplc=nplc, autozero=autozero)
        assert fake.written == []


@pytest.mark.parametrize("kwargs", [
    dict(n_samples=0, interval_s=0.1), dict(n_samples=1_000_000_001, interval_s=0.1),
    dict(n_samples=10, interval_s=1e-6), dict(n_samples=10, interval_s=0.1, range_v=2),
    dict(n_samples=10, interval_s=0.1, nplc=3), dict(n_samples=10, interval_s=0.1, autozero="X"),
    dict(n_samples=10, interval_s=0.1, aperture_s=5.0), dict(n_samples=2.5, interval_s=0.1),
])
def test_configure_timed_trace_rejects_bad_arguments_before_the_wire(kwargs: dict) -> None:
    dmm, fake = make_dmm()
    with pytest.raises(ValueError):
        dmm.configure_timed_trace(**kwargs)
    assert fake.written == []


def test_fetch_all_refuses_a_trace_longer_than_reading_memory() -> None:
    dmm, fake = make_dmm(options="DIG")
    dmm.configure_timed_trace(60_000, 1e-3, nplc=0.02)
    fake.written.clear()
    with pytest.raises(RuntimeError, match="stream_trace"):
        dmm.fetch_all()
    assert fake.written == []


finite = st.floats(min_value=-1e37, max_value=1e37, allow_nan=False, width=64)


@given(st.lists(finite, min_size=1, max_size=400))
@settings(max_examples=60, deadline=None)
def test_read_and_remove_decodes_real64_blocks_exactly(values: list[float]) -> None:
    n = len(values)
    dmm, fake = make_dmm(replies={f"R? {n}": pack_real64_block(values)})
    readings = dmm.read_and_remove(n)
    assert fake.written == FORMAT_COMMANDS + [f"R? {n}"]
    assert readings.astype("<f8").tobytes() == np.array(values, dtype="<f8").tobytes()


def test_fetch_all_and_read_flag_overloads_as_nan() -> None:
    raw = [1.5, 9.9e37, -9.9e37, 9.91e37, -2.25e-6]
    dmm, fake = make_dmm(replies={"FETC?": pack_real64_block(raw), "READ?": pack_real64_block([9.9e37])})
    readings = dmm.fetch_all()
    assert np.isnan(readings).tolist() == [False, True, True, True, False]
    assert readings[0] == 1.5 and readings[4] == -2.25e-6
    assert math.isnan(dmm.measure_dc_voltage())
    assert fake.written == FORMAT_COMMANDS + ["FETC?", "READ?"]  # format selected once


def test_measure_dc_voltage_expects_one_reading() -> None:
    dmm, _ = make_dmm(replies={"READ?": pack_real64_block([1.25])})
    assert dmm.measure_dc_voltage() == 1.25
    dmm.resource.replies["READ?"] = pack_real64_block([1.0, 2.0])
    with pytest.raises(InstrumentReplyError):
        dmm.measure_dc_voltage()


def test_reset_forgets_the_binary_format() -> None:
    dmm, fake = make_dmm(replies={"READ?": pack_real64_block([0.5])})
    dmm.measure_dc_voltage()
    dmm.reset()
    dmm.measure_dc_voltage()
    assert fake.written.count("FORM REAL,64") == 2


@pytest.mark.parametrize("reply, value", [("+1.73730000E-03 VDC", 1.7373e-3),
                                          ("-2.5E+00 VDC", -2.5)])
def test_last_reading(reply: str, value: float) -> None:
    dmm, fake = make_dmm(replies={"DATA:LAST?": reply})
    assert dmm.last_reading() == value
    assert fake.written == ["DATA:LAST?"]


def test_read_available_drains_what_is_there() -> None:
    dmm, fake = make_dmm(replies={"R? 3": pack_real64_block([1.0, 2.0, 3.0])})
    fake.replies["DATA:POIN?"] = "+0"
    assert dmm.read_available().size == 0
    fake.replies["DATA:POIN?"] = "+3"
    assert dmm.read_available().tolist() == [1.0, 2.0, 3.0]
    assert fake.written == ["DATA:POIN?", "DATA:POIN?"] + FORMAT_COMMANDS + ["R? 3"]
    fake.replies["R? 2"] = pack_real64_block([4.0, 5.0])
    assert dmm.read_available(max_n=2).tolist() == [4.0, 5.0]


def test_snapshot_records_identity_options_and_settings() -> None:
    dmm, _ = make_dmm(replies={"FUNC?": '"VOLT"', "VOLT:DC:RANG?": "+1.0E+01", "VOLT:DC:RANG:AUTO?": "0",
                         "VOLT:DC:NPLC?": "+1.0E+00",
                         "VOLT:DC:ZERO:AUTO?": "0", "TRIG:SOUR?": "IMM", "TRIG:COUN?": "+1",
                         "TRIG:DEL?": "+0.0E+00", "SAMP:SOUR?": "TIM", "SAMP:TIM?": "+1.0E-02",
                         "SAMP:COUN?": "+100"})
    snap = dmm.snapshot()
    assert snap["idn"]["model"] == "34465A" and snap["options"] == ["DIG", "MEM"]
    assert snap["settings"]["nplc"] == 1.0 and snap["settings"]["sample_count"] == 100
    assert snap["line_frequency_hz"] == 50.0 and snap["memory_depth"] == 2_000_000


def test_last_reading_overload_is_nan() -> None:
    assert math.isnan(make_dmm(replies={"DATA:LAST?": "+9.90000000E+37 VDC"})[0].last_reading())


def test_read_and_remove_bounds() -> None:
    dmm, fake = make_dmm(options="0")
    bad_counts: tuple[Any, ...] = (0, 50_001, 2.5)  # a caller's mistakes, a fraction among them
    for bad in bad_counts:
        with pytest.raises(ValueError):
            dmm.read_and_remove(bad)
    assert fake.written == []


class AcquiringMeter:
    """Answers DATA:POIN? and R? n like a meter acquiring ``data`` at one sample per
    ``interval_s`` of (fake) time; time advances only when the driver calls ``wait``."""

    def __init__(self, data: np.ndarray, interval_s: float, fake: FakeResource) -> None:
        self.data, self.interval_s, self.t = data, interval_s, 0.0
        self.removed = 0
        self.started = False
        self.waits: list[float] = []
        fake.replies["DATA:POIN?"] = lambda _: f"+{self.acquired() - self.removed}"
        for k in range(1, 101):  # every chunk size these tests use
            fake.replies[f"R? {k}"] = self.remove
        fake.replies["INIT"] = self.start

    def start(self, _: str) -> None:
        self.started = True

    def acquired(self) -> int:
        return min(len(self.data), int(self.t / self.interval_s + 1e-9)) if self.started else 0

    def remove(self, message: str) -> bytes:
        k = min(int(message.split()[1]), self.acquired() - self.removed)
        block = pack_real64_block(self.data[self.removed:self.removed + k])
        self.removed += k
        return block

    def wait(self, dt: float) -> None:
        self.waits.append(dt)
        self.t += dt


@given(data=st.lists(finite, min_size=1, max_size=300), chunk=st.integers(1, 64),
       interval_s=st.sampled_from([1e-3, 0.02, 0.1]))
@settings(max_examples=40, deadline=None)
def test_stream_trace_yields_the_trace_in_order_in_fixed_chunks(
        data: list[float], chunk: int, interval_s: float) -> None:
    dmm, fake = make_dmm()
    dmm.configure_timed_trace(len(data), interval_s, nplc=0.02)
    meter = AcquiringMeter(np.array(data), interval_s, fake)
    fake.written.clear()
    chunks = list(dmm.stream_trace(chunk, wait=meter.wait))
    assert all(c.dtype == np.float64 for c in chunks)
    assert [len(c) for c in chunks[:-1]] == [chunk] * (len(chunks) - 1)
    assert 1 <= len(chunks[-1]) <= chunk
    assert np.concatenate(chunks).tobytes() == np.array(data, dtype="<f8").tobytes()
    assert fake.written.count("INIT") == 1 and "ABOR" not in fake.written
    assert all(w > 0 for w in meter.waits)


def test_stream_trace_aborts_when_the_consumer_stops_early() -> None:
    dmm, fake = make_dmm()
    dmm.configure_timed_trace(100, 0.01, nplc=0.2)
    meter = AcquiringMeter(np.arange(100.0), 0.01, fake)
    stream = dmm.stream_trace(10, wait=meter.wait)
    first = next(stream)
    stream.close()
    assert first.tolist() == list(range(10))
    assert fake.written[-2:] == ["ABOR", "SYST:ERR?"]


def test_stream_trace_times_out_when_no_readings_arrive() -> None:
    dmm, fake = make_dmm(replies={"DATA:POIN?": "+0"})
    dmm.configure_timed_trace(10, 0.01, nplc=0.2)
    waited: list[float] = []
    with pytest.raises(TimeoutError):
        list(dmm.stream_trace(5, wait=waited.append, stall_timeout_s=1.0))
    assert 1.0 <= sum(waited) < 1.2
    assert "ABOR" in fake.written


def test_stream_trace_reports_a_full_reading_memory() -> None:
    dmm, fake = make_dmm(options="0", replies={"DATA:POIN?": "+50000"})
    dmm.configure_timed_trace(100_000, 1e-3, nplc=0.02)
    with pytest.raises(RuntimeError, match="reading memory full"):
        next(dmm.stream_trace(10_000, wait=lambda s: None))
    assert "ABOR" in fake.written


def test_stream_trace_validates_before_the_wire() -> None:
    dmm, fake = make_dmm(options="0")
    with pytest.raises(RuntimeError, match="configure_timed_trace"):
        dmm.stream_trace(wait=lambda s: None)
    dmm.configure_timed_trace(10, 0.1)
    fake.written.clear()
    with pytest.raises(ValueError, match=r"\[1, 25000\]"):
        dmm.stream_trace(25_001, wait=lambda s: None)
    no_wait: Any = None  # a caller that forgot the bench clock
    with pytest.raises(ValueError):
        dmm.stream_trace(10, wait=no_wait)
    assert fake.written == []


def test_driver_fits_the_timed_trace_multimeter_protocol() -> None:
    assert_conforms(make_dmm()[0], TimedTraceMultimeter)


@pytest.fixture()
def sim_dmm() -> Any:
    resource = open_resource("TCPIP0::127.0.0.1::5025::SOCKET",
                             backend=f"{SIM_YAML_DIR / 'keysight_34465a.yaml'}@sim")
    yield Keysight34465A(resource)
    resource.close()


def test_pyvisa_sim_vocabulary_round_trips(sim_dmm: Keysight34465A) -> None:
    assert sim_dmm.idn.model == "34465A" and sim_dmm.memory_depth == 2_000_000
    assert sim_dmm.line_frequency_hz == 50.0
    sim_dmm.nplc = 0.006
    sim_dmm.autozero = "OFF"
    sim_dmm.display_text = "bench"
    plan = sim_dmm.configure_timed_trace(500, 0.002, nplc=0.02, range_v=1)
    assert (sim_dmm.nplc, sim_dmm.sample_count, sim_dmm.sample_interval_s) == (0.02, 500, 0.002)
    assert (sim_dmm.sample_source, sim_dmm.trigger_source) == ("TIM", "IMM")
    assert sim_dmm.autozero == "OFF"
    assert sim_dmm.display_text == "bench" and plan.n_samples == 500
    assert sim_dmm.last_reading() == 1.23456789
    sim_dmm.initiate()
    assert sim_dmm.points_available() == 0
    sim_dmm.abort()
    sim_dmm.reset()


def test_pyvisa_sim_error_queue_reaches_the_driver(sim_dmm: Keysight34465A) -> None:
    sim_dmm.resource.write("VOLT:DC:NPLC 7")  # bypasses the driver's validation
    with pytest.raises(InstrumentError) as info:
        sim_dmm.check_errors("VOLT:DC:NPLC 7")
    assert info.value.code == -100
    sim_dmm.check_errors()  # the queue was drained
