"""Input checks, sample correlation and model identification for :mod:`bench.analysis.timeseries._fit`.

This module holds the series/order validators shared by every time-series estimator
(``as_series`` demeans and checks a series, ``check_order`` bounds a model order by the
series length), the FFT sample ACF, Levinson–Durbin and the PACF, the :class:`Correlogram`
with its Bartlett / ``z/sqrt(n)`` confidence bands, and Document A's cut-off/tail-off rules
that propose a model class and initial orders (:func:`cutoff_lag`, :func:`identify`).
Conventions (biased autocovariances, lags in samples) are those of
:mod:`bench.analysis.timeseries._fit`, which re-exports every public name here.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy import fft as sp_fft
from scipy import stats


def as_series(x: np.ndarray, min_len: int, name: str = "x") -> np.ndarray:
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


def check_order(order: int, n: int, name: str = "p") -> int:
    if int(order) != order or order < 0:
        raise ValueError(f"{name} = {order!r} must be a non-negative integer")
    if order > max(0, n // 10):
        raise ValueError(f"{name} = {order} needs at least {10 * order} samples, got {n} (allowed {name} ≤ {n // 10})")
    return int(order)


# --------------------------------------------------------------------------- correlation


def sample_acf(x: np.ndarray, nlags: int) -> np.ndarray:
    """Biased sample autocorrelation ``r_0..r_nlags`` (``r_0 = 1``), computed by FFT.

    ``r_k = c_k / c_0`` with ``c_k = (1/n) Σ_{t=k}^{n-1} x̃_t x̃_{t-k}`` of the demeaned series
    ``x̃`` (the biased estimate, which keeps Toeplitz matrices positive definite).

    Parameters
    ----------
    x : array_like of float, shape (n,)
        The series, in any unit; finite, not constant, n ≥ 2.
    nlags : int
        Largest lag, in samples, in ``[0, n − 1]``.

    Returns
    -------
    ndarray of float, shape (nlags + 1,)
        ``r_0..r_nlags`` (dimensionless, ``r_0 = 1``), index = lag.

    Raises
    ------
    ValueError
        If ``x`` is not 1-D, has fewer than 2 samples, a non-finite value or is constant,
        or ``nlags`` is outside ``[0, n − 1]``.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> x = lfilter([1.0], [1.0, -0.6], np.random.default_rng(0).normal(size=5000))  # AR(1), φ = 0.6
    >>> from bench.analysis.timeseries import sample_acf
    >>> sample_acf(x, 3).round(2).tolist()  # φ^k
    [1.0, 0.6, 0.36, 0.21]
    """
    xd = as_series(x, 2)
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
    """Partial autocorrelation ``pacf[0..nlags]`` by Levinson–Durbin on the biased ACF.

    ``pacf[k]`` is the last coefficient of the Yule–Walker AR(k) fit (the reflection
    coefficient κ_k); the PACF of an AR(p) vanishes beyond lag p.

    Parameters
    ----------
    x : array_like of float, shape (n,)
        The series, in any unit; finite, not constant, n ≥ 2.
    nlags : int
        Largest lag, in samples, in ``[0, n − 1]``.

    Returns
    -------
    ndarray of float, shape (nlags + 1,)
        Partial autocorrelations (dimensionless, ``pacf[0] = 1``), index = lag.

    Raises
    ------
    ValueError
        As :func:`sample_acf`.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> x = lfilter([1.0], [1.0, -0.6], np.random.default_rng(0).normal(size=5000))  # AR(1), φ = 0.6
    >>> from bench.analysis.timeseries import sample_pacf
    >>> pacf = sample_pacf(x, 3)
    >>> round(float(pacf[1]), 2), bool(np.all(np.abs(pacf[2:]) < 2 / np.sqrt(x.size)))  # cuts off after lag 1
    (0.6, True)
    """
    return levinson_durbin(sample_acf(x, nlags), nlags)[1]


@dataclass(frozen=True, eq=False)
class Correlogram:
    """Sample ACF/PACF with the half-widths of their ``1 - alpha`` confidence bands.

    ``acf_band[k]`` follows Bartlett's formula (an MA(k-1) null hypothesis, the right
    test for "the ACF cuts off after lag k-1"); ``pacf_band`` is ``z / sqrt(n)`` (the
    PACF of an AR(p) is asymptotically N(0, 1/n) beyond lag p).  Index = lag.

    Attributes
    ----------
    acf : ndarray of float, shape (nlags + 1,)
        Biased sample autocorrelation, ``acf[0] = 1`` (dimensionless).
    acf_band : ndarray of float, shape (nlags + 1,)
        Half-width of the ACF band at each lag, ``z·sqrt((1 + 2 Σ_{j<k} r_j²)/n)``; 0 at lag 0.
    pacf : ndarray of float, shape (nlags + 1,)
        Sample partial autocorrelation, ``pacf[0] = 1``.
    pacf_band : float
        Half-width of the PACF band, ``z / sqrt(n)``.
    alpha : float
        Significance level of the bands, in (0, 1).
    n : int
        Length of the series, in samples.
    nlags : int
        Property: largest lag.
    """

    acf: np.ndarray
    acf_band: np.ndarray
    pacf: np.ndarray
    pacf_band: float
    alpha: float
    n: int

    @property
    def nlags(self) -> int:
        """Largest lag of the correlogram, in samples."""
        return self.acf.size - 1


def correlogram(x: np.ndarray, nlags: int | None = None, alpha: float = 0.05) -> Correlogram:
    """ACF and PACF of ``x`` up to ``nlags`` (default ``min(max(20, 10 log10 n), n // 4)``).

    Bands are two-sided at level ``1 − alpha`` with ``z = Φ⁻¹(1 − alpha/2)``: Bartlett's
    formula for the ACF, ``z / sqrt(n)`` for the PACF (see :class:`Correlogram`).

    Parameters
    ----------
    x : array_like of float, shape (n,)
        The series, in any unit; finite, not constant, n ≥ 8.
    nlags : int, optional
        Largest lag in samples, in ``[1, n // 2]``; default ``min(max(20, 10 log10 n), n // 4)``.
    alpha : float, default 0.05
        Significance level of the bands, in (0, 1).

    Returns
    -------
    Correlogram
        ACF, PACF and their band half-widths, index = lag.

    Raises
    ------
    ValueError
        If ``x`` has fewer than 8 samples (or fails :func:`sample_acf`'s checks), ``alpha`` is
        outside (0, 1) or ``nlags`` outside ``[1, n // 2]``.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> x = lfilter([1.0], [1.0, -0.6], np.random.default_rng(0).normal(size=5000))  # AR(1), φ = 0.6
    >>> from bench.analysis.timeseries import correlogram
    >>> c = correlogram(x)
    >>> c.nlags, round(c.pacf_band, 4)  # 10 log10(5000) lags; 1.96 / sqrt(5000)
    (36, 0.0277)
    >>> bool(c.acf[1] > c.acf_band[1]), bool(abs(c.pacf[2]) < c.pacf_band)
    (True, True)
    """
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
    """Model class and initial orders proposed by Document A's ACF/PACF table.

    Returned by :func:`identify`.

    Attributes
    ----------
    kind : {"AR", "MA", "ARMA"}
        Proposed model class.
    p : int
        Proposed AR order.
    q : int
        Proposed MA order.
    acf_cutoff : int or None
        Last significant ACF lag if the ACF cuts off, else None (it tails off).
    pacf_cutoff : int or None
        Last significant PACF lag if the PACF cuts off, else None.
    reason : str
        The rule that decided, in words.
    """

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
    the shorter of the two if both do (parsimony), ARMA(1, 1) to start with if neither.

    A sequence cuts off after lag k when lag k is at least twice its band, lag k + 1 is
    inside, and no more later lags stick out than white noise would by chance
    (:func:`~bench.analysis.timeseries._acf.cutoff_lag`); otherwise it tails off.

    Parameters
    ----------
    corr : Correlogram
        ACF/PACF with bands, from :func:`correlogram`.
    max_order : int, default 8
        Largest cut-off lag (model order) considered, in samples.

    Returns
    -------
    Identification
        Model class, initial orders ``p``, ``q``, the cut-off lags and the reason.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> x = lfilter([1.0], [1.0, -0.6], np.random.default_rng(0).normal(size=5000))  # AR(1), φ = 0.6
    >>> from bench.analysis.timeseries import correlogram, identify
    >>> ident = identify(correlogram(x))
    >>> ident.kind, ident.p, ident.q
    ('AR', 1, 0)
    >>> ident.reason
    'PACF cuts off after lag 1; ACF tails off'
    """
    a = cutoff_lag(corr.acf, corr.acf_band, max_order, corr.alpha)
    p = cutoff_lag(corr.pacf, corr.pacf_band, max_order, corr.alpha)
    if p is not None and (a is None or p <= a):
        why = "ACF tails off" if a is None else f"ACF cuts off only after lag {a}"
        return Identification("AR", p, 0, a, p, f"PACF cuts off after lag {p}; {why}")
    if a is not None:
        why = "PACF tails off" if p is None else f"PACF cuts off only after lag {p}"
        return Identification("MA", 0, a, a, p, f"ACF cuts off after lag {a}; {why}")
    return Identification("ARMA", 1, 1, a, p, "ACF and PACF both tail off")
