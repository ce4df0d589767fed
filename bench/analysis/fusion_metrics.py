"""Metrics of rate fusion against a reference, and :func:`analyze_fusion` (Document B side by side).

* **Per-frequency amplitude (%) and phase (deg) error**: every series is fitted by one
  linear least-squares model ``c + Σᵢ (aᵢ cos 2πfᵢt + bᵢ sin 2πfᵢt)`` at the known (or
  detected) tone frequencies; the phasor ratio ``Ŷ(f)/Y_ref(f)`` gives amplitude error
  ``100(|ratio| − 1)`` and phase error ``arg(ratio)`` (deg, lead positive).
* **RMS error** of each method over the run (after ``settle_s``).
* **Divergence check** by the normalised innovation squared: the mean NIS over ``N``
  samples of a consistent filter with ``d`` degrees of freedom is ``χ²(N d)/N``; it is
  *consistent* if inside the two-sided ``1 − alpha`` χ² interval.  A filter that is merely
  inconsistent (wrong model, wrong R) keeps a steady NIS; one that *diverges* lets it grow:
  *diverged* if the rate is not finite or the mean NIS of the last tenth of the run exceeds
  both the upper bound and ten times the median of the ten tenths' means.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.stats import chi2

from bench.analysis import fusion as fu
from bench.analysis.fusion_models import FusionModel, SensorModel, fit_transfer_function

DEFAULT_HF = SensorModel("highpass", 1, 2.0, 1.0)  # MHD-class: first-order high-pass at 2 Hz
DEFAULT_LF = SensorModel("lowpass", 1, 30.0, 1.0)  # FOG/MEMS-class: first-order low-pass at 30 Hz
FusionParams = fu.FusionParams
METHODS = ("fused", "hf", "lf", "fixed_r_kf", "complementary")


def _tone_fit(t_s, y, freqs_hz) -> tuple[np.ndarray, np.ndarray]:
    """One joint least-squares fit of ``c + Σᵢ (aᵢ cos 2πfᵢt + bᵢ sin 2πfᵢt)`` to each column of
    ``y``: the phasors (tone × column) and the residual (same shape as ``y``)."""
    t = np.asarray(t_s, dtype=float)
    f = np.asarray(freqs_hz, dtype=float)
    y = np.asarray(y, dtype=float)
    arg = 2 * np.pi * np.outer(t - t[0], f)
    design = np.column_stack([np.ones_like(t), np.cos(arg), np.sin(arg)])
    coef, *_ = np.linalg.lstsq(design, y, rcond=None)
    return coef[1:1 + f.size] - 1j * coef[1 + f.size:1 + 2 * f.size], y - design @ coef


def sine_phasors(t_s, y, freqs_hz) -> np.ndarray:
    """Complex amplitudes ``Aᵢ`` (``y ≈ c + Σ |Aᵢ| cos(2πfᵢt + arg Aᵢ)``) by one joint LS fit;
    ``y`` may hold several series as columns (then one row of phasors per tone, column per series)."""
    return _tone_fit(t_s, y, freqs_hz)[0]


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


@dataclass
class FusionAnalysis:
    """Everything :func:`analyze_fusion` found; arrays stay out of :meth:`to_dict` except the
    per-frequency errors."""

    rate_hz: float
    n_samples: int
    model: FusionModel
    params: FusionParams
    model_source: str
    crossover_hz: float
    fused: np.ndarray
    estimates: dict
    nis: dict
    r_interval_fraction: dict
    r_range: dict
    fits: dict = field(default_factory=dict)
    rms_error: dict | None = None
    tones_hz: np.ndarray | None = None
    amplitude_error_pct: dict | None = None
    #: standard error of each amplitude error (%): the series' noise at the tone (:func:`tone_noise_std`)
    amplitude_error_std_pct: dict | None = None
    #: per tone, |fused amplitude error| − the better single sensor's (pp), its standard error
    #: (from the fused-minus-sensor series) and which sensor was better
    excess_pct: np.ndarray | None = None
    excess_std_pct: np.ndarray | None = None
    excess_best: list | None = None
    phase_error_deg: dict | None = None
    notes: list = field(default_factory=list)

    def to_dict(self) -> dict:
        def floats(v):
            return None if v is None else [float(x) for x in v]

        return {
            "rate_hz": float(self.rate_hz), "n_samples": int(self.n_samples), "model": self.model.to_dict(),
            "model_source": self.model_source, "params": self.params.to_dict(),
            "crossover_hz": float(self.crossover_hz),
            "fits": {k: v.to_dict() for k, v in self.fits.items()},
            "rms_error": None if self.rms_error is None else {k: float(v) for k, v in self.rms_error.items()},
            "tones_hz": floats(self.tones_hz),
            "amplitude_error_pct": None if self.amplitude_error_pct is None else
            {k: floats(v) for k, v in self.amplitude_error_pct.items()},
            "amplitude_error_std_pct": None if self.amplitude_error_std_pct is None else
            {k: floats(v) for k, v in self.amplitude_error_std_pct.items()},
            "excess_pct": floats(self.excess_pct), "excess_std_pct": floats(self.excess_std_pct),
            "excess_best": None if self.excess_best is None else list(self.excess_best),
            "phase_error_deg": None if self.phase_error_deg is None else
            {k: floats(v) for k, v in self.phase_error_deg.items()},
            "nis": {k: v.to_dict() for k, v in self.nis.items()},
            "r_interval_fraction": {k: floats(v) for k, v in self.r_interval_fraction.items()},
            "r_range": {k: floats(v) for k, v in self.r_range.items()},
            "notes": list(self.notes),
        }


def analyze_fusion(t, hf, lf, ref=None, rate_hz: float | None = None, *, hf_model: SensorModel | None = None,
                   lf_model: SensorModel | None = None, tones_hz=None, crossover_hz: float | None = None,
                   params: fu.FusionParams | None = None, q: float | None = None, settle_s: float = 0.0,
                   discretization: str = "euler", alpha: float = 0.05) -> FusionAnalysis:
    """Run Document B's sequential filter and the baselines on one record and compare them.

    Sensor models: the given ones; else, with ``ref``, fitted (:func:`fit_transfer_function`,
    order ≤ 2) to each sensor's FRF at the tones (``tones_hz`` or :func:`detect_tones` of
    ``ref``); else :data:`DEFAULT_HF`/:data:`DEFAULT_LF`.  Noise σ²: with ``ref``, the variance
    of each sensor's residual after the LS fit of its tones; else :func:`~fusion.white_noise_var`.
    ``params`` default to :func:`~fusion.tune_fusion_params`; ``crossover_hz`` to
    ``√(f_h·f_l)``.  Metrics start ``settle_s`` after the first sample."""
    t = np.asarray(t, dtype=float).ravel()
    hf, lf = fu._check_series(hf, lf)
    if t.size != hf.size:
        raise ValueError(f"t has {t.size} samples and hf {hf.size}; they must match")
    if rate_hz is None:
        rate_hz = (t.size - 1) / float(t[-1] - t[0]) if t[-1] > t[0] else math.nan
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise ValueError(f"rate_hz {rate_hz} must be a finite value > 0")
    ts = 1.0 / rate_hz
    if ref is not None:
        ref = np.asarray(ref, dtype=float).ravel()
        if ref.size != hf.size or not np.all(np.isfinite(ref)):
            raise ValueError(f"ref must have {hf.size} finite samples like hf (has {ref.size})")
    notes, fits = [], {}
    tones = None
    if ref is not None:
        tones = detect_tones(ref, rate_hz) if tones_hz is None else np.asarray(tones_hz, dtype=float)
        if tones.size == 0 or np.any(tones <= 0) or np.any(tones >= rate_hz / 2):
            raise ValueError(f"tones_hz must be non-empty and within (0, {rate_hz / 2:g}) Hz")
    hf_err = lf_err = 0.0
    if hf_model is not None and lf_model is not None:
        source = "given"
    elif ref is not None and tones.size >= 5:
        a = sine_phasors(t, np.column_stack([ref, hf, lf]), tones)
        frf = {"hf": a[:, 1] / a[:, 0], "lf": a[:, 2] / a[:, 0]}
        fits["hf"] = fit_transfer_function(tones, frf["hf"], "highpass")
        fits["lf"] = fit_transfer_function(tones, frf["lf"], "lowpass")
        hf_model = hf_model or fits["hf"].model
        lf_model = lf_model or fits["lf"].model
        notes.append(f"passband misfit of the fitted models: HF {fu.passband_misfit(hf_model, tones, frf['hf']):.3g}, "
                     f"LF {fu.passband_misfit(lf_model, tones, frf['lf']):.3g} (not used as ε)")
        source = "fitted to the FRF against ref"
    else:
        hf_model, lf_model = hf_model or DEFAULT_HF, lf_model or DEFAULT_LF
        source = "default"
        notes.append("sensor models are defaults (HF high-pass 2 Hz, LF low-pass 30 Hz); pass models or a ref")
    if ref is not None:
        hf_var, lf_var = _residual_var(t, np.column_stack([hf, lf]), tones)
    else:
        hf_var, lf_var = fu.white_noise_var(hf), fu.white_noise_var(lf)
    hf_var, lf_var = max(hf_var, 1e-30), max(lf_var, 1e-30)
    model, tuned = fu.tune_fusion_params(hf_model, lf_model, hf_var, lf_var, hf, lf, ts, hf_model_error=hf_err,
                                         lf_model_error=lf_err, discretization=discretization)
    if q is not None:
        model = FusionModel(hf_model, lf_model, q)
    params = params or tuned
    if crossover_hz is None:
        crossover_hz = math.sqrt(hf_model.corner_hz * lf_model.corner_hz)

    seq = fu.sequential_fusion(hf, lf, ts, model, params)
    kf = fu.fixed_r_kalman(hf, lf, ts, model, params)
    estimates = {"fused": seq.rate, "hf": hf / hf_model.gain, "lf": lf / lf_model.gain, "fixed_r_kf": kf.rate,
                 "complementary": fu.complementary_filter(hf, lf, rate_hz, model, crossover_hz)}
    keep = slice(int(round(settle_s * rate_hz)), None)
    nis = {"fused_hf": nis_check(seq.nis[keep, 0], 1, alpha, seq.rate),
           "fused_lf": nis_check(seq.nis[keep, 1], 1, alpha, seq.rate),
           "fused": nis_check(seq.nis[keep].sum(axis=1), 2, alpha, seq.rate),
           "fixed_r_kf": nis_check(kf.nis[keep, 0], 2, alpha, kf.rate)}
    names = ("hf", "lf")
    frac = {n: np.bincount(seq.interval[keep, j], minlength=3) / seq.interval[keep, j].size
            for j, n in enumerate(names)}
    r_range = {n: [float(seq.r[keep, j].min()), float(seq.r[keep, j].max())] for j, n in enumerate(names)}
    out = FusionAnalysis(rate_hz, hf.size, model, params, source, float(crossover_hz), seq.rate, estimates, nis,
                         frac, r_range, fits, notes=notes)
    if ref is not None:
        e = {k: v[keep] - ref[keep] for k, v in estimates.items()}
        out.rms_error = {k: float(np.sqrt(np.mean(v * v))) for k, v in e.items()}
        names = list(estimates)
        # one fit gives every series' phasors and its residual (column 0: the reference)
        phasors, resid = _tone_fit(t[keep], np.column_stack([ref[keep]] + [estimates[k][keep] for k in names]),
                                   tones)
        resid = {k: resid[:, j] for j, k in enumerate(names, start=1)}
        out.tones_hz = tones
        out.amplitude_error_pct, out.phase_error_deg, out.amplitude_error_std_pct = {}, {}, {}
        ref_amp = np.abs(phasors[:, 0])
        noise = {k: tone_noise_std(resid[k], rate_hz, tones) for k in names}
        for col, k in enumerate(names, start=1):
            ratio = phasors[:, col] / phasors[:, 0]
            out.amplitude_error_pct[k] = 100 * (np.abs(ratio) - 1)
            out.amplitude_error_std_pct[k] = 100 * noise[k] / ref_amp
            out.phase_error_deg[k] = np.degrees(np.angle(ratio))
        # fused against the better single sensor, tone by tone: the two share their noise, so
        # the excess's standard error comes from the difference series, not from each alone
        amp = np.abs(np.vstack([out.amplitude_error_pct["hf"], out.amplitude_error_pct["lf"]]))
        best = np.argmin(amp, axis=0)
        # the fit is linear: the difference series' residual is the difference of the residuals
        diff_sd = np.vstack([tone_noise_std(resid["fused"] - resid[m], rate_hz, tones) for m in ("hf", "lf")])
        idx = np.arange(tones.size)
        out.excess_pct = np.abs(out.amplitude_error_pct["fused"]) - amp[best, idx]
        out.excess_std_pct = 100 * diff_sd[best, idx] / ref_amp
        out.excess_best = [("hf", "lf")[b] for b in best]
    return out


def excess_over_best(analysis: dict) -> tuple[np.ndarray, np.ndarray]:
    """Per tone: the fused rate's |amplitude error| less the better single sensor's (pp), and
    the standard error of that difference (pp) — as :func:`analyze_fusion` computed them from
    the fused-minus-sensor series; for an older analysis without them, from each series'
    own standard error (an overestimate: the two share their noise)."""
    if analysis.get("excess_pct") is not None:
        return (np.asarray(analysis["excess_pct"], dtype=float), np.asarray(analysis["excess_std_pct"], dtype=float))
    amp = {k: np.abs(np.asarray(v, dtype=float)) for k, v in analysis["amplitude_error_pct"].items()}
    sd = analysis.get("amplitude_error_std_pct") or {k: np.zeros_like(v) for k, v in amp.items()}
    sd = {k: np.asarray(v, dtype=float) for k, v in sd.items()}
    which = np.argmin(np.vstack([amp["hf"], amp["lf"]]), axis=0)
    idx = np.arange(which.size)
    best = np.vstack([amp["hf"], amp["lf"]])[which, idx]
    best_sd = np.vstack([sd["hf"], sd["lf"]])[which, idx]
    return amp["fused"] - best, np.hypot(sd["fused"], best_sd)


def _residual(t, ys, tones) -> np.ndarray:
    """Each column of ``ys`` less its LS fit at the tones (and its mean)."""
    return _tone_fit(t, ys, tones)[1]


def _residual_var(t, ys, tones) -> np.ndarray:
    """Variance of each column of ``ys`` after removing its LS fit at the tones (and its mean)."""
    return np.var(_residual(t, ys, tones), axis=0)


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
