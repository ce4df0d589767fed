"""Standardized one-step innovations of a residual under the model's noise: white + its
stochastic effects (Kalman filter). White, unit-variance samples when the model is right, so the
white-noise localization tests apply to them whatever colour the model's noise has.

State space (sample interval dt = 1/rate_hz): each stochastic effect's states from its
``state_space`` hook (:class:`bench.discovery.effects_noise.StateBlock`: diagonal, x_k = φ·x_{k−1}
+ e_k, var e = q, variance p0 at the first sample — a Gauss–Markov starts stationary, a random
walk with the variance it reaches over the record); observation: r_k = Σ x_k + v_k, v white of
sd ``white_sd``.

Innovation e_k = r_k − E[r_k | r_<k], standardized by its variance S_k. The filter is linear
in the residual: ``innovations(a·r1 + b·r2) = a·innovations(r1) + b·innovations(r2)``, so a
logged input passed through it is what its effect looks like in the innovations.
Units: residual and ``white_sd`` in the sensor unit, rate in Hz, the output dimensionless.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from bench.discovery.effects_noise import Processes, StochasticEffect


@numba.njit(cache=True)
def _filter(y, phi, q, p0, r_var):  # pragma: no cover - compiled
    m = phi.size
    n = y.size
    x = np.zeros(m)
    p = np.zeros((m, m))
    for i in range(m):
        p[i, i] = p0[i]
    out = np.empty(n)
    hp = np.zeros(m)
    for k in range(n):
        pred = 0.0
        for i in range(m):
            pred += x[i]
        s = r_var
        for i in range(m):
            acc = 0.0
            for j in range(m):
                acc += p[i, j]
            hp[i] = acc  # (H P)_i = (P Hᵀ)_i, P symmetric
            s += acc
        e = y[k] - pred
        out[k] = e / math.sqrt(s)
        for i in range(m):  # update with gain K = P Hᵀ / S
            x[i] += hp[i] * e / s
        for i in range(m):
            for j in range(m):
                p[i, j] -= hp[i] * hp[j] / s
        for i in range(m):  # predict: diagonal F and Q
            x[i] *= phi[i]
            for j in range(m):
                p[i, j] *= phi[i] * phi[j]
            p[i, i] += q[i]
    return out


def _states(rate_hz: float, n: int, effects: Processes) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The model's noise as diagonal states: each effect's ``state_space`` block, in order."""
    dt = 1.0 / rate_hz
    phi: list[float] = []
    q: list[float] = []
    p0: list[float] = []
    for eff, p in effects:
        if not isinstance(eff, StochasticEffect):
            raise ValueError(f"effect {getattr(eff, 'id', eff)!r} is not stochastic; allowed: the model's "
                             "stochastic effects (StochasticEffect)")
        block = eff.state_space(p, dt, n)
        phi += block.phi
        q += block.q
        p0 += block.p0
    return np.array(phi, float), np.array(q, float), np.array(p0, float)


def noise_psd(f_hz: np.ndarray, rate_hz: float, stochastic_effects: Processes = ()) -> np.ndarray:
    """One-sided PSD (unit²/Hz) at ``f_hz`` of the sampled stochastic effects (no white part):
    Σ over their states q/|1−φe^{−iω}|² (a Gauss–Markov σ²(1−φ²)/|1−φe^{−iω}|², a random walk
    K²·dt/|1−e^{−iω}|²), ω = 2πf/fs, times 2/fs — on the scale where white noise of sd σ has
    2σ²/fs."""
    f = np.asarray(f_hz, float)
    phi, q, _ = _states(float(rate_hz), 1, list(stochastic_effects))
    w = 2 * np.pi * f / rate_hz
    out = np.zeros_like(f)
    for ph, qq in zip(phi, q):
        with np.errstate(divide="ignore"):
            out = out + qq / (1 - 2 * ph * np.cos(w) + ph * ph)
    return out * 2.0 / rate_hz


def innovations(residual: np.ndarray, rate_hz: float, white_sd: float,
                stochastic_effects: Processes = ()) -> np.ndarray:
    """Standardized one-step innovations of ``residual`` (sensor unit, uniform samples at
    ``rate_hz``) under white noise of sd ``white_sd`` plus ``stochastic_effects`` — (effect,
    params) pairs (``Model.stochastic_effects()``). Without stochastic effects this is
    ``residual / white_sd``."""
    r = np.asarray(residual, dtype=float)
    if r.ndim != 1 or r.size == 0:
        raise ValueError(f"residual has shape {r.shape}; allowed: a non-empty 1-D array")
    if not np.all(np.isfinite(r)):
        raise ValueError("residual has non-finite values; allowed: finite numbers")
    if not (isinstance(rate_hz, (int, float, np.floating)) and math.isfinite(rate_hz) and rate_hz > 0):
        raise ValueError(f"rate_hz = {rate_hz!r}; allowed: a finite number > 0")
    if not (math.isfinite(white_sd) and white_sd > 0):
        raise ValueError(f"white_sd = {white_sd!r}; allowed: a finite number > 0")
    phi, q, p0 = _states(float(rate_hz), r.size, list(stochastic_effects))
    if phi.size == 0:
        return r / white_sd
    return _filter(r, phi, q, p0, float(white_sd) ** 2)
