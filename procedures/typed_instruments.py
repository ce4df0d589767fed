"""Typed access to the station's instruments.

A step asks its context for "the multimeter named ``dmm``" and gets a
:class:`~instruments.protocols.TimedTraceMultimeter`, not a model number: every call a
procedure makes on an instrument is then checked by mypy against the driver interfaces of
``instruments/protocols.py``, and any driver (or test double) with those members fits.

The framework's ``Context.instruments`` is a plain mapping (``bench.core`` knows no
instrument); this module is where the procedures layer puts the types on it.  A station
without the instrument is a ``LookupError`` naming it and what the station has (the runner
refuses such a station before a run exists, from the steps' ``requires``).
"""

from __future__ import annotations

from typing import Any

from bench.core.step import Context
from instruments.protocols import (
    AngularTable,
    FrameGyro,
    PositionRateTable,
    PowerSupply,
    RandomVibrationTable,
    ScanningMultimeter,
    ThermalChamber,
    TimedTraceMultimeter,
)


def _instrument(ctx: Context, name: str) -> Any:
    try:
        return ctx.instruments[name]
    except KeyError:
        raise LookupError(f"the station has no instrument {name!r}; it has "
                          f"{sorted(ctx.instruments)}") from None


def multimeter(ctx: Context, name: str = "dmm") -> TimedTraceMultimeter:
    """A DC voltmeter taking timed traces: ``dmm`` (the unit's output), ``dmm_temp`` (its
    temperature sensor), ``dmm_mhd`` (the angular rig's MHD sensor, digitizing)."""
    return _instrument(ctx, name)


def scanner(ctx: Context, name: str = "daq") -> ScanningMultimeter:
    """The scanning DAQ whose multiplexer channels read the fixture's test sockets."""
    return _instrument(ctx, name)


def power_supply(ctx: Context, name: str = "supply") -> PowerSupply:
    """The multi-output DC supply that powers the unit (its wiring: ``ctx.wiring``)."""
    return _instrument(ctx, name)


def turntable(ctx: Context, name: str = "turntable") -> PositionRateTable:
    """The dual-axis position/rate table the unit is mounted on."""
    return _instrument(ctx, name)


def frame_gyro(ctx: Context, name: str = "gyro") -> FrameGyro:
    """A gyro streaming frames on a serial line: ``gyro`` (the unit), ``lf_gyro`` (the angular
    rig's low-frequency rate sensor)."""
    return _instrument(ctx, name)


def shaker(ctx: Context, name: str = "shaker") -> RandomVibrationTable:
    """The random-vibration shaker and its controller."""
    return _instrument(ctx, name)


def angular_table(ctx: Context, name: str = "angular_table") -> AngularTable:
    """The angular vibration table with its reference capture (Document B's rig)."""
    return _instrument(ctx, name)


def chamber(ctx: Context, name: str = "chamber") -> ThermalChamber:
    """The temperature chamber's controller the unit (and its table) stands in."""
    return _instrument(ctx, name)


__all__ = ["multimeter", "scanner", "power_supply", "turntable", "frame_gyro", "shaker", "angular_table", "chamber"]
