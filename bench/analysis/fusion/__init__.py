"""Angular-rate fusion of a high- and a low-frequency sensor (Document B) and its baselines.

Two coaxial rate sensors see the same rate: an HF sensor (a high-pass, e.g. an MHD) and an
LF sensor (a low-pass, e.g. a FOG), each described by a :class:`SensorModel`, fitted to a
measured FRF by :func:`fit_transfer_function`. :func:`analyze_fusion`, the main entry point,
runs every fusion method (:data:`METHODS`) on one record: each sensor alone, the
complementary filter (:func:`complementary_filter`), Document B's sequential adaptive-R Kalman
filter (:func:`sequential_fusion`, tuned by :func:`tune_fusion`), a fixed-R Kalman filter
(:func:`fixed_r_kalman`) and the complementary Kalman filter and smoother
(:func:`complementary_kalman`); with the table's reference it tunes them on the first part of
the record, judges them on the rest and recommends one that is no worse than the
:data:`BASELINES`.

What a user calls::

    analyze_fusion, FusionAnalysis, METHODS, BASELINES, excess_over_best
    complementary_kalman, ComplementaryNoise, ComplementaryRun, fit_complementary_noise
    SensorModel, FusionModel, TransferFit, fit_transfer_function
    sequential_fusion, sequential_kalman, fixed_r_kalman, complementary_filter, FusionParams, AdaptiveNoise, FilterRun
    tune_fusion, FusionTuning
    find_spikes, SpikeSearch, estimate_relative_timing, RelativeTiming, check_method, MethodCheck

Without a reference (the usual case on a production rig) :func:`analyze_fusion` finds each
sensor's spikes and dropouts without a model of the motion (:func:`find_spikes`), puts the LF
record on the HF clock from the sensors' cross-spectrum (:func:`estimate_relative_timing`) and
recommends only a method that passes its consistency checks (:func:`check_method`), else the
complementary filter.

The modules behind it are private: import from ``bench.analysis.fusion``.
"""

from bench.analysis.fusion._analysis import BASELINES, METHODS, FusionAnalysis, analyze_fusion, excess_over_best
from bench.analysis.fusion._complementary import (
    ComplementaryNoise,
    ComplementaryRun,
    complementary_kalman,
    fit_complementary_noise,
)
from bench.analysis.fusion._consistency import MethodCheck, check_method
from bench.analysis.fusion._models import FusionModel, SensorModel, TransferFit, fit_transfer_function
from bench.analysis.fusion._outliers import SpikeSearch, find_spikes
from bench.analysis.fusion._sequential import (
    AdaptiveNoise,
    FilterRun,
    FusionParams,
    complementary_filter,
    fixed_r_kalman,
    sequential_fusion,
    sequential_kalman,
)
from bench.analysis.fusion._timing import RelativeTiming, estimate_relative_timing
from bench.analysis.fusion._tuning import FusionTuning, tune_fusion

__all__ = [
    "AdaptiveNoise",
    "BASELINES",
    "ComplementaryNoise",
    "ComplementaryRun",
    "FilterRun",
    "FusionAnalysis",
    "FusionModel",
    "FusionParams",
    "FusionTuning",
    "METHODS",
    "MethodCheck",
    "RelativeTiming",
    "SensorModel",
    "SpikeSearch",
    "TransferFit",
    "analyze_fusion",
    "check_method",
    "complementary_filter",
    "complementary_kalman",
    "estimate_relative_timing",
    "excess_over_best",
    "find_spikes",
    "fit_complementary_noise",
    "fit_transfer_function",
    "fixed_r_kalman",
    "sequential_fusion",
    "sequential_kalman",
    "tune_fusion",
]
