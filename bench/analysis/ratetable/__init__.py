"""Rate-table calibration of a gyro (IEEE Std 952 / 647): scale factor, bias, nonlinearity.

What a user calls::

    fit_rate_table, RateTableResult, rate_plan, whole_revolution_duration_s, earth_rate_vertical_dps

The modules behind it are private: import from ``bench.analysis.ratetable``.
"""

from bench.analysis.ratetable._fit import (
    RateTableResult,
    earth_rate_vertical_dps,
    fit_rate_table,
    rate_plan,
    whole_revolution_duration_s,
)

__all__ = ["RateTableResult", "earth_rate_vertical_dps", "fit_rate_table", "rate_plan", "whole_revolution_duration_s"]
