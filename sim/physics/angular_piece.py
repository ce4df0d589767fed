"""One piece of an angular vibration table's motion: a sum of sinusoids with linear envelopes.

The table's motion (``sim.physics.angular_table``) is a time-ordered list of pieces.  Within
a piece ``[t_start_s, t_end_s)`` the table's angular rate (rad/s) is

    ω(t) = Σₖ (αₖ + βₖ·τ)·sin(2π fₖ τ + φₖ),    τ = t − t_start_s,

and its angle is ``angle0_rad + ∫ω``.  Ramps (linear envelopes), dwells (β = 0), multi-tone
demands, harmonic distortion (extra components at 2f, 3f, …) and a continuous sweep
(phase-continuous pieces of constant frequency, one per controller update) are all of this
form, so a linear sensor's response to the motion is exact in closed form
(``sim.physics.rate_sensors``).  A piece with no components is the table at rest.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class MotionPiece:
    """Rate ``Σ (α + β τ) sin(2π f τ + φ)`` over ``[t_start_s, t_end_s)`` (``t_end_s`` may be ∞)."""

    t_start_s: float
    t_end_s: float
    freq_hz: np.ndarray       # (n,) component frequencies, > 0
    alpha_rad_s: np.ndarray   # (n,) rate amplitude at t_start_s
    beta_rad_s2: np.ndarray   # (n,) slope of the amplitude envelope (rad/s per s)
    phase_rad: np.ndarray     # (n,) phase at t_start_s
    angle0_rad: float = 0.0   # table angle at t_start_s

    def __post_init__(self):
        arrays = [np.atleast_1d(np.asarray(getattr(self, n), dtype=float))
                  for n in ("freq_hz", "alpha_rad_s", "beta_rad_s2", "phase_rad")]
        if len({a.shape for a in arrays}) != 1 or arrays[0].ndim != 1:
            raise ValueError("freq_hz, alpha_rad_s, beta_rad_s2 and phase_rad must be 1-D of one length")
        if not all(np.all(np.isfinite(a)) for a in arrays) or np.any(arrays[0] <= 0):
            raise ValueError("piece components must be finite with frequencies > 0 Hz")
        if not (math.isfinite(self.t_start_s) and self.t_end_s > self.t_start_s):
            raise ValueError(f"piece [{self.t_start_s}, {self.t_end_s}) must have finite start < end")
        for name, a in zip(("freq_hz", "alpha_rad_s", "beta_rad_s2", "phase_rad"), arrays):
            object.__setattr__(self, name, a)

    @property
    def n(self) -> int:
        return int(self.freq_hz.size)

    def rate_rad_s(self, t_s) -> np.ndarray:
        tau = np.asarray(t_s, dtype=float)[..., None] - self.t_start_s
        w = 2 * np.pi * self.freq_hz
        return np.sum((self.alpha_rad_s + self.beta_rad_s2 * tau) * np.sin(w * tau + self.phase_rad), axis=-1)

    def accel_rad_s2(self, t_s) -> np.ndarray:
        tau = np.asarray(t_s, dtype=float)[..., None] - self.t_start_s
        w = 2 * np.pi * self.freq_hz
        arg = w * tau + self.phase_rad
        return np.sum(self.beta_rad_s2 * np.sin(arg) + (self.alpha_rad_s + self.beta_rad_s2 * tau) * w * np.cos(arg),
                      axis=-1)

    def angle_rad(self, t_s) -> np.ndarray:
        """``angle0 + ∫_{t_start}^{t} ω``: ∫(α+βτ)sin(wτ+φ) = −(α+βτ)cos/w + β sin/w² (+ const)."""
        tau = np.asarray(t_s, dtype=float)[..., None] - self.t_start_s
        w = 2 * np.pi * self.freq_hz

        def antiderivative(tt):
            arg = w * tt + self.phase_rad
            return (-(self.alpha_rad_s + self.beta_rad_s2 * tt) * np.cos(arg) / w
                    + self.beta_rad_s2 * np.sin(arg) / w ** 2)

        return self.angle0_rad + np.sum(antiderivative(tau) - antiderivative(np.zeros(1)), axis=-1)

    def end_state(self) -> tuple[np.ndarray, np.ndarray, float]:
        """Amplitudes, phases and angle at ``t_end_s`` (finite end): what a phase-continuous
        next piece starts from."""
        d = self.t_end_s - self.t_start_s
        amp = self.alpha_rad_s + self.beta_rad_s2 * d
        phase = np.mod(2 * np.pi * self.freq_hz * d + self.phase_rad, 2 * np.pi)
        return amp, phase, float(self.angle_rad(np.array([self.t_end_s]))[0])


def at_rest(t_start_s: float, t_end_s: float = math.inf, angle_rad: float = 0.0) -> MotionPiece:
    """A piece with no motion (no components)."""
    e = np.zeros(0)
    return MotionPiece(t_start_s, t_end_s, e, e, e, e, angle_rad)
