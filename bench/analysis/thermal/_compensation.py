"""The thermal compensation model a navigation computer loads, and its use on raw outputs.

Output model (the roles of :mod:`bench.analysis.thermal._inputs`), T the temperature the file
names (``temperature_source``: the unit's own sensor, or the element)::

    output = SF(T) · (x + B(T) + K2(T)·x² + Σ_j sign_j · M_j(T) · u_j)
    q(T)   = Σ_k c_k · (T − reference_c)^k          for each quantity q, k = 0 … 3

x the input along the sensitive axis (``input_unit``), ``output`` in ``output_unit``, u_j the
inputs along other axes that cross-axis terms multiply. Without a scale-factor quantity the
output is already in input units (SF ≡ 1, and the file must say ``output_unit = input_unit``).
:func:`compensate` inverts the model: x̂ = 2z / (1 + √(1 + 4·K2·z)) with
z = output/SF(T) − B(T) − Σ sign·M(T)·u (the root of x + K2·x² = z that tends to z as K2 → 0).

The model's file (TOML, documented and versioned) is read and written by
:mod:`bench.analysis.thermal._compensation_file`; the checks live here, on the dataclasses, so
a model built in code and a model read from a file pass the same ones (errors name the
file's key: ``quantities.<name>.coefficients`` …).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from bench.analysis._checks import as_array, check_choice, check_int, check_real, is_real
from bench.analysis.thermal._calibration import ThermalCalibration
from bench.analysis.thermal._inputs import ROLES, TEMPERATURE_LIMITS_C
from bench.analysis.thermal._poly import MAX_ORDER, polynomial_rows

FORMAT = "inertial-bench-thermal-compensation"
FORMAT_VERSION = 1
SUPPORTED_VERSIONS = (1,)
TEMPERATURE_SOURCES = ("unit_sensor", "element")
ORDER_SELECTIONS = ("bic", "loo", "fixed")
OUTSIDE_POLICIES = ("raise", "clamp", "extrapolate")
_GRID_POINTS = 201


def _check_text(key: str, value, *, empty: bool = False) -> str:
    if not isinstance(value, str) or (not empty and not value.strip()) or len(value) > 4096:
        allowed = "a string" if empty else "a non-empty string"
        raise ValueError(f"{key} = {value!r}: allowed {allowed} (≤ 4096 characters)")
    return value


def _check_range(key: str, value) -> tuple[float, float]:
    lo_lim, hi_lim = TEMPERATURE_LIMITS_C
    if not (isinstance(value, (list, tuple)) and len(value) == 2 and all(is_real(v) for v in value)
            and lo_lim <= value[0] < value[1] <= hi_lim):
        raise ValueError(f"{key} = {value!r}: allowed [low, high] °C with {lo_lim:g} ≤ low < high ≤ {hi_lim:g}")
    return float(value[0]), float(value[1])


@dataclass(frozen=True, eq=False)
class QuantityCompensation:
    """One quantity of a compensation model: its polynomial of temperature, covariance and fit figures.

    One quantity of the model: polynomial ``coefficients`` about the model's reference
    temperature (unit per °C^k), their ``covariance``, and the fit's figures (module
    docstring). ``key`` is the TOML path used in error messages. A :class:`CompensationModel`
    built in code is given one per quantity; the values are checked on construction
    (``ValueError``).

    Attributes
    ----------
    name : str
        The quantity's name (an identifier): its ``[quantities.<name>]`` table.
    role : {"bias", "scale_factor", "k2", "cross_axis"}
        Its role in the output model.
    unit : str
        Its unit.
    coefficients : ndarray, shape (n + 1,)
        c_k of q(T) = Σ c_k (T − reference_c)^k, in unit per °C^k; orders 0 … 3.
    covariance : ndarray, shape (n + 1, n + 1)
        Their covariance (symmetric positive semi-definite).
    residual_rms : float
        RMS of the fit's residuals, in unit.
    residual_max_abs : float
        Largest absolute residual, in unit.
    prediction_std_max : float
        Largest standard uncertainty of the curve over the valid range, in unit.
    n_points : int
        Number of temperatures fitted.
    order_selection : {"bic", "loo", "fixed"}
        How the order was chosen.
    cross_input : str or None
        For ``cross_axis`` only: the other-axis input it multiplies.
    sign : float
        For ``cross_axis`` only: ±1 as the model writes the term (1.0 otherwise).
    """

    name: str
    role: str
    unit: str
    coefficients: np.ndarray
    covariance: np.ndarray
    residual_rms: float
    residual_max_abs: float
    prediction_std_max: float
    n_points: int
    order_selection: str
    cross_input: str | None = None
    sign: float = 1.0

    def __post_init__(self) -> None:
        key = f"quantities.{self.name}"
        if not (isinstance(self.name, str) and self.name.isidentifier()):
            raise ValueError(f"quantities.{self.name!r}: a quantity name must be an identifier (letters, digits, _)")
        check_choice(f"{key}.role", self.role, ROLES)
        _check_text(f"{key}.unit", self.unit)
        c = self.coefficients
        if not (isinstance(c, (list, tuple, np.ndarray)) and 1 <= len(c) <= MAX_ORDER + 1
                and all(is_real(v) for v in c)):
            raise ValueError(f"{key}.coefficients = {c!r}: allowed 1 to {MAX_ORDER + 1} finite numbers "
                             f"(orders 0 … {MAX_ORDER})")
        coef = np.array(c, dtype=float)
        n = coef.size
        cov_in = self.covariance
        try:
            cov = np.array(cov_in, dtype=float)
        except (TypeError, ValueError):
            cov = np.full((0, 0), np.nan)
        if cov.shape != (n, n) or not np.all(np.isfinite(cov)):
            raise ValueError(f"{key}.covariance = {cov_in!r}: allowed a {n}×{n} array of finite numbers "
                             f"(one row per coefficient)")
        scale = max(float(np.abs(cov).max()), 1e-300)
        if not np.allclose(cov, cov.T, rtol=1e-9, atol=1e-12 * scale) \
                or np.linalg.eigvalsh((cov + cov.T) / 2).min() < -1e-9 * scale:
            raise ValueError(f"{key}.covariance must be symmetric positive semi-definite")
        object.__setattr__(self, "coefficients", coef)
        object.__setattr__(self, "covariance", (cov + cov.T) / 2)
        for name in ("residual_rms", "residual_max_abs", "prediction_std_max"):
            object.__setattr__(self, name, check_real(f"{key}.{name}", getattr(self, name), 0.0, math.inf))
        object.__setattr__(self, "n_points", check_int(f"{key}.n_points", self.n_points, n, 10_000))
        check_choice(f"{key}.order_selection", self.order_selection, ORDER_SELECTIONS)
        if self.role == "cross_axis":
            if not (isinstance(self.cross_input, str) and self.cross_input.isidentifier()):
                raise ValueError(f"{key}.cross_input = {self.cross_input!r}: allowed the name of the other-axis "
                                 "input it multiplies (an identifier, e.g. 'a_p')")
            if self.sign not in (1.0, -1.0) or isinstance(self.sign, bool):
                raise ValueError(f"{key}.sign = {self.sign!r}: allowed 1.0 or -1.0")
            object.__setattr__(self, "sign", float(self.sign))
        elif self.cross_input is not None or self.sign != 1.0:
            raise ValueError(f"{key}: cross_input and sign are allowed only with role 'cross_axis', "
                             f"not {self.role!r}")

    @property
    def order(self) -> int:
        return self.coefficients.size - 1

    def evaluate(self, temperature_c, reference_c: float) -> np.ndarray:
        u = np.atleast_1d(np.asarray(temperature_c, dtype=float)) - reference_c
        return polynomial_rows(u, self.order) @ self.coefficients

    def std(self, temperature_c, reference_c: float) -> np.ndarray:
        """Standard uncertainty of the stored curve at temperatures (from ``covariance``)."""
        x = polynomial_rows(np.atleast_1d(np.asarray(temperature_c, dtype=float)) - reference_c, self.order)
        return np.sqrt(np.clip(np.einsum("ij,jk,ik->i", x, self.covariance, x), 0.0, None))

    def to_dict(self) -> dict:
        d: dict = {"role": self.role, "unit": self.unit, "coefficients": self.coefficients.tolist(),
                   "covariance": self.covariance.tolist(), "residual_rms": self.residual_rms,
                   "residual_max_abs": self.residual_max_abs, "prediction_std_max": self.prediction_std_max,
                   "n_points": self.n_points, "order_selection": self.order_selection}
        if self.role == "cross_axis":
            d["cross_input"], d["sign"] = self.cross_input, self.sign
        return d


@dataclass(frozen=True, eq=False)
class CompensationModel:
    """A thermal compensation model: per-quantity polynomials of temperature and the output model.

    The whole compensation file (module docstring). ``created`` and ``notes`` are the
    caller's free text (a date, a run id: the library reads no clock).

    Usually made by :func:`compensation_model` or read by :func:`compensation_from_toml`;
    a model built in code passes the same checks. Index it by name
    (``model["k0"]``) or by role (``model.quantity("bias")``).

    Parameters
    ----------
    unit_serial : str
        Serial number of the unit, non-empty (≤ 4096 characters).
    unit_model : str
        Model of the unit, non-empty.
    temperature_source : {"unit_sensor", "element"}
        Which temperature T the curves take: the unit's own sensor or the sensing element.
    reference_c : float
        Reference temperature of every polynomial, in °C, within −100 … 200.
    valid_range_c : tuple of float
        ``(low, high)`` in °C with −100 ≤ low < high ≤ 200: where the model holds.
    input_unit : str
        Unit of the input x along the sensitive axis (e.g. ``"g"``).
    output_unit : str
        Unit of the raw output (e.g. ``"mA"``); must equal ``input_unit`` without a
        scale-factor quantity.
    quantities : tuple of QuantityCompensation
        One or more, names unique, at most one each of ``bias``, ``scale_factor``, ``k2``; a
        scale factor must not cross zero within ``valid_range_c``.
    created : str, default ""
        The caller's free text (a date, a run id).
    notes : str, default ""
        The caller's free text.
    version : int, default 1
        File format version; this reader supports 1.
    element_lag_s : float, optional
        With ``temperature_source = "element"``: the element's temperature is the unit's
        sensor through a first-order lag of this time constant, s, in [0, 1e5]
        (τ·dT_e/dt = T_sensor − T_e; :func:`analyze_thermal_record`); the navigation computer
        filters its sensor so before evaluating the curves. None: not stated (an optional key
        of the file, written only when set).

    Raises
    ------
    ValueError
        If a field is outside what is allowed above (the message names the file's key).
    """

    unit_serial: str
    unit_model: str
    temperature_source: str
    reference_c: float
    valid_range_c: tuple[float, float]
    input_unit: str
    output_unit: str
    quantities: tuple[QuantityCompensation, ...]
    created: str = ""
    notes: str = ""
    version: int = FORMAT_VERSION
    element_lag_s: float | None = None

    def __post_init__(self) -> None:
        if self.version not in SUPPORTED_VERSIONS or isinstance(self.version, bool):
            raise ValueError(f"version = {self.version!r}: this reader supports versions "
                             f"{', '.join(map(str, SUPPORTED_VERSIONS))}")
        _check_text("unit_serial", self.unit_serial)
        _check_text("unit_model", self.unit_model)
        _check_text("created", self.created, empty=True)
        _check_text("notes", self.notes, empty=True)
        check_choice("temperature_source", self.temperature_source, TEMPERATURE_SOURCES)
        if self.element_lag_s is not None:
            if self.temperature_source != "element":
                raise ValueError(f"element_lag_s = {self.element_lag_s!r} is allowed only with temperature_source "
                                 f"'element', not {self.temperature_source!r}")
            object.__setattr__(self, "element_lag_s", check_real("element_lag_s", self.element_lag_s, 0.0, 1e5))
        object.__setattr__(self, "reference_c", check_real("reference_c", self.reference_c, *TEMPERATURE_LIMITS_C))
        object.__setattr__(self, "valid_range_c", _check_range("valid_range_c", self.valid_range_c))
        _check_text("input_unit", self.input_unit)
        _check_text("output_unit", self.output_unit)
        if not self.quantities:
            raise ValueError("quantities: allowed one or more [quantities.<name>] tables, got none")
        names = [q.name for q in self.quantities]
        for n in names:
            if names.count(n) > 1:
                raise ValueError(f"quantities.{n} appears twice: names must be unique")
        for role in ("bias", "scale_factor", "k2"):
            having = [q.name for q in self.quantities if q.role == role]
            if len(having) > 1:
                raise ValueError(f"quantities {', '.join(having)} all have role {role!r}: allowed at most one")
        sf = self.quantity("scale_factor")
        if sf is None and self.output_unit != self.input_unit:
            raise ValueError(f"output_unit = {self.output_unit!r} differs from input_unit = {self.input_unit!r} "
                             "but no quantity has role 'scale_factor': add one, or state the output in input units")
        if sf is not None:
            grid = np.linspace(*self.valid_range_c, _GRID_POINTS)
            values = sf.evaluate(grid, self.reference_c)
            if not (np.all(values > 0) or np.all(values < 0)):
                raise ValueError(f"quantities.{sf.name}.coefficients = {sf.coefficients.tolist()}: the scale "
                                 f"factor crosses zero within valid_range_c {list(self.valid_range_c)}")

    def quantity(self, role: str) -> QuantityCompensation | None:
        """The quantity playing a single-instance role ("bias", "scale_factor", "k2"), or None."""
        return next((q for q in self.quantities if q.role == role), None)

    def __getitem__(self, name: str) -> QuantityCompensation:
        for q in self.quantities:
            if q.name == name:
                return q
        raise KeyError(f"no quantity {name!r}; the model holds {', '.join(q.name for q in self.quantities)}")

    def to_dict(self) -> dict:
        return {"format": FORMAT, "version": self.version, "unit_serial": self.unit_serial,
                "unit_model": self.unit_model, "created": self.created,
                "temperature_source": self.temperature_source, "reference_c": self.reference_c,
                "valid_range_c": list(self.valid_range_c), "input_unit": self.input_unit,
                "output_unit": self.output_unit, "notes": self.notes,
                **({} if self.element_lag_s is None else {"element_lag_s": self.element_lag_s}),
                "quantities": {q.name: q.to_dict() for q in self.quantities}}


def compensation_model(calibration: ThermalCalibration, *, unit_serial: str, unit_model: str,
                       input_unit: str, output_unit: str, temperature_source: str = "unit_sensor",
                       valid_range_c: tuple[float, float] | None = None, created: str = "",
                       notes: str = "") -> CompensationModel:
    """The compensation model of a calibration.

    ``valid_range_c`` defaults to the temperature span every quantity was calibrated over
    (the intersection of their points' ranges). Each quantity's selected polynomial, its
    covariance and its fit figures go into the model; write it with
    :func:`compensation_to_toml`.

    Parameters
    ----------
    calibration : ThermalCalibration
        The result of :func:`calibrate_over_temperature`.
    unit_serial : str
        Serial number of the unit.
    unit_model : str
        Model of the unit.
    input_unit : str
        Unit of the input along the sensitive axis (e.g. ``"g"``, ``"deg/s"``).
    output_unit : str
        Unit of the raw output (e.g. ``"mA"``); ``input_unit`` when no quantity is a scale
        factor.
    temperature_source : {"unit_sensor", "element"}, default "unit_sensor"
        Which temperature the curves take.
    valid_range_c : tuple of float, optional
        ``(low, high)`` in °C, −100 ≤ low < high ≤ 200; default the calibrated span.
    created : str, default ""
        The caller's free text (a date, a run id).
    notes : str, default ""
        The caller's free text.

    Returns
    -------
    CompensationModel
        The model the navigation computer loads.

    Raises
    ------
    ValueError
        If the quantities' temperature ranges do not overlap (and no ``valid_range_c`` is
        given), ``valid_range_c`` is not an allowed range, or the model's own checks fail
        (:class:`CompensationModel`).

    Examples
    --------
    >>> import numpy as np
    >>> from bench.analysis.thermal import QuantityPoints, calibrate_over_temperature, compensation_model
    >>> t = np.array([-40.0, -20.0, 0.0, 25.0, 45.0, 70.0])  # noise-free points, for brevity
    >>> bias = QuantityPoints("k0", "bias", "g", t, 2e-3 + 5e-5 * (t - 25), np.full(t.size, 1e-5))
    >>> sf = QuantityPoints("k1", "scale_factor", "mA/g", t, 1.2 * (1 + 100e-6 * (t - 25)), np.full(t.size, 1e-5))
    >>> model = compensation_model(calibrate_over_temperature([bias, sf]), unit_serial="QA-0001",
    ...                            unit_model="QA-2000", input_unit="g", output_unit="mA")
    >>> model.valid_range_c, model.reference_c, [q.name for q in model.quantities]
    ((-40.0, 70.0), 25.0, ['k0', 'k1'])
    >>> model["k1"].coefficients.round(6).tolist()  # mA/g, mA/g/°C
    [1.2, 0.00012]
    """
    lo = max(q.fit.temperature_range_c[0] for q in calibration.quantities)
    hi = min(q.fit.temperature_range_c[1] for q in calibration.quantities)
    if valid_range_c is None:
        if not lo < hi:
            raise ValueError(f"the quantities' temperature ranges do not overlap ({lo:g} … {hi:g} °C): "
                             "pass valid_range_c")
        valid_range_c = (lo, hi)
    rng = _check_range("valid_range_c", valid_range_c)
    grid = np.linspace(rng[0], rng[1], _GRID_POINTS)
    quantities = []
    for q in calibration.quantities:
        fit, p = q.fit, q.points
        quantities.append(QuantityCompensation(
            name=p.name, role=p.role, unit=p.unit, coefficients=fit.coefficients, covariance=fit.covariance,
            residual_rms=float(np.sqrt(np.mean(fit.residuals**2))),
            residual_max_abs=float(np.abs(fit.residuals).max()),
            prediction_std_max=float(fit.std(grid).max()), n_points=int(fit.temperature_c.size),
            order_selection=fit.criterion, cross_input=p.cross_input, sign=p.sign))
    return CompensationModel(unit_serial=unit_serial, unit_model=unit_model,
                             temperature_source=temperature_source, reference_c=calibration.reference_c,
                             valid_range_c=rng, input_unit=input_unit, output_unit=output_unit,
                             quantities=tuple(quantities), created=created, notes=notes)


# --------------------------------------------------------------------------- use


@dataclass(frozen=True, eq=False)
class CompensatedOutput:
    """Output of :func:`compensate`: the compensated input estimate per sample and what was applied.

    Compensated input estimate x̂ (``input_unit``) per sample; ``applied`` names the
    quantities used, ``not_applied`` the cross-axis ones whose input was not given (reason);
    ``in_range`` marks the samples whose temperature lies in the model's valid range.

    Attributes
    ----------
    input_estimate : ndarray, shape (N,)
        x̂ per sample, in the model's ``input_unit``.
    applied : tuple of str
        Names of the quantities used, in the order applied.
    not_applied : dict of str to str
        Cross-axis quantities left out, with the reason.
    in_range : ndarray of bool, shape (N,)
        Samples whose temperature lies within ``valid_range_c``.
    """

    input_estimate: np.ndarray
    applied: tuple[str, ...]
    not_applied: dict[str, str]
    in_range: np.ndarray


def _temperatures(model: CompensationModel, temperature_c, n: int, outside: str) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(temperature_c, dtype=float)
    t = np.broadcast_to(t, (n,)).copy() if t.ndim == 0 else as_array("temperature_c", t, size=n)
    if not np.all(np.isfinite(t)):
        raise ValueError("temperature_c must be finite")
    check_choice("outside", outside, OUTSIDE_POLICIES)
    lo, hi = model.valid_range_c
    in_range = (t >= lo) & (t <= hi)
    if outside == "raise" and not np.all(in_range):
        i = int(np.flatnonzero(~in_range)[0])
        raise ValueError(f"temperature_c[{i}] = {t[i]:g} °C outside the model's valid range [{lo:g}, {hi:g}] °C "
                         "(outside='clamp' or 'extrapolate' to use it anyway)")
    return (np.clip(t, lo, hi) if outside == "clamp" else t), in_range


def _cross_terms(model: CompensationModel, t: np.ndarray, cross_inputs, n: int) -> tuple[np.ndarray, list, dict]:
    given = dict(cross_inputs or {})
    names = {q.cross_input for q in model.quantities if q.role == "cross_axis"}
    unknown = sorted(set(given) - names)
    if unknown:
        raise ValueError(f"cross_inputs names {', '.join(unknown)}; the model's cross-axis inputs are "
                         f"{', '.join(sorted(n for n in names if n)) or 'none'}")
    total, applied, skipped = np.zeros(n), [], {}
    for q in model.quantities:
        if q.role != "cross_axis":
            continue
        if q.cross_input not in given:
            skipped[q.name] = f"its input {q.cross_input!r} was not given in cross_inputs"
            continue
        u = as_array(f"cross_inputs[{q.cross_input!r}]", given[q.cross_input], size=n)
        total += q.sign * q.evaluate(t, model.reference_c) * u
        applied.append(q.name)
    return total, applied, skipped


def compensate(model: CompensationModel, output, temperature_c, *,
               cross_inputs: Mapping[str, np.ndarray] | None = None, outside: str = "raise") -> CompensatedOutput:
    """The input estimate x̂ per sample from raw outputs and temperatures, by inverting the model.

    Invert the output model: the input x̂ per sample from raw ``output`` (``output_unit``)
    at ``temperature_c`` (°C, per sample or one value). ``cross_inputs`` maps a cross-axis
    term's ``cross_input`` name to that axis's input per sample. ``outside``: "raise" (a
    temperature outside ``valid_range_c`` is an error), "clamp" (evaluate at the nearer
    limit, as a navigation computer would) or "extrapolate". The inversion is
    x̂ = 2z / (1 + √(1 + 4·K2·z)) with z = output/SF(T) − B(T) − Σ sign·M(T)·u (module
    docstring).

    Parameters
    ----------
    model : CompensationModel
        The compensation model.
    output : array_like, shape (N,)
        Raw output per sample, in the model's ``output_unit``; finite.
    temperature_c : float or array_like, shape (N,)
        Temperature per sample (or one for all), in °C, from the model's
        ``temperature_source``; finite.
    cross_inputs : mapping of str to array_like, optional
        Input along another axis per sample (``input_unit``), keyed by a cross-axis term's
        ``cross_input`` name; a term whose input is missing is not applied.
    outside : {"raise", "clamp", "extrapolate"}, default "raise"
        What to do with a temperature outside ``valid_range_c``.

    Returns
    -------
    CompensatedOutput
        x̂ per sample (``input_unit``), the quantities applied and not applied, and which
        samples were in range.

    Raises
    ------
    ValueError
        If ``output`` or ``temperature_c`` is not finite or not of one length, ``outside`` is
        unknown, a temperature is outside the valid range with ``outside="raise"``,
        ``cross_inputs`` names an input the model has not, or an output lies beyond the K2
        model's turning point.

    Examples
    --------
    >>> import numpy as np
    >>> from bench.analysis.thermal import QuantityPoints, calibrate_over_temperature, compensate, compensation_model
    >>> t = np.array([-40.0, -20.0, 0.0, 25.0, 45.0, 70.0])  # noise-free points, for brevity
    >>> bias = QuantityPoints("k0", "bias", "g", t, 2e-3 + 5e-5 * (t - 25), np.full(t.size, 1e-5))
    >>> sf = QuantityPoints("k1", "scale_factor", "mA/g", t, 1.2 * (1 + 100e-6 * (t - 25)), np.full(t.size, 1e-5))
    >>> model = compensation_model(calibrate_over_temperature([bias, sf]), unit_serial="QA-0001",
    ...                            unit_model="QA-2000", input_unit="g", output_unit="mA")
    >>> temp = np.array([-30.0, 10.0, 60.0])
    >>> x = np.array([0.0, 0.5, 1.0])  # g
    >>> raw = 1.2 * (1 + 100e-6 * (temp - 25)) * (x + 2e-3 + 5e-5 * (temp - 25))  # mA
    >>> out = compensate(model, raw, temp)
    >>> bool(np.all(np.abs(out.input_estimate - x) < 1e-9)), out.applied
    (True, ('k1', 'k0'))
    >>> compensate(model, raw, [-50.0, 10.0, 60.0], outside="clamp").in_range.tolist()
    [False, True, True]
    """
    y = as_array("output", output)
    t, in_range = _temperatures(model, temperature_c, y.size, outside)
    ref = model.reference_c
    applied = []
    sf, bias, k2 = (model.quantity(r) for r in ("scale_factor", "bias", "k2"))
    z = y.copy()
    if sf is not None:
        z = z / sf.evaluate(t, ref)
        applied.append(sf.name)
    if bias is not None:
        z -= bias.evaluate(t, ref)
        applied.append(bias.name)
    cross, cross_applied, skipped = _cross_terms(model, t, cross_inputs, y.size)
    z -= cross
    applied += cross_applied
    if k2 is not None:
        k = k2.evaluate(t, ref)
        disc = 1.0 + 4.0 * k * z
        if np.any(disc < 0):
            i = int(np.flatnonzero(disc < 0)[0])
            raise ValueError(f"output[{i}] = {float(y[i])!r} lies beyond the K2 model's turning point "
                             f"(1 + 4·K2·z = {disc[i]:.3g} < 0): no input gives it")
        z = 2.0 * z / (1.0 + np.sqrt(disc))
        applied.append(k2.name)
    return CompensatedOutput(z, tuple(applied), skipped, in_range)


def model_output(model: CompensationModel, input_value, temperature_c, *,
                 cross_inputs: Mapping[str, np.ndarray] | None = None, outside: str = "raise") -> np.ndarray:
    """The output the model predicts for input ``input_value`` (``input_unit``) at
    ``temperature_c``: the forward model that :func:`compensate` inverts."""
    x = as_array("input_value", input_value)
    t, _ = _temperatures(model, temperature_c, x.size, outside)
    ref = model.reference_c
    sf, bias, k2 = (model.quantity(r) for r in ("scale_factor", "bias", "k2"))
    indicated = x.copy()
    if bias is not None:
        indicated += bias.evaluate(t, ref)
    if k2 is not None:
        indicated += k2.evaluate(t, ref) * x**2
    indicated += _cross_terms(model, t, cross_inputs, x.size)[0]
    return indicated if sf is None else sf.evaluate(t, ref) * indicated
