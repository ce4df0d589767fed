"""Seeded noise processes sampled at simulated times.

Every process owns the ``numpy.random.Generator`` it is given and draws exactly one
standard normal per output sample, in time order. Its values therefore depend only on
the time grid and the generator's seed, not on how the grid is split into calls.
Give each process its own generator (e.g. ``rng.spawn(1)[0]``) so that processes do
not interleave draws from one stream.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter

# Steps within this relative tolerance of a run's first step count as "the same step":
# the rounding jitter of t0 + k*dt grids is eps*t/dt (1e-8 for 1 ms steps at t = 1e5 s);
# using the first step's coefficients then errs by < 1e-6 * dt/τ, far below the noise.
_UNIFORM_RTOL = 1e-6


def _check_times(t, t_last: float | None) -> np.ndarray:
    arr = np.asarray(t, dtype=float)
    if arr.ndim != 1:
        raise ValueError(f"times must be a 1-D array, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError("times must be finite")
    if arr.size > 1 and np.any(np.diff(arr) < 0):
        raise ValueError("times must be non-decreasing")
    if arr.size and t_last is not None and arr[0] < t_last:
        raise ValueError(f"time {arr[0]!r} s precedes the last sample at {t_last!r} s")
    return arr


def _linear_scan(a: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Solve ``x_k = a_k x_{k-1} + u_k`` (x_{-1} = 0) with log2(n) vectorised passes.

    Hillis-Steele prefix scan of the affine maps x -> a x + u; stable because |a| ≤ 1.
    """
    a = a.copy()
    x = u.copy()
    shift = 1
    while shift < x.size:
        x[shift:] = a[shift:] * x[:-shift] + x[shift:]  # compose with the map `shift` back
        a[shift:] = a[shift:] * a[:-shift]
        shift *= 2
    return x


class GaussMarkov:
    """First-order Gauss-Markov process with standard deviation ``sigma`` and correlation time ``tau_s``.

    Exact discretisation for any increasing times:
    ``x_{k+1} = φ x_k + σ sqrt(1 - φ²) w_k`` with ``φ = exp(-Δt/τ)``, started from the
    stationary distribution ``x_0 = σ w_0``. Autocovariance ``σ² exp(-|Δt|/τ)``.

    Uniform grids (all steps equal to the first step of the run within 1e-6 relative,
    including the step from the previous call) run through ``scipy.signal.lfilter`` with
    the carried filter state; the coefficients come from the run's first step, so the
    result is bit-identical however the grid is split into calls. Other grids use a
    vectorised prefix scan with per-step coefficients (equal to rounding, ~1e-15).
    """

    def __init__(self, sigma: float, tau_s: float, rng: np.random.Generator):
        if not (math.isfinite(sigma) and sigma >= 0.0):
            raise ValueError(f"sigma={sigma!r} must be finite and ≥ 0")
        if not (math.isfinite(tau_s) and tau_s > 0.0):
            raise ValueError(f"tau_s={tau_s!r} must be finite and > 0")
        if not isinstance(rng, np.random.Generator):
            raise TypeError("rng must be a numpy.random.Generator")
        self.sigma = float(sigma)
        self.tau_s = float(tau_s)
        self._rng = rng
        self._t_last: float | None = None
        self._x_last = 0.0
        self._run_dt: float | None = None  # step of the current uniform run

    def _coefficients(self, dt):
        phi = np.exp(-np.asarray(dt) / self.tau_s)
        gain = self.sigma * np.sqrt(-np.expm1(-2.0 * np.asarray(dt) / self.tau_s))  # σ sqrt(1-φ²)
        return phi, gain

    def sample(self, t) -> np.ndarray:
        """Process values at times ``t`` (1-D, non-decreasing, ≥ the last sampled time)."""
        t = _check_times(t, self._t_last)
        n = t.size
        if n == 0:
            return np.empty(0)
        w = self._rng.standard_normal(n)
        out = np.empty(n)
        start = 0
        if self._t_last is None:
            out[0] = self.sigma * w[0]  # stationary start
            start = 1
            prev_t = t[0]
        else:
            prev_t = self._t_last
        prev_x = out[0] if start else self._x_last
        if n > start:
            dt = np.empty(n - start)
            dt[0] = t[start] - prev_t
            np.subtract(t[start + 1:], t[start:-1], out=dt[1:])
            ref = self._run_dt if self._run_dt is not None else dt[0]
            lo, hi = (float(dt.min()), float(dt.max()))
            lo1, hi1 = (float(dt[1:].min()), float(dt[1:].max())) if dt.size > 2 else (0.0, 0.0)
            if hi - ref <= _UNIFORM_RTOL * ref and ref - lo <= _UNIFORM_RTOL * ref:
                phi, gain = (float(c) for c in self._coefficients(ref))
                # x_k = gain w_k + phi x_{k-1}; zi carries phi * x_{k-1} across calls.
                out[start:], _ = lfilter([gain], [1.0, -phi], w[start:], zi=[phi * prev_x])
                self._run_dt = ref
            elif dt.size > 2 and hi1 - dt[1] <= _UNIFORM_RTOL * dt[1] \
                    and dt[1] - lo1 <= _UNIFORM_RTOL * dt[1]:
                # a gap, then a uniform run (a new acquisition): one exact step across the
                # gap, the run through lfilter — avoids the O(n log n) scan on the usual case
                phi0, gain0 = (float(c) for c in self._coefficients(dt[0]))
                out[start] = phi0 * prev_x + gain0 * w[start]
                phi, gain = (float(c) for c in self._coefficients(dt[1]))
                out[start + 1:], _ = lfilter([gain], [1.0, -phi], w[start + 1:],
                                             zi=[phi * out[start]])
                self._run_dt = float(dt[1])
            else:
                phi, gain = self._coefficients(dt)
                u = gain * w[start:]
                u[0] += phi[0] * prev_x
                out[start:] = _linear_scan(phi, u)
                self._run_dt = None  # a later uniform run starts from its own first step
        self._t_last = float(t[-1])
        self._x_last = float(out[-1])
        return out


class WhiteNoise:
    """Band-limited white noise averaged over a finite integration time.

    ``density_per_rthz`` is the one-sided amplitude spectral density N (units/√Hz,
    e.g. g/√Hz). Averaging over T seconds is a boxcar with equivalent noise bandwidth
    1/(2T), so each averaged sample has ``σ = N / sqrt(2 T)``; samples are independent
    (non-overlapping averages).
    """

    def __init__(self, density_per_rthz: float, rng: np.random.Generator):
        if not (math.isfinite(density_per_rthz) and density_per_rthz >= 0.0):
            raise ValueError(f"density_per_rthz={density_per_rthz!r} must be finite and ≥ 0")
        if not isinstance(rng, np.random.Generator):
            raise TypeError("rng must be a numpy.random.Generator")
        self.density_per_rthz = float(density_per_rthz)
        self._rng = rng

    def sigma(self, averaging_time_s: float) -> float:
        """Standard deviation of one sample averaged over ``averaging_time_s``."""
        if not (math.isfinite(averaging_time_s) and averaging_time_s > 0.0):
            raise ValueError(f"averaging_time_s={averaging_time_s!r} must be finite and > 0")
        return self.density_per_rthz / math.sqrt(2.0 * averaging_time_s)

    def sample(self, n: int, averaging_time_s: float) -> np.ndarray:
        """``n`` independent averaged samples."""
        if int(n) != n or n < 0:
            raise ValueError(f"n={n!r} must be a non-negative integer")
        return self.sigma(averaging_time_s) * self._rng.standard_normal(int(n))


class RandomWalk:
    """Random walk (integrated white noise) starting at 0 at the first sampled time.

    ``density_per_rts`` is the walk coefficient q (units/√s): ``Var[x(t) - x(s)] = q² |t - s|``.
    Use it for drift-type terms (e.g. a bias random walk in g/√s).
    """

    def __init__(self, density_per_rts: float, rng: np.random.Generator):
        if not (math.isfinite(density_per_rts) and density_per_rts >= 0.0):
            raise ValueError(f"density_per_rts={density_per_rts!r} must be finite and ≥ 0")
        if not isinstance(rng, np.random.Generator):
            raise TypeError("rng must be a numpy.random.Generator")
        self.density_per_rts = float(density_per_rts)
        self._rng = rng
        self._t_last: float | None = None
        self._x_last = 0.0

    def sample(self, t) -> np.ndarray:
        """Walk values at times ``t`` (1-D, non-decreasing, ≥ the last sampled time)."""
        t = _check_times(t, self._t_last)
        if t.size == 0:
            return np.empty(0)
        w = self._rng.standard_normal(t.size)
        prev_t = t[0] if self._t_last is None else self._t_last
        steps = self.density_per_rts * np.sqrt(np.diff(np.concatenate(([prev_t], t)))) * w
        # Sequential accumulation from the carried value: identical however t is split.
        out = np.cumsum(np.concatenate(([self._x_last], steps)))[1:]
        self._t_last = float(t[-1])
        self._x_last = float(out[-1])
        return out
