"""Angular-rate fusion of a high- and a low-frequency sensor (Document B) and its baselines.

What a user calls::

    analyze_fusion, FusionAnalysis, METHODS, BASELINES, excess_over_best
    complementary_kalman
    SensorModel, FusionModel, TransferFit, fit_transfer_function
    sequential_fusion, sequential_kalman, fixed_r_kalman, complementary_filter, FusionParams, AdaptiveNoise, FilterRun
    tune_fusion, FusionTuning

The modules behind it are private: import from ``bench.analysis.fusion``.
"""

from bench.analysis.fusion._analysis import BASELINES, METHODS, FusionAnalysis, analyze_fusion, excess_over_best
from bench.analysis.fusion._complementary import complementary_kalman
from bench.analysis.fusion._models import FusionModel, SensorModel, TransferFit, fit_transfer_function
from bench.analysis.fusion._sequential import (
    AdaptiveNoise,
    FilterRun,
    FusionParams,
    complementary_filter,
    fixed_r_kalman,
    sequential_fusion,
    sequential_kalman,
)
from bench.analysis.fusion._tuning import FusionTuning, tune_fusion

__all__ = [
    "AdaptiveNoise",
    "BASELINES",
    "FilterRun",
    "FusionAnalysis",
    "FusionModel",
    "FusionParams",
    "FusionTuning",
    "METHODS",
    "SensorModel",
    "TransferFit",
    "analyze_fusion",
    "complementary_filter",
    "complementary_kalman",
    "excess_over_best",
    "fit_transfer_function",
    "fixed_r_kalman",
    "sequential_fusion",
    "sequential_kalman",
    "tune_fusion",
]
