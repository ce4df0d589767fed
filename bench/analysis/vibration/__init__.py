"""Random-vibration error model of a gyro channel (Document C): EMD, AR per IMF, AR-Kalman fit.

A rate record taken under vibration is split by empirical mode decomposition; the trend
and periodic components are kept as the non-random terms, and every random IMF is tested
(stationarity, whiteness), given a Yule–Walker AR model and fitted twice — by the AR
one-step prediction and by an AR-based Kalman filter — so that the two fits of the record
can be compared by their error statistics.  The entry point is :func:`analyze_vibration`,
which returns a :class:`VibrationAnalysis`; :func:`model_imf` (an :class:`ImfModel`) and
:func:`kalman_ar_fit` (a :class:`KalmanFit`) work on one IMF, and :class:`FitError` holds
the error statistics of a fit.

What a user calls::

    kalman_ar_fit, KalmanFit
    model_imf, ImfModel, StationarityTest, Whiteness
    analyze_vibration, VibrationAnalysis, FitError

The modules behind it are private: import from ``bench.analysis.vibration``.
"""

from bench.analysis.vibration._ar_kalman import KalmanFit, kalman_ar_fit
from bench.analysis.vibration._ar_models import ImfModel, StationarityTest, Whiteness, model_imf
from bench.analysis.vibration._pipeline import FitError, VibrationAnalysis, analyze_vibration

__all__ = [
    "FitError",
    "ImfModel",
    "KalmanFit",
    "StationarityTest",
    "VibrationAnalysis",
    "Whiteness",
    "analyze_vibration",
    "kalman_ar_fit",
    "model_imf",
]
