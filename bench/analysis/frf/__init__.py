"""Stepped-sine frequency response of a sensor against a reference, and the time base between two records.

At each frequency of a stepped-sine run on the angular vibration table, the reference and the
sensor's output are each fitted by :func:`sine_fit` over the same whole-period window; the
ratio of their complex amplitudes is the sensor's response (:func:`frf_point`), and
:func:`frf`, the main entry point, collects the dwells into an :class:`FrfResult` whose
``weights`` feed :func:`bench.analysis.fusion.fit_transfer_function`. A sensor on its own
clock is put onto the table's first: :func:`estimate_time_base` measures the clock's rate
error from a tone, :func:`apply_time_base` corrects the timestamps and :func:`resample` moves
a record onto another's grid; :func:`aperture_compensate` undoes an interval mean's droop.

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
