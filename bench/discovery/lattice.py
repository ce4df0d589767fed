"""Quantization judged on the output histogram: are the readings on a lattice of spacing s?

A quantized output has no waveform of its own when the step is below the noise (the error is
white, variance s²/12), so it is judged on its histogram signature instead:

* lattice visibility V(s) = |mean exp(2πi·d/s)| over the non-zero successive differences d of
  the readings within 8 white sds (moves of the input excluded) (1 when every reading is on a lattice of s, whatever its offset; differences are
  a few steps, so V is smooth in s, where the readings themselves — thousands of steps from
  zero — would make it a comb far too narrow to scan);
* bound under "no quantization": for y = signal + Gaussian noise of sd σ (the calibrated white
  level), |E exp(2πi·d/s)| ≤ exp(−4π²σ²/s²) whatever the signal; a quantized output has
  σ² ≥ s²/12 so its bound is ≤ exp(−4π²/12) ≈ 0.04 while V = 1;
* p-value: the excess E = V − bound against the Rayleigh tail P(n·|V̂ − V|² > x) = e^{−x},
  Bonferroni over the scanned steps;
* fit: the largest step whose visibility is within 10 % of the best (a lattice of s is also one
  of s/2, s/3 …), refined by a bounded scalar search; std ≈ s² / (2π·rms(d)·√n) (the step
  change that turns the phase of a typical difference by one radian over √n of them);
* held-out score: the visibility excess measured on the held-out blocks at the step fitted on
  the training blocks, times the share of the white variance that quantization accounts for
  (s²/12)/σ² — a variance-reduction analogue comparable with the other candidates' scores.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize


#: only differences within this many white sds: the input's moves would make V a narrow comb
MAX_DIFF_SD = 8.0


@dataclass(frozen=True)
class LatticeFit:
    step: float
    step_std: float
    visibility: float
    bound: float
    p_value: float


def visibility(y: np.ndarray, s: np.ndarray | float) -> np.ndarray:
    """|mean exp(2πi y/s)| for each step in ``s``."""
    s = np.atleast_1d(np.asarray(s, float))
    out = np.empty(s.size)
    for k, sk in enumerate(s):
        ph = 2 * np.pi * y / sk
        out[k] = math.hypot(float(np.mean(np.cos(ph))), float(np.mean(np.sin(ph))))
    return out


def fit_lattice(y: np.ndarray, noise_sd: float, low: float, high: float, n_grid: int = 300) -> LatticeFit:
    """Scan steps in [max(low, σ/4), min(high, √12·σ·1.2)] (a larger step would make the white
    level larger than measured) and return the fitted lattice with its p-value."""
    d = np.diff(np.asarray(y, float))
    y = d[(d != 0) & (np.abs(d) <= MAX_DIFF_SD * noise_sd)]
    n = y.size
    if n < 16:
        return LatticeFit(float("nan"), float("nan"), 0.0, 1.0, 1.0)
    lo = max(low, noise_sd / 4)
    hi = min(high, math.sqrt(12) * noise_sd * 1.2)
    if not lo < hi:
        return LatticeFit(float("nan"), float("nan"), 0.0, 1.0, 1.0)
    grid = np.geomspace(lo, hi, n_grid)
    v = visibility(y, grid)
    bound = np.exp(-4 * np.pi ** 2 * noise_sd ** 2 / grid ** 2)
    excess = v - bound
    best = float(np.max(v))
    cand = np.flatnonzero(v >= 0.9 * best)
    k = int(cand[-1])  # the largest step with near-best visibility: the fundamental
    fine = np.linspace(grid[k] / 1.4, grid[min(k + 1, grid.size - 1)], 200)  # s/2 lies outside
    vf = visibility(y, fine)
    j = int(np.argmax(vf))
    a, b = fine[max(j - 1, 0)], fine[min(j + 1, fine.size - 1)]
    res = optimize.minimize_scalar(lambda s: -visibility(y, s)[0], bounds=(a, b), method="bounded")
    s = float(res.x)
    vs = float(visibility(y, s)[0])
    bs = float(math.exp(-4 * math.pi ** 2 * noise_sd ** 2 / s ** 2))
    ex = max(vs - bs, float(excess[k]), 0.0)
    p = min(1.0, math.exp(-n * ex ** 2) * n_grid)
    std = s * s / (2 * math.pi * max(float(np.sqrt(np.mean(y ** 2))), 1e-300) * math.sqrt(n))
    return LatticeFit(s, std, vs, bs, p)


def heldout_score(y: np.ndarray, noise_sd: float, folds: np.ndarray, low: float, high: float) -> float:
    """Held-out visibility excess × (s²/12)/σ², both folds averaged."""
    scores = []
    for k in (0, 1):
        te = folds == k
        fit = fit_lattice(np.cumsum(np.concatenate([[0.0], _test_diffs(y, ~te)])), noise_sd, low, high)
        if not np.isfinite(fit.step):
            return 0.0
        d = _test_diffs(y, te)
        d = d[(d != 0) & (np.abs(d) <= MAX_DIFF_SD * noise_sd)]
        v = float(visibility(d, fit.step)[0]) if d.size else 0.0
        excess = v - math.exp(-4 * math.pi ** 2 * noise_sd ** 2 / fit.step ** 2)
        scores.append(excess * min(1.0, fit.step ** 2 / 12 / noise_sd ** 2))
    return float(np.mean(scores))


def _test_diffs(y: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Successive differences inside the selected rows (never across a gap)."""
    d = np.diff(y)
    both = rows[1:] & rows[:-1]
    return d[both]
