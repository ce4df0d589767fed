"""Relative clock skew and delay of an HF/LF pair from their cross-spectrum: no reference, any motion.

Two sensors that read the same rate through their models ``G_h``, ``G_l`` have the
cross-spectrum ``S_hl(f) = G_h(f)·G_l*(f)·S_ω(f)·e^{i2πf·d}``, ``d`` how much later the LF
sensor reads than the HF one.  Whatever the motion — tones or broadband (a random profile) — the
phase of ``S_hl`` less the models' phases is ``2πf·d`` wherever both sensors see it.  If the LF
clock runs off the HF one by ``ε`` (its sample ``k``, stamped ``k/fs``, really taken at
``(1+ε)·k/fs``), ``d`` drifts: ``d(t) = d₀ − ε·t``.  So (:func:`estimate_relative_timing`):

1. the record is cut into ``TIMING_BLOCKS`` blocks; in each, Welch's cross-spectrum and
   coherence ``γ²`` (Hann segments, half overlap) over the *overlap band* — every bin where
   ``γ²`` exceeds what noise alone gives (:data:`COHERENCE_FALSE_ALARM`): the sensors' common
   motion;
2. each bin's phase less the models' phases, weighted by its inverse variance
   ``2K·γ²/(1−γ²)`` (Bendat & Piersol, *Random Data*, 4th ed., §9.2.4: K averaged segments,
   halved here for the segments' overlap);
3. a delay for the whole record by the weighted phasor sum over a grid of delays within
   ± half the Welch segment's length and ``MAX_DELAY_S`` (no phase unwrapping: the largest sum
   wins; the sum repeats every segment length) — a half turn common to all bins at that delay is
   a gain of the wrong sign, not a delay, and is taken out — then each block's delay refined by
   weighted least squares of its residual phase against ``2πf`` (standard error from the weights);
4. the blocks' delays against their mid times by weighted least squares: ``d₀`` (at the
   record's middle) and ``ε``, the standard errors inflated by √(χ²/dof) when the blocks
   scatter more than their weights say (an unmodelled drift, model error);
5. the LF record put on the HF clock by that first estimate (:func:`align_relative`'s
   band-limited resampling, significant or not) and steps 1–4 repeated on the aligned pair:
   what they find is added to the first estimate, with their standard errors.  A Welch
   estimate is the cross-spectrum smoothed over a bin; where the phase slopes (a delay) while
   the magnitude falls (a sensor's roll-off, the motion's band edge) the smoothed phase is
   biased toward a smaller delay, by many standard errors where the coherence is high.  On the
   aligned pair the delay's slope is gone; what is left — the models' own phase curvature
   under the smoothing — grows as the bin width squared, so steps 1–4 once more with segments
   half as long quadruple it: a third of the change of the delay is the bias left at full
   resolution (Richardson), and it joins the delay's standard error in quadrature.

:func:`align_relative` then puts the LF record on the HF clock (band-limited resampling,
:func:`~bench.analysis.frf.resample`): the skew and the delay are corrected only where
significant — beyond ``TIMING_SIGNIFICANCE`` standard errors (a false alarm rate of 0.27 % for a
normal estimate: correcting noise would add a drift).  The delay ``d`` is relative to the models:
a model's phase error that is linear in frequency is indistinguishable from a delay.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.signal import csd, welch

from bench.analysis.frf import resample
from bench.analysis.fusion._models import SensorModel

TIMING_BLOCKS = 8  # blocks the record is cut into for the drift of the delay (≥ 3 for a line and its scatter)
SEGMENTS_PER_BLOCK = 8  # Welch segments (half overlap) per block at least
COHERENCE_FALSE_ALARM = 1e-3  # a bin counts as common motion if noise alone reaches its coherence this rarely
TIMING_SIGNIFICANCE = 3.0  # skew and delay are corrected only beyond this many standard errors (0.27 %)
MAX_DELAY_S = 0.05  # the delay grid searched: ± this (s); a larger skew·duration is not a clock error
MIN_BINS = 3  # a block needs this many coherent bins for a delay


@dataclass(frozen=True)
class RelativeTiming:
    """The LF sensor's clock and delay relative to the HF sensor's (module docstring).

    Attributes
    ----------
    skew_ppm : float
        LF clock rate error relative to the HF clock, in ppm (positive: its samples are taken
        later and later); NaN where it could not be measured.
    skew_std_ppm : float
        Its standard error, in ppm.
    delay_s : float
        How much later the LF sensor reads than the HF one at ``epoch_s``, beyond the models'
        phases, in s.
    delay_std_s : float
        Its standard error, in s, the bias the spectral resolution leaves included (step 5).
    epoch_s : float
        Time at which ``delay_s`` holds (the record's middle), in s of the time column.
    band_hz : tuple of float
        Lowest and highest frequency of the bins used, in Hz.
    n_bins : int
        Coherent bins used over all blocks.
    n_blocks : int
        Blocks with a delay.
    chi2_reduced : float
        Scatter of the blocks' delays about the line, per degree of freedom.
    skew_corrected : bool
        Whether :func:`align_relative` corrects the skew (significant).
    delay_corrected : bool
        Whether it corrects the delay (significant).
    """

    skew_ppm: float
    skew_std_ppm: float
    delay_s: float
    delay_std_s: float
    epoch_s: float
    band_hz: tuple
    n_bins: int
    n_blocks: int
    chi2_reduced: float
    skew_corrected: bool
    delay_corrected: bool

    def to_dict(self) -> dict:
        return {"skew_ppm": _num(self.skew_ppm), "skew_std_ppm": _num(self.skew_std_ppm),
                "delay_s": _num(self.delay_s), "delay_std_s": _num(self.delay_std_s), "epoch_s": float(self.epoch_s),
                "band_hz": [_num(v) for v in self.band_hz], "n_bins": int(self.n_bins),
                "n_blocks": int(self.n_blocks), "chi2_reduced": _num(self.chi2_reduced),
                "skew_corrected": bool(self.skew_corrected), "delay_corrected": bool(self.delay_corrected),
                "method": "cross-spectrum phase of the two sensors in their coherent band, per block"}


def _num(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None


def _coherence_floor(n_avg: float) -> float:
    """Coherence that two independent noises exceed with probability :data:`COHERENCE_FALSE_ALARM`
    after ``n_avg`` independent averages: ``1 − p^{1/(n−1)}`` (Bendat & Piersol §9.2.3)."""
    return 1.0 - COHERENCE_FALSE_ALARM ** (1.0 / max(n_avg - 1.0, 1.0))


def _segment(rate_hz: float, n_block: int, hf_model: SensorModel, lf_model: SensorModel) -> int:
    """Welch segment: a resolution of an eighth of the corners' geometric mean if the block holds
    ``SEGMENTS_PER_BLOCK`` such segments, else as long as it does (a power of two ≥ 64)."""
    want = 8 * rate_hz / math.sqrt(hf_model.corner_hz * lf_model.corner_hz)
    most = 2 * n_block / (SEGMENTS_PER_BLOCK + 1)
    return int(2 ** max(6, math.floor(math.log2(max(min(want, most), 64)))))


def estimate_relative_timing(hf, lf, rate_hz: float, hf_model: SensorModel, lf_model: SensorModel, *,
                             t0_s: float = 0.0) -> RelativeTiming:
    """The LF sensor's clock skew and delay relative to the HF sensor's, from their cross-spectrum.

    Any common motion will do — broadband or tones — (module docstring); no reference is used.

    Parameters
    ----------
    hf, lf : array_like, shape (n,)
        The two sensors' readings on one nominal time grid, their output units; finite.
    rate_hz : float
        Sample rate, in Hz; finite and > 0.
    hf_model, lf_model : SensorModel
        The sensors' models: their phases are taken out of the cross-spectrum.
    t0_s : float, default 0.0
        Time of the first sample, in s (for ``epoch_s``).

    Returns
    -------
    RelativeTiming
        Skew (ppm) and delay (s) with standard errors; NaN skew where fewer than three blocks
        held a coherent band.

    Raises
    ------
    ValueError
        If the series differ in length or hold a non-finite value, or ``rate_hz`` is not a
        finite value > 0.

    Examples
    --------
    Broadband motion read by a 1 Hz high-pass and a 40 Hz low-pass whose clock is 50 ppm slow and
    which reads 0.5 ms late:

    >>> import numpy as np
    >>> from scipy.signal import bilinear, lfilter
    >>> from bench.analysis.fusion import SensorModel, estimate_relative_timing
    >>> fs, n = 2000.0, 40000
    >>> rng = np.random.default_rng(1)
    >>> fine = np.cumsum(rng.standard_normal(8 * n + 800)) * 0.01  # the motion at 8× the rate
    >>> fine -= np.convolve(fine, np.ones(401) / 401, mode="same")  # no drift below 2 Hz·8
    >>> tf = np.arange(fine.size) / (8 * fs) - 0.05
    >>> t = np.arange(n) / fs
    >>> hf_m, lf_m = SensorModel("highpass", 1, 1.0), SensorModel("lowpass", 1, 40.0)
    >>> def read(model, instants):
    ...     b, a = bilinear(*((([1 / (2 * np.pi * model.corner_hz), 0], [1 / (2 * np.pi * model.corner_hz), 1])
    ...                       if model.kind == "highpass" else ([1], [1 / (2 * np.pi * model.corner_hz), 1]))),
    ...                     8 * fs)
    ...     return np.interp(instants, tf, lfilter(b, a, fine)) + 1e-3 * rng.standard_normal(instants.size)
    >>> hf, lf = read(hf_m, t), read(lf_m, t * (1 + 50e-6) - 5e-4)
    >>> timing = estimate_relative_timing(hf, lf, fs, hf_m, lf_m)
    >>> abs(timing.skew_ppm - 50) < 3 * timing.skew_std_ppm, timing.skew_corrected
    (True, True)
    """
    hf = np.asarray(hf, dtype=float).ravel()
    lf = np.asarray(lf, dtype=float).ravel()
    if hf.size != lf.size or not (np.all(np.isfinite(hf)) and np.all(np.isfinite(lf))):
        raise ValueError(f"hf ({hf.size}) and lf ({lf.size}) must be finite series of one length")
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise ValueError(f"rate_hz {rate_hz} must be a finite value > 0")
    first = _one_pass(hf, lf, rate_hz, hf_model, lf_model, t0_s, 1)
    if first.n_blocks == 0:
        return first
    # 5. the pair put on one clock by the first estimate, and the rest measured at two resolutions
    t = t0_s + np.arange(hf.size) / rate_hz
    on_one_clock = replace(first, skew_corrected=math.isfinite(first.skew_ppm), delay_corrected=True)
    try:
        part, lf_aligned = align_relative(t, lf, on_one_clock, rate_hz)
    except ValueError:  # too little overlap left to refine on
        return first
    t0_rest = float(t[part][0])
    rest = _one_pass(hf[part], lf_aligned, rate_hz, hf_model, lf_model, t0_rest, 1, aligned=True)
    coarse = _one_pass(hf[part], lf_aligned, rate_hz, hf_model, lf_model, t0_rest, 2, aligned=True)
    if rest.n_blocks == 0 or coarse.n_blocks == 0:
        return first

    def at_epoch(timing: RelativeTiming) -> float:  # its delay at the first pass's epoch
        skew = timing.skew_ppm * 1e-6 if math.isfinite(timing.skew_ppm) else 0.0
        return timing.delay_s - skew * (first.epoch_s - timing.epoch_s)

    d0 = first.delay_s + at_epoch(rest)
    # the smoothing bias grows as the bin width squared: halving the segment quadruples it, so a
    # third of the change is the bias left at full resolution (Richardson); it joins the error
    bias = (at_epoch(coarse) - at_epoch(rest)) / 3
    sd0 = math.hypot(rest.delay_std_s, bias)
    if math.isfinite(first.skew_ppm) and math.isfinite(rest.skew_ppm):
        eps_ppm, sde_ppm = first.skew_ppm + rest.skew_ppm, rest.skew_std_ppm
    else:
        eps_ppm, sde_ppm = first.skew_ppm, first.skew_std_ppm
    skew_ok = math.isfinite(eps_ppm) and math.isfinite(sde_ppm)
    return RelativeTiming(eps_ppm, sde_ppm, d0, sd0, first.epoch_s, rest.band_hz, rest.n_bins, rest.n_blocks,
                          rest.chi2_reduced, skew_ok and abs(eps_ppm) > TIMING_SIGNIFICANCE * sde_ppm,
                          abs(d0) > TIMING_SIGNIFICANCE * sd0)


def _one_pass(hf: np.ndarray, lf: np.ndarray, rate_hz: float, hf_model: SensorModel, lf_model: SensorModel,
              t0_s: float, coarsen: int, aligned: bool = False) -> RelativeTiming:
    """Steps 1–4 of the module docstring on one pair, the Welch segment ``coarsen`` times shorter
    than :func:`_segment` gives; an ``aligned`` pair (put on one clock already) skips the grid of
    step 3: what is left of its delay is a fraction of a sample."""
    n = hf.size
    bounds = np.linspace(0, n, TIMING_BLOCKS + 1).astype(int)
    nper = max(_segment(rate_hz, int(np.diff(bounds).min()), hf_model, lf_model) // coarsen, 32)
    blocks = []  # (mid time, frequencies, phase less the models', weights)
    for i0, i1 in zip(bounds[:-1], bounds[1:]):
        if i1 - i0 < 2 * nper:
            continue
        kw = {"fs": rate_hz, "nperseg": nper, "noverlap": nper // 2, "window": "hann", "detrend": "constant"}
        f, s_hl = csd(hf[i0:i1], lf[i0:i1], **kw)
        s_hh, s_ll = welch(hf[i0:i1], **kw)[1], welch(lf[i0:i1], **kw)[1]
        n_avg = max((i1 - i0 - nper) // (nper // 2) + 1, 1) / 2  # half-overlapped segments count half
        with np.errstate(divide="ignore", invalid="ignore"):
            coh = np.abs(s_hl) ** 2 / (s_hh * s_ll)
        use = (f > 0) & np.isfinite(coh) & (coh > _coherence_floor(n_avg)) & (coh < 1)
        if use.sum() < MIN_BINS:
            continue
        # csd(x, y) is conj(X)·Y, whose phase is arg G_l − arg G_h − 2πf·d
        phase = np.angle(np.conj(s_hl[use]) * lf_model.response(f[use]) * np.conj(hf_model.response(f[use])))
        weight = 2 * n_avg * coh[use] / (1 - coh[use])
        blocks.append((t0_s + (0.5 * (i0 + i1) - 0.5) / rate_hz, f[use], phase, weight))
    epoch = t0_s + 0.5 * (n - 1) / rate_hz
    if not blocks:
        return RelativeTiming(math.nan, math.nan, 0.0, math.inf, epoch, (math.nan, math.nan), 0, 0, math.nan,
                              False, False)
    f_all = np.concatenate([b[1] for b in blocks])
    ph_all = np.concatenate([b[2] for b in blocks])
    w_all = np.concatenate([b[3] for b in blocks])
    # the record's delay: the weighted phasor sum over a grid fine enough that its step turns the
    # highest bin by at most 0.1 rad, then the per-block refinement below
    # (the sum repeats every 1/Δf, Δf the bins' spacing: the grid spans one period at most)
    phasor = w_all * np.exp(1j * ph_all)
    d_rec = 0.0
    if not aligned:
        step = 0.1 / (2 * np.pi * f_all.max())
        reach = min(MAX_DELAY_S, 0.5 * nper / rate_hz)
        grid = np.arange(-reach, reach + step, step)
        d_rec = float(grid[int(np.argmax(_grid_scores(phasor, f_all, grid)))])
    # a gain of the wrong sign turns every bin by π: that is not a delay (any other phase common to
    # the bins — a model's phase error — goes into the delay with the models' other errors)
    common = math.pi * round(float(np.angle(np.sum(phasor * np.exp(-2j * np.pi * f_all * d_rec)))) / math.pi)
    mids, delays, sds = [], [], []
    for mid, f, ph, w in blocks:
        d = d_rec
        for _ in range(2):  # refine on the wrapped residual: small once d is near
            resid = np.angle(np.exp(1j * (ph - common - 2 * np.pi * f * d)))
            x = 2 * np.pi * f
            d += float(np.sum(w * x * resid) / np.sum(w * x * x))
        mids.append(mid)
        delays.append(d)
        sds.append(1.0 / math.sqrt(float(np.sum(w * (2 * np.pi * f) ** 2))))
    mids_a, d_a, sd_a = np.array(mids), np.array(delays), np.array(sds)
    band = (float(f_all.min()), float(f_all.max()))
    wb = 1.0 / sd_a ** 2
    if mids_a.size < 3:  # a delay, no skew
        d0 = float(np.sum(wb * d_a) / np.sum(wb))
        sd0 = float(1 / math.sqrt(np.sum(wb)))
        return RelativeTiming(math.nan, math.nan, d0, sd0, epoch, band, int(f_all.size), int(mids_a.size), math.nan,
                              False, abs(d0) > TIMING_SIGNIFICANCE * sd0)
    x = mids_a - epoch
    design = np.column_stack([np.ones_like(x), -x])
    cov = np.linalg.inv(design.T @ (wb[:, None] * design))
    coef = cov @ design.T @ (wb * d_a)
    chi2_red = float(np.sum(wb * (d_a - design @ coef) ** 2) / (mids_a.size - 2))
    cov = cov * max(1.0, chi2_red)
    d0, eps = float(coef[0]), float(coef[1])
    sd0, sde = math.sqrt(cov[0, 0]), math.sqrt(cov[1, 1])
    return RelativeTiming(eps * 1e6, sde * 1e6, d0, sd0, epoch, band, int(f_all.size), int(mids_a.size), chi2_red,
                          abs(eps) > TIMING_SIGNIFICANCE * sde, abs(d0) > TIMING_SIGNIFICANCE * sd0)


def _grid_scores(phasor: np.ndarray, f: np.ndarray, grid: np.ndarray) -> np.ndarray:
    out = np.empty(grid.size)
    for chunk in np.array_split(np.arange(grid.size), max(1, grid.size // 256)):
        out[chunk] = np.abs(np.exp(-2j * np.pi * np.outer(grid[chunk], f)) @ phasor)
    return out


def align_relative(t_s, lf, timing: RelativeTiming, rate_hz: float) -> tuple[slice, np.ndarray]:
    """The LF record on the HF sensor's clock: its samples' instants moved by the significant part
    of ``timing`` (skew, delay) and resampled (band-limited) at the HF instants ``t_s``; the ends
    that would need extrapolation dropped.  Returns the kept slice of ``t_s`` and the LF there."""
    t = np.asarray(t_s, dtype=float)
    lf = np.asarray(lf, dtype=float)
    eps = timing.skew_ppm * 1e-6 if timing.skew_corrected else 0.0
    d0 = timing.delay_s if timing.delay_corrected else 0.0
    if eps == 0.0 and d0 == 0.0:
        return slice(0, t.size), lf
    # the LF sample stamped t is read when the HF one stamped t − d(t) is, d(t) = d0 − ε(t − epoch)
    t_lf = t - (d0 - eps * (t - timing.epoch_s))
    keep = np.flatnonzero((t >= t_lf[0]) & (t <= t_lf[-1]))
    if keep.size < 16:
        raise ValueError(f"after the LF delay {d0:.3g} s and skew {eps * 1e6:.3g} ppm only {keep.size} samples "
                         "overlap")
    part = slice(int(keep[0]), int(keep[-1]) + 1)
    return part, resample(t_lf, lf, t[part])
