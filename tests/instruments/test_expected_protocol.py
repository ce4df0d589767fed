"""The VISA doubles of ``bench.testing.visa`` hold a driver to its exchange: a write that is not
the next message, a read with nothing sent, a reply left unread or a pair never exchanged each
fail the test, naming the bytes; binary blocks go through pyvisa's own reader."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.testing import NO_ERROR, FakeResource, ProtocolResource, expected_protocol, pack_real64_block
from instruments import InstrumentError, KeysightE36312A
from instruments.base import SCPIInstrument, control, in_range

IDN = "Keysight Technologies,E36312A,MY61000001,2.1.0"


class Source(SCPIInstrument):
    level_v = control("LEV?", "LEV {value}", "Level, volts.", validator=in_range, values=(0.0, 5.0))


def test_a_setting_and_a_reading_exchange_exactly_the_listed_messages() -> None:
    with expected_protocol(Source, [("LEV 2.5", None), ("SYST:ERR?", NO_ERROR), ("LEV?", "+2.5E+00")],
                           name="source") as source:
        source.level_v = 2.5
        assert source.level_v == 2.5
        assert source.name == "source"
        assert source.resource.written == ["LEV 2.5", "SYST:ERR?", "LEV?"]


def test_an_instrument_error_after_a_setting_reaches_the_driver() -> None:
    exchange = [("LEV 1", None), ("SYST:ERR?", '-222,"Data out of range"'), ("SYST:ERR?", NO_ERROR)]
    with expected_protocol(Source, exchange) as source, pytest.raises(InstrumentError, match="-222"):
        source.level_v = 1


def test_a_real_driver_names_its_bytes() -> None:
    exchange = [("*IDN?", IDN), ("VOLT 5,(@1)", None), ("SYST:ERR?", NO_ERROR), ("OUTP ON,(@1)", None),
                ("SYST:ERR?", NO_ERROR)]
    with expected_protocol(KeysightE36312A, exchange) as supply:
        supply.ch[1].voltage_setpoint_v = 5
        supply.ch[1].output_enabled = True


def test_a_write_other_than_the_next_message_fails_there() -> None:
    with pytest.raises(AssertionError, match=r"wrote 'LEV 3'; pair 0 \('LEV 2', None\) expects 'LEV 2'"):
        with expected_protocol(Source, [("LEV 2", None), ("SYST:ERR?", NO_ERROR)]) as source:
            source.level_v = 3


def test_a_write_past_the_exchange_fails() -> None:
    with pytest.raises(AssertionError, match="after the last of 1 pairs"):
        with expected_protocol(Source, [("LEV 2", None)]) as source:
            source.level_v = 2


def test_pairs_never_exchanged_fail_at_the_end() -> None:
    with pytest.raises(AssertionError, match=r"1 pair\(s\) of the exchange never took place: pair 2"):
        with expected_protocol(Source, [("LEV 2", None), ("SYST:ERR?", NO_ERROR), ("LEV?", "+2")]) as source:
            source.level_v = 2


def test_a_reply_left_unread_fails_at_the_next_write_or_the_end() -> None:
    resource = ProtocolResource([("A?", "1"), ("B", None)])
    resource.write("A?")
    with pytest.raises(AssertionError, match=r"wrote 'B' before reading b'1\\n'"):
        resource.write("B")
    resource = ProtocolResource([("A?", "1")])
    resource.write("A?")
    with pytest.raises(AssertionError, match="left b'1\\\\n' unread"):
        resource.assert_done()


def test_a_read_without_a_write_takes_a_pair_with_no_message_and_nothing_else() -> None:
    resource = ProtocolResource([("A?", "1"), (None, "2"), ("B", None)])
    assert resource.query("A?") == "1"
    assert resource.read() == "2"
    with pytest.raises(AssertionError, match=r"read with nothing sent to it; pair 2 \('B', None\) is next"):
        resource.read()
    resource.write("B")
    resource.assert_done()


def test_the_block_of_an_error_in_the_driver_propagates_without_the_end_check() -> None:
    with pytest.raises(ValueError, match="outside the allowed range"):
        with expected_protocol(Source, [("never sent", None)]) as source:
            source.level_v = 9


@given(st.lists(st.floats(width=64, allow_nan=False), max_size=200))
@settings(max_examples=40, deadline=None)
def test_a_binary_block_is_read_through_pyvisa_by_both_doubles(values: list[float]) -> None:
    block = pack_real64_block(values)
    scripted = ProtocolResource([("FETC?", block)])
    decoded = scripted.query_binary_values("FETC?", datatype="d", container=np.array)
    scripted.assert_done()
    table = FakeResource(replies={"FETC?": block})
    assert np.array_equal(decoded, table.query_binary_values("FETC?", datatype="d", container=np.array))
    assert decoded.astype("<f8").tobytes() == np.array(values, dtype="<f8").tobytes()


def test_the_table_double_fails_an_unexpected_query_and_answers_the_error_queue() -> None:
    fake = FakeResource(errors=('-113,"Undefined header"',))
    assert fake.query("SYST:ERR?") == '-113,"Undefined header"'
    assert fake.query("SYST:ERR?") == NO_ERROR
    with pytest.raises(AssertionError, match=r"unexpected query 'VOLT\?'"):
        fake.query("VOLT?")
