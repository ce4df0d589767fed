"""The simulated DAQ970A: scan timing on the virtual clock, settling through the fixture filter,
per-socket wiring, the error queue, and determinism whatever the draining."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sim.devices.daq import AUTO_DELAY_S, READING_OVERHEAD_S, RELAY_CLOSE_S
from sim.devices.dmm_model import READING_OVERHEAD_S as DMM_OVERHEAD_S
from sim.station import SimStationConfig, SimulatedStation

FOUR = {"1": "QA-SIM-0001", "2": "QA-SIM-0002", "3": "QA-SIM-0003", "4": "QA-SIM-0004"}


def station(seed: int = 1, **kw) -> SimulatedStation:
    return SimulatedStation(SimStationConfig(seed=seed, fixture=kw.pop("fixture", FOUR), **kw))


def powered(s: SimulatedStation) -> None:
    assert s.supply.process(b"APPL CH2,15,0.1;APPL CH3,15,0.1;OUTP ON,(@2,3)") is None
    s.world.advance(5.0)


def rows(reply: bytes) -> np.ndarray:
    return np.array(reply.decode().strip().split(","), dtype=float).reshape(-1, 3)


def ask(dev, *messages: str) -> bytes | None:
    reply = None
    for m in messages:
        reply = dev.process(m.encode())
    return reply


def test_sweeps_follow_the_timer_and_each_channel_its_relay_delay_and_integration():
    s = station()
    powered(s)
    daq = s.fixture.daq
    ask(daq, "CONF:VOLT:DC 10,(@101:102)", "VOLT:NPLC 1,(@101:102)", "TRIG:SOUR TIM",
        "TRIG:TIM 0.5", "TRIG:COUN 3", "FORM:READ:TIME ON", "FORM:READ:CHAN ON")
    t_init = s.world.now
    out = rows(ask(daq, "INIT", "FETC?"))
    per_channel = RELAY_CLOSE_S + AUTO_DELAY_S + 2 * 1 / 50 + DMM_OVERHEAD_S + READING_OVERHEAD_S
    first = RELAY_CLOSE_S + AUTO_DELAY_S
    expected_t = [0.5 * k + first + j * per_channel for k in range(3) for j in range(2)]
    np.testing.assert_allclose(out[:, 1], expected_t, atol=1e-6)
    assert out[:, 2].tolist() == [101, 102] * 3
    assert s.world.now == pytest.approx(t_init + 1.0 + 2 * per_channel)  # FETC? waited for the end


def test_a_timer_shorter_than_a_sweep_is_stretched_to_the_sweep():
    s = station()
    daq = s.fixture.daq
    ask(daq, "CONF:VOLT:DC (@101:104)", "TRIG:SOUR TIM", "TRIG:TIM 0.01", "TRIG:COUN 3",
        "FORM:READ:TIME ON", "FORM:READ:CHAN ON")
    t = rows(ask(daq, "INIT", "FETC?"))[:, 1]
    sweep = t[4] - t[0]
    assert sweep == pytest.approx(4 * (t[1] - t[0]))
    assert sweep > 0.01


def test_each_channel_reads_its_own_sockets_unit():
    s = station()
    powered(s)
    s.world.advance(600.0)
    daq = s.fixture.daq
    ask(daq, "CONF:VOLT:DC 10,(@101:104)", "VOLT:NPLC 10,(@101:104)", "TRIG:COUN 5")
    v = rows(ask(daq, "FORM:READ:CHAN ON;TIME ON", "INIT", "FETC?"))
    means = {ch: v[v[:, 2] == ch, 0].mean() for ch in (101, 102, 103, 104)}
    truth = s.fixture_truth()
    for socket in (1, 2, 3, 4):
        k1 = truth[socket]["k1_ma_per_g"]
        # level, IA up: ≈ (K0 + 1 g)·K1·R; the units differ by their drawn scale factors
        assert means[100 + socket] == pytest.approx(k1 * 1e-3 * 5000.0, rel=5e-3)
    assert len({round(m, 4) for m in means.values()}) == 4


def test_an_open_socket_reads_zero_and_a_short_delay_shows_the_previous_channel():
    s = station(fixture_open=[2], fixture_settling_tau_s=1e-4)
    powered(s)
    daq = s.fixture.daq
    ask(daq, "CONF:VOLT:DC 10,(@101:102)", "VOLT:NPLC 0.02,(@101:102)", "ZERO:AUTO OFF,(@101:102)",
        "TRIG:COUN 20", "FORM:READ:CHAN ON;TIME ON")
    settled = rows(ask(daq, "INIT", "FETC?"))
    open_settled = settled[settled[:, 2] == 102, 0]
    unit = settled[settled[:, 2] == 101, 0].mean()
    assert abs(open_settled).max() < 1e-3
    ask(daq, "ROUT:CHAN:DEL 0,(@101:102)")
    fast = rows(ask(daq, "INIT", "FETC?"))
    open_fast = fast[fast[:, 2] == 102, 0]
    aperture, tau = 0.02 / 50, 1e-4
    residue = tau / aperture * (1 - np.exp(-aperture / tau))  # mean of exp(−t/τ) over the aperture
    np.testing.assert_allclose(open_fast, unit * residue, rtol=2e-3)


def test_bad_channel_lists_and_conflicts_are_refused_with_their_codes():
    daq = station().fixture.daq
    assert ask(daq, "CONF:VOLT:DC (@201)") is None
    error = daq.pop_error()
    assert error.startswith("-222,") and "101..120" in error
    assert ask(daq, "ROUT:SCAN (@)", "INIT") is None
    assert daq.pop_error().startswith("-221,")
    ask(daq, "CONF:VOLT:DC (@101)", "TRIG:COUN INF", "INIT")
    assert ask(daq, "FETC?") is None                        # could never end: no reply
    assert daq.pop_error().startswith("-230,")
    assert ask(daq, "VOLT:NPLC 1,(@101)") is None           # settings while scanning
    assert daq.pop_error().startswith("-221,")
    ask(daq, "ABOR")
    assert ask(daq, "FORM:READ:TIME:TYPE ABS") is None
    assert daq.pop_error().startswith("-221,")
    assert ask(daq, "SYST:CTYP? 100") == b"Keysight Technologies,DAQM901A,0,1.0\n"
    assert daq.pop_error() == '+0,"No error"'


def test_channel_out_of_range_names_the_allowed_channels():
    daq = station().fixture.daq
    ask(daq, "ROUT:SCAN (@121)")
    error = daq.pop_error()
    assert error.startswith("-222,") and "121" in error and "101..120" in error


def test_overload_reads_the_overload_marker():
    s = station()
    daq = s.fixture.daq
    daq.overload(1e4)
    out = rows(ask(daq, "CONF:VOLT:DC 10,(@101:102)", "FORM:READ:CHAN ON;TIME ON",
                   "TRIG:COUN 2", "INIT", "FETC?"))
    assert np.all(np.abs(out[:, 0]) == 9.9e37)


@settings(max_examples=10, deadline=None)
@given(st.lists(st.integers(1, 40), min_size=1, max_size=8), st.integers(0, 2**32 - 1))
def test_same_seed_same_bytes_however_the_scan_is_drained(chunks, seed):
    def scan(drain: list[int] | None) -> bytes:
        s = station(seed % 1000)
        powered(s)
        daq = s.fixture.daq
        ask(daq, "CONF:VOLT:DC 10,(@101:104)", "VOLT:NPLC 0.2,(@101:104)", "TRIG:SOUR TIM",
            "TRIG:TIM 0.1", "TRIG:COUN 30", "FORM:READ:CHAN ON;TIME ON", "INIT")
        if drain is None:
            reply = ask(daq, "FETC?")
            assert reply is not None
            return reply.strip()
        parts: list[bytes] = []
        for _ in range(200):  # bounded: the scan ends after 30 sweeps
            if sum(len(p.split(b",")) for p in parts) >= 360:
                break
            for n in drain:
                s.world.advance(0.05 * n)
                block = ask(daq, "R?")
                assert block is not None
                payload = block.strip()[2 + int(block[1:2]):]
                if payload:
                    parts.append(payload)
        return b",".join(parts)
    assert scan(chunks) == scan(None)
