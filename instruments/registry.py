"""The driver registry: every driver a station file can name, by its key.

A station file's ``driver = "keysight_34465a"`` is looked up here: the driver class, the
instrument-kind interface it implements (``instruments.protocols``), the kind of connection
it is driven over, and the options a station file may give it.  Opening a station
(``bench.app.station``) reads nothing else about drivers; the simulated station names each
of its instruments' drivers by these keys (``sim.station.INSTRUMENTS``, as text: ``sim``
imports nothing of the bench).

A driver is called as ``cls(connection, name=<instrument name>, **driver_options)``, where
the connection is what its transport opens: a pyvisa message-based resource (:data:`VISA`)
a pyserial port (:data:`SERIAL`) or a connected pymodbus ``ModbusTcpClient`` (:data:`MODBUS`,
a chamber controller).  A driver for another kind of connection adds its transport name here
and its opener beside the others in ``bench.app.station.OPENERS``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from .angular_table import AngularVibrationTable
from .chamber import WatlowF4TChamber
from .daq import KeysightDAQ970A
from .fog import BAUD_RATES, SerialGyro
from .multimeter import Keysight34465A
from .power_supply import KeysightE36312A
from .protocols import (
    AngularTable,
    FrameGyro,
    PositionRateTable,
    PowerSupply,
    RandomVibrationTable,
    ScanningMultimeter,
    ThermalChamber,
    TimedTraceMultimeter,
)
from .shaker import VibrationTable
from .turntable import DualAxisTurntable

#: a pyvisa message-based resource (``TCPIP::host::port::SOCKET``, GPIB, USB, a pyvisa-sim YAML)
VISA = "visa"
#: a pyserial port (a device path such as ``/dev/ttyUSB0``, or ``socket://host:port``)
SERIAL = "serial"
#: a pymodbus Modbus TCP client (``modbus://host[:port]``, port 502 by default)
MODBUS = "modbus"
TRANSPORTS = (VISA, SERIAL, MODBUS)


@dataclass(frozen=True)
class Option:
    """One station-file option of a driver: its default and the values allowed — a set
    (``choices``) or an inclusive numeric range (``range``).  ``connection``: the option
    configures the connection (a serial port's ``baudrate``), not the driver."""

    default: Any
    choices: tuple[Any, ...] | None = None
    range: tuple[float, float] | None = None
    connection: bool = False

    def problem(self, key: str, value: Any) -> str | None:
        """Why ``value`` cannot be this option's value (naming the allowed ones), or None."""
        number = not isinstance(value, bool) and isinstance(value, (int, float))
        if self.range is not None and not (number and self.range[0] <= value <= self.range[1]):
            return f"{key} = {value!r} must be a number in {self.range[0]:g}..{self.range[1]:g}"
        if self.choices is not None and not (number and value in self.choices):
            return f"{key} = {value!r} not in {'|'.join(map(str, self.choices))}"
        return None


@dataclass(frozen=True)
class Driver:
    """One registry entry."""

    key: str
    #: the driver class: ``cls(connection, name=..., **driver options)``
    cls: Callable[..., Any]
    #: the instrument-kind interface it implements (``instruments.protocols``)
    protocol: type
    #: what it is driven over: :data:`VISA` or :data:`SERIAL`
    transport: str
    #: the station-file options it takes, each checked; empty: none checked (free keys such as
    #: ``options = [...]``, the option codes ``bench doctor`` expects, are kept for the tools)
    options: Mapping[str, Option] = field(default_factory=lambda: MappingProxyType({}))

    def __post_init__(self) -> None:
        if self.transport not in TRANSPORTS:
            raise ValueError(f"driver {self.key}: transport {self.transport!r} not in {'|'.join(TRANSPORTS)}")

    def connection_options(self, given: Mapping[str, Any]) -> dict[str, Any]:
        """The connection's options: each given one, else its default."""
        return {k: given.get(k, o.default) for k, o in self.options.items() if o.connection}

    def driver_options(self, given: Mapping[str, Any]) -> dict[str, Any]:
        """The driver's keyword options: each given one, else its default."""
        return {k: given.get(k, o.default) for k, o in self.options.items() if not o.connection}


#: every driver, by key
DRIVERS: Mapping[str, Driver] = MappingProxyType({d.key: d for d in (
    Driver("keysight_34465a", Keysight34465A, TimedTraceMultimeter, VISA),
    Driver("keysight_e36312a", KeysightE36312A, PowerSupply, VISA),
    Driver("acutrol_turntable", DualAxisTurntable, PositionRateTable, VISA),
    Driver("fog_serial", SerialGyro, FrameGyro, SERIAL, MappingProxyType({
        "baudrate": Option(921600, choices=BAUD_RATES, connection=True),
        "scale_factor_pulses_per_arcsec": Option(None, range=(1e-6, 1e9)),
        "polarity": Option(1, choices=(1, -1))})),
    Driver("vibration_controller", VibrationTable, RandomVibrationTable, VISA),
    Driver("angular_vibration_table", AngularVibrationTable, AngularTable, VISA),
    Driver("watlow_f4t", WatlowF4TChamber, ThermalChamber, MODBUS, MappingProxyType({
        "device_id": Option(1, range=(0, 247)),
        "ambient_set_point_c": Option(23.0, range=(-70.0, 180.0))})),
    Driver("keysight_daq970a", KeysightDAQ970A, ScanningMultimeter, VISA),
)})

__all__ = ["DRIVERS", "MODBUS", "SERIAL", "TRANSPORTS", "VISA", "Driver", "Option"]
