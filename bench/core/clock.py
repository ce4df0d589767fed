"""The bench clock: procedures wait only through it.

On a real station it is the wall clock.  On a simulated station it is the World's virtual
clock, reached through the sim-control endpoint over the same wire as any instrument, so a
30-minute warm-up costs milliseconds and the procedure cannot tell the difference.
"""

from __future__ import annotations

import math
import time
from typing import Protocol


class Clock(Protocol):
    simulated: bool

    def now(self) -> float:
        """Seconds on this clock (monotonic; origin arbitrary)."""

    def sleep(self, seconds: float) -> None:
        """Let ``seconds`` pass on this clock."""


def _check_duration(seconds: float) -> float:
    if not isinstance(seconds, (int, float)) or not math.isfinite(seconds) or seconds < 0:
        raise ValueError(f"wait of {seconds!r} s must be a finite number ≥ 0")
    return float(seconds)


class WallClock:
    """Real time, for a station of real instruments."""

    simulated = False

    def now(self) -> float:
        return time.monotonic()

    def sleep(self, seconds: float) -> None:
        time.sleep(_check_duration(seconds))


class SimulatedClock:
    """Virtual time of a simulated station, via its sim-control endpoint (a pyvisa resource)."""

    simulated = True

    def __init__(self, resource) -> None:
        self.resource = resource

    def now(self) -> float:
        return float(self.resource.query("SIM:TIME?"))

    def sleep(self, seconds: float) -> None:
        seconds = _check_duration(seconds)
        if seconds == 0:
            return
        # *OPC? returns once the world has advanced: the reply is the synchronisation point.
        reply = self.resource.query(f"SIM:TIME:ADV {seconds!r};*OPC?")
        if reply.strip() != "1":
            raise RuntimeError(f"sim-control did not confirm the advance of {seconds} s: {reply!r}")
        err = self.resource.query("SYST:ERR?")
        if not err.startswith(("+0", "0")):
            raise RuntimeError(f"sim-control refused the advance of {seconds} s: {err.strip()}")
