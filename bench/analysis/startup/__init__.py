"""Start-up model of a quartz flexure accelerometer (Document A): denoise, trend, time-series model.

A power-on trace (time in s, output in V, mA or g) is denoised with Daubechies wavelets
(universal soft threshold), fitted with an exponential settling plus linear drift
``c + a·exp(−t/τ) + b·t``, and its standardised residual modelled as an AR, MA or ARMA
process chosen by ACF/PACF identification and AIC/BIC.  The entry point is
:func:`analyze_startup`, which returns a :class:`StartupAnalysis`; its ``model``, a
:class:`StartupModel`, prints its equation and simulates new start-up traces.  The steps
are callable on their own (:func:`wavelet_denoise`, :func:`fit_trend`); :func:`validate_trace`
and :func:`json_safe` are the input check and JSON helper the pipeline (and
:mod:`bench.analysis.vibration`) share.

What a user calls::

    wavelet_denoise, DenoiseResult
    analyze_startup, StartupAnalysis, StartupModel, Outliers, validate_trace, json_safe
    fit_trend, TrendFit

The modules behind it are private: import from ``bench.analysis.startup``.
"""

from bench.analysis.startup._denoise import DenoiseResult, wavelet_denoise
from bench.analysis.startup._pipeline import (
    Outliers,
    StartupAnalysis,
    StartupModel,
    analyze_startup,
    json_safe,
    validate_trace,
)
from bench.analysis.startup._trend import TrendFit, fit_trend

__all__ = [
    "DenoiseResult",
    "Outliers",
    "StartupAnalysis",
    "StartupModel",
    "TrendFit",
    "analyze_startup",
    "fit_trend",
    "json_safe",
    "validate_trace",
    "wavelet_denoise",
]
