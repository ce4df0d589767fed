"""The air of a temperature test chamber, on the virtual clock, in closed form.

Conditioning on (the controller's loop in Auto, the limit not tripped, power on):

1. the *demand* r(t) moves from where it is toward the set point in a straight line, at the
   user's ramp rate when the controller ramps, never faster than the plant can heat
   (``heat_rate_c_per_min``) or cool (``cool_rate_c_per_min``); it stops at the set point;
2. the air follows the demand as a closed loop of second order,
   T̈ = ω²(r − T) − 2ζω Ṫ  (ω = 2π/``loop_period_s``, ζ = ``loop_damping``):
   it lags a ramp by 2ζ/ω·ṙ and overshoots where the ramp ends, then settles.

Conditioning off (standby, a tripped limit, power off): the air relaxes toward the lab's
ambient with the insulated box's time constant ``standby_tau_s``.

Both are linear systems driven by a polynomial of degree ≤ 1 between events, so the air is
an exact exponential polynomial per segment (``sim.physics.thermal_lti``); segments start
at each change of demand and where a ramp reaches its set point (a world event).  Each new
segment is announced to ``listeners`` (the units inside, ``sim.physics.thermal_unit``) with
its start time.  The state (T, Ṫ) is continuous across every change.

Figures of the default chamber (assumed, a mid-size single-stage rate-table chamber with a
cascade refrigeration unit): −70 … +180 °C, heating 4 °C/min, cooling 2.5 °C/min, loop
period 420 s, damping 0.5: the air lags a full-rate heating ramp by 4.5 °C, overshoots the
set point by 1.3 °C where it ends and is inside ±0.1 °C about 8 min later; 45 min standby
time constant.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from sim.physics.thermal_lti import ExpPoly, LinearBlock, evaluate_segments


class Scheduler(Protocol):
    """What the air needs of the world: events at simulated instants."""

    now: float

    def schedule(self, t_s: float, callback: Callable[[], None], name: str = "") -> Any: ...

    def cancel(self, event: Any) -> None: ...


@dataclass(frozen=True)
class ChamberParams:
    """The chamber's plant and loop (°C, s)."""

    lab_ambient_c: float = 23.0
    min_c: float = -70.0
    max_c: float = 180.0
    heat_rate_c_per_min: float = 4.0
    cool_rate_c_per_min: float = 2.5
    loop_period_s: float = 420.0
    loop_damping: float = 0.5
    standby_tau_s: float = 2700.0

    def __post_init__(self) -> None:
        checks = {"lab_ambient_c": (-40.0, 60.0), "min_c": (-200.0, 100.0), "max_c": (0.0, 500.0),
                  "heat_rate_c_per_min": (0.01, 100.0), "cool_rate_c_per_min": (0.01, 100.0),
                  "loop_period_s": (1.0, 1e4), "loop_damping": (0.05, 0.95), "standby_tau_s": (1.0, 1e6)}
        for name, (lo, hi) in checks.items():
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not lo <= v <= hi:
                raise ValueError(f"{name}={v!r} outside the allowed range [{lo}, {hi}]")
        if not self.min_c < self.lab_ambient_c < self.max_c:
            raise ValueError(f"lab_ambient_c={self.lab_ambient_c!r} must lie in min_c..max_c "
                             f"({self.min_c}..{self.max_c})")

    @property
    def omega_rad_s(self) -> float:
        return 2.0 * math.pi / self.loop_period_s

    def ramp_lag_c(self, rate_c_per_s: float) -> float:
        """Steady lag of the air behind a demand ramping at ``rate_c_per_s``."""
        return 2.0 * self.loop_damping / self.omega_rad_s * rate_c_per_s


class ChamberAir:
    """The chamber air temperature (an :class:`sim.physics.thermal_unit.AmbientSource`)."""

    def __init__(self, world: Scheduler, params: ChamberParams | None = None) -> None:
        self.world = world
        self.params = p = params or ChamberParams()
        w, z = p.omega_rad_s, p.loop_damping
        self._loop = LinearBlock(np.array([[0.0, 1.0], [-w * w, -2.0 * z * w]]), np.array([[0.0], [w * w]]))
        self._idle = LinearBlock(np.eye(2) * (-1.0 / p.standby_tau_s), np.array([[1.0 / p.standby_tau_s], [0.0]]))
        self.listeners: list[Callable[[float], None]] = []
        t0 = float(world.now)
        self._starts: list[float] = [t0]
        self._signals: list[ExpPoly] = [ExpPoly.constant(t0, [p.lab_ambient_c, 0.0])]
        self._starts_arr = np.asarray(self._starts)
        self.conditioning = False
        self._demand = ExpPoly.constant(t0, [p.lab_ambient_c])  # r(t) of the current segment
        self._target_c = p.lab_ambient_c
        self._ramp_end_s = t0
        self._ramp_event: Any = None

    # -- control -------------------------------------------------------------------------------
    def command(self, conditioning: bool, target_c: float, ramp_c_per_min: float | None) -> None:
        """The controller's demand from now on: conditioning on/off, set point, user ramp rate
        (None: step the set point; the plant's rate limits still apply)."""
        t = float(self.world.now)
        p = self.params
        target = float(np.clip(target_c, p.min_c, p.max_c))
        if self._ramp_event is not None:
            self.world.cancel(self._ramp_event)
            self._ramp_event = None
        state = self._signals[-1].value(t)
        if not conditioning:
            self.conditioning = False
            self._target_c = target
            self._ramp_end_s = t
            self._start(t, self._idle.respond(state, ExpPoly.constant(t, [p.lab_ambient_c])), None)
            return
        r0 = float(self.reference_c(t)) if self.conditioning else float(state[0])
        self.conditioning, self._target_c = True, target
        cap = p.heat_rate_c_per_min if target >= r0 else p.cool_rate_c_per_min
        rate = cap if ramp_c_per_min is None else min(cap, float(ramp_c_per_min))
        rate_s = math.copysign(rate / 60.0, target - r0)
        duration = abs(target - r0) / abs(rate_s) if target != r0 else 0.0
        if duration > 0.0:
            demand = ExpPoly.ramp(t, [r0], [rate_s])
            self._ramp_end_s = t + duration
            self._ramp_event = self.world.schedule(self._ramp_end_s, self._ramp_done, name="chamber ramp end")
        else:
            demand = ExpPoly.constant(t, [target])
            self._ramp_end_s = t
        self._start(t, self._loop.respond(state, demand), demand)

    def _ramp_done(self) -> None:
        self._ramp_event = None
        t = float(self.world.now)
        state = self._signals[-1].value(t)
        demand = ExpPoly.constant(t, [self._target_c])
        self._start(t, self._loop.respond(state, demand), demand)

    def _start(self, t: float, signal: ExpPoly, demand: ExpPoly | None) -> None:
        if self._starts[-1] == t:
            self._signals[-1] = signal
        else:
            self._starts.append(t)
            self._signals.append(signal)
            self._starts_arr = np.asarray(self._starts)
        self._demand = demand if demand is not None else ExpPoly.constant(t, [float(signal.value(t)[0])])
        for listener in list(self.listeners):
            listener(t)

    # -- queries --------------------------------------------------------------------------------
    def air_c(self, t) -> np.ndarray:
        """Air temperature (°C) at times ``t`` (any time from the chamber's creation on)."""
        return evaluate_segments(self._starts_arr, self._signals, t)[:, 0]

    def air_rate_c_per_s(self, t) -> np.ndarray:
        return evaluate_segments(self._starts_arr, self._signals, t, derivative=True)[:, 0]

    def signal_from(self, t_s: float) -> ExpPoly:
        """The air temperature from ``t_s`` on, until the next change (for the units inside)."""
        i = int(np.searchsorted(self._starts_arr, t_s, side="right")) - 1
        return self._signals[max(i, 0)].row(0).rebased(t_s)

    def reference_c(self, t: float) -> float:
        """The demand r(t) now (conditioning on), else the air temperature."""
        if not self.conditioning:
            return float(self.air_c(t)[0])
        return float(np.clip(self._demand.value(t)[0], min(self._demand.c0[0], self._target_c),
                             max(self._demand.c0[0], self._target_c)))

    @property
    def target_c(self) -> float:
        return self._target_c

    @property
    def ramp_end_s(self) -> float:
        """When the demand reaches the set point (≤ now: it is there)."""
        return self._ramp_end_s

    @property
    def segment_start_s(self) -> float:
        return self._starts[-1]

    def first_crossing(self, level_c: float, above: bool, t_from: float, horizon_s: float) -> float | None:
        """The first time in [t_from, t_from + horizon_s] at which the current segment's air
        crosses ``level_c`` upward (``above``) or downward, else None (a scan, then bisection).
        A ramp's segment is valid only until the ramp ends: the scan stops there (the next
        segment is scanned when it starts)."""
        sig = self._signals[-1]
        if self._ramp_end_s > t_from:
            horizon_s = min(horizon_s, self._ramp_end_s - t_from)
        n = 2048
        ts = t_from + np.linspace(0.0, horizon_s, n + 1)
        vals = sig.at(ts)[:, 0] - level_c
        bad = vals > 0 if above else vals < 0
        if not bad.any():
            return None
        k = int(np.argmax(bad))
        if k == 0:
            return float(ts[0])
        lo, hi = ts[k - 1], ts[k]
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            v = sig.value(mid)[0] - level_c
            if (v > 0) if above else (v < 0):
                hi = mid
            else:
                lo = mid
        return float(hi)
