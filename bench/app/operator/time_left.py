"""How long a batch still takes, as the operator page shows it: steady, counting down.

The plan is in station seconds (each step's planned duration); the operator waits in wall
seconds.  The pace between the two is read from the run itself: the wall time spent so far
(time waiting at a prompt excluded) over the planned time done.  That raw estimate jumps as
the pace differs from step to step (a simulated station's waits take no wall time; a table
move overruns its plan), so what is shown is smoothed, and it never goes up within a batch:

- between two progress reports the raw estimate counts down one second a second;
- the shown value counts down one second a second and closes the gap to a lower raw
  estimate with the time constant :data:`TAU_S`; a higher raw estimate (the station fell
  behind) holds it where it is until the count-down meets it.

A new batch (a retest included) starts a new estimate.  Pure arithmetic: the caller passes
the times, so the functions are tested without a clock.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

#: the shown estimate closes the gap to a lower raw one with this time constant (s): a person
#: glancing at the page every few seconds sees it move by at most 1 − e^(−1/10) ≈ 10 % of the
#: gap a second beyond the count-down — never "84 s" then "5 s" — and a real change of pace is
#: shown within 3 τ = 30 s
TAU_S = 10.0
#: the pace is read once this fraction of the plan is done; before it, the wall time is mostly
#: the station opening, not its pace (a wall-clock station uses the plan itself until then)
MIN_FRACTION = 0.01


def raw_time_left(elapsed_s: float, done_s: float, total_s: float,
                  prior_wall_per_planned: float | None = None) -> float | None:
    """Wall seconds left at the pace so far: ``elapsed_s`` (wall) over ``done_s`` (planned)
    times the planned time left; before :data:`MIN_FRACTION` of the plan is done, the plan at
    ``prior_wall_per_planned`` (1.0 on a wall-clock station) less the time spent, or None
    (no estimate yet) without a prior."""
    if not total_s > 0 or not math.isfinite(total_s):
        return None
    done_s = min(max(done_s, 0.0), total_s)
    if done_s >= MIN_FRACTION * total_s and elapsed_s > 0:
        return elapsed_s / done_s * (total_s - done_s)
    if prior_wall_per_planned is None:
        return None
    return max(prior_wall_per_planned * total_s - elapsed_s, 0.0)


def next_shown(shown_s: float, dt_s: float, raw_s: float, tau_s: float = TAU_S) -> float:
    """The shown estimate ``dt_s`` later: counted down by ``dt_s``, then moved toward
    ``raw_s`` by the fraction 1 − e^(−dt/τ) of the gap; never above ``shown_s`` (a station
    behind its plan holds the count-down) nor below 0."""
    if not dt_s >= 0 or not tau_s > 0:
        raise ValueError(f"dt_s = {dt_s!r} must be ≥ 0 and tau_s = {tau_s!r} > 0")
    counted = max(shown_s - dt_s, 0.0)
    toward = counted + (1.0 - math.exp(-dt_s / tau_s)) * (raw_s - counted)
    return min(shown_s, max(toward, 0.0))


@dataclass
class TimeLeft:
    """One batch's time-left estimate: :meth:`report` at each progress report, :meth:`at`
    whenever the page asks.  Times are the batch's active wall seconds (prompts excluded)."""

    prior_wall_per_planned: float | None = None   # 1.0 on a wall-clock station, None if unknown
    tau_s: float = TAU_S
    shown_s: float | None = field(default=None, init=False)       # what the page shows
    _raw_s: float | None = field(default=None, init=False)        # the raw estimate at the last report ...
    _raw_at_s: float = field(default=0.0, init=False)             # ... and when it was made
    _shown_at_s: float = field(default=0.0, init=False)

    def report(self, elapsed_s: float, done_s: float, total_s: float) -> None:
        """A progress report: ``done_s`` of ``total_s`` planned seconds after ``elapsed_s``."""
        raw = raw_time_left(elapsed_s, done_s, total_s, self.prior_wall_per_planned)
        if raw is not None:
            self._raw_s, self._raw_at_s = raw, elapsed_s

    def at(self, elapsed_s: float) -> float | None:
        """The estimate to show at ``elapsed_s``: None until the first raw estimate."""
        if self._raw_s is None:
            return None
        raw = max(self._raw_s - max(elapsed_s - self._raw_at_s, 0.0), 0.0)
        if self.shown_s is None:
            self.shown_s, self._shown_at_s = raw, elapsed_s
            return raw
        dt = max(elapsed_s - self._shown_at_s, 0.0)
        self.shown_s, self._shown_at_s = next_shown(self.shown_s, dt, raw, self.tau_s), elapsed_s
        return self.shown_s


__all__ = ["TAU_S", "MIN_FRACTION", "raw_time_left", "next_shown", "TimeLeft"]
