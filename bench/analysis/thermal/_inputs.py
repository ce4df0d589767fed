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

from dataclasses import dataclass

import numpy as np

#: Temperatures the analysis accepts, °C (wider than any chamber: −100 … +200).
from bench.analysis._checks import as_array, check_choice

TEMPERATURE_LIMITS_C = (-100.0, 200.0)
#: Roles a quantity may play in the output model (module docstring).
ROLES = ("bias", "scale_factor", "k2", "cross_axis")


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

    Parameters
    ----------
    name : str
        The quantity's name, an identifier (e.g. ``"k0"``, ``"bias"``); the key of the
        compensation file.
    role : {"bias", "scale_factor", "k2", "cross_axis"}
        Its role in the output model (module docstring).
    unit : str
        Unit of ``value`` and ``std`` (e.g. ``"g"``, ``"mA/g"``), non-empty.
    temperature_c : array_like, shape (m,)
        Temperature of each point, in °C, within −100 … +200.
    value : array_like, shape (m,)
        The estimate at each temperature, in ``unit``; a scale factor's non-zero.
    std : array_like, shape (m,)
        Its standard uncertainty, in ``unit``; > 0.
    temperature_std_c : array_like, shape (m,), optional
        Standard uncertainty of each point's temperature, in °C, within [0, 50].
    cross_input : str, optional
        For ``cross_axis`` only: the other-axis input it multiplies (an identifier).
    sign : float, default 1.0
        For ``cross_axis`` only: +1 or −1, as the model writes the term.

    Raises
    ------
    ValueError
        If a field is outside what is allowed above (the message names the field, e.g.
        ``k0.std[2]``, and the allowed range).

    Examples
    --------
    >>> from bench.analysis.thermal import QuantityPoints
    >>> q = QuantityPoints("k0", "bias", "g", [-40, 25, 70], [1.2e-3, 1.0e-3, 0.9e-3], [1e-5, 1e-5, 1e-5])
    >>> q.temperature_c.tolist(), q.role
    ([-40.0, 25.0, 70.0], 'bias')
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
