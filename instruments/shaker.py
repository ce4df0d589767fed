"""Random-vibration controller of an electrodynamic shaker (language: docs/ARCHITECTURE.md).

``:PROF:RAND <f1>,<asd1>,...`` / ``:PROF:RAND:FLAT <asd>,<f_lo>,<f_hi>`` / ``:PROF:SINE
<hz>,<g>``, ``:LEV <dB>``, ``:STAR``, ``:STOP``, ``:STAT?``, ``:READ:GRMS?`` ...  Errors
go to the SCPI error queue and raise :class:`~instruments.base.InstrumentError`.

Validation before the wire: frequencies, ASD values, sine amplitude, level and ramp are
checked against :class:`VibrationLimits`, and a random profile's g rms (the log-log ASD
integrated exactly here, independently of the controller) against the g rms limit.  The
displacement and velocity a low-frequency profile implies are the controller's to refuse
(-222 naming the value and the allowed range).

The driver never sleeps: :meth:`VibrationTable.wait_running` takes the caller's
``wait(seconds)`` (the bench clock).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from .base import control, in_range, measurement, parse_bool
from .ramped import RampedController

STATES = ("IDLE", "RAMP", "RUN", "ABORT")


@dataclass(frozen=True)
class VibrationLimits:
    """What the driver lets through (the controller enforces its own too)."""

    f_min_hz: float = 5.0
    f_max_hz: float = 3000.0
    max_asd_g2hz: float = 10.0
    max_grms: float = 30.0
    max_sine_peak_g: float = 50.0
    level_db: tuple[float, float] = (-30.0, 6.0)
    ramp_s: tuple[float, float] = (0.01, 60.0)
    max_breakpoints: int = 32


@dataclass(frozen=True)
class RandomProfileSpec:
    """A random profile as the controller holds it: breakpoints (Hz, g²/Hz)."""

    freqs_hz: tuple[float, ...]
    asd_g2hz: tuple[float, ...]

    @property
    def grms(self) -> float:
        return random_profile_grms(self.freqs_hz, self.asd_g2hz)


@dataclass(frozen=True)
class SineProfileSpec:
    freq_hz: float
    peak_g: float

    @property
    def grms(self) -> float:
        return self.peak_g / math.sqrt(2.0)


def _exact(x: float) -> str:
    """A profile value in full (shortest round-trip) precision: ``:PROF?`` gives it back as set."""
    return repr(float(x))


class VibrationAbortedError(RuntimeError):
    """The controller went to ABORT (interlock, emergency stop) while the driver waited."""


def random_profile_grms(freqs_hz: Sequence[float], asd_g2hz: Sequence[float]) -> float:
    """g rms of a breakpoint ASD, log-log between breakpoints: √Σ ∫ P₁ (f/f₁)^b df."""
    total = 0.0
    for f1, f2, p1, p2 in zip(freqs_hz, freqs_hz[1:], asd_g2hz, asd_g2hz[1:]):
        b = math.log(p2 / p1) / math.log(f2 / f1)
        # b = -1 (−3 dB/oct) integrates to a logarithm; otherwise a power law
        total += p1 * f1 * math.log(f2 / f1) if abs(b + 1) < 1e-12 else (p2 * f2 - p1 * f1) / (b + 1)
    return math.sqrt(total)


def _parse_profile(reply: str) -> RandomProfileSpec | SineProfileSpec | None:
    fields = [f.strip() for f in reply.split(",")]
    kind = fields[0].upper()
    try:
        values = [float(x) for x in fields[1:]]
    except ValueError:
        raise ValueError(f":PROF? reply {reply!r} is not <kind>,<numbers>") from None
    if kind == "NONE":
        return None
    if kind == "SINE" and len(values) == 2:
        return SineProfileSpec(*values)
    if kind == "RAND" and len(values) >= 4 and len(values) % 2 == 0:
        return RandomProfileSpec(tuple(values[0::2]), tuple(values[1::2]))
    raise ValueError(f":PROF? reply {reply!r} is not NONE, SINE,<hz>,<g> or RAND,<f>,<asd>,...")


class VibrationTable(RampedController):
    """A shaker and its random-vibration controller.  The constructor does no I/O."""

    aborted_error = VibrationAbortedError

    def __init__(self, resource: Any, name: str | None = None,
                 limits: VibrationLimits | None = None) -> None:
        super().__init__(resource, name)
        self.limits = limits or VibrationLimits()

    level_db = control(
        ":LEV?", ":LEV {value}",
        "Level in dB re the profile (accelerations × 10^(dB/20)); ramps while running.",
        validator=in_range, values=lambda s: s.limits.level_db,
    )
    ramp_time_s = control(
        ":RAMP?", ":RAMP {value}",
        "Ramp time in s: start ramps 0 → level, stop ramps level → 0.",
        validator=in_range, values=lambda s: s.limits.ramp_s,
    )
    state = measurement(":STAT?", "IDLE, RAMP, RUN or ABORT.", parse=lambda r: r.strip().upper())
    level_grms = measurement(":READ:GRMS?", "Control level achieved, g rms (last second).")
    target_grms = measurement(":TARG:GRMS?", "g rms the profile gives at the set level.")
    profile_grms = measurement(":PROF:GRMS?", "The profile's g rms at 0 dB.")
    profile = measurement(":PROF?", "The profile: RandomProfileSpec, SineProfileSpec or None.",
                          parse=_parse_profile)
    interlock_closed = measurement(":INT?", "True while the interlock is closed and not tripped.",
                                   parse=parse_bool)
    axis = measurement(":AXIS?", "Motion axis, unit vector (x, y, z) in the platform frame.",
                       parse=lambda r: tuple(float(x) for x in r.split(",")))

    snapshot_settings = ("profile", "level_db", "ramp_time_s", "state", "axis")

    def set_random_profile(self, freqs_hz: Sequence[float] | None = None,
                           asd_g2hz: Sequence[float] | None = None, *, grms: float | None = None,
                           f_lo_hz: float = 20.0, f_hi_hz: float = 2000.0) -> RandomProfileSpec:
        """A breakpoint ASD (``freqs_hz``, ``asd_g2hz``), or a flat one of ``grms`` between
        ``f_lo_hz`` and ``f_hi_hz``.  Validated here before anything is sent."""
        lim = self.limits
        f_range = (lim.f_min_hz, lim.f_max_hz)
        if grms is not None:
            if freqs_hz is not None or asd_g2hz is not None:
                raise ValueError("give breakpoints (freqs_hz, asd_g2hz) or grms, not both")
            g = in_range("grms", grms, (1e-6, lim.max_grms))
            lo, hi = in_range("f_lo_hz", f_lo_hz, f_range), in_range("f_hi_hz", f_hi_hz, f_range)
            if not hi > lo:
                raise ValueError(f"f_hi_hz={f_hi_hz!r} is outside the allowed range ({lo:g}, {lim.f_max_hz:g}]")
            asd = in_range("asd_g2hz", g * g / (hi - lo), (1e-9, lim.max_asd_g2hz))
            self.configure_command(f":PROF:RAND:FLAT {_exact(asd)},{_exact(lo)},{_exact(hi)}")
            return RandomProfileSpec((lo, hi), (asd, asd))
        if freqs_hz is None or asd_g2hz is None:
            raise ValueError("give breakpoints freqs_hz and asd_g2hz, or grms")
        f, p = list(freqs_hz), list(asd_g2hz)
        if not 2 <= len(f) <= lim.max_breakpoints or len(f) != len(p):
            raise ValueError(f"breakpoints: {len(f)} frequencies and {len(p)} ASD values; allowed "
                             f"2..{lim.max_breakpoints} of each, equal counts")
        f = [in_range(f"freqs_hz[{i}]", x, f_range) for i, x in enumerate(f)]
        p = [in_range(f"asd_g2hz[{i}]", x, (1e-9, lim.max_asd_g2hz)) for i, x in enumerate(p)]
        for i in range(1, len(f)):
            if not f[i] > f[i - 1]:
                raise ValueError(f"freqs_hz[{i}]={f[i]!r} is outside the allowed range "
                                 f"({f[i - 1]:g}, {lim.f_max_hz:g}] (frequencies must increase)")
        g = random_profile_grms(f, p)
        if g > lim.max_grms:
            raise ValueError(f"profile g rms={g:.6g} is outside the allowed range [0, {lim.max_grms:g}]")
        self.configure_command(":PROF:RAND " + ",".join(
            f"{_exact(a)},{_exact(b)}" for a, b in zip(f, p)))
        return RandomProfileSpec(tuple(f), tuple(p))

    def set_sine(self, freq_hz: float, peak_g: float) -> SineProfileSpec:
        """Sine dwell at ``freq_hz`` with ``peak_g`` peak acceleration."""
        f = in_range("freq_hz", freq_hz, (self.limits.f_min_hz, self.limits.f_max_hz))
        g = in_range("peak_g", peak_g, (1e-6, self.limits.max_sine_peak_g))
        self.configure_command(f":PROF:SINE {_exact(f)},{_exact(g)}")
        return SineProfileSpec(f, g)
