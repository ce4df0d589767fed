"""Metrics of a rate estimate against a reference: tone phasors, per-tone amplitude and
phase error and their standard errors, and the NIS divergence check.

* **Per-frequency amplitude (%) and phase (deg) error**: every series is fitted by one
  linear least-squares model ``c + Σᵢ (aᵢ cos 2πfᵢt + bᵢ sin 2πfᵢt)`` at the known (or
  detected) tone frequencies; the phasor ratio ``Ŷ(f)/Y_ref(f)`` gives amplitude error
  ``100(|ratio| − 1)`` and phase error ``arg(ratio)`` (deg, lead positive).
* **Standard error at a tone** (:func:`tone_noise_std`) from the residual's local spectrum.
* **Divergence check** by the normalised innovation squared: the mean NIS over ``N``
  samples of a consistent filter with ``d`` degrees of freedom is ``χ²(N d)/N``; it is
  *consistent* if inside the two-sided ``1 − alpha`` χ² interval.  A filter that is merely
  inconsistent (wrong model, wrong R) keeps a steady NIS; one that *diverges* lets it grow:
  *diverged* if the rate is not finite or the mean NIS of the last tenth of the run exceeds
  both the upper bound and ten times the median of the ten tenths' means.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2


def tone_fit(t_s, y, freqs_hz) -> tuple[np.ndarray, np.ndarray]:
    """One joint least-squares fit of ``c + Σᵢ (aᵢ cos 2πfᵢt + bᵢ sin 2πfᵢt)`` to each column of
    ``y``: the phasors (tone × column) and the residual (same shape as ``y``)."""
    t = np.asarray(t_s, dtype=float)
    f = np.asarray(freqs_hz, dtype=float)
    y = np.asarray(y, dtype=float)
    arg = 2 * np.pi * np.outer(t - t[0], f)
    design = np.column_stack([np.ones_like(t), np.cos(arg), np.sin(arg)])
    # normal equations: the cosine/sine columns of a record holding a period or more of each tone
    # are far from collinear, and this is 4× faster than an SVD on long records
    coef = np.linalg.solve(design.T @ design, design.T @ y)
    return coef[1:1 + f.size] - 1j * coef[1 + f.size:1 + 2 * f.size], y - design @ coef


def without_outliers(t_s, y, freqs_hz, threshold: float = 8.0) -> tuple[np.ndarray, np.ndarray]:
    """``y`` (a series or columns of series) with its outliers — samples whose residual from the
    least-squares tone fit exceeds ``threshold`` robust standard deviations (1.4826·MAD) —
    replaced by the fit, the fit then redone without them; and the outlier mask.  For
    identifying sensors (FRF, noise levels) on records with spikes or dropouts, whose few
    huge samples would otherwise leak into every tone and every variance."""
    t = np.asarray(t_s, dtype=float)
    y = np.asarray(y, dtype=float)
    cols = y.reshape(y.shape[0], -1)
    f = np.asarray(freqs_hz, dtype=float)
    arg = 2 * np.pi * np.outer(t - t[0], f)
    design = np.column_stack([np.ones_like(t), np.cos(arg), np.sin(arg)])
    out, mask = cols.copy(), np.zeros(cols.shape, dtype=bool)
    for j in range(cols.shape[1]):
        keep = np.ones(t.size, dtype=bool)
        for _ in range(2):
            d = design[keep]
            coef = np.linalg.solve(d.T @ d, d.T @ cols[keep, j])
            fit = design @ coef
            r = cols[:, j] - fit
            mad = 1.4826 * float(np.median(np.abs(r[keep] - np.median(r[keep]))))
            bad = np.abs(r) > threshold * mad if mad > 0 else np.zeros(t.size, dtype=bool)
            if not np.any(bad) or np.array_equal(~bad, keep) or bad.sum() > t.size // 4:
                break
            keep = ~bad
        mask[:, j] = ~keep
        out[~keep, j] = fit[~keep]
    return out.reshape(y.shape), mask.reshape(y.shape)


def sine_phasors(t_s, y, freqs_hz) -> np.ndarray:
    """Complex amplitudes ``Aᵢ`` (``y ≈ c + Σ |Aᵢ| cos(2πfᵢt + arg Aᵢ)``) by one joint LS fit;
    ``y`` may hold several series as columns (then one row of phasors per tone, column per series)."""
    return tone_fit(t_s, y, freqs_hz)[0]


def detect_tones(y, rate_hz: float, max_tones: int = 24, rel_threshold: float = 1e-2) -> np.ndarray:
    """Tone frequencies (Hz) of a multi-tone record: local maxima of its Hann-windowed
    spectrum above ``rel_threshold`` of the largest (DC bin excluded), refined by a parabola
    through the log magnitudes of the peak bin and its neighbours."""
    y = np.asarray(y, dtype=float)
    spec = np.abs(np.fft.rfft((y - y.mean()) * np.hanning(y.size)))
    peak = (spec[1:-1] > spec[:-2]) & (spec[1:-1] >= spec[2:]) & (spec[1:-1] > rel_threshold * spec[1:].max())
    bins = np.flatnonzero(peak) + 1
    bins = bins[np.argsort(spec[bins])[::-1][:max_tones]]
    out = []
    for b in np.sort(bins):
        lo, mid, hi = np.log(spec[b - 1:b + 2] + 1e-300)
        den = lo - 2 * mid + hi
        out.append((b + (0.5 * (lo - hi) / den if den != 0 else 0.0)) * rate_hz / y.size)
    return np.asarray(out)


@dataclass(frozen=True)
class NisStats:
    """Mean NIS over ``n`` samples, its χ² bounds for ``dof`` per sample, and the verdicts."""

    mean: float
    lower: float
    upper: float
    n: int
    dof: int
    consistent: bool
    diverged: bool

    def to_dict(self) -> dict:
        return {"mean": float(self.mean), "lower": float(self.lower), "upper": float(self.upper), "n": int(self.n),
                "dof": int(self.dof), "consistent": bool(self.consistent), "diverged": bool(self.diverged)}


def nis_check(nis, dof: int, alpha: float = 0.05, rate=None) -> NisStats:
    """χ² check of per-sample NIS values with ``dof`` degrees of freedom each (see module doc)."""
    nis = np.asarray(nis, dtype=float).ravel()
    if nis.size == 0:
        raise ValueError("no NIS values to check")
    if not 0 < alpha < 1:
        raise ValueError(f"alpha {alpha} must be in (0, 1)")
    n = nis.size
    lower, upper = chi2.ppf([alpha / 2, 1 - alpha / 2], n * dof) / n
    finite = bool(np.all(np.isfinite(nis))) and (rate is None or bool(np.all(np.isfinite(rate))))
    mean = float(np.mean(nis)) if finite else math.inf
    tenths = [float(np.mean(c)) for c in np.array_split(nis, min(10, n))]
    diverged = bool((not finite) or (tenths[-1] > upper and tenths[-1] > 10 * float(np.median(tenths))))
    return NisStats(mean, float(lower), float(upper), n, dof, bool(finite and lower <= mean <= upper), diverged)


def tone_residual(t, ys, tones) -> np.ndarray:
    """Each column of ``ys`` less its LS fit at the tones (and its mean)."""
    return tone_fit(t, ys, tones)[1]


def tone_residual_var(t, ys, tones) -> np.ndarray:
    """Variance of each column of ``ys`` after removing its LS fit at the tones (and its mean):
    the sensors' noise variance on a stretch with a known multi-tone input."""
    return np.var(tone_residual(t, ys, tones), axis=0)


def tone_noise_std(residual, rate_hz: float, tones_hz, half_bins: int = 8) -> np.ndarray:
    """Standard error of one component (cos or sin) of a least-squares phasor at each tone,
    from the noise left in ``residual`` (the series less its tone fit), coloured or not:
    ``√(S(f)/T)`` with ``S`` the one-sided PSD at the tone — the periodogram averaged over
    ±``half_bins`` bins around it, skipping the tone's own bins and every other tone's —
    and ``T`` the record length.  (For white noise of variance σ² this is σ√(2/N).)"""
    r = np.asarray(residual, dtype=float)
    n = r.size
    psd = 2.0 * np.abs(np.fft.rfft(r - r.mean())) ** 2 / (rate_hz * n)
    df = rate_hz / n
    tone_bins = np.round(np.asarray(tones_hz, dtype=float) / df).astype(int)
    out = np.empty(tone_bins.size)
    for i, k in enumerate(tone_bins):
        bins = np.arange(max(k - half_bins, 1), min(k + half_bins + 1, psd.size))
        near_tone = np.min(np.abs(bins[:, None] - tone_bins[None, :]), axis=1) <= 1
        use = bins[~near_tone] if np.any(~near_tone) else bins
        out[i] = math.sqrt(float(np.mean(psd[use])) / (n / rate_hz))
    return out
