"""Least squares under white noise plus a Gauss–Markov drift: exact GLS on a series with gaps.

A long static record's residual is not white: besides the white noise, the bias wanders
(bias instability, slow drift). The noise model here is the inertial engineer's usual one —
**white noise plus a first-order Gauss–Markov process** (an AR(1) at the sample spacing):

    e_t = w_t + d_t,   w_t ~ N(0, σ²),   d_t = φ·d_{t−1} + η_t,   Var d = ρ·σ²

Given (φ, ρ), y and every column of X are **whitened exactly** by a Kalman filter of the
drift state: its innovations v_t / √F_t are independent and of variance σ², and the gain and
F_t do not depend on the data, so one pass whitens all columns at once (after the gain has
converged, the filter is the fixed ARMA(1,1) filter (1 − φB)/(1 − φ(1 − K)B), run by
``scipy.signal.lfilter``). Rows a mask leaves out are missing observations: the filter
predicts the drift across them, so the whitening stays exact for the rows kept. The
whitened regression gives the GLS coefficients and their covariance σ̂²(X_wᵀX_w)⁻¹.

(φ, ρ) are estimated **jointly with the regression by restricted maximum likelihood**, not
from the residual of a first ordinary fit: drift that the regressors partly absorb leaves an
ordinary residual that looks whiter than the noise is, and a covariance built on it is too
narrow. For n rows and k columns::

    ℓ_R(φ, ρ) = −½ Σ_t ln F_t − ½ ln det(X_wᵀX_w) − (n − k)/2 · ln(RSS_w / (n − k))

(exact for Gaussian noise). The drift is always fitted (it nests white noise, ρ → 0): a BIC
test for it left out drifts half as large as the white noise, and with them the width of
every interval on a slow regressor. A few hours of record pin (φ, ρ) down loosely, and a
covariance taken at the estimate alone claims too much whenever the drift is underestimated:
:func:`gls_integrated` integrates the coefficient covariance over the estimate's Laplace
approximation instead (figures in docs/METHODS.md, "Calibration over temperature").
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize, signal

_PHI_MAX = 0.9999
_RATIO_BOUNDS = (1e-4, 1e4)
_LOGIT_BOUNDS = (-8.0, 12.0)
_CONVERGED = 1e-12


@dataclass(frozen=True)
class NoiseModel:
    """White noise plus a Gauss–Markov drift at the row spacing: ``phi`` its correlation
    from one row to the next, ``ratio`` its variance over the white noise's (0: white only)."""

    phi: float = 0.0
    ratio: float = 0.0

    @property
    def white_only(self) -> bool:
        return self.ratio == 0.0 or self.phi == 0.0

    def to_dict(self) -> dict:
        return {"phi": self.phi, "ratio": self.ratio}


@dataclass(frozen=True, eq=False)
class GlsFit:
    """GLS coefficients and covariance; ``sigma`` the white noise's standard deviation
    (drift variance ρσ²), ``rss`` the whitened residual sum of squares over ``n`` rows
    (``dof`` = n − columns), ``log_det`` Σ ln F_t."""

    coefficients: np.ndarray
    covariance: np.ndarray
    noise: NoiseModel
    sigma: float
    rss: float
    n: int
    dof: int
    log_det: float

    def bic(self) -> float:
        """BIC of the exact Gaussian likelihood (columns, noise parameters and σ counted)."""
        k = self.coefficients.size + (0 if self.noise.white_only else 2) + 1
        loglik = -0.5 * (self.log_det + self.n * math.log(max(self.rss, 1e-300) / self.n))
        return -2.0 * loglik + k * math.log(self.n)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(start, stop) of each run of True in ``mask``."""
    edges = np.flatnonzero(np.diff(np.r_[0, mask.astype(np.int8), 0]))
    return list(zip(edges[0::2].tolist(), edges[1::2].tolist()))


def _whiten_run(a: np.ndarray, phi: float, ratio: float, state: np.ndarray,
                p: float) -> tuple[np.ndarray, float, np.ndarray, float]:
    """One run of observed rows (2-D, rows = time) through the drift's Kalman filter, from the
    predicted drift ``state`` (per column) and its variance ``p`` (σ² units): innovations / √F,
    Σ ln F, and the prediction for the row after the run."""
    n = a.shape[0]
    q = ratio * (1.0 - phi * phi)
    out = np.empty_like(a)
    log_det = 0.0
    t = 0
    while t < n:
        f = p + 1.0
        gain = p / f
        v = a[t] - state
        out[t] = v / math.sqrt(f)
        log_det += math.log(f)
        state = phi * (state + gain * v)
        p_next = phi * phi * p / f + q
        t += 1
        converged = abs(p_next - p) <= _CONVERGED * p_next
        p = p_next
        if converged:
            break
    if t < n:  # steady state: a fixed linear filter from here on
        f = p + 1.0
        gain = p / f
        c, d = phi * (1.0 - gain), phi * gain
        rest = a[t:]
        pred = signal.lfilter([0.0, d], [1.0, -c], rest, axis=0, zi=state[None, :])[0]
        out[t:] = (rest - pred) / math.sqrt(f)
        log_det += (n - t) * math.log(f)
        state = c * pred[-1] + d * rest[-1]
    return out, log_det, state, p


def whiten(a: np.ndarray, mask: np.ndarray, noise: NoiseModel) -> tuple[np.ndarray, float]:
    """The masked rows of ``a`` (1-D or 2-D, rows = time) whitened exactly for ``noise``
    (module docstring), and Σ ln F_t (the log-determinant of the noise covariance / σ²).
    Rows left out are missing observations: the drift is carried across them (φ^g, and its
    variance towards the stationary one), not restarted, so the runs stay correlated."""
    two_d = a.reshape(a.shape[0], -1)
    if noise.white_only:
        return a[mask], 0.0
    phi, ratio = noise.phi, noise.ratio
    pieces, log_det = [], 0.0
    state, p, last = np.zeros(two_d.shape[1]), ratio, None
    for start, stop in _runs(mask):
        if last is not None:  # predict across the gap of start − last missing rows
            decay = phi ** (start - last)
            state, p = decay * state, decay * decay * p + ratio * (1.0 - decay * decay)
        out, ld, state, p = _whiten_run(two_d[start:stop], phi, ratio, state, p)
        pieces.append(out)
        log_det += ld
        last = stop
    w = np.concatenate(pieces)
    return (w[:, 0] if a.ndim == 1 else w), log_det


def solve(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Least squares with unit-norm columns (SVD): coefficients, (XᵀX)⁻¹, residual sum of squares."""
    norms = np.linalg.norm(x, axis=0)
    norms[norms == 0.0] = 1.0
    u, s, vt = np.linalg.svd(x / norms, full_matrices=False)
    if s[-1] <= 1e-12 * s[0]:
        raise ValueError("the fitted terms are not separable on these data (singular design)")
    beta = vt.T @ ((u.T @ y) / s)
    inv = (vt.T / s**2) @ vt
    resid = y - (x / norms) @ beta
    return beta / norms, inv / np.outer(norms, norms), float(resid @ resid)


def gls(x: np.ndarray, y: np.ndarray, mask: np.ndarray, noise: NoiseModel) -> GlsFit:
    """GLS of ``y`` on the columns of ``x`` over the rows in ``mask`` under ``noise``."""
    w, log_det = whiten(np.column_stack([x, y]), mask, noise)
    xw, yw = w[:, :-1], w[:, -1]
    n, k = xw.shape
    if n <= k:
        raise ValueError(f"{n} usable rows for {k} terms: the record is too short for this model")
    coef, inv, rss = solve(xw, yw)
    s2 = rss / (n - k)
    return GlsFit(coef, inv * s2, noise, math.sqrt(s2), rss, n, n - k, log_det)


def _reml(xy: np.ndarray, mask: np.ndarray, noise: NoiseModel) -> float:
    """Restricted log-likelihood (up to a constant) of the noise model (module docstring)."""
    w, log_det = whiten(xy, mask, noise)
    xw, yw = w[:, :-1], w[:, -1]
    n, k = xw.shape
    _, inv, rss = solve(xw, yw)
    _, logdet_inv = np.linalg.slogdet(inv)
    return -0.5 * log_det + 0.5 * logdet_inv - (n - k) / 2 * math.log(max(rss, 1e-300) / (n - k))


def _unpack(theta) -> NoiseModel:
    """(φ, ρ) from the unconstrained parameters (logit of φ/φ_max, ln ρ), held within the
    bounds REML searches (a quadrature node of a flat likelihood can land far outside)."""
    logit = min(max(float(theta[0]), _LOGIT_BOUNDS[0]), _LOGIT_BOUNDS[1])
    log_ratio = min(max(float(theta[1]), math.log(_RATIO_BOUNDS[0])), math.log(_RATIO_BOUNDS[1]))
    return NoiseModel(_PHI_MAX / (1.0 + math.exp(-logit)), math.exp(log_ratio))


def _pack(noise: NoiseModel) -> np.ndarray:
    return np.array([math.log(noise.phi / (_PHI_MAX - noise.phi)), math.log(noise.ratio)])


def fit_noise(x: np.ndarray, y: np.ndarray, mask: np.ndarray) -> NoiseModel:
    """White noise plus a Gauss–Markov drift, (φ, ρ) by REML jointly with the regression of
    ``y`` on ``x`` (white alone only when the drift does not raise the restricted likelihood)."""
    xy = np.column_stack([x, y])
    white = -2.0 * _reml(xy, mask, NoiseModel())

    def cost(theta) -> float:
        return -_reml(xy, mask, _unpack(theta))

    lo, hi = (math.log(b) for b in _RATIO_BOUNDS)
    starts = [(logit, math.log(r)) for logit in (0.0, 3.0, 6.0) for r in (0.1, 1.0, 10.0)]
    best = min(starts, key=cost)
    res = optimize.minimize(cost, np.array(best), method="L-BFGS-B", bounds=[_LOGIT_BOUNDS, (lo, hi)])
    # No BIC penalty on the drift: wrongly leaving out a slow drift makes every interval of a
    # slow regressor too narrow, while a drift that is not there only widens them a little.
    return _unpack(res.x) if 2.0 * float(res.fun) < white else NoiseModel()


# Three-point Gauss–Hermite rule per dimension (nodes in standard deviations, weights sum to 1).
_GH_NODES = (-math.sqrt(3.0), 0.0, math.sqrt(3.0))
_GH_WEIGHTS = (1.0 / 6.0, 2.0 / 3.0, 1.0 / 6.0)


def noise_quadrature(x: np.ndarray, y: np.ndarray, mask: np.ndarray,
                     noise: NoiseModel) -> tuple[tuple[NoiseModel, ...], np.ndarray]:
    """Nodes and weights over the REML estimate's uncertainty: a Laplace approximation in
    (logit φ, ln ρ) — the inverse Hessian of −ℓ_R at the estimate — integrated by a 3 × 3
    Gauss–Hermite rule. White noise, or a Hessian that is not positive definite (an estimate
    on a bound), gives the estimate alone."""
    if noise.white_only:
        return (noise,), np.ones(1)
    xy = np.column_stack([x, y])
    theta = _pack(noise)
    h = 0.05

    def cost(t) -> float:
        return -_reml(xy, mask, _unpack(t))

    f0 = cost(theta)
    hess = np.empty((2, 2))
    for i in range(2):
        ei = np.eye(2)[i] * h
        hess[i, i] = (cost(theta + ei) - 2 * f0 + cost(theta - ei)) / h**2
    e0, e1 = np.eye(2)[0] * h, np.eye(2)[1] * h
    hess[0, 1] = hess[1, 0] = (cost(theta + e0 + e1) - cost(theta + e0 - e1)
                               - cost(theta - e0 + e1) + cost(theta - e0 - e1)) / (4 * h**2)
    try:
        lower = np.linalg.cholesky(np.linalg.inv(hess))
    except np.linalg.LinAlgError:
        return (noise,), np.ones(1)
    nodes, weights = [], []
    for z0, w0 in zip(_GH_NODES, _GH_WEIGHTS):
        for z1, w1 in zip(_GH_NODES, _GH_WEIGHTS):
            nodes.append(_unpack(theta + lower @ np.array([z0, z1])))
            weights.append(w0 * w1)
    return tuple(nodes), np.array(weights)


def gls_integrated(x: np.ndarray, y: np.ndarray, mask: np.ndarray, noise: NoiseModel,
                   nodes: tuple[NoiseModel, ...], weights: np.ndarray) -> GlsFit:
    """GLS at ``noise`` with a covariance integrated over the noise parameters' uncertainty
    (:func:`noise_quadrature`): Σ w_j [C_j + (β_j − β̄)(β_j − β̄)ᵀ], the law of total
    variance. A feasible GLS whose drift is estimated from a few hours of record otherwise
    claims too much whenever the REML estimate of the drift falls short."""
    fit = gls(x, y, mask, noise)
    if len(nodes) == 1:
        return fit
    fits = [gls(x, y, mask, nd) for nd in nodes]
    betas = np.array([f.coefficients for f in fits])
    mean = weights @ betas
    cov = sum(w * (f.covariance + np.outer(b - mean, b - mean)) for w, f, b in zip(weights, fits, betas))
    return GlsFit(fit.coefficients, np.asarray(cov), fit.noise, fit.sigma, fit.rss, fit.n, fit.dof, fit.log_det)


def separation(column: np.ndarray, others: np.ndarray) -> float:
    """Fraction of ``column``'s norm outside the span of ``others``' columns (1: orthogonal to
    them, 0: a combination of them) — 1/√VIF of the term the column carries."""
    norm = float(np.linalg.norm(column))
    if norm == 0.0:
        return 0.0
    q, _ = np.linalg.qr(others / np.maximum(np.linalg.norm(others, axis=0), 1e-300))
    rest = column - q @ (q.T @ column)
    return float(np.linalg.norm(rest) / norm)
