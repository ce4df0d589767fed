"""Random-vibration error model of a gyro channel (Document C): EMD, AR per IMF, AR-Kalman fit.

What a user calls::

    kalman_ar_fit, KalmanFit
    model_imf, ImfModel
    analyze_vibration, VibrationAnalysis, FitError

The modules behind it are private: import from ``bench.analysis.vibration``.
"""

from bench.analysis.vibration._ar_kalman import KalmanFit, kalman_ar_fit
from bench.analysis.vibration._ar_models import ImfModel, model_imf
from bench.analysis.vibration._pipeline import FitError, VibrationAnalysis, analyze_vibration

__all__ = ["FitError", "ImfModel", "KalmanFit", "VibrationAnalysis", "analyze_vibration", "kalman_ar_fit", "model_imf"]
