"""Dual-axis turntable kinematics: trapezoidal servo axes and the platform attitude.

Each axis follows a *demand profile* r(t) (time-optimal trapezoid, rate ramp or coast)
through a second-order servo loop, so the platform position is p(t) = r(t) + e(t).
The servo loop is a PD position loop with velocity feed-forward (no acceleration
feed-forward), natural frequency ωn and damping ζ; its error obeys
``ë + 2ζωn ė + ωn² e = -r̈``. Because r̈ is piecewise constant, e(t) is exact and cheap:
a constant lag ``-r̈/ωn²`` plus one damped oscillation per acceleration step ("kick").
Consequences (defaults ωn = 2π·10 Hz, ζ = 0.5), all continuous in position, rate and
acceleration:
- the platform trails the demand by a/ωn² while accelerating at a and runs ahead of it
  while braking, so a move ends a/ωn² past the target (5 mdeg at 20 °/s²), then rings
  back (undershoot 0.8 mdeg) with envelope exp(-ζωn t); ``in_position`` is true once that
  envelope is below the tolerance (1 mdeg) and a dwell (0.05 s) has passed: settling
  takes ln(envelope/tolerance)/(ζωn) + dwell ≈ 0.11 s after a 20 °/s² move (see
  ``settle_time_s``);
- the user limits bound the *demand* (``demand_profile``); the platform's response
  (2ζωn s + ωn²)/(s² + 2ζωn s + ωn²) overshoots acceleration steps by ~30 % and the rate
  limit by ~0.55·a/ωn (0.17 °/s at 20 °/s²), as a real servo does.
OFF disables the drive: the axis coasts to rest at a constant (Coulomb) friction
deceleration and the servo error is gone. Angles in degrees, never wrapped.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from sim.physics.gravity import STANDARD_GRAVITY_MPS2, earth_rate_enu_rps

MODES = ("OFF", "POS", "RATE")
_NEGLIGIBLE_DEG = 1e-15  # servo ringing below this is not evaluated (speed only)


def wrap_deg(angle_deg):
    """Wrap angles to (-180, 180] degrees, for display only."""
    wrapped = 180.0 - np.mod(180.0 - np.asarray(angle_deg, dtype=float), 360.0)
    return wrapped if np.ndim(wrapped) else float(wrapped)


def _scalar_or_array(values: np.ndarray):
    """0-d results come back as Python scalars, arrays unchanged."""
    return values.item() if values.ndim == 0 else values


def _sign(x: float) -> float:
    return math.copysign(1.0, x) if x != 0 else 0.0


def move_phases(p0: float, v0: float, target: float, vmax: float, amax: float) -> list[tuple[float, float]]:
    """Time-optimal phases ``(duration_s, accel_dps2)`` taking (p0, v0) to rest at ``target``."""
    phases = []
    d = target - p0
    stop = v0 * abs(v0) / (2.0 * amax)  # signed distance needed to brake to rest
    # 1. Heading away from the target, or too fast to stop in time: brake to rest first.
    if v0 != 0.0 and (v0 * d < 0.0 or abs(stop) > abs(d)):
        phases.append((abs(v0) / amax, -_sign(v0) * amax))
        p0, v0, d = p0 + stop, 0.0, target - (p0 + stop)
    if d == 0.0:
        return phases
    s, u0, dist = _sign(d), abs(v0), abs(d)
    # 2. Peak speed of a triangle: accelerate from u0, brake to 0, covering dist.
    vpeak = math.sqrt(amax * dist + 0.5 * u0 * u0)
    if vpeak <= vmax:
        return phases + [((vpeak - u0) / amax, s * amax), (vpeak / amax, -s * amax)]
    # 3. Trapezoid: reach vmax (accelerating, or braking if above a lowered limit), cruise, brake.
    cruise = dist - abs(vmax**2 - u0**2) / (2.0 * amax) - vmax**2 / (2.0 * amax)
    return phases + [
        (abs(vmax - u0) / amax, s * amax * _sign(vmax - u0)),
        (max(cruise, 0.0) / vmax, 0.0),
        (vmax / amax, -s * amax),
    ]


def trapezoid_time_s(distance_deg: float, vmax: float, amax: float) -> float:
    """Closed-form duration of a rest-to-rest time-optimal move (reference for tests)."""
    d = abs(distance_deg)
    if d <= vmax**2 / amax:
        return 2.0 * math.sqrt(d / amax)  # triangular
    return d / vmax + vmax / amax  # trapezoidal


def _truncate(phases: list[tuple[float, float]], duration: float) -> list[tuple[float, float]]:
    """The first ``duration`` seconds of ``phases`` followed by an implicit cruise at a = 0."""
    kept = []
    for dur, acc in phases + [(math.inf, 0.0)]:
        kept.append((min(dur, duration), acc))
        duration -= dur
        if duration <= 0.0:
            break
    return kept


@dataclass
class _Plan:
    """Piecewise-constant-acceleration demand from ``tb[0]`` on, plus its servo error."""

    mode: str
    tb: np.ndarray  # segment start times; the last segment lasts forever with a = 0
    pb: np.ndarray
    vb: np.ndarray
    ab: np.ndarray
    kicks: list = field(default_factory=list)  # damped oscillations, see Axis._kick
    servo: bool = True
    demand: float = 0.0  # POS target (deg) or RATE demand (dps)
    t_done: float = math.inf  # in position / at rate
    t_limit: float = math.inf  # braking at a position limit started

    @property
    def t_end(self) -> float:
        return float(self.tb[-1])


class Axis:
    """One servo axis of the turntable; see the module docstring for the model.

    Hardware maxima ``rate_max_dps``/``accel_max_dps2`` bound the user limits; optional
    position limits ``lo_deg``/``hi_deg`` (None = unlimited, continuous rotation). In RATE
    mode the axis brakes at the user acceleration so as to stop exactly at a position
    limit (``limit_reached`` then true). POS targets outside the limits raise; OFF
    coasting is not limited (mechanical stops are not modelled). Commands come at
    non-decreasing times; evaluations at times ≥ the last command.
    """

    def __init__(self, rate_max_dps: float = 500.0, accel_max_dps2: float = 500.0,
                 lo_deg: float | None = None, hi_deg: float | None = None, *,
                 rate_limit_dps: float = 30.0, accel_limit_dps2: float = 20.0,
                 servo_natural_hz: float = 10.0, servo_damping: float = 0.5,
                 position_tolerance_deg: float = 1e-3, rate_tolerance_dps: float = 1e-3,
                 dwell_s: float = 0.05, friction_dps2: float = 2.0):
        for name, val in (("rate_max_dps", rate_max_dps), ("accel_max_dps2", accel_max_dps2),
                          ("servo_natural_hz", servo_natural_hz), ("friction_dps2", friction_dps2),
                          ("position_tolerance_deg", position_tolerance_deg),
                          ("rate_tolerance_dps", rate_tolerance_dps)):
            if not (math.isfinite(val) and val > 0.0):
                raise ValueError(f"{name}={val!r} must be finite and > 0")
        if not (0.0 < servo_damping < 1.0):
            raise ValueError(f"servo_damping={servo_damping!r} outside the allowed range (0, 1)")
        if not (0.0 <= dwell_s <= 60.0):
            raise ValueError(f"dwell_s={dwell_s!r} outside the allowed range [0, 60]")
        if lo_deg is not None and hi_deg is not None and not lo_deg < hi_deg:
            raise ValueError(f"position limits lo_deg={lo_deg!r} must be < hi_deg={hi_deg!r}")
        self.rate_max_dps, self.accel_max_dps2 = float(rate_max_dps), float(accel_max_dps2)
        self.lo_deg, self.hi_deg = lo_deg, hi_deg
        self.friction_dps2 = float(friction_dps2)
        self.position_tolerance_deg, self.rate_tolerance_dps = position_tolerance_deg, rate_tolerance_dps
        self.dwell_s = float(dwell_s)
        self._wn = 2.0 * math.pi * servo_natural_hz
        self._sigma = servo_damping * self._wn  # decay rate of the ringing, 1/s
        self._wd = self._wn * math.sqrt(1.0 - servo_damping**2)  # damped frequency, rad/s
        self.rate_limit_dps = self._check_limit("rate_limit_dps", rate_limit_dps, self.rate_max_dps)
        self.accel_limit_dps2 = self._check_limit("accel_limit_dps2", accel_limit_dps2, self.accel_max_dps2)
        self._plan = self._build("OFF", 0.0, 0.0, 0.0, [], 0.0, servo=False)
        self._last_target_deg = 0.0

    # ---- command interface -------------------------------------------------------
    @property
    def mode(self) -> str:
        return self._plan.mode

    @property
    def demand(self) -> float:
        """POS target in degrees or RATE demand in deg/s of the current plan."""
        return self._plan.demand

    @property
    def position_demand_deg(self) -> float:
        """Current POS target, or the last one while in another mode (0 initially)."""
        return self._plan.demand if self.mode == "POS" else self._last_target_deg

    @property
    def rate_demand_dps(self) -> float:
        """Current RATE demand; 0 outside RATE mode."""
        return self._plan.demand if self.mode == "RATE" else 0.0

    @property
    def position_limits_deg(self) -> tuple[float | None, float | None]:
        return self.lo_deg, self.hi_deg

    def command_hold(self, t_cmd: float) -> None:
        """Enter POS mode where the axis is: brake to rest and hold (same as ``stop``)."""
        self.stop(t_cmd)

    def command_rate_mode(self, t_cmd: float) -> None:
        """Enter RATE mode with a zero rate demand: the axis brakes to rest and waits."""
        self.command_rate(t_cmd, 0.0)

    def command_position(self, t_cmd: float, target_deg: float) -> None:
        """POS mode: time-optimal trapezoid from the current state to rest at ``target_deg``."""
        target = float(target_deg)
        lo = -math.inf if self.lo_deg is None else self.lo_deg
        hi = math.inf if self.hi_deg is None else self.hi_deg
        if not (math.isfinite(target) and lo <= target <= hi):
            raise ValueError(f"target_deg={target_deg!r} outside the allowed range [{lo}, {hi}]")
        self._move_to(t_cmd, target)

    def command_rate(self, t_cmd: float, rate_dps: float) -> None:
        """RATE mode: ramp the rate at the acceleration limit to ``rate_dps``, then hold it."""
        rate = float(rate_dps)
        if not (math.isfinite(rate) and abs(rate) <= self.rate_limit_dps):
            raise ValueError(f"rate_dps={rate_dps!r} outside the allowed range "
                             f"[{-self.rate_limit_dps}, {self.rate_limit_dps}]")
        t0, r, rd, e, ed = self._handover(t_cmd)
        a = self.accel_limit_dps2
        prefix, _, v_start = self._limit_brake_prefix(r, rd)
        phases = prefix + [(abs(rate - v_start) / a, _sign(rate - v_start) * a)]
        plan = self._build("RATE", t0, r, rd, phases, rate, e, ed, final_v=rate)
        t_brake = self._limit_brake_time(plan, first_segment=len(prefix))
        if math.isfinite(t_brake):  # keep the demand until t_brake, then stop at the limit
            v_brake = float(self._reference(plan, np.array([t_brake]))[1][0])
            phases = _truncate(phases, t_brake - t0) + [(abs(v_brake) / a, -_sign(v_brake) * a)]
            plan = self._build("RATE", t0, r, rd, phases, rate, e, ed, final_v=0.0)
        if math.isfinite(t_brake) or prefix:  # limit braking starts now (prefix) or at t_brake
            plan.t_done, plan.t_limit = math.inf, (t0 if prefix else t_brake)
        self._plan = plan

    def stop(self, t_cmd: float) -> None:
        """Brake to rest at the acceleration limit, then hold that position in POS mode."""
        t0, r, rd, e, ed = self._handover(t_cmd)
        a = self.accel_limit_dps2
        phases, final, _ = self._limit_brake_prefix(r, rd)
        if not phases:
            phases, final = [(abs(rd) / a, -_sign(rd) * a)], r + rd * abs(rd) / (2.0 * a)
        self._plan = self._build("POS", t0, r, rd, phases, final, e, ed, final_p=final, final_v=0.0)
        self._last_target_deg = final

    def command_off(self, t_cmd: float) -> None:
        """Disable the drive: coast from the actual state to rest at the friction deceleration."""
        t0, r, rd, e, ed = self._handover(t_cmd)
        p, v, f = r + e, rd + ed, self.friction_dps2
        self._plan = self._build("OFF", t0, p, v, [(abs(v) / f, -_sign(v) * f)], 0.0, servo=False, final_v=0.0)

    def set_rate_limit(self, t: float, rate_dps: float) -> None:
        """Set the user rate limit (≤ hardware maximum); a running move is re-planned at ``t``."""
        self.rate_limit_dps = self._check_limit("rate_limit_dps", rate_dps, self.rate_max_dps)
        if self.mode == "RATE" and abs(self.demand) > self.rate_limit_dps:
            self.command_rate(t, _sign(self.demand) * self.rate_limit_dps)  # clip the demand
        else:
            self._replan(t)

    def set_accel_limit(self, t: float, accel_dps2: float) -> None:
        """Set the user acceleration limit (≤ hardware maximum); a running move is re-planned."""
        self.accel_limit_dps2 = self._check_limit("accel_limit_dps2", accel_dps2, self.accel_max_dps2)
        self._replan(t)

    # ---- evaluation (vectorised over t) ----------------------------------------------
    def position_deg(self, t) -> np.ndarray:
        return self._evaluate(t, 0)

    def rate_dps(self, t) -> np.ndarray:
        return self._evaluate(t, 1)

    def accel_dps2(self, t) -> np.ndarray:
        return self._evaluate(t, 2)

    def demand_profile(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Demand (position deg, rate dps, accel dps2) the servo follows; limits bound these."""
        arr = self._times(t)
        pos, rate, acc = self._reference(self._plan, arr.reshape(-1))
        return pos.reshape(arr.shape), rate.reshape(arr.shape), acc.reshape(arr.shape)

    def in_position(self, t) -> np.ndarray:
        """POS mode and the settling envelope below tolerance for the dwell time."""
        return _scalar_or_array((self._times(t) >= self._plan.t_done) & (self.mode == "POS"))

    def at_rate(self, t) -> np.ndarray:
        """RATE mode, ramp done and rate error envelope below tolerance for the dwell."""
        return _scalar_or_array((self._times(t) >= self._plan.t_done) & (self.mode == "RATE"))

    def moving(self, t) -> np.ndarray:
        """The demand profile is still changing, or a constant rate is held."""
        return _scalar_or_array((self._times(t) < self._plan.t_end) | (self._plan.vb[-1] != 0.0))

    def limit_reached(self, t) -> np.ndarray:
        """Braking at a position limit has started (RATE mode)."""
        return _scalar_or_array(self._times(t) >= self._plan.t_limit)

    def at_rest_from_s(self) -> float:
        """Time from which the position no longer changes: the demand has ended at zero
        rate and every settling oscillation is below 1e-15° (inf while a rate is held)."""
        plan = self._plan
        if plan.vb[-1] != 0.0:
            return math.inf
        t_rest = plan.t_end
        for tk, _, horizon in plan.kicks:
            if horizon >= 0.0:
                t_rest = max(t_rest, tk + horizon)
        return t_rest

    @property
    def settle_time_s(self) -> float:
        """Time from the end of the current demand profile until in position / at rate."""
        return self._plan.t_done - self._plan.t_end

    # ---- internals ------------------------------------------------------------------
    @staticmethod
    def _check_limit(name: str, value: float, maximum: float) -> float:
        if not (math.isfinite(value) and 0.0 < value <= maximum):
            raise ValueError(f"{name}={value!r} outside the allowed range (0, {maximum}]")
        return float(value)

    def _times(self, t) -> np.ndarray:
        arr = np.asarray(t, dtype=float)
        if arr.size and not (np.all(np.isfinite(arr)) and np.min(arr) >= self._plan.tb[0]):
            raise ValueError(f"times must be finite and ≥ the last command at {self._plan.tb[0]!r} s")
        return arr

    def _handover(self, t_cmd: float):
        """Demand and servo-error state at the command time (continuity of p and v)."""
        t0 = float(self._times(np.array([t_cmd]))[0])
        r, rd, e, ed = self._state(self._plan, t0)  # e = ė = 0 after OFF: demand = actual
        return t0, r, rd, e, ed

    def _move_to(self, t_cmd: float, target: float) -> None:
        t0, r, rd, e, ed = self._handover(t_cmd)
        prefix, p_rest, v_rest = self._limit_brake_prefix(r, rd)
        p_from = p_rest if prefix else r
        phases = prefix + move_phases(p_from, v_rest, target, self.rate_limit_dps, self.accel_limit_dps2)
        self._plan = self._build("POS", t0, r, rd, phases, target, e, ed, final_p=target, final_v=0.0)
        self._last_target_deg = target

    def _limit_brake_prefix(self, r: float, rd: float):
        """Emergency brake if braking at the user limit would carry the demand past a position limit.

        Happens only after the user acceleration limit was lowered mid-move or after
        coasting (OFF) toward a limit: brake at the deceleration that stops exactly at
        the limit, capped at the hardware maximum. Returns (phases, rest position, rest rate);
        no phases and (None, rd) when the user limit suffices.
        """
        stop = r + rd * abs(rd) / (2.0 * self.accel_limit_dps2)
        for lim, s in ((self.hi_deg, 1.0), (self.lo_deg, -1.0)):
            if lim is None or s * rd <= 0.0 or s * stop <= s * lim:
                continue
            room = s * (lim - r)
            a_brake = min(rd * rd / (2.0 * room) if room > 0.0 else math.inf, self.accel_max_dps2)
            return [(abs(rd) / a_brake, -_sign(rd) * a_brake)], r + rd * abs(rd) / (2.0 * a_brake), 0.0
        return [], None, rd

    def _replan(self, t: float) -> None:
        t = float(self._times(np.array([t]))[0])
        if t >= self._plan.t_end or self.mode == "OFF":
            return  # nothing in progress: new limits only affect later moves
        if self.mode == "POS":
            self._move_to(t, self.demand)  # accepted earlier; may lie past a limit after coasting
        else:
            self.command_rate(t, self.demand)

    def _build(self, mode, t0, p0, v0, phases, demand, e0=0.0, ed0=0.0, *, servo=True,
               final_p=None, final_v=None) -> _Plan:
        # Integrate the constant-acceleration phases into segment start states.
        tb, pb, vb, ab = [t0], [p0], [v0], []
        for dur, acc in phases:
            if dur <= 0.0:
                continue
            ab.append(acc)
            tb.append(tb[-1] + dur)
            pb.append(pb[-1] + vb[-1] * dur + 0.5 * acc * dur * dur)
            vb.append(vb[-1] + acc * dur)
        ab.append(0.0)
        if len(ab) > 1:  # end exactly at the final rate and, for POS, exactly on target
            vb[-1] = vb[-1] if final_v is None else final_v
            pb[-1] = pb[-1] if final_p is None else final_p
        tb_a, pb_a, vb_a, ab_a = (np.array(x, dtype=float) for x in (tb, pb, vb, ab))
        plan = _Plan(mode, tb_a, pb_a, vb_a, ab_a, servo=servo, demand=demand)
        if servo:
            # The error is -r̈/ωn² + Σ kicks; the first kick makes it continuous at t0,
            # each acceleration step Δa adds a kick (Δa/ωn², 0).
            wn2 = self._wn**2
            plan.kicks.append(self._kick(t0, e0 + ab[0] / wn2, ed0))
            plan.kicks += [self._kick(tb[j], (ab[j] - ab[j - 1]) / wn2, 0.0) for j in range(1, len(ab))]
            _, _, e, ed = self._state(plan, plan.t_end)
            env = math.hypot(e, (ed + self._sigma * e) / self._wd)  # ringing amplitude after t_end
            tol = self.position_tolerance_deg if mode == "POS" else self.rate_tolerance_dps / self._wn
            plan.t_done = plan.t_end + max(0.0, math.log(env / tol) / self._sigma if env > 0 else 0.0) + self.dwell_s
        return plan

    def _kick(self, tk: float, x0: float, v0: float):
        """Damped oscillation e^{-στ}(A cos ωdτ + B sin ωdτ), value x0 and slope v0 at τ = 0.

        Returns (t_k, [(A, B) of the value and its 1st and 2nd derivatives], horizon_s):
        beyond the horizon the oscillation is below 1e-15 deg and is not evaluated.
        """
        sg, wd = self._sigma, self._wd
        coeffs = [(x0, (v0 + sg * x0) / wd)]
        for _ in range(2):  # d/dτ maps (A, B) to (ωd B − σA, −ωd A − σB)
            a, b = coeffs[-1]
            coeffs.append((wd * b - sg * a, -wd * a - sg * b))
        env = math.hypot(*coeffs[0])
        return (float(tk), coeffs, math.log(env / _NEGLIGIBLE_DEG) / sg if env > 0 else -1.0)

    @staticmethod
    def _reference(plan: _Plan, t: np.ndarray):
        """Demand (position, rate, acceleration) at times t."""
        idx = np.searchsorted(plan.tb, t, side="right") - 1
        dt = t - plan.tb[idx]
        a = plan.ab[idx]
        return plan.pb[idx] + plan.vb[idx] * dt + 0.5 * a * dt * dt, plan.vb[idx] + a * dt, a

    def _servo_error(self, plan: _Plan, t: np.ndarray, order: int, accel: np.ndarray) -> np.ndarray:
        """Servo error (order 0), its rate (1) or acceleration (2); ``accel`` = demand r̈(t)."""
        out = -accel / self._wn**2 if (plan.servo and order == 0) else np.zeros(t.shape)
        if not plan.servo:
            return out
        ordered = t.size < 2 or bool(np.all(t[1:] >= t[:-1]))
        for tk, coeffs, horizon in plan.kicks:
            if horizon < 0.0:
                continue
            sel: slice | np.ndarray
            if ordered:  # the usual case: slice the kick's window instead of masking
                lo, hi = np.searchsorted(t, tk, side="left"), np.searchsorted(t, tk + horizon, side="right")
                sel = slice(lo, hi)
            else:
                sel = np.flatnonzero((t >= tk) & (t <= tk + horizon))
            tau = t[sel] - tk
            if tau.size:
                a, b = coeffs[order]
                out[sel] += np.exp(-self._sigma * tau) * (a * np.cos(self._wd * tau) + b * np.sin(self._wd * tau))
        return out

    def _state(self, plan: _Plan, t: float):
        """Demand r, ṙ and servo error e, ė at one time."""
        arr = np.array([float(t)])
        r, rd, acc = self._reference(plan, arr)
        e, ed = (self._servo_error(plan, arr, k, acc)[0] for k in (0, 1))
        return float(r[0]), float(rd[0]), float(e), float(ed)

    def _evaluate(self, t, order: int) -> np.ndarray:
        arr = self._times(t)
        flat = arr.reshape(-1)
        ref = self._reference(self._plan, flat)
        return _scalar_or_array((ref[order] + self._servo_error(self._plan, flat, order, ref[2])).reshape(arr.shape))

    def _limit_brake_time(self, plan: _Plan, first_segment: int = 0) -> float:
        """First time the braking point r + ṙ|ṙ|/(2a) of the demand reaches a position limit."""
        amax, best = self.accel_limit_dps2, math.inf
        for lim, s in ((self.hi_deg, 1.0), (self.lo_deg, -1.0)):
            if lim is None:
                continue
            for j in range(first_segment, len(plan.tb)):
                # Mirror so the limit is "above"; the braking point rises while w > 0.
                q, w, b = s * plan.pb[j], s * plan.vb[j], s * plan.ab[j]
                dur = plan.tb[j + 1] - plan.tb[j] if j + 1 < len(plan.tb) else math.inf
                roots = np.roots([b / 2 + b * b / (2 * amax), w * (1 + b / amax), q + w * w / (2 * amax) - s * lim])
                if q + w * w / (2 * amax) >= s * lim and (w > 0 or (w == 0 and b > 0)):
                    roots = np.array([0.0])
                cands = [r.real for r in roots if abs(r.imag) < 1e-12 and 0 <= r.real <= dur and w + b * r.real >= 0]
                if cands:
                    best = min(best, plan.tb[j] + min(cands))
                    break
        return best


class DualAxisTable:
    """Inner axis 1 (about platform z) inside outer axis 2 (horizontal, about level x = East).

    Zero position: platform level, platform z up. The attitude is
    ``C = R_x(θ_outer) @ R_z(θ_inner)`` with ``v_level = C @ v_platform`` and the level
    frame East-North-Up (the outer axis is assumed aligned East). The sensor is taken to
    sit on the intersection of the axes: centripetal and tangential accelerations are
    ignored.
    """

    def __init__(self, inner: Axis | None = None, outer: Axis | None = None):
        self.inner = inner if inner is not None else Axis()
        self.outer = outer if outer is not None else Axis(rate_max_dps=200.0, accel_max_dps2=200.0)

    @property
    def axes(self) -> tuple[Axis, Axis]:
        """(axis 1 = inner, axis 2 = outer), indexed by controller number - 1."""
        return self.inner, self.outer

    def axis(self, number: int) -> Axis:
        """Axis by its controller number: 1 inner, 2 outer."""
        if number not in (1, 2):
            raise ValueError(f"axis number {number!r} outside the allowed values {{1, 2}}")
        return self.inner if number == 1 else self.outer

    def _trig(self, t: np.ndarray):
        i, o = np.radians(self.inner.position_deg(t)), np.radians(self.outer.position_deg(t))
        return np.cos(i), np.sin(i), np.cos(o), np.sin(o)

    @staticmethod
    def _rows(ci, si, co, so):
        # Rows of C = R_x(o) @ R_z(i), written out; each row is (n, 3).
        zero = np.zeros_like(ci)
        return (np.stack([ci, -si, zero], axis=1), np.stack([co * si, co * ci, -so], axis=1),
                np.stack([so * si, so * ci, co], axis=1))

    def platform_to_level(self, t) -> np.ndarray:
        """Rotation matrices C (n, 3, 3) with v_level = C @ v_platform."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        return np.stack(self._rows(*self._trig(t)), axis=1)

    def specific_force_platform_g(self, t, g_mps2: float) -> np.ndarray:
        """Specific force (n, 3) on the platform in standard-g units, magnitude g_local/g0.

        A body at rest feels the ground's reaction, +g along level Up: f_platform =
        Cᵀ (0, 0, g/g0), i.e. the third row of C. Stationary level platform: (0, 0, g/g0).
        """
        if not (math.isfinite(g_mps2) and 9.7 <= g_mps2 <= 9.9):
            raise ValueError(f"g_mps2={g_mps2!r} outside the allowed range [9.7, 9.9]")
        t = np.atleast_1d(np.asarray(t, dtype=float))
        scale = g_mps2 / STANDARD_GRAVITY_MPS2
        if t.size > 1 and t.min() >= max(self.inner.at_rest_from_s(), self.outer.at_rest_from_s()):
            # both axes at rest: one evaluation, repeated (long static traces cost O(1))
            ci, si, co, so = self._trig(t[:1])
            row = np.array([so[0] * si[0], so[0] * ci[0], co[0]]) * scale
            return np.broadcast_to(row, (t.size, 3))  # read-only view, rows share memory
        ci, si, co, so = self._trig(t)
        return np.stack([so * si, so * ci, co], axis=1) * scale

    def angular_rate_platform_dps(self, t, latitude_deg: float) -> np.ndarray:
        """Inertial angular rate of the platform in platform axes, deg/s, shape (n, 3).

        Gimbal part from Ċ = C [ω]×: ω = θ̇_outer R_z(θ_inner)ᵀ x̂ + θ̇_inner ẑ
        = (θ̇_o cos θ_i, -θ̇_o sin θ_i, θ̇_i); Earth part Cᵀ ω_ie(ENU) = Ω_N·row2 + Ω_U·row3
        of C (Ω_E = 0).
        """
        _, north, up = np.degrees(earth_rate_enu_rps(latitude_deg))
        t = np.atleast_1d(np.asarray(t, dtype=float))
        ci, si, co, so = self._trig(t)
        di, do = self.inner.rate_dps(t), self.outer.rate_dps(t)
        gimbal = np.stack([do * ci, -do * si, di], axis=1)
        _, row2, row3 = self._rows(ci, si, co, so)
        return gimbal + north * row2 + up * row3
