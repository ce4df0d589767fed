"""Angular vibration table controller (language: docs/ARCHITECTURE.md, "Angular vibration
table language").

Tones are (rate amplitude °/s, frequency Hz, phase °): the table's rate is
``Σ A sin(2π f (t − t_on) + φ)``.  :meth:`AngularVibrationTable.set_tones` writes the
oscillator table and picks SINE (one tone) or MULTI; :meth:`configure_sweep` a continuous
LIN/LOG sweep; :meth:`start` runs the staged demand (while running: the old demand ramps
down, then the new one up).  The reference capture returns the table's encoder angle and
reference rate on the table's own clock as binary blocks.

Validation before the wire against :class:`AngularLimits`: ranges of every value, and for
a tone set the combined check the controller makes — the sums over tones of the angle
amplitude A/(2πf), of the rate amplitude A and of the acceleration amplitude A·2πf must
not exceed the table's peak angle, rate and acceleration.  Errors the controller reports
raise :class:`~instruments.base.InstrumentError`.

The driver never sleeps: :meth:`AngularVibrationTable.wait_running` takes the caller's
``wait(seconds)`` (the bench clock).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .base import SCPIInstrument, control, in_range, int_in_range, measurement, parse_bool, parse_int
from .ramped import RampedController

STATES = ("IDLE", "RAMP", "RUN", "ABORT")
SPACINGS = ("LIN", "LOG")
_DEG = 180.0 / math.pi
#: samples per :REF:DATA:REM? transfer when reading everything (24 bytes each: 12 MB)
READ_CHUNK_POINTS = 500_000


@dataclass(frozen=True)
class AngularLimits:
    """What the driver lets through (the controller enforces its own too): peak angle ±
    ``angle_deg`` (°), peak rate ``rate_dps`` (°/s), peak angular acceleration
    ``accel_dps2`` (°/s²), the band, the number of tones and the ranges of the settings."""

    angle_deg: float = 0.5 * _DEG
    rate_dps: float = 40.0 * _DEG
    accel_dps2: float = 1400.0 * _DEG
    f_min_hz: float = 0.1
    f_max_hz: float = 1000.0
    max_tones: int = 16
    ramp_s: tuple[float, float] = (0.01, 60.0)
    sweep_time_s: tuple[float, float] = (0.1, 1000.0)
    reference_rate_hz: tuple[float, float] = (1.0, 50_000.0)
    reference_count: tuple[int, int] = (1, 1_000_000_000)
    reference_memory: int = 4_000_000


@dataclass(frozen=True)
class ToneSpec:
    amplitude_dps: float
    freq_hz: float
    phase_deg: float = 0.0


@dataclass(frozen=True)
class SweepSpec:
    start_hz: float
    stop_hz: float
    duration_s: float
    amplitude_dps: float
    spacing: str = "LOG"


class AngularTableAbortedError(RuntimeError):
    """The controller went to ABORT (interlock, emergency stop) while the driver waited."""


def _exact(x: float) -> str:
    return repr(float(x))


def check_tones(tones: Sequence[Sequence[float]], limits: AngularLimits) -> tuple[ToneSpec, ...]:
    """Tones as :class:`ToneSpec` after the range and combined-limit checks (ValueError
    naming the value and the allowed range)."""
    lim = limits
    tones_ = [ToneSpec(*t) if not isinstance(t, ToneSpec) else t for t in tones]
    if not 1 <= len(tones_) <= lim.max_tones:
        raise ValueError(f"{len(tones_)} tones is outside the allowed range [1, {lim.max_tones}]")
    out = []
    for i, t in enumerate(tones_):
        out.append(ToneSpec(in_range(f"tones[{i}].amplitude_dps", t.amplitude_dps, (0.0, lim.rate_dps)),
                            in_range(f"tones[{i}].freq_hz", t.freq_hz, (lim.f_min_hz, lim.f_max_hz)),
                            in_range(f"tones[{i}].phase_deg", t.phase_deg, (-360.0, 360.0))))
    sums = (("angle amplitude sum", sum(t.amplitude_dps / (2 * math.pi * t.freq_hz) for t in out),
             lim.angle_deg, "deg"),
            ("rate amplitude sum", sum(t.amplitude_dps for t in out), lim.rate_dps, "dps"),
            ("acceleration amplitude sum", sum(t.amplitude_dps * 2 * math.pi * t.freq_hz for t in out),
             lim.accel_dps2, "deg/s^2"))
    for name, value, limit, unit in sums:
        if value > limit * (1 + 1e-12):
            raise ValueError(f"{name}={value:.6g} {unit} is outside the allowed range [0, {limit:.6g}] {unit}")
    return tuple(out)


class AngularVibrationTable(RampedController):
    """An angular vibration table and its controller.  The constructor does no I/O;
    ``allowed`` holds the figures the driver validates against (see :meth:`limits`)."""

    aborted_error = AngularTableAbortedError

    idempotent_queries = SCPIInstrument.idempotent_queries | frozenset({
        ":STAT?", ":REF:POIN?", ":REF:OVER?", ":REF:RUNN?", ":LIM:ANGL?", ":LIM:RATE?", ":LIM:ACC?",
        ":LIM:FREQ?", ":LIM:TON?"})

    def __init__(self, resource: Any, name: str | None = None, allowed: AngularLimits | None = None) -> None:
        super().__init__(resource, name)
        self.allowed = allowed or AngularLimits()

    ramp_time_s = control(
        ":RAMP?", ":RAMP {value}",
        "Ramp time in s (each tone ramps over it rounded up to whole periods of the tone).",
        validator=in_range, values=lambda s: s.allowed.ramp_s,
    )
    state = measurement(":STAT?", "IDLE, RAMP, RUN or ABORT.", parse=lambda r: r.strip().upper())
    mode = measurement(":SYNT:MODE?", "SINE, MULTI or SWEEP: what :STARt runs.", parse=lambda r: r.strip().upper())
    interlock_closed = measurement(":INT?", "True while the interlock is closed and not tripped.",
                                   parse=parse_bool)
    reference_points = measurement(":REF:POIN?", "Reference samples captured and not yet read.", parse=parse_int)
    reference_overflow = measurement(":REF:OVER?", "True when the capture memory overflowed (oldest lost).",
                                     parse=parse_bool)
    reference_running = measurement(":REF:RUNN?", "True while the capture still takes samples.", parse=parse_bool)

    snapshot_settings = ("mode", "ramp_time_s", "state")

    # ---- demands -----------------------------------------------------------------------
    def set_tones(self, tones: Sequence[Sequence[float]]) -> tuple[ToneSpec, ...]:
        """Stage ``tones`` [(amplitude_dps, freq_hz, phase_deg), ...]: the oscillator table is
        cleared and written, the mode set to SINE (one tone) or MULTI.  Runs on :meth:`start`."""
        specs = check_tones(tones, self.allowed)
        with self.configuring():
            self.configure_command(":OSC:CLE")
            for i, t in enumerate(specs, start=1):
                self.configure_command(f":OSC{i}:MAGN {_exact(t.amplitude_dps)};FREQ {_exact(t.freq_hz)};"
                                       f"PHAS {_exact(t.phase_deg)};STAT ON")
            self.configure_command(f":SYNT:MODE {'SINE' if len(specs) == 1 else 'MULTI'}")
        return specs

    def tones(self) -> tuple[ToneSpec, ...]:
        """The enabled oscillators as the controller holds them."""
        n = self.allowed.max_tones
        on = self.query(";".join(f":OSC{i}:STAT?" for i in range(1, n + 1))).split(";")
        out = []
        for i, flag in enumerate(on, start=1):
            if parse_bool(flag):
                a, f, p = self.query(f":OSC{i}:MAGN?;:OSC{i}:FREQ?;:OSC{i}:PHAS?").split(";")
                out.append(ToneSpec(float(a), float(f), float(p)))
        return tuple(out)

    def configure_sweep(self, start_hz: float, stop_hz: float, duration_s: float, amplitude_dps: float,
                        spacing: str = "LOG") -> SweepSpec:
        """Stage a continuous sweep ``start_hz`` → ``stop_hz`` over ``duration_s`` at
        ``amplitude_dps``, ``spacing`` LIN or LOG; the table must hold the amplitude at
        every frequency passed."""
        lim = self.allowed
        f = (lim.f_min_hz, lim.f_max_hz)
        f0, f1 = in_range("start_hz", start_hz, f), in_range("stop_hz", stop_hz, f)
        if f0 == f1:
            raise ValueError(f"stop_hz={stop_hz!r} equals start_hz: a sweep needs two frequencies (use set_tones)")
        t = in_range("duration_s", duration_s, lim.sweep_time_s)
        a = in_range("amplitude_dps", amplitude_dps, (0.0, lim.rate_dps))
        sp = str(spacing).upper()
        if sp not in SPACINGS:
            raise ValueError(f"spacing={spacing!r} is outside the allowed values {SPACINGS}")
        for x in (f0, f1):
            check_tones([(a, x, 0.0)], lim)
        with self.configuring():
            self.configure_command(f":SWE:STAR {_exact(f0)};STOP {_exact(f1)};TIME {_exact(t)};"
                                   f"MAGN {_exact(a)};SPAC {sp}")
            self.configure_command(":SYNT:MODE SWE")
        return SweepSpec(f0, f1, t, a, sp)

    def limits(self) -> AngularLimits:
        """The table's limits read from the controller (degrees); other fields as ``allowed``."""
        f_min, f_max = (float(x) for x in self.query(":LIM:FREQ?").split(","))
        return AngularLimits(angle_deg=float(self.query(":LIM:ANGL?")),
                             rate_dps=float(self.query(":LIM:RATE?")),
                             accel_dps2=float(self.query(":LIM:ACC?")),
                             f_min_hz=f_min, f_max_hz=f_max, max_tones=int(self.query(":LIM:TON?")),
                             ramp_s=self.allowed.ramp_s, sweep_time_s=self.allowed.sweep_time_s,
                             reference_rate_hz=self.allowed.reference_rate_hz,
                             reference_count=self.allowed.reference_count,
                             reference_memory=self.allowed.reference_memory)

    # ---- interlock ---------------------------------------------------------------------
    # ---- reference capture -------------------------------------------------------------
    def configure_reference(self, rate_hz: float, count: int) -> None:
        """``count`` samples at ``rate_hz`` on the next :meth:`start_reference`."""
        lim = self.allowed
        r = in_range("rate_hz", rate_hz, lim.reference_rate_hz)
        n = int_in_range("count", count, lim.reference_count)
        self.configure_command(f":REF:RATE {_exact(r)};COUN {n}")

    def start_reference(self) -> None:
        """``:REF:INIT``: capture from the controller's present time (memory cleared)."""
        self.configure_command(":REF:INIT")

    def abort_reference(self) -> None:
        self.configure_command(":REF:ABOR")

    def read_reference(self, max_points: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Up to ``max_points`` oldest captured samples (all captured so far when None),
        removed from the controller: (t_s since the capture start, encoder angle_deg,
        reference rate_dps)."""
        if max_points is not None:
            n = int_in_range("max_points", max_points, (1, self.allowed.reference_memory))
            rows = self._remove(n)
        else:
            parts = []
            while True:
                part = self._remove(READ_CHUNK_POINTS)
                parts.append(part)
                if part.shape[0] < READ_CHUNK_POINTS:
                    break
            rows = np.concatenate(parts)
        return rows[:, 0].copy(), rows[:, 1].copy(), rows[:, 2].copy()

    def _remove(self, n: int) -> np.ndarray:
        values = self.query_real64(f":REF:DATA:REM? {n}")
        if values.size % 3:
            raise ValueError(f"{self.name}: reference block of {values.size} values is not whole triples")
        return values.reshape(-1, 3)



__all__ = ["AngularLimits", "AngularTableAbortedError", "AngularVibrationTable", "STATES", "SweepSpec",
           "ToneSpec", "check_tones"]
