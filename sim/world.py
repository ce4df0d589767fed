"""The simulated world: one physics state, one virtual clock, seeded randomness.

Every simulated instrument is a *view* of one :class:`World`.  Time is simulated and
advances only by events: a server asks the world to advance (because the bench clock
asked to wait, or because a blocking query such as ``FETC?`` needs an acquisition to
finish) and the world runs its scheduled events and continuous activities in time order.
Waiting thirty simulated minutes therefore costs only the arithmetic of what happens in
them.

Determinism: every model draws from its own generator, ``world.rng(name)``, seeded from
``(seed, crc32(name))``.  Adding a model never shifts another model's random stream, and
the same seed gives the same bytes on the wire.
"""

from __future__ import annotations

import heapq
import itertools
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

#: Longest single advance accepted (one simulated year); protects servers from absurd requests.
MAX_ADVANCE_S = 3.2e7


class Activity(Protocol):
    """Something continuous (a DMM acquisition, a frame stream) run forward in time order."""

    def run_until(self, t_s: float) -> None: ...


@dataclass(order=True)
class _Event:
    t_s: float
    order: int
    callback: Callable[[], None] = field(compare=False)
    name: str = field(compare=False, default="")
    cancelled: bool = field(compare=False, default=False)


class World:
    """Physics state + virtual clock + seeded generators.

    Parameters
    ----------
    seed:
        Non-negative integer; the whole world's randomness derives from it.
    """

    def __init__(self, seed: int = 0) -> None:
        if not isinstance(seed, (int, np.integer)) or seed < 0 or seed >= 2**63:
            raise ValueError(f"seed {seed!r} must be an integer in 0..2**63-1")
        self.seed = int(seed)
        self.now = 0.0
        self._events: list[_Event] = []
        self._order = itertools.count()
        self._activities: list[Activity] = []
        self._rngs: dict[str, np.random.Generator] = {}
        self.models: dict[str, object] = {}
        self.log: list[tuple[float, str]] = []  # (t_s, message) of notable state changes

    # -- randomness ------------------------------------------------------------------
    def rng(self, name: str) -> np.random.Generator:
        """The generator of the model called ``name`` (created on first use)."""
        if name not in self._rngs:
            key = zlib.crc32(name.encode("utf-8"))
            self._rngs[name] = np.random.Generator(
                np.random.PCG64(np.random.SeedSequence([self.seed, key]))
            )
        return self._rngs[name]

    # -- events and activities ------------------------------------------------------
    def schedule(self, t_s: float, callback: Callable[[], None], name: str = "") -> _Event:
        """Run ``callback`` when simulated time reaches ``t_s`` (≥ now)."""
        if not np.isfinite(t_s) or t_s < self.now:
            raise ValueError(f"event time {t_s!r} s must be finite and ≥ now ({self.now} s)")
        event = _Event(float(t_s), next(self._order), callback, name)
        heapq.heappush(self._events, event)
        return event

    @staticmethod
    def cancel(event: _Event) -> None:
        event.cancelled = True

    def add_activity(self, activity: Activity) -> None:
        if activity not in self._activities:
            self._activities.append(activity)

    def remove_activity(self, activity: Activity) -> None:
        if activity in self._activities:
            self._activities.remove(activity)

    def next_event_time(self) -> float | None:
        while self._events and self._events[0].cancelled:
            heapq.heappop(self._events)
        return self._events[0].t_s if self._events else None

    # -- the clock --------------------------------------------------------------------
    def advance(self, dt_s: float) -> None:
        """Advance simulated time by ``dt_s`` seconds (0 ≤ dt ≤ one year)."""
        if not np.isfinite(dt_s) or dt_s < 0 or dt_s > MAX_ADVANCE_S:
            raise ValueError(f"advance of {dt_s!r} s is outside 0..{MAX_ADVANCE_S:g} s")
        self.advance_to(self.now + dt_s)

    def advance_to(self, t_s: float) -> None:
        """Run events and activities in time order up to and including ``t_s``."""
        if not np.isfinite(t_s) or t_s < self.now:
            raise ValueError(f"cannot advance to {t_s!r} s: it is before now ({self.now} s)")
        if t_s - self.now > MAX_ADVANCE_S:
            raise ValueError(f"advance to {t_s} s exceeds the {MAX_ADVANCE_S:g} s limit")
        while True:
            t_next = self.next_event_time()
            if t_next is None or t_next > t_s:
                break
            event = heapq.heappop(self._events)
            # Continuous activities catch up to the event first, so a state change
            # applied by the event never leaks into samples taken before it.
            self._run_activities(event.t_s)
            self.now = event.t_s
            event.callback()
        self._run_activities(t_s)
        self.now = t_s

    def _run_activities(self, t_s: float) -> None:
        for activity in list(self._activities):
            activity.run_until(t_s)

    def note(self, message: str) -> None:
        self.log.append((self.now, message))
