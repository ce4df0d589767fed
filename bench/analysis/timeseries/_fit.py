"""Stationary time-series tools for the start-up model (Document A, steps 6–7).

This module holds the fitted-model layer: :class:`ArmaFit`, the AR fit with
standard errors and conditional likelihood (:func:`fit_ar`), exact ML (:func:`fit_arma_ml`)
and conditional-least-squares ARMA fitting (:func:`fit_arma_css`, Hannan–Rissanen start
values), and order selection by AIC/BIC (:func:`select_order`, :func:`burg_bic`).  It is
the module the library's other methods import from: it re-exports the correlation and
identification tools of :mod:`._acf`, the AR estimators of :mod:`._ar` and the Ljung–Box
test of :mod:`._diag` (users import from :mod:`bench.analysis.timeseries`).

Conventions used throughout:

* The ARMA(p, q) model of a zero-mean series ``x`` is
  ``x_k = φ1 x_{k-1} + … + φp x_{k-p} + e_k + θ1 e_{k-1} + … + θq e_{k-q}``,
  ``e_k`` white with variance ``sigma2`` (statsmodels' sign convention).
  Lags are in samples; the sampling interval lives with the caller.
* Every estimator subtracts the sample mean first (as statsmodels does).
* Autocovariances are the biased (divide by N) estimates, which keep the Toeplitz
  matrices positive definite.
* ``aic = -2 ln L + 2k`` and ``bic = -2 ln L + k ln n`` with ``k = p + q + 1`` (the
  innovation variance counts as a parameter).  For AR least-squares fits ``ln L`` is the
  Gaussian likelihood conditional on the first ``n_condition`` samples, likewise for the
  conditional-least-squares ARMA fits; for statsmodels' ML fits it is the exact
  likelihood.  Criteria are comparable within one order-selection table, whose cells
  all use one definition and one conditioning sample.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy.signal import lfilter
from statsmodels.tsa.arima.model import ARIMA

from bench.analysis.timeseries._acf import (
    Correlogram,
    Identification,
    as_series,
    check_order,
    correlogram,
    cutoff_lag,
    identify,
    levinson_durbin,
    sample_acf,
    sample_pacf,
)
from bench.analysis.timeseries._ar import (
    AR_METHODS,
    ArMethod,
    ar_interpolate,
    ar_path,
    burg,
    burg_path,
    lag_sums,
    ulrych_clayton,
    yule_walker,
)
from bench.analysis.timeseries._diag import LjungBox, default_lb_lags, ljung_box

__all__ = [
    "AR_METHODS", "ArMethod", "ArmaFit", "CSS_SEGMENT", "Correlogram", "Identification", "LjungBox",
    "OrderCandidate", "OrderSelection", "ar_interpolate", "burg", "burg_bic", "correlogram", "cutoff_lag",
    "default_lb_lags", "fit_ar", "fit_arma_css", "fit_arma_ml", "identify", "levinson_durbin", "ljung_box",
    "sample_acf", "sample_pacf", "select_order", "ulrych_clayton", "yule_walker",
]


@dataclass(frozen=True, eq=False)
class ArmaFit:
    """A fitted zero-mean ARMA(p, q) model (conventions in the module docstring).

    ``x_k = φ1 x_{k-1} + … + φp x_{k-p} + e_k + θ1 e_{k-1} + … + θq e_{k-q}``, ``e_k`` white
    with variance ``sigma2``; ``x`` is the series with its sample mean removed, in unit ``u``.

    Attributes
    ----------
    kind : {"AR", "MA", "ARMA"}
        Model class (``"AR"`` also for p = q = 0, white noise).
    p : int
        AR order.
    q : int
        MA order.
    ar : tuple of float
        φ1..φp (dimensionless).
    ma : tuple of float
        θ1..θq (dimensionless, statsmodels' sign convention).
    ar_std : tuple of float
        Standard errors of ``ar``.
    ma_std : tuple of float
        Standard errors of ``ma``.
    sigma2 : float
        Innovation variance, in ``u²``.
    loglik : float
        Gaussian log-likelihood (conditional for ``fit_ar``/``fit_arma_css``, exact for ``fit_arma_ml``).
    aic : float
        ``-2 ln L + 2k``, ``k = p + q + 1``.
    bic : float
        ``-2 ln L + k ln n``.
    method : str
        Estimator: an AR method name, ``"ml"`` or ``"css"`` (or a note on a fallback).
    n : int
        Length of the series, in samples.
    residuals : ndarray of float
        One-step prediction errors, in ``u`` (AR fits: from sample p on).
    is_stationary : bool
        Property: every root of ``1 - Σ φ_k z^k`` lies outside the unit circle.
    """

    kind: Literal["AR", "MA", "ARMA"]
    p: int
    q: int
    ar: tuple[float, ...]
    ma: tuple[float, ...]
    ar_std: tuple[float, ...]
    ma_std: tuple[float, ...]
    sigma2: float
    loglik: float
    aic: float
    bic: float
    method: str
    n: int
    residuals: np.ndarray  # one-step prediction errors, in the units of x

    @property
    def is_stationary(self) -> bool:
        """True when every root of ``1 - Σ φ_k z^k`` lies outside the unit circle."""
        return self.p == 0 or bool(np.all(np.abs(np.roots(np.r_[1.0, -np.asarray(self.ar)][::-1])) > 1.0))


def _kind(p: int, q: int) -> Literal["AR", "MA", "ARMA"]:
    return "ARMA" if p and q else ("MA" if q else "AR")


def _conditional_ic(
    xd: np.ndarray, phi: np.ndarray, n_condition: int, f: np.ndarray | None = None
) -> tuple[float, float, float, int]:
    """Conditional Gaussian (loglik, aic, bic, n) of an AR fit on samples ``n_condition..n-1``.

    ``f`` may be a precomputed ``lag_sums(xd, n_condition, size)`` with ``size > p``.
    """
    f = lag_sums(xd, n_condition, phi.size + 1) if f is None else f[: phi.size + 1, : phi.size + 1]
    w = np.r_[1.0, -phi]
    n = xd.size - n_condition
    s2 = float(w @ f @ w) / n
    ll = -0.5 * n * (np.log(2 * np.pi * s2) + 1)
    k = phi.size + 1
    return ll, -2 * ll + 2 * k, -2 * ll + k * np.log(n), n


def fit_ar(x: np.ndarray, p: int, method: ArMethod = "ulrych-clayton", n_condition: int | None = None) -> ArmaFit:
    """Fit AR(p) with one of the least-squares/moment estimators.

    ``ar_std`` is the asymptotic ``sqrt(diag(sigma2 Γ_p⁻¹ / n))`` (``Γ_p`` the Toeplitz
    matrix of sample autocovariances), shared by all three estimators.  ``n_condition``
    (default ``p``) sets the samples conditioned on in the likelihood, so a table of orders
    can use one common sample.

    Parameters
    ----------
    x : array_like of float, shape (n,)
        The series, in any unit ``u``; finite, not constant, n ≥ 16; the sample mean is removed.
    p : int
        AR order, a non-negative integer ≤ ``n // 10``.
    method : {"ulrych-clayton", "burg", "yule-walker"}, default "ulrych-clayton"
        Estimator (:func:`ulrych_clayton`, :func:`burg`, :func:`yule_walker`).
    n_condition : int, optional
        Samples conditioned on in the likelihood, in ``[p, n // 2 − 1]``; default ``p``.

    Returns
    -------
    ArmaFit
        ``kind="AR"``, coefficients with standard errors, ``sigma2`` in ``u²``, conditional
        log-likelihood, AIC/BIC, and the ``n − p`` residuals in ``u``.

    Raises
    ------
    ValueError
        If ``x`` is not 1-D, has fewer than 16 samples, a non-finite value or is constant,
        ``p`` is not a non-negative integer ≤ ``n // 10``, ``n_condition`` is outside
        ``[p, n // 2 − 1]`` or ``method`` is not one of :data:`AR_METHODS`.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> x = lfilter([1.0], [1.0, -0.6], np.random.default_rng(0).normal(size=5000))  # AR(1), φ = 0.6, σ² = 1
    >>> from bench.analysis.timeseries import fit_ar
    >>> fit = fit_ar(x, 1)
    >>> fit.kind, fit.method, fit.residuals.size
    ('AR', 'ulrych-clayton', 4999)
    >>> bool(abs(fit.ar[0] - 0.6) < 3 * fit.ar_std[0]), round(fit.ar_std[0], 3)
    (True, 0.011)
    >>> round(fit.sigma2, 2), fit.is_stationary
    (0.99, True)
    """
    xd = as_series(x, 16)
    p = check_order(p, xd.size)
    n_condition = p if n_condition is None else n_condition
    if not p <= n_condition < xd.size // 2:
        raise ValueError(f"n_condition = {n_condition} must be in [{p}, {xd.size // 2 - 1}]")
    phi, sigma2 = ar_path(xd, p, method)[-1] if method != "ulrych-clayton" else ulrych_clayton(xd, p)
    if p:
        r = np.array([xd[k:] @ xd[: xd.size - k] for k in range(p)]) / xd.size
        gamma = r[np.abs(np.subtract.outer(np.arange(p), np.arange(p)))]
        std = tuple(np.sqrt(np.diag(sigma2 * np.linalg.inv(gamma)) / xd.size).tolist())
    else:
        std = ()
    ll, aic, bic, _ = _conditional_ic(xd, phi, n_condition)
    resid = lfilter(np.r_[1.0, -phi], [1.0], xd)[p:]
    return ArmaFit("AR", p, 0, tuple(phi.tolist()), (), std, (), sigma2, ll, aic, bic, method, xd.size, resid)


def fit_arma_ml(x: np.ndarray, p: int, q: int) -> ArmaFit:
    """Fit ARMA(p, q) by exact Gaussian maximum likelihood (statsmodels ``ARIMA``, no constant).

    Uses the innovations-algorithm likelihood (same optimum as the state-space one, several
    times faster); stationarity and invertibility are enforced by the parametrisation.

    Parameters
    ----------
    x : array_like of float, shape (n,)
        The series, in any unit ``u``; finite, not constant, n ≥ 16; the sample mean is removed.
    p : int
        AR order, a non-negative integer ≤ ``n // 10``.
    q : int
        MA order, a non-negative integer ≤ ``n // 10``.

    Returns
    -------
    ArmaFit
        ``method="ml"``: coefficients with standard errors, ``sigma2`` in ``u²``, exact
        log-likelihood, AIC/BIC and the ``n`` residuals in ``u``.

    Raises
    ------
    ValueError
        If ``x`` is not 1-D, has fewer than 16 samples, a non-finite value or is constant, or
        ``p`` or ``q`` is not a non-negative integer ≤ ``n // 10``.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> e = np.random.default_rng(1).normal(size=3000)
    >>> x = lfilter([1.0, 0.4], [1.0, -0.5], e)  # ARMA(1, 1): φ = 0.5, θ = 0.4, σ² = 1
    >>> from bench.analysis.timeseries import fit_arma_ml
    >>> fit = fit_arma_ml(x, 1, 1)
    >>> fit.kind, fit.method
    ('ARMA', 'ml')
    >>> round(fit.ar[0], 1), round(fit.ma[0], 1), round(fit.sigma2, 1)
    (0.5, 0.4, 1.0)
    """
    xd = as_series(x, 16)
    p, q = check_order(p, xd.size, "p"), check_order(q, xd.size, "q")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # convergence chatter; the fit is still the best found
        res = ARIMA(xd, order=(p, 0, q), trend="n").fit(method="innovations_mle")
    params, bse = np.asarray(res.params), np.asarray(res.bse)
    return ArmaFit(
        _kind(p, q), p, q,
        tuple(params[:p].tolist()), tuple(params[p : p + q].tolist()),
        tuple(bse[:p].tolist()), tuple(bse[p : p + q].tolist()),
        float(params[-1]), float(res.llf), float(res.aic), float(res.bic), "ml", xd.size,
        np.asarray(res.resid),
    )


def _long_ar_residuals(xd: np.ndarray) -> tuple[np.ndarray, int]:
    """Residuals of a long Yule–Walker AR(m), m ≈ 10 log10 n: the innovations estimate of Hannan–Rissanen."""
    m = min(max(8, int(10 * np.log10(xd.size))), xd.size // 10)
    return lfilter(np.r_[1.0, -levinson_durbin(sample_acf(xd, m), m)[0]], [1.0], xd), m


def _hannan_rissanen(xd: np.ndarray, p: int, q: int, long_ar: tuple[np.ndarray, int] | None = None) -> np.ndarray:
    """Hannan–Rissanen start values: OLS of x on its lags and on lagged long-AR residuals."""
    e, m = _long_ar_residuals(xd) if long_ar is None else long_ar
    k = max(p, q) + m
    cols = [xd[k - i : xd.size - i] for i in range(1, p + 1)] + [e[k - j : xd.size - j] for j in range(1, q + 1)]
    return np.linalg.lstsq(np.column_stack(cols), xd[k:], rcond=None)[0]


def _admissible(theta: np.ndarray, p: int) -> bool:
    """AR part stationary and MA part invertible (all polynomial roots outside the unit circle)."""
    return all(np.all(np.abs(np.roots(np.r_[1.0, c])) < 1.0) for c in (-theta[:p], theta[p:]) if c.size)


CSS_SEGMENT = 1 << 16  # longer series: Gauss–Newton converges on this leading segment first


def _css_start(xd: np.ndarray, p: int, q: int, long_ar: tuple[np.ndarray, int] | None) -> np.ndarray:
    """Start values for the CSS Gauss–Newton.

    Up to ``4·CSS_SEGMENT`` samples: Hannan–Rissanen on the whole series.  Longer: the
    converged CSS fit of the first ``CSS_SEGMENT`` samples (its error, ~n_seg^-1/2, is a
    few full-length standard errors, which one or two full-length Gauss–Newton steps
    remove), so the expensive iterations run on 65 536 samples instead of 10⁶.
    ``long_ar`` must belong to the series the Hannan–Rissanen step runs on.
    """
    if xd.size > 4 * CSS_SEGMENT:
        seg = xd[:CSS_SEGMENT] - xd[:CSS_SEGMENT].mean()
        fit = fit_arma_css(seg, p, q, _long_ar=long_ar)
        return np.r_[fit.ar, fit.ma]
    start = _hannan_rissanen(xd, p, q, long_ar)
    return next((f * start for f in (1.0, 0.9, 0.5) if _admissible(f * start, p)), np.zeros(p + q))


def _segment_long_ar(xd: np.ndarray) -> tuple[np.ndarray, int]:
    """Long-AR residuals for the start values of :func:`fit_arma_css` on ``xd`` (see :func:`_css_start`)."""
    if xd.size > 4 * CSS_SEGMENT:
        return _long_ar_residuals(xd[:CSS_SEGMENT] - xd[:CSS_SEGMENT].mean())
    return _long_ar_residuals(xd)


def fit_arma_css(
    x: np.ndarray, p: int, q: int, n_condition: int | None = None, _long_ar: tuple[np.ndarray, int] | None = None,
    _start: np.ndarray | None = None,
) -> ArmaFit:
    """ARMA(p, q) by conditional least squares (conditional Gaussian ML).

    Residuals ``e = (1 - Σφ B^k)/(1 + Σθ B^k) x`` start from zero pre-sample values; the
    first ``n_condition`` (default ``max(p, q)``) are left out of the likelihood.
    Gauss–Newton from Hannan–Rissanen start values with the analytic Jacobian
    ``∂e_t/∂φ_k = -[x/θ(B)]_{t-k}``, ``∂e_t/∂θ_k = -[e/θ(B)]_{t-k}``, halving any step that
    leaves the stationary/invertible region or raises the sum of squares.  O(n) per
    iteration and asymptotically as efficient as exact ML: the workhorse of the order grid.
    ``ar_std``/``ma_std`` are ``sqrt(diag(sigma2 (JᵀJ)⁻¹))``.  Series longer than
    ``4·CSS_SEGMENT`` start from the converged fit of their first ``CSS_SEGMENT`` samples
    (:func:`_css_start`).  ``_long_ar`` (long-AR residuals of the series the start values
    come from, :func:`_segment_long_ar`) and ``_start`` (admissible start values, e.g. a
    neighbouring fit) let a caller share work between fits.

    Parameters
    ----------
    x : array_like of float, shape (n,)
        The series, in any unit ``u``; finite, not constant, n ≥ 16; the sample mean is removed.
    p : int
        AR order, a non-negative integer ≤ ``n // 10``.
    q : int
        MA order, a non-negative integer ≤ ``n // 10``.
    n_condition : int, optional
        Leading residuals left out of the likelihood, in ``[max(p, q), n // 2 − 1]``;
        default ``max(p, q)``.
    _long_ar : tuple of (ndarray, int), optional
        Internal: long-AR residuals and their order for the Hannan–Rissanen start.
    _start : ndarray, optional
        Internal: admissible start values ``[φ1..φp, θ1..θq]``; ignored if not admissible.

    Returns
    -------
    ArmaFit
        ``method="css"``: coefficients with standard errors, ``sigma2`` in ``u²``, conditional
        log-likelihood, AIC/BIC and the ``n − n_condition`` residuals in ``u``.

    Raises
    ------
    ValueError
        If ``x`` is not 1-D, has fewer than 16 samples, a non-finite value or is constant,
        ``p`` or ``q`` is not a non-negative integer ≤ ``n // 10``, or ``n_condition`` is
        outside ``[max(p, q), n // 2 − 1]``.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> e = np.random.default_rng(1).normal(size=3000)
    >>> x = lfilter([1.0, 0.4], [1.0, -0.5], e)  # ARMA(1, 1): φ = 0.5, θ = 0.4, σ² = 1
    >>> from bench.analysis.timeseries import fit_arma_css
    >>> fit = fit_arma_css(x, 1, 1)
    >>> fit.method, fit.residuals.size
    ('css', 2999)
    >>> round(fit.ar[0], 1), round(fit.ma[0], 1), round(fit.sigma2, 1)
    (0.5, 0.4, 1.0)
    >>> bool(abs(fit.ma[0] - 0.4) < 3 * fit.ma_std[0])
    True
    """
    xd = as_series(x, 16)
    p, q = check_order(p, xd.size, "p"), check_order(q, xd.size, "q")
    m = max(p, q) if n_condition is None else n_condition
    if not max(p, q) <= m < xd.size // 2:
        raise ValueError(f"n_condition = {n_condition} must be in [{max(p, q)}, {xd.size // 2 - 1}]")

    def resid_jac(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        ma = np.r_[1.0, theta[p:]]
        e = lfilter(np.r_[1.0, -theta[:p]], ma, xd)
        jac = np.empty((xd.size - m, p + q))
        xf = lfilter([1.0], ma, xd) if p else xd
        ef = lfilter([1.0], ma, e) if q else e
        for k in range(1, p + 1):
            jac[:, k - 1] = -xf[m - k : xd.size - k]
        for k in range(1, q + 1):
            jac[:, p + k - 1] = -ef[m - k : xd.size - k]
        return e[m:], jac

    theta = np.zeros(p + q)
    if p + q:
        if _start is not None and np.shape(_start) == (p + q,) and _admissible(np.asarray(_start, float), p):
            theta = np.array(_start, dtype=float)
        else:
            theta = _css_start(xd, p, q, _long_ar)
    e, jac = resid_jac(theta)
    if p + q:
        for _ in range(100):
            gram = jac.T @ jac
            grad = jac.T @ e
            d = 1.0 / np.sqrt(np.maximum(np.diag(gram), 1e-300))  # equilibrate the normal equations
            step = d * np.linalg.solve(gram * np.outer(d, d) + 1e-12 * np.eye(p + q), -d * grad)
            sse = e @ e
            # the Gauss–Newton model predicts an SSE drop of -grad·step; below the stopping
            # gain (log-likelihood 0.005) no evaluation of the step is worth its O(n) cost
            if -(grad @ step) <= 0.005 / e.size * sse:
                break
            while np.max(np.abs(step)) > 1e-12:
                trial = theta + step
                if _admissible(trial, p):
                    e_new, jac_new = resid_jac(trial)
                    if e_new @ e_new <= sse:
                        break
                step = step / 2
            else:
                break  # no descent step left: converged
            # misspecified cells (e.g. MA(1) for ARMA(1,1) data) make Gauss–Newton overshoot
            # and zig-zag; one step to the minimum of the parabola through SSE(0), SSE'(0)
            # and SSE(step) removes most of it at the cost of one evaluation
            curv = e_new @ e_new - sse - 2 * (grad @ step)
            alpha = -(grad @ step) / curv if curv > 0 else 1.0
            if abs(alpha - 1.0) > 0.25 and 0.0 < alpha < 4.0 and _admissible(theta + alpha * step, p):
                e_alt, jac_alt = resid_jac(theta + alpha * step)
                if e_alt @ e_alt < e_new @ e_new:
                    trial, e_new, jac_new = theta + alpha * step, e_alt, jac_alt
            theta, e, jac = trial, e_new, jac_new
            if sse - e @ e <= 0.01 / e.size * sse:  # log-likelihood gain below 0.005
                break
    sigma2 = float(e @ e / e.size)
    std = np.sqrt(np.diag(sigma2 * np.linalg.pinv(jac.T @ jac))) if p + q else np.zeros(0)
    ll = -0.5 * e.size * (np.log(2 * np.pi * sigma2) + 1)
    k = p + q + 1
    return ArmaFit(_kind(p, q), p, q, tuple(theta[:p].tolist()), tuple(theta[p:].tolist()),
                   tuple(std[:p].tolist()), tuple(std[p:].tolist()), sigma2, ll, -2 * ll + 2 * k,
                   -2 * ll + k * np.log(e.size), "css", xd.size, e)


# --------------------------------------------------------------------------- order selection


@dataclass(frozen=True)
class OrderCandidate:
    """One cell of an AIC/BIC order table: the orders ``(p, q)`` and both criteria there.

    An element of :attr:`OrderSelection.candidates`, returned by :func:`select_order`.

    Attributes
    ----------
    p : int
        AR order.
    q : int
        MA order.
    aic : float
        Akaike information criterion of the ARMA(p, q) fit (dimensionless; smaller is better).
    bic : float
        Bayesian information criterion of the fit (dimensionless; smaller is better).
    """

    p: int
    q: int
    aic: float
    bic: float


@dataclass(frozen=True)
class OrderSelection:
    """AIC/BIC over a grid of orders; ``best_aic``/``best_bic`` are ``(p, q)``.

    Returned by :func:`select_order`.

    Attributes
    ----------
    candidates : tuple of OrderCandidate
        One cell per order pair, each with ``p``, ``q``, ``aic`` and ``bic``, in grid order.
    best_aic : tuple of (int, int)
        ``(p, q)`` of the smallest AIC.
    best_bic : tuple of (int, int)
        ``(p, q)`` of the smallest BIC.
    method : str
        Estimator used for every cell (the AR method, or ``"css"``).
    """

    candidates: tuple[OrderCandidate, ...]
    best_aic: tuple[int, int]
    best_bic: tuple[int, int]
    method: str  # estimator used for every cell


def select_order(
    x: np.ndarray, kind: Literal["AR", "MA", "ARMA"], max_p: int, max_q: int = 0,
    ar_method: ArMethod = "ulrych-clayton", _fits: dict | None = None,
) -> OrderSelection:
    """Fill the AIC/BIC table for ``kind``, every cell conditioned on the same first samples.

    AR: p = 0..max_p by ``ar_method``.  MA: q = 0..max_q; ARMA: p = 0..max_p × q = 0..max_q;
    both by conditional least squares (:func:`fit_arma_css`), which is O(n) per cell.
    ``_fits``, if given, receives every MA/ARMA cell's :class:`ArmaFit` keyed by ``(p, q)``.

    Parameters
    ----------
    x : array_like of float, shape (n,)
        The series, in any unit; finite, not constant, n ≥ 16; the sample mean is removed.
    kind : {"AR", "MA", "ARMA"}
        Model class of the grid.
    max_p : int
        Largest AR order, a non-negative integer ≤ ``n // 10`` (ignored for ``"MA"``).
    max_q : int, default 0
        Largest MA order, a non-negative integer ≤ ``n // 10`` (ignored for ``"AR"``).
    ar_method : {"ulrych-clayton", "burg", "yule-walker"}, default "ulrych-clayton"
        AR estimator of an ``"AR"`` grid.
    _fits : dict, optional
        Internal: receives every MA/ARMA cell's :class:`ArmaFit` keyed by ``(p, q)``.

    Returns
    -------
    OrderSelection
        Every cell's AIC and BIC and the ``(p, q)`` each criterion picks.

    Raises
    ------
    ValueError
        If ``x`` is not 1-D, has fewer than 16 samples, a non-finite value or is constant,
        ``max_p`` or ``max_q`` is not a non-negative integer ≤ ``n // 10``, ``kind`` is not
        ``"AR"``, ``"MA"`` or ``"ARMA"``, or ``ar_method`` is not one of :data:`AR_METHODS`.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> x = lfilter([1.0], [1.0, -0.6], np.random.default_rng(0).normal(size=5000))  # AR(1), φ = 0.6, σ² = 1
    >>> from bench.analysis.timeseries import select_order
    >>> sel = select_order(x, "AR", 5)
    >>> sel.best_aic, sel.best_bic, len(sel.candidates)
    ((1, 0), (1, 0), 6)
    >>> [c.p for c in sel.candidates]
    [0, 1, 2, 3, 4, 5]
    """
    xd = as_series(x, 16)
    max_p = check_order(max_p, xd.size, "max_p")
    max_q = check_order(max_q, xd.size, "max_q")
    cells: list[OrderCandidate] = []
    method: str
    if kind == "AR":
        f = lag_sums(xd, max_p, max_p + 1)
        for k, (phi, _) in enumerate(ar_path(xd, max_p, ar_method)):
            _, aic, bic, _ = _conditional_ic(xd, phi, max_p, f)
            cells.append(OrderCandidate(k, 0, aic, bic))
        method = ar_method
    elif kind in ("MA", "ARMA"):
        m = max(max_p, max_q) if kind == "ARMA" else max_q
        long_ar = _segment_long_ar(xd)  # shared by every cell's start values
        for p in range(max_p + 1) if kind == "ARMA" else [0]:
            for q in range(max_q + 1):
                fit = fit_arma_css(xd, p, q, n_condition=m, _long_ar=long_ar)
                cells.append(OrderCandidate(p, q, fit.aic, fit.bic))
                if _fits is not None:
                    _fits[(p, q)] = fit
        method = "css"
    else:
        raise ValueError(f"kind {kind!r} must be 'AR', 'MA' or 'ARMA'")
    best = {c: min(cells, key=lambda cell: getattr(cell, c)) for c in ("aic", "bic")}
    return OrderSelection(tuple(cells), (best["aic"].p, best["aic"].q), (best["bic"].p, best["bic"].q), method)


def burg_bic(x: np.ndarray, max_p: int) -> tuple[np.ndarray, float]:
    """Burg AR model with the BIC order (p ≤ max_p), from one Burg recursion: a quick,
    always-stationary noise model for standard errors and interpolation."""
    xd = as_series(x, 16)
    max_p = check_order(max_p, xd.size, "max_p")
    phis, sig = burg_path(xd, max_p)
    f = lag_sums(xd, max_p, max_p + 1)
    bics = [_conditional_ic(xd, phi, max_p, f)[2] for phi in phis]
    best = int(np.argmin(bics))
    return phis[best], float(sig[best])
