"""Vibration test profiles of an electrodynamic shaker and the shaker's limits.

Random profile: a one-sided acceleration spectral density (ASD, g²/Hz) given at
breakpoints and interpolated **log-log** between them (straight lines on a log-log plot,
i.e. constant dB/octave), zero outside the first and last breakpoint — the way random
vibration specifications (MIL-STD-810 514, NAVMAT P-9492) are written.  Between two
breakpoints the ASD is a power law P(f) = P₁ (f/f₁)^b, b = ln(P₂/P₁)/ln(f₂/f₁), so every
moment integrates exactly:

    ∫ P(f) (2πf)^(-2k) df  over [f₁, f₂]   (k = 0: g², 1: velocity², 2: displacement²)

g rms = √(moment 0); velocity rms = g₀·√(moment 1) m/s; displacement rms = g₀·√(moment 2)
m.  Sine dwell: a frequency and a peak acceleration; g rms = peak/√2.

Levels: a profile is the 0 dB reference; a level of L dB multiplies accelerations by
10^(L/20) (the ASD by 10^(L/10)), as on a vibration controller.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim.physics.gravity import STANDARD_GRAVITY_MPS2

#: largest number of breakpoints a random profile may have
MAX_BREAKPOINTS = 32


def _number(name: str, value: object, lo: float, hi: float, *, open_lo: bool = False) -> float:
    if isinstance(value, (int, float, np.floating, np.integer)) and not isinstance(value, bool):
        x = float(value)
    else:
        x = math.nan
    if not (math.isfinite(x) and (x > lo if open_lo else x >= lo) and x <= hi):
        raise ValueError(f"{name} = {value!r} not in {'(' if open_lo else '['}{lo:g}, {hi:g}]")
    return x


@dataclass(frozen=True)
class RandomProfile:
    """Breakpoints of a random-vibration ASD: frequencies (Hz, increasing) and g²/Hz (> 0)."""

    freqs_hz: tuple[float, ...]
    psd_g2hz: tuple[float, ...]

    def __post_init__(self) -> None:
        f, p = tuple(self.freqs_hz), tuple(self.psd_g2hz)
        if not 2 <= len(f) <= MAX_BREAKPOINTS or len(f) != len(p):
            raise ValueError(f"a random profile needs 2..{MAX_BREAKPOINTS} breakpoints with one ASD "
                             f"each, got {len(f)} frequencies and {len(p)} ASD values")
        f = tuple(_number(f"freqs_hz[{i}]", x, 0.0, 1e6, open_lo=True) for i, x in enumerate(f))
        p = tuple(_number(f"psd_g2hz[{i}]", x, 0.0, 1e6, open_lo=True) for i, x in enumerate(p))
        for i in range(1, len(f)):
            if not f[i] > f[i - 1]:
                raise ValueError(f"freqs_hz[{i}] = {f[i]!r} must be above freqs_hz[{i - 1}] = {f[i - 1]!r}")
        object.__setattr__(self, "freqs_hz", f)
        object.__setattr__(self, "psd_g2hz", p)

    @classmethod
    def flat(cls, psd_g2hz: float, f_lo_hz: float, f_hi_hz: float) -> RandomProfile:
        """A flat ASD between two frequencies."""
        return cls((f_lo_hz, f_hi_hz), (psd_g2hz, psd_g2hz))

    @classmethod
    def flat_grms(cls, grms: float, f_lo_hz: float, f_hi_hz: float) -> RandomProfile:
        """The flat ASD whose g rms is ``grms`` (g²/Hz = grms² / bandwidth)."""
        g = _number("grms", grms, 0.0, 1e4, open_lo=True)
        lo = _number("f_lo_hz", f_lo_hz, 0.0, 1e6, open_lo=True)
        hi = _number("f_hi_hz", f_hi_hz, lo, 1e6, open_lo=True)
        return cls.flat(g * g / (hi - lo), lo, hi)

    @property
    def f_lo_hz(self) -> float:
        return self.freqs_hz[0]

    @property
    def f_hi_hz(self) -> float:
        return self.freqs_hz[-1]

    @property
    def slopes(self) -> np.ndarray:
        """Power-law exponent b of each segment (dB/octave = 10·log10(2)·b)."""
        f, p = np.array(self.freqs_hz), np.array(self.psd_g2hz)
        return np.log(p[1:] / p[:-1]) / np.log(f[1:] / f[:-1])

    def psd(self, f_hz) -> np.ndarray:
        """ASD in g²/Hz at ``f_hz`` (log-log interpolation; 0 outside the profile)."""
        f = np.asarray(f_hz, dtype=float)
        inside = (f >= self.f_lo_hz) & (f <= self.f_hi_hz)
        out = np.zeros(f.shape)
        logp = np.interp(np.log(f[inside]), np.log(self.freqs_hz), np.log(self.psd_g2hz))
        out[inside] = np.exp(logp)
        return out

    def moment(self, k: int) -> float:
        """∫ P(f)·(2πf)^(−2k) df over the profile, exactly (segment by segment)."""
        total = 0.0
        for (f1, f2), (p1, _), b in zip(zip(self.freqs_hz, self.freqs_hz[1:]),
                                        zip(self.psd_g2hz, self.psd_g2hz[1:]), self.slopes):
            e = b - 2 * k  # exponent of the integrand's power law
            c = p1 * (2 * math.pi * f1) ** (-2 * k)  # integrand at f1
            r = f2 / f1
            # ∫ c (f/f1)^e df = c f1 (r^(e+1) − 1)/(e+1), or c f1 ln r when e = −1
            total += c * f1 * (math.log(r) if abs(e + 1) < 1e-12 else math.expm1((e + 1) * math.log(r)) / (e + 1))
        return total

    @property
    def grms(self) -> float:
        """Overall acceleration, g rms."""
        return math.sqrt(self.moment(0))

    @property
    def velocity_rms_mps(self) -> float:
        return STANDARD_GRAVITY_MPS2 * math.sqrt(self.moment(1))

    @property
    def displacement_rms_m(self) -> float:
        return STANDARD_GRAVITY_MPS2 * math.sqrt(self.moment(2))

    def scaled_db(self, level_db: float) -> RandomProfile:
        """The profile at ``level_db`` (ASD × 10^(level/10))."""
        factor = 10.0 ** (level_db / 10.0)
        return RandomProfile(self.freqs_hz, tuple(p * factor for p in self.psd_g2hz))


@dataclass(frozen=True)
class SineProfile:
    """Sine dwell: frequency (Hz) and peak acceleration (g)."""

    freq_hz: float
    peak_g: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "freq_hz", _number("freq_hz", self.freq_hz, 0.0, 1e6, open_lo=True))
        object.__setattr__(self, "peak_g", _number("peak_g", self.peak_g, 0.0, 1e4, open_lo=True))

    @property
    def f_lo_hz(self) -> float:
        return self.freq_hz

    @property
    def f_hi_hz(self) -> float:
        return self.freq_hz

    @property
    def grms(self) -> float:
        return self.peak_g / math.sqrt(2.0)

    @property
    def velocity_rms_mps(self) -> float:
        return self.grms * STANDARD_GRAVITY_MPS2 / (2 * math.pi * self.freq_hz)

    @property
    def displacement_rms_m(self) -> float:
        return self.grms * STANDARD_GRAVITY_MPS2 / (2 * math.pi * self.freq_hz) ** 2

    def scaled_db(self, level_db: float) -> SineProfile:
        return SineProfile(self.freq_hz, self.peak_g * 10.0 ** (level_db / 20.0))


Profile = RandomProfile | SineProfile


@dataclass(frozen=True)
class ShakerLimits:
    """What the shaker (armature + fixture + unit) may be driven to.

    Assumed figures of a mid-size air-cooled electrodynamic shaker (the class of LDS V8 /
    TIRA TV 5220): 5–3000 Hz, 50.8 mm stroke (±25.4 mm), 1.8 m/s peak velocity (under
    its 2.0 m/s rating), and with a ~20 kg fixture and unit 30 g rms random / 50 g peak
    sine.  Random peaks are taken as ``sigma_clip`` × rms (controllers clip the drive at
    3σ).
    """

    f_min_hz: float = 5.0
    f_max_hz: float = 3000.0
    max_grms: float = 30.0
    max_sine_peak_g: float = 50.0
    max_velocity_mps: float = 1.8
    max_displacement_m: float = 0.0254
    sigma_clip: float = 3.0
    max_psd_g2hz: float = 10.0

    def violation(self, profile: Profile, level_db: float = 0.0) -> str | None:
        """None if ``profile`` at ``level_db`` is within the limits, else what is not
        (the value and the allowed range)."""
        if not (self.f_min_hz <= profile.f_lo_hz and profile.f_hi_hz <= self.f_max_hz):
            bad = profile.f_lo_hz if profile.f_lo_hz < self.f_min_hz else profile.f_hi_hz
            return f"frequency {bad:g} Hz not in {self.f_min_hz:g}..{self.f_max_hz:g} Hz"
        p = profile.scaled_db(level_db)
        if isinstance(p, RandomProfile):
            peak_psd = max(p.psd_g2hz)
            if peak_psd > self.max_psd_g2hz:
                return f"ASD {peak_psd:.6g} g2/Hz not in 0..{self.max_psd_g2hz:g} g2/Hz"
            if p.grms > self.max_grms:
                return f"level {p.grms:.6g} g rms not in 0..{self.max_grms:g} g rms"
            crest = self.sigma_clip
            what = f"{crest:g} sigma "
        else:
            if p.peak_g > self.max_sine_peak_g:
                return f"sine {p.peak_g:.6g} g peak not in 0..{self.max_sine_peak_g:g} g peak"
            crest, what = math.sqrt(2.0), ""
        velocity = crest * p.velocity_rms_mps
        if velocity > self.max_velocity_mps:
            return (f"velocity {what}peak {velocity:.6g} m/s not in 0..{self.max_velocity_mps:g} m/s "
                    f"(from content at {p.f_lo_hz:g} Hz)")
        displacement = crest * p.displacement_rms_m
        if displacement > self.max_displacement_m:
            return (f"displacement {what}peak {displacement * 1e3:.6g} mm not in "
                    f"0..{self.max_displacement_m * 1e3:g} mm (from content at {p.f_lo_hz:g} Hz)")
        return None
