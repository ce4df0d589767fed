"""Dual-axis position/rate turntable with an ACUTROL-style controller language.

The language (docs/ARCHITECTURE.md) is SCPI syntax with the axis number first:
``:MODE:POS 1``, ``:DEM:POS 1,90``, ``:READ:RATE? 2``, ``:STAT? 1``, ``:INT:CLOS`` ...
Axis 1 is the inner axis (normal to the platform), axis 2 the outer (tilts the
platform).  Angles are degrees, rates deg/s, accelerations deg/s².  Errors go to the
SCPI error queue (``SYST:ERR?``) and raise :class:`~instruments.base.InstrumentError`.

The driver never sleeps: :meth:`TableAxis.wait_in_position` takes the caller's
``wait(seconds)`` (the bench clock).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from .base import (
    InstrumentChannel,
    control,
    in_range,
    in_set,
    measurement,
    parse_bool,
    parse_int,
    read_settings,
)
from .protocols import SafeOrder, Wait
from .ramped import Interlocked, poll_until

log = logging.getLogger(__name__)

MODES = ("POS", "RATE", "OFF")


@dataclass(frozen=True)
class AxisLimits:
    """What the driver lets through to one axis (the controller enforces its own too)."""

    position_min_deg: float = -360.0
    position_max_deg: float = 360.0
    max_rate_dps: float = 1000.0
    max_accel_dps2: float = 1000.0


#: Default limits: the inner axis is the faster one on a typical two-axis rate table.
DEFAULT_LIMITS: Mapping[int, AxisLimits] = {
    1: AxisLimits(max_rate_dps=1000.0, max_accel_dps2=1000.0),
    2: AxisLimits(max_rate_dps=500.0, max_accel_dps2=500.0),
}


@dataclass(frozen=True)
class AxisStatus:
    """``:STAT? <axis>`` bit field, decoded."""

    raw: int
    in_position: bool
    moving: bool
    at_rate: bool
    limit_reached: bool
    interlock_open: bool
    fault: bool

    IN_POSITION = 1
    MOVING = 2
    AT_RATE = 4
    LIMIT_REACHED = 8
    INTERLOCK_OPEN = 16
    FAULT = 32

    @classmethod
    def from_bits(cls, raw: int) -> AxisStatus:
        return cls(
            raw=raw,
            in_position=bool(raw & cls.IN_POSITION),
            moving=bool(raw & cls.MOVING),
            at_rate=bool(raw & cls.AT_RATE),
            limit_reached=bool(raw & cls.LIMIT_REACHED),
            interlock_open=bool(raw & cls.INTERLOCK_OPEN),
            fault=bool(raw & cls.FAULT),
        )


class AxisFaultError(RuntimeError):
    """An axis reported a fault or an open interlock while the driver waited on it."""

    def __init__(self, axis: int, status: AxisStatus, what: str, instrument: str = "") -> None:
        self.axis, self.status = axis, status
        where = f"{instrument}: axis {axis}" if instrument else f"axis {axis}"
        super().__init__(f"{where}: {what} (status {status.raw})")


class TableAxis(InstrumentChannel):
    """One axis: mode, demands, readbacks, user limits, status, moves."""

    field_name = "axis"

    def __init__(self, parent: DualAxisTurntable, number: int, limits: AxisLimits) -> None:
        super().__init__(parent, number)
        self.limits = limits

    @property
    def position_range_deg(self) -> tuple[float, float]:
        return (self.limits.position_min_deg, self.limits.position_max_deg)

    @property
    def rate_range_dps(self) -> tuple[float, float]:
        return (-self.limits.max_rate_dps, self.limits.max_rate_dps)

    mode = control(
        ":MODE? {axis}", ":MODE:{value} {axis}",
        "Servo mode: POS (position loop), RATE (rate loop) or OFF (drive disabled, coasts).",
        validator=in_set, values=MODES, fmt=str, parse=lambda r: r.strip().upper(),
    )
    position_demand_deg = control(
        ":DEM:POS? {axis}", ":DEM:POS {axis},{value}",
        "Position demand in degrees (a trapezoidal move in POS mode).",
        validator=in_range, values=lambda ax: ax.position_range_deg,
    )
    rate_demand_dps = control(
        ":DEM:RATE? {axis}", ":DEM:RATE {axis},{value}",
        "Rate demand in deg/s (ramped at the acceleration limit in RATE mode).",
        validator=in_range, values=lambda ax: ax.rate_range_dps,
    )
    rate_limit_dps = control(
        ":LIM:RATE? {axis}", ":LIM:RATE {axis},{value}",
        "User rate limit in deg/s, up to the axis maximum.",
        validator=in_range, values=lambda ax: (0.0, ax.limits.max_rate_dps),
    )
    accel_limit_dps2 = control(
        ":LIM:ACC? {axis}", ":LIM:ACC {axis},{value}",
        "User acceleration limit in deg/s², up to the axis maximum.",
        validator=in_range, values=lambda ax: (0.0, ax.limits.max_accel_dps2),
    )
    position_deg = measurement(":READ:POS? {axis}", "Measured position, degrees.")
    rate_dps = measurement(":READ:RATE? {axis}", "Measured rate, deg/s.")
    accel_dps2 = measurement(":READ:ACC? {axis}", "Measured acceleration, deg/s².")
    status = measurement(
        ":STAT? {axis}", "Status bits decoded into an AxisStatus.",
        parse=lambda r: AxisStatus.from_bits(parse_int(r)),
    )

    snapshot_settings = ("mode", "rate_limit_dps", "accel_limit_dps2", "position_deg")

    def move_to(self, position_deg: float) -> None:
        """Position mode and a move to ``position_deg`` (validated before anything is sent)."""
        target = in_range(self.label("position_deg"), position_deg, self.position_range_deg)
        with self.configuring():
            self.mode = "POS"
            self.position_demand_deg = target

    def set_rate(self, rate_dps: float) -> None:
        """Rate mode at ``rate_dps`` (validated before anything is sent)."""
        rate = in_range(self.label("rate_dps"), rate_dps, self.rate_range_dps)
        with self.configuring():
            self.mode = "RATE"
            self.rate_demand_dps = rate

    def stop(self) -> None:
        """``:STOP``: decelerate to rest and hold position."""
        self.configure_command(f":STOP {self.number}")

    def wait_in_position(self, wait: Wait, timeout_s: float, poll_s: float = 0.1) -> AxisStatus:
        """Poll status until in position and not moving; returns that status.

        ``wait(seconds)`` lets time pass between polls.  Raises :class:`AxisFaultError`
        on a fault or open interlock, ``TimeoutError`` after ``timeout_s`` of waiting.
        """
        return self._wait_for(lambda s: s.in_position and not s.moving, "in position",
                              wait, timeout_s, poll_s)

    def wait_at_rate(self, wait: Wait, timeout_s: float, poll_s: float = 0.1) -> AxisStatus:
        """Poll status until the axis is at its rate demand; otherwise as
        :meth:`wait_in_position`."""
        return self._wait_for(lambda s: s.at_rate, "at rate", wait, timeout_s, poll_s)

    def _wait_for(
        self, done: Callable[[AxisStatus], bool], what: str, wait: Wait,
        timeout_s: float, poll_s: float,
    ) -> AxisStatus:
        def reached(status: AxisStatus) -> bool:
            if status.fault:
                what_fault = "fault, interlock tripped" if status.interlock_open else "fault"
                raise AxisFaultError(self.number, status, what_fault, self.parent.name)
            if status.interlock_open:
                raise AxisFaultError(self.number, status, "interlock open", self.parent.name)
            return done(status)

        return poll_until(lambda: self.status, reached, wait, timeout_s, poll_s,
                          lambda status, waited: f"axis {self.number} not {what} after {waited:g} s "
                                                 f"(status {status.raw})")


@dataclass(frozen=True)
class StopFailure:
    """An axis that :meth:`DualAxisTurntable.stop_all` could not stop, and why."""

    axis: int
    error: Exception


class DualAxisTurntable(Interlocked):
    """Two-axis position/rate table; ``table.axis[1]`` (inner), ``table.axis[2]`` (outer).

    ``limits`` overrides :data:`DEFAULT_LIMITS` per axis.  The constructor does no I/O.
    """

    def __init__(
        self, resource: Any, name: str | None = None,
        limits: Mapping[int, AxisLimits] | None = None,
    ) -> None:
        super().__init__(resource, name)
        chosen = dict(DEFAULT_LIMITS)
        chosen.update(limits or {})
        if set(chosen) != {1, 2}:
            raise ValueError(f"limits name axes {sorted(chosen)}; allowed axes are 1 and 2")
        self.axis: dict[int, TableAxis] = {n: TableAxis(self, n, chosen[n]) for n in (1, 2)}

    interlock_closed = measurement(":INT?", "True while the interlock is closed (drives enabled).",
                                   parse=parse_bool)
    safe_order = SafeOrder.MOTION
    safe_action = "stop"

    def snapshot_details(self) -> dict[str, Any]:
        return {"axes": {n: read_settings(ax, ax.snapshot_settings) for n, ax in self.axis.items()}}

    def stop_all(self) -> list[StopFailure]:
        """Send ``:STOP`` to every axis, even if one fails; for teardown.

        Never raises for a per-axis failure (instrument error, I/O error, timeout): each
        is logged and returned, so the caller's teardown can go on to make the rest safe.
        """
        failures: list[StopFailure] = []
        for number, axis in self.axis.items():
            try:
                axis.stop()
            except Exception as exc:  # teardown must reach every axis
                log.error("%s: could not stop axis %d: %s", self.name, number, exc)
                failures.append(StopFailure(number, exc))
        return failures

    def make_safe(self) -> None:
        """Teardown: :meth:`stop_all`, then one error naming every axis that did not stop."""
        failures = self.stop_all()
        if failures:
            raise RuntimeError("; ".join(f"axis {f.axis}: {f.error}" for f in failures))
