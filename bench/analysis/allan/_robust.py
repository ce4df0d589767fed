"""Isolated outliers (spikes) of a rate record, found at a stated false-alarm rate and replaced.

Test.  Each sample is compared with the median of its ``2·HALF_WINDOW`` neighbours (the
sample itself left out, so that a spike does not pull its own reference): the residual
``e = y − median(neighbours)``, scaled by ``s = 1.4826·MAD(e)`` (the normal-consistent
median absolute deviation, unaffected by up to half the samples being outliers).  For
Gaussian noise ``e/s`` is close to standard normal (the neighbour median is independent of
the sample, so tail and core of ``e`` share one scale).  A sample is flagged when
``|e| > z·s`` with ``z`` the normal quantile at ``1 − false_alarm/(2n)``: a two-sided
Bonferroni bound at ``false_alarm/n`` per sample, so that a clean record of ``n`` samples
has at least one false flag with probability ≤ ``false_alarm`` (default 1 %).  As ``s`` is
estimated, ``z`` is taken as the Student quantile with the MAD's degrees of freedom,
``n/(2·1.36)`` (a MAD is as uncertain as a standard deviation from 0.37·n samples).

Replacement.  A flagged sample takes the value of its neighbour median: the local level,
which keeps a wandering bias (rate random walk, flicker) and removes the spike.  The
sample's own white part is lost and the local level is counted twice, so a record with a
fraction ``f`` replaced has its Allan variance off by about ``f`` (relative) at short τ —
low at τ0, high by a similar amount at τ ≫ the window — which is small beside what the
spikes do (their variance enters every τ).

Pure: arrays in, a frozen dataclass out.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from bench.analysis.allan._stats import upper_normal_quantile

#: neighbours each side: with an outlier fraction ≤ 20 %, 10 neighbours hold a clean majority
#: (≥ 6 clean) with probability 1 − P(Binom(10, 0.2) ≥ 5) = 97 %; and a bias wandering over
#: more than 10 samples is followed
HALF_WINDOW = 5
MAD_TO_SIGMA = 1.482602218505602  # 1/Φ⁻¹(3/4): MAD of a normal sample → its σ
#: n·var(1.4826·MAD)/σ² for a normal sample (asymptotic, Hampel): 1.36, so the scale is as
#: uncertain as a standard deviation with n/(2·1.36) degrees of freedom
MAD_DOF_PER_SAMPLE = 1.0 / (2.0 * 1.3605)
DEFAULT_FALSE_ALARM = 0.01
_CHUNK = 1 << 16


@dataclass(frozen=True, eq=False)
class OutlierScreen:
    """Isolated outliers of a rate record and the record with them replaced.

    Returned by :func:`screen_outliers` (module docstring for the test).

    Attributes
    ----------
    cleaned : ndarray of float, shape (n,)
        The record with each flagged sample replaced by the median of its neighbours, in
        the record's unit.
    flagged : ndarray of int, shape (k,)
        Indices of the flagged samples, increasing.
    threshold : float
        The normal quantile ``z`` a scaled residual must exceed (dimensionless).
    scale : float
        ``1.4826·MAD`` of the residuals from the neighbour median, in the record's unit
        (0 when more than half the residuals are 0: then nothing is flagged).
    false_alarm : float
        Probability that a clean Gaussian record has at least one flag, as asked for.
    n_samples : int
        Samples screened.
    n_flagged : int
        Property: number of flagged samples.
    fraction : float
        Property: ``n_flagged / n_samples``.

    Examples
    --------
    >>> import numpy as np
    >>> from bench.analysis.allan import screen_outliers
    >>> y = np.random.default_rng(0).normal(0.0, 1.0, 10_000)
    >>> y[[100, 5000]] += 40.0
    >>> s = screen_outliers(y)
    >>> s.flagged.tolist(), round(s.threshold, 2)
    ([100, 5000], 4.9)
    """

    cleaned: np.ndarray
    flagged: np.ndarray
    threshold: float
    scale: float
    false_alarm: float
    n_samples: int

    @property
    def n_flagged(self) -> int:
        """Number of flagged samples."""
        return int(self.flagged.size)

    @property
    def fraction(self) -> float:
        """Fraction of the samples flagged (0 … 1)."""
        return self.n_flagged / self.n_samples if self.n_samples else 0.0

    def summary(self) -> str:
        """One line for a report: how many samples were replaced and at what false-alarm rate."""
        return (f"{self.fraction:.1%} of samples are outliers ({self.n_flagged} of {self.n_samples}, "
                f"|y − neighbour median| > {self.threshold:.2f}·1.4826·MAD, false-alarm probability "
                f"{self.false_alarm:g} per record); robust estimate used")

    def to_dict(self) -> dict:
        return {"n_flagged": self.n_flagged, "fraction": self.fraction, "threshold_sigma": self.threshold,
                "scale": self.scale, "false_alarm": self.false_alarm, "n_samples": self.n_samples,
                "method": "|y - median of 10 neighbours| > z * 1.4826 MAD, z = normal quantile at "
                          "1 - false_alarm/(2n); flagged samples replaced by the neighbour median"}


def student_quantile(z: float, dof: float) -> float:
    """Student-t quantile with ``dof`` degrees of freedom at the normal quantile ``z``
    (Cornish–Fisher, two terms; relative error < 1e-3 for dof ≥ 20)."""
    return z + (z ** 3 + z) / (4.0 * dof) + (5 * z ** 5 + 16 * z ** 3 + 3 * z) / (96.0 * dof ** 2)


def neighbour_median(y: np.ndarray) -> np.ndarray:
    """Median of the ``2·HALF_WINDOW`` neighbours of each sample (mirrored at the ends), itself left out."""
    h = HALF_WINDOW
    padded = np.pad(y, h, mode="reflect") if y.size > h else np.pad(y, h, mode="edge")
    keep = np.r_[0:h, h + 1:2 * h + 1]
    out = np.empty(y.size)
    for s in range(0, y.size, _CHUNK):  # chunks: the window copy stays in cache, not n × 10 floats
        e = min(s + _CHUNK, y.size)
        windows = sliding_window_view(padded[s:e + 2 * h], 2 * h + 1)[:, keep]
        out[s:e] = np.median(windows, axis=1)
    return out


def screen_outliers(y, false_alarm: float = DEFAULT_FALSE_ALARM) -> OutlierScreen:
    """Flag isolated outliers of a rate record at a stated false-alarm rate and replace them.

    A sample is an outlier when its distance from the median of its 10 neighbours exceeds
    ``z·1.4826·MAD`` of those distances, ``z`` the normal quantile at
    ``1 − false_alarm/(2n)``: a clean Gaussian record of ``n`` samples is flagged at all with
    probability ≤ ``false_alarm``.  Flagged samples are replaced by their neighbour median
    (module docstring for the method and its small bias).

    Parameters
    ----------
    y : array_like of float, shape (n,)
        Rate samples (any unit), finite, n ≥ 3.
    false_alarm : float, default 0.01
        Probability, in (0, 1), that a record of clean Gaussian noise has one flag or more.

    Returns
    -------
    OutlierScreen
        The flagged indices, the cleaned record (same unit as ``y``), the threshold and scale.

    Raises
    ------
    ValueError
        If ``false_alarm`` is outside (0, 1), ``y`` is not 1-D with at least 3 samples, or a
        sample is not finite.

    Examples
    --------
    White noise with 5 % spikes of ±30 σ: the spikes are found and replaced.

    >>> import numpy as np
    >>> from bench.analysis.allan import screen_outliers
    >>> rng = np.random.default_rng(1)
    >>> y = rng.normal(size=20_000)
    >>> spikes = rng.choice(y.size, 1000, replace=False)
    >>> y[spikes] += rng.choice([-30.0, 30.0], spikes.size)
    >>> s = screen_outliers(y)
    >>> s.n_flagged, bool(set(spikes.tolist()) == set(s.flagged.tolist()))
    (1000, True)
    >>> round(float(np.std(s.cleaned)), 2)
    0.97
    """
    if isinstance(false_alarm, bool) or not isinstance(false_alarm, (int, float)) or not 0.0 < false_alarm < 1.0:
        raise ValueError(f"false_alarm = {false_alarm!r} must lie in (0, 1)")
    arr = np.asarray(y, dtype=float)
    if arr.ndim != 1 or arr.size < 3:
        raise ValueError(f"the record must be one-dimensional with at least 3 samples, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"the record has {int(np.sum(~np.isfinite(arr)))} non-finite values; all must be finite")
    n = arr.size
    level = neighbour_median(arr)
    resid = arr - level
    scale = MAD_TO_SIGMA * float(np.median(np.abs(resid - np.median(resid))))
    # Student rather than normal: the scale is itself estimated (MAD_DOF_PER_SAMPLE)
    z = student_quantile(upper_normal_quantile(false_alarm / (2.0 * n)), max(n * MAD_DOF_PER_SAMPLE, 20.0))
    if scale > 0:
        flagged = np.flatnonzero(np.abs(resid) > z * scale)
    else:  # more than half the residuals are 0 (a coarse quantizer at rest): no scale to test against
        flagged = np.zeros(0, dtype=np.int64)
    cleaned = arr.copy()
    cleaned[flagged] = level[flagged]
    return OutlierScreen(cleaned=cleaned, flagged=flagged, threshold=z, scale=scale,
                         false_alarm=float(false_alarm), n_samples=n)
