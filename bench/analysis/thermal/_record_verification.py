"""Verification of a record fit on a record: the input recovered through the fitted model.

The fit of :func:`~bench.analysis.thermal.analyze_thermal_record` applied to a record (the same,
or better a second one over another chamber profile): the element's temperature estimated from
the logged one through the fitted lag, then per sample the compensated input
x̂ = y/S(T_e) − B(T_e) (the compensation file's inversion, K2 and cross terms aside), and on
block means of ``block_s`` the errors against the applied input:

* **compensated error** e_c = x̂ − x: what is left after compensation;
* **uncompensated error** e_u = y/S(T_ref) − B(T_ref) − x: what a calibration at the reference
  temperature alone leaves.

``noise_rms`` is the block-level noise the fit's own noise model states (white plus drift, in
input units): a model that transfers leaves ``compensated_rms`` ≈ ``noise_rms``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bench.analysis._checks import check_real
from bench.analysis.thermal._ramp import lag_filter
from bench.analysis.thermal._ramp_record import Blocks
from bench.analysis.thermal._record import MIN_BLOCKS, ThermalRecordResult, check_record


@dataclass(frozen=True, eq=False)
class RecordVerification:
    """Compensated and uncompensated errors of a record fit on a record, in input units.

    Attributes
    ----------
    compensated_rms, compensated_max_abs : float
        RMS and largest absolute block error after compensation, input units.
    uncompensated_rms, uncompensated_max_abs : float
        The same with the reference-temperature bias and scale factor only.
    noise_rms : float
        The block-level noise the fit states (white plus drift), input units.
    n_blocks : int
        Blocks compared.
    block_t_s, block_error : ndarray
        Block mean times (s) and compensated errors (input units).
    """

    compensated_rms: float
    compensated_max_abs: float
    uncompensated_rms: float
    uncompensated_max_abs: float
    noise_rms: float
    n_blocks: int
    block_t_s: np.ndarray
    block_error: np.ndarray

    def to_dict(self) -> dict:
        return {"compensated_rms": self.compensated_rms, "compensated_max_abs": self.compensated_max_abs,
                "uncompensated_rms": self.uncompensated_rms, "uncompensated_max_abs": self.uncompensated_max_abs,
                "noise_rms": self.noise_rms, "n_blocks": self.n_blocks, "block_t_s": self.block_t_s.tolist(),
                "block_error": self.block_error.tolist()}


def verify_thermal_record(result: ThermalRecordResult, t_s, output, temperature_c, applied=None, *,
                          block_s: float | None = None) -> RecordVerification:
    """Compensate a record with a record fit and compare with the applied input (module docstring).

    Parameters
    ----------
    result : ThermalRecordResult
        The fit (:func:`analyze_thermal_record`).
    t_s : array_like, shape (N,)
        Sample times, in s, strictly increasing; the record starts soaked.
    output : array_like, shape (N,)
        The unit's output, in the fit's output units.
    temperature_c : array_like, shape (N,)
        The logged temperature, in °C.
    applied : array_like, shape (N,), optional
        The input applied (input units); None: zero (a static unit, whose constant input the
        fit's bias holds).
    block_s : float, optional
        Averaging block, in s, in (0, 3600]; default the fit's.

    Returns
    -------
    RecordVerification
        RMS and largest compensated and uncompensated block errors, and the noise the fit states.

    Raises
    ------
    ValueError
        If an array is not 1-D of the length of ``t_s``, not finite, times do not increase, a
        temperature is outside −100 … 200 °C, or the record gives fewer than 40 blocks.

    Examples
    --------
    A static gyro (bias TC 2e-3 °/s/°C) whose element lags the logged sensor by 300 s, fitted
    and then compensated on its own record: what is left is the noise, not the temperature.

    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from bench.analysis.thermal import analyze_thermal_record, verify_thermal_record
    >>> t = np.arange(0.0, 14000.0, 2.0)
    >>> logged = np.interp(t, [0, 1800, 4200, 7200, 10000, 14000], [25, 25, 60, 60, 0, 0])
    >>> a = np.exp(-2.0 / 300.0)
    >>> element = lfilter([1 - a], [1, -a], logged, zi=[a * logged[0]])[0]
    >>> y = 0.05 + 2e-3 * (element - 25) + 5e-3 * np.random.default_rng(2).standard_normal(t.size)
    >>> fit = analyze_thermal_record(t, y, logged)
    >>> v = verify_thermal_record(fit, t, y, logged)
    >>> bool(v.uncompensated_rms > 10 * v.compensated_rms), bool(v.compensated_rms < 3 * v.noise_rms)
    (True, True)
    """
    t = np.asarray(t_s, dtype=float)
    y = np.asarray(output, dtype=float)
    temp = np.asarray(temperature_c, dtype=float)
    x = np.zeros(t.size) if applied is None else np.asarray(applied, dtype=float)
    if t.ndim != 1:
        raise ValueError(f"t_s has shape {t.shape}: allowed 1-D")
    check_record(t, temp, y, x)
    block = result.block_s if block_s is None else check_real("block_s", block_s, 0.0, 3600.0, low_open=True)
    blocks = Blocks.of(t, block)
    if int(blocks.full.sum()) < MIN_BLOCKS:
        raise ValueError(f"the record gives {int(blocks.full.sum())} blocks of {block:g} s; at least {MIN_BLOCKS} "
                         "are needed")
    te = lag_filter(t, temp, result.lag_s.value)
    ref = result.reference_c
    sf = np.ones(t.size) if result.scale_factor_curve is None else result.scale_factor_curve.evaluate(te)
    sf_ref = 1.0 if result.scale_factor_curve is None else float(result.scale_factor_curve.evaluate(ref)[0])
    compensated = y / sf - result.bias_curve.evaluate(te)
    uncompensated = y / sf_ref - float(result.bias_curve.evaluate(ref)[0])
    xb = blocks.mean(x)
    e_c, e_u = blocks.mean(compensated) - xb, blocks.mean(uncompensated) - xb
    noise = result.noise_sigma * math.sqrt(1.0 + result.noise.ratio) / abs(sf_ref)
    return RecordVerification(
        compensated_rms=float(np.sqrt(np.mean(e_c**2))), compensated_max_abs=float(np.abs(e_c).max()),
        uncompensated_rms=float(np.sqrt(np.mean(e_u**2))), uncompensated_max_abs=float(np.abs(e_u).max()),
        noise_rms=float(noise), n_blocks=int(e_c.size), block_t_s=blocks.mean(t), block_error=e_c)
