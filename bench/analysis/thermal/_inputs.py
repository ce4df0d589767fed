"""Inputs of the calibration over temperature: per-temperature estimates and their checks.

A thermal sweep yields, at each temperature point, an estimate of every calibrated quantity
(bias, scale factor, K2, misalignment …) with its standard uncertainty, and the temperature
the point stands for (of the sensing element, or of the unit's own sensor) with its own
uncertainty. :class:`QuantityPoints` carries one quantity's points with what a compensation
needs to know about it: its role in the output model and its unit.

Roles (the output model of :mod:`bench.analysis.thermal._compensation`)::

    output = scale_factor(T) · (x + bias(T) + k2(T)·x² + Σ_j sign_j · cross_j(T) · u_j)

``bias`` (input units), ``scale_factor`` (output units per input unit), ``k2`` (per input
unit), ``cross_axis`` (dimensionless: a misalignment in rad or a cross-coupling, multiplying
the input ``u_j`` along another axis; ``sign`` ±1 as the model writes it, e.g. −δp·a_o).
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import numpy as np

#: Temperatures the analysis accepts, °C (wider than any chamber: −100 … +200).
TEMPERATURE_LIMITS_C = (-100.0, 200.0)
#: Roles a quantity may play in the output model (module docstring).
ROLES = ("bias", "scale_factor", "k2", "cross_axis")


def is_real(value) -> bool:
    """A finite real number (bool excluded)."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool) and math.isfinite(value)


def check_real(name: str, value, low: float, high: float, *, low_open: bool = False) -> float:
    """``value`` as a float when finite and in [low, high] ((low, high] with ``low_open``);
    otherwise ValueError naming the value and the allowed range."""
    ok = is_real(value) and (low < value if low_open else low <= value) and value <= high
    if not ok:
        bracket = "(" if low_open else "["
        raise ValueError(f"{name} = {value!r} outside the allowed range {bracket}{low:g}, {high:g}]")
    return float(value)


def check_int(name: str, value, low: int, high: int) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or not low <= int(value) <= high:
        raise ValueError(f"{name} = {value!r} must be an integer in [{low}, {high}]")
    return int(value)


def check_choice(name: str, value, allowed: tuple[str, ...]) -> str:
    if value not in allowed:
        raise ValueError(f"{name} = {value!r} must be one of {', '.join(map(repr, allowed))}")
    return str(value)


def as_array(name: str, values, *, size: int | None = None, min_size: int = 1,
             positive: bool = False, limits: tuple[float, float] | None = None) -> np.ndarray:
    """1-D finite float array (a copy), checked for length, sign and range."""
    arr = np.array(values, dtype=float)
    if arr.ndim != 1 or arr.size < min_size or (size is not None and arr.size != size):
        want = f"length {size}" if size is not None else f"length ≥ {min_size}"
        raise ValueError(f"{name} must be a 1-D array of {want}, got shape {arr.shape}")
    bad = ~np.isfinite(arr)
    if positive:
        bad |= ~(arr > 0)
    if limits is not None:
        bad |= (arr < limits[0]) | (arr > limits[1])
    if np.any(bad):
        i = int(np.flatnonzero(bad)[0])
        allowed = (f"[{limits[0]:g}, {limits[1]:g}]" if limits is not None
                   else "(0, ∞)" if positive else "finite numbers")
        raise ValueError(f"{name}[{i}] = {float(arr[i])!r} outside the allowed range {allowed}")
    return arr


@dataclass(frozen=True, eq=False)
class QuantityPoints:
    """One quantity's estimates over temperature.

    ``temperature_c`` (m,): temperature of each point in °C (within −100 … +200);
    ``value`` (m,) and ``std`` (m,, > 0): the estimate and its standard uncertainty in
    ``unit``; ``temperature_std_c`` (m,, ≥ 0) or None: standard uncertainty of each point's
    temperature (sensor noise, element-to-sensor gradient), propagated through the fitted
    slope. ``role``: one of :data:`ROLES`; ``cross_input`` and ``sign`` only for
    ``cross_axis`` (the name of the other-axis input it multiplies, e.g. ``"a_p"``, and the
    sign the model writes it with).
    """

    name: str
    role: str
    unit: str
    temperature_c: np.ndarray
    value: np.ndarray
    std: np.ndarray
    temperature_std_c: np.ndarray | None = None
    cross_input: str | None = None
    sign: float = 1.0

    def __post_init__(self) -> None:
        if not (isinstance(self.name, str) and self.name.isidentifier()):
            raise ValueError(f"name = {self.name!r} must be an identifier (letters, digits, _)")
        check_choice(f"{self.name}.role", self.role, ROLES)
        if not (isinstance(self.unit, str) and self.unit.strip()):
            raise ValueError(f"{self.name}.unit = {self.unit!r} must be a non-empty string")
        t = as_array(f"{self.name}.temperature_c", self.temperature_c, limits=TEMPERATURE_LIMITS_C)
        object.__setattr__(self, "temperature_c", t)
        object.__setattr__(self, "value", as_array(f"{self.name}.value", self.value, size=t.size))
        object.__setattr__(self, "std", as_array(f"{self.name}.std", self.std, size=t.size, positive=True))
        if self.temperature_std_c is not None:
            ts = as_array(f"{self.name}.temperature_std_c", self.temperature_std_c, size=t.size,
                          limits=(0.0, 50.0))
            object.__setattr__(self, "temperature_std_c", ts)
        if self.role == "cross_axis":
            if not (isinstance(self.cross_input, str) and self.cross_input.isidentifier()):
                raise ValueError(f"{self.name}.cross_input = {self.cross_input!r} must name the other-axis "
                                 "input (an identifier such as 'a_p') for a cross_axis quantity")
            if self.sign not in (1.0, -1.0):
                raise ValueError(f"{self.name}.sign = {self.sign!r} must be +1 or -1")
        elif self.cross_input is not None or self.sign != 1.0:
            raise ValueError(f"{self.name}: cross_input and sign apply only to role 'cross_axis', "
                             f"not {self.role!r}")
        if self.role == "scale_factor" and np.any(self.value == 0.0):
            raise ValueError(f"{self.name}.value contains 0: a scale factor must be non-zero")
