"""Rate-table calibration of a gyro (IEEE Std 952 / 647): scale factor, bias, nonlinearity.

The gyro turns on a rate table at a plan of rates of both signs (:func:`rate_plan`), each
dwell lasting whole revolutions (:func:`whole_revolution_duration_s`) so the Earth rate's
horizontal part and the table's wobble average out; the input rate is the table rate plus
the Earth rate's vertical part (:func:`earth_rate_vertical_dps`). :func:`fit_rate_table`, the
main entry point, fits the mean output per rate by weighted least squares and returns the
scale factor and its error (ppm), the bias (°/h), the nonlinearity (ppm of full scale) and
the asymmetry (ppm), each with its standard error (:class:`RateTableResult`).

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
