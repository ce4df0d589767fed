"""Start-up model of a quartz flexure accelerometer (Document A): denoise, trend, time-series model.

What a user calls::

    wavelet_denoise, DenoiseResult
    analyze_startup, StartupAnalysis, StartupModel, validate_trace, json_safe
    fit_trend, TrendFit

The modules behind it are private: import from ``bench.analysis.startup``.
"""

from bench.analysis.startup._denoise import DenoiseResult, wavelet_denoise
from bench.analysis.startup._pipeline import StartupAnalysis, StartupModel, analyze_startup, json_safe, validate_trace
from bench.analysis.startup._trend import TrendFit, fit_trend

__all__ = [
    "DenoiseResult",
    "StartupAnalysis",
    "StartupModel",
    "TrendFit",
    "analyze_startup",
    "fit_trend",
    "json_safe",
    "validate_trace",
    "wavelet_denoise",
]
