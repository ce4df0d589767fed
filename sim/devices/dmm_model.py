"""Measurement physics of a Keysight 34465A-class digital multimeter (DC volts).

What the model reproduces, and why it matters on an inertial bench:

* **Integration (aperture) averaging.**  A reading is the mean of the input over the
  aperture ``T = NPLC / f_line``.  Line-frequency pickup ``A·sin(2π f t + φ)`` averages to
  ``A·sinc(f T)·sin(...)`` — zero for integer NPLC (normal-mode rejection, finite because
  the mains frequency is never exactly nominal) and not for fractional NPLC.
* **Reading noise** from the data sheet's performance-vs-integration-time table
  (rms noise in ppm of range, 10 V range; approximate to within a factor of ~1.5).
* **Autozero.**  ON: the zero offset is measured every reading (offset removed, reading
  time doubles).  OFF: a fixed zero offset remains.  ONCE: offset measured once, kept.
* **Overload** reads ±9.9E37 when |input| exceeds 120 % of the range.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: rms noise in ppm of range versus NPLC (34465A data sheet, DCV 10 V range, approximate)
NOISE_PPM_OF_RANGE = {
    0.001: 30.0, 0.002: 15.0, 0.006: 6.0, 0.02: 3.0, 0.06: 1.5,
    0.2: 0.7, 1.0: 0.3, 10.0: 0.1, 100.0: 0.03,
}
#: NPLC values needing the DIG option
DIG_NPLC = (0.001, 0.002, 0.006)
RANGES_V = (0.1, 1.0, 10.0, 100.0, 1000.0)
#: extra noise factor on the 100 mV range (fixed µV floor dominates)
LOW_RANGE_NOISE_FACTOR = {0.1: 4.0}
#: per-reading overhead (s) beyond the aperture: ADC setup and data handling
READING_OVERHEAD_S = 2e-5
OVERLOAD = 9.9e37


def allowed_nplc(has_dig: bool) -> tuple[float, ...]:
    return tuple(n for n in sorted(NOISE_PPM_OF_RANGE) if has_dig or n not in DIG_NPLC)


def round_up_nplc(value: float, has_dig: bool) -> float:
    """The instrument rounds a requested NPLC up to the next supported value."""
    for n in allowed_nplc(has_dig):
        if value <= n * (1 + 1e-9):
            return n
    return 100.0


def range_for(volts: float) -> float:
    """Smallest range that holds ``volts`` (as ``VOLT:RANG`` selects it)."""
    for r in RANGES_V:
        if abs(volts) <= r * (1 + 1e-9):
            return r
    raise ValueError(f"range {volts} V not in 0..1000 V")


@dataclass
class LinePickup:
    """Mains interference at the DMM input."""

    amplitude_v: float = 3e-6
    nominal_hz: float = 50.0
    #: real mains sits slightly off nominal: finite rejection at integer NPLC
    offset_fraction: float = 2e-4
    phase_rad: float = 0.3

    def averaged(self, t_start: np.ndarray, aperture_s: float) -> np.ndarray:
        """Mean of the pickup over [t, t+T] for each start time t."""
        f = self.nominal_hz * (1 + self.offset_fraction)
        w = 2 * np.pi * f
        if aperture_s <= 0:
            return self.amplitude_v * np.sin(w * t_start + self.phase_rad)
        # ∫ sin(w t + φ) dt / T = [cos(w t0 + φ) − cos(w (t0+T) + φ)] / (w T)
        #                       = sinc-like gain × sin at mid-aperture (one sin per reading)
        half = w * aperture_s / 2
        gain = self.amplitude_v * np.sin(half) / half
        return gain * np.sin(w * (t_start + aperture_s / 2) + self.phase_rad)


@dataclass
class DmmFrontEnd:
    """Settings that shape every reading (changed by SCPI commands)."""

    range_v: float = 10.0
    autorange: bool = True
    nplc: float = 10.0
    autozero: str = "ON"  # ON | OFF | ONCE
    line_hz: float = 50.0
    #: integration set in seconds by VOLT:APER (None: integration is NPLC / f_line)
    aperture_override_s: float | None = None

    @property
    def aperture_s(self) -> float:
        if self.aperture_override_s is not None:
            return self.aperture_override_s
        return self.nplc / self.line_hz

    @property
    def reading_time_s(self) -> float:
        """Time one reading occupies: aperture (×2 with autozero on) plus overhead."""
        factor = 2.0 if self.autozero == "ON" else 1.0
        return factor * self.aperture_s + READING_OVERHEAD_S


def noise_ppm(fe: DmmFrontEnd) -> float:
    """rms noise (ppm of range) for the integration in use; an aperture set in seconds
    is interpolated log-log between the table's NPLC points."""
    if fe.aperture_override_s is None:
        return NOISE_PPM_OF_RANGE[fe.nplc]
    nplc_equiv = fe.aperture_override_s * fe.line_hz
    xs = np.log(sorted(NOISE_PPM_OF_RANGE))
    ys = np.log([NOISE_PPM_OF_RANGE[k] for k in sorted(NOISE_PPM_OF_RANGE)])
    return float(np.exp(np.interp(np.log(nplc_equiv), xs, ys)))


class DmmConverter:
    """Turns the averaged input voltage into readings: noise, zero offset, overload."""

    def __init__(self, rng: np.random.Generator, zero_offset_sigma_v: float = 1.5e-6,
                 noise_scale: float = 1.0) -> None:
        # noise_scale 0: an ideal converter (a station for checking procedures' arithmetic
        # end to end); the draws still happen, so the other streams never shift
        self.rng = rng
        self.noise_scale = float(noise_scale)
        self.zero_offset_v = float(rng.normal(0.0, zero_offset_sigma_v)) * self.noise_scale
        self._once_offset: float | None = None

    def convert(self, mean_input_v: np.ndarray, fe: DmmFrontEnd) -> np.ndarray:
        n = mean_input_v.shape[0]
        if fe.autorange:
            # per reading (no hysteresis), so the bytes never depend on how the
            # acquisition was split into batches
            ranges = np.asarray(RANGES_V)
            idx = np.minimum(np.searchsorted(ranges, np.abs(mean_input_v) * (1 - 1e-12)),
                             len(ranges) - 1)
            rng_v: np.ndarray | float = ranges[idx]
            factor: np.ndarray | float = np.where(rng_v == 0.1, LOW_RANGE_NOISE_FACTOR[0.1], 1.0)
        else:
            rng_v = fe.range_v
            factor = LOW_RANGE_NOISE_FACTOR.get(fe.range_v, 1.0)
        sigma = noise_ppm(fe) * 1e-6 * rng_v * factor * self.noise_scale
        readings = mean_input_v + self.rng.normal(0.0, 1.0, n) * sigma
        if fe.autozero == "OFF":
            readings += self.zero_offset_v
        elif fe.autozero == "ONCE":
            if self._once_offset is None:
                self._once_offset = float(self.rng.normal(0.0, 1.0)) * float(np.max(sigma))
            readings += self._once_offset
        over = np.abs(mean_input_v) > 1.2 * rng_v
        readings[over] = np.copysign(OVERLOAD, mean_input_v[over])
        return readings

    def autozero_once(self) -> None:
        self._once_offset = None


class ForcedInput:
    """Intervals in which a meter's input is forced to a voltage (the overload fault): a window
    opens at ``force`` and closes at ``release``; :meth:`apply` puts the forced volts over the
    readings whose aperture starts inside a window.  Shared by the DMM and the scanning DAQ."""

    def __init__(self) -> None:
        #: (t_from_s, t_to_s, volts); the last window is open while t_to_s is inf
        self.windows: list[tuple[float, float, float]] = []

    @property
    def active(self) -> bool:
        return bool(self.windows) and self.windows[-1][1] == math.inf

    def force(self, now_s: float, volts: float) -> None:
        self.release(now_s)
        self.windows.append((now_s, math.inf, float(volts)))

    def release(self, now_s: float) -> None:
        if self.active:
            t0, _, volts = self.windows[-1]
            self.windows[-1] = (t0, now_s, volts)

    def apply(self, t_start: np.ndarray, volts: np.ndarray) -> np.ndarray:
        for t0, t1, forced in self.windows:
            volts = np.where((t_start >= t0) & (t_start < t1), forced, volts)
        return volts
