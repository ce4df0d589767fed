"""SCPI base machinery: declarative settings, error queue, groups, wire helpers.

The driver tests' doubles (``FakeResource``, ``expected_protocol``, ``pack_real64_block``) are
in ``bench.testing.visa``, beside ``assert_conforms`` in ``bench.testing.conformance``.
"""

from __future__ import annotations

import math
from collections import deque
from typing import Any

import numpy as np
import pytest
import pyvisa
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.testing import SIM_YAML_DIR, FakeResource, pack_real64_block
from instruments.base import (
    Identity,
    InstrumentError,
    InstrumentReplyError,
    SCPIInstrument,
    boolean,
    channel_list,
    control,
    format_number,
    in_range,
    in_set,
    int_in_range,
    measurement,
    open_resource,
    parse_bool,
    parse_error_reply,
    parse_int,
    quote_string,
    unquote_string,
)

# --- a small instrument to exercise the machinery ------------------------------------


class Widget(SCPIInstrument):
    level_v = control("LEV?", "LEV {value}", "Level, volts.", validator=in_range, values=(0.0, 5.0))
    mode = control("MODE?", "MODE {value}", "Mode.", validator=in_set, values=("FAST", "SLOW"),
                   fmt=str, parse=str)
    enabled = control("ENAB?", "ENAB {value}", "On/off.", validator=boolean,
                      set_map={True: "ON", False: "OFF"}, parse=parse_bool)
    count = control("COUN?", "COUN {value}", "Count.", validator=int_in_range, values=(1, 10),
                    parse=parse_int)
    reading = measurement("READ?", "A reading.")


def make_widget(**kw: Any) -> tuple[Widget, FakeResource]:
    fake = FakeResource(**kw)
    return Widget(fake, name="widget"), fake


def test_constructor_does_no_io() -> None:
    widget, fake = make_widget()
    assert fake.written == []
    assert widget.name == "widget"


@pytest.mark.parametrize("attr, value, command", [
    ("level_v", 2.5, "LEV 2.5"),
    ("level_v", 5, "LEV 5"),
    ("mode", "slow", "MODE SLOW"),
    ("enabled", True, "ENAB ON"),
    ("enabled", False, "ENAB OFF"),
    ("count", 7, "COUN 7"),
    ("count", 3.0, "COUN 3"),
])
def test_setting_writes_command_then_drains_error_queue(
        attr: str, value: Any, command: str) -> None:
    widget, fake = make_widget()
    setattr(widget, attr, value)
    assert fake.written == [command, "SYST:ERR?"]


@pytest.mark.parametrize("attr, value, fragment", [
    ("level_v", 5.01, "[0, 5]"),
    ("level_v", -1, "[0, 5]"),
    ("level_v", float("nan"), "[0, 5]"),
    ("level_v", "3", "not a real number"),
    ("level_v", True, "not a real number"),
    ("mode", "MEDIUM", "(FAST, SLOW)"),
    ("enabled", 1, "True or False"),
    ("count", 2.5, "[1, 10]"),
    ("count", 11, "[1, 10]"),
])
def test_invalid_value_raises_before_anything_is_written(
        attr: str, value: Any, fragment: str) -> None:
    widget, fake = make_widget()
    with pytest.raises(ValueError) as info:
        setattr(widget, attr, value)
    assert attr in str(info.value) and repr(value) in str(info.value)
    assert fragment in str(info.value)
    assert fake.written == []


def test_getters_parse_replies() -> None:
    widget, _ = make_widget(replies={"LEV?": "+2.50000000E+00", "ENAB?": "1", "COUN?": "+7",
                                     "READ?": "-1.5E-03", "MODE?": "FAST"})
    assert widget.level_v == 2.5
    assert widget.enabled is True
    assert widget.count == 7
    assert widget.reading == -1.5e-3
    assert widget.mode == "FAST"


def test_read_only_setting_refuses_assignment() -> None:
    widget, fake = make_widget()
    with pytest.raises(AttributeError):
        widget.reading = 1.0
    assert fake.written == []


def test_instrument_error_carries_code_message_and_command() -> None:
    widget, _ = make_widget(errors=('-222,"Data out of range"', '-221,"Settings conflict"'))
    with pytest.raises(InstrumentError) as info:
        widget.level_v = 1.0
    err = info.value
    assert (err.instrument_name, err.command, err.code, err.message) == (
        "widget", "LEV 1", -222, "Data out of range")
    assert err.further == ((-221, "Settings conflict"),)
    assert "-222" in str(err) and "LEV 1" in str(err)


def test_configuring_group_checks_errors_once_at_the_end() -> None:
    widget, fake = make_widget(errors=('-221,"Settings conflict"',))
    with pytest.raises(InstrumentError) as info:
        with widget.configuring():
            widget.level_v = 1
            with widget.configuring():  # nested groups join the outer one
                widget.mode = "FAST"
            assert "SYST:ERR?" not in fake.written
    assert fake.written == ["LEV 1", "MODE FAST", "SYST:ERR?", "SYST:ERR?"]
    assert info.value.command == "LEV 1; MODE FAST"


def test_group_interrupted_by_bad_value_drains_queue_and_raises_the_value_error() -> None:
    widget, fake = make_widget(errors=('-222,"Data out of range"',))
    with pytest.raises(ValueError):
        with widget.configuring():
            widget.level_v = 1
            widget.level_v = 99
    assert fake.written == ["LEV 1", "SYST:ERR?", "SYST:ERR?"]
    assert not fake.error_queue  # drained, so the stale error is not blamed on later commands


def test_error_queue_that_never_empties_is_reported() -> None:
    widget, fake = make_widget(replies={"SYST:ERR?": '-350,"Queue overflow"'})
    fake.error_queue = deque(['-350,"Queue overflow"'] * 100)
    with pytest.raises(InstrumentReplyError):
        widget.check_errors()


def test_common_commands() -> None:
    widget, fake = make_widget(replies={
        "*IDN?": "Keysight Technologies,34465A,MY1,A.03", "*OPC?": "1", "*OPT?": '"DIG","0",MEM'})
    assert widget.idn == Identity("Keysight Technologies", "34465A", "MY1", "A.03")
    assert widget.idn.model == "34465A"  # cached: asked once
    assert widget.options == ("DIG", "MEM")
    widget.reset()
    widget.clear()
    assert fake.written == ["*IDN?", "*OPT?", "*RST", "*OPC?", "SYST:ERR?", "*CLS"]


def test_malformed_idn_reply_is_an_error() -> None:
    with pytest.raises(InstrumentReplyError):
        Identity.parse("only,three,fields")


@pytest.mark.parametrize("value, text", [(10, "10"), (10.0, "10"), (0.001, "0.001"),
                                         (2e-5, "2e-05"), (-45.5, "-45.5"), (0.1 + 0.2, "0.3")])
def test_format_number(value: float, text: str) -> None:
    assert format_number(value) == text


def test_format_number_refuses_bool() -> None:
    with pytest.raises(TypeError):
        format_number(True)


@given(st.floats(allow_nan=False, allow_infinity=False))
@settings(max_examples=200, deadline=None)
def test_format_number_is_exact_to_12_digits(x: float) -> None:
    assert math.isclose(float(format_number(x)), x, rel_tol=1e-11, abs_tol=0.0)


@given(st.lists(st.integers(1, 999), min_size=1, max_size=12, unique=True))
@settings(deadline=None)
def test_channel_list_round_trips(channels: list[int]) -> None:
    text = channel_list(channels)
    assert text.startswith("(@") and text.endswith(")")
    assert [int(c) for c in text[2:-1].split(",")] == channels


@pytest.mark.parametrize("bad", [[], [1, 1], [0], [-2], [True], [1.5]])
def test_channel_list_rejects_bad_lists(bad: list[Any]) -> None:
    with pytest.raises(ValueError):
        channel_list(bad)


def test_channel_list_examples() -> None:
    assert channel_list([1, 2]) == "(@1,2)"
    assert channel_list([3]) == "(@3)"


@given(st.integers(-999, 999), st.text(st.characters(min_codepoint=32, max_codepoint=126)))
@settings(deadline=None)
def test_error_reply_round_trips(code: int, message: str) -> None:
    assert parse_error_reply(f'{code:+d},"{message}"') == (code, message)


@pytest.mark.parametrize("bad", ["", "No error", "+0,No error", "x,\"y\""])
def test_malformed_error_reply_is_an_error(bad: str) -> None:
    with pytest.raises(InstrumentReplyError):
        parse_error_reply(bad)


@given(st.text(st.characters(min_codepoint=32, max_codepoint=126)))
@settings(deadline=None)
def test_quoted_strings_round_trip(text: str) -> None:
    assert unquote_string(quote_string(text)) == text


@pytest.mark.parametrize("reply, value", [("1", True), ("0", False), ("ON", True), ("off", False)])
def test_parse_bool(reply: str, value: bool) -> None:
    assert parse_bool(reply) is value


def test_parse_bool_and_int_refuse_garbage() -> None:
    with pytest.raises(InstrumentReplyError):
        parse_bool("2")
    with pytest.raises(InstrumentReplyError):
        parse_int("1.5")


@given(st.lists(st.floats(width=64, allow_nan=False), max_size=300))
@settings(max_examples=60, deadline=None)
def test_real64_block_decodes_exactly(values: list[float]) -> None:
    widget, fake = make_widget(replies={"FETC?": pack_real64_block(values)})
    decoded = widget.query_real64("FETC?")
    assert decoded.dtype == np.float64 and decoded.flags.writeable
    assert decoded.astype("<f8").tobytes() == np.array(values, dtype="<f8").tobytes()
    assert fake.written == ["FETC?"]


def test_open_resource_sets_terminations_and_chunk() -> None:
    resource = open_resource("TCPIP0::127.0.0.1::5025::SOCKET",
                             backend=f"{SIM_YAML_DIR / 'keysight_34465a.yaml'}@sim", timeout_ms=1234)
    try:
        assert resource.read_termination == "\n" and resource.write_termination == "\n"
        assert resource.timeout == 1234
        assert resource.chunk_size >= 1 << 20
        assert resource.query("*IDN?").split(",")[1] == "34465A"
    finally:
        resource.close()


def test_open_resource_uses_a_given_resource_manager() -> None:
    manager = pyvisa.ResourceManager(f"{SIM_YAML_DIR / 'turntable.yaml'}@sim")
    resource = open_resource("TCPIP0::127.0.0.1::5027::SOCKET", backend="@unused",
                             resource_manager=manager)
    try:
        assert resource.query("*IDN?").startswith("Inertial Bench")
    finally:
        resource.close()
        manager.close()


def test_validators_return_canonical_values() -> None:
    assert in_set("x", "slow", ("FAST", "SLOW")) == "SLOW"
    assert in_set("x", 0.2000000000001, (0.2, 1.0)) == 0.2
    assert int_in_range("x", 4.0, (1, 5)) == 4 and isinstance(int_in_range("x", 4.0, (1, 5)), int)
    with pytest.raises(ValueError):
        in_set("x", 0.21, (0.2, 1.0))

