"""Spikes in one sensor's record, found without a model of the motion.

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
flagged, so ``z = Φ⁻¹(1 − false_alarm/(2n))`` (5.7 at n = 10⁵).  A bounded signal (a tone the
interpolator does not remove) stays below ``√2·1.4826·MAD``-ish and is never flagged.
Candidates within the interpolator's reach of each other form a cluster (a spike's neighbours see
``c_j`` of it, and two spikes a few samples apart add up); in each cluster the spikes are the set
of samples whose spikes, fitted jointly, leave the least residual sum of squares (the best one
and two by exhaustive search, more by forward selection, then swaps), each fitted size beyond
``z`` of its own standard deviations on noise alone; their fitted sizes are taken out of the
reading and the search repeated on the cleaned record.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.stats import norm

SPIKE_HALF_WIDTH = 8  # neighbours each side of the interpolator
SPIKE_BAND = 0.3  # ... exact (to 10⁻⁴) up to this fraction of the sample rate
SPIKE_FALSE_ALARM = 0.01  # chance that a spike-free Gaussian record has any sample flagged
MAX_FLAGGED = 2000  # a record with more "spikes" than this is not spiky but not what the detector assumes
MAX_ROUNDS = 6  # find–replace rounds (a spike hidden beside a larger one is found in the next)


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
                    noise_sd: float) -> tuple[list, np.ndarray]:
    """Spikes among samples ``lo … hi−1``: the support (set of spiked samples) whose spikes, fitted
    jointly by least squares on the residual rows they reach, leave the least sum of squares —
    the best one and the best two by exhaustive search (two spikes a few samples apart are best
    fitted by neither alone), more by greedy forward selection from there, then single swaps
    while they lower the sum — grown while the
    newest fitted size exceeds ``least``, then pruned of any whose size fell to ``least`` or
    below; returns the samples and their fitted sizes.  Growth stops once the rows' residual is
    down to what their noise alone leaves (twice its expected sum of squares)."""
    m = (kernel.size - 1) // 2
    rows = np.arange(max(lo - m, 0), min(hi + m, r.size))
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
    span = list(range(lo, hi))
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


@dataclass(frozen=True)
class SpikeSearch:
    """What :func:`find_spikes` found in one record.

    Attributes
    ----------
    index : ndarray of int
        The spiked samples, sorted.
    threshold_sigma : float
        The threshold, in robust standard deviations of the interpolation residual.
    scale : float
        That robust standard deviation (1.4826·MAD), in reading units.
    false_alarm : float
        The stated chance that a spike-free Gaussian record has any sample flagged.
    """

    index: np.ndarray
    threshold_sigma: float
    scale: float
    false_alarm: float

    def to_dict(self) -> dict:
        return {"count": int(self.index.size),
                "threshold_sigma": float(self.threshold_sigma) if math.isfinite(self.threshold_sigma) else None,
                "scale": float(self.scale), "false_alarm": float(self.false_alarm),
                "method": "interpolation residual beyond the threshold in robust σ (1.4826·MAD)"}


def find_spikes(y, false_alarm: float = SPIKE_FALSE_ALARM) -> tuple[np.ndarray, SpikeSearch]:
    """A record with its spikes replaced by the interpolation from their neighbours, and what was found.

    Spikes are found without a model of the motion (module docstring).

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
        The flagged samples' indices, the threshold and the residual's robust scale.

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
            chosen, size = _cluster_spikes(r, lo, hi, kernel, z, noise_sd)
            out[chosen] -= size
            found.extend(chosen)
            added += len(chosen)
        if not added:
            break
    index = np.unique(np.array(found, dtype=int))
    return out, SpikeSearch(index, z, scale, float(false_alarm))
