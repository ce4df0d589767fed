"""Where a residual departs from the model's noise floor: time, frequency, τ and each logged input.

Pure: arrays and a :class:`~bench.discovery.data.Record` in, a frozen :class:`Localization` out.
Units: the residual is in the sensor unit (g or deg/s); ``noise_sd`` is the model's white-noise
standard deviation in that unit; times in s, frequencies in Hz.

Each test is calibrated against white noise of sd ``noise_sd`` (the model's floor) with a
Bonferroni correction across the cells it scans, so on a residual at the floor every list is
empty with probability about ``1 - alpha`` per test:

* time: the record cut into ``n_segments`` contiguous segments; a segment is flagged when its
  mean departs from 0 (z test, σ/√m) or its variance from σ² (χ² test); plus the CUSUM of the
  residual against the Kolmogorov bound (a slow drift shows there first).
* frequency: Welch PSD (Hann, 50 % overlap) against the white floor 2σ²/fs; a bin is flagged
  when PSD/floor exceeds the χ²(ν)/ν quantile (ν from the number of averaged segments);
  contiguous flagged bins are merged: one or two bins → a line, more → a band.
* τ: overlapping Allan deviation (:func:`bench.analysis.allan.overlapping_adev`, Greenhall EDF,
  CI at ``1 - alpha/n_τ``) against the white-noise expectation σ/√(τ·fs).
* inputs: correlation of the residual with x, x², x³ (centred) and, for ``input``, with dx/dt
  (a time delay shows as −τ·SF·dx/dt); the standard error of r uses Bartlett's effective sample
  size n/(1 + 2Σρₓ(k)ρᵣ(k)), so slow inputs (temperature, time since power-on) are not over-read.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import signal, special, stats

from bench.analysis.allan import overlapping_adev
from bench.discovery.data import Record
from bench.discovery.significance import welch_dof, welch_nperseg

INPUT_COLUMNS = ("input", "cross_input", "temp", "t_on", "vib", "accel")


@dataclass(frozen=True)
class Segment:
    """A time segment whose residual departs from the floor: mean (unit) and rms/σ."""

    start_s: float
    end_s: float
    mean: float
    rms_ratio: float
    z_mean: float

    def describe(self) -> str:
        return (f"segment {self.start_s:.6g}–{self.end_s:.6g} s: mean {self.mean:.3g} "
                f"({self.z_mean:+.1f} σ of a mean), rms {self.rms_ratio:.2f}× the floor")


@dataclass(frozen=True)
class Band:
    """Frequencies whose PSD exceeds the white floor: ``kind`` is "line" or "band"."""

    kind: str
    f_low_hz: float
    f_high_hz: float
    peak_hz: float
    peak_ratio: float

    def describe(self) -> str:
        where = (f"{self.peak_hz:.4g} Hz" if self.kind == "line"
                 else f"{self.f_low_hz:.4g}–{self.f_high_hz:.4g} Hz (peak {self.peak_hz:.4g} Hz)")
        return f"spectral {self.kind} at {where}: PSD {self.peak_ratio:.3g}× the white floor"


@dataclass(frozen=True)
class TauRange:
    """Averaging times whose Allan deviation lies outside the white expectation's CI."""

    tau_low_s: float
    tau_high_s: float
    worst_ratio: float

    def describe(self) -> str:
        return (f"Allan deviation at τ = {self.tau_low_s:.4g}–{self.tau_high_s:.4g} s: up to "
                f"{self.worst_ratio:.3g}× the white-noise expectation")


@dataclass(frozen=True)
class InputCorrelation:
    """Correlation of the residual with a transform of a logged column."""

    column: str
    transform: str  # "x", "x^2", "x^3", "dx/dt"
    r: float
    z: float
    n_eff: float

    def describe(self) -> str:
        return (f"correlation with {self.transform.replace('x', self.column, 1)}: r = {self.r:+.3f} "
                f"({self.z:+.1f} σ, effective n {self.n_eff:.0f})")


@dataclass(frozen=True)
class Localization:
    """Everything flagged, plus the curves the report plots (PSD, ADEV and their floors)."""

    segments: tuple[Segment, ...]
    cusum_p: float
    bands: tuple[Band, ...]
    taus: tuple[TauRange, ...]
    correlations: tuple[InputCorrelation, ...]
    freq_hz: np.ndarray = field(repr=False)
    psd: np.ndarray = field(repr=False)
    psd_floor: float = 0.0
    tau_s: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    adev: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    adev_white: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    alpha: float = 0.01

    @property
    def any_structure(self) -> bool:
        """True when any test flags departure from the floor."""
        return bool(self.segments or self.bands or self.taus or self.correlations
                    or self.cusum_p < self.alpha)

    def descriptions(self) -> list[str]:
        """One line per finding, for the report and the "unexplained structure" list."""
        segs = sorted(self.segments, key=lambda s: -abs(s.z_mean))
        out = [s.describe() for s in segs[:4]]
        if len(segs) > 4:
            out.append(f"… and {len(segs) - 4} more segments depart (from "
                       f"{min(s.start_s for s in segs):.6g} s to {max(s.end_s for s in segs):.6g} s)")
        if self.cusum_p < self.alpha:
            out.append(f"cumulative sum departs from a zero-mean record (CUSUM p = {self.cusum_p:.2g})")
        out += [b.describe() for b in self.bands]
        out += [t.describe() for t in self.taus]
        out += [c.describe() for c in self.correlations]
        return out

    def to_dict(self) -> dict:
        return {"segments": [s.__dict__ for s in self.segments], "cusum_p": self.cusum_p,
                "bands": [b.__dict__ for b in self.bands], "taus": [t.__dict__ for t in self.taus],
                "correlations": [c.__dict__ for c in self.correlations],
                "descriptions": self.descriptions()}


def _check(residual, rec: Record, noise_sd: float) -> np.ndarray:
    r = np.asarray(residual, dtype=float)
    if r.shape != (rec.n,):
        raise ValueError(f"residual has shape {r.shape}; allowed: ({rec.n},) like the record")
    if not np.all(np.isfinite(r)):
        raise ValueError("residual has non-finite values; allowed: finite numbers")
    if not (np.isfinite(noise_sd) and noise_sd > 0):
        raise ValueError(f"noise_sd = {noise_sd!r}; allowed: a finite number > 0")
    return r


def time_segments(r: np.ndarray, t_s: np.ndarray, noise_sd: float, n_segments: int = 16,
                  alpha: float = 0.01) -> tuple[tuple[Segment, ...], float]:
    """Flagged segments and the CUSUM p-value (Kolmogorov limit of max|S_k|/(σ√n))."""
    n = r.size
    n_segments = max(1, min(n_segments, n // 8))
    edges = np.linspace(0, n, n_segments + 1).astype(int)
    a = alpha / (2 * n_segments)  # Bonferroni over segments and the two tests
    z_crit = stats.norm.isf(a / 2)
    out = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        seg = r[lo:hi]
        m = seg.size
        z = seg.mean() / (noise_sd / np.sqrt(m))
        ms = float(np.mean(seg ** 2))
        chi_p = stats.chi2.sf(m * ms / noise_sd ** 2, m)
        if abs(z) > z_crit or chi_p < a:
            out.append(Segment(float(t_s[lo]), float(t_s[hi - 1]), float(seg.mean()),
                               float(np.sqrt(ms) / noise_sd), float(z)))
    # a bridge: the residual's own mean is removed, max |B| has the Kolmogorov law
    s = np.cumsum(r - r.mean()) / (noise_sd * np.sqrt(n))
    cusum_p = float(special.kolmogorov(np.max(np.abs(s))))
    return tuple(out), cusum_p


def spectral_bands(r: np.ndarray, rate_hz: float, noise_sd: float, alpha: float = 0.01,
                   nperseg: int | None = None):
    """Welch PSD, the white floor and the flagged lines and bands."""
    n = r.size
    nperseg = int(nperseg or welch_nperseg(n))
    f, p = signal.welch(r, fs=rate_hz, window="hann", nperseg=nperseg, detrend=False)
    floor = 2.0 * noise_sd ** 2 / rate_hz
    nu = welch_dof(n, nperseg)
    crit = stats.chi2.isf(alpha / max(f.size, 1), nu) / nu
    flag = p / floor > crit
    flag[0] = False  # DC: the calibrated bias
    bands = []
    i = 0
    while i < f.size:
        if not flag[i]:
            i += 1
            continue
        j = i
        while j + 1 < f.size and flag[j + 1]:
            j += 1
        pk = i + int(np.argmax(p[i:j + 1]))
        bands.append(Band("line" if j - i <= 1 else "band", float(f[i]), float(f[j]),
                          float(f[pk]), float(p[pk] / floor)))
        i = j + 1
    return tuple(bands), f, p, floor


def allan_taus(r: np.ndarray, rate_hz: float, noise_sd: float, alpha: float = 0.01):
    """τ ranges where the white expectation lies outside the ADEV's (1 − alpha) interval."""
    if r.size < 16:
        return (), np.zeros(0), np.zeros(0), np.zeros(0)
    n_tau = max(1, int(np.log2(r.size // 2)) + 1)  # octave τ list length: Bonferroni over it
    res = overlapping_adev(r, rate_hz, "octave", unit=None, confidence=1.0 - alpha / n_tau)
    tau, adev = res.tau_s, res.adev
    white = noise_sd / np.sqrt(tau * rate_hz)
    lo, hi = res.adev_ci[:, 0], res.adev_ci[:, 1]
    bad = (lo > white) | (hi < white)
    bad &= np.isfinite(lo) & np.isfinite(hi)
    out = []
    i = 0
    while i < tau.size:
        if not bad[i]:
            i += 1
            continue
        j = i
        while j + 1 < tau.size and bad[j + 1]:
            j += 1
        ratio = adev[i:j + 1] / white[i:j + 1]
        worst = ratio[int(np.argmax(np.abs(np.log(ratio))))]
        out.append(TauRange(float(tau[i]), float(tau[j]), float(worst)))
        i = j + 1
    return tuple(out), tau, adev, white


def _acf(x: np.ndarray, max_lag: int) -> np.ndarray:
    x = x - x.mean()
    n = x.size
    spec = np.fft.rfft(x, 2 * n)
    c = np.fft.irfft(spec * np.conj(spec))[:max_lag + 1]
    return c / c[0] if c[0] > 0 else np.zeros(max_lag + 1)


def input_correlations(r: np.ndarray, rec: Record, alpha: float = 0.01) -> tuple[InputCorrelation, ...]:
    """Significant correlations of the residual with x, x², x³ (and dx/dt of ``input``)."""
    n = r.size
    max_lag = min(n - 1, max(10, n // 20))
    acf_r = _acf(r, max_lag)
    cands = []
    for name in INPUT_COLUMNS:
        if not rec.logged(name) and not (name == "t_on"):
            continue
        x = rec.column(name)
        if np.ptp(x) == 0:
            continue
        xs = (x - x.mean()) / np.ptp(x)
        trans = {"x": xs, "x^2": xs ** 2, "x^3": xs ** 3}
        if name == "input":
            trans["dx/dt"] = np.gradient(x, rec.t_s)
        for tname, v in trans.items():
            if np.ptp(v) == 0:
                continue
            cands.append((name, tname, v))
    out = []
    a = alpha / max(len(cands), 1)
    z_crit = stats.norm.isf(a / 2)
    rc = r - r.mean()
    sr = np.sqrt(np.sum(rc ** 2))
    for name, tname, v in cands:
        vc = v - v.mean()
        sv = np.sqrt(np.sum(vc ** 2))
        if sv == 0 or sr == 0:
            continue
        rho = float(np.dot(rc, vc) / (sr * sv))
        acf_v = _acf(v, max_lag)
        infl = 1.0 + 2.0 * float(np.sum(acf_v[1:] * acf_r[1:]))
        n_eff = float(np.clip(n / max(infl, 1e-9), 3.0, n))
        z = rho * np.sqrt(n_eff - 2) / np.sqrt(max(1 - rho ** 2, 1e-12))
        if abs(z) > z_crit:
            out.append(InputCorrelation(name, tname, rho, float(z), n_eff))
    return tuple(out)


def localize(rec: Record, residual, noise_sd: float, *, alpha: float = 0.01,
             n_segments: int = 16) -> Localization:
    """Localize the departure of ``residual`` (= y − model prediction) from white noise of sd
    ``noise_sd``: time segments, spectral lines/bands, Allan τ ranges, input correlations."""
    r = _check(residual, rec, float(noise_sd))
    if not 0 < alpha < 1:
        raise ValueError(f"alpha = {alpha!r}; allowed: (0, 1)")
    rate = rec.rate_hz
    segs, cusum_p = time_segments(r, rec.t_s, noise_sd, n_segments, alpha)
    bands, f, p, floor = spectral_bands(r, rate, noise_sd, alpha)
    taus, tau, adev, white = allan_taus(r, rate, noise_sd, alpha)
    corr = input_correlations(r, rec, alpha)
    return Localization(segs, cusum_p, bands, taus, corr, f, p, floor, tau, adev, white, alpha)
