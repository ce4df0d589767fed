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

from bench.analysis.thermal._compensation import CompensationModel, QuantityCompensation
from bench.analysis.thermal._inputs import QuantityPoints, check_choice
from bench.analysis.thermal._poly import polynomial_rows

OUTSIDE = ("raise", "skip")
_PPM = 1e6


@dataclass(frozen=True, eq=False)
class QuantityVerification:
    """One quantity's errors over the verification temperatures, in ``error_unit`` ("ppm"
    for a scale factor, the quantity's unit otherwise)."""

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
    """Every verified quantity, and the model's quantities the run did not measure."""

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
    """Errors of the second ``run``'s quantities against ``model`` (matched by name, roles
    must agree). ``outside``: "raise" on a run temperature outside the model's valid range,
    or "skip" such points (they are listed in ``skipped_temperatures_c``)."""
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

