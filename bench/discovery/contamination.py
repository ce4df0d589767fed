"""Contamination in the observation model: isolated outliers, found and set aside, never named.

A real record carries spikes (a bad frame, an EMI hit) and heavy-tailed white noise. In the
model they are part of the observation noise, not a structure: a sample is an **outlier** when
its departure from the mean of its two neighbours, ``d_i = y_i − (y_{i−1} + y_{i+1})/2`` (a
slow process or a smooth term cancels; on white Gaussian noise ``d`` is exactly Gaussian, of
variance 1.5 σ²), is the largest of its three and exceeds what that Gaussian of the record's
robust scale (1.4826 · MAD of ``d``) reaches with probability ``alpha`` anywhere in the record —
the threshold ``Φ⁻¹(1 − α/(2n))`` (Bonferroni over the n samples), so on a clean Gaussian record
nothing is flagged with probability ≥ 1 − α. A spike of size A leaves −A/2 at its neighbours:
only the largest is the outlier.

The flagged samples are left out of the likelihood (missing observations of the Kalman
filter) and replaced by the running median in the readings the deterministic fits see; the
report says how many and which share ("9 % of samples are outliers; robust fit used").
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import median_filter
from scipy.stats import norm

from bench.discovery.data import Record

#: Running-median window (samples): wider than a spike of two samples, narrow enough to follow
#: a level step within two samples.
WINDOW = 5

#: Per-record false-alarm rate of the outlier test on a clean Gaussian record.
FALSE_ALARM = 0.01


@dataclass(frozen=True)
class Contamination:
    """The outliers of a record: their mask, the threshold (robust z) and the scale."""

    outlier: np.ndarray = field(repr=False)
    threshold_z: float
    scale: float

    @property
    def count(self) -> int:
        return int(np.count_nonzero(self.outlier))

    @property
    def fraction(self) -> float:
        return float(self.count / max(self.outlier.size, 1))

    def describe(self) -> str:
        """One line for the report (empty when nothing was flagged)."""
        if not self.count:
            return ""
        return (f"{self.count} samples ({100 * self.fraction:.2g} %) are isolated outliers (beyond "
                f"{self.threshold_z:.2f} robust σ of their running median, a {100 * FALSE_ALARM:g} % per-record "
                "false-alarm rate on Gaussian noise): left out of the likelihood — robust fit used")


def find_outliers(y: np.ndarray, alpha: float = FALSE_ALARM) -> Contamination:
    """The isolated outliers of the series ``y`` (module docstring). ValueError for ``alpha``
    outside (0, 1) or fewer than ``WINDOW`` samples."""
    y = np.asarray(y, dtype=float)
    if not 0 < alpha < 1:
        raise ValueError(f"alpha = {alpha!r}; allowed: (0, 1)")
    if y.size < WINDOW:
        raise ValueError(f"{y.size} samples; allowed: at least {WINDOW}")
    d = np.zeros(y.size)
    d[1:-1] = y[1:-1] - 0.5 * (y[:-2] + y[2:])
    inner = d[1:-1]
    mad = float(np.median(np.abs(inner - np.median(inner))))
    scale = 1.4826 * mad
    if not scale > 0:  # readings on a coarse lattice: most departures are exactly 0
        return Contamination(np.zeros(y.size, bool), math.inf, 0.0)
    z = float(norm.isf(alpha / (2 * y.size)))
    a = np.abs(d - np.median(inner))
    a[0] = a[-1] = 0.0  # the ends have one neighbour: not judged
    peak = np.ones(y.size, bool)
    peak[1:] &= a[1:] >= a[:-1]
    peak[:-1] &= a[:-1] >= a[1:]
    return Contamination((a > z * scale) & peak, z, scale)


def cleaned(rec: Record, c: Contamination, prediction: np.ndarray | None = None) -> Record:
    """``rec`` with its outliers replaced by ``prediction`` (what a model predicts there; default
    0) plus the running median of the residual around them — what the deterministic fits see;
    ``rec`` itself when there are none."""
    if not c.count:
        return rec
    base = np.zeros(rec.n) if prediction is None else np.asarray(prediction, float)
    r = rec.y - base
    y = rec.y.copy()
    # the median of five is robust to two outliers in its window
    y[c.outlier] = base[c.outlier] + median_filter(r, size=WINDOW, mode="nearest")[c.outlier]
    return rec.replace(y=y)
