"""Allan deviation of a static record and the IEEE Std 952 noise terms read from it.

The overlapping Allan deviation (NIST SP 1065) of a gyro or accelerometer record taken at
rest, with Greenhall EDF confidence intervals, and the five IEEE 952 terms — quantization
Q, random walk N, bias instability B, rate random walk K and ramp R — both fitted (weighted
non-negative least squares of the Allan variance model) and read off slope lines, in the
customary units of the sensor.  The entry point is :func:`overlapping_adev`, which returns
an :class:`AllanResult`; the other functions are its building blocks, for refitting a curve
(:func:`fit_noise_terms`, :func:`read_off`), drawing slope lines (:func:`term_adev`) or
intervals of other estimates (:func:`edf_greenhall`, :func:`adev_interval`).

``robust=True`` replaces isolated outliers first (:func:`screen_outliers`, at a stated
false-alarm rate per record); every term is checked against the curve by name
(:class:`TermCheck`: the slope the curve shows where the term dominates, and the read-off
with its interval against the fit); a sample-to-sample correlated output has its N fitted
as white noise through a first-order low-pass.

What a user calls::

    overlapping_adev, AllanResult, NoiseCoefficient, averaging_factors
    fit_noise_terms, NoiseFit, read_off, ReadOff, term_adev, TERMS, B_FACTOR
    adev_interval, edf_greenhall, ONE_SIGMA
    screen_outliers, OutlierScreen, DEFAULT_FALSE_ALARM, TermCheck, CHECK_CONFIDENCE

The modules behind it are private: import from ``bench.analysis.allan``.
"""

from bench.analysis.allan._adev import AllanResult, NoiseCoefficient, averaging_factors, overlapping_adev
from bench.analysis.allan._checks import CHECK_CONFIDENCE, TermCheck
from bench.analysis.allan._noise import B_FACTOR, TERMS, NoiseFit, ReadOff, fit_noise_terms, read_off, term_adev
from bench.analysis.allan._robust import DEFAULT_FALSE_ALARM, OutlierScreen, screen_outliers
from bench.analysis.allan._stats import ONE_SIGMA, adev_interval, edf_greenhall

__all__ = [
    "AllanResult",
    "B_FACTOR",
    "CHECK_CONFIDENCE",
    "DEFAULT_FALSE_ALARM",
    "NoiseCoefficient",
    "NoiseFit",
    "ONE_SIGMA",
    "OutlierScreen",
    "ReadOff",
    "TERMS",
    "TermCheck",
    "adev_interval",
    "averaging_factors",
    "edf_greenhall",
    "fit_noise_terms",
    "overlapping_adev",
    "read_off",
    "screen_outliers",
    "term_adev",
]
