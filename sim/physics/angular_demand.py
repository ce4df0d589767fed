"""What an angular vibration table may be asked to do: its limits and the demands it runs.

Limits (:class:`AngularTableLimits`) are those of a PTB-class angular acceleration exciter
(the primary angular vibration standards of PTB and of the Chinese NIM, built on air-bearing
rotary exciters; published ranges are of the order of ±0.5 rad angle, some tens of rad/s
rate and ~1.4·10³ rad/s² angular acceleration over 0.1 Hz – 1 kHz).  The figures here
are *assumed* round values of that class, not a data sheet: ±0.5 rad peak angle, 40 rad/s
peak rate, 1400 rad/s² peak angular acceleration, 0.1–1000 Hz, up to 16 simultaneous tones.

A demand is a set of tones (rate amplitude, frequency, phase) or a sweep.  It is refused
when the *sum over tones* of the angle amplitude A/(2πf), of the rate amplitude A or of the
acceleration amplitude A·2πf exceeds its limit: those sums bound the peaks of the demanded
motion whatever the phases.  Everything is in SI (rad, rad/s, rad/s², Hz) here; the
controller language converts to degrees.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

TWO_PI = 2.0 * math.pi
SWEEP_SPACINGS = ("LIN", "LOG")
#: sweep duration range (s): 1000 s at 10 ms updates is 10⁵ pieces, the most we keep
SWEEP_TIME_RANGE_S = (0.1, 1000.0)


@dataclass(frozen=True)
class Tone:
    """One demanded oscillation: rate ``A sin(2π f (t − t_on) + φ)`` with ``t_on`` the start
    of the ramp that brings it in."""

    rate_amplitude_rad_s: float
    freq_hz: float
    phase_rad: float = 0.0

    def __post_init__(self):
        for name in ("rate_amplitude_rad_s", "freq_hz", "phase_rad"):
            v = getattr(self, name)
            if not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"{name} = {v!r} must be a finite number")
        if self.rate_amplitude_rad_s < 0:
            raise ValueError(f"rate_amplitude_rad_s = {self.rate_amplitude_rad_s!r} not in 0..inf rad/s")


@dataclass(frozen=True)
class Sweep:
    """A continuous sweep from ``start_hz`` to ``stop_hz`` over ``duration_s`` at a constant
    rate amplitude; LIN: f(τ) = f₀ + (f₁ − f₀) τ/T, LOG: f(τ) = f₀ (f₁/f₀)^(τ/T)."""

    start_hz: float
    stop_hz: float
    duration_s: float
    rate_amplitude_rad_s: float
    spacing: str = "LOG"

    def __post_init__(self):
        if self.spacing not in SWEEP_SPACINGS:
            raise ValueError(f"spacing = {self.spacing!r} not in {'|'.join(SWEEP_SPACINGS)}")
        lo, hi = SWEEP_TIME_RANGE_S
        if not (isinstance(self.duration_s, (int, float)) and lo <= self.duration_s <= hi):
            raise ValueError(f"sweep time {self.duration_s!r} s not in {lo:g}..{hi:g} s")
        for name in ("start_hz", "stop_hz", "rate_amplitude_rad_s"):
            v = getattr(self, name)
            if not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise ValueError(f"{name} = {v!r} must be a finite number ≥ 0")

    def freq_at(self, tau_s):
        """Instantaneous frequency (Hz) ``tau_s`` after the sweep starts (scalar or array)."""
        x = tau_s / self.duration_s
        if self.spacing == "LIN":
            return self.start_hz + (self.stop_hz - self.start_hz) * x
        return self.start_hz * (self.stop_hz / self.start_hz) ** x


@dataclass(frozen=True)
class AngularTableLimits:
    """Peak angle (rad), rate (rad/s), angular acceleration (rad/s²), band (Hz), tones."""

    max_angle_rad: float = 0.5
    max_rate_rad_s: float = 40.0
    max_accel_rad_s2: float = 1400.0
    f_min_hz: float = 0.1
    f_max_hz: float = 1000.0
    max_tones: int = 16

    def excess(self, amplitudes_rad_s: Sequence[float], freqs_hz: Sequence[float]
               ) -> tuple[str, float, float, str] | None:
        """The first limit the tones break: (quantity, value, limit, unit), SI; else None.

        Quantities: ``tones`` (count), ``frequency``, ``angle amplitude sum``, ``rate
        amplitude sum``, ``acceleration amplitude sum``.
        """
        a = [float(x) for x in amplitudes_rad_s]
        f = [float(x) for x in freqs_hz]
        if len(a) != len(f):
            raise ValueError(f"{len(a)} amplitudes and {len(f)} frequencies: give one of each per tone")
        if not 1 <= len(f) <= self.max_tones:
            return ("tones", float(len(f)), float(self.max_tones), "")
        for x in f:
            if not self.f_min_hz <= x <= self.f_max_hz:
                return ("frequency", x, self.f_max_hz if x > self.f_max_hz else self.f_min_hz, "Hz")
        for x in a:
            if not (math.isfinite(x) and x >= 0):
                return ("rate amplitude", x, self.max_rate_rad_s, "rad/s")
        sums = (("angle amplitude sum", sum(ai / (TWO_PI * fi) for ai, fi in zip(a, f)), self.max_angle_rad, "rad"),
                ("rate amplitude sum", sum(a), self.max_rate_rad_s, "rad/s"),
                ("acceleration amplitude sum", sum(ai * TWO_PI * fi for ai, fi in zip(a, f)),
                 self.max_accel_rad_s2, "rad/s^2"))
        for name, value, limit, unit in sums:
            if value > limit * (1 + 1e-12):  # a demand exactly at a limit is allowed
                return (name, value, limit, unit)
        return None

    def violation(self, tones: Sequence[Tone]) -> str | None:
        """A message naming the value and the allowed range, or None when the tones fit."""
        return describe(self.excess([t.rate_amplitude_rad_s for t in tones], [t.freq_hz for t in tones]), self)

    def sweep_violation(self, sweep: Sweep) -> str | None:
        """A sweep fits when its one tone fits at every frequency it passes: the angle sum is
        largest at the lowest frequency, the acceleration at the highest (both monotonic)."""
        for f in (sweep.start_hz, sweep.stop_hz):
            problem = self.violation([Tone(sweep.rate_amplitude_rad_s, f)])
            if problem:
                return f"sweep: {problem}"
        if sweep.start_hz == sweep.stop_hz:
            return f"sweep: stop {sweep.stop_hz:g} Hz equals start; use a SINE dwell"
        return None


def describe(excess: tuple[str, float, float, str] | None, lim: AngularTableLimits,
             to_unit: dict[str, tuple[str, float]] | None = None) -> str | None:
    """Message for :meth:`AngularTableLimits.excess`; ``to_unit`` maps an SI unit to
    (unit, factor) for the caller's language (the controller speaks degrees)."""
    if excess is None:
        return None
    name, value, limit, unit = excess
    if name == "tones":
        return f"{int(value)} tones not in 1..{lim.max_tones}"
    if name == "frequency":
        return f"frequency {value:g} Hz not in {lim.f_min_hz:g}..{lim.f_max_hz:g} Hz"
    u, k = (to_unit or {}).get(unit, (unit, 1.0))
    return f"{name} {value * k:.6g} {u} not in 0..{limit * k:.6g} {u}"


__all__ = ["AngularTableLimits", "SWEEP_SPACINGS", "SWEEP_TIME_RANGE_S", "Sweep", "Tone", "describe"]
