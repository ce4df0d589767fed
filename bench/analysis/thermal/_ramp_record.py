"""The record of a thermal ramp: block means, the sensor's rate, branches and reversals.

What :mod:`bench.analysis.thermal._ramp` fits is prepared here, on block means of the static
record (blocks with under half the usual count — the record's edges, gaps — are dropped):

* **rate** — the least-squares slope of the sensor's samples over a window about each block's
  centre (by default the block itself), °C/min;
* **branches** — +1 up, −1 down, 0 until the first branch is known. A direction is taken,
  and a reversal confirmed, once the temperature has moved a dead band from its extreme; the
  reversal is put where the temperature last stood within a quarter of the band of the
  extreme (on a dwell at the extreme, the noise's own maximum would be anywhere in it), and
  the first branch counts from where the move became known (the state before the record is
  unknown);
* **steady blocks** — the rate at the block and a half-window before and after agree within
  a tolerance: a unit settled into its ramp (or its dwell), not accelerating out of a
  reversal or a soak;
* **segments** — each branch with its steady rate, and the ramp rate of each direction.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class RampSegment:
    """A branch between two reversals of the sensor temperature: ``direction`` +1 up, −1 down;
    ``rate_c_per_min`` the mean rate over its steady blocks (None: none steady)."""

    start_s: float
    end_s: float
    direction: int
    temperature_from_c: float
    temperature_to_c: float
    rate_c_per_min: float | None


@dataclass(frozen=True, eq=False)
class Blocks:
    """Consecutive blocks of ``block_s`` over sample times; ``full`` marks blocks with at least
    half the usual count (the record's edges and gaps drop out)."""

    starts: np.ndarray  # first sample of every block
    counts: np.ndarray
    full: np.ndarray

    @classmethod
    def of(cls, t: np.ndarray, block_s: float) -> Blocks:
        idx = np.floor((t - t[0]) / block_s).astype(np.int64)
        starts = np.concatenate([[0], np.flatnonzero(np.diff(idx)) + 1])
        counts = np.diff(np.concatenate([starts, [t.size]]))
        return cls(starts, counts, counts >= 0.5 * np.median(counts))

    def mean(self, a: np.ndarray) -> np.ndarray:
        """Block means of the samples (1-D, or 2-D with rows = samples) over the full blocks."""
        sums = np.add.reduceat(a, self.starts, axis=0)
        return (sums / (self.counts if a.ndim == 1 else self.counts[:, None]))[self.full]


def block_means(t, y, temp, block_s) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Block means; blocks with under half the usual count (edges, gaps) are dropped."""
    blocks = Blocks.of(t, block_s)
    return blocks.mean(t), blocks.mean(y), blocks.mean(temp)


def local_slope(t: np.ndarray, y: np.ndarray, half_width_s: float) -> np.ndarray:
    """Slope of the least-squares line through the points within ±half_width_s (per s)."""
    lo = np.searchsorted(t, t - half_width_s, side="left")
    hi = np.searchsorted(t, t + half_width_s, side="right")
    u = t - t[0]
    cs = [np.concatenate([[0.0], np.cumsum(v)]) for v in (np.ones_like(u), u, y, u * u, u * y)]
    n, su, sy, suu, suy = (c[hi] - c[lo] for c in cs)
    den = suu - su * su / n
    with np.errstate(invalid="ignore", divide="ignore"):
        slope = (suy - su * sy / n) / den
    return np.where(den > 0, slope, 0.0)


def slope_at(t: np.ndarray, y: np.ndarray, at: np.ndarray, half_width_s: float) -> np.ndarray:
    """Slope (per s) of the least-squares line through the samples within ±half_width_s of each
    time in ``at``: at block centres with the block's width, the block's mean rate to second
    order (a ramp's turn included), where a slope of block means smooths it over more blocks."""
    lo = np.searchsorted(t, at - half_width_s, side="left")
    hi = np.searchsorted(t, at + half_width_s, side="right")
    u = t - t[0]
    cs = [np.concatenate([[0.0], np.cumsum(v)]) for v in (np.ones_like(u), u, y, u * u, u * y)]
    n, su, sy, suu, suy = (c[hi] - c[lo] for c in cs)
    with np.errstate(invalid="ignore", divide="ignore"):
        den = suu - su * su / n
        slope = (suy - su * sy / n) / den
    return np.where((n >= 2) & (den > 0), slope, 0.0)


def branch_states(temp: np.ndarray, band: float) -> tuple[np.ndarray, list[int]]:
    """Branch state per block (+1 up, −1 down, 0 until the first branch is known) and the
    branch starts: where the first branch became known, then each extremum of T (a
    reversal). A direction is taken, and a reversal confirmed, once T has moved ``band`` from
    the extreme."""
    n = temp.size
    starts: list[int] = []
    directions: list[int] = []
    direction, i_min, i_max, ext = 0, 0, 0, 0
    for i in range(1, n):
        if direction == 0:
            i_min = i if temp[i] < temp[i_min] else i_min
            i_max = i if temp[i] > temp[i_max] else i_max
            # The state before the record is unknown: the first branch counts from the block
            # where the temperature has moved ``band`` from its extreme, not from the extreme.
            if temp[i] - temp[i_min] >= band:
                direction, ext = 1, i
                starts.append(i)
            elif temp[i_max] - temp[i] >= band:
                direction, ext = -1, i
                starts.append(i)
            if direction:
                directions.append(direction)
            continue
        if direction * (temp[i] - temp[ext]) > 0:
            ext = i  # further in the current direction
        elif direction * (temp[ext] - temp[i]) >= band:
            # A reversal: it happened when T last stood within band/4 of the extreme (on a
            # dwell at the extreme, the noise's own maximum would be anywhere in it).
            near = direction * (temp[ext:i] - temp[ext]) >= -band / 4
            starts.append(ext + int(np.flatnonzero(near)[-1]))
            direction = -direction
            directions.append(direction)
            ext = i
    state = np.zeros(n, dtype=int)
    for k, (first, d) in enumerate(zip(starts, directions)):
        last = starts[k + 1] if k + 1 < len(starts) else n - 1
        state[first + 1:last + 1] = d  # the extremum closes the branch that reached it
    return state, starts


def steady_blocks(tb: np.ndarray, rate: np.ndarray, half_width_s: float, tolerance: float) -> np.ndarray:
    """Blocks whose rate, and the rates ``half_width_s`` before and after, agree within
    ``tolerance`` (°C/min); blocks nearer the record's ends are not steady."""
    before = np.interp(tb - half_width_s, tb, rate)
    after = np.interp(tb + half_width_s, tb, rate)
    inside = (tb - half_width_s >= tb[0]) & (tb + half_width_s <= tb[-1])
    spread = np.maximum.reduce([before, after, rate]) - np.minimum.reduce([before, after, rate])
    return inside & (spread <= tolerance)


def ramp_segments(tb, temp, rate, state, starts, steady) -> tuple[RampSegment, ...]:
    bounds = starts + [tb.size - 1]
    out = []
    for a, b in zip(bounds[:-1], bounds[1:]):
        d = int(state[min(a + 1, tb.size - 1)])
        sel = np.zeros(tb.size, dtype=bool)
        sel[a:b + 1] = True
        sel &= steady
        r = float(np.mean(rate[sel])) if np.any(sel) else None
        out.append(RampSegment(float(tb[a]), float(tb[b]), d, float(temp[a]), float(temp[b]), r))
    return tuple(out)


def ramp_rates(rate: np.ndarray, state: np.ndarray, used: np.ndarray) -> tuple[float, float]:
    """Median rate (°C/min) of the up and of the down blocks, dwells (|rate| under a tenth of
    the largest) left out."""
    moving = used & (np.abs(rate) >= 0.1 * np.abs(rate[used]).max())
    up, dn = rate[moving & (state > 0)], rate[moving & (state < 0)]
    return (float(np.median(up)) if up.size else 0.0, float(np.median(dn)) if dn.size else 0.0)
