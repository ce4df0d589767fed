"""Spikes and dropouts in one sensor's record, found without a model of the motion.

A sensor's bandwidth sits well below its sample rate, so its reading is predicted from its
neighbours: a symmetric interpolator ``ŷ_k = Σ_j c_j (y_{k−j} + y_{k+j})``, ``j = 1…SPIKE_HALF_WIDTH``,
whose response ``2 Σ c_j cos(jθ)`` is 1 (to 10⁻⁴) up to ``SPIKE_BAND``·fs, takes out whatever
the motion is — tones, broadband vibration, steps slower than the band — and leaves the
*interpolation residual* ``y_k − ŷ_k``: the reading's noise (its own "innovation" given its
neighbours) and, whole, any one-sample outlier.  (The tone fit used with a reference,
:func:`~bench.analysis.fusion._metrics.without_outliers`, needs the motion to be its tones: on
random motion its residual is the motion.)

:func:`find_spikes`: a sample is a spike candidate if its residual exceeds ``z`` robust standard
deviations (1.4826·MAD of the residual: a few spikes do not move it); the ``SPIKE_HALF_WIDTH``
samples at each end, where the interpolator runs off the record, are not searched.  ``z`` follows
from a stated false-alarm rate: ``false_alarm`` (default :data:`SPIKE_FALSE_ALARM`, 1 %) is the
chance that a record of Gaussian noise (and Gaussian motion beyond the band) has *any* sample
flagged, so ``z = Φ⁻¹(1 − false_alarm/(2n))`` (5.7 at n = 10⁵).  What the interpolator leaves
of the motion (at most 10⁻⁴ of it below ``SPIKE_BAND``·fs) is bounded and adds to the noise's
residual: it moves the tail, and so the rate, only where the noise is as small as that leak.
Candidates within the interpolator's reach of each other form a cluster (a spike's neighbours see
``c_j`` of it, and two spikes a few samples apart add up); in each cluster the spikes are the set
of samples whose spikes, fitted jointly, leave the least residual sum of squares (the best one
and two by exhaustive search, more by forward selection, then swaps), each fitted size beyond
``z`` of its own standard deviations on noise alone; their fitted sizes are taken out of the
reading and the search repeated on the cleaned record.

**Runs** (a dropout: the reading falls to one value — zero, its offset — for a stretch, with its
own noise or none).  Inside a run the reading is flat, and a flat stretch is
motion the interpolator predicts: only the run's two edges, where the reading jumps, leave a
residual.  An edge is no spike (no few samples explain a jump between two levels, and which side
is the outlier cannot be told from one edge), so before the spikes are sought the candidates are
searched for runs: a stretch of at least two samples whose readings lie within ``z`` noise
standard deviations (``σ_n``, the reading's white noise: the residual's robust scale over the
interpolator's norm) of their median, with both neighbours on each side beyond that band (a
jump, not a smooth departure nor a lone spike beside a flat stretch), and

* *long*: the stretch between two clusters of candidates flat (the run's edges make the
  clusters, its interior — at least ``2·SPIKE_HALF_WIDTH`` samples, as clusters are that far
  apart — has no candidate), extended over the clusters' samples at the same level; or
* *short*: a flat stretch inside one cluster whose fill (below) leaves none of the cluster's
  residual beyond the threshold — a flat stretch beside a spike does not, since the spike stays.

A run is filled with the best linear prediction from ``RUN_NEIGHBOURS`` readings on each side
(kriging, the record's own autocovariance — its samples within reach of a candidate left out —
as the motion's statistics: no model of the motion, only its second moments): near its edges it
continues the motion, deep inside it falls back to the record's mean.  Like a spike, a run must
stand out: some reading of it beyond ``z`` of its prediction's own standard error (the motion's
own peak, which the interpolator passes a little of, is predicted by its neighbours and does
not).  Nothing in the search for runs looks at a record without candidates, so it leaves the
false-alarm rate as stated; a cluster that touches a run is then fitted by correcting the run's
samples only (never its neighbours: the fill's error at its edges is not a spike beside it).  A
run is not found — and its edges are fitted as spikes — where an edge lies in the record's
unsearched ends, does not jump beyond the band (the motion passing the run's level there, or a held
last value, whose start does not jump), or shares its cluster with a spike.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.stats import norm

SPIKE_HALF_WIDTH = 8  # neighbours each side of the interpolator
SPIKE_BAND = 0.3  # ... exact (to 10⁻⁴) up to this fraction of the sample rate
SPIKE_FALSE_ALARM = 0.01  # chance that a spike-free Gaussian record has any sample flagged
MAX_FLAGGED = 2000  # a record with more "spikes" than this is not spiky but not what the detector assumes
MAX_ROUNDS = 6  # find–replace rounds (a spike hidden beside a larger one is found in the next)
#: readings each side of a run that its fill is predicted from: four interpolator reaches, a few
#: periods of the fastest motion the interpolator passes (beyond, the prediction is the mean anyway)
RUN_NEIGHBOURS = 4 * SPIKE_HALF_WIDTH


def interpolator_taps(half_width: int = SPIKE_HALF_WIDTH, band: float = SPIKE_BAND) -> np.ndarray:
    """Taps ``c_1 … c_half_width`` of the symmetric interpolator (module docstring): least squares
    of ``2 Σ c_j cos(jθ) = 1`` over ``θ`` up to ``2π·band``."""
    theta = np.linspace(0.0, 2 * np.pi * band, 400)
    design = np.column_stack([2 * np.cos(j * theta) for j in range(1, half_width + 1)])
    return np.linalg.lstsq(design, np.ones_like(theta), rcond=None)[0]


def interpolation_residual(y, taps: np.ndarray | None = None) -> np.ndarray:
    """``y_k − Σ_j c_j (y_{k−j} + y_{k+j})`` (the ends, where the interpolator runs off the
    record, mirrored)."""
    c = interpolator_taps() if taps is None else np.asarray(taps, dtype=float)
    m = c.size
    y = np.asarray(y, dtype=float)
    padded = np.pad(y, m, mode="reflect")
    kernel = np.concatenate([-c[::-1], [1.0], -c])
    return np.convolve(padded, kernel, mode="valid")


def _cluster_spikes(r: np.ndarray, lo: int, hi: int, kernel: np.ndarray, z: float,
                    noise_sd: float, candidates: list | None = None) -> tuple[list, np.ndarray]:
    """Spikes among samples ``lo … hi−1`` (or among ``candidates``; the rows those samples reach):
    the support (set of spiked samples) whose spikes, fitted jointly by least squares on the
    residual rows they reach (not the rows that run off the record), leave the least sum of squares —
    the best one and the best two by exhaustive search (two spikes a few samples apart are best
    fitted by neither alone), more by greedy forward selection from there, then single swaps
    while they lower the sum — grown while the
    newest fitted size exceeds ``least``, then pruned of any whose size fell to ``least`` or
    below; returns the samples and their fitted sizes.  Growth stops once the rows' residual is
    down to what their noise alone leaves (twice its expected sum of squares)."""
    m = (kernel.size - 1) // 2
    rows = np.arange(max(lo - m, m), min(hi + m, r.size - m))  # rows that interpolate (not off the ends)
    target = r[rows]
    # the rows' residual from the reading's noise: r = M·n over the samples the rows reach
    reach = np.arange(rows[0] - m, rows[-1] + m + 1)
    gap_n = rows[:, None] - reach[None, :]
    noise_map = np.where(np.abs(gap_n) <= m, kernel[np.clip(gap_n + m, 0, 2 * m)], 0.0)

    def fit(cols: list) -> tuple[float, np.ndarray]:
        gap = rows[:, None] - np.asarray(cols)[None, :]
        k = np.where(np.abs(gap) <= m, kernel[np.clip(gap + m, 0, 2 * m)], 0.0)
        c = np.linalg.lstsq(k, target, rcond=None)[0]
        return float(np.sum((target - k @ c) ** 2)), c

    def z_of(cols: list) -> np.ndarray:
        """Each fitted size in its own standard deviations (noise alone: c = P·M·n)."""
        gap = rows[:, None] - np.asarray(cols)[None, :]
        k = np.where(np.abs(gap) <= m, kernel[np.clip(gap + m, 0, 2 * m)], 0.0)
        pm = np.linalg.pinv(k) @ noise_map
        return np.abs(np.linalg.lstsq(k, target, rcond=None)[0]) / (noise_sd * np.sqrt(np.sum(pm * pm, axis=1)))

    # what the rows hold of noise alone, with room: once the fit leaves no more, no spike is left
    quiet = 2.0 * float(np.sum(noise_map * noise_map)) * noise_sd ** 2
    span = list(range(lo, hi)) if candidates is None else list(candidates)
    best = min(([j] for j in span), key=lambda cols: fit(cols)[0])
    if z_of(best)[0] <= z:
        return [], np.zeros(0)
    pairs = [[i, j] for i in span for j in span if i < j]
    if pairs and fit(best)[0] > quiet:
        pair = min(pairs, key=lambda cols: fit(cols)[0])
        if np.min(z_of(pair)) > z:
            best = pair
            while len(best) < len(span) and fit(best)[0] > quiet:
                more = min(([*best, j] for j in span if j not in best), key=lambda cols: fit(cols)[0])
                if z_of(more)[-1] <= z:
                    break
                best = more
    for _ in range(len(span)):  # swap: a sample chosen early, before its neighbours, may be the wrong one
        rss = fit(best)[0]
        swaps = ([*best[:i], j, *best[i + 1:]] for i in range(len(best)) for j in span if j not in best)
        better = min(swaps, key=lambda cols: fit(cols)[0], default=None)
        if better is None or fit(better)[0] >= rss * (1 - 1e-9):
            break
        best = better
    while True:  # prune: a spike whose joint size fell to the noise is not one
        zs = z_of(best)
        weakest = int(np.argmin(zs))
        if zs[weakest] > z or len(best) == 1:
            return best, fit(best)[1]
        best = best[:weakest] + best[weakest + 1:]


def _autocovariance(y: np.ndarray, keep: np.ndarray, lags: int) -> tuple[np.ndarray, float]:
    """The record's autocovariance at lags ``0 … lags`` and its mean, from the samples ``keep``
    (the others set to the mean: the biased estimate, positive semi-definite)."""
    mean = float(np.mean(y[keep]))
    x = np.where(keep, y - mean, 0.0)
    nfft = 1 << int(math.ceil(math.log2(2 * y.size)))
    acov = np.fft.irfft(np.abs(np.fft.rfft(x, nfft)) ** 2, nfft)[:lags + 1] / max(int(np.count_nonzero(keep)), 1)
    return acov, mean


def _fill_run(y: np.ndarray, a: int, b: int, acov: np.ndarray, mean: float,
              usable: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Samples ``a … b−1`` predicted from up to :data:`RUN_NEIGHBOURS` usable readings each side
    (simple kriging with the autocovariance ``acov``: the best linear predictor of a stationary
    record; the noise is in ``acov[0]``, so the readings are not fitted exactly), and each
    prediction's standard error (reading units)."""
    p = RUN_NEIGHBOURS
    near = np.concatenate([np.arange(max(a - p, 0), a), np.arange(b, min(b + p, y.size))])
    near = near[usable[near]]
    if near.size == 0:
        return np.full(b - a, mean), np.full(b - a, math.sqrt(acov[0]))
    gap = np.arange(a, b)
    cross = acov[np.abs(near[:, None] - gap[None, :])]
    weights = np.linalg.lstsq(acov[np.abs(near[:, None] - near[None, :])], cross, rcond=None)[0]
    var = acov[0] - np.sum(weights * cross, axis=0)
    return mean + weights.T @ (y[near] - mean), np.sqrt(np.maximum(var, 0.0))


def _jumps_at_both_ends(y: np.ndarray, a: int, b: int, level: float, band: float) -> bool:
    """Both readings before ``a`` and both from ``b`` on lie beyond ``band`` of ``level``."""
    return (a >= 2 and b + 1 < y.size and min(abs(y[a - 1] - level), abs(y[a - 2] - level)) > band
            and min(abs(y[b] - level), abs(y[b + 1] - level)) > band)


def _find_runs(y: np.ndarray, r: np.ndarray, bad: np.ndarray, kernel: np.ndarray, z: float, scale: float,
               noise_sd: float) -> list:
    """Runs ``(start, stop)`` among the candidates ``bad`` of the residual ``r`` of ``y``, filled in
    ``y`` in place (module docstring, **Runs**)."""
    n, m = y.size, (kernel.size - 1) // 2
    band = z * noise_sd
    groups = np.split(bad, np.flatnonzero(np.diff(bad) > 2 * m) + 1)
    spans = [(max(int(g[0]) - m, m), min(int(g[-1]) + m + 1, n - m)) for g in groups]
    found: list = []  # (start, stop, the cluster a short run must explain, or None)
    for i in range(len(groups) - 1):  # long: the flat stretch between two clusters
        s, e = int(groups[i][-1]) + 1, int(groups[i + 1][0])
        level = float(np.median(y[s:e]))
        if np.max(np.abs(y[s:e] - level)) > band:
            continue
        while s > spans[i][0] and abs(y[s - 1] - level) <= band:
            s -= 1
        while e < spans[i + 1][1] and abs(y[e] - level) <= band:
            e += 1
        if _jumps_at_both_ends(y, s, e, level, band):
            found.append((s, e, None))
    for i, (lo, hi) in enumerate(spans):  # short: a flat stretch inside one cluster
        s = lo
        while s < hi - 1:
            e = s + 1
            while e < hi and np.ptp(y[s:e + 1]) <= 2 * band:
                e += 1
            if e - s < 2:
                s += 1
                continue
            level = float(np.median(y[s:e]))
            if (np.max(np.abs(y[s:e] - level)) <= band and _jumps_at_both_ends(y, s, e, level, band)
                    and not any(s < fb and fa < e for fa, fb, _ in found)):
                found.append((s, e, i))
            s = e
    if not found:
        return []
    keep = np.ones(n, dtype=bool)  # the motion's statistics from the samples no candidate reaches
    for lo, hi in spans:
        keep[max(lo - m, 0):hi + m] = False
    for s, e, _ in found:
        keep[s:e] = False
    if not keep.any():
        return []
    acov, mean = _autocovariance(y, keep, min(n - 1, max(e - s for s, e, _ in found) + 2 * RUN_NEIGHBOURS))
    usable = np.ones(n, dtype=bool)  # a long run is no neighbour of another (a short candidate may be motion)
    for s, e, cluster in found:
        if cluster is None:
            usable[s:e] = False

    def standing_out(s: int, e: int) -> float:
        """How far the candidate's most outlying reading is from its prediction, in the
        prediction's standard errors."""
        fill, fill_sd = _fill_run(y, s, e, acov, mean, usable)
        return float(np.max(np.abs(y[s:e] - fill) / np.maximum(fill_sd, 1e-300)))

    # the most outlying first, each filled before the next is judged (a stretch beside a filled run
    # is judged against the fill, not against the run it replaced)
    runs: list = []
    for s, e, cluster in sorted(found, key=lambda c: -standing_out(c[0], c[1])):
        level = float(np.median(y[s:e]))
        if any(s <= b and a <= e for a, b in runs) or not _jumps_at_both_ends(y, s, e, level, band):
            continue
        fill, fill_sd = _fill_run(y, s, e, acov, mean, usable)
        # a run, like a spike, must stand out: some reading beyond z of the prediction's own error
        if not np.any(np.abs(y[s:e] - fill) > z * fill_sd):
            continue
        if cluster is not None:  # a short run must explain its cluster: nothing left beyond the threshold
            lo, hi = spans[cluster]
            trial = y[max(lo - m, 0):min(hi + m, n)].copy()
            trial[s - max(lo - m, 0):e - max(lo - m, 0)] = fill
            if np.max(np.abs(np.convolve(trial, kernel, mode="valid"))) > z * scale:
                continue
        y[s:e] = fill
        usable[s:e] = False
        runs.append((s, e))
    return sorted(runs)


@dataclass(frozen=True)
class SpikeSearch:
    """What :func:`find_spikes` found in one record.

    Attributes
    ----------
    index : ndarray of int
        Every sample replaced — spikes and the samples of runs — sorted.
    threshold_sigma : float
        The threshold, in robust standard deviations of the interpolation residual.
    scale : float
        That robust standard deviation (1.4826·MAD), in reading units.
    false_alarm : float
        The stated chance that a spike-free Gaussian record has any sample flagged.
    runs : ndarray of int, shape (k, 2)
        Each run (a dropout: the reading flat between two jumps) replaced: its first sample and
        the sample after its last.
    """

    index: np.ndarray
    threshold_sigma: float
    scale: float
    false_alarm: float
    runs: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=int))

    def to_dict(self) -> dict:
        return {"count": int(self.index.size),
                "threshold_sigma": float(self.threshold_sigma) if math.isfinite(self.threshold_sigma) else None,
                "scale": float(self.scale), "false_alarm": float(self.false_alarm),
                "runs": [[int(a), int(b)] for a, b in self.runs],
                "method": "interpolation residual beyond the threshold in robust σ (1.4826·MAD); runs (flat between "
                          "two jumps) filled by kriging from their neighbours"}


def find_spikes(y, false_alarm: float = SPIKE_FALSE_ALARM) -> tuple[np.ndarray, SpikeSearch]:
    """A record with its spikes and dropouts replaced from their neighbours, and what was found.

    Spikes and runs (dropouts: the reading flat between two jumps) are found without a model of
    the motion (module docstring); a spike is replaced by the interpolation from its neighbours,
    a run by the prediction from the readings either side.

    Parameters
    ----------
    y : array_like, shape (n,)
        One sensor's readings, its output unit; finite, n > 2·``SPIKE_HALF_WIDTH``.
    false_alarm : float, default 0.01
        Chance that a spike-free record of Gaussian noise has any sample flagged, in (0, 1).

    Returns
    -------
    cleaned : ndarray, shape (n,)
        ``y`` with the flagged samples replaced.
    search : SpikeSearch
        The flagged samples' indices, the runs, the threshold and the residual's robust scale.

    Raises
    ------
    ValueError
        If ``y`` is not finite, too short, or ``false_alarm`` is outside (0, 1).

    Examples
    --------
    Broadband motion (a random walk, smoothed) with white noise and three spikes:

    >>> import numpy as np
    >>> from bench.analysis.fusion import find_spikes
    >>> rng = np.random.default_rng(0)
    >>> motion = np.convolve(np.cumsum(rng.standard_normal(20019)), np.ones(20) / 20, mode="valid")
    >>> y = motion + 0.01 * rng.standard_normal(motion.size)
    >>> y[[500, 501, 9000]] += [3.0, -2.0, 5.0]
    >>> cleaned, search = find_spikes(y)
    >>> search.index.tolist()
    [500, 501, 9000]
    >>> bool(np.max(np.abs(cleaned - motion)) < 0.1)
    True

    A dropout — the reading at zero for 6 samples — is one run, every sample of it replaced:

    >>> y[15000:15006] = 0.0
    >>> cleaned, search = find_spikes(y)
    >>> search.runs.tolist(), search.index.size
    ([[15000, 15006]], 9)
    >>> bool(np.max(np.abs(cleaned - motion)) < 0.5)
    True
    """
    y = np.asarray(y, dtype=float).ravel()
    taps = interpolator_taps()
    m = taps.size
    if y.size <= 2 * m or not np.all(np.isfinite(y)):
        raise ValueError(f"y must hold more than {2 * m} finite samples (has {y.size})")
    if not (math.isfinite(false_alarm) and 0 < false_alarm < 1):
        raise ValueError(f"false_alarm {false_alarm} must be in (0, 1)")
    z = float(norm.isf(false_alarm / (2 * y.size)))
    kernel = np.concatenate([-taps[::-1], [1.0], -taps])
    r = interpolation_residual(y, taps)
    scale = 1.4826 * float(np.median(np.abs(r - np.median(r))))  # the spikes are too few to move the MAD
    noise_sd = scale / float(np.linalg.norm(kernel))  # the reading's white noise, from the residual's
    out = y.copy()
    found: list = []
    runs: list = []
    big = np.abs(r) > z * scale
    big[:m] = big[-m:] = False
    bad = np.flatnonzero(big)
    if scale > 0 and 0 < bad.size <= MAX_FLAGGED:
        runs = _find_runs(out, r, bad, kernel, z, scale, noise_sd)
        if runs:  # a run's rows are not the reading's noise (a run without noise would shrink the scale)
            noise_rows = np.ones(y.size, dtype=bool)
            for a, b in runs:
                found.extend(range(a, b))
                noise_rows[max(a - m, 0):b + m] = False
            if np.count_nonzero(noise_rows) > y.size // 2:
                scale = 1.4826 * float(np.median(np.abs(r[noise_rows] - np.median(r[noise_rows]))))
                noise_sd = scale / float(np.linalg.norm(kernel))
    for _ in range(MAX_ROUNDS):
        r = interpolation_residual(out, taps)
        big = np.abs(r) > z * scale
        big[:m] = big[-m:] = False  # where the interpolator runs off the record it does not interpolate
        bad = np.flatnonzero(big)
        if scale <= 0 or bad.size == 0 or bad.size > MAX_FLAGGED:
            break
        added = 0
        # samples closer than twice the interpolator's reach share residual rows: one cluster
        for group in np.split(bad, np.flatnonzero(np.diff(bad) > 2 * m) + 1):
            lo, hi = max(int(group[0]) - m, m), min(int(group[-1]) + m + 1, y.size - m)
            # beside a run, what is left is its fill's error: the run's samples are corrected, not its neighbours
            inside = [k for a, b in runs for k in range(max(a, lo - m), min(b, hi + m))]
            chosen, size = _cluster_spikes(r, lo, hi, kernel, z, noise_sd, inside or None)
            out[chosen] -= size
            found.extend(chosen)
            added += len(chosen)
        if not added:
            break
    index = np.unique(np.array(found, dtype=int))
    return out, SpikeSearch(index, z, scale, float(false_alarm), np.array(runs, dtype=int).reshape(-1, 2))
