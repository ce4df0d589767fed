"""Stationary time-series tools for the start-up model (Document A, steps 6–7).

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
from scipy import fft as sp_fft
from scipy import stats
from scipy.signal import lfilter

ArMethod = Literal["ulrych-clayton", "burg", "yule-walker"]
AR_METHODS: tuple[str, ...] = ("ulrych-clayton", "burg", "yule-walker")


def _series(x: np.ndarray, min_len: int, name: str = "x") -> np.ndarray:
    """Return ``x`` as a demeaned 1-D float array, after checking length and finiteness."""
    arr = np.asarray(x, dtype=float)
    if arr.ndim != 1:
        raise ValueError(f"{name} must be one-dimensional, got shape {arr.shape}")
    if arr.size < min_len:
        raise ValueError(f"{name} has {arr.size} samples; at least {min_len} are required")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} contains {int(np.sum(~np.isfinite(arr)))} non-finite values; all must be finite")
    out = arr - arr.mean()
    if not np.any(out):
        raise ValueError(f"{name} is constant; there is nothing to model")
    return out


def _check_order(order: int, n: int, name: str = "p") -> int:
    if int(order) != order or order < 0:
        raise ValueError(f"{name} = {order!r} must be a non-negative integer")
    if order > max(0, n // 10):
        raise ValueError(f"{name} = {order} needs at least {10 * order} samples, got {n} (allowed {name} ≤ {n // 10})")
    return int(order)


# --------------------------------------------------------------------------- correlation


def sample_acf(x: np.ndarray, nlags: int) -> np.ndarray:
    """Biased sample autocorrelation ``r_0..r_nlags`` (``r_0 = 1``), computed by FFT."""
    xd = _series(x, 2)
    n = xd.size
    if not 0 <= nlags < n:
        raise ValueError(f"nlags = {nlags} must be in [0, {n - 1}]")
    nfft = sp_fft.next_fast_len(2 * n - 1, real=True)  # ≥ 2n - 1: no circular wrap-around
    spec = sp_fft.rfft(xd, nfft)
    acov = sp_fft.irfft(spec.real**2 + spec.imag**2, nfft)[: nlags + 1] / n
    if acov[0] <= 0:
        raise ValueError("x is constant; its autocorrelation is undefined")
    return acov / acov[0]


def levinson_durbin(r: np.ndarray, order: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Solve the Yule–Walker equations for autocovariances ``r[0..order]``.

    Returns ``(phi, pacf, sigma2)``: AR coefficients of order ``order``, the partial
    autocorrelations ``pacf[0..order]`` (``pacf[0] = 1``) and the innovation variance of
    every intermediate order ``sigma2[0..order]``.
    """
    r = np.asarray(r, dtype=float)
    phi = np.zeros(0)
    pacf = np.ones(order + 1)
    sigma2 = np.empty(order + 1)
    sigma2[0] = r[0]
    for k in range(1, order + 1):
        kappa = (r[k] - phi @ r[k - 1 : 0 : -1]) / sigma2[k - 1]
        phi = np.concatenate([phi - kappa * phi[::-1], [kappa]])
        pacf[k] = kappa
        sigma2[k] = sigma2[k - 1] * (1.0 - kappa**2)
    return phi, pacf, sigma2


def sample_pacf(x: np.ndarray, nlags: int) -> np.ndarray:
    """Partial autocorrelation ``pacf[0..nlags]`` by Levinson–Durbin on the biased ACF."""
    return levinson_durbin(sample_acf(x, nlags), nlags)[1]


@dataclass(frozen=True, eq=False)
class Correlogram:
    """Sample ACF/PACF with the half-widths of their ``1 - alpha`` confidence bands.

    ``acf_band[k]`` follows Bartlett's formula (an MA(k-1) null hypothesis, the right
    test for "the ACF cuts off after lag k-1"); ``pacf_band`` is ``z / sqrt(n)`` (the
    PACF of an AR(p) is asymptotically N(0, 1/n) beyond lag p).  Index = lag.
    """

    acf: np.ndarray
    acf_band: np.ndarray
    pacf: np.ndarray
    pacf_band: float
    alpha: float
    n: int

    @property
    def nlags(self) -> int:
        return self.acf.size - 1


def correlogram(x: np.ndarray, nlags: int | None = None, alpha: float = 0.05) -> Correlogram:
    """ACF and PACF of ``x`` up to ``nlags`` (default ``min(max(20, 10 log10 n), n // 4)``)."""
    n = np.asarray(x).size
    if n < 8:
        raise ValueError(f"x has {n} samples; at least 8 are required for a correlogram")
    if not 0 < alpha < 1:
        raise ValueError(f"alpha = {alpha} must be in (0, 1)")
    if nlags is None:
        nlags = min(max(20, int(10 * np.log10(n))), n // 4)
    if not 1 <= nlags <= n // 2:
        raise ValueError(f"nlags = {nlags} must be in [1, {n // 2}]")
    acf = sample_acf(x, nlags)
    z = stats.norm.ppf(1 - alpha / 2)
    var = np.full(nlags + 1, 1.0 / n)
    var[0] = 0.0
    var[2:] *= 1 + 2 * np.cumsum(acf[1:-1] ** 2)
    pacf = levinson_durbin(acf, nlags)[1]
    return Correlogram(acf, z * np.sqrt(var), pacf, float(z / np.sqrt(n)), alpha, n)


# --------------------------------------------------------------------------- identification


@dataclass(frozen=True)
class Identification:
    """Model class and initial orders proposed by Document A's ACF/PACF table."""

    kind: Literal["AR", "MA", "ARMA"]
    p: int
    q: int
    acf_cutoff: int | None  # last significant ACF lag if the ACF cuts off, else None
    pacf_cutoff: int | None
    reason: str


def cutoff_lag(values: np.ndarray, band: np.ndarray | float, max_order: int, alpha: float = 0.05) -> int | None:
    """Lag ``k ≤ max_order`` after which a correlation sequence "cuts off", else None.

    ``values[0]`` is lag 0 and is ignored.  It cuts off after ``k`` when the drop is
    abrupt — lag ``k`` at least twice its band (k ≥ 1), lag ``k + 1`` inside — and no
    more later lags stick out than white noise would by chance (the 99 % point of
    Binomial(m, alpha): about ``alpha`` of white lags fall outside a ``1 - alpha`` band).
    A geometric decay crosses the band gradually, so it fails the first test and counts
    as tailing off.
    """
    vals = np.abs(np.asarray(values, dtype=float))
    bands = np.broadcast_to(band, vals.shape)
    outside = vals[1:] > bands[1:]
    for k in range(0, min(max_order, outside.size - 1) + 1):
        later = outside[k:]
        abrupt = k == 0 or vals[k] >= 2 * bands[k]
        if abrupt and not later[0] and later.sum() <= stats.binom.ppf(0.99, later.size, alpha):
            return k
    return None


def identify(corr: Correlogram, max_order: int = 8) -> Identification:
    """Apply the cut-off/tail-off rules: AR if only the PACF cuts off, MA if only the ACF,
    the shorter of the two if both do (parsimony), ARMA(1, 1) to start with if neither."""
    a = cutoff_lag(corr.acf, corr.acf_band, max_order, corr.alpha)
    p = cutoff_lag(corr.pacf, corr.pacf_band, max_order, corr.alpha)
    if a is None and p is None:
        return Identification("ARMA", 1, 1, a, p, "ACF and PACF both tail off")
    if a is None or (p is not None and p <= a):
        why = "ACF tails off" if a is None else f"ACF cuts off only after lag {a}"
        return Identification("AR", p, 0, a, p, f"PACF cuts off after lag {p}; {why}")
    why = "PACF tails off" if p is None else f"PACF cuts off only after lag {p}"
    return Identification("MA", 0, a, a, p, f"ACF cuts off after lag {a}; {why}")


# --------------------------------------------------------------------------- AR estimators


def _full_lag_sums(x: np.ndarray, size: int) -> np.ndarray:
    """``full[d] = sum_{s=d}^{n-1} x[s] x[s-d]`` for ``d = 0..size-1``."""
    return np.array([x[d:] @ x[: x.size - d] for d in range(size)])


def _lag_sums(x: np.ndarray, start: int, size: int, full: np.ndarray | None = None) -> np.ndarray:
    """``F[i, j] = sum_{t=start}^{n-1} x[t-i] x[t-j]`` for ``0 ≤ i, j < size ≤ start + 1``.

    One full-length dot product per lag difference (``full``, reusable across calls),
    then exact corrections at the ends: O(n·size) instead of the O(n·size²) of forming
    the lagged data matrix.
    """
    n = x.size
    full = _full_lag_sums(x, size) if full is None else full
    out = np.empty((size, size))
    for i in range(size):
        for j in range(i, size):
            d = j - i  # s = t - i runs over [start - i, n - 1 - i]; full[d] over [d, n - 1]
            head = x[d : start - i] @ x[: start - i - d]
            tail = x[n - i :] @ x[n - i - d : n - d]
            out[i, j] = out[j, i] = full[d] - head - tail
    return out


def ulrych_clayton(x: np.ndarray, p: int, _full: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """AR(p) by the Ulrych–Clayton (forward–backward least squares, modified covariance) method.

    Minimises ``sum_{t=p}^{n-1} [(x_t - Σ φ_k x_{t-k})² + (x_{t-p} - Σ φ_k x_{t-p+k})²]``
    over ``φ``: the forward and the time-reversed (backward) prediction errors share one
    coefficient vector.  Returns ``(phi, sigma2)`` with ``sigma2`` the mean of the ``2(n-p)``
    squared errors.  Stationarity is not guaranteed (unlike Burg/Yule–Walker).
    """
    xd = _series(x, 2)
    p = _check_order(p, xd.size)
    if p == 0:
        return np.zeros(0), float(xd @ xd / xd.size)
    f = _lag_sums(xd, p, p + 1, _full)
    c = f + f[::-1, ::-1]  # backward errors: indices mirrored, w_i x_{t-p+i}
    phi = np.linalg.solve(c[1:, 1:], c[1:, 0])
    w = np.concatenate([[1.0], -phi])
    return phi, float(w @ c @ w / (2 * (xd.size - p)))


def burg(x: np.ndarray, p: int) -> tuple[np.ndarray, float]:
    """AR(p) by Burg's method; ``sigma2`` is the mean squared forward–backward error."""
    phi, sigma2 = _burg_path(_series(x, 2), _check_order(p, np.asarray(x).size))
    return phi[-1], float(sigma2[-1])


def _burg_path(xd: np.ndarray, pmax: int) -> tuple[list[np.ndarray], np.ndarray]:
    """Burg recursion returning the AR coefficients and ``sigma2`` of every order 0..pmax."""
    f, b, old_f, step = xd.copy(), xd.copy(), np.empty_like(xd), np.empty_like(xd)
    phis, sig = [np.zeros(0)], [xd @ xd / xd.size]
    for k in range(1, pmax + 1):
        # f_{k-1}(t) and b_{k-1}(t-1), t = k..n-1, updated in place (views of shrinking
        # length): the same arithmetic as fresh arrays, without 10⁶-sample allocations
        f, b = f[1:], b[:-1]
        m = f.size
        kappa = 2 * (f @ b) / (f @ f + b @ b)
        np.copyto(old_f[:m], f)
        f -= np.multiply(b, kappa, out=step[:m])
        b -= np.multiply(old_f[:m], kappa, out=step[:m])
        phis.append(np.concatenate([phis[-1] - kappa * phis[-1][::-1], [kappa]]))
        sig.append((f @ f + b @ b) / (2 * (xd.size - k)))
    return phis, np.array(sig)


def yule_walker(x: np.ndarray, p: int) -> tuple[np.ndarray, float]:
    """AR(p) by Yule–Walker (method of moments) on the biased autocovariances."""
    xd = _series(x, 2)
    p = _check_order(p, xd.size)
    r = np.array([xd[k:] @ xd[: xd.size - k] for k in range(p + 1)]) / xd.size
    phi, _, sigma2 = levinson_durbin(r, p)
    return phi, float(sigma2[-1])


def _ar_path(xd: np.ndarray, pmax: int, method: str) -> list[tuple[np.ndarray, float]]:
    """Coefficients and ``sigma2`` for every order 0..pmax with one estimator."""
    if method == "burg":
        phis, sig = _burg_path(xd, pmax)
        return list(zip(phis, sig.tolist()))
    if method == "yule-walker":
        r = np.array([xd[k:] @ xd[: xd.size - k] for k in range(pmax + 1)]) / xd.size
        fits = [levinson_durbin(r, k) for k in range(pmax + 1)]
        return [(phi, float(sig[-1])) for phi, _, sig in fits]
    if method == "ulrych-clayton":
        full = _full_lag_sums(xd, pmax + 1)
        return [ulrych_clayton(xd, k, full) for k in range(pmax + 1)]
    raise ValueError(f"AR method {method!r} is not one of {AR_METHODS}")


# --------------------------------------------------------------------------- fitted models


@dataclass(frozen=True, eq=False)
class ArmaFit:
    """A fitted zero-mean ARMA(p, q) model (conventions in the module docstring)."""

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

    ``f`` may be a precomputed ``_lag_sums(xd, n_condition, size)`` with ``size > p``.
    """
    f = _lag_sums(xd, n_condition, phi.size + 1) if f is None else f[: phi.size + 1, : phi.size + 1]
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
    """
    xd = _series(x, 16)
    p = _check_order(p, xd.size)
    n_condition = p if n_condition is None else n_condition
    if not p <= n_condition < xd.size // 2:
        raise ValueError(f"n_condition = {n_condition} must be in [{p}, {xd.size // 2 - 1}]")
    phi, sigma2 = _ar_path(xd, p, method)[-1] if method != "ulrych-clayton" else ulrych_clayton(xd, p)
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
    """
    from statsmodels.tsa.arima.model import ARIMA  # heavy import, only needed here

    xd = _series(x, 16)
    p, q = _check_order(p, xd.size, "p"), _check_order(q, xd.size, "q")
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
    """
    xd = _series(x, 16)
    p, q = _check_order(p, xd.size, "p"), _check_order(q, xd.size, "q")
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
    p: int
    q: int
    aic: float
    bic: float


@dataclass(frozen=True)
class OrderSelection:
    """AIC/BIC over a grid of orders; ``best_aic``/``best_bic`` are ``(p, q)``."""

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
    """
    xd = _series(x, 16)
    max_p = _check_order(max_p, xd.size, "max_p")
    max_q = _check_order(max_q, xd.size, "max_q")
    cells: list[OrderCandidate] = []
    if kind == "AR":
        f = _lag_sums(xd, max_p, max_p + 1)
        for k, (phi, _) in enumerate(_ar_path(xd, max_p, ar_method)):
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


def ar_interpolate(x: np.ndarray, missing: np.ndarray, phi: np.ndarray, sweeps: int = 10) -> np.ndarray:
    """Replace ``x[missing]`` by their conditional expectation given the other samples under AR(phi).

    For a zero-mean AR(p) with ``a = [1, -φ1, …, -φp]`` the two-sided interpolator is
    ``x̂_t = -Σ_{k=1..p} ρi_k (x_{t-k} + x_{t+k})`` with the inverse autocorrelations
    ``ρi_k = Σ_j a_j a_{j+k} / Σ_j a_j²`` (exact for isolated gaps away from the ends).
    Adjacent gaps are solved by repeating the update (``sweeps`` Jacobi passes).  The
    values in ``x[missing]`` on entry are the starting guess (e.g. linear interpolation).
    """
    out = np.array(x, dtype=float)
    idx = np.flatnonzero(missing)
    phi = np.asarray(phi, dtype=float)
    if idx.size == 0 or phi.size == 0:
        if idx.size:
            out[idx] = 0.0  # white noise: the best guess of a missing sample is the mean
        return out
    a = np.r_[1.0, -phi]
    p = phi.size
    rho_inv = np.array([a[: a.size - k] @ a[k:] for k in range(1, p + 1)]) / (a @ a)
    pad = np.r_[np.zeros(p), out, np.zeros(p)]  # samples beyond the ends count as the mean
    for _ in range(sweeps):
        guess = -sum(rho_inv[k - 1] * (pad[idx + p - k] + pad[idx + p + k]) for k in range(1, p + 1))
        pad[idx + p] = guess
    return pad[p:-p]


def burg_bic(x: np.ndarray, max_p: int) -> tuple[np.ndarray, float]:
    """Burg AR model with the BIC order (p ≤ max_p), from one Burg recursion: a quick,
    always-stationary noise model for standard errors and interpolation."""
    xd = _series(x, 16)
    max_p = _check_order(max_p, xd.size, "max_p")
    phis, sig = _burg_path(xd, max_p)
    f = _lag_sums(xd, max_p, max_p + 1)
    bics = [_conditional_ic(xd, phi, max_p, f)[2] for phi in phis]
    best = int(np.argmin(bics))
    return phis[best], float(sig[best])


# --------------------------------------------------------------------------- diagnostics


@dataclass(frozen=True)
class LjungBox:
    """Ljung–Box portmanteau test of residual whiteness; ``dof = lags - model_df``."""

    statistic: float
    p_value: float
    lags: int
    dof: int


def ljung_box(residuals: np.ndarray, lags: int, model_df: int = 0, _acf: np.ndarray | None = None) -> LjungBox:
    """``Q = n(n+2) Σ_{k=1}^{lags} r_k² / (n-k)`` against χ² with ``lags - model_df`` dof.

    ``_acf``: the residuals' sample ACF from lag 0 to at least ``lags``, if already computed.
    """
    n = np.asarray(residuals).size
    if not model_df < lags < n:
        raise ValueError(f"lags = {lags} must be in ({model_df}, {n}) (model_df = {model_df}, n = {n})")
    if _acf is not None and np.size(_acf) > lags:
        r = np.asarray(_acf, dtype=float)[1 : lags + 1]
    else:
        r = sample_acf(residuals, lags)[1:]
    q = float(n * (n + 2) * np.sum(r**2 / (n - np.arange(1, lags + 1))))
    return LjungBox(q, float(stats.chi2.sf(q, lags - model_df)), lags, lags - model_df)


def default_lb_lags(n: int, model_df: int) -> int:
    """Lags for the whiteness test: 20 or ``model_df + 10`` if larger, at most ``n // 5``."""
    lags = min(max(20, model_df + 10), n // 5)
    if lags <= model_df:
        raise ValueError(f"{n} residuals are too few to test a model with {model_df} parameters")
    return lags
