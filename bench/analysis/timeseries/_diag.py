"""Residual diagnostics for :mod:`bench.analysis.timeseries._fit`: the Ljung–Box test.

This module holds the Ljung–Box portmanteau test of residual whiteness
(:func:`ljung_box`, returning a :class:`LjungBox`) and the default number of lags it
uses for a model with a given number of parameters (:func:`default_lb_lags`).  It is
re-exported by :mod:`bench.analysis.timeseries._fit`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

from bench.analysis.timeseries._acf import sample_acf


@dataclass(frozen=True)
class LjungBox:
    """Ljung–Box portmanteau test of residual whiteness; ``dof = lags - model_df``.

    Returned by :func:`ljung_box`.

    Attributes
    ----------
    statistic : float
        ``Q = n(n+2) Σ_{k=1}^{lags} r_k² / (n-k)`` (dimensionless).
    p_value : float
        Probability of a χ² with ``dof`` degrees of freedom exceeding ``Q``; small values
        reject whiteness.
    lags : int
        Number of autocorrelation lags in ``Q``.
    dof : int
        Degrees of freedom, ``lags − model_df``.
    """

    statistic: float
    p_value: float
    lags: int
    dof: int


def ljung_box(residuals: np.ndarray, lags: int, model_df: int = 0, _acf: np.ndarray | None = None) -> LjungBox:
    """Ljung–Box portmanteau test of whiteness of ``residuals``.

    ``Q = n(n+2) Σ_{k=1}^{lags} r_k² / (n-k)`` against χ² with ``lags - model_df`` dof.

    ``_acf``: the residuals' sample ACF from lag 0 to at least ``lags``, if already computed.

    Parameters
    ----------
    residuals : array_like of float, shape (n,)
        Residuals of a fitted model (or any series), in any unit.
    lags : int
        Number of autocorrelation lags summed, in ``(model_df, n)``.
    model_df : int, default 0
        Parameters of the model the residuals come from (``p + q`` for an ARMA), removed from
        the degrees of freedom.
    _acf : ndarray, optional
        Internal: the residuals' sample ACF from lag 0 to at least ``lags``, if already computed.

    Returns
    -------
    LjungBox
        Statistic ``Q``, its p-value, ``lags`` and the degrees of freedom.

    Raises
    ------
    ValueError
        If ``lags`` is not in ``(model_df, n)``, or the residuals fail :func:`sample_acf`'s checks.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from bench.analysis.timeseries import ljung_box
    >>> e = np.random.default_rng(0).normal(size=5000)
    >>> lb = ljung_box(e, 20)
    >>> lb.dof, bool(lb.p_value > 0.05)  # white noise passes
    (20, True)
    >>> x = lfilter([1.0], [1.0, -0.6], e)  # AR(1) does not
    >>> bool(ljung_box(x, 20).p_value < 1e-6)
    True
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
    """Lags for the whiteness test: 20 or ``model_df + 10`` if larger, at most ``n // 5``.

    Parameters
    ----------
    n : int
        Number of residuals.
    model_df : int
        Parameters of the fitted model (``p + q``).

    Returns
    -------
    int
        ``min(max(20, model_df + 10), n // 5)`` lags.

    Raises
    ------
    ValueError
        If that number does not exceed ``model_df`` (too few residuals for the model).

    Examples
    --------
    >>> from bench.analysis.timeseries import default_lb_lags
    >>> default_lb_lags(5000, 2), default_lb_lags(5000, 15), default_lb_lags(60, 2)
    (20, 25, 12)
    """
    lags = min(max(20, model_df + 10), n // 5)
    if lags <= model_df:
        raise ValueError(f"{n} residuals are too few to test a model with {model_df} parameters")
    return lags
