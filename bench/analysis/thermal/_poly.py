"""A quantity as a polynomial of temperature: weighted least squares, order chosen from the data.

Model, about a reference temperature T_ref (°C)::

    q(T) = Σ_{j=0..n} c_j · (T − T_ref)^j,        n = 0 … 3

fitted by weighted least squares to per-temperature estimates q_i ± σ_i at T_i ± σ_T,i.
The temperature uncertainty enters by the **effective variance** method (Orear 1982):
σ_eff,i² = σ_i² + (q'(T_i) σ_T,i)², q' from the current fit, iterated to a fixed point
(the slope is smooth, so three to five passes settle it). The coefficient covariance is
(XᵀWX)⁻¹ with W = diag(1/σ_eff²) — the stated uncertainties taken as absolute
(``uncertainty="stated"``) — or scaled by χ²/dof (``"scaled"``: the stated σ are relative
weights, statsmodels' default) or by max(1, χ²/dof) (``"birge"``: never narrower than
stated, widened by the Birge ratio when the points scatter more than they claim).

**Order.** Both criteria are computed for every order from 0 to min(``max_order``, m − 2)
(at least one degree of freedom left to judge the fit) and both are reported:

* **BIC** with the stated uncertainties: χ² + (n + 1)·ln m (with ``"scaled"``,
  m·ln(χ²/m) + (n + 1)·ln m, the common scale unknown);
* **leave-one-temperature-out cross-validation**: the mean of (e_i/σ_eff,i)² over the
  points, e_i the error predicting point i from a fit without it, computed exactly from
  the hat matrix as r_i / (1 − h_ii).

The default picks by **BIC**. With the 5 – 9 temperatures of a sweep, leaving out an end
point turns its prediction into an extrapolation whose error grows as (ΔT)^n: one end
point decides the LOO score, which then swings between orders from draw to draw. BIC uses
the uncertainties the tumble or rate table states, which the end points do not dominate.
Measured on the tests' independent generator (1000 units, 7 temperatures −40 … +70 °C, cubic
terms in half of them, often near the noise): BIC chose the true order for 81.7 % of units,
LOO for 79.4 %; the selected curve's TC covered its truth at 2σ for 90.8 % (BIC) and 88.6 %
(LOO); the residual on a second temperature profile was the same for both (docs/METHODS.md,
``python -m tests.analysis.thermal_coverage``). ``criterion="loo"`` picks by cross-validation
instead. Figures derived from the curve (a temperature coefficient) carry the doubt about the
order through :meth:`TemperaturePolynomial.averaged`: BIC-weighted over the candidate orders,
the TC's 2σ coverage on the same draws is 96.2 %.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import stats

from bench.analysis.thermal._inputs import (
    TEMPERATURE_LIMITS_C,
    as_array,
    check_choice,
    check_int,
    check_real,
)
from bench.values import Estimate

MAX_ORDER = 3
CRITERIA = ("bic", "loo")
UNCERTAINTY_MODES = ("stated", "scaled", "birge")
_EFFECTIVE_VARIANCE_PASSES = 6
_PPM = 1e6


@dataclass(frozen=True)
class OrderScore:
    """One candidate order: its χ² (stated σ), degrees of freedom, BIC and LOO score
    (mean squared standardised leave-one-out prediction error; ∞ when a point decides
    its own fit)."""

    order: int
    chi2: float
    dof: int
    bic: float
    loo: float

    def to_dict(self) -> dict:
        return {"order": self.order, "chi2": self.chi2, "dof": self.dof, "bic": self.bic,
                "loo": None if math.isinf(self.loo) else self.loo}


@dataclass(frozen=True, eq=False)
class PolynomialCurve:
    """q(T) = Σ coefficients[j] · (T − reference_c)^j (unit per °C^j) with the coefficients'
    ``covariance``: evaluation, standard uncertainty and slopes at any temperature."""

    reference_c: float
    coefficients: np.ndarray
    covariance: np.ndarray

    @property
    def order(self) -> int:
        return int(self.coefficients.size) - 1

    def _rows(self, temperature_c, derivative: int = 0) -> np.ndarray:
        u = np.atleast_1d(np.asarray(temperature_c, dtype=float)) - self.reference_c
        return polynomial_rows(u, self.order, derivative)

    def evaluate(self, temperature_c) -> np.ndarray:
        """Value at temperatures in °C (array in, array out)."""
        return self._rows(temperature_c) @ self.coefficients

    def std(self, temperature_c) -> np.ndarray:
        """Standard uncertainty of the curve's value at temperatures in °C."""
        x = self._rows(temperature_c)
        return np.sqrt(np.clip(np.einsum("ij,jk,ik->i", x, self.covariance, x), 0.0, None))

    def value_at(self, temperature_c: float) -> Estimate:
        x = self._rows(temperature_c)[0]
        return Estimate(float(x @ self.coefficients), math.sqrt(max(float(x @ self.covariance @ x), 0.0)))

    def slope_at(self, temperature_c: float) -> Estimate:
        """dq/dT at a temperature, in the quantity's unit per °C."""
        d = self._rows(temperature_c, 1)[0]
        return Estimate(float(d @ self.coefficients), math.sqrt(max(float(d @ self.covariance @ d), 0.0)))

    def relative_slope_ppm_per_c(self, temperature_c: float) -> Estimate:
        """(dq/dT)/q at a temperature in ppm/°C (a scale factor's temperature coefficient),
        its uncertainty by the delta method."""
        x, d = self._rows(temperature_c)[0], self._rows(temperature_c, 1)[0]
        q, dq = float(x @ self.coefficients), float(d @ self.coefficients)
        if q == 0.0:
            raise ValueError(f"the curve's value at {temperature_c} °C is 0: no relative slope")
        grad = _PPM * (d / q - dq * x / q**2)
        return Estimate(_PPM * dq / q, math.sqrt(max(float(grad @ self.covariance @ grad), 0.0)))

    def to_dict(self) -> dict:
        return {"reference_c": self.reference_c, "coefficients": self.coefficients.tolist(),
                "covariance": self.covariance.tolist()}


@dataclass(frozen=True, eq=False)
class TemperaturePolynomial(PolynomialCurve):
    """A :class:`PolynomialCurve` fitted to per-temperature points. ``sigma`` is each point's
    effective standard uncertainty (value and temperature), ``residuals`` = value − fit,
    ``covariance_scale`` the factor applied to (XᵀWX)⁻¹ (1 for ``"stated"``)."""

    criterion: str
    uncertainty: str
    order_bic: int
    order_loo: int
    scores: tuple[OrderScore, ...]
    temperature_c: np.ndarray
    value: np.ndarray
    sigma: np.ndarray
    residuals: np.ndarray
    chi2: float
    dof: int
    p_value: float | None
    covariance_scale: float
    temperature_range_c: tuple[float, float]
    candidates: tuple[PolynomialCurve, ...]
    bic_weights: np.ndarray

    def averaged(self, quantity: Callable[[PolynomialCurve], Estimate]) -> Estimate:
        """``quantity`` of the curve averaged over the candidate orders with BIC weights
        w_k ∝ exp(−BIC_k/2), its standard uncertainty Σ w_k √(σ_k² + (q_k − q̄)²) (Buckland,
        Burnham & Augustin 1997): it carries the doubt about the order, which the selected
        curve's own σ leaves out. With the order fixed by the caller, the selected curve's."""
        if self.criterion == "fixed":
            return quantity(self)
        values = [quantity(c) for c in self.candidates]
        w = self.bic_weights
        mean = float(sum(wk * e.value for wk, e in zip(w, values)))
        std = float(sum(wk * math.sqrt((e.std or 0.0) ** 2 + (e.value - mean) ** 2) for wk, e in zip(w, values)))
        return Estimate(mean, std)

    def to_dict(self) -> dict:
        return {**super().to_dict(), "order": self.order, "bic_weights": self.bic_weights.tolist(),
                "criterion": self.criterion, "uncertainty": self.uncertainty,
                "order_bic": self.order_bic, "order_loo": self.order_loo,
                "scores": [s.to_dict() for s in self.scores],
                "temperature_c": self.temperature_c.tolist(), "value": self.value.tolist(),
                "sigma": self.sigma.tolist(), "residuals": self.residuals.tolist(),
                "chi2": self.chi2, "dof": self.dof, "p_value": self.p_value,
                "covariance_scale": self.covariance_scale,
                "temperature_range_c": list(self.temperature_range_c)}


def polynomial_rows(u: np.ndarray, order: int, derivative: int = 0) -> np.ndarray:
    """Rows of d^k/du^k [1, u, u², …, u^order] at offsets ``u`` (shape (len(u), order + 1))."""
    out = np.zeros((u.size, order + 1))
    for j in range(derivative, order + 1):
        out[:, j] = math.perm(j, derivative) * u ** (j - derivative)
    return out


@dataclass(frozen=True, eq=False)
class _Wls:
    coefficients: np.ndarray
    inverse: np.ndarray  # (XᵀWX)⁻¹
    residuals: np.ndarray
    sigma: np.ndarray
    leverage: np.ndarray
    chi2: float


def _wls(u: np.ndarray, y: np.ndarray, sigma: np.ndarray, order: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Coefficients, (XᵀWX)⁻¹ and leverages of the weighted polynomial fit (SVD of the
    whitened design with unit-norm columns, so a 3rd-order fit over ±60 °C stays well scaled)."""
    x = polynomial_rows(u, order)
    xw, yw = x / sigma[:, None], y / sigma
    norms = np.linalg.norm(xw, axis=0)
    norms[norms == 0.0] = 1.0
    uu, s, vt = np.linalg.svd(xw / norms, full_matrices=False)
    if s[-1] <= 1e-12 * s[0]:
        raise ValueError(f"order {order} needs at least {order + 1} distinct temperatures")
    beta = vt.T @ ((uu.T @ yw) / s)
    inv = (vt.T / s**2) @ vt
    leverage = np.sum(uu**2, axis=1)
    return beta / norms, inv / np.outer(norms, norms), leverage


def _fit_order(u, y, std, t_std, order) -> _Wls:
    """WLS at one order with the effective variance iterated to its fixed point."""
    sigma = std
    for _ in range(_EFFECTIVE_VARIANCE_PASSES if t_std is not None and order > 0 else 1):
        coef, inv, lev = _wls(u, y, sigma, order)
        if t_std is None or order == 0:
            break
        slope = polynomial_rows(u, order, 1) @ coef
        new = np.sqrt(std**2 + (slope * t_std) ** 2)
        converged = np.allclose(new, sigma, rtol=1e-6)
        sigma = new
        if converged:
            break
    coef, inv, lev = _wls(u, y, sigma, order)
    resid = y - polynomial_rows(u, order) @ coef
    return _Wls(coef, inv, resid, sigma, lev, float(np.sum((resid / sigma) ** 2)))


def _scores(fit: _Wls, order: int, m: int, uncertainty: str) -> OrderScore:
    k = order + 1
    if uncertainty == "scaled":
        bic = m * math.log(max(fit.chi2, 1e-300) / m) + k * math.log(m)
    else:
        bic = fit.chi2 + k * math.log(m)
    if np.any(fit.leverage >= 1.0 - 1e-9):
        loo = math.inf
    else:
        loo = float(np.mean((fit.residuals / (1.0 - fit.leverage) / fit.sigma) ** 2))
    return OrderScore(order, fit.chi2, m - k, float(bic), loo)


def fit_temperature_polynomial(temperature_c, value, std, *, temperature_std_c=None,
                               reference_c: float = 25.0, order: int | None = None,
                               max_order: int = MAX_ORDER, criterion: str = "bic",
                               uncertainty: str = "stated") -> TemperaturePolynomial:
    """Fit ``value`` ± ``std`` at ``temperature_c`` as a polynomial about ``reference_c``.

    ``temperature_c`` (m,) in °C within −100 … +200, at least 2 distinct; ``value`` (m,)
    in any unit; ``std`` (m,) its standard uncertainty (> 0); ``temperature_std_c`` (m,)
    or None. ``order`` fixes the order (0 … min(3, m − 1)); None chooses it by
    ``criterion`` ("bic" or "loo") among 0 … min(``max_order``, m − 2). ``uncertainty``:
    "stated", "scaled" or "birge" (module docstring).
    """
    t = as_array("temperature_c", temperature_c, min_size=2, limits=TEMPERATURE_LIMITS_C)
    y = as_array("value", value, size=t.size)
    s = as_array("std", std, size=t.size, positive=True)
    ts = None if temperature_std_c is None else as_array(
        "temperature_std_c", temperature_std_c, size=t.size, limits=(0.0, 50.0))
    if ts is not None and not np.any(ts):
        ts = None
    ref = check_real("reference_c", reference_c, *TEMPERATURE_LIMITS_C)
    check_choice("criterion", criterion, CRITERIA)
    check_choice("uncertainty", uncertainty, UNCERTAINTY_MODES)
    m = t.size
    distinct = np.unique(t).size
    if distinct < 2:
        raise ValueError(f"temperature_c has {distinct} distinct value: at least 2 are needed")
    u = t - ref
    top = min(MAX_ORDER, m - 1, distinct - 1)
    if order is not None:
        chosen = check_int("order", order, 0, top)
    else:
        check_int("max_order", max_order, 0, MAX_ORDER)
    candidates = range(0, max(0, min(max_order, m - 2, distinct - 1)) + 1)
    fits = {k: _fit_order(u, y, s, ts, k) for k in candidates}
    scores = tuple(_scores(fits[k], k, m, uncertainty) for k in candidates)
    order_bic = min(scores, key=lambda c: c.bic).order
    order_loo = min(scores, key=lambda c: c.loo).order
    if order is None:
        chosen = order_bic if criterion == "bic" else order_loo
    fit = fits[chosen] if chosen in fits else _fit_order(u, y, s, ts, chosen)
    dof = m - chosen - 1
    scale = _covariance_scale(fit.chi2, dof, chosen, uncertainty)
    bics = np.array([c.bic for c in scores])
    weights = np.exp(-(bics - bics.min()) / 2.0)
    curves = tuple(PolynomialCurve(ref, fits[k].coefficients,
                                   fits[k].inverse * _covariance_scale(fits[k].chi2, m - k - 1, k, uncertainty))
                   for k in candidates)
    return TemperaturePolynomial(
        reference_c=ref, coefficients=fit.coefficients, covariance=fit.inverse * scale,
        criterion=criterion if order is None else "fixed", uncertainty=uncertainty,
        order_bic=order_bic, order_loo=order_loo, scores=scores, temperature_c=t, value=y,
        sigma=fit.sigma, residuals=fit.residuals, chi2=fit.chi2, dof=dof,
        p_value=float(stats.chi2.sf(fit.chi2, dof)) if dof > 0 else None,
        covariance_scale=float(scale), temperature_range_c=(float(t.min()), float(t.max())),
        candidates=curves, bic_weights=weights / weights.sum())


def _covariance_scale(chi2: float, dof: int, order: int, uncertainty: str) -> float:
    """The factor on (XᵀWX)⁻¹ for an uncertainty mode (module docstring)."""
    if uncertainty == "stated":
        return 1.0
    if dof <= 0:
        raise ValueError(f"uncertainty={uncertainty!r} estimates the scatter from the residuals: "
                         f"order {order} needs at least {order + 2} points, got {order + 1 + dof}")
    return chi2 / dof if uncertainty == "scaled" else max(1.0, chi2 / dof)
