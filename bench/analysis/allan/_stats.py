"""Confidence intervals of the overlapping Allan deviation: EDF and chi-squared bounds.

Equivalent degrees of freedom (EDF) follow Greenhall & Riley, "Uncertainty of stability
variances based on finite differences" (35th PTTI, 2003), the algorithm Stable32 and
allantools' ``edf_greenhall`` implement, for the unmodified overlapping Allan variance
(``d = 2``, ``F = m``, stride ``S = m``) and power-law noise ``S_y(f) ∝ f^α``,
``α ∈ {2, 1, 0, −1, −2}``.  For white phase noise (α = 2) the second differences are
correlated only at lags ``m`` and ``2m``, so the EDF is evaluated exactly,
``M² / (M + 2(M−m)⁺·(4/6)² + 2(M−2m)⁺·(1/6)²)``, which equals Greenhall's table
formula where that applies and also covers ``M < 2m``.

The interval for the deviation at confidence ``c`` is
``σ̂·√(edf / χ²_{(1+c)/2}(edf))`` … ``σ̂·√(edf / χ²_{(1−c)/2}(edf))`` (NIST SP 1065
eq. 45).  The chi-squared quantile is computed here (numpy and the standard library
only): Newton on the regularised incomplete gamma function from the Wilson–Hilferty
start for ``edf < 10⁵``; above that Wilson–Hilferty itself (relative error < 10⁻⁷).
"""

from __future__ import annotations

import math

import numpy as np

#: probability inside ±1 standard deviation of a normal distribution (68.27 %)
ONE_SIGMA = math.erf(1.0 / math.sqrt(2.0))
ALPHAS = (2, 1, 0, -1, -2)

_J_MAX = 100
# Greenhall & Riley Table 2 (d = 2): 1/edf ≈ (a0 − a1/r)/r for long records
_TABLE2 = {2: (35.0 / 18.0, 1.0), 1: (790.0, 410.0), 0: (2.0 / 3.0, 1.0 / 3.0),
           -1: (0.852, 0.375), -2: (1.079, 0.368)}
_TABLE3_D2 = (15.23, 12.0)  # flicker PM normalisation b0 + b1·ln m
_WH_ABOVE = 1e5


def _sw(t: np.ndarray | float, alpha: int) -> np.ndarray:
    """Greenhall's generalised autocovariance kernel ``sw(t)`` for noise exponent α."""
    abs_t = np.abs(np.asarray(t, dtype=float))
    if alpha == 2:
        return -abs_t
    if alpha == 0:
        return abs_t ** 3
    if alpha == -2:
        return abs_t ** 5
    power = {1: 2, -1: 4}[alpha]
    with np.errstate(divide="ignore", invalid="ignore"):
        out = abs_t ** power * np.log(abs_t)
    return np.where(abs_t == 0.0, 0.0, out)


def _sx(t: np.ndarray | float, f: float, alpha: int) -> np.ndarray:
    if math.isinf(f):
        return _sw(t, alpha + 2)
    return f * f * (2.0 * _sw(t, alpha) - _sw(t - 1.0 / f, alpha) - _sw(t + 1.0 / f, alpha))


def _sz(t: np.ndarray | float, f: float, alpha: int) -> np.ndarray:
    """Second-difference (d = 2) filter applied to ``sx``."""
    return (6.0 * _sx(t, f, alpha) - 4.0 * _sx(t - 1.0, f, alpha) - 4.0 * _sx(t + 1.0, f, alpha)
            + _sx(t - 2.0, f, alpha) + _sx(t + 2.0, f, alpha))


def _basic_sum(j_lim: int, m_terms: float, stride: float, f: float, alpha: int) -> float:
    """Greenhall's BasicSum: ``sz(0)² + (1−J/M)·sz(J/S)² + 2·Σ_{j<J} (1−j/M)·sz(j/S)²``."""
    j = np.arange(1, int(j_lim))
    inner = np.sum((1.0 - j / m_terms) * _sz(j / stride, f, alpha) ** 2)
    return float(_sz(0.0, f, alpha) ** 2 + (1.0 - j_lim / m_terms) * _sz(j_lim / stride, f, alpha) ** 2
                 + 2.0 * inner)


def _inverse_edf(alpha: int, m: int, n_phase: int) -> float:
    """``1/edf`` of the overlapping Allan variance at ``τ = m·τ0`` from ``n_phase`` phase points."""
    terms = n_phase - 2 * m
    r = terms / m
    if alpha == 2:
        lag1, lag2 = max(terms - m, 0), max(terms - 2 * m, 0)
        return (terms + 2.0 * lag1 * (4.0 / 6.0) ** 2 + 2.0 * lag2 * (1.0 / 6.0) ** 2) / terms ** 2
    j_lim = min(terms, 3 * m)
    if alpha == 1:
        b0, b1 = _TABLE3_D2
        if j_lim <= _J_MAX:
            return _basic_sum(j_lim, terms, m, m, 1) / (float(_sz(0.0, m, 1)) ** 2 * terms)
        if r > 3:
            a0, a1 = _TABLE2[1]
            return (a0 - a1 / r) / ((b0 + b1 * math.log(m)) ** 2 * r)
        mp = _J_MAX / r
        return _basic_sum(_J_MAX, _J_MAX, mp, mp, 1) / ((b0 + b1 * math.log(m)) ** 2 * _J_MAX)
    if j_lim <= _J_MAX:
        f = float(m) if 3 * m <= _J_MAX else math.inf
        return _basic_sum(j_lim, terms, m, f, alpha) / (float(_sz(0.0, f, alpha)) ** 2 * terms)
    if r > 3:
        a0, a1 = _TABLE2[alpha]
        return (a0 - a1 / r) / r
    mp = _J_MAX / r
    return _basic_sum(_J_MAX, _J_MAX, mp, math.inf, alpha) / (float(_sz(0.0, math.inf, alpha)) ** 2 * _J_MAX)


def edf_greenhall(alpha: np.ndarray | int, m: np.ndarray | int, n_phase: int) -> np.ndarray:
    """Equivalent degrees of freedom of the overlapping Allan variance (module docstring).

    ``alpha``: noise exponent(s) in {2, 1, 0, −1, −2}; ``m``: averaging factor(s) ≥ 1 with
    ``n_phase − 2m ≥ 1``; ``n_phase``: phase points (rate samples + 1).

    Greenhall & Riley (35th PTTI, 2003), as Stable32 and allantools' ``edf_greenhall``, for
    the unmodified overlapping variance (``d = 2``, ``F = m``, ``S = m``) and power-law noise
    ``S_y(f) ∝ f^α``; white phase noise (α = 2) is evaluated exactly.

    Parameters
    ----------
    alpha : int or array_like of int
        Noise exponent(s) α: 2 white PM, 1 flicker PM, 0 white FM, −1 flicker FM, −2
        random-walk FM.  Broadcast against ``m``.
    m : int or array_like of int
        Averaging factor(s) τ/τ0, each in ``[1, (n_phase − 1) // 2]``.
    n_phase : int
        Number of phase points of the record (rate samples + 1).

    Returns
    -------
    ndarray of float
        EDF (dimensionless) with the broadcast shape of ``alpha`` and ``m``.

    Raises
    ------
    ValueError
        If an α is not one of {2, 1, 0, −1, −2} or an ``m`` is outside ``[1, (n_phase − 1) // 2]``.

    Examples
    --------
    >>> from bench.analysis.allan import edf_greenhall
    >>> edf_greenhall(0, [1, 10, 100], 1001).round(1).tolist()  # white FM: fewer dof at long τ
    [782.0, 135.1, 12.8]
    >>> edf_greenhall([2, 0, -2], 10, 1001).round(1).tolist()  # at one τ, by noise type
    [507.2, 135.1, 91.0]
    """
    alpha_arr, m_arr = np.broadcast_arrays(np.asarray(alpha), np.asarray(m))
    out = np.empty(alpha_arr.shape, dtype=float)
    for idx, (a, mm) in enumerate(zip(alpha_arr.ravel(), m_arr.ravel())):
        a, mm = int(a), int(mm)
        if a not in ALPHAS:
            raise ValueError(f"alpha = {a} is not a supported noise exponent (allowed: {ALPHAS})")
        if mm < 1 or n_phase - 2 * mm < 1:
            raise ValueError(f"m = {mm} must be in [1, {(n_phase - 1) // 2}] for {n_phase} phase points")
        out.flat[idx] = 1.0 / _inverse_edf(a, mm, n_phase)
    return out


def _normal_ppf(p: float) -> float:
    """Standard normal quantile by Newton on ``math.erf`` (|error| < 1e-14 for 1e-12 < p < 1 − 1e-12)."""
    z = 0.0
    for _ in range(100):
        step = (0.5 * (1.0 + math.erf(z / math.sqrt(2.0))) - p) / (math.exp(-0.5 * z * z) / math.sqrt(2 * math.pi))
        z -= max(-2.0, min(2.0, step))
        if abs(step) < 1e-15 * max(1.0, abs(z)):
            break
    return z


def upper_normal_quantile(p: float) -> float:
    """``z`` with ``P(Z > z) = p`` for a standard normal ``Z``, ``0 < p < 1/2`` (Newton on ``erfc``)."""
    z = math.sqrt(-2.0 * math.log(p))  # a start above the root
    for _ in range(100):
        tail = 0.5 * math.erfc(z / math.sqrt(2.0))
        step = (tail - p) / (math.exp(-0.5 * z * z) / math.sqrt(2.0 * math.pi))  # d tail/dz = −φ(z)
        z += step
        if abs(step) < 1e-13 * max(1.0, z):
            break
    return z


def _gamma_p(a: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Regularised lower incomplete gamma ``P(a, x)`` by its power series, in logs (x > 0)."""
    n_terms = int(np.clip(np.max(x - a + 30.0 * np.sqrt(x + 1.0) + 50.0), 50, 200_000))
    k = np.arange(1, n_terms + 1)
    log_terms = np.cumsum(np.log(x)[:, None] - np.log(a[:, None] + k[None, :]), axis=1)
    top = np.maximum(0.0, log_terms.max(axis=1))
    log_sum = top + np.log(np.exp(-top) + np.exp(log_terms - top[:, None]).sum(axis=1))
    lgam1 = np.array([math.lgamma(v + 1.0) for v in a])
    return np.exp(np.minimum(0.0, -x + a * np.log(x) - lgam1 + log_sum))


def chi2_ppf(p: float, dof: np.ndarray) -> np.ndarray:
    """Quantile of the chi-squared distribution with (real) ``dof > 0`` at probability ``0 < p < 1``."""
    dof = np.atleast_1d(np.asarray(dof, dtype=float))
    z = _normal_ppf(p)
    h = 2.0 / (9.0 * dof)
    wh = dof * np.maximum(1.0 - h + z * np.sqrt(h), 1e-3) ** 3  # Wilson–Hilferty
    out = wh.copy()
    small = dof < _WH_ABOVE
    if np.any(small):
        a = dof[small] / 2.0
        x = wh[small] / 2.0
        lo, hi = np.zeros_like(x), np.full_like(x, np.inf)
        lgam = np.array([math.lgamma(v) for v in a])
        active = np.arange(a.size)
        for _ in range(200):
            aa, xx = a[active], x[active]
            cdf = _gamma_p(aa, xx)
            lo[active] = np.where(cdf < p, xx, lo[active])
            hi[active] = np.where(cdf >= p, xx, hi[active])
            pdf = np.exp((aa - 1.0) * np.log(xx) - xx - lgam[active])
            with np.errstate(divide="ignore", invalid="ignore"):
                step = (cdf - p) / pdf
            new = xx - step
            # converged: a negligible step, or the CDF equals p to its own precision (the log
            # of its prefactor sums terms of size ~x + a·|ln x|, each rounded)
            cdf_tol = 4e-16 * (xx + aa * np.abs(np.log(xx)) + np.abs(lgam[active]) + 1.0)
            done = np.isfinite(step) & ((np.abs(step) <= 1e-13 * xx) | (np.abs(cdf - p) <= cdf_tol))
            # keep Newton inside the bracket; bisect (or double) otherwise
            lo_a, hi_a = lo[active], hi[active]
            bad = ~done & (~np.isfinite(new) | (new <= lo_a) | (new >= hi_a))
            new = np.where(bad, np.where(np.isfinite(hi_a), 0.5 * (lo_a + hi_a), 2.0 * xx), new)
            x[active] = new
            active = active[~done]
            if active.size == 0:
                break
        out[small] = 2.0 * x
    return out


def adev_interval(adev: np.ndarray, edf: np.ndarray, confidence: float = ONE_SIGMA) -> np.ndarray:
    """``(lo, hi)`` per deviation at ``confidence`` for chi-squared with ``edf`` degrees of freedom.

    ``lo = σ̂·√(edf / χ²_{(1+c)/2}(edf))`` and ``hi = σ̂·√(edf / χ²_{(1−c)/2}(edf))``
    (NIST SP 1065 eq. 45), the chi-squared quantile computed in this module.

    Parameters
    ----------
    adev : array_like of float, shape (k,)
        Allan deviations, in any unit.
    edf : array_like of float, shape (k,)
        Their equivalent degrees of freedom, > 0 (e.g. from :func:`edf_greenhall`).
    confidence : float, default ONE_SIGMA
        Two-sided confidence level ``c`` in (0, 1); default 0.6827 (one sigma).

    Returns
    -------
    ndarray of float, shape (k, 2)
        Lower and upper bound of each deviation, in the unit of ``adev``.

    Examples
    --------
    >>> from bench.analysis.allan import adev_interval
    >>> adev_interval([1.0, 1.0], [50.0, 5000.0]).round(3).tolist()  # ≈ ±1/√(2·edf)
    [[0.913, 1.117], [0.99, 1.01]]
    >>> adev_interval([1.0], [50.0], confidence=0.95).round(3).tolist()
    [[0.837, 1.243]]
    """
    adev, edf = np.asarray(adev, dtype=float), np.asarray(edf, dtype=float)
    tail = (1.0 - confidence) / 2.0
    lo = adev * np.sqrt(edf / chi2_ppf(1.0 - tail, edf))
    hi = adev * np.sqrt(edf / chi2_ppf(tail, edf))
    return np.column_stack([lo, hi])
