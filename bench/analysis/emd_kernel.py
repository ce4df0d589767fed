"""The inner loop of :mod:`bench.analysis.emd`: extrema, mirrored envelope knots and one sifting.

Speed notes (measured beside PyEMD in ``benchmarks/bench_emd.py``; the sifting count is
fixed by the stop criterion, so only the cost of one sifting can be cut):

* One sifting is a single pass over the record in cache-sized blocks: the envelopes
  (or, when knot intervals are long, one merged mean spline), the subtraction, the
  sums of the SD criterion, the extrema and the zero crossings of the result are
  computed block by block while the block is in cache.  Whole-record temporaries made
  every step memory-bound.
* The extrema of the sifted result are found in the same pass, so each sifting finds
  extrema once (PyEMD does it three times).
* Spline coefficients come from one symmetric tridiagonal solve per envelope (LAPACK
  ``ptsv``); a sample's interval is known from the block's knot range (a running count
  of knots, or ``np.repeat`` of the per-interval sample counts), so no per-sample
  search happens.
* Sums use ``einsum``, not BLAS ``dot``: on a busy machine a BLAS call may wake its
  thread pool and cost milliseconds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.linalg import lapack

BLOCK = 16384  # samples per block: a handful of float arrays of this size stay in L2


# --------------------------------------------------------------------------- extrema


def find_extrema(h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the local maxima and minima of ``h``.

    A flat run of equal samples between a rise and a fall (or a fall and a rise) counts
    once, at its middle rounded half to even (as PyEMD); flat runs touching an end of
    the record are not extrema.
    """
    d = np.diff(h)
    if np.count_nonzero(d) == d.size:  # no flat runs: one comparison per sample
        up = d > 0
        chg = np.flatnonzero(up[1:] != up[:-1])
        idx = chg + 1
    else:
        nz = np.flatnonzero(d)
        up = d[nz] > 0
        chg = np.flatnonzero(up[1:] != up[:-1])
        idx = np.rint(0.5 * (nz[chg] + 1 + nz[chg + 1])).astype(np.intp)  # middle of the flat run
    is_max = up[chg]
    return idx[is_max], idx[~is_max]


def count_zero_crossings(h: np.ndarray) -> int:
    """Sign changes of ``h`` between consecutive samples, exact zeros skipped."""
    pos = h > 0
    if np.count_nonzero(h) == h.size:
        return int(np.count_nonzero(pos[1:] != pos[:-1]))
    s = pos[h != 0]
    return int(np.count_nonzero(s[1:] != s[:-1]))


# --------------------------------------------------------------------------- ends


def _mirror_start(first: float, imax: np.ndarray, vmax: np.ndarray, imin: np.ndarray, vmin: np.ndarray,
                  nbsym: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Knots reflected before sample 0: ``(pos_max, val_max, pos_min, val_min)``, ascending.

    Rilling's rule: reflect about the first extremum unless the first sample lies beyond
    the first extremum of the other kind, in which case sample 0 itself acts as an
    extremum of that kind and the reflection is about it.  Falls back to reflecting the
    first ``nbsym`` extrema about sample 0 when the reflected knots would not reach it.
    """
    extra_max = extra_min = None
    if imax[0] < imin[0]:  # the first extremum is a maximum
        if first > vmin[0]:
            sym, kmax, kmin = int(imax[0]), slice(1, nbsym + 1), slice(0, nbsym)
        else:  # sample 0 acts as a minimum
            sym, kmax, kmin, extra_min = 0, slice(0, nbsym), slice(0, nbsym - 1), first
    else:
        if first < vmax[0]:
            sym, kmax, kmin = int(imin[0]), slice(0, nbsym), slice(1, nbsym + 1)
        else:  # sample 0 acts as a maximum
            sym, kmax, kmin, extra_max = 0, slice(0, nbsym - 1), slice(0, nbsym), first
    pmax, qmax, pmin, qmin = imax[kmax], vmax[kmax], imin[kmin], vmin[kmin]
    if extra_max is not None:
        pmax, qmax = np.r_[0, pmax], np.r_[extra_max, qmax]
    if extra_min is not None:
        pmin, qmin = np.r_[0, pmin], np.r_[extra_min, qmin]
    tmax, tmin = 2 * sym - pmax, 2 * sym - pmin
    if not (tmax.size and tmin.size and tmax.min() <= 0 and tmin.min() <= 0):
        pmax, qmax, pmin, qmin = imax[:nbsym], vmax[:nbsym], imin[:nbsym], vmin[:nbsym]
        tmax, tmin = -pmax, -pmin
    return tmax[::-1], qmax[::-1], tmin[::-1], qmin[::-1]


def envelope_knots(h: np.ndarray, imax: np.ndarray, imin: np.ndarray, nbsym: int
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Envelope knots ``(pos_max, val_max, pos_min, val_min)`` with mirrored ends.

    Needs at least one maximum and one minimum; positions are strictly increasing
    integers whose first is ≤ 0 and last ≥ ``h.size - 1``.
    """
    n = h.size
    vmax, vmin = h[imax], h[imin]
    lpx, lvx, lpn, lvn = _mirror_start(h[0], imax, vmax, imin, vmin, nbsym)
    # the end is the start of the reversed record: reflect there and map back
    rpx, rvx, rpn, rvn = _mirror_start(h[-1], (n - 1 - imax)[::-1], vmax[::-1],
                                       (n - 1 - imin)[::-1], vmin[::-1], nbsym)
    px = np.concatenate([lpx, imax, (n - 1 - rpx)[::-1]])
    vx = np.concatenate([lvx, vmax, rvx[::-1]])
    pn = np.concatenate([lpn, imin, (n - 1 - rpn)[::-1]])
    vn = np.concatenate([lvn, vmin, rvn[::-1]])
    return (*_strict(px, vx), *_strict(pn, vn))


def _strict(pos: np.ndarray, val: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Drop repeated knot positions (a reflection can land on an existing knot)."""
    keep = np.r_[True, np.diff(pos) > 0]
    return (pos, val) if keep.all() else (pos[keep], val[keep])


# --------------------------------------------------------------------------- splines


def not_a_knot_slopes(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """First derivatives at the knots of the not-a-knot cubic spline through ``(x, y)``, ≥ 4 knots.

    The slope equations ``h_i s_{i-1} + 2(h_{i-1} + h_i) s_i + h_{i-1} s_{i+1} = 3(h_i δ_{i-1} +
    h_{i-1} δ_i)`` (``h`` knot spacings, ``δ`` secant slopes) divided by ``h_{i-1} h_i`` are
    symmetric; eliminating the end slopes with the not-a-knot conditions (scipy's end
    rows) keeps them symmetric and strictly diagonally dominant, so LAPACK's ``ptsv``
    (LDLᵀ, no pivoting) solves them — the same slopes as ``CubicSpline`` to rounding.
    """
    dx = np.diff(x)
    inv = 1.0 / dx
    delta = np.diff(y) * inv
    rhs = delta * inv
    rhs = rhs[:-1] + rhs[1:]
    rhs *= 3.0
    diag = inv[:-1] + inv[1:]
    diag[1:-1] *= 2.0  # the end rows lose half their diagonal to the eliminated end slopes
    h0, h1, hb, ha = dx[0], dx[1], dx[-2], dx[-1]
    d0, d1 = h0 + h1, hb + ha
    r0 = ((h0 + 2 * d0) * h1 * delta[0] + h0**2 * delta[1]) / d0  # s0 = (r0 - d0 s1) / h1
    r1 = (ha**2 * delta[-2] + (2 * d1 + ha) * hb * delta[-1]) / d1  # s_end = (r1 - d1 s_{end-1}) / hb
    rhs[0] -= r0 * inv[0] * inv[1]
    rhs[-1] -= r1 * inv[-2] * inv[-1]
    *_, s, info = lapack.dptsv(diag, inv[1:-1].copy(), rhs, overwrite_d=1, overwrite_e=1, overwrite_b=1)
    if info != 0:
        raise ValueError(f"envelope spline system is singular (LAPACK ptsv info = {info})")
    out = np.empty(x.size)
    out[1:-1] = s
    out[0] = (r0 - d0 * s[0]) / h1
    out[-1] = (r1 - d1 * s[-1]) / hb
    return out


@dataclass(frozen=True, eq=False)
class Spline:
    """A not-a-knot cubic spline through integer knots, as per-interval polynomials
    ``c0 + c1·t + c2·t² + c3·t³`` in ``t = sample − pos[i]``."""

    pos: np.ndarray  # knot positions (int)
    start: np.ndarray  # pos[:-1] as float
    c0: np.ndarray
    c1: np.ndarray
    c2: np.ndarray
    c3: np.ndarray

    @classmethod
    def through(cls, pos: np.ndarray, val: np.ndarray) -> Spline:
        x = pos.astype(float)
        if x.size >= 4:
            s = not_a_knot_slopes(x, val)
            dx = np.diff(x)
            delta = np.diff(val) / dx
            c2 = (3.0 * delta - 2.0 * s[:-1] - s[1:]) / dx
            c3 = (s[:-1] + s[1:] - 2.0 * delta) / (dx * dx)
            return cls(pos, x[:-1], val[:-1], s[:-1], c2, c3)
        c3, c2, c1, c0 = CubicSpline(x, val).c  # 2-3 knots: scipy's line / parabola
        return cls(pos, x[:-1], c0, c1, c2, c3)

    @classmethod
    def average(cls, a: Spline, b: Spline) -> Spline:
        """``(a + b) / 2`` as one piecewise cubic on the union of both knot sets, where both
        are defined: each polynomial re-expanded (Taylor shift) at the merged interval starts."""
        lo, hi = max(a.pos[0], b.pos[0]), min(a.pos[-1], b.pos[-1])
        pos = np.concatenate([a.pos, b.pos])
        pos.sort(kind="stable")  # two sorted runs: a linear merge
        pos = pos[np.r_[True, pos[1:] != pos[:-1]]]
        pos = pos[(pos >= lo) & (pos <= hi)]
        starts = pos[:-1]
        parts = []
        for s in (a, b):
            i = np.clip(np.searchsorted(s.pos, starts, side="right") - 1, 0, s.pos.size - 2)
            d = (starts - s.pos[i]).astype(float)
            c1, c2, c3 = s.c1[i], s.c2[i], s.c3[i]
            parts.append((s.c0[i] + d * (c1 + d * (c2 + d * c3)), c1 + d * (2.0 * c2 + 3.0 * c3 * d),
                          c2 + 3.0 * c3 * d, c3))
        return cls(pos, starts.astype(float), *(0.5 * (p + q) for p, q in zip(*parts)))

    def block_ranges(self, starts: np.ndarray, stops: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """First and last interval touching each block ``[start, stop)``."""
        last = self.pos.size - 2
        lo = np.searchsorted(self.pos, starts, side="right") - 1
        hi = np.minimum(np.searchsorted(self.pos, stops - 1, side="right") - 1, last)
        return lo, hi

    def evaluate_block(self, a: int, b: int, lo: int, hi: int, ws: Workspace, out: np.ndarray) -> None:
        """Write the spline at samples ``a..b-1`` into ``out`` (intervals ``lo..hi``; scratch from ``ws``)."""
        m = b - a
        grid, t, tmp = ws.grid, ws.t[:m], ws.tmp[:m]
        inner = self.pos[lo + 1 : hi + 1]  # knots inside the block, all in (a, b)
        if 16 * inner.size < m:
            # long intervals: expanding the coefficients run by run is a few memcpy's
            cnt = np.diff(np.concatenate(([a], inner, [b])))
            sl = slice(lo, hi + 1)
            np.subtract(grid[a:b], np.repeat(self.start[sl], cnt), out=t)
            np.multiply(np.repeat(self.c3[sl], cnt), t, out=out)
            for c in (self.c2, self.c1):  # Horner
                out += np.repeat(c[sl], cnt)
                out *= t
            out += np.repeat(self.c0[sl], cnt)
            return
        # short intervals: the interval index of every sample by a running count of knots,
        # then one gather per coefficient
        idx = ws.idx[:m]
        idx[:] = 0
        idx[inner - a] = 1
        idx[0] = lo
        np.cumsum(idx, out=idx)
        np.take(self.start, idx, out=t)
        np.subtract(grid[a:b], t, out=t)
        np.take(self.c3, idx, out=out)
        for c in (self.c2, self.c1, self.c0):  # Horner
            out *= t
            np.take(c, idx, out=tmp)
            out += tmp

    def __call__(self, n: int) -> np.ndarray:
        """The spline at samples ``0..n-1`` (blocked like a sifting)."""
        ws = Workspace(n)
        out = np.empty(n)
        lo, hi = self.block_ranges(ws.starts, ws.stops)
        for k, (a, b) in enumerate(zip(ws.starts.tolist(), ws.stops.tolist())):
            self.evaluate_block(a, b, int(lo[k]), int(hi[k]), ws, out[a:b])
        return out


# --------------------------------------------------------------------------- one sifting


class Workspace:
    """Scratch arrays reused by every sifting of one record."""

    def __init__(self, n: int, block: int | None = None):
        self.n = n
        self.grid = np.arange(n, dtype=float)
        b = min(BLOCK if block is None else block, n)
        self.starts = np.arange(0, n, b)
        self.stops = np.minimum(self.starts + b, n)
        self.t, self.u, self.lo, self.tmp = (np.empty(b) for _ in range(4))
        self.idx = np.empty(b, dtype=np.intp)
        self.d = np.empty(b + 1)  # differences of a block and the two samples before it
        self.flag = np.empty(b + 1, dtype=bool)


@dataclass(frozen=True)
class SiftStats:
    """What one sifting ``h → h − m`` measured (``m`` the envelope mean)."""

    mean_energy: float  # Σ m²
    input_energy: float  # Σ h²
    imax: np.ndarray  # extrema of the result
    imin: np.ndarray
    zero_crossings: int  # of the result
    over_theta1: int  # Rilling: samples with |m| > θ1·a (a the envelope half-range)
    over_theta2: int  # samples with |m| > θ2·a


def sift(h: np.ndarray, out: np.ndarray, upper: Spline, lower: Spline | None, ws: Workspace,
         thetas: tuple[float, float] | None = None) -> SiftStats:
    """``out = h − (upper + lower)/2`` in one blocked pass, with the sums and counts of
    :class:`SiftStats`; ``thetas = (θ1, θ2)`` also counts Rilling's exceedances.  With
    ``lower=None``, ``upper`` is the envelope mean itself (:meth:`Spline.average`)."""
    if lower is None and thetas is not None:
        raise ValueError("Rilling's criterion needs both envelopes")
    ulo, uhi = upper.block_ranges(ws.starts, ws.stops)
    if lower is not None:
        llo, lhi = lower.block_ranges(ws.starts, ws.stops)
    e_mean = e_in = 0.0
    zc = over1 = over2 = 0
    maxima: list[np.ndarray] = []
    minima: list[np.ndarray] = []
    exact = True  # no flat runs and no exact zeros met: block results are final
    for k, (a, b) in enumerate(zip(ws.starts.tolist(), ws.stops.tolist())):
        m = b - a
        u, lo, t, tmp, flag = ws.u[:m], ws.lo[:m], ws.t[:m], ws.tmp[:m], ws.flag
        upper.evaluate_block(a, b, int(ulo[k]), int(uhi[k]), ws, u)
        if lower is not None:
            lower.evaluate_block(a, b, int(llo[k]), int(lhi[k]), ws, lo)
            u += lo
            u *= 0.5  # u is now the envelope mean
        if thetas is not None:
            lo -= u  # -(upper - lower)/2
            np.abs(lo, out=lo)
            np.abs(u, out=tmp)
            np.multiply(lo, thetas[0], out=t)
            over1 += int(np.count_nonzero(np.greater(tmp, t, out=flag[:m])))
            np.multiply(lo, thetas[1], out=t)
            over2 += int(np.count_nonzero(np.greater(tmp, t, out=flag[:m])))
        hb = h[a:b]
        # einsum, not BLAS dot: a BLAS call may wake its thread pool, which costs
        # milliseconds per call on a busy machine
        e_mean += float(np.einsum("i,i->", u, u))
        e_in += float(np.einsum("i,i->", hb, hb))
        np.subtract(hb, u, out=out[a:b])
        if not exact:
            continue
        # extrema at a-1..b-2 (all samples they need are final now); zero crossings of
        # the pairs (a-1, a)..(b-2, b-1)
        w0 = max(a - 2, 0)
        w = out[w0:b]
        d = ws.d[: w.size - 1]
        np.subtract(w[1:], w[:-1], out=d)
        if np.equal(d, 0.0, out=flag[: d.size]).any():  # cheaper than count_nonzero on floats
            exact = False
            continue
        up = np.greater(d, 0, out=flag[: d.size])
        chg = np.flatnonzero(up[1:] != up[:-1])
        if chg.size:
            pos = chg + (w0 + 1)
            first = 0 if up[chg[0]] else 1  # without flat runs maxima and minima alternate
            maxima.append(pos[first::2])
            minima.append(pos[1 - first :: 2])
        z = out[max(a - 1, 0) : b]
        if np.equal(z, 0.0, out=flag[: z.size]).any():
            exact = False
            continue
        sgn = np.greater(z, 0, out=flag[: z.size])
        zc += int(np.count_nonzero(sgn[1:] != sgn[:-1]))
    if exact:
        imax, imin = np.concatenate(maxima), np.concatenate(minima)
    else:  # flat runs or exact zeros: the whole-record rules decide
        imax, imin = find_extrema(out)
        zc = count_zero_crossings(out)
    return SiftStats(e_mean, e_in, imax, imin, zc, over1, over2)
