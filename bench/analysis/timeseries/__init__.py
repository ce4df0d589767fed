"""Stationary time-series models: ACF/PACF identification, AR and ARMA fits, order selection, whiteness.

The Box–Jenkins workflow for a zero-mean stationary series (lags in samples; the
sampling interval stays with the caller): :func:`correlogram` and :func:`identify` propose
a model class and orders from the ACF/PACF cut-off/tail-off table, :func:`select_order`
fills the AIC/BIC table over a grid of orders, :func:`fit_ar` (Ulrych–Clayton, Burg or
Yule–Walker), :func:`fit_arma_css` (conditional least squares) and :func:`fit_arma_ml`
(exact maximum likelihood) return an :class:`ArmaFit`, and :func:`ljung_box` tests the
residuals' whiteness.  The model is
``x_k = Σ φ_i x_{k−i} + e_k + Σ θ_j e_{k−j}`` (statsmodels' sign convention).

What a user calls::

    correlogram, Correlogram, identify, Identification, sample_acf, sample_pacf
    ulrych_clayton, burg, yule_walker, AR_METHODS
    ljung_box, LjungBox, default_lb_lags
    fit_ar, fit_arma_ml, fit_arma_css, ArmaFit, select_order, OrderSelection, OrderCandidate

The modules behind it are private: import from ``bench.analysis.timeseries``.
"""

from bench.analysis.timeseries._acf import Correlogram, Identification, correlogram, identify, sample_acf, sample_pacf
from bench.analysis.timeseries._ar import AR_METHODS, burg, ulrych_clayton, yule_walker
from bench.analysis.timeseries._diag import LjungBox, default_lb_lags, ljung_box
from bench.analysis.timeseries._fit import (
    ArmaFit,
    OrderCandidate,
    OrderSelection,
    fit_ar,
    fit_arma_css,
    fit_arma_ml,
    select_order,
)

__all__ = [
    "AR_METHODS",
    "ArmaFit",
    "Correlogram",
    "Identification",
    "LjungBox",
    "OrderCandidate",
    "OrderSelection",
    "burg",
    "correlogram",
    "default_lb_lags",
    "fit_ar",
    "fit_arma_css",
    "fit_arma_ml",
    "identify",
    "ljung_box",
    "sample_acf",
    "sample_pacf",
    "select_order",
    "ulrych_clayton",
    "yule_walker",
]
