"""Stochastic catalogue effects: coloured bias noise with no deterministic waveform.

Their detectability is judged on the Allan variance, where they separate from white noise:
``z = max_T (AVAR_effect(T) / AVAR_white(T)) · sqrt((N_T − 1) / 2)`` over averaging times
``T = m·dt`` (m = 1, 2, 4, ... with at least 9 non-overlapping clusters N_T), i.e. the excess
Allan variance in units of the white estimate's standard error (Allan 1966; IEEE Std 952).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from bench.discovery.effects_base import Effect, _p, base_regressors, project_out, vdot


@numba.njit(cache=True)
def _gauss_markov(dt, w, sigma, tau):
    """x_0 = σ·w_0 (stationary); x_k = φ_k·x_{k−1} + σ·sqrt(1 − φ_k²)·w_k, φ_k = exp(−dt_k/τ)."""
    n = w.size
    x = np.empty(n)
    x[0] = sigma * w[0]
    for k in range(1, n):
        phi = math.exp(-dt[k - 1] / tau)
        x[k] = phi * x[k - 1] + sigma * math.sqrt(1.0 - phi * phi) * w[k]
    return x


def _allan_z(avar_fn, rec, noise_sd: float) -> float:
    dt = rec.dt_s
    best = 0.0
    m = 1
    while rec.n // m >= 9:
        t = m * dt
        clusters = rec.n // m
        white = noise_sd ** 2 / m
        best = max(best, avar_fn(t) / white * math.sqrt((clusters - 1) / 2.0))
        m *= 2
    return best


class GaussMarkov(Effect):
    id = "gauss_markov"
    description = "exponentially correlated bias noise (first-order Gauss-Markov), e.g. bias instability"
    form = "x' = −x/tau_s + w, stationary sd sigma; y += x (exact discretisation for any dt)"
    inputs = ("t",)
    main_param = "sigma"
    signature = "tau: Allan hump peaking near 1.9·tau_s; ACF e^{−lag/tau_s}; spectrum Lorentzian with corner 1/(2π·tau_s)"
    stochastic = True
    ranges = {  # QA-2000 coloured noise µg over tens of s; FOG bias instability ~0.1-1 deg/h (3e-5-3e-4 deg/s)
        "accelerometer": (_p("sigma", "g", 1e-8, 1e-3, log=True), _p("tau_s", "s", 0.1, 1e5, log=True)),
        "gyro": (_p("sigma", "deg/s", 1e-6, 0.1, log=True), _p("tau_s", "s", 0.1, 1e5, log=True)),
        "mhd": (_p("sigma", "deg/s", 1e-5, 1.0, log=True), _p("tau_s", "s", 1e-3, 1e4, log=True)),
    }

    def _noise(self, p, rec, rng):
        w = rng.standard_normal(rec.n)
        if p["sigma"] == 0:
            return np.zeros(rec.n)
        return _gauss_markov(np.diff(rec.t_s), w, float(p["sigma"]), float(p["tau_s"]))

    @staticmethod
    def avar(sigma: float, tau_s: float, t_s: float) -> float:
        """Allan variance of the process at averaging time t_s (u²)."""
        x = t_s / tau_s
        return 2 * sigma ** 2 * tau_s / t_s * (1 - (3 - 4 * math.exp(-x) + math.exp(-2 * x)) / (2 * x))

    def snr(self, p, rec, noise_sd):
        return _allan_z(lambda t: self.avar(p["sigma"], p["tau_s"], t), rec, noise_sd)

    def drawable_range(self, q, rec, kind):
        if q.name == "tau_s":  # ten samples up to a thirtieth of the record: hump inside the Allan range
            lo = max(q.low, 10 * rec.dt_s)
            return lo, max(min(q.high, rec.duration_s / 30), lo * 1.01)
        return q.low, q.high

    def fit_range(self, q, rec, kind):
        if q.name == "tau_s":  # a correlation time beyond a fifth of the record looks like a walk or drift
            return rec.dt_s, 0.2 * rec.duration_s
        return q.low, q.high

    def fit_starts(self, rec, residual, *, kind=None):
        """sigma from the residual's sd after the white part (lag-1 covariance), tau_s where the
        autocorrelation falls to e^{−1} of its lag-1 value, and that tau ×/÷ 3."""
        r = project_out(np.asarray(residual, float), base_regressors(rec))
        r = r - r.mean()
        var = vdot(r, r) / r.size
        c1 = vdot(r[1:], r[:-1]) / r.size
        sigma = math.sqrt(max(c1, var * 0.05))
        lags = np.unique(np.geomspace(1, max(2, rec.n // 10), 40).astype(int))
        acf = np.array([vdot(r[k:], r[:-k]) / r.size for k in lags]) / max(c1, 1e-300)
        below = np.flatnonzero(acf < math.exp(-1))
        tau = float(lags[below[0]] * rec.dt_s) if below.size else rec.duration_s / 30
        q = self.params[1]
        return [{"sigma": sigma, "tau_s": float(np.clip(tau * f, q.low, q.high))} for f in (1.0, 3.0, 1 / 3)]


class RateRandomWalk(Effect):
    id = "rate_random_walk"
    description = "random walk of the bias (integrated white noise): rate random walk K in IEEE 952 terms"
    form = "x_k = x_{k−1} + k_per_rs·sqrt(dt_k)·w_k, x_0 = 0; y += x"
    inputs = ("t",)
    main_param = "k_per_rs"
    signature = "tau: Allan slope +1/2 at long tau (σ = K·sqrt(T/3)); spectrum 1/f²"
    stochastic = True
    kinds = ("accelerometer", "gyro")
    ranges = {  # FOG RRW ~0.01-10 deg/h/√h (1 deg/h/√h = 4.6e-6 deg/s/√s); accelerometers µg/√s-class
        "accelerometer": (_p("k_per_rs", "g/sqrt(s)", 1e-10, 1e-4, log=True),),
        "gyro": (_p("k_per_rs", "deg/s/sqrt(s)", 1e-8, 1e-2, log=True),),
    }

    def _noise(self, p, rec, rng):
        w = rng.standard_normal(rec.n)
        steps = p["k_per_rs"] * np.sqrt(np.diff(rec.t_s)) * w[1:]
        return np.concatenate([[0.0], np.cumsum(steps)])

    def snr(self, p, rec, noise_sd):
        k = p["k_per_rs"]
        return _allan_z(lambda t: k * k * t / 3.0, rec, noise_sd)

    def fit_starts(self, rec, residual, *, kind=None):
        """K from the growth of var(r[k+m] − r[k]) between lags n/10 and n/5 (the white part
        cancels in the difference), and ×/÷ 3."""
        r = np.asarray(residual, float)
        m1, m2 = max(1, rec.n // 10), max(2, rec.n // 5)
        v1 = float(np.var(r[m1:] - r[:-m1]))
        v2 = float(np.var(r[m2:] - r[:-m2]))
        k2 = (v2 - v1) / ((m2 - m1) * rec.dt_s)
        q = self.params[0]
        k = math.sqrt(k2) if k2 > 0 else q.low * 10
        return [{"k_per_rs": float(np.clip(k * f, q.low, q.high))} for f in (1.0, 3.0, 1 / 3)]
