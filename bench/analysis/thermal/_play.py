"""The play (backlash) operator: a hysteresis that takes a reversal of some degrees to switch.

Its memory m stays put while |T − m| < w and is dragged at distance w otherwise; the output
z = (T − m)/w lies in [−1, 1]: +1 well into a rise, −1 well into a fall, crossing over
linearly in 2w of travel after a reversal (w → 0: an instant flip at each extremum).
:func:`width_profile` reads w from a record by profiling the whitened residual of a fit that
holds the play as one of its columns (:mod:`bench.analysis.thermal._ramp`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from bench.analysis.thermal._drift_gls import GlsFit

WIDTH_GRID = 121  # 0.125 °C steps over the default 0.125 … 15 °C
_CHI2_1_95 = 3.841458820694124  # χ²₁ quantile at 0.95: the profile-likelihood interval (Wilks)


def play_output(temp: np.ndarray, width_c: float) -> np.ndarray:
    """z = (T − m)/w of a play (backlash) operator of half width w on ``temp``: m holds while
    |T − m| < w and follows at distance w otherwise; m starts at T_0 (z = 0)."""
    memory = []
    m = float(temp[0])
    for low, high in zip((temp - width_c).tolist(), (temp + width_c).tolist()):
        if m < low:
            m = low
        elif m > high:
            m = high
        memory.append(m)
    return np.clip((temp - np.array(memory)) / width_c, -1.0, 1.0)  # ±1 exactly when dragged


@dataclass(frozen=True, eq=False)
class WidthProfile:
    """The play's half width profiled on a grid: the minimiser, the 95 % profile-likelihood
    interval, and the grid's weights ∝ exp(−Δχ²/2) with the fit at each grid point."""

    width: float
    interval: tuple[float, float]
    at_edge: bool
    weights: np.ndarray
    betas: np.ndarray


def memory_known(temp: np.ndarray, state: np.ndarray, starts: list[int], width_c: float) -> np.ndarray:
    """Blocks where a play of half width up to ``width_c`` has a known memory whatever it was
    before the record (it was within w of T): the first branch (``state``, ``starts`` of
    :func:`~bench.analysis.thermal._ramp_record.branch_states`) once it has moved 2w from its
    start, and every block after the first reversal; never before the first branch is known."""
    first = np.arange(temp.size) <= (starts[1] if len(starts) > 1 else temp.size)
    if not starts:
        return np.zeros(temp.size, dtype=bool)
    direction = int(state[min(starts[0] + 1, temp.size - 1)])
    travel = direction * (temp - temp[starts[0]])
    moved = np.maximum.accumulate(np.where(first, travel, -np.inf)) >= 2 * width_c
    return (state != 0) & (~first | moved)


def width_profile(fit: Callable[[float], GlsFit], lo: float, hi: float, points: int = WIDTH_GRID) -> WidthProfile:
    """w over [lo, hi]: the whitened residual of ``fit(w)`` (the GLS fit with the play of half
    width w) on a grid of ``points`` (the profile is
    bumpy — block means switch the play by steps — and can be flat over degrees, so no local
    search alone), refined by a bounded search around the best point. Δχ² = ΔRSS/σ̂²; the 95 %
    interval is where Δχ² ≤ χ²₁(0.95) = 3.84 (Wilks)."""
    grid = np.linspace(lo, hi, points)

    def rss_at(w: float) -> float:
        try:
            return fit(w).rss
        except ValueError:  # a width whose column is constant or collinear: not a candidate
            return math.inf
    fits: list[GlsFit | None] = []
    for w in grid:
        try:
            fits.append(fit(w))
        except ValueError:
            fits.append(None)
    rss = np.array([math.inf if f is None else f.rss for f in fits])
    if not np.isfinite(rss).any():
        raise ValueError("no play width in the range fitted gives a separable design")
    i = int(np.argmin(rss))
    a, b = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
    best = optimize.minimize_scalar(rss_at, bounds=(a, b), method="bounded", options={"xatol": 1e-3 * (b - a)})
    w_hat, rss_min = (float(best.x), float(best.fun)) if best.fun <= rss[i] else (float(grid[i]), float(rss[i]))
    ref = fits[i]
    assert ref is not None  # rss[i] is finite
    dchi2 = (rss - rss_min) / (rss_min / ref.dof)
    inside = grid[dchi2 <= _CHI2_1_95]
    low, high = (float(inside.min()), float(inside.max())) if inside.size else (w_hat, w_hat)
    step = grid[1] - grid[0]
    low, high = min(low - step / 2, w_hat), max(high + step / 2, w_hat)  # the grid's own resolution
    weights = np.where(np.isfinite(dchi2), np.exp(-0.5 * (np.where(np.isfinite(dchi2), dchi2, 0.0) - dchi2.min())),
                       0.0)
    at_edge = bool(dchi2[0] <= _CHI2_1_95 or dchi2[-1] <= _CHI2_1_95)
    return WidthProfile(w_hat, (float(max(low, lo)), float(min(high, hi))), at_edge, weights / weights.sum(),
                         np.array([ref.coefficients if f is None else f.coefficients for f in fits]))
