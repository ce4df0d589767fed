"""The DAQ970A driver: the bytes it puts on the wire, validation before any byte, the reading
blocks it decodes (written here apart from the simulator's encoder), and a scan against the
simulated unit over TCP."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from bench.core.clock import SimulatedClock
from bench.testing import FakeResource
from instruments.base import InstrumentError, open_resource
from instruments.daq import KeysightDAQ970A, parse_scan_block
from sim.station import SimStationConfig, SimulatedStation


def test_configure_scan_writes_the_scan_and_checks_the_error_queue_once():
    res = FakeResource()
    daq = KeysightDAQ970A(res, name="daq")
    plan = daq.configure_scan([103, 101, 102], interval_s=0.5, sweeps=20, nplc=1.0, autozero=False)
    assert res.written == [
        "ABOR", "CONF:VOLT:DC 10,(@101,102,103)", "VOLT:DC:NPLC 1,(@101,102,103)",
        "ZERO:AUTO OFF,(@101,102,103)", "ROUT:CHAN:DEL:AUTO ON,(@101,102,103)",
        "ROUT:SCAN (@101,102,103)", "TRIG:SOUR TIM", "TRIG:TIM 0.500", "TRIG:COUN 20",
        "FORM:READ:TIME ON", "FORM:READ:TIME:TYPE REL", "FORM:READ:CHAN ON", "SYST:ERR?"]
    assert plan.channels == (101, 102, 103) and plan.sweeps == 20
    assert plan.duration_s == pytest.approx(19 * 0.5 + plan.sweep_s)


def test_a_given_channel_delay_is_sent_instead_of_the_auto_delay():
    res = FakeResource()
    KeysightDAQ970A(res).configure_scan([101], interval_s=1.0, sweeps=1, channel_delay_s=0.01)
    assert "ROUT:CHAN:DEL 0.01,(@101)" in res.written


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"channels": [121]}, "channel=121"),
    ({"channels": [101, 101]}, "repeat"),
    ({"channels": []}, "empty"),
    ({"sweeps": 0}, "sweeps=0"),
    ({"nplc": 5.0}, "nplc=5.0"),
    ({"interval_s": 0.05, "channels": list(range(101, 109)), "nplc": 1.0}, "at least"),
])
def test_bad_scans_are_refused_before_anything_is_written(kwargs, message):
    res = FakeResource()
    args = {"channels": [101, 102], "interval_s": 1.0, "sweeps": 10, **kwargs}
    with pytest.raises(ValueError, match=message):
        KeysightDAQ970A(res).configure_scan(args.pop("channels"), **args)
    assert res.written == []


def test_an_instrument_error_names_the_commands_it_followed():
    res = FakeResource(errors=('-222,"Data out of range;channel 101 not in 101..120"',))
    with pytest.raises(InstrumentError, match="-222"):
        KeysightDAQ970A(res, name="daq").configure_scan([101], interval_s=1.0, sweeps=1)


def _block(text: str) -> str:
    """A definite-length block as IEEE 488.2 §8.7.9 writes it (written apart from the simulator)."""
    n = str(len(text.encode()))
    return f"#{len(n)}{n}{text}"


@given(st.lists(st.tuples(st.floats(-299.0, 299.0), st.floats(0.0, 1e5), st.integers(101, 120)),
                max_size=40))
def test_scan_blocks_decode_to_readings_times_and_channels(rows):
    text = ",".join(f"{v:+.8E},{t:.6f},{c}" for v, t, c in rows)
    got = parse_scan_block(_block(text), "daq", "R?")
    assert len(got) == len(rows)
    np.testing.assert_allclose(got.volts, [float(f"{v:+.8E}") for v, _, _ in rows])
    np.testing.assert_allclose(got.t_s, [float(f"{t:.6f}") for _, t, _ in rows])
    assert got.channel.tolist() == [c for _, _, c in rows]


def test_overload_markers_become_nan_and_a_short_block_is_an_error():
    got = parse_scan_block(_block("+9.90000000E+37,0.1,101,+1.0E+00,0.2,102"), "daq", "R?")
    assert np.isnan(got.volts[0]) and got.volts[1] == 1.0
    with pytest.raises(Exception, match="header says"):
        parse_scan_block("#15+1.0", "daq", "R?")


def test_a_scan_of_four_sockets_against_the_simulated_unit():
    fixture = {str(n): f"QA-SIM-000{n}" for n in range(1, 5)}
    with SimulatedStation(SimStationConfig(seed=2, fixture=fixture)) as sim:
        res = open_resource(sim.resources()["daq"], timeout_ms=20000)
        try:
            daq = KeysightDAQ970A(res, name="daq")
            daq.check_model()
            assert daq.line_frequency_hz == 50.0
            daq.configure_scan(range(101, 105), interval_s=0.2, sweeps=10, nplc=0.2, autozero=False)
            clock = open_resource(sim.resources()["sim"], timeout_ms=20000)
            chunks = list(daq.stream_scan(SimulatedClock(clock).sleep, poll_s=0.5))
            clock.close()
            readings = np.concatenate([c.volts for c in chunks])
            channels = np.concatenate([c.channel for c in chunks])
            assert readings.size == 40
            assert channels.tolist() == list(range(101, 105)) * 10
            assert np.all(np.abs(readings) < 1e-3)  # the units are unpowered: every socket reads 0 V
            daq.make_safe()
        finally:
            res.close()
