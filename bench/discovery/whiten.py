"""Standardized one-step innovations of a residual under the model's noise: white + its
stochastic effects (Kalman filter). White, unit-variance samples when the model is right, so the
white-noise localization tests apply to them whatever colour the model's noise has.

State space (sample interval dt = 1/rate_hz): each stochastic effect's block of states from its
``state_space`` hook (:class:`bench.discovery.effects_noise.StateBlock`: x_k = F·x_{k−1} + e_k,
cov e = Q, seen as h·x_k, covariance P0 at the first sample — a Gauss–Markov starts stationary, a
random walk with the variance it reaches over the record; most blocks are diagonal, a moving
average such as white angle noise is not); the model's states are the blocks side by side
(block-diagonal F); observation: r_k = Σ_b h_b·x_{b,k} + v_k, v white of sd ``white_sd``.

Innovation e_k = r_k − E[r_k | r_<k], standardized by its variance S_k. The filter is linear
in the residual: ``innovations(a·r1 + b·r2) = a·innovations(r1) + b·innovations(r2)``, so a
logged input passed through it is what its effect looks like in the innovations.
Units: residual and ``white_sd`` in the sensor unit, rate in Hz, the output dimensionless.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numba
import numpy as np

from bench.discovery.effects_noise import Processes, StateBlock, StochasticEffect


@numba.njit(cache=True, inline="always")
def _innovation(y_k, h, x):  # pragma: no cover - compiled
    """y_k − h·x: the measurement less its one-step prediction."""
    pred = 0.0
    for i in range(h.size):
        pred += h[i] * x[i]
    return y_k - pred


@numba.njit(cache=True, inline="always")
def _gain(p, h, r_var, hp):  # pragma: no cover - compiled
    """Writes P hᵀ into ``hp`` and returns the innovation variance S = h P hᵀ + r_var."""
    s = r_var
    for i in range(h.size):
        acc = 0.0
        for j in range(h.size):
            acc += p[i, j] * h[j]
        hp[i] = acc
        s += h[i] * acc
    return s


@numba.njit(cache=True)
def _filter(y, f, q, h, p0, r_var, lo, hi, out_e, out_s, out_g):  # pragma: no cover - compiled
    """Time-varying Kalman filter of y under the block-diagonal state space (f, q, h, p0);
    ``lo[i]``, ``hi[i]``: the range of columns of row i's block. Writes each innovation and its
    variance into ``out_e`` and ``out_s``, and — when ``out_g`` has a row per sample — the update
    gain K_k = P hᵀ/S (0 where not observed) into ``out_g`` (for :func:`_smooth_back`).
    Cost O(n·m²·b), b the largest block — until the covariance reaches its steady state: F, Q
    and the white variance do not change, so once a whole update leaves P bit for bit as it
    was, every later one would too, and from there on
    only the state is propagated with the same gain (O(n·m·b); the same numbers). A NaN in ``y``
    is a sample not observed: the state and P are only predicted through it (its innovation is
    NaN, its variance the prediction's), and the steady state is sought again after it."""
    m = h.size
    n = y.size
    x = np.zeros(m)
    xn = np.zeros(m)
    p = p0.copy()
    prev = np.empty((m, m))
    fp = np.zeros((m, m))
    hp = np.zeros(m)
    s = r_var
    steady = False
    for k in range(n):
        e = _innovation(y[k], h, x)
        missing = math.isnan(e)  # not observed: predict only
        if missing:
            steady = False
        if not steady:  # else hp and s are those of the fixed point
            s = _gain(p, h, r_var, hp)
        out_e[k] = e
        out_s[k] = s
        if missing:
            for i in range(m):
                hp[i] = 0.0  # no gain: neither the state nor P is updated
        if out_g.shape[0] == n:
            for i in range(m):
                out_g[k, i] = hp[i] / s
        for i in range(m):  # update with gain K = P hᵀ / S
            x[i] += hp[i] * e / s if not missing else 0.0
        # predict: x ← F x, P ← F P Fᵀ + Q, F block-diagonal (row i reads columns lo[i]..hi[i])
        for i in range(m):
            acc = 0.0
            for a in range(lo[i], hi[i]):
                acc += f[i, a] * x[a]
            xn[i] = acc
        for i in range(m):
            x[i] = xn[i]
        if steady:
            continue
        for i in range(m):
            for j in range(m):
                prev[i, j] = p[i, j]
                p[i, j] -= hp[i] * hp[j] / s
        for i in range(m):
            for j in range(m):
                acc = 0.0
                for a in range(lo[i], hi[i]):
                    acc += f[i, a] * p[a, j]
                fp[i, j] = acc
        same = True
        for i in range(m):
            for j in range(i, m):
                acc = 0.0
                for b in range(lo[j], hi[j]):
                    acc += fp[i, b] * f[j, b]
                v = acc + q[i, j]
                if v != prev[i, j] or v != prev[j, i]:
                    same = False
                p[i, j] = v
                p[j, i] = v  # symmetric by construction: keep it so against rounding
        steady = same and not missing


@numba.njit(cache=True)
def _filter_diagonal(y, f, q, h, p0, r_var, out_e, out_s, out_g):  # pragma: no cover - compiled
    """:func:`_filter` when F is diagonal (Gauss–Markov, random walk, flicker's 13 Gauss–Markov
    states in one block), the same products without the block loops — whose other terms are
    zeros: ``P ← (f_i·(P − P hᵀ h P / S)_ij)·f_j + Q_ij`` over the upper triangle. The same
    numbers; flicker's filter of 180 000 samples 0.59 s → 0.045 s."""
    m = h.size
    n = y.size
    x = np.zeros(m)
    p = p0.copy()
    hp = np.zeros(m)
    d = np.zeros(m)
    for i in range(m):
        d[i] = f[i, i]
    s = r_var
    steady = False
    for k in range(n):
        e = _innovation(y[k], h, x)
        missing = math.isnan(e)
        if missing:
            steady = False
        if not steady:
            s = _gain(p, h, r_var, hp)
        out_e[k] = e
        out_s[k] = s
        if missing:
            for i in range(m):
                hp[i] = 0.0
        if out_g.shape[0] == n:
            for i in range(m):
                out_g[k, i] = hp[i] / s
        for i in range(m):
            x[i] += hp[i] * e / s if not missing else 0.0
        for i in range(m):
            x[i] = 0.0 + d[i] * x[i]
        if steady:
            continue
        same = True
        for i in range(m):
            for j in range(i, m):
                v = (0.0 + d[i] * (p[i, j] - hp[i] * hp[j] / s)) * d[j] + q[i, j]
                if v != p[i, j] or v != p[j, i]:
                    same = False
                p[i, j] = v
                p[j, i] = v
        steady = same and not missing


@numba.njit(cache=True)
def _smooth_back(e, s, g, f, q, h, lo, hi, blo, bhi, out):  # pragma: no cover - compiled
    """Fixed-interval smoothed state disturbances (de Jong's smoother; Durbin & Koopman, §4.5)
    from the filter's innovations ``e``, their variances ``s`` and update gains ``g``:
    ``out[k, b]`` = h_b·Q_b·r_k, the disturbance e_k that moved block b's states into x_k given the
    whole record, as seen in the output; r_k the smoothing cumulant of x_k after sample k,
    r_k = hᵀ(e_k/S_k − g_kᵀr) + r with r = Fᵀr_{k+1} (a NaN innovation, a sample not observed,
    adds no term). ``lo``/``hi`` each row's block, ``blo``/``bhi`` the blocks reported."""
    m = h.size
    r = np.zeros(m)
    rk = np.zeros(m)
    for k in range(e.size - 1, -1, -1):
        seen = not math.isnan(e[k])
        kr = 0.0
        for i in range(m):
            kr += g[k, i] * r[i]
        for i in range(m):
            rk[i] = h[i] * (e[k] / s[k] - kr) + r[i] if seen else r[i]
        for b in range(blo.size):
            acc = 0.0
            for i in range(blo[b], bhi[b]):
                qi = 0.0
                for j in range(blo[b], bhi[b]):
                    qi += q[i, j] * rk[j]
                acc += h[i] * qi
            out[k, b] = acc
        for i in range(m):
            acc = 0.0
            for a in range(lo[i], hi[i]):
                acc += f[a, i] * rk[a]
            r[i] = acc


@numba.njit(cache=True)
def _simulate(f, lq, lp0, h, z, out):  # pragma: no cover - compiled
    """``out[k]`` = h·x_k with x_0 = L_P0·z_0, x_k = F·x_{k−1} + L_Q·z_k (L: square roots)."""
    n, m = z.shape
    x = np.zeros(m)
    xn = np.zeros(m)
    for i in range(m):
        acc = 0.0
        for j in range(m):
            acc += lp0[i, j] * z[0, j]
        x[i] = acc
    for k in range(n):
        if k > 0:
            for i in range(m):
                acc = 0.0
                for a in range(m):
                    acc += f[i, a] * x[a] + lq[i, a] * z[k, a]
                xn[i] = acc
            for i in range(m):
                x[i] = xn[i]
        acc = 0.0
        for i in range(m):
            acc += h[i] * x[i]
        out[k] = acc


@dataclass(frozen=True, eq=False)
class StateSpace:
    """The model's noise states: block-diagonal ``f``, ``q``, ``p0``, the observation row ``h``
    and, per row, the column range of its block (``lo``, ``hi``)."""

    f: np.ndarray
    q: np.ndarray
    h: np.ndarray
    p0: np.ndarray
    lo: np.ndarray
    hi: np.ndarray

    @classmethod
    def of_blocks(cls, blocks: Sequence[StateBlock]) -> StateSpace:
        m = sum(b.m for b in blocks)
        f, q, p0 = np.zeros((m, m)), np.zeros((m, m)), np.zeros((m, m))
        h = np.zeros(m)
        lo, hi = np.zeros(m, np.int64), np.zeros(m, np.int64)
        i = 0
        for b in blocks:
            j = i + b.m
            f[i:j, i:j], q[i:j, i:j], p0[i:j, i:j], h[i:j] = b.f, b.q, b.p0, b.h
            lo[i:j], hi[i:j] = i, j
            i = j
        return cls(f, q, h, p0, lo, hi)

    @property
    def m(self) -> int:
        return int(self.h.size)

    def filter(self, y: np.ndarray, white_var: float) -> tuple[np.ndarray, np.ndarray]:
        """(innovations, their variances) of ``y`` with white measurement noise ``white_var``."""
        e, s, _ = self._run(y, white_var, gains=False)
        return e, s

    def _run(self, y: np.ndarray, white_var: float, *, gains: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        y = np.ascontiguousarray(y, dtype=float)
        e, s = np.empty_like(y), np.empty_like(y)
        g = np.zeros((y.size if gains else 0, self.m))
        if not np.any(self.f - np.diag(np.diag(self.f))):  # F diagonal: no block loops needed
            _filter_diagonal(y, self.f, self.q, self.h, self.p0, float(white_var), e, s, g)
        else:
            _filter(y, self.f, self.q, self.h, self.p0, float(white_var), self.lo, self.hi, e, s, g)
        return e, s, g

    def blocks(self) -> list[tuple[int, int]]:
        """Each block's row range (lo, hi), in order: one per process of :func:`state_space`."""
        return sorted(set(zip(self.lo.tolist(), self.hi.tolist())))

    def smoothed_disturbances(self, y: np.ndarray, white_var: float) -> np.ndarray:
        """(n, blocks): each block's disturbance given the whole of ``y`` as it moves the output
        (h_b·E[e_{b,k} | y]; the filter's gains, then :func:`_smooth_back`). NaN in ``y``: not observed."""
        e, s, g = self._run(y, white_var, gains=True)
        b = np.array(self.blocks(), dtype=np.int64).reshape(-1, 2)
        out = np.zeros((e.size, b.shape[0]))
        _smooth_back(e, s, g, self.f, self.q, self.h, self.lo, self.hi, np.ascontiguousarray(b[:, 0]),
                     np.ascontiguousarray(b[:, 1]), out)
        return out

    def simulate(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """One realisation of the states' output h·x_k over ``n`` samples (x_0 from ``p0``)."""
        z = rng.standard_normal((int(n), self.m))
        out = np.empty(int(n))
        _simulate(self.f, _root(self.q), _root(self.p0), self.h, z, out)
        return out


def _root(a: np.ndarray) -> np.ndarray:
    """A square root L (L·Lᵀ = a) of a covariance, semi-definite allowed (a walk's Q, a P0 of 0)."""
    w, v = np.linalg.eigh(a)
    return np.ascontiguousarray(v * np.sqrt(np.clip(w, 0.0, None)))


def state_space(rate_hz: float, n: int, effects: Processes) -> StateSpace:
    """The model's noise as one state space: each effect's ``state_space`` block, in order."""
    dt = 1.0 / rate_hz
    blocks = []
    for eff, p in effects:
        if not isinstance(eff, StochasticEffect):
            raise ValueError(f"effect {getattr(eff, 'id', eff)!r} is not stochastic; allowed: the model's "
                             "stochastic effects (StochasticEffect)")
        blocks.append(eff.state_space(p, dt, n))
    return StateSpace.of_blocks(blocks)


def block_psd(block: StateBlock, w: np.ndarray) -> np.ndarray:
    """Per-sample level spectrum of one block at ω (rad/sample): G·Q·Gᴴ, G = h·(I − F e^{−iω})⁻¹."""
    m = block.m
    z = np.exp(-1j * np.asarray(w, float))
    if np.count_nonzero(block.f - np.diag(np.diag(block.f))) == 0 and \
            np.count_nonzero(block.q - np.diag(np.diag(block.q))) == 0:
        phi, qd = np.diag(block.f), np.diag(block.q)
        with np.errstate(divide="ignore"):
            return np.sum(block.h ** 2 * qd / np.abs(1.0 - phi * z[:, None]) ** 2, axis=1)
    a = np.eye(m)[None, :, :] - block.f[None, :, :] * z[:, None, None]
    g = np.linalg.solve(np.transpose(a, (0, 2, 1)), np.broadcast_to(block.h, (w.size, m))[..., None])[..., 0]
    return np.real(np.einsum("wi,ij,wj->w", g, block.q, np.conj(g)))


def noise_psd(f_hz: np.ndarray, rate_hz: float, stochastic_effects: Processes = (), n: int = 1) -> np.ndarray:
    """One-sided PSD (unit²/Hz) at ``f_hz`` of the sampled stochastic effects (no white part) on a
    record of ``n`` samples (a flicker's states span the record's band):
    each block's G·Q·Gᴴ (a Gauss–Markov σ²(1−φ²)/|1−φe^{−iω}|², a random walk
    K²·dt/|1−e^{−iω}|², white angle noise (Q/dt)²·|1 − e^{−iω}|²), ω = 2πf/fs, times 2/fs — on
    the scale where white noise of sd σ has 2σ²/fs."""
    f = np.asarray(f_hz, float)
    dt = 1.0 / float(rate_hz)
    w = 2 * np.pi * f / rate_hz
    out = np.zeros_like(f)
    for eff, p in stochastic_effects:
        if not isinstance(eff, StochasticEffect):
            raise ValueError(f"effect {getattr(eff, 'id', eff)!r} is not stochastic; allowed: StochasticEffect")
        out = out + block_psd(eff.state_space(p, dt, int(n)), w)
    return out * 2.0 / rate_hz


#: Frequencies of the Allan-variance integral per record: log-spaced from a thousandth of the
#: record's lowest Fourier frequency to the Nyquist frequency (the integrand's relative error on
#: white noise, flicker and a walk is below 1e-3 there).
AVAR_GRID = 8000


def model_avar(tau_s: np.ndarray, rate_hz: float, n: int, white_sd: float,
               stochastic_effects: Processes = (), ramp_per_s: float = 0.0) -> np.ndarray:
    """Allan variance at ``tau_s`` of white noise of sd ``white_sd`` per sample, the sampled
    ``stochastic_effects`` and a ramp: σ²(τ) = 2∫₀^{fs/2} S(f)·sin⁴(πfτ)/(πfτ)² df over the
    processes' one-sided PSD (:func:`noise_psd`), plus σ_w²/(fs·τ) for the white noise and
    R²τ²/2 for the ramp (IEEE Std 952, annex C)."""
    tau = np.atleast_1d(np.asarray(tau_s, float))
    fs = float(rate_hz)
    out = white_sd ** 2 / (fs * tau) + 0.5 * (ramp_per_s * tau) ** 2
    if stochastic_effects:
        f = np.geomspace(fs / (1000.0 * max(int(n), 2)), fs / 2, AVAR_GRID)
        psd = noise_psd(f, fs, stochastic_effects, n)
        x = np.pi * f[None, :] * tau[:, None]
        out = out + 2.0 * np.trapezoid(psd[None, :] * np.sin(x) ** 4 / x ** 2, f, axis=1)
    return out


def exact_nll(r: np.ndarray, rate_hz: float, white_var: float, stochastic_effects: Processes = ()) -> float:
    """The exact Gaussian −ln L of ``r`` (its constant dropped) under white noise of variance
    ``white_var`` plus ``stochastic_effects``: ½·Σ(ln sₖ + eₖ²/sₖ) over the Kalman innovations eₖ
    and their variances sₖ; ``inf`` where a variance is not positive (a parameter search's edge).
    A NaN in ``r`` is a sample not observed (``StateSpace.filter``): it adds no term."""
    r = np.asarray(r, dtype=float)
    if not stochastic_effects:
        r = r[~np.isnan(r)]
        return 0.5 * (float(r @ r) / white_var + r.size * math.log(white_var))
    e, v = state_space(float(rate_hz), r.size, list(stochastic_effects)).filter(r, float(white_var))
    if not np.all(v > 0):
        return math.inf
    seen = ~np.isnan(e)
    return 0.5 * float(np.sum(np.log(v[seen]) + e[seen] ** 2 / v[seen]))


def innovations(residual: np.ndarray, rate_hz: float, white_sd: float,
                stochastic_effects: Processes = (), seen: np.ndarray | None = None) -> np.ndarray:
    """Standardized one-step innovations of ``residual`` (sensor unit, uniform samples at
    ``rate_hz``) under white noise of sd ``white_sd`` plus ``stochastic_effects`` — (effect,
    params) pairs (``Model.stochastic_effects()``). Without stochastic effects this is
    ``residual / white_sd``. ``seen``: a boolean mask of the samples that observe the noise
    (``Model.noise_seen``: a clipped stretch holds none of it); the others are missing to the
    filter — their innovations NaN — so the states are carried across a clip by their dynamics,
    not pulled to the clip's flat residual (a Gauss–Markov read a 6-σ jump at each clip's edge)."""
    r = np.asarray(residual, dtype=float)
    if r.ndim != 1 or r.size == 0:
        raise ValueError(f"residual has shape {r.shape}; allowed: a non-empty 1-D array")
    if not np.all(np.isfinite(r)):
        raise ValueError("residual has non-finite values; allowed: finite numbers")
    if seen is not None:
        seen = np.asarray(seen, bool)
        if seen.shape != r.shape:
            raise ValueError(f"seen has shape {seen.shape}; allowed: the residual's {r.shape}")
        if not seen.any():
            raise ValueError("seen holds no sample; allowed: a mask with at least one True")
        r = np.where(seen, r, np.nan)
    if not (isinstance(rate_hz, (int, float, np.floating)) and math.isfinite(rate_hz) and rate_hz > 0):
        raise ValueError(f"rate_hz = {rate_hz!r}; allowed: a finite number > 0")
    if not (math.isfinite(white_sd) and white_sd > 0):
        raise ValueError(f"white_sd = {white_sd!r}; allowed: a finite number > 0")
    ss = state_space(float(rate_hz), r.size, list(stochastic_effects))
    if ss.m == 0:
        return r / white_sd
    e, s = ss.filter(r, float(white_sd) ** 2)
    return e / np.sqrt(s)


def seen_only(r: np.ndarray, seen: np.ndarray | None) -> np.ndarray:
    """``r`` less its mean over the ``seen`` samples, NaN at the others — missing to
    :meth:`StateSpace.filter` and :func:`exact_nll`; ``seen`` None: every sample, the mean removed."""
    r = np.asarray(r, float)
    if seen is None:
        return r - r.mean()
    seen = np.asarray(seen, bool)
    return np.where(seen, r - float(np.mean(r[seen])), np.nan)


def innovation_var(rate_hz: float, n: int, white_sd: float, stochastic_effects: Processes = (),
                   seen: np.ndarray | None = None) -> np.ndarray:
    """Per-sample one-step innovation variance (sensor unit²) of ``innovations`` under white noise
    of sd ``white_sd`` plus ``stochastic_effects``: ``white_sd²`` plus the states' prediction
    variance (large at the start and after samples not ``seen``, settling to the filter's
    steady state)."""
    ss = state_space(float(rate_hz), int(n), list(stochastic_effects))
    if ss.m == 0:
        return np.full(int(n), float(white_sd) ** 2)
    y = np.zeros(int(n)) if seen is None else np.where(np.asarray(seen, bool), 0.0, np.nan)
    return np.asarray(ss.filter(y, float(white_sd) ** 2)[1], float)


def wander_sd(rate_hz: float, n: int, stochastic_effects: Processes = ()) -> float:
    """Sd of the random processes' sum about its record mean on ``n`` samples at ``rate_hz``
    (their spectra summed over the record's Fourier frequencies, DC excluded): how far they move
    the signal in a record — along a quantizer's lattice, for one."""
    w = 2 * np.pi * np.arange(1, (int(n) - 1) // 2 + 1) / int(n)
    total = 0.0
    for eff, p in stochastic_effects:
        if not isinstance(eff, StochasticEffect):
            raise ValueError(f"effect {eff.id!r} is not a random process; allowed: StochasticEffect pairs")
        total += 2.0 / int(n) * float(np.sum(block_psd(eff.state_space(p, 1.0 / float(rate_hz), int(n)), w)))
    return math.sqrt(total)


def one_step_prediction(r: np.ndarray, block: StateBlock, white_sd: float) -> np.ndarray:
    """Kalman one-step prediction of ``r`` from its past under white noise of sd ``white_sd``
    plus the states of ``block`` (a fitted process's own ``state_space``)."""
    e, _ = StateSpace.of_blocks([block]).filter(np.asarray(r, float), float(white_sd) ** 2)
    return np.asarray(r, float) - e
