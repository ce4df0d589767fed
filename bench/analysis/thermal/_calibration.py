"""Calibration over temperature: every quantity of a thermal sweep as a polynomial of temperature.

Each quantity's per-temperature estimates (:class:`~bench.analysis.thermal._inputs.QuantityPoints`)
are fitted by :func:`~bench.analysis.thermal._poly.fit_temperature_polynomial` about one
reference temperature, and its **temperature coefficient** at the reference is reported:

* a scale factor's in ppm/°C, ``10⁶ · q'(T_ref) / q(T_ref)`` (the datasheet's SF TC);
* every other quantity's in its unit per °C, ``q'(T_ref)`` (the bias TC in g/°C, °/h/°C …),

each with its standard uncertainty (delta method). The coefficient and the value at the
reference are **averaged over the candidate orders with BIC weights**
(:meth:`~bench.analysis.thermal._poly.TemperaturePolynomial.averaged`), because the slope of
the selected curve alone ignores the doubt about the order: over 1000 units drawn with cubic
terms near the noise, the selected curve's TC covered its truth at 2σ in 90.8 % of draws,
the averaged one in 96.2 % (intervals 21 % wider at the median; docs/METHODS.md). The
selected curve's own slope is kept as ``temperature_coefficient_selected``: it is the slope
of the curve the compensation file holds. The result turns into the compensation file with
:func:`bench.analysis.thermal._compensation.compensation_model`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from bench.analysis._checks import check_real
from bench.analysis.thermal._inputs import QuantityPoints
from bench.analysis.thermal._poly import (
    MAX_ORDER,
    PolynomialCurve,
    TemperaturePolynomial,
    fit_temperature_polynomial,
)
from bench.values import Estimate


@dataclass(frozen=True, eq=False)
class QuantityCalibration:
    """One quantity's calibration over temperature: its fit, value and temperature coefficient.

    One quantity over temperature: its fit, its value and temperature coefficient at the
    reference temperature (BIC-averaged over the orders; ``temperature_coefficient_selected``
    that of the selected curve), the coefficient in ``tc_unit``: "ppm/°C" for a scale factor,
    "<unit>/°C" otherwise.

    Attributes
    ----------
    points : QuantityPoints
        The quantity's per-temperature estimates.
    fit : TemperaturePolynomial
        Its polynomial of temperature about the reference.
    value_at_reference : Estimate
        q(T_ref), BIC-averaged over the candidate orders, in the quantity's unit.
    temperature_coefficient : Estimate
        Temperature coefficient at T_ref, BIC-averaged, in ``tc_unit``: 10⁶·q'/q for a scale
        factor, q' otherwise.
    temperature_coefficient_selected : Estimate
        The same from the selected curve alone (the slope of the curve the compensation
        file holds), in ``tc_unit``.
    tc_unit : str
        ``"ppm/°C"`` for a scale factor, ``"<unit>/°C"`` otherwise.
    name : str
        Property: the quantity's name.
    """

    points: QuantityPoints
    fit: TemperaturePolynomial
    value_at_reference: Estimate
    temperature_coefficient: Estimate
    temperature_coefficient_selected: Estimate
    tc_unit: str

    @property
    def name(self) -> str:
        return self.points.name

    def to_dict(self) -> dict:
        p = self.points
        return {"name": p.name, "role": p.role, "unit": p.unit, "cross_input": p.cross_input,
                "sign": p.sign, "fit": self.fit.to_dict(),
                "value_at_reference": self.value_at_reference.to_dict(),
                "temperature_coefficient": self.temperature_coefficient.to_dict(),
                "temperature_coefficient_selected": self.temperature_coefficient_selected.to_dict(),
                "tc_unit": self.tc_unit}


@dataclass(frozen=True, eq=False)
class ThermalCalibration:
    """Every quantity's calibration, in the order given, about ``reference_c`` (°C).

    Index it by name: ``calibration["k0"]`` is that quantity's :class:`QuantityCalibration`.

    Attributes
    ----------
    reference_c : float
        Reference temperature of every fit, in °C.
    quantities : tuple of QuantityCalibration
        One per quantity, in the order given.
    names : tuple of str
        Property: the quantities' names, in order.
    """

    reference_c: float
    quantities: tuple[QuantityCalibration, ...]

    def __getitem__(self, name: str) -> QuantityCalibration:
        for q in self.quantities:
            if q.name == name:
                return q
        raise KeyError(f"no quantity {name!r}; calibrated: {', '.join(q.name for q in self.quantities)}")

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(q.name for q in self.quantities)

    def to_dict(self) -> dict:
        return {"reference_c": self.reference_c, "quantities": [q.to_dict() for q in self.quantities]}


def calibrate_quantity(points: QuantityPoints, *, reference_c: float = 25.0, order: int | None = None,
                       max_order: int = MAX_ORDER, criterion: str = "bic",
                       uncertainty: str = "stated") -> QuantityCalibration:
    """Fit one quantity over temperature and read its temperature coefficient at ``reference_c``
    (arguments as :func:`~bench.analysis.thermal._poly.fit_temperature_polynomial`)."""
    fit = fit_temperature_polynomial(points.temperature_c, points.value, points.std,
                                     temperature_std_c=points.temperature_std_c, reference_c=reference_c,
                                     order=order, max_order=max_order, criterion=criterion,
                                     uncertainty=uncertainty)
    ref = fit.reference_c

    def tc(curve: PolynomialCurve) -> Estimate:
        return curve.relative_slope_ppm_per_c(ref) if points.role == "scale_factor" else curve.slope_at(ref)

    tc_unit = "ppm/°C" if points.role == "scale_factor" else f"{points.unit}/°C"
    return QuantityCalibration(points, fit, fit.averaged(lambda c: c.value_at(ref)), fit.averaged(tc), tc(fit),
                               tc_unit)


def calibrate_over_temperature(quantities: Sequence[QuantityPoints], *, reference_c: float = 25.0,
                               orders: Mapping[str, int] | None = None, max_order: int = MAX_ORDER,
                               criterion: str = "bic", uncertainty: str = "stated") -> ThermalCalibration:
    """Calibrate every quantity of a sweep about one ``reference_c`` (°C).

    ``quantities``: one :class:`QuantityPoints` per quantity, names unique, at most one
    ``bias`` and one ``scale_factor`` and one ``k2`` (the output model has one of each).
    ``orders`` fixes the order of named quantities; the others are chosen by ``criterion``.
    Each quantity is fitted by :func:`fit_temperature_polynomial` and its value and
    temperature coefficient at the reference are BIC-averaged over the candidate orders
    (module docstring).

    Parameters
    ----------
    quantities : sequence of QuantityPoints
        One per quantity, at least one; names unique, at most one each of the roles
        ``bias``, ``scale_factor`` and ``k2``.
    reference_c : float, default 25.0
        Reference temperature, in °C, within [−100, 200].
    orders : mapping of str to int, optional
        Fixed polynomial order (0 … 3) of the named quantities.
    max_order : int, default 3
        Highest order considered for the others, 0 … 3.
    criterion : {"bic", "loo"}, default "bic"
        How the others' order is chosen.
    uncertainty : {"stated", "scaled", "birge"}, default "stated"
        How the coefficient covariance uses the stated σ.

    Returns
    -------
    ThermalCalibration
        Every quantity's fit, value at the reference (its unit) and temperature coefficient
        (ppm/°C for a scale factor, unit/°C otherwise).

    Raises
    ------
    ValueError
        If ``reference_c`` is outside [−100, 200], ``quantities`` is empty, names repeat, a
        single-instance role appears twice, ``orders`` names an unknown quantity, or a fit
        fails (see :func:`fit_temperature_polynomial`).

    Examples
    --------
    An accelerometer's bias (g) and scale factor (mA/g, +100 ppm/°C) at six temperatures:

    >>> import numpy as np
    >>> from bench.analysis.thermal import QuantityPoints, calibrate_over_temperature
    >>> t = np.array([-40.0, -20.0, 0.0, 25.0, 45.0, 70.0])
    >>> rng = np.random.default_rng(0)
    >>> bias = 2e-3 + 5e-5 * (t - 25) + 1e-5 * rng.standard_normal(t.size)
    >>> sf = 1.2 * (1 + 100e-6 * (t - 25)) + 1e-5 * rng.standard_normal(t.size)
    >>> cal = calibrate_over_temperature([
    ...     QuantityPoints("k0", "bias", "g", t, bias, np.full(t.size, 1e-5)),
    ...     QuantityPoints("k1", "scale_factor", "mA/g", t, sf, np.full(t.size, 1e-5))])
    >>> cal.names, cal["k1"].tc_unit, cal["k0"].tc_unit
    (('k0', 'k1'), 'ppm/°C', 'g/°C')
    >>> round(cal["k1"].temperature_coefficient.value), round(cal["k0"].temperature_coefficient.value * 1e6)
    (100, 50)
    """
    ref = check_real("reference_c", reference_c, -100.0, 200.0)
    if not quantities:
        raise ValueError("quantities is empty: give at least one quantity's points")
    names = [q.name for q in quantities]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ValueError(f"quantity names must be unique; repeated: {', '.join(dup)}")
    for role in ("bias", "scale_factor", "k2"):
        having = [q.name for q in quantities if q.role == role]
        if len(having) > 1:
            raise ValueError(f"at most one quantity may have role {role!r}; got {', '.join(having)}")
    orders = dict(orders or {})
    unknown = sorted(set(orders) - set(names))
    if unknown:
        raise ValueError(f"orders names {', '.join(unknown)}, not among the quantities ({', '.join(names)})")
    return ThermalCalibration(ref, tuple(
        calibrate_quantity(q, reference_c=ref, order=orders.get(q.name), max_order=max_order,
                           criterion=criterion, uncertainty=uncertainty)
        for q in quantities))
