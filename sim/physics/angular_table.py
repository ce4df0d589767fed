"""Angular vibration table: its motion over time as a list of :class:`MotionPiece`.

The table rotates about one axis.  Its motion is a time-ordered list of pieces
(``sim.physics.angular_piece``), each a sum of sinusoids with linear envelopes, planned
by the commands below.  Commands apply at their time (the World's ``now``) and never
change the past: the piece containing the command's time is cut there and the future is
planned afresh from the state at that instant (amplitude, phase and angle of every
component), so rate and angle are continuous across every piece boundary.

Timeline conventions
    * Before the first command the table is at rest at angle 0 from :data:`REST_SINCE_S`
      (−10⁹ s, "−∞" in practice): times before 0 are valid and give rest.
    * A tone's phase φ is its phase at the start of the ramp that brings it in.
    * Ramps are linear in amplitude.  Each tone ramps over the ramp time rounded *up* to a
      whole number of its own periods: the integral of a linearly ramped sine over whole
      periods leaves the mean angle unchanged, so the table oscillates about the angle it
      rested at and comes back to it after a stop (a 0.1 Hz tone ramps over ≥ 10 s).
    * A new demand while running ramps the old tones down (each over its whole periods),
      then the new tones up — no cross-fade, so old and new never add up beyond a limit.
    * ``stop`` ramps down to rest; ``abort`` (also an opened interlock) cuts every
      component to zero linearly over :data:`ABORT_DECAY_S` (10 ms), leaving the table
      wherever it is; the state latches ABORT until :meth:`AngularMotion.reset_abort`.
    * A sweep ramps up at its start frequency, then runs phase-continuous pieces of
      constant frequency, one per controller update (``update_s``, 10 ms), each at the
      sweep law's frequency at the piece's midpoint, then ramps down at the last piece's
      frequency and rests (IDLE).

Harmonic distortion: every fundamental f of amplitude A comes with components 2f and 3f
of amplitudes d₂·A and d₃·A (default 0.3 % and 0.1 %) whose phases are 2θ + ψ₂ and
3θ + ψ₃ (θ the fundamental's phase; ψ drawn once from ``rng``, or fixed without one) —
what the table's reference encoder sees.  ``distortion=(0.0, 0.0)`` gives pure tones.
The limits are checked on the demand (the fundamentals); the distortion adds at most
d₂ + d₃ (0.4 %) to the rate, 2d₂ + 3d₃ (0.9 %) to the acceleration, and a ramp's envelope
slope adds at most A/T_ramp to a tone's acceleration (≤ 1/(2π) of A·2πf, since T_ramp is at
least one period) — the rated limits apply to demands, as on a real controller.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import replace

import numpy as np

from sim.physics.angular_demand import AngularTableLimits, Sweep, Tone
from sim.physics.angular_kernel import angle_base, evaluate
from sim.physics.angular_piece import MotionPiece, at_rest

#: time for the motion to die away after an abort or an opened interlock (s)
ABORT_DECAY_S = 0.01
DEFAULT_RAMP_S = 1.0
RAMP_RANGE_S = (0.01, 60.0)
#: controller update interval of a sweep (s): one constant-frequency piece each
DEFAULT_UPDATE_S = 0.01
#: relative rate amplitudes of the 2nd and 3rd harmonic
DEFAULT_DISTORTION = (0.003, 0.001)
#: the rest the timeline starts with ("−∞")
REST_SINCE_S = -1.0e9
#: harmonic phase offsets (rad) when no rng is given
FIXED_HARMONIC_PHASES_RAD = (0.7, 2.1)

IDLE, RAMP, RUN, ABORT = "IDLE", "RAMP", "RUN", "ABORT"
SINE, MULTI, SWEEP = "SINE", "MULTI", "SWEEP"


class AngularMotion:
    """Demands, ramps and state of one angular vibration table; its motion over time."""

    def __init__(self, limits: AngularTableLimits | None = None, rng: np.random.Generator | None = None,
                 distortion: tuple[float, float] = DEFAULT_DISTORTION,
                 update_s: float = DEFAULT_UPDATE_S) -> None:
        d = tuple(float(x) for x in distortion)
        if len(d) != 2 or not all(0.0 <= x <= 0.1 for x in d):
            raise ValueError(f"distortion = {distortion!r}: two relative amplitudes in 0..0.1")
        if not 1e-4 <= update_s <= 0.1:
            raise ValueError(f"update_s = {update_s!r} s not in 0.0001..0.1 s")
        self.limits = limits or AngularTableLimits()
        self.distortion = d
        self.harmonic_phase_rad = (tuple(float(x) for x in rng.uniform(0, 2 * math.pi, 2))
                                   if rng is not None else FIXED_HARMONIC_PHASES_RAD)
        self.update_s = float(update_s)
        self.ramp_s = DEFAULT_RAMP_S
        self.mode: str | None = None  # SINE, MULTI or SWEEP of the last demand started
        self._pieces: list[MotionPiece] = [at_rest(REST_SINCE_S)]
        self._starts: list[float] = [REST_SINCE_S]
        self._labels: list[str] = [IDLE]
        self._fund: list[np.ndarray] = [np.zeros(0)]  # fundamental of each component (Hz)
        self._abort_t: float | None = None
        self._t_last = -math.inf
        self._cache = None

    # ---- checks ------------------------------------------------------------------------
    def check_tones(self, tones) -> list[Tone]:
        tones = list(tones)
        problem = self.limits.violation(tones)
        if problem:
            raise ValueError(problem)
        return tones

    def check_sweep(self, sweep: Sweep) -> Sweep:
        problem = self.limits.sweep_violation(sweep)
        if problem:
            raise ValueError(problem)
        return sweep

    def set_ramp(self, ramp_s: float) -> None:
        lo, hi = RAMP_RANGE_S
        if not (isinstance(ramp_s, (int, float)) and lo <= ramp_s <= hi):
            raise ValueError(f"ramp {ramp_s!r} s not in {lo:g}..{hi:g} s")
        self.ramp_s = float(ramp_s)

    # ---- commands ----------------------------------------------------------------------
    def start_tones(self, t_s: float, tones) -> None:
        """Run ``tones`` (a SINE dwell when one, MULTI otherwise); while running, the old
        demand ramps down first.  ValueError naming a limit the tones break."""
        tones = self.check_tones(tones)
        t = self._command_time(t_s, start=True)
        freq, amp, phase, fund = self._components([(x.rate_amplitude_rad_s, x.freq_hz, x.phase_rad) for x in tones])
        t, angle = self._ramp_down_then(t)
        t, _, phase, angle = self._ramp(t, freq, np.zeros_like(amp), amp, phase, fund, angle,
                                        self._ramp_times(fund))
        keep = amp != 0  # a tone of zero amplitude is no motion
        self._append(MotionPiece(t, math.inf, freq[keep], amp[keep], np.zeros(int(keep.sum())), phase[keep], angle),
                     RUN, fund[keep])
        self.mode = SINE if len(tones) == 1 else MULTI

    def start_sweep(self, t_s: float, sweep: Sweep) -> None:
        """Run ``sweep``; IDLE again after its ramp-down.  ValueError if any frequency in it
        breaks a limit."""
        self.check_sweep(sweep)
        t = self._command_time(t_s, start=True)
        t, angle = self._ramp_down_then(t)
        a = sweep.rate_amplitude_rad_s
        freq, amp, phase, fund = self._components([(a, sweep.start_hz, 0.0)])
        t, _, theta_all, angle = self._ramp(t, freq, np.zeros_like(amp), amp, phase, fund, angle,
                                            self._ramp_times(fund))
        t0 = t
        for piece, fund in self._sweep_pieces(t0, sweep, float(theta_all[0]), angle):
            self._append(piece, RUN, fund)
        angle = float(self._pieces[-1].angle_rad(np.array([self._pieces[-1].t_end_s]))[0])
        last = self._pieces[-1]
        freq, amp, phase, fund = last.freq_hz, last.alpha_rad_s, last.end_state()[1], self._fund[-1]
        t, _, _, angle = self._ramp(t0 + sweep.duration_s, freq, amp, np.zeros_like(amp), phase, fund, angle,
                                    self._ramp_times(fund))
        self._append(at_rest(t, math.inf, angle), IDLE, np.zeros(0))
        self.mode = SWEEP

    def _sweep_pieces(self, t0: float, sweep: Sweep, theta0: float, angle0: float):
        """The sweep's constant-frequency pieces, one per update; phases and angles chained
        in closed form (vectorised: a 1000 s sweep is 10⁵ pieces)."""
        edges = np.unique(np.minimum(  # unique: no empty last piece when rounding lands on the end
            np.arange(math.ceil(sweep.duration_s / self.update_s - 1e-9) + 1) * self.update_s, sweep.duration_s))
        dur = np.diff(edges)
        f = np.asarray(sweep.freq_at(0.5 * (edges[:-1] + edges[1:])), dtype=float)
        theta = theta0 + 2 * np.pi * np.concatenate([[0.0], np.cumsum(f * dur)[:-1]])  # fundamental phase
        orders = [1] + [k for k, d in zip((2, 3), self.distortion) if d > 0]
        rel = [1.0] + [d for d in self.distortion if d > 0]
        psi = [0.0] + [p for p, d in zip(self.harmonic_phase_rad, self.distortion) if d > 0]
        n = np.array(orders, dtype=float)
        freq = f[:, None] * n                                              # (pieces, components)
        phase = np.mod(theta[:, None] * n + np.array(psi), 2 * np.pi)
        amp = sweep.rate_amplitude_rad_s * np.array(rel)
        w = 2 * np.pi * freq
        # ∫ over a piece of A sin(wτ + φ) = A (cos φ − cos(w d + φ)) / w
        gain = np.sum(amp * (np.cos(phase) - np.cos(w * dur[:, None] + phase)) / w, axis=1)
        angles = angle0 + np.concatenate([[0.0], np.cumsum(gain)[:-1]])
        zeros = np.zeros(len(orders))
        for k in range(dur.size):
            yield (MotionPiece(t0 + edges[k], t0 + edges[k + 1], freq[k], amp, zeros, phase[k], float(angles[k])),
                   np.full(len(orders), f[k]))

    def stop(self, t_s: float) -> None:
        """Ramp down to rest (each tone over whole periods); nothing to do at rest."""
        t = self._command_time(t_s)
        if self._moving_from(t) and not self.aborted:  # an abort already brings it to rest, faster
            t, angle = self._ramp_down_then(t)
            self._append(at_rest(t, math.inf, angle), IDLE, np.zeros(0))

    def abort(self, t_s: float) -> None:
        """Cut the drive now: every component to zero over :data:`ABORT_DECAY_S`; ABORT latches."""
        t = self._command_time(t_s)
        if self._moving_from(t) and not self.aborted:
            freq, amp, phase, fund, angle = self._cut(t)
            t, _, _, angle = self._ramp(t, freq, amp, np.zeros_like(amp), phase, fund, angle,
                                        np.full(amp.size, ABORT_DECAY_S))
            self._append(at_rest(t, math.inf, angle), IDLE, np.zeros(0))
        if self._abort_t is None:
            self._abort_t = float(t_s)

    def reset_abort(self, t_s: float) -> None:
        t = self._command_time(t_s)
        if self._abort_t is not None and self._moving_from(t):
            raise RuntimeError("table still decaying; reset after it reached rest")
        self._abort_t = None

    # ---- state -------------------------------------------------------------------------
    @property
    def aborted(self) -> bool:
        return self._abort_t is not None

    @property
    def driving(self) -> bool:
        """The plan ends in motion (started and neither stopped nor a finished sweep)."""
        return self._labels[-1] != IDLE

    def state(self, t_s: float) -> str:
        """IDLE (at rest), RAMP (amplitudes changing), RUN (dwell, multi-tone or sweeping) or
        ABORT (latched from the abort until :meth:`reset_abort`)."""
        if self._abort_t is not None and t_s >= self._abort_t:
            return ABORT
        return self._labels[self._index(t_s)]

    def at_rest(self, t_s: float) -> bool:
        """No motion at ``t_s`` and none planned after it."""
        return not self._moving_from(t_s)

    # ---- the motion --------------------------------------------------------------------
    def pieces(self, t0_s: float, t1_s: float) -> list[MotionPiece]:
        """Pieces overlapping [t0, t1] in time order (the one containing t0 first)."""
        if not t1_s >= t0_s:
            raise ValueError(f"window [{t0_s!r}, {t1_s!r}] s must have t0 ≤ t1")
        i0 = self._index(t0_s)
        i1 = bisect.bisect_right(self._starts, t1_s)
        return self._pieces[i0:max(i1, i0 + 1)]

    def rate_rad_s(self, t_s) -> np.ndarray:
        return self.motion(t_s)[0]

    def angle_rad(self, t_s) -> np.ndarray:
        return self.motion(t_s)[1]

    def accel_rad_s2(self, t_s) -> np.ndarray:
        return self.motion(t_s)[2]

    # ---- planning ----------------------------------------------------------------------
    def _command_time(self, t_s: float, start: bool = False) -> float:
        t = float(t_s)
        if not (math.isfinite(t) and t >= self._t_last):
            raise ValueError(f"t_s = {t_s!r} must be finite and ≥ the last command's time {self._t_last!r} s")
        if start and self.aborted:
            raise RuntimeError("aborted: reset the interlock first")
        self._t_last = t
        return t

    def _index(self, t_s: float) -> int:
        return max(0, bisect.bisect_right(self._starts, float(t_s)) - 1)

    def _moving_from(self, t: float) -> bool:
        i = self._index(t)
        return any(p.n for p in self._pieces[i:])

    def _components(self, tones, theta: float | None = None):
        """(freq, amp, phase, fund) arrays of fundamentals and their harmonics; ``theta``
        overrides the (single) fundamental's phase (sweeps)."""
        rows = []
        for a, f, ph in tones:
            ph = ph if theta is None else theta
            rows.append((f, a, ph, f))
            for k, (d, psi) in enumerate(zip(self.distortion, self.harmonic_phase_rad), start=2):
                if d > 0:
                    rows.append((k * f, d * a, (k * ph + psi) % (2 * math.pi), f))
        freq, amp, phase, fund = (np.array(c, dtype=float) for c in zip(*rows))
        return freq, amp, phase, fund

    def _ramp_times(self, fund: np.ndarray) -> np.ndarray:
        """The ramp time rounded up to whole periods of each component's fundamental."""
        return np.ceil(self.ramp_s * fund - 1e-9) / fund

    def _cut(self, t: float):
        """Forget the plan from ``t`` on; (freq, amp, phase, fund, angle) at ``t``."""
        i = self._index(t)
        p, fund, label = self._pieces[i], self._fund[i], self._labels[i]
        del self._pieces[i:], self._starts[i:], self._labels[i:], self._fund[i:]
        self._cache = None
        if p.t_start_s == t:
            amp, phase, angle = p.alpha_rad_s, p.phase_rad, p.angle0_rad
        else:
            p = replace(p, t_end_s=t)
            self._append(p, label, fund)
            amp, phase, angle = p.end_state()
        keep = amp != 0
        return p.freq_hz[keep], amp[keep], phase[keep], fund[keep], angle

    def _append(self, piece: MotionPiece, label: str, fund: np.ndarray) -> None:
        self._pieces.append(piece)
        self._starts.append(piece.t_start_s)
        self._labels.append(label)
        self._fund.append(fund)
        self._cache = None

    def _ramp_down_then(self, t: float) -> tuple[float, float]:
        """Ramp what moves at ``t`` down to zero; (time it is at rest, angle there)."""
        freq, amp, phase, fund, angle = self._cut(t)
        if amp.size:
            t, _, _, angle = self._ramp(t, freq, amp, np.zeros_like(amp), phase, fund, angle, self._ramp_times(fund))
        return t, angle

    def _ramp(self, t, freq, amp0, amp1, phase, fund, angle, durations):
        """Pieces taking each component linearly from ``amp0`` to ``amp1`` over its own
        ``durations`` from ``t``; a piece boundary at every distinct end.  Returns (end time,
        amplitudes, phases, angle) at the last end."""
        ends = t + durations
        amp, phase = amp0.astype(float), phase.astype(float)
        slope = (amp1 - amp0) / durations
        cur = t
        for b in sorted(set(ends.tolist())):
            ramping = ends > cur
            keep = ramping | (amp != 0)
            piece = MotionPiece(cur, b, freq[keep], amp[keep], np.where(ramping, slope, 0.0)[keep], phase[keep], angle)
            self._append(piece, RAMP, fund[keep])
            a_end, ph_end, angle = piece.end_state()
            amp[keep], phase[keep] = a_end, ph_end
            done = ends <= b
            amp[done] = amp1[done]  # exactly the target, no rounding residue
            cur = b
        return cur, amp, phase, angle

    # ---- evaluation --------------------------------------------------------------------
    def motion(self, t_s) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(rate rad/s, angle rad, acceleration rad/s²) at times ``t_s`` (any shape), in one pass."""
        t = np.asarray(t_s, dtype=float)
        flat = np.ascontiguousarray(t.reshape(-1))
        r, a, c = evaluate(flat, *self._tables())
        return r.reshape(t.shape), a.reshape(t.shape), c.reshape(t.shape)

    def _tables(self):
        """Per-piece parameters padded to the widest piece, for the compiled kernel."""
        if self._cache is None:
            n, m = len(self._pieces), max(1, max(p.n for p in self._pieces))
            f = np.ones((n, m))
            a, b, ph = np.zeros((n, m)), np.zeros((n, m)), np.zeros((n, m))
            for i, p in enumerate(self._pieces):
                f[i, :p.n], a[i, :p.n], b[i, :p.n], ph[i, :p.n] = p.freq_hz, p.alpha_rad_s, p.beta_rad_s2, p.phase_rad
            base = angle_base(np.array([p.angle0_rad for p in self._pieces]), f, a, b, ph)
            self._cache = (np.array(self._starts), np.array([p.n for p in self._pieces], dtype=np.int64),
                           f, a, b, ph, base)
        return self._cache


__all__ = ["ABORT", "ABORT_DECAY_S", "AngularMotion", "AngularTableLimits", "DEFAULT_DISTORTION",
           "DEFAULT_RAMP_S", "DEFAULT_UPDATE_S", "IDLE", "MULTI", "RAMP", "RAMP_RANGE_S", "REST_SINCE_S", "RUN",
           "SINE", "SWEEP", "Sweep", "Tone"]
