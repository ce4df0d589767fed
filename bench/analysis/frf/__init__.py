"""Stepped-sine frequency response of a sensor against a reference, and the time base between two records.

What a user calls::

    frf, FrfResult, frf_point, FrfPoint, sine_fit, SineFit, component_std
    TimeBase, estimate_time_base, apply_time_base, resample, aperture_compensate

The modules behind it are private: import from ``bench.analysis.frf``.
"""

from bench.analysis.frf._stepped_sine import FrfPoint, FrfResult, SineFit, component_std, frf, frf_point, sine_fit
from bench.analysis.frf._timebase import TimeBase, aperture_compensate, apply_time_base, estimate_time_base, resample

__all__ = [
    "FrfPoint",
    "FrfResult",
    "SineFit",
    "TimeBase",
    "aperture_compensate",
    "apply_time_base",
    "component_std",
    "estimate_time_base",
    "frf",
    "frf_point",
    "resample",
    "sine_fit",
]
