"""Pure analysis functions: arrays and numbers in, small frozen dataclasses out (no I/O).

Start-up model of Document A: :func:`analyze_startup` runs the whole pipeline; the
pieces live in :mod:`.denoise`, :mod:`.trend` and :mod:`.timeseries`.
"""

from bench.analysis.denoise import DenoiseResult, wavelet_denoise
from bench.analysis.startup import StartupAnalysis, StartupModel, analyze_startup, validate_trace
from bench.analysis.trend import Estimate, TrendFit, fit_trend

__all__ = [
    "DenoiseResult",
    "Estimate",
    "StartupAnalysis",
    "StartupModel",
    "TrendFit",
    "analyze_startup",
    "fit_trend",
    "validate_trace",
    "wavelet_denoise",
]
