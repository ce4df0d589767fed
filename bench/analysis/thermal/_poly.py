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

from bench.analysis._checks import as_array, check_choice, check_int, check_real
from bench.analysis.thermal._inputs import TEMPERATURE_LIMITS_C
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
    """A quantity's polynomial of temperature, fitted to per-temperature points, with its order scores.

    A :class:`PolynomialCurve` fitted to per-temperature points. ``sigma`` is each point's
    effective standard uncertainty (value and temperature), ``residuals`` = value − fit,
    ``covariance_scale`` the factor applied to (XᵀWX)⁻¹ (1 for ``"stated"``).

    The curve's methods: ``evaluate(T)``, ``std(T)``, ``value_at(T)``, ``slope_at(T)`` (unit
    per °C), ``relative_slope_ppm_per_c(T)`` and :meth:`averaged` (over the candidate orders).
    "unit" below is the unit of the fitted values.

    Attributes
    ----------
    reference_c : float
        Reference temperature T_ref, in °C.
    coefficients : ndarray, shape (n + 1,)
        c_j of q(T) = Σ c_j (T − T_ref)^j, in unit per °C^j.
    covariance : ndarray, shape (n + 1, n + 1)
        Covariance of the coefficients (scaled by ``covariance_scale``).
    order : int
        Property: the selected order n (0 … 3).
    criterion : str
        How the order was chosen: ``"bic"``, ``"loo"`` or ``"fixed"`` (given by the caller).
    uncertainty : str
        ``"stated"``, ``"scaled"`` or ``"birge"`` (module docstring).
    order_bic : int
        The order BIC picks.
    order_loo : int
        The order leave-one-out cross-validation picks.
    scores : tuple of OrderScore
        χ², dof, BIC and LOO score of every candidate order.
    temperature_c : ndarray, shape (m,)
        The points' temperatures, in °C.
    value : ndarray, shape (m,)
        The points' values, unit.
    sigma : ndarray, shape (m,)
        Each point's effective standard uncertainty (value and temperature), unit.
    residuals : ndarray, shape (m,)
        value − fit, unit.
    chi2 : float
        Σ (residual/sigma)² of the selected fit.
    dof : int
        m − n − 1.
    p_value : float or None
        P(χ²_dof ≥ chi2); None when dof is 0.
    covariance_scale : float
        Factor applied to (XᵀWX)⁻¹ (1 for ``"stated"``).
    temperature_range_c : tuple of float
        ``(min, max)`` of the points' temperatures, in °C.
    candidates : tuple of PolynomialCurve
        The fitted curve of every candidate order, lowest first.
    bic_weights : ndarray
        Weights ∝ exp(−BIC/2) of the candidates, summing to 1.
    """

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
    "stated", "scaled" or "birge" (module docstring). Weighted least squares with the
    effective-variance method for the temperature uncertainty (Orear 1982).

    Parameters
    ----------
    temperature_c : array_like, shape (m,)
        Temperatures of the points, in °C, within −100 … +200; at least 2 distinct.
    value : array_like, shape (m,)
        The quantity at each temperature, any unit.
    std : array_like, shape (m,)
        Standard uncertainty of each value, same unit; > 0.
    temperature_std_c : array_like, shape (m,), optional
        Standard uncertainty of each temperature, in °C, within [0, 50].
    reference_c : float, default 25.0
        Reference temperature T_ref the polynomial is written about, in °C (−100 … 200).
    order : int, optional
        Fixed order, 0 … min(3, m − 1, distinct temperatures − 1); None chooses it.
    max_order : int, default 3
        Highest order considered when choosing, 0 … 3.
    criterion : {"bic", "loo"}, default "bic"
        How the order is chosen.
    uncertainty : {"stated", "scaled", "birge"}, default "stated"
        How the coefficient covariance uses the stated σ.

    Returns
    -------
    TemperaturePolynomial
        Coefficients (unit per °C^j) and covariance, the order scores, residuals and χ²,
        and every candidate curve with its BIC weight.

    Raises
    ------
    ValueError
        If the arrays are not 1-D of one length, not finite, out of range or with ``std`` ≤ 0;
        fewer than 2 distinct temperatures; ``reference_c``, ``order``, ``max_order``,
        ``criterion`` or ``uncertainty`` outside what is allowed; or ``"scaled"``/``"birge"``
        with no degree of freedom left.

    Examples
    --------
    A bias with a 50 µg/°C slope and a small curvature, 10 µg noise, six temperatures:

    >>> import numpy as np
    >>> from bench.analysis.thermal import fit_temperature_polynomial
    >>> t = np.array([-40.0, -20.0, 0.0, 25.0, 45.0, 70.0])
    >>> truth = 2e-3 + 5e-5 * (t - 25) + 1e-7 * (t - 25) ** 2
    >>> y = truth + 1e-5 * np.random.default_rng(0).standard_normal(t.size)
    >>> fit = fit_temperature_polynomial(t, y, np.full(t.size, 1e-5))
    >>> fit.order, fit.order_bic, fit.dof
    (2, 2, 3)
    >>> slope = fit.slope_at(25.0)  # g/°C
    >>> round(slope.value * 1e6, 2), bool(abs(slope.value - 5e-5) < 3 * slope.std)
    (50.0, True)
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
