"""The simulated world: one physics state, one virtual clock, seeded randomness.

Every simulated instrument is a *view* of one :class:`World`.  Time is simulated and, by
default (*event-driven*), advances only by events: a server asks the world to advance
(because the bench clock asked to wait, or because a blocking query such as ``FETC?`` needs
an acquisition to finish) and the world runs its scheduled events and continuous activities
in time order.  Waiting thirty simulated minutes therefore costs only the arithmetic of what
happens in them.

*Paced* (``World(seed, pace=N)``), the clock also follows the wall: simulated time runs at
``N`` simulated seconds per wall second from where it stood when the clock was anchored
(:meth:`World.anchor_pace`), so a client that polls sees readings arrive and ramps move.  The
server's loop runs the world up to the paced clock (:meth:`World.catch_up`) before each
message and every few milliseconds; a wait ahead of the paced clock (:meth:`World.advance_to`
from a blocking query) waits for the wall through :attr:`World.wait_for_wall` instead of
jumping, so the world never runs ahead of the paced clock.

Determinism: every model draws from its own generator, ``world.rng(name)``, seeded from
``(seed, crc32(name))``.  Adding a model never shifts another model's random stream, and,
event-driven, the same seed gives the same bytes on the wire.  Paced, what a reply holds
depends on when it was asked: the wall clock is an input.
"""

from __future__ import annotations

import heapq
import itertools
import time
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

#: Longest single advance accepted (one simulated year); protects servers from absurd requests.
MAX_ADVANCE_S = 3.2e7
#: Paces accepted, simulated seconds per wall second: from a thousandth of real time (a one-second
#: event takes a quarter of an hour: slower helps no one) to a million (one ~5 ms turn of the
#: server loop then spans over an hour of simulated time: faster, a poll follows nothing — use
#: the event-driven clock).
MIN_PACE, MAX_PACE = 1e-3, 1e6


def check_pace(pace: object) -> float | None:
    """``pace`` as a :class:`World` takes it: None (event-driven) or a number of simulated
    seconds per wall second in ``MIN_PACE..MAX_PACE`` (1: real time); ``ValueError`` naming
    the value and the range otherwise."""
    if pace is None:
        return None
    if isinstance(pace, bool) or not isinstance(pace, (int, float)) or not MIN_PACE <= pace <= MAX_PACE:
        raise ValueError(f"pace = {pace!r} not in {MIN_PACE:g}..{MAX_PACE:g} simulated seconds per wall "
                         "second (1 = realtime); leave it unset for event-driven time")
    return float(pace)


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
    pace:
        None: event-driven time (the default).  A number: the clock also follows the wall at
        this many simulated seconds per wall second (``MIN_PACE..MAX_PACE``; 1 = real time).
    """

    def __init__(self, seed: int = 0, pace: float | None = None) -> None:
        if not isinstance(seed, (int, np.integer)) or seed < 0 or seed >= 2**63:
            raise ValueError(f"seed {seed!r} must be an integer in 0..2**63-1")
        self.seed = int(seed)
        self.now = 0.0
        #: simulated seconds per wall second while the clock follows the wall; None: event-driven
        self.pace = check_pace(pace)
        self._anchor = (time.monotonic(), 0.0)  # (wall s, simulated s) the paced clock runs on from
        #: how a wait ahead of the paced clock lets the wall catch up; returns once
        #: ``paced_now() >= t_s``.  The server installs one that suspends only the waiting
        #: message; this default sleeps the calling thread.
        self.wait_for_wall: Callable[[float], None] = self.sleep_until
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

    # -- paced time (the clock follows the wall) ----------------------------------------
    def anchor_pace(self) -> None:
        """The paced clock runs on from ``now`` at this wall instant (a server calls it as it
        starts serving, so no time passes while nobody can ask)."""
        self._anchor = (time.monotonic(), self.now)

    def paced_now(self) -> float:
        """Where the paced clock stands (simulated s); ``now`` when event-driven."""
        if self.pace is None:
            return self.now
        wall_s, t_s = self._anchor
        return t_s + self.pace * (time.monotonic() - wall_s)

    def wall_delay(self, t_s: float) -> float:
        """Wall seconds until the paced clock reaches ``t_s`` (0: reached, or event-driven)."""
        if self.pace is None:
            return 0.0
        return max(0.0, (t_s - self.paced_now()) / self.pace)

    def catch_up(self) -> None:
        """Run the world up to the paced clock (nothing when event-driven or already there).
        Not bounded by ``MAX_ADVANCE_S``: the span is the wall's, not a request's."""
        if self.pace is not None:
            t_s = self.paced_now()
            if t_s > self.now:
                self._run_to(t_s)

    def sleep_until(self, t_s: float) -> None:
        """The plain wait for the wall: this thread sleeps until the paced clock reaches ``t_s``."""
        while (delay_s := self.wall_delay(t_s)) > 0:
            time.sleep(delay_s)

    # -- the clock --------------------------------------------------------------------
    def advance(self, dt_s: float) -> None:
        """Advance simulated time by ``dt_s`` seconds (0 ≤ dt ≤ one year)."""
        if not np.isfinite(dt_s) or dt_s < 0 or dt_s > MAX_ADVANCE_S:
            raise ValueError(f"advance of {dt_s!r} s is outside 0..{MAX_ADVANCE_S:g} s")
        self.advance_to(self.now + dt_s)

    def advance_to(self, t_s: float) -> None:
        """Run events and activities in time order up to and including ``t_s``.

        Paced, a time ahead of the paced clock is waited for first (:attr:`wait_for_wall`),
        so the world never runs ahead of the wall; meanwhile the server may run the world on,
        to ``t_s`` or past it (then there is nothing left to do).
        """
        if not np.isfinite(t_s) or t_s < self.now:
            raise ValueError(f"cannot advance to {t_s!r} s: it is before now ({self.now} s)")
        if t_s - self.now > MAX_ADVANCE_S:
            raise ValueError(f"advance to {t_s} s exceeds the {MAX_ADVANCE_S:g} s limit")
        if self.pace is not None and t_s > self.paced_now():
            self.catch_up()
            self.wait_for_wall(t_s)
            if t_s <= self.now:
                return
        self._run_to(t_s)

    def _run_to(self, t_s: float) -> None:
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
