"""A sensor unit as two thermal nodes — case and sensing element — driven by its ambient air.

    dT_c/dt = (T_air − T_c)/τ_ca + ρ (T_e − T_c)/τ_e          case (the unit's housing)
    dT_e/dt = (T_c − T_e)/τ_e + q·powered                       sensing element

ρ = C_e/C_c (``capacity_ratio``), τ_e the element's time constant to the case
(``element_tau_s``), q the self-heating of the element while powered.  τ_ca and q follow
from the figures a data sheet or a warm-up record gives: the dominant time constant of the
unit (``dominant_tau_s``, the slow eigenvalue is exactly −1/τ) and the steady case rise
above the air while powered (``self_heating_delta_c``).  Powered, the element then runs
``q·τ_e`` above the case; during a ramp of the air at r °C/s the case lags the air and the
element lags the case by about r·τ_e: the gradients a thermal calibration sees.

Exact between events (``sim.physics.thermal_lti``): the ambient is an exponential
polynomial per segment (a constant, or the chamber air's closed-form response), the heating
is constant between power changes, so the node temperatures are closed-form exponential
polynomials; a new segment starts at each ambient change and each power change, the state
continuous across it.  History is kept, so any time from the creation on can be evaluated.

Hysteresis (:meth:`TwoNodeBody.hysteresis_memory_c`): a play (backlash) operator of half
width w on the element temperature — the memory m stays put while |T_e − m| < w and is
dragged along at distance w otherwise, so after a warm excursion m sits w below T_e and
after a cold one w above: up-ramps and down-ramps see T_e − m = +w / −w.  It is sampled on
an absolute grid of ``HYSTERESIS_GRID_S`` (not on the query times, so the result does not
depend on how the unit is read) and clamped continuously between grid points.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from sim.physics.thermal_lti import ExpPoly, LinearBlock, evaluate_segments

#: spacing of the hysteresis memory's absolute time grid (s); element time constants are minutes
HYSTERESIS_GRID_S = 10.0


class AmbientSource(Protocol):
    """The air around a unit: a scalar exponential polynomial per segment, listeners called at
    each change with its time."""

    listeners: list[Callable[[float], None]]

    def signal_from(self, t_s: float) -> ExpPoly:
        """The air temperature (°C) from ``t_s`` on, until its next change."""


class ConstantAmbient:
    """A still room: the air at ``value_c`` for ever."""

    def __init__(self, value_c: float) -> None:
        self.value_c = float(value_c)
        self.listeners: list[Callable[[float], None]] = []

    def signal_from(self, t_s: float) -> ExpPoly:
        return ExpPoly.constant(t_s, [self.value_c])


@dataclass(frozen=True)
class TwoNodeParams:
    """Thermal figures of one unit (times in s, temperatures in °C)."""

    dominant_tau_s: float = 600.0       # slow eigenvalue −1/τ: what a warm-up record shows
    element_tau_s: float = 30.0         # element ↔ case
    capacity_ratio: float = 0.15        # ρ = C_element / C_case
    self_heating_delta_c: float = 4.0   # steady case rise above the air while powered
    hysteresis_width_c: float = 0.0     # play operator half width w (0: no memory)

    def __post_init__(self) -> None:
        checks = {"dominant_tau_s": (1.0, 1e5), "element_tau_s": (0.1, 1e5), "capacity_ratio": (1e-3, 10.0),
                  "self_heating_delta_c": (0.0, 100.0), "hysteresis_width_c": (0.0, 100.0)}
        for name, (lo, hi) in checks.items():
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not lo <= v <= hi:
                raise ValueError(f"{name}={v!r} outside the allowed range [{lo}, {hi}]")
        tau, te, rho = self.dominant_tau_s, self.element_tau_s, self.capacity_ratio
        if not te < tau / (1.0 + rho) / 1.5:
            raise ValueError(f"element_tau_s={te!r} must be < dominant_tau_s/(1 + capacity_ratio)/1.5 = "
                             f"{tau / (1 + rho) / 1.5:.6g} s (the element is the fast node)")

    @property
    def case_tau_s(self) -> float:
        """τ_ca (case ↔ air) such that the slow eigenvalue is exactly −1/dominant_tau_s."""
        tau, te, rho = self.dominant_tau_s, self.element_tau_s, self.capacity_ratio
        return tau * (tau - te) / ((1.0 + rho) * tau - te)

    @property
    def heating_c_per_s(self) -> float:
        """q: the element's heating rate while powered."""
        return self.self_heating_delta_c / (self.capacity_ratio * self.case_tau_s)

    @property
    def element_rise_over_case_c(self) -> float:
        """Steady element − case difference while powered."""
        return self.heating_c_per_s * self.element_tau_s

    def block(self) -> LinearBlock:
        tca, te, rho = self.case_tau_s, self.element_tau_s, self.capacity_ratio
        a = np.array([[-1.0 / tca - rho / te, rho / te], [1.0 / te, -1.0 / te]])
        b = np.array([[1.0 / tca, 0.0], [0.0, 1.0]])  # inputs: air °C, heating °C/s
        return LinearBlock(a, b)


class TwoNodeBody:
    """Case and element temperatures of one unit on the virtual clock.

    Starts at ``t0_s`` unpowered, in equilibrium with its ambient.  ``set_power`` calls and
    ambient changes come at non-decreasing times; queries accept any time from ``t0_s`` on
    (the whole history is kept: a few segments per chamber set point or power cycle).
    """

    def __init__(self, params: TwoNodeParams, ambient: AmbientSource, t0_s: float = 0.0) -> None:
        self.params = params
        self.ambient = ambient
        self._block = params.block()
        self._q = params.heating_c_per_s
        self._powered = False
        air0 = float(ambient.signal_from(t0_s).value(t0_s)[0])
        self._w = float(params.hysteresis_width_c)
        self._grid_k0 = math.ceil(t0_s / HYSTERESIS_GRID_S)
        self._m0 = air0          # memory before the first grid point
        self._m_grid: list[float] = []  # memory at grid points k0, k0+1, ...
        self._starts: list[float] = []
        self._signals: list[ExpPoly] = []
        self._starts_arr = np.empty(0)
        self._append(float(t0_s), np.array([air0, air0]))
        ambient.listeners.append(self._ambient_changed)

    # -- segments ----------------------------------------------------------------------------
    def _append(self, t: float, x0: np.ndarray) -> None:
        u = ExpPoly.stack([self.ambient.signal_from(t), ExpPoly.constant(t, [self._q if self._powered else 0.0])])
        signal = self._block.respond(x0, u)
        if self._starts and self._starts[-1] == t:
            self._signals[-1] = signal
        else:
            self._starts.append(t)
            self._signals.append(signal)
            self._starts_arr = np.asarray(self._starts)
        # hysteresis memory past a new boundary was computed on the old trajectory: recompute
        keep = max(0, math.floor(t / HYSTERESIS_GRID_S) - self._grid_k0 + 1)
        del self._m_grid[keep:]

    def _boundary(self, t: float) -> None:
        t = float(t)
        if not (math.isfinite(t) and t >= self._starts[-1]):
            raise ValueError(f"t={t!r} s must be finite and ≥ the last thermal change at {self._starts[-1]!r} s")
        self._append(t, self._signals[-1].value(t))

    def _ambient_changed(self, t: float) -> None:
        self._boundary(t)

    def set_power(self, t_s: float, on: bool) -> None:
        """Self-heating on or off from ``t_s``."""
        if bool(on) == self._powered:
            return
        self._powered = bool(on)
        self._boundary(t_s)

    @property
    def powered(self) -> bool:
        return self._powered

    @property
    def last_change_s(self) -> float:
        return self._starts[-1]

    # -- queries -----------------------------------------------------------------------------
    def nodes_c(self, t) -> np.ndarray:
        """(k, 2): case and element temperatures (°C) at times ``t``."""
        return evaluate_segments(self._starts_arr, self._signals, t)

    def rates_c_per_s(self, t) -> np.ndarray:
        """(k, 2): their time derivatives (°C/s)."""
        return evaluate_segments(self._starts_arr, self._signals, t, derivative=True)

    def case_c(self, t) -> np.ndarray:
        return self.nodes_c(t)[:, 0]

    def element_c(self, t) -> np.ndarray:
        return self.nodes_c(t)[:, 1]

    def hysteresis_memory_c(self, t, element_c: np.ndarray | None = None) -> np.ndarray:
        """The play operator's memory m (°C) at times ``t`` (``element_c``: T_e at ``t`` if known)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        te = self.element_c(t) if element_c is None else np.asarray(element_c, dtype=float)
        if self._w == 0.0 or not t.size:
            return te.copy()
        k = np.floor(t / HYSTERESIS_GRID_S).astype(np.int64)
        self._extend_memory(int(k.max()))
        grid = np.asarray(self._m_grid)
        j = k - self._grid_k0
        base = (np.where(j >= 0, grid[np.clip(j, 0, grid.size - 1)], self._m0) if grid.size
                else np.full(t.shape, self._m0))
        return np.clip(base, te - self._w, te + self._w)

    def _extend_memory(self, k_max: int) -> None:
        have = len(self._m_grid)
        need = k_max - self._grid_k0 + 1
        if need <= have:
            return
        times = (self._grid_k0 + np.arange(have, need)) * HYSTERESIS_GRID_S
        te = self.element_c(times)
        m = self._m_grid[-1] if have else self._m0
        w = self._w
        out = self._m_grid
        for v in te.tolist():  # the play operator: sequential by nature, a few thousand steps a day
            if v - m > w:
                m = v - w
            elif m - v > w:
                m = v + w
            out.append(m)
