"""The driver registry: every driver implements its kind's Protocol, make_safe included, and
is opened over a known transport with checked options."""

from __future__ import annotations

import inspect

import pytest

from bench.testing import assert_conforms
from instruments.angular_table import AngularVibrationTable
from instruments.chamber import WatlowF4TChamber
from instruments.daq import KeysightDAQ970A
from instruments.fog import SerialGyro
from instruments.multimeter import Keysight34465A
from instruments.power_supply import KeysightE36312A
from instruments.protocols import (
    AngularTable,
    FrameGyro,
    PositionRateTable,
    PowerSupply,
    RandomVibrationTable,
    SafeInstrument,
    SafeOrder,
    ScanningMultimeter,
    ThermalChamber,
    TimedTraceMultimeter,
)
from instruments.registry import DRIVERS, TRANSPORTS, Driver, Option
from instruments.shaker import VibrationTable
from instruments.turntable import DualAxisTurntable

# Checked by the type checker (mypy runs on tests/): each driver is structurally its Protocol.
STATIC: tuple[type[TimedTraceMultimeter], type[PowerSupply], type[PositionRateTable], type[FrameGyro],
              type[RandomVibrationTable], type[AngularTable], type[ThermalChamber],
              type[ScanningMultimeter]] = (
    Keysight34465A, KeysightE36312A, DualAxisTurntable, SerialGyro, VibrationTable, AngularVibrationTable,
    WatlowF4TChamber, KeysightDAQ970A)


class Connection:
    """What a constructor may ask before any procedure runs (identity, options, line frequency)."""

    timeout = 2.0
    resource_name = "fake"
    replies = {"*OPT?": '"DIG","MEM"', "SYST:LFR?": "50", "SYST:ERR?": '+0,"No error"'}

    def __init__(self, model: str) -> None:
        self.model = model

    def query(self, command: str) -> str:
        return f"Keysight Technologies,{self.model},MY1,1.0" if command == "*IDN?" else self.replies[command]

    def write(self, command: str) -> None:
        raise AssertionError(f"a constructor wrote {command!r}")


MODELS = {"keysight_34465a": "34465A", "keysight_e36312a": "E36312A"}


def built(entry: Driver) -> SafeInstrument:
    """The driver on a connection that answers the constructor's questions (no I/O after that)."""
    driver: SafeInstrument = entry.cls(Connection(MODELS.get(entry.key, "?")), name=entry.key)
    return driver


@pytest.mark.parametrize("entry", DRIVERS.values(), ids=lambda d: d.key)
def test_every_driver_has_every_member_of_its_protocol(entry: Driver) -> None:
    driver = built(entry)
    assert_conforms(driver, entry.protocol)  # make_safe, safe_order, safe_action included
    assert entry.transport in TRANSPORTS
    assert isinstance(driver.safe_order, SafeOrder)
    assert isinstance(driver.safe_action, str) and driver.safe_action
    assert not inspect.signature(driver.make_safe).parameters


def test_the_teardown_order_puts_power_first_and_motion_last():
    order = {key: built(d).safe_order for key, d in DRIVERS.items()}
    assert order["keysight_e36312a"] == SafeOrder.POWER
    assert order["keysight_34465a"] == order["fog_serial"] == SafeOrder.ACQUISITION
    assert {order[k] for k in ("acutrol_turntable", "vibration_controller", "angular_vibration_table")} == {
        SafeOrder.MOTION}


def test_the_static_conformance_list_names_every_registered_driver():
    assert set(STATIC) == {d.cls for d in DRIVERS.values()}
    assert all({"make_safe", "safe_order", "safe_action"} <= set(dir(d.protocol)) for d in DRIVERS.values())
    assert all(SafeInstrument in d.protocol.__mro__ for d in DRIVERS.values())


def test_options_split_between_connection_and_driver_and_check_values():
    gyro = DRIVERS["fog_serial"]
    assert gyro.connection_options({}) == {"baudrate": 921600}
    assert gyro.driver_options({"polarity": -1}) == {"scale_factor_pulses_per_arcsec": None, "polarity": -1}
    assert gyro.options["baudrate"].problem("baudrate", 9600) == "baudrate = 9600 not in 115200|230400|460800|921600"
    assert gyro.options["polarity"].problem("polarity", True) == "polarity = True not in 1|-1"
    assert Option(None, range=(0.0, 1.0)).problem("x", 2) == "x = 2 must be a number in 0..1"
    assert Option(None, range=(0.0, 1.0)).problem("x", 0.5) is None
    assert DRIVERS["keysight_34465a"].connection_options({"options": ["DIG"]}) == {}
    with pytest.raises(ValueError, match="transport .can. not in visa|serial|modbus"):
        Driver("can_bus_thing", object, object, "can")
