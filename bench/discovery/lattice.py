"""Quantization judged on the output histogram: are the readings on a lattice of spacing s?

A quantized output has no waveform of its own when the step is below the noise (the error is
white, variance s²/12), so it is judged on its histogram signature instead:

* lattice visibility V(s) = |mean exp(2πi·d/s)| over the non-zero successive differences d of
  the readings within 8 white sds (moves of the input excluded) (1 when every reading is on a
  lattice of s, whatever its offset; differences are a few steps, so V is smooth in s, where the
  readings themselves — thousands of steps from zero — would make it a comb far too narrow to
  scan);
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


#: Taylor order of the binned characteristic function: |ω·δ| ≤ 1/2 inside a bin, so the first
#: neglected term (1/2)^17/17! is ~2e-20, below float64 rounding
_TAYLOR_ORDER = 16


class CharFun:
    """|mean exp(iω·y)| of fixed samples ``y`` for many ω, exact to rounding and O(bins) per ω.

    The samples are binned at width h ≤ 1/ω_max; inside bin b, exp(iω·y) = exp(iω·c_b)·
    Σ_k (iω·δ)^k/k! with δ = y − c_b, |ω·δ| ≤ 1/2, so V(ω) = |Σ_b exp(iω c_b) Σ_k (iω)^k/k!·M_bk|/n
    with the bin moments M_bk = Σ δ^k computed once (the old per-ω pass over every sample cost
    n cos + n sin per ω). ``omega_max`` (rad per unit of y): the largest ω that will be asked."""

    def __init__(self, y: np.ndarray, omega_max: float):
        y = np.asarray(y, float).ravel()
        self.n = y.size
        self.direct = None
        if self.n == 0:
            return
        h = 1.0 / max(float(omega_max), 1e-300)
        lo = float(y.min())
        n_bins = int(math.floor((float(y.max()) - lo) / h)) + 1
        if n_bins > max(self.n // 4, 1):  # bins would not be fewer than samples: sum directly
            self.direct = y
            return
        b = np.minimum(((y - lo) / h).astype(np.int64), n_bins - 1)
        centre = lo + (np.arange(n_bins) + 0.5) * h
        delta = y - centre[b]
        mom = np.empty((_TAYLOR_ORDER + 1, n_bins))
        pw = np.ones_like(y)
        for k in range(_TAYLOR_ORDER + 1):
            mom[k] = np.bincount(b, weights=pw, minlength=n_bins)
            pw = pw * delta
        keep = mom[0] > 0
        self.centre = centre[keep]
        self.mom = mom[:, keep]
        self.omega_max = 1.0 / h
        self.fact = np.array([math.factorial(k) for k in range(_TAYLOR_ORDER + 1)], float)

    def __call__(self, omega: np.ndarray | float) -> np.ndarray:
        w = np.atleast_1d(np.asarray(omega, float))
        if self.n == 0:
            return np.zeros(w.size)
        if self.direct is not None:
            return _direct(self.direct, w)
        if np.any(np.abs(w) > self.omega_max * (1 + 1e-12)):
            raise ValueError(f"omega up to {np.max(np.abs(w)):.6g}; allowed: |omega| <= {self.omega_max:.6g}")
        out = np.empty(w.size)
        for i in range(0, w.size, 256):  # (chunk × bins) complex phases at a time
            wc = w[i:i + 256]
            coef = (1j * wc[:, None]) ** np.arange(_TAYLOR_ORDER + 1) / self.fact  # (m, K+1)
            inner = coef @ self.mom  # (m, bins): Σ_k (iω)^k/k! M_bk
            ph = np.exp(1j * wc[:, None] * self.centre[None, :])
            out[i:i + 256] = np.abs(np.sum(ph * inner, axis=1)) / self.n
        return out


def _direct(y: np.ndarray, w: np.ndarray) -> np.ndarray:
    out = np.empty(w.size)
    for k, wk in enumerate(w):
        ph = wk * y
        out[k] = math.hypot(float(np.mean(np.cos(ph))), float(np.mean(np.sin(ph))))
    return out


def visibility(y: np.ndarray, s: np.ndarray | float, *, cf: CharFun | None = None) -> np.ndarray:
    """|mean exp(2πi y/s)| for each step in ``s``; ``cf``: a :class:`CharFun` of ``y`` built for
    ω up to 2π/min(s) (reused across calls: fitting asks for ~500 steps on the same samples)."""
    s = np.atleast_1d(np.asarray(s, float))
    if cf is None:
        cf = CharFun(y, 2 * np.pi / float(np.min(np.abs(s)))) if s.size else None
        if cf is None:
            return np.zeros(0)
    return cf(2 * np.pi / s)


def fit_lattice(y: np.ndarray, noise_sd: float, low: float, high: float, n_grid: int = 300) -> LatticeFit:
    """Scan steps in [max(low, σ/4), min(high, 1.2·max(√12·σ, median non-zero |difference|))]
    and return the fitted lattice with its p-value."""
    readings = np.asarray(y, float)
    d = np.diff(readings)
    noise_sd = difference_sd(d, noise_sd)
    y = d[(d != 0) & (np.abs(d) <= MAX_DIFF_SD * noise_sd)]
    n = y.size
    if n < 16:
        return LatticeFit(float("nan"), float("nan"), 0.0, 1.0, 1.0)
    lo = max(low, noise_sd / 4)
    # a larger step than √12·σ would make the white level larger than measured — unless the
    # input dwells: a coarse quantizer's readings then sit still between steps and its floor is
    # below s/√12, so the typical non-zero difference (one step) bounds the scan as well
    hi = min(high, max(math.sqrt(12) * noise_sd, float(np.median(np.abs(y)))) * 1.2)
    if not lo < hi:
        return LatticeFit(float("nan"), float("nan"), 0.0, 1.0, 1.0)
    grid = np.geomspace(lo, hi, n_grid)
    cf = CharFun(y, 2 * np.pi / grid[0] * 1.5)  # the fine scan reaches grid[0]/1.4
    v = visibility(y, grid, cf=cf)
    bound = np.exp(-4 * np.pi ** 2 * noise_sd ** 2 / grid ** 2)
    excess = v - bound
    best = float(np.max(v))
    cand = np.flatnonzero(v >= 0.9 * best)
    k = int(cand[-1])  # the largest step with near-best visibility: the fundamental
    fine = np.linspace(grid[k] / 1.4, grid[min(k + 1, grid.size - 1)], 200)  # s/2 lies outside
    vf = visibility(y, fine, cf=cf)
    j = int(np.argmax(vf))
    a, b = fine[max(j - 1, 0)], fine[min(j + 1, fine.size - 1)]
    res = optimize.minimize_scalar(lambda s: -visibility(y, s, cf=cf)[0], bounds=(a, b), method="bounded")
    s = float(res.x)
    vs = float(visibility(y, s, cf=cf)[0])
    bs = float(math.exp(-4 * math.pi ** 2 * noise_sd ** 2 / s ** 2))
    ex = max(vs - bs, float(excess[k]), 0.0)
    p = min(1.0, math.exp(-n * ex ** 2) * n_grid)
    std = s * s / (2 * math.pi * max(float(np.sqrt(np.mean(y ** 2))), 1e-300) * math.sqrt(n))
    s, std = refine_step(readings, s, std)
    return LatticeFit(s, std, vs, bs, p)


#: the noise is judged in this many contiguous stretches: the bound holds for the quietest
SD_SEGMENTS = 8


def difference_sd(d: np.ndarray, noise_sd: float, clip: float = 4.0) -> float:
    """The white sd the lattice is judged against: the calibrated floor ``noise_sd``, or less
    when the readings' own successive differences say so — rms/√2 of the non-zero ones within
    ``clip`` times their own sd (iterated from the floor; a Gaussian's sd is biased by < 0.1 %
    at 4), over the whole record and in each of :data:`SD_SEGMENTS` stretches, the smallest:
    noise whose level changes along the record (bursts) has a characteristic function above
    the Gaussian bound of its average level, and would pass for a lattice. Zeros are left out: a
    clipped plateau repeats one reading, and a coarse quantizer's non-zero differences (±s, ±2s
    …) give rms/√2 ≥ s/√2, above its floor s/√12, so the floor stays. A misfit the model cannot
    follow (a clipped plateau's edges, a step) lifts the residual's high-frequency floor; judged
    against that, readings whose noise is far below it look like a lattice of steps much coarser
    than their differences."""
    d = np.asarray(d, float)
    sd = _difference_sd(d, noise_sd, clip)
    for part in np.array_split(d, SD_SEGMENTS):
        if np.count_nonzero(part) >= 64:
            sd = min(sd, _difference_sd(part, noise_sd, clip))
    return sd


def _difference_sd(d: np.ndarray, noise_sd: float, clip: float) -> float:
    d = np.abs(d)
    d = d[d > 0]
    sd = float(noise_sd)
    for _ in range(30):
        kept = d[d <= clip * math.sqrt(2) * sd]
        if kept.size < 16:
            return float(noise_sd)
        new = math.sqrt(float(np.mean(kept * kept)) / 2)
        if abs(new - sd) <= 1e-6 * sd:
            break
        sd = new
    return float(min(noise_sd, sd))


def refine_step(readings: np.ndarray, step: float, step_std: float, *,
                max_rounds: int = 60, consistent: float = 0.95) -> tuple[float, float]:
    """(step, its std) refined on the distinct reading levels, not on small differences.

    The differences pin the step to ~s²/(2π·rms(d)·√n), but a prediction over a large input
    range needs it to ~s/(max|y|/s): reading m·s misplaces the lattice by m·δs. Distinct levels
    of a quantized output are integer multiples of the step apart, so (:func:`_lattice_slope`)
    gaps whose multiple is unambiguous at the current precision join levels into clusters, the
    step is the least-squares slope of level against integer index, and a better step makes
    larger gaps unambiguous, until nothing more joins. Started from the histogram's step and
    from the smallest gap (exactly one step when neighbouring levels occur); a start is kept
    only if at least ``consistent`` of the gaps are whole multiples of its result, and the
    larger such step wins (the fundamental, not a sub-multiple). The unrefined pair comes back
    when the levels do not lie on a lattice."""
    v = np.unique(np.asarray(readings, float))
    if v.size < 3 or not (np.isfinite(step) and step > 0):
        return step, step_std
    gaps = np.diff(v)
    best = None
    for s0, rel0 in ((float(step), max(float(step_std) / float(step), 1e-15)), (float(gaps.min()), 1e-3)):
        out = _lattice_slope(v, gaps, s0, rel0, max_rounds)
        if out is None:
            continue
        s_fit, rel, share = out
        if share >= consistent and (best is None or s_fit > best[0] * (1 + 1e-9)):
            best = (s_fit, s_fit * rel)
    return best if best is not None else (step, step_std)


def _lattice_slope(v: np.ndarray, gaps: np.ndarray, s: float, rel: float,
                   max_rounds: int) -> tuple[float, float, float] | None:
    """(step, relative std, share of gaps that are whole multiples of it) from start ``s``."""
    joined = -1
    ok = np.zeros(gaps.size, bool)
    for _ in range(max_rounds):
        k = gaps / s
        kr = np.round(k)
        ok = (kr >= 1) & (np.abs(k - kr) < 0.25) & (kr * rel < 0.25)
        if not ok.any():
            return None
        cluster = np.concatenate([[0], np.cumsum(~ok)])
        index = np.concatenate([[0.0], np.cumsum(np.where(ok, kr, 0.0))])
        dm_i = index - (np.bincount(cluster, index) / np.bincount(cluster))[cluster]
        dm_v = v - (np.bincount(cluster, v) / np.bincount(cluster))[cluster]
        ss = float(dm_i @ dm_i)
        if ss <= 0:
            return None
        s = float(dm_i @ dm_v) / ss
        res = dm_v - s * dm_i
        rel = max(math.sqrt(float(res @ res) / max(v.size - int(cluster[-1]) - 2, 1) / ss) / s, 1e-15)
        if int(ok.sum()) == joined:
            break
        joined = int(ok.sum())
    k = gaps / s
    share = float(np.mean((np.round(k) >= 1) & (np.abs(k - np.round(k)) < 0.25)))
    return s, rel, share


def heldout_score(y: np.ndarray, noise_sd: float, folds: np.ndarray, low: float, high: float) -> float:
    """Held-out visibility excess × (s²/12)/σ², both folds averaged."""
    scores = []
    noise_sd = difference_sd(np.diff(np.asarray(y, float)), noise_sd)
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
