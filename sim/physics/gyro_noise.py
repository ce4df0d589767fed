"""Slow bias noise of the FOG on a fixed knot grid: flicker (Gauss-Markov sum) + rate random walk.

The slow terms have correlation times of seconds to days, yet the gyro is evaluated at
frame rates of kHz. Drawing them per frame would cost one normal per term per frame;
instead they are simulated exactly at knots ``j·h`` of absolute time (h = τ_min/64) and
linearly interpolated to the requested times. Interpolation removes only their power
above ~1/(2h), where each term's PSD has fallen to under (h/τ)² of its low-frequency
level — orders of magnitude below the white angle noise there.

Determinism: knots are generated in index order from one generator, one row of draws
(one per term + one for the walk) per knot, so their values depend only on the knot
indices and the seed — not on how the times are split into calls, nor on the frame
rate. Between calls whose spans are not contiguous the process jumps exactly over the
gap (a single transition to the next needed knot), so that a long idle span costs nothing.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter

#: knot step as a fraction of the shortest correlation time
KNOT_STEPS_PER_TAU = 64


class KnotBias:
    """Σ Gauss-Markov(σᵢ, τᵢ) + random walk (q per √s), units of σ and q, at knots j·``step_s``.

    Gauss-Markov terms start from their stationary distribution and the walk from 0 at
    the first knot at or before the first requested time. ``values`` takes non-decreasing
    times at or after the previous call's last time.
    """

    def __init__(self, sigmas, taus_s, walk_per_rts: float, step_s: float, rng: np.random.Generator):
        self._sigma = np.asarray(sigmas, dtype=float).reshape(-1)
        self._tau = np.asarray(taus_s, dtype=float).reshape(-1)
        if self._sigma.shape != self._tau.shape:
            raise ValueError(f"sigmas {self._sigma.shape} and taus_s {self._tau.shape} must match")
        if np.any(~np.isfinite(self._sigma)) or np.any(self._sigma < 0):
            raise ValueError(f"sigmas={sigmas!r} must be finite and ≥ 0")
        if np.any(~np.isfinite(self._tau)) or np.any(self._tau <= 0):
            raise ValueError(f"taus_s={taus_s!r} must be finite and > 0")
        if not (math.isfinite(walk_per_rts) and walk_per_rts >= 0.0):
            raise ValueError(f"walk_per_rts={walk_per_rts!r} must be finite and ≥ 0")
        if not (math.isfinite(step_s) and step_s > 0.0):
            raise ValueError(f"step_s={step_s!r} must be finite and > 0")
        if not isinstance(rng, np.random.Generator):
            raise TypeError("rng must be a numpy.random.Generator")
        self._q = float(walk_per_rts)
        self.step_s = float(step_s)
        self._rng = rng
        self.active = bool(np.any(self._sigma > 0) or self._q > 0)
        self._j: int | None = None  # index of the last generated knot
        self._x = np.zeros(self._sigma.size)  # Gauss-Markov states at knot _j
        self._walk = 0.0
        self._knots = np.empty(0)  # total at knots _j-1, _j (or just _j)
        self._t_last: float | None = None

    def _advance(self, first_step: int, count: int) -> np.ndarray:
        """Generate ``count`` knots, the first ``first_step`` knot steps after knot _j
        (or the stationary start when none exists), the others one step apart."""
        w = self._rng.standard_normal((count, self._sigma.size + 1))
        total = np.zeros(count)
        h = self.step_s
        for i, (s, tau) in enumerate(zip(self._sigma, self._tau)):
            x = np.empty(count)
            if self._j is None:
                x[0] = s * w[0, i]  # stationary start
            else:
                d = first_step * h
                x[0] = math.exp(-d / tau) * self._x[i] + s * math.sqrt(-math.expm1(-2.0 * d / tau)) * w[0, i]
            if count > 1:
                phi = math.exp(-h / tau)
                gain = s * math.sqrt(-math.expm1(-2.0 * h / tau))
                x[1:], _ = lfilter([gain], [1.0, -phi], w[1:, i], zi=[phi * x[0]])
            self._x[i] = x[-1]
            total += x
        if self._q > 0.0:
            steps = self._q * math.sqrt(h) * w[:, -1]
            steps[0] = 0.0 if self._j is None else self._q * math.sqrt(first_step * h) * w[0, -1]
            walk = np.cumsum(np.concatenate(([self._walk], steps)))[1:]
            self._walk = float(walk[-1])
            total += walk
        return total

    def values(self, t, contiguous: bool = True) -> np.ndarray:
        """Process at times ``t`` (1-D, non-decreasing, ≥ the previous call's last time).

        ``contiguous=False`` declares a gap since the previous call: knots in it are skipped
        by one exact transition instead of being generated one by one.
        """
        t = np.asarray(t, dtype=float)
        if t.ndim != 1:
            raise ValueError(f"times must be 1-D, got shape {t.shape}")
        if t.size == 0 or not self.active:
            return np.zeros(t.size)
        if self._t_last is not None and t[0] < self._t_last:
            raise ValueError(f"time {t[0]!r} s precedes the last evaluated time {self._t_last!r} s")
        u = t / self.step_s
        ju = np.floor(u)
        j_lo, j_hi = int(ju[0]), int(ju[-1]) + 1
        if self._j is None:
            new = self._advance(0, j_hi - j_lo + 1)
            base, knots = j_lo, new
        elif not contiguous and j_lo > self._j + 1:
            new = self._advance(j_lo - self._j, j_hi - j_lo + 1)
            base, knots = j_lo, new
        else:
            base = self._j - self._knots.size + 1
            knots = self._knots
            if j_hi > self._j:
                knots = np.concatenate((knots, self._advance(1, j_hi - self._j)))
        self._j = base + knots.size - 1
        self._knots = knots[-2:].copy()
        self._t_last = float(t[-1])
        idx = (ju - base).astype(np.intp)
        frac = u - ju
        return knots[idx] * (1.0 - frac) + knots[idx + 1] * frac
