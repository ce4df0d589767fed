"""Calibration over temperature: soak detection, bias and scale-factor polynomials, ramps, compensation.

A thermal sweep soaks the unit at each set point until its own sensor is stable
(:func:`soak_status`; :func:`find_soak` finds when it was in a whole record) and estimates every
calibrated quantity there (:class:`QuantityPoints`).
:func:`calibrate_over_temperature`, the main entry point, fits each quantity as a polynomial
of temperature (:func:`fit_temperature_polynomial`, order by BIC) and reads its temperature
coefficient; :func:`compensation_model` turns the result into the compensation file a
navigation computer loads (:func:`compensation_to_toml`, :func:`compensation_from_toml`),
:func:`compensate` applies it to raw outputs, and :func:`verify_compensation` checks it on a
second run. :func:`analyze_thermal_ramp` reads bias over temperature, thermal hysteresis (with
its switching width, a play operator) and rate sensitivity from one record over a temperature
ramp. :func:`analyze_thermal_record` reads bias and scale factor over temperature from one
continuous chamber record (soaks and ramps, the applied input logged), the sensing element's
lag behind the logged sensor fitted; :meth:`ThermalRecordResult.compensation_model` gives its
compensation file and :func:`verify_thermal_record` checks it on a record.

What a user calls::

    calibrate_over_temperature, ThermalCalibration, QuantityCalibration
    compensation_model, CompensationModel, QuantityCompensation, compensate, CompensatedOutput
    compensation_to_toml, compensation_from_toml
    QuantityPoints
    fit_temperature_polynomial, TemperaturePolynomial
    analyze_thermal_ramp, ThermalRampResult
    analyze_thermal_record, ThermalRecordResult, verify_thermal_record, RecordVerification
    soak_status, find_soak, SoakCriterion, SoakStatus, SoakResult
    verify_compensation, CompensationVerification, QuantityVerification

The modules behind it are private: import from ``bench.analysis.thermal``.
"""

from bench.analysis.thermal._calibration import QuantityCalibration, ThermalCalibration, calibrate_over_temperature
from bench.analysis.thermal._compensation import (
    CompensatedOutput,
    CompensationModel,
    QuantityCompensation,
    compensate,
    compensation_model,
)
from bench.analysis.thermal._compensation_file import compensation_from_toml, compensation_to_toml
from bench.analysis.thermal._inputs import QuantityPoints
from bench.analysis.thermal._poly import TemperaturePolynomial, fit_temperature_polynomial
from bench.analysis.thermal._ramp import ThermalRampResult, analyze_thermal_ramp
from bench.analysis.thermal._record import ThermalRecordResult, analyze_thermal_record
from bench.analysis.thermal._record_verification import RecordVerification, verify_thermal_record
from bench.analysis.thermal._soak import SoakCriterion, SoakResult, SoakStatus, find_soak, soak_status
from bench.analysis.thermal._verification import CompensationVerification, QuantityVerification, verify_compensation

__all__ = [
    "CompensatedOutput",
    "CompensationModel",
    "CompensationVerification",
    "QuantityCalibration",
    "QuantityCompensation",
    "QuantityPoints",
    "QuantityVerification",
    "RecordVerification",
    "SoakCriterion",
    "SoakResult",
    "SoakStatus",
    "TemperaturePolynomial",
    "ThermalCalibration",
    "ThermalRampResult",
    "ThermalRecordResult",
    "analyze_thermal_ramp",
    "analyze_thermal_record",
    "calibrate_over_temperature",
    "compensate",
    "compensation_from_toml",
    "compensation_model",
    "compensation_to_toml",
    "find_soak",
    "fit_temperature_polynomial",
    "soak_status",
    "verify_compensation",
    "verify_thermal_record",
]
