"""The simulated 34465A's trigger model, reading memory and reply formats, byte for byte."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sim.devices.dmm import Multimeter
from sim.world import World


def make(seed=0, options=("DIG", "MEM"), signal=None):
    world = World(seed)
    sig = signal or (lambda t, ap: np.full(t.shape, 1.25))
    return world, Multimeter(world, "dmm", sig, options=options)


def ask(dev, text):
    out = dev.process(text.encode())
    return None if out is None else out.decode() if not out.startswith(b"#") else out


def err(dev):
    return ask(dev, "SYST:ERR?").strip()


def block_values(raw: bytes) -> np.ndarray:
    n = int(raw[1:2])
    length = int(raw[2:2 + n])
    return np.frombuffer(raw[2 + n:2 + n + length], dtype="<f8")


def test_reply_formats_are_the_real_instruments():
    world, dmm = make()
    assert ask(dmm, "SAMP:COUN 100;COUN?") == "+100\n"  # SCPI path rule: COUN? is under SAMP
    assert ask(dmm, "VOLT:NPLC 0.2;:VOLT:NPLC?") == "+2.00000000E-01\n"
    assert ask(dmm, "SYST:LFR?") == "50\n"
    assert ask(dmm, "*OPT?") == "DIG,MEM\n"
    assert ask(dmm, "READ?").startswith("+1.2500")
    assert ask(dmm, "DATA:LAST?").endswith(" VDC\n")
    assert ask(dmm, "FORM?") == "ASC,9\n"


def test_timed_trace_appears_as_simulated_time_passes():
    world, dmm = make()
    ask(dmm, "CONF:VOLT:DC 10;:VOLT:NPLC 1;:VOLT:ZERO:AUTO OFF;:TRIG:DEL 0;"
             ":SAMP:SOUR TIM;:SAMP:TIM 0.1;:SAMP:COUN 50")
    ask(dmm, "INIT")
    assert ask(dmm, "DATA:POIN?") == "+0\n"
    world.advance(1.0)           # readings end at 0.02, 0.12, ... → 10 by t = 1 s
    assert ask(dmm, "DATA:POIN?") == "+10\n"
    world.advance(100.0)
    assert ask(dmm, "DATA:POIN?") == "+50\n"
    assert err(dmm) == '+0,"No error"'


def test_fetch_waits_in_simulated_time_for_the_acquisition_to_end():
    world, dmm = make()
    ask(dmm, "CONF:VOLT:DC 10;:SAMP:SOUR TIM;:SAMP:TIM 1;:SAMP:COUN 30;:TRIG:DEL 0")
    ask(dmm, "INIT")
    values = ask(dmm, "FETC?").strip().split(",")
    assert len(values) == 30 and world.now == pytest.approx(29 + 10 / 50)


def test_bus_trigger_and_trigger_count():
    world, dmm = make()
    ask(dmm, "TRIG:SOUR BUS;COUN 3;:SAMP:COUN 2")
    ask(dmm, "INIT")
    world.advance(10)
    assert ask(dmm, "DATA:POIN?") == "+0\n"
    for expected in (2, 4, 6):
        ask(dmm, "*TRG")
        world.advance(5)
        assert ask(dmm, "DATA:POIN?") == f"+{expected}\n"
    ask(dmm, "*TRG")  # the meter is idle again: trigger ignored
    assert err(dmm) == '-211,"Trigger ignored"'


def test_fetch_that_can_never_complete_answers_with_an_error_not_a_hang():
    world, dmm = make()
    ask(dmm, "TRIG:SOUR BUS")
    ask(dmm, "INIT")
    assert ask(dmm, "FETC?") is None
    assert err(dmm).startswith("-230")


def test_init_during_a_measurement_is_refused():
    world, dmm = make()
    ask(dmm, "TRIG:SOUR BUS")
    ask(dmm, "INIT")
    ask(dmm, "INIT")
    assert err(dmm).startswith("-213")


def test_reading_memory_overflow_keeps_the_newest_and_sets_questionable_bit_14():
    ramp = lambda t, ap: t.copy()
    world, dmm = make(options=(), signal=ramp)
    ask(dmm, "CONF:VOLT:DC 100;:VOLT:NPLC 0.02;:VOLT:ZERO:AUTO OFF;:TRIG:DEL 0;"
             ":SAMP:SOUR TIM;:SAMP:TIM 0.001;:SAMP:COUN 60000")
    ask(dmm, "INIT")
    world.advance(100)
    assert ask(dmm, "DATA:POIN?") == "+50000\n"
    assert int(ask(dmm, "STAT:QUES:COND?")) & (1 << 14)
    ask(dmm, "FORM REAL,64;:FORM:BORD SWAP")
    kept = block_values(ask(dmm, "R?"))
    assert kept[0] == pytest.approx(10000 * 0.001, abs=3e-3)  # 100 V range: 0.3 mV noise  # the 10 000 oldest were lost


def test_data_remove_with_wait_lets_time_pass_and_without_wait_refuses():
    world, dmm = make()
    ask(dmm, "CONF:VOLT:DC 10;:SAMP:SOUR TIM;:SAMP:TIM 0.5;:SAMP:COUN 20")
    ask(dmm, "INIT")
    assert ask(dmm, "DATA:REM? 5") is None
    assert err(dmm).startswith("-222")
    assert len(ask(dmm, "DATA:REM? 5,WAIT").split(",")) == 5
    assert world.now == pytest.approx(4 * 0.5 + 0.2)


def test_real64_byte_order_follows_form_bord():
    world, dmm = make()
    ask(dmm, "SAMP:COUN 3;:FORM REAL,64")
    big = ask(dmm, "READ?")
    assert np.all(np.frombuffer(big[4:4 + 24], dtype=">f8") == pytest.approx(1.25, abs=1e-4))
    ask(dmm, "FORM:BORD SWAP")
    little = ask(dmm, "READ?")
    assert little[:4] == b"#224"
    assert np.all(block_values(little) == pytest.approx(1.25, abs=1e-4))


@settings(max_examples=15, deadline=None)
@given(st.lists(st.floats(0.01, 3.0), min_size=1, max_size=12), st.integers(0, 2**32 - 1),
       st.sampled_from(["10", "AUTO"]))
def test_how_the_trace_is_polled_never_changes_its_bytes(steps, seed, range_word):
    """Same seed, same bytes: draining in arbitrary chunks equals one FETC? at the end —
    with a fixed range and with autorange over a signal that crosses range boundaries."""
    def configure(dev):
        ask(dev, f"CONF:VOLT:DC {range_word};:VOLT:NPLC 0.2;:SAMP:SOUR TIM;:SAMP:TIM 0.01;"
                 ":SAMP:COUN 500;:FORM REAL,64;:FORM:BORD SWAP")
        ask(dev, "INIT")

    noisy = lambda t, ap: 1.05 * np.sin(3 * t)
    world_a, a = make(seed, signal=noisy)
    world_b, b = make(seed, signal=noisy)
    configure(a)
    configure(b)
    drained = []
    for dt in steps:
        world_a.advance(dt)
        drained.append(block_values(ask(a, "R?")))
    world_a.advance(10)
    drained.append(block_values(ask(a, "R?")))
    whole = block_values(ask(b, "FETC?"))
    assert np.concatenate(drained).tobytes() == whole.tobytes()


def test_bus_triggered_acquisition_completes_on_fetch():
    world, dmm = make()
    ask(dmm, "*RST;TRIG:SOUR BUS;:SAMP:COUN 5")
    ask(dmm, "INIT")
    ask(dmm, "*TRG")
    assert len(ask(dmm, "FETC?").split(",")) == 5
    assert err(dmm) == '+0,"No error"'


def test_queries_with_min_max_def_return_the_limits():
    world, dmm = make()
    assert ask(dmm, "SAMP:COUN? MAX") == "+1000000000\n"
    assert ask(dmm, "SAMP:COUN? MIN") == "+1\n"
    assert float(ask(dmm, "VOLT:NPLC? MAX")) == 100.0
    assert float(ask(dmm, "VOLT:NPLC? MIN")) == 0.001  # DIG option fitted
    assert float(ask(dmm, "VOLT:RANG? MAX")) == 1000.0
    assert float(ask(dmm, "TRIG:DEL? MAX")) == 3600.0
    assert ask(dmm, "TRIG:COUN? MAX") == "+1000000000\n"  # 34465A: 1..1e9 (34460A/61A: 1e6)
    _, plain = make(options=())
    assert float(ask(plain, "VOLT:NPLC? MIN")) == 0.02
    assert ask(dmm, "SAMP:COUN? maximum") == "+1000000000\n"  # long form, any case
    assert ask(dmm, "SAMP:COUN? MAXWELL") is None and err(dmm).startswith("-224")


def test_a_bare_header_that_needs_a_value_is_missing_parameter():
    world, dmm = make()
    for header in ("VOLT:ZERO:AUTO", "TRIG:COUN", "SAMP:SOUR", "VOLT:NPLC"):
        assert dmm.process(header.encode()) is None
        assert err(dmm) == '-109,"Missing parameter"', header


def test_aperture_is_kept_in_seconds_not_rounded_to_nplc():
    world, dmm = make()
    ask(dmm, "VOLT:APER 0.05")
    assert float(ask(dmm, "VOLT:APER?")) == pytest.approx(0.05)
    assert ask(dmm, "VOLT:APER:ENAB?") == "1\n"
    assert dmm.fe.aperture_s == pytest.approx(0.05)
    ask(dmm, "VOLT:NPLC 1")
    assert ask(dmm, "VOLT:APER:ENAB?") == "0\n" and dmm.fe.aperture_s == pytest.approx(0.02)
    ask(dmm, "VOLT:APER 5")
    assert err(dmm).startswith("-222")


def test_work_per_advance_is_bounded_by_the_reading_memory():
    """A year of 50 k readings/s must not wedge the server: only what memory holds is made."""
    world, dmm = make()
    ask(dmm, "CONF:VOLT:DC 10;:VOLT:NPLC 0.001;:VOLT:ZERO:AUTO OFF;:TRIG:COUN INF;"
             ":SAMP:COUN 1000000;:SAMP:SOUR TIM;:SAMP:TIM 2E-5")
    ask(dmm, "INIT")
    world.advance(3e7)
    assert ask(dmm, "DATA:POIN?") == "+2000000\n"
    assert int(ask(dmm, "STAT:QUES:COND?")) & (1 << 14)
    assert dmm.state == "ACQUIRING"
    ask(dmm, "ABOR")
    assert err(dmm) == '+0,"No error"'


def test_a_model_failure_during_acquisition_is_reported_and_time_keeps_moving():
    def broken(t, ap):
        if t[-1] > 5:
            raise RuntimeError("sensor model exploded")
        return np.zeros(t.shape)

    world, dmm = make(signal=broken)
    ask(dmm, "SAMP:SOUR TIM;:SAMP:TIM 1;:SAMP:COUN 100")
    ask(dmm, "INIT")
    world.advance(50)
    assert world.now == 50 and dmm.state == "IDLE"
    assert err(dmm).startswith("-240")
