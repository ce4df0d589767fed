"""Verification of a thermal compensation on a second run over a different temperature profile.

The second run yields, at its own temperatures, new estimates of the model's quantities
(:class:`~bench.analysis.thermal._inputs.QuantityPoints`, same names). At each point:

* **compensated error** — the estimate minus the model's curve at that temperature,
  e_c = q_v(T) − q̂(T): what is left after the navigation computer applies the file;
* **uncompensated error** — the estimate minus the model's value at the reference
  temperature, e_u = q_v(T) − q̂(T_ref): what a single room-temperature calibration leaves.

A scale factor's errors are relative, in ppm: 10⁶·(q_v/q̂ − 1). Each error carries its
standard uncertainty: the second run's own (value, and temperature through the model's
slope) and the model's curve (its coefficient covariance). The model's part is common to
every point, so the consistency test of the compensated errors against zero,
χ² = eᵀ Σ⁻¹ e with Σ = diag(run variances) + X C Xᵀ, uses the full covariance; ``noise_rms``
is the root-mean-square of the errors' standard uncertainties: the residual the noise alone
allows. A compensation that works leaves ``compensated_rms`` ≈ ``noise_rms`` and a
χ² p-value that is not small.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats

from bench.analysis._checks import check_choice
from bench.analysis.thermal._compensation import CompensationModel, QuantityCompensation
from bench.analysis.thermal._inputs import QuantityPoints
from bench.analysis.thermal._poly import polynomial_rows

OUTSIDE = ("raise", "skip")
_PPM = 1e6


@dataclass(frozen=True, eq=False)
class QuantityVerification:
    """One quantity's errors over the verification temperatures, compensated and uncompensated.

    An element of :attr:`CompensationVerification.quantities`. Errors are in ``error_unit``
    ("ppm" for a scale factor, the quantity's unit otherwise).

    Attributes
    ----------
    name : str
        The quantity's name.
    role : str
        Its role in the output model.
    error_unit : str
        Unit of every error below.
    temperature_c : ndarray, shape (m,)
        Verification temperatures used, in °C.
    compensated_error : ndarray, shape (m,)
        e_c = q_v(T) − q̂(T) (relative, in ppm, for a scale factor).
    compensated_std : ndarray, shape (m,)
        Its standard uncertainty (run and model).
    uncompensated_error : ndarray, shape (m,)
        e_u = q_v(T) − q̂(T_ref).
    uncompensated_std : ndarray, shape (m,)
        Its standard uncertainty.
    compensated_rms : float
        RMS of the compensated errors.
    compensated_max_abs : float
        Largest |compensated error|.
    uncompensated_rms : float
        RMS of the uncompensated errors.
    uncompensated_max_abs : float
        Largest |uncompensated error|.
    noise_rms : float
        RMS of the compensated errors' standard uncertainties: what the noise alone allows.
    chi2 : float
        eᵀ Σ⁻¹ e of the compensated errors with their full covariance.
    dof : int
        Degrees of freedom of the χ² test (the number of points).
    p_value : float
        P(χ²_dof ≥ chi2): small when the compensation leaves more than the noise.
    skipped_temperatures_c : ndarray
        Run temperatures outside the model's valid range, left out (``outside="skip"``).
    """

    name: str
    role: str
    error_unit: str
    temperature_c: np.ndarray
    compensated_error: np.ndarray
    compensated_std: np.ndarray
    uncompensated_error: np.ndarray
    uncompensated_std: np.ndarray
    compensated_rms: float
    compensated_max_abs: float
    uncompensated_rms: float
    uncompensated_max_abs: float
    noise_rms: float
    chi2: float
    dof: int
    p_value: float
    skipped_temperatures_c: np.ndarray

    def to_dict(self) -> dict:
        d = {k: getattr(self, k) for k in ("name", "role", "error_unit", "compensated_rms", "compensated_max_abs",
                                            "uncompensated_rms", "uncompensated_max_abs", "noise_rms", "chi2",
                                            "dof", "p_value")}
        for k in ("temperature_c", "compensated_error", "compensated_std", "uncompensated_error",
                  "uncompensated_std", "skipped_temperatures_c"):
            d[k] = getattr(self, k).tolist()
        return d


@dataclass(frozen=True, eq=False)
class CompensationVerification:
    """Every verified quantity, and the model's quantities the run did not measure.

    Index it by name: ``verification["k0"]`` is that quantity's errors.

    Attributes
    ----------
    quantities : tuple of QuantityVerification
        One per quantity both the model and the run hold, in the model's order.
    not_verified : tuple of str
        Names of the model's quantities the run did not measure.
    """

    quantities: tuple[QuantityVerification, ...]
    not_verified: tuple[str, ...]

    def __getitem__(self, name: str) -> QuantityVerification:
        for q in self.quantities:
            if q.name == name:
                return q
        raise KeyError(f"no verified quantity {name!r}; verified: {', '.join(q.name for q in self.quantities)}")

    def to_dict(self) -> dict:
        return {"quantities": [q.to_dict() for q in self.quantities], "not_verified": list(self.not_verified)}


def _verify_one(model: CompensationModel, q: QuantityCompensation, points: QuantityPoints,
                outside: str) -> QuantityVerification:
    if points.role != q.role:
        raise ValueError(f"{points.name}: role {points.role!r} in the run, {q.role!r} in the model")
    lo, hi = model.valid_range_c
    t_all = points.temperature_c
    inside = (t_all >= lo) & (t_all <= hi)
    if outside == "raise" and not np.all(inside):
        i = int(np.flatnonzero(~inside)[0])
        raise ValueError(f"{points.name}.temperature_c[{i}] = {t_all[i]:g} °C outside the model's valid range "
                         f"[{lo:g}, {hi:g}] °C (outside='skip' to leave such points out)")
    if not np.any(inside):
        raise ValueError(f"{points.name}: no verification temperature within the valid range [{lo:g}, {hi:g}] °C")
    t, v, s = t_all[inside], points.value[inside], points.std[inside]
    ts = None if points.temperature_std_c is None else points.temperature_std_c[inside]
    ref = model.reference_c
    x = polynomial_rows(t - ref, q.order)
    curve = x @ q.coefficients
    run_var = s**2
    if ts is not None:
        slope = polynomial_rows(t - ref, q.order, 1) @ q.coefficients
        run_var = run_var + (slope * ts) ** 2
    x0 = polynomial_rows(np.array([0.0]), q.order)[0]
    at_ref = float(x0 @ q.coefficients)
    model_cov = x @ q.covariance @ x.T  # common to every point: the curve is one estimate
    ref_var = float(x0 @ q.covariance @ x0)
    if q.role == "scale_factor":  # relative errors in ppm, first order in the small ratios
        comp = _PPM * (v / curve - 1.0)
        unc = _PPM * (v / at_ref - 1.0)
        jac = _PPM * v / curve**2
        cov = np.diag(_PPM**2 * run_var / curve**2) + np.outer(jac, jac) * model_cov
        unc_var = _PPM**2 * (run_var / at_ref**2 + (v / at_ref**2) ** 2 * ref_var)
        unit = "ppm"
    else:
        comp, unc = v - curve, v - at_ref
        cov = np.diag(run_var) + model_cov
        unc_var = run_var + ref_var
        unit = q.unit
    comp_std = np.sqrt(np.diag(cov))
    chi2 = float(comp @ np.linalg.lstsq(cov, comp, rcond=None)[0])
    return QuantityVerification(
        name=q.name, role=q.role, error_unit=unit, temperature_c=t, compensated_error=comp,
        compensated_std=comp_std, uncompensated_error=unc, uncompensated_std=np.sqrt(unc_var),
        compensated_rms=float(np.sqrt(np.mean(comp**2))), compensated_max_abs=float(np.abs(comp).max()),
        uncompensated_rms=float(np.sqrt(np.mean(unc**2))), uncompensated_max_abs=float(np.abs(unc).max()),
        noise_rms=float(np.sqrt(np.mean(comp_std**2))), chi2=chi2, dof=int(t.size),
        p_value=float(stats.chi2.sf(chi2, t.size)), skipped_temperatures_c=t_all[~inside])


def verify_compensation(model: CompensationModel, run: Sequence[QuantityPoints], *,
                        outside: str = "raise") -> CompensationVerification:
    """Errors of a second run's quantities against a compensation model.

    The second ``run``'s quantities against ``model`` (matched by name, roles must agree).
    ``outside``: "raise" on a run temperature outside the model's valid range, or "skip" such
    points (they are listed in ``skipped_temperatures_c``). Compensated and uncompensated
    errors, their uncertainties and the χ² consistency test are defined in the module
    docstring: a compensation that works leaves ``compensated_rms`` ≈ ``noise_rms`` and a
    p-value that is not small.

    Parameters
    ----------
    model : CompensationModel
        The compensation model under test.
    run : sequence of QuantityPoints
        The verification run's estimates over its own temperatures (°C), at least one; names
        unique and in the model, roles as in the model.
    outside : {"raise", "skip"}, default "raise"
        What to do with a run temperature outside the model's ``valid_range_c``.

    Returns
    -------
    CompensationVerification
        Per quantity: compensated and uncompensated errors (ppm for a scale factor, its unit
        otherwise), their RMS, the noise RMS and the χ² test; and the quantities not verified.

    Raises
    ------
    ValueError
        If ``outside`` is unknown, ``run`` is empty, names a quantity not in the model or
        repeats a name, a role differs from the model's, a temperature is outside the valid
        range with ``outside="raise"``, or a quantity has no temperature within it.

    Examples
    --------
    >>> import numpy as np
    >>> from bench.analysis.thermal import QuantityPoints, calibrate_over_temperature, compensation_model
    >>> from bench.analysis.thermal import verify_compensation
    >>> t = np.array([-40.0, -20.0, 0.0, 25.0, 45.0, 70.0])
    >>> bias = QuantityPoints("k0", "bias", "g", t, 2e-3 + 5e-5 * (t - 25), np.full(t.size, 1e-5))
    >>> sf = QuantityPoints("k1", "scale_factor", "mA/g", t, 1.2 * (1 + 100e-6 * (t - 25)), np.full(t.size, 1e-5))
    >>> model = compensation_model(calibrate_over_temperature([bias, sf]), unit_serial="QA-0001",
    ...                            unit_model="QA-2000", input_unit="g", output_unit="mA")
    >>> t2 = np.array([-35.0, -5.0, 35.0, 65.0])  # a second run, other temperatures, 10 µg noise
    >>> b2 = 2e-3 + 5e-5 * (t2 - 25) + 1e-5 * np.random.default_rng(0).standard_normal(t2.size)
    >>> v = verify_compensation(model, [QuantityPoints("k0", "bias", "g", t2, b2, np.full(t2.size, 1e-5))])
    >>> v.not_verified, v["k0"].error_unit, v["k0"].dof
    (('k1',), 'g', 4)
    >>> q = v["k0"]  # µg: compensated ≈ noise, uncompensated ≈ 2 mg
    >>> round(q.compensated_rms * 1e6, 1), round(q.noise_rms * 1e6, 1), round(q.uncompensated_rms * 1e6)
    (3.4, 11.6, 1969)
    >>> bool(q.p_value > 0.05)
    True
    """
    check_choice("outside", outside, OUTSIDE)
    if not run:
        raise ValueError("run is empty: give the verification run's quantities")
    names = [p.name for p in run]
    model_names = [q.name for q in model.quantities]
    unknown = [n for n in names if n not in model_names]
    if unknown:
        raise ValueError(f"run quantity {unknown[0]!r} is not in the model (it holds {', '.join(model_names)})")
    if len(set(names)) != len(names):
        raise ValueError(f"run quantity names must be unique, got {', '.join(names)}")
    by_name = {p.name: p for p in run}
    verified = tuple(_verify_one(model, q, by_name[q.name], outside) for q in model.quantities if q.name in by_name)
    return CompensationVerification(verified, tuple(n for n in model_names if n not in by_name))

