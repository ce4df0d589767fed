"""First-order thermal model of a self-heating sensor.

The sensor body is one lumped node: while powered it relaxes exponentially toward
``ambient_c + self_heating_delta_c``, while unpowered back toward ``ambient_c``, both
with time constant ``tau_s``. The temperature is continuous at every switch.
"""

from __future__ import annotations

import math

import numpy as np


def _as_times(t) -> np.ndarray:
    arr = np.asarray(t, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise ValueError("times must be finite")
    return arr


class ThermalNode:
    """Lumped first-order thermal node, temperatures in °C, times in simulated seconds.

    Starts unpowered at ``ambient_c`` (thermal equilibrium). ``set_power`` calls must come
    at non-decreasing times; ``temperature_c`` accepts any times at or after the last
    switch (earlier times raise ``ValueError``: the history is not kept).
    """

    def __init__(self, ambient_c: float = 23.0, self_heating_delta_c: float = 4.0, tau_s: float = 600.0):
        if not (-100.0 <= ambient_c <= 200.0):
            raise ValueError(f"ambient_c={ambient_c!r} outside the allowed range [-100, 200]")
        if not (0.0 <= self_heating_delta_c <= 100.0):
            raise ValueError(f"self_heating_delta_c={self_heating_delta_c!r} outside the allowed range [0, 100]")
        if not (0.0 < tau_s <= 1e6):
            raise ValueError(f"tau_s={tau_s!r} outside the allowed range (0, 1e6]")
        self.ambient_c = float(ambient_c)
        self.self_heating_delta_c = float(self_heating_delta_c)
        self.tau_s = float(tau_s)
        self._powered = False
        self._t_switch = -math.inf  # at equilibrium since forever
        self._temp_at_switch_c = self.ambient_c

    @property
    def powered(self) -> bool:
        return self._powered

    @property
    def last_switch_s(self) -> float:
        """Time of the last power switch (``-inf`` if never switched)."""
        return self._t_switch

    def _target_c(self) -> float:
        return self.ambient_c + (self.self_heating_delta_c if self._powered else 0.0)

    def temperature_c(self, t) -> np.ndarray:
        """Node temperature in °C at times ``t`` (scalar or array, each ≥ last switch)."""
        arr = _as_times(t)
        if arr.size and np.min(arr) < self._t_switch:
            raise ValueError(
                f"time {np.min(arr)!r} s precedes the last power switch at {self._t_switch!r} s"
            )
        target = self._target_c()
        if math.isinf(self._t_switch):
            return np.full(arr.shape, target)
        decay = np.exp(-(arr - self._t_switch) / self.tau_s)
        return target + (self._temp_at_switch_c - target) * decay

    def set_power(self, t: float, on: bool) -> None:
        """Switch the self-heating on or off at time ``t`` (≥ the last switch)."""
        t = float(t)
        if not math.isfinite(t) or t < self._t_switch:
            raise ValueError(f"t={t!r} s must be finite and ≥ the last switch at {self._t_switch!r} s")
        if bool(on) == self._powered:
            return  # no change: keep the running exponential untouched
        self._temp_at_switch_c = float(self.temperature_c(t))  # continuity at the switch
        self._t_switch = t
        self._powered = bool(on)
