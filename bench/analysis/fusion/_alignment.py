"""Sensor models and time alignment of a recorded HF/LF pair against its reference.

A pair recorded on one time column may still be off in time: each sensor's sample clock can
run fast or slow against the reference's (a few to a hundred ppm: over a minute, a drift of
milliseconds, tens of degrees at the LF sensor's corner) and each may report late (latency,
an unmodelled pole far above the band).  :func:`fit_and_align`, on the stretch it is given
(the tuning part: the reference of the judged part is never used), with each sensor's
outliers (spikes, dropouts: > 8 robust σ from its tone fit) replaced by that fit
(:func:`~bench.analysis.fusion._metrics.without_outliers`) — they are left in the record the
fusion sees (what a sensor alone reads, and what Document B's adaptive R is meant to handle);
a copy with them replaced (step 4) goes beside it, for the methods run on a cleaned record,
which are judged like every other and so cannot displace a better one:

1. a quick FRF of each sensor against the reference at the tones (least-squares phasors);
2. each sensor's clock rate error, from the phase drift of the highest tone it passes
   (:func:`~bench.analysis.frf._timebase.estimate_time_base`, blocks of at least ten periods;
   the other tones fitted out of both series first, :func:`only_tone` — left in, they leak
   into blocks a few of their periods long and the rate's uncertainty grows 20×),
   when the stretch holds at least three blocks and the error is significant (beyond three
   standard errors: correcting noise would add a drift);
3. on the rate-corrected time axes, the FRF again and each sensor's transfer function with a
   pure delay (:func:`~bench.analysis.fusion._models.fit_transfer_function`, order ≤ 2; order 1
   with fewer than six tones), each FRF point weighted by its standard uncertainty (from both
   series' noise at the tone); for the HF sensor also with a first-order pole above the tones,
   kept if it halves the misfit — then undone on the HF record (:func:`undo_upper_pole`); for
   the LF sensor also as the mean over each sample interval (an integrating converter: its
   response ``sinc(f/fs)`` divided out of the FRF, the half interval's lag left to the delay),
   kept if it halves the misfit — then undone on the LF record (:func:`undo_interval_mean`);
4. the HF samples kept as they are on their corrected instants less the HF delay; the LF
   record (its instants corrected and moved back by its delay) and the reference resampled
   onto them (:func:`~bench.analysis.frf._timebase.resample`, band-limited), the ends that
   would need extrapolation dropped.  The cleaned copy (``hf_clean``, ``lf_clean``): each
   sensor's whole record, on its corrected clock (where the tones stay coherent over the
   record), with the samples beyond 8 robust σ of its own tone fit replaced by that fit
   (the reference unused), *before* the look-ahead filters and the resampling, which would
   smear a one-sample spike over their taps below the threshold; then aligned the same way.
   It needs the motion to be the tones (a tone test): on other motion the residual is the
   motion and little or nothing is replaced.

The fusion then sees two sensors whose only differences from the reference are their
transfer functions without delay and their noise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bench.analysis.frf import TimeBase, apply_time_base, estimate_time_base, resample
from bench.analysis.fusion._metrics import tone_fit, tone_noise_std, without_outliers
from bench.analysis.fusion._models import ORDER_GAIN_FACTOR, TransferFit, fit_transfer_function, min_frf_points

MIN_TONES = 4  # a first-order high- or low-pass with a delay needs this many FRF points (second order: 6)
CLOCK_BLOCK_S = 5.0  # longest clock block (s); at least ten periods of the tone
MIN_CLOCK_BLOCKS = 3
UPPER_POLE_HALF_WIDTH = 8  # taps each side of the derivative filter that undoes an HF upper pole
UPPER_POLE_BAND = 0.25  # ... designed to be exact (1e-6) up to this fraction of the sample rate
INTERVAL_MEAN_HALF_WIDTH = 8  # taps each side of the filter that undoes an LF interval mean
INTERVAL_MEAN_BAND = 0.25  # ... designed up to this fraction of the sample rate
CLOCK_SIGNIFICANCE = 3.0  # a clock rate error is corrected only beyond this many standard errors


@dataclass(frozen=True)
class PairAlignment:
    """What :func:`fit_and_align` found: each sensor's fit (with its delay), its clock (``None``
    where the stretch was too short to measure it) and how many samples each end lost."""

    hf_fit: TransferFit
    lf_fit: TransferFit
    hf_clock: TimeBase | None
    lf_clock: TimeBase | None
    trimmed_start: int
    trimmed_end: int
    notes: tuple
    lf_interval_mean: bool = False
    #: samples replaced by the tone fit in the cleaned copy, HF and LF, over the whole record
    outliers_replaced: tuple = (0, 0)

    def to_dict(self) -> dict:
        def clock(tb):
            return None if tb is None else tb.to_dict()

        return {"hf_fit": self.hf_fit.to_dict(), "lf_fit": self.lf_fit.to_dict(), "hf_clock": clock(self.hf_clock),
                "lf_clock": clock(self.lf_clock), "trimmed_start": int(self.trimmed_start),
                "trimmed_end": int(self.trimmed_end), "notes": list(self.notes),
                "lf_interval_mean": self.lf_interval_mean,
                "outliers_replaced": {"hf": int(self.outliers_replaced[0]), "lf": int(self.outliers_replaced[1])}}


def _frf(t_ref, ref, t_y, y, tones, rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """``Y/REF`` at the tones (both phasors quoted at ``t_ref[0]``) and the standard uncertainty
    of its real and imaginary parts, from each series' noise at the tone
    (:func:`~bench.analysis.fusion._metrics.tone_noise_std`)."""
    a_ref, r_ref = tone_fit(t_ref, ref, tones)
    a_y, r_y = tone_fit(t_y, y, tones)
    a_y = a_y * np.exp(2j * np.pi * tones * (t_ref[0] - t_y[0]))
    g = a_y / a_ref
    rel = np.hypot(tone_noise_std(r_y, rate_hz, tones) / np.abs(a_y), tone_noise_std(r_ref, rate_hz, tones)
                   / np.abs(a_ref))
    return g, np.maximum(np.abs(g) * rel, 1e-12 * np.abs(g))


def derivative_taps(half_width: int = UPPER_POLE_HALF_WIDTH, band: float = UPPER_POLE_BAND) -> np.ndarray:
    """Antisymmetric taps ``d_m`` (m = 1…``half_width``) of a derivative filter
    ``ẏ_k ≈ fs·Σ d_m (y_{k+m} − y_{k−m})``: least squares on the relative error of its response
    ``2 Σ d_m sin mθ`` against ``θ`` up to ``band``·fs (1.4·10⁻⁶ at 8 taps to fs/4)."""
    theta = np.linspace(1e-3, 2 * np.pi * band, 400)
    design = np.column_stack([2 * np.sin(m * theta) for m in range(1, half_width + 1)]) / theta[:, None]
    return np.linalg.lstsq(design, np.ones_like(theta), rcond=None)[0]


def undo_upper_pole(y, upper_hz: float, rate_hz: float) -> np.ndarray:
    """``y`` with a first-order pole at ``upper_hz`` undone: ``y + ẏ/(2π f_u)`` (the derivative by
    :func:`derivative_taps`, looking ``UPPER_POLE_HALF_WIDTH`` samples ahead; the ends, where
    it would run off the record, keep the two-point difference)."""
    y = np.asarray(y, dtype=float)
    if not (math.isfinite(upper_hz) and upper_hz > 0):
        raise ValueError(f"upper_hz {upper_hz} must be a finite value > 0")
    taps = derivative_taps()
    half = taps.size
    dy = np.gradient(y) * rate_hz
    if y.size > 2 * half:
        inner = np.zeros(y.size - 2 * half)
        for m, d in enumerate(taps, start=1):
            inner += d * (y[half + m:y.size - half + m] - y[half - m:y.size - half - m])
        dy[half:-half] = inner * rate_hz
    return y + dy / (2 * math.pi * upper_hz)


def inverse_sinc_taps(half_width: int = INTERVAL_MEAN_HALF_WIDTH, band: float = INTERVAL_MEAN_BAND) -> np.ndarray:
    """Symmetric taps ``c_0, c_1 … c_half_width`` of a filter whose response
    ``c_0 + 2 Σ c_m cos mθ`` is ``1/sinc(θ/2π)`` — the inverse of a mean over one sample
    interval — up to ``band``·fs: least squares on the relative error (≈ 10⁻⁶ at 8 taps to
    fs/4; its gain at Nyquist stays below 2)."""
    theta = np.linspace(0.0, 2 * np.pi * band, 400)
    target = 1.0 / np.sinc(theta / (2 * np.pi))
    design = np.column_stack([np.ones_like(theta)] + [2 * np.cos(m * theta) for m in range(1, half_width + 1)])
    return np.linalg.lstsq(design / target[:, None], np.ones_like(theta), rcond=None)[0]


def undo_interval_mean(y) -> np.ndarray:
    """``y`` whose samples are means over their own sample interval, with that averaging undone
    by :func:`inverse_sinc_taps` (looking ``INTERVAL_MEAN_HALF_WIDTH`` samples ahead; the ends,
    where the filter would run off the record, keep their samples).  Offline only."""
    y = np.asarray(y, dtype=float)
    if y.ndim != 1:
        raise ValueError(f"y must be 1-D (has shape {y.shape})")
    taps = inverse_sinc_taps()
    half = taps.size - 1
    if y.size <= 2 * half:
        return y.copy()
    out = y.copy()
    kernel = np.concatenate([taps[:0:-1], taps])
    out[half:-half] = np.convolve(y, kernel, mode="valid")
    return out


def only_tone(t_s, y, tones_hz, f_hz: float) -> np.ndarray:
    """``y`` less every tone of ``tones_hz`` but ``f_hz`` (one joint least-squares fit over the
    record): the clock's per-block sine fits at ``f_hz`` then see its noise, not the other
    tones leaking into blocks a few of their periods long."""
    tones = np.asarray(tones_hz, dtype=float)
    others = tones[~np.isclose(tones, f_hz)]
    if others.size == 0:
        return np.asarray(y, dtype=float)
    t = np.asarray(t_s, dtype=float)
    phasors, residual = tone_fit(t, y, tones)
    kept = phasors[np.isclose(tones, f_hz)].sum()
    arg = 2 * np.pi * f_hz * (t - t[0])
    return residual + kept.real * np.cos(arg) - kept.imag * np.sin(arg)


def _clock(t, ref, y, tones, f_hz: float, notes: list, name: str) -> TimeBase | None:
    ref, y = only_tone(t, ref, tones, f_hz), only_tone(t, y, tones, f_hz)
    span = float(t[-1] - t[0])
    block = max(10.0 / f_hz, min(CLOCK_BLOCK_S, span / 4))
    if span < MIN_CLOCK_BLOCKS * block:
        notes.append(f"{name} clock not measured: {span:.3g} s holds fewer than {MIN_CLOCK_BLOCKS} blocks of "
                     f"{block:.3g} s at {f_hz:.4g} Hz")
        return None
    tb = estimate_time_base(t, ref, t, y, f_hz, block)
    if abs(tb.rate_ppm) <= CLOCK_SIGNIFICANCE * tb.rate_std_ppm:
        notes.append(f"{name} clock rate error {tb.rate_ppm:+.3g} ± {tb.rate_std_ppm:.2g} ppm is not significant "
                     f"(≤ {CLOCK_SIGNIFICANCE:g}σ): not corrected")
        return None
    return tb


def fit_and_align(t_s, hf, lf, ref, tones_hz, rate_hz: float,
                  fit_part: slice | None = None) -> tuple[dict, PairAlignment]:
    """Fit both sensors and align the record (module docstring).  ``fit_part`` the stretch the
    clocks and models are measured on (default: all).  Returns the aligned ``{"t_s", "hf",
    "lf", "ref", "hf_clean", "lf_clean"}`` (``t_s`` on the reference's clock; the last two the
    cleaned copy, the same arrays as ``hf``/``lf`` where nothing was replaced) and what was found."""
    t = np.asarray(t_s, dtype=float)
    hf, lf, ref = (np.asarray(v, dtype=float) for v in (hf, lf, ref))
    tones = np.sort(np.asarray(tones_hz, dtype=float))
    if tones.size < MIN_TONES:
        raise ValueError(f"{tones.size} tones; at least {MIN_TONES} are needed to fit a sensor with a delay")
    part = slice(None) if fit_part is None else fit_part
    tp, rp = t[part], ref[part]
    notes: list[str] = []
    cleaned, mask = without_outliers(tp, np.column_stack([hf[part], lf[part]]), tones)
    hp, lp = cleaned[:, 0], cleaned[:, 1]
    outliers = mask.sum(axis=0)
    if np.any(outliers):
        notes.append(f"outliers left out of the models' identification: {int(outliers[0])} HF and "
                     f"{int(outliers[1])} LF samples (> 8 robust σ from the tone fit)")
    g_hf, g_lf = _frf(tp, rp, tp, hp, tones, rate_hz)[0], _frf(tp, rp, tp, lp, tones, rate_hz)[0]
    passed_hf = tones[np.abs(g_hf) >= 0.5 * np.max(np.abs(g_hf))]
    passed_lf = tones[np.abs(g_lf) >= 0.5 * np.abs(g_lf[0])]
    clocks = {}
    for name, y, passed in (("hf", hp, passed_hf), ("lf", lp, passed_lf)):
        clocks[name] = _clock(tp, rp, y, tones, float(passed.max()) if passed.size else float(tones.min()), notes, name)
    epoch = float(t[0])
    t_hf = t if clocks["hf"] is None else apply_time_base(t, clocks["hf"], epoch_s=epoch)
    t_lf = t if clocks["lf"] is None else apply_time_base(t, clocks["lf"], epoch_s=epoch)
    fits = {}
    interval_mean = False
    for name, kind, ty, y in (("hf", "highpass", t_hf[part], hp), ("lf", "lowpass", t_lf[part], lp)):
        g, sd = _frf(tp, rp, ty, y, tones, rate_hz)
        order = 2 if tones.size >= 6 else 1
        fits[name] = fit_transfer_function(tones, g, kind, max_order=order, fit_delay=True, weights=1.0 / sd)
        if name == "hf" and tones.size >= min_frf_points(order, True, True):
            # the HF sensor's own bandwidth limit, if the FRF shows one: a pole above the tones that
            # explains at least half of the misfit (left out, it bends the fitted gain and corner)
            upper = fit_transfer_function(tones, g, kind, max_order=order, fit_delay=True, weights=1.0 / sd,
                                          upper_pole=True)
            if (upper.upper_hz is not None and tones.max() < upper.upper_hz
                    and upper.residual < fits[name].residual / ORDER_GAIN_FACTOR):
                fits[name] = upper
        if name == "lf" and tones.max() <= INTERVAL_MEAN_BAND * rate_hz:
            # the LF sensor's samples may be means over their interval (an integrating converter):
            # its sinc droop is outside the fitted family and would bend the gain and the corner
            droop = np.sinc(tones / rate_hz)
            mean = fit_transfer_function(tones, g / droop, kind, max_order=order, fit_delay=True,
                                         weights=droop / sd)
            if mean.residual < fits[name].residual / ORDER_GAIN_FACTOR:
                fits[name] = mean
                interval_mean = True
    hf_fit, lf_fit = fits["hf"], fits["lf"]
    # the cleaned copy, each sensor on its own corrected clock (step 4)
    hf_clean, hf_mask = without_outliers(t_hf, hf, tones)
    lf_clean, lf_mask = without_outliers(t_lf, lf, tones)
    replaced = (int(hf_mask.sum()), int(lf_mask.sum()))
    if any(replaced):
        notes.append(f"outliers replaced by each sensor's tone fit in the cleaned copy: {replaced[0]} HF and "
                     f"{replaced[1]} LF samples of the whole record")
    if hf_fit.upper_hz is not None:
        hf = undo_upper_pole(hf, hf_fit.upper_hz, rate_hz)
        hf_clean = undo_upper_pole(hf_clean, hf_fit.upper_hz, rate_hz) if replaced[0] else hf
        notes.append(f"HF upper pole at {hf_fit.upper_hz:.4g} Hz measured and undone "
                     f"(a {UPPER_POLE_HALF_WIDTH}-sample look-ahead filter)")
    elif not replaced[0]:
        hf_clean = hf
    if interval_mean:
        lf = undo_interval_mean(lf)
        lf_clean = undo_interval_mean(lf_clean) if replaced[1] else lf
        notes.append(f"LF samples are means over their interval: sinc droop measured and undone "
                     f"(a {INTERVAL_MEAN_HALF_WIDTH}-sample look-ahead filter)")
    t_base = t_hf - hf_fit.delay_s
    t_lf = t_lf - lf_fit.delay_s
    lo = max(t_lf[0], t[0])
    hi = min(t_lf[-1], t[-1])
    keep = np.flatnonzero((t_base >= lo) & (t_base <= hi))
    if keep.size < 16:
        raise ValueError(f"after alignment only {keep.size} samples overlap; the delays "
                         f"(HF {hf_fit.delay_s:.3g} s, LF {lf_fit.delay_s:.3g} s) leave no common record")
    i0, i1 = int(keep[0]), int(keep[-1]) + 1
    tb = t_base[i0:i1]
    aligned = {"t_s": tb, "hf": hf[i0:i1], "lf": resample(t_lf, lf, tb), "ref": resample(t, ref, tb)}
    aligned["hf_clean"] = hf_clean[i0:i1] if replaced[0] else aligned["hf"]
    aligned["lf_clean"] = resample(t_lf, lf_clean, tb) if replaced[1] else aligned["lf"]
    for name, fit in (("HF", hf_fit), ("LF", lf_fit)):
        if not math.isfinite(fit.residual) or fit.residual > 0.05:
            notes.append(f"{name} model misfit {fit.residual:.3g} (relative RMS over the tones): the fusion "
                         "will inherit it")
    return aligned, PairAlignment(hf_fit, lf_fit, clocks["hf"], clocks["lf"], i0, t.size - i1, tuple(notes),
                                  interval_mean, replaced)
