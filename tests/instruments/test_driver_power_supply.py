"""Keysight E36312A/E36313A driver: exact wire bytes per channel setting, per-model
per-channel validation, channel lists, errors, and the pyvisa-sim vocabulary."""

from __future__ import annotations

from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.testing import SIM_YAML_DIR, FakeResource, assert_conforms
from instruments import (
    CHANNEL_RATINGS,
    InstrumentError,
    InstrumentReplyError,
    KeysightE36312A,
    PowerSupply,
    SupplyChannel,
)
from instruments.base import UnsupportedInstrumentError, open_resource


def make_supply(model: str = "E36312A", **replies: Any) -> tuple[KeysightE36312A, FakeResource]:
    fake = FakeResource(replies={"*IDN?": f"Keysight Technologies,{model},MY61000001,2.1.0",
                                 **replies})
    supply = KeysightE36312A(fake)
    fake.written.clear()
    return supply, fake


def test_construction_reads_the_model() -> None:
    fake = FakeResource(replies={"*IDN?": "Keysight Technologies,E36313A,MY1,2.1.0"})
    supply = KeysightE36312A(fake)
    assert fake.written == ["*IDN?"]
    assert supply.model == "E36313A" and sorted(supply.ch) == [1, 2, 3]
    assert supply.ch[1].current_range_a == (0.0, 10.0)
    assert supply.ch[3].voltage_range_v == (0.0, 25.0)


def test_unknown_model_is_refused() -> None:
    with pytest.raises(UnsupportedInstrumentError):
        make_supply("E36103B")


@pytest.mark.parametrize("channel, attr, value, command", [
    (1, "voltage_setpoint_v", 5, "VOLT 5,(@1)"),
    (2, "voltage_setpoint_v", 12.5, "VOLT 12.5,(@2)"),
    (3, "voltage_setpoint_v", 0, "VOLT 0,(@3)"),
    (1, "current_limit_a", 0.25, "CURR 0.25,(@1)"),
    (2, "current_limit_a", 1, "CURR 1,(@2)"),
    (3, "output_enabled", True, "OUTP ON,(@3)"),
    (1, "output_enabled", False, "OUTP OFF,(@1)"),
])
def test_channel_setting_writes_exact_bytes(
        channel: int, attr: str, value: Any, command: str) -> None:
    supply, fake = make_supply()
    setattr(supply.ch[channel], attr, value)
    assert fake.written == [command, "SYST:ERR?"]


def test_channel_readings_use_channel_lists() -> None:
    supply, fake = make_supply(**{
        "VOLT? (@2)": "+1.20000000E+01", "CURR? (@2)": "+5.00000000E-01", "OUTP? (@2)": "1",
        "MEAS:VOLT? (@2)": "+1.19998000E+01", "MEAS:CURR? (@2)": "+2.50000000E-02"})
    ch = supply.ch[2]
    assert (ch.voltage_setpoint_v, ch.current_limit_a, ch.output_enabled) == (12.0, 0.5, True)
    assert (ch.measured_voltage_v, ch.measured_current_a) == (11.9998, 0.025)
    assert fake.written == ["VOLT? (@2)", "CURR? (@2)", "OUTP? (@2)", "MEAS:VOLT? (@2)",
                            "MEAS:CURR? (@2)"]


def test_apply_writes_one_command() -> None:
    supply, fake = make_supply()
    supply.ch[1].apply(5, 1)
    supply.ch[3].apply(24.5, 0.125)
    assert fake.written == ["APPL CH1,5,1", "SYST:ERR?", "APPL CH3,24.5,0.125", "SYST:ERR?"]


def test_apply_validates_both_values_before_the_wire() -> None:
    supply, fake = make_supply()
    with pytest.raises(ValueError, match=r"ch\[2\]\.current_a=1\.5 .*\[0, 1\]"):
        supply.ch[2].apply(5.0, 1.5)
    with pytest.raises(ValueError, match=r"ch\[1\]\.voltage_v=7 .*\[0, 6\]"):
        supply.ch[1].apply(7, 1.0)
    assert fake.written == []


@given(model=st.sampled_from(sorted(CHANNEL_RATINGS)), channel=st.integers(1, 3),
       voltage=st.floats(-5, 30, allow_nan=False), current=st.floats(-1, 12, allow_nan=False))
@settings(max_examples=150, deadline=None)
def test_setpoints_are_validated_against_the_models_channel_rating(
        model: str, channel: int, voltage: float, current: float) -> None:
    supply, fake = make_supply(model)
    rating = CHANNEL_RATINGS[model][channel]
    for attr, value, limit in (("voltage_setpoint_v", voltage, rating.max_voltage_v),
                               ("current_limit_a", current, rating.max_current_a)):
        fake.written.clear()
        if 0 <= value <= limit:
            setattr(supply.ch[channel], attr, value)
            assert fake.written[0].startswith(("VOLT ", "CURR ")) and fake.written[0].endswith(
                f",(@{channel})")
        else:
            with pytest.raises(ValueError, match=rf"\[0, {limit:g}\]"):
                setattr(supply.ch[channel], attr, value)
            assert fake.written == []


def test_supply_wide_commands_use_channel_lists() -> None:
    supply, fake = make_supply(**{"MEAS:VOLT? (@2,3)": "+1.2E+01,+0.0E+00",
                                  "MEAS:CURR? (@1,2,3)": "+1.0E-01,+2.0E-02,+0.0E+00"})
    supply.outputs_off()
    supply.set_outputs([1, 3], True)
    assert supply.measure_voltages_v([2, 3]) == (12.0, 0.0)
    assert supply.measure_currents_a() == (0.1, 0.02, 0.0)
    assert fake.written == ["OUTP OFF,(@1,2,3)", "SYST:ERR?", "OUTP ON,(@1,3)", "SYST:ERR?",
                            "MEAS:VOLT? (@2,3)", "MEAS:CURR? (@1,2,3)"]


@pytest.mark.parametrize("call", [
    lambda s: s.set_outputs([4], True), lambda s: s.set_outputs([], True),
    lambda s: s.set_outputs([1], 1), lambda s: s.measure_voltages_v([1, 1]),
])
def test_bad_channel_lists_raise_before_the_wire(call: Any) -> None:
    supply, fake = make_supply()
    with pytest.raises(ValueError):
        call(supply)
    assert fake.written == []


def test_measurement_list_of_the_wrong_length_is_an_error() -> None:
    supply, _ = make_supply(**{"MEAS:VOLT? (@1,2,3)": "+1.0E+00,+2.0E+00"})
    with pytest.raises(InstrumentReplyError):
        supply.measure_voltages_v()


def test_instrument_error_is_raised_with_code_and_message() -> None:
    supply, fake = make_supply()
    fake.error_queue.append('-221,"Settings conflict"')
    with pytest.raises(InstrumentError) as info:
        supply.ch[2].output_enabled = True
    assert (info.value.code, info.value.message, info.value.command) == (
        -221, "Settings conflict", "OUTP ON,(@2)")


def test_snapshot_records_identity_and_every_channel() -> None:
    replies = {f"{q}? (@{n})": r for n in (1, 2, 3)
               for q, r in (("VOLT", "+5.0E+00"), ("CURR", "+1.0E-01"), ("OUTP", "0"))}
    replies["CURR? (@3)"] = "garbage"
    supply, fake = make_supply(**replies)
    fake.error_queue.append('-113,"Undefined header"')  # left by a failed read
    snap = supply.snapshot()
    assert not fake.error_queue and fake.written[-2:] == ["SYST:ERR?", "SYST:ERR?"]
    assert snap["idn"]["model"] == "E36312A"
    assert snap["channels"][1] == {"voltage_setpoint_v": 5.0, "current_limit_a": 0.1,
                                   "output_enabled": False}
    assert snap["channels"][3]["current_limit_a"].startswith("error:")


def test_driver_fits_the_power_supply_protocols() -> None:
    supply, fake = make_supply()
    assert_conforms(supply, PowerSupply)
    assert_conforms(supply.ch[1], SupplyChannel)
    assert fake.written == []


@pytest.fixture()
def sim_supply() -> Any:
    resource = open_resource("TCPIP0::127.0.0.1::5026::SOCKET",
                             backend=f"{SIM_YAML_DIR / 'keysight_e36312a.yaml'}@sim")
    yield KeysightE36312A(resource)
    resource.close()


def test_pyvisa_sim_vocabulary_round_trips(sim_supply: KeysightE36312A) -> None:
    assert sim_supply.model == "E36312A"
    sim_supply.ch[1].voltage_setpoint_v = 5.5
    sim_supply.ch[2].current_limit_a = 0.25
    sim_supply.ch[3].output_enabled = True
    assert sim_supply.ch[1].voltage_setpoint_v == 5.5
    assert sim_supply.ch[2].current_limit_a == 0.25
    assert sim_supply.ch[3].output_enabled is True
    sim_supply.ch[1].apply(5, 1)
    sim_supply.outputs_off()
    assert sim_supply.measure_voltages_v() == (4.9998, 12.0001, 0.0)
    assert sim_supply.ch[1].measured_current_a == 0.1023


def test_pyvisa_sim_rejects_a_setpoint_above_the_rating(sim_supply: KeysightE36312A) -> None:
    sim_supply.resource.write("VOLT 30,(@2)")  # bypasses the driver's validation
    with pytest.raises(InstrumentError) as info:
        sim_supply.check_errors("VOLT 30,(@2)")
    assert info.value.code == -100
    assert sim_supply.ch[2].voltage_setpoint_v == 0.0
