"""Procedures reach the station's instruments through the Protocols of
``instruments/protocols.py`` (``procedures.typed_instruments``), so mypy checks every call a
procedure makes against the driver interfaces.  Here: the drivers fit those Protocols —
statically (mypy checks :func:`drivers_as_protocols`) and member by member on the built-in
simulated station — every instrument a catalogued step requires has a typed accessor, and a
missing instrument is named."""

from __future__ import annotations

import inspect
from collections.abc import Callable
from types import SimpleNamespace
from typing import Any, cast

import pytest

from bench.app.station import Station, builtin_sim_config
from bench.core.step import Context
from instruments.angular_table import AngularVibrationTable
from instruments.chamber import WatlowF4TChamber
from instruments.fog import SerialGyro
from instruments.multimeter import Keysight34465A
from instruments.power_supply import KeysightE36312A
from instruments.protocols import (
    AngularTable,
    FrameGyro,
    PositionRateTable,
    PowerSupply,
    RandomVibrationTable,
    ThermalChamber,
    TimedTraceMultimeter,
)
from instruments.shaker import VibrationTable
from instruments.turntable import DualAxisTurntable
from procedures.catalogue import CATALOGUE
from procedures.typed_instruments import (
    angular_table,
    chamber,
    frame_gyro,
    multimeter,
    power_supply,
    shaker,
    turntable,
)


def drivers_as_protocols(dmm: Keysight34465A, supply: KeysightE36312A, table: DualAxisTurntable,
                         gyro: SerialGyro, vibration: VibrationTable, angular: AngularVibrationTable,
                         f4t: WatlowF4TChamber,
                         ) -> tuple[TimedTraceMultimeter, PowerSupply, PositionRateTable, FrameGyro,
                                    RandomVibrationTable, AngularTable, ThermalChamber]:
    """Never called: mypy refuses this file if a driver no longer fits its Protocol."""
    return dmm, supply, table, gyro, vibration, angular, f4t


#: station name → (typed accessor, the Protocol it returns)
ACCESS: dict[str, tuple[Callable[[Context, str], Any], type]] = {
    "dmm": (multimeter, TimedTraceMultimeter),
    "dmm_temp": (multimeter, TimedTraceMultimeter),
    "dmm_mhd": (multimeter, TimedTraceMultimeter),
    "supply": (power_supply, PowerSupply),
    "turntable": (turntable, PositionRateTable),
    "gyro": (frame_gyro, FrameGyro),
    "lf_gyro": (frame_gyro, FrameGyro),
    "shaker": (shaker, RandomVibrationTable),
    "angular_table": (angular_table, AngularTable),
    "chamber": (chamber, ThermalChamber),
}


def members(protocol: type) -> set[str]:
    names = set(getattr(protocol, "__annotations__", {}))
    return names | {n for n, v in vars(protocol).items()
                    if not n.startswith("_") and (callable(v) or isinstance(v, property))}


def test_every_instrument_a_step_requires_has_a_typed_accessor() -> None:
    required = {r for step in CATALOGUE.steps.values() for r in step.requires}
    assert required == set(ACCESS)


def test_the_station_drivers_have_every_member_of_their_protocol() -> None:
    with Station(builtin_sim_config(), seed=1) as station:
        ctx = cast(Context, SimpleNamespace(instruments=station.instruments))
        for name, (accessor, protocol) in ACCESS.items():
            inst = accessor(ctx, name)
            assert inst is station.instruments[name]
            for member in sorted(members(protocol)):  # looked up statically: nothing on the wire
                assert inspect.getattr_static(inst, member, None) is not None, (name, member)


def test_a_missing_instrument_is_named_with_what_the_station_has() -> None:
    ctx = cast(Context, SimpleNamespace(instruments={"dmm": object()}))
    with pytest.raises(LookupError, match=r"no instrument 'gyro'; it has \['dmm'\]"):
        frame_gyro(ctx)
