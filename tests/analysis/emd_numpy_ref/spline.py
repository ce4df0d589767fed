"""Envelope splines of :mod:`bench.analysis.emd._emd`: not-a-knot cubic splines through integer
knots, their evaluation block by block, and the scratch arrays every sifting reuses.

Speed notes (see :mod:`.emd_kernel` for the sifting pass that calls these):

* Spline coefficients come from one symmetric tridiagonal solve per envelope (LAPACK
  ``ptsv``, about half of the set-up); the rest of the set-up runs in cache-sized
  chunks on arrays kept in the :class:`Workspace` (fresh arrays of 10⁵ knots cost as
  much in page faults as their arithmetic).
* A sample's interval is known from the block's knot range, so no per-sample search
  happens: ``np.repeat`` of the per-interval sample counts when intervals are longer
  than ~4 samples, else a running count of knots — one for both envelopes (upper knots
  count 1, lower ones 2³²), as the cumulative sum is the dearest per-sample step.
  Gathers use ``mode="wrap"``: the default ``"raise"`` with ``out=`` gathers into a
  temporary first and costs half as much again.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, overload

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.linalg import lapack

BLOCK = 16384  # samples per block: a handful of float arrays of this size stay in L2


# --------------------------------------------------------------------------- splines


SPLINE_CHUNK = 8192  # knots per chunk of the spline set-up: its temporaries stay in L2


def not_a_knot_slopes(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """First derivatives at the knots of the not-a-knot cubic spline through ``(x, y)``, ≥ 4 knots.

    The slope equations ``h_i s_{i-1} + 2(h_{i-1} + h_i) s_i + h_{i-1} s_{i+1} = 3(h_i δ_{i-1} +
    h_{i-1} δ_i)`` (``h`` knot spacings, ``δ`` secant slopes) divided by ``h_{i-1} h_i`` are
    symmetric; eliminating the end slopes with the not-a-knot conditions (scipy's end
    rows) keeps them symmetric and strictly diagonally dominant, so LAPACK's ``ptsv``
    (LDLᵀ, no pivoting) solves them — the same slopes as ``CubicSpline`` to rounding.
    """
    return _not_a_knot(x, y, coefficients=False)[0]


@overload
def _not_a_knot(x: np.ndarray, y: np.ndarray, coefficients: Literal[True] = True,
                scratch: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...


@overload
def _not_a_knot(x: np.ndarray, y: np.ndarray, coefficients: Literal[False],
                scratch: np.ndarray | None = None) -> tuple[np.ndarray, None, None]: ...


def _not_a_knot(x: np.ndarray, y: np.ndarray, coefficients: bool = True, scratch: np.ndarray | None = None
                ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """Slopes ``s`` at the knots and, with ``coefficients``, the per-interval ``c2, c3`` of
    ``y_i + s_i t + c2 t² + c3 t³``.

    Every step but the LAPACK solve runs chunk by chunk so that its temporaries stay in
    cache (whole-record temporaries of 10⁵ knots made each step memory-bound); each value
    is computed by the same operations in the same order as whole-array code would.
    ``scratch`` (shape ``(≥ 7, ≥ x.size)``, e.g. from :meth:`Workspace.scratch`) holds
    the results and intermediates instead of fresh arrays.
    """
    m = x.size
    if scratch is None:
        scratch = np.empty((7, m))
    dx, dy, inv, s, diag, c2, c3 = (scratch[k, :m] for k in range(7))
    dx, dy, inv, diag, c2, c3 = dx[:-1], dy[:-1], inv[:-1], diag[:-2], c2[:-1], c3[:-1]
    rhs = s[1:-1]  # ptsv solves in place: the inner slopes land in s
    for j0 in range(0, m - 2, SPLINE_CHUNK):  # unknowns j0..j1-1 need intervals j0..j1
        j1 = min(j0 + SPLINE_CHUNK, m - 2)
        w = slice(j0, j1 + 1)
        np.subtract(x[j0 + 1 : j1 + 2], x[j0 : j1 + 1], out=dx[w])
        np.subtract(y[j0 + 1 : j1 + 2], y[j0 : j1 + 1], out=dy[w])
        iv = np.divide(1.0, dx[w], out=inv[w])
        r = dy[w] * iv  # secant slope δ
        r *= iv
        np.add(r[:-1], r[1:], out=rhs[j0:j1])
        rhs[j0:j1] *= 3.0
        np.add(iv[:-1], iv[1:], out=diag[j0:j1])
        diag[j0:j1] *= 2.0
    diag[0] *= 0.5  # the end rows lose half their diagonal to the eliminated end slopes
    diag[-1] *= 0.5
    h0, h1, hb, ha = dx[0], dx[1], dx[-2], dx[-1]
    d0, d1 = h0 + h1, hb + ha
    end_delta = (dy[0] * inv[0], dy[1] * inv[1], dy[-2] * inv[-2], dy[-1] * inv[-1])
    r0 = ((h0 + 2 * d0) * h1 * end_delta[0] + h0**2 * end_delta[1]) / d0  # s0 = (r0 - d0 s1) / h1
    r1 = (ha**2 * end_delta[-2] + (2 * d1 + ha) * hb * end_delta[-1]) / d1  # s_end = (r1 - d1 s_{end-1}) / hb
    rhs[0] -= r0 * inv[0] * inv[1]
    rhs[-1] -= r1 * inv[-2] * inv[-1]
    # ptsv overwrites its inputs: none of them is needed afterwards
    *_, sol, info = lapack.dptsv(diag, inv[1:-1], rhs, overwrite_d=1, overwrite_e=1, overwrite_b=1)
    if info != 0:
        raise ValueError(f"envelope spline system is singular (LAPACK ptsv info = {info})")
    if not np.shares_memory(sol, s):
        s[1:-1] = sol
    s[0] = (r0 - d0 * s[1]) / h1
    s[-1] = (r1 - d1 * s[-2]) / hb
    if not coefficients:
        return s, None, None
    for i0 in range(0, m - 1, SPLINE_CHUNK):
        w = slice(i0, min(i0 + SPLINE_CHUNK, m - 1))
        h, s0, s1 = dx[w], s[i0 : w.stop], s[i0 + 1 : w.stop + 1]
        delta = dy[w] / h
        a = 3.0 * delta  # c2 = (3δ - 2 s0 - s1) / h
        a -= 2.0 * s0
        a -= s1
        np.divide(a, h, out=c2[w])
        b = s0 + s1  # c3 = (s0 + s1 - 2δ) / h²
        b -= 2.0 * delta
        h *= h
        np.divide(b, h, out=c3[w])
    return s, c2, c3


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
    def through(cls, pos: np.ndarray, val: np.ndarray, scratch: np.ndarray | None = None) -> Spline:
        """The spline through ``(pos, val)``; ``scratch`` (shape ``(≥ 8, ≥ pos.size)``) holds
        its arrays instead of fresh ones (they stay valid until ``scratch`` is reused)."""
        if scratch is None:
            x = pos.astype(float)
        else:
            x = scratch[7, : pos.size]
            x[:] = pos
        if x.size >= 4:
            s, c2, c3 = _not_a_knot(x, val, scratch=scratch)
            return cls(pos, x[:-1], val[:-1], s[:-1], c2, c3)
        c3, c2, c1, c0 = CubicSpline(x, val).c  # 2-3 knots: scipy's line / parabola
        return cls(pos, x[:-1], c0, c1, c2, c3)

    @classmethod
    def average(cls, a: Spline, b: Spline) -> Spline:
        """``(a + b) / 2`` as one piecewise cubic on the union of both knot sets, where both
        are defined: each polynomial re-expanded (Taylor shift) at the merged interval starts.

        Chunked like :func:`_not_a_knot` so that the temporaries stay in cache."""
        lo, hi = max(a.pos[0], b.pos[0]), min(a.pos[-1], b.pos[-1])
        pos = np.concatenate([a.pos, b.pos])
        order = np.argsort(pos, kind="stable")  # two sorted runs: a linear merge, a's knot first on ties
        pos = pos[order]
        # the interval of a (of b) holding each merged knot: a running count of its knots
        ia = np.cumsum(order < a.pos.size, dtype=np.intp)
        ib = np.arange(1, pos.size + 1) - ia
        ia -= 1
        ib -= 1
        keep = np.empty(pos.size, dtype=bool)  # of repeated positions the last, which counts both
        np.not_equal(pos[1:], pos[:-1], out=keep[:-1])
        keep[-1] = True
        keep &= pos >= lo
        keep &= pos <= hi
        pos, ia, ib = pos[keep], ia[keep][:-1], ib[keep][:-1]
        np.clip(ia, 0, a.pos.size - 2, out=ia)
        np.clip(ib, 0, b.pos.size - 2, out=ib)
        start = pos[:-1].astype(float)
        m = start.size
        c0, c1, c2, c3 = (np.empty(m) for _ in range(4))
        for k0 in range(0, m, SPLINE_CHUNK):
            w = slice(k0, min(k0 + SPLINE_CHUNK, m))
            q = [s._shifted(i[w], start[w]) for s, i in ((a, ia), (b, ib))]
            for out, p, r in zip((c0, c1, c2, c3), *q):
                np.add(p, r, out=out[w])
                out[w] *= 0.5
        return cls(pos, start, c0, c1, c2, c3)

    def _shifted(self, i: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, ...]:
        """Coefficients ``c0..c3`` of interval ``i``'s polynomial re-expanded about ``x``."""
        d = np.subtract(x, np.take(self.start, i, mode="wrap"))
        c1, c2, c3 = (np.take(c, i, mode="wrap") for c in (self.c1, self.c2, self.c3))
        v = c3 * d  # c0 + d (c1 + d (c2 + d c3))
        v += c2
        v *= d
        v += c1
        v *= d
        v += np.take(self.c0, i, mode="wrap")
        e = 3.0 * c3  # 3 c3 d
        e *= d
        u = 2.0 * c2  # c1 + d (2 c2 + 3 c3 d)
        u += e
        u *= d
        u += c1
        e += c2  # c2 + 3 c3 d
        return v, u, e, c3

    def block_ranges(self, starts: np.ndarray, stops: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """First and last interval touching each block ``[start, stop)``."""
        last = self.pos.size - 2
        lo = np.searchsorted(self.pos, starts, side="right") - 1
        hi = np.minimum(np.searchsorted(self.pos, stops - 1, side="right") - 1, last)
        return lo, hi

    def short_intervals(self, a: int, b: int, lo: int, hi: int) -> bool:
        """Whether :meth:`evaluate_block` gathers by interval index on block ``[a, b)``."""
        return 4 * (hi - lo) >= b - a

    def evaluate_block(self, a: int, b: int, lo: int, hi: int, ws: Workspace, out: np.ndarray,
                       idx: np.ndarray | None = None) -> None:
        """Write the spline at samples ``a..b-1`` into ``out`` (intervals ``lo..hi``; scratch from
        ``ws``); ``idx``, when given, is each sample's interval index (short intervals only)."""
        m = b - a
        grid, t, tmp = ws.grid, ws.t[:m], ws.tmp[:m]
        inner = self.pos[lo + 1 : hi + 1]  # knots inside the block, all in (a, b)
        if idx is None and not self.short_intervals(a, b, lo, hi):
            # intervals longer than ~4 samples: expanding the coefficients run by run beats
            # the running count and gathers below (measured: 0.4–0.7× their time)
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
        if idx is None:
            idx = ws.idx[:m]
            idx[:] = 0
            idx[inner - a] = 1
            idx[0] = lo
            np.cumsum(idx, out=idx)
        # mode="wrap": the indices are valid, and "raise" gathers into a temporary first
        np.take(self.start, idx, out=t, mode="wrap")
        np.subtract(grid[a:b], t, out=t)
        np.take(self.c3, idx, out=out, mode="wrap")
        for c in (self.c2, self.c1, self.c0):  # Horner
            out *= t
            np.take(c, idx, out=tmp, mode="wrap")
            out += tmp

    def __call__(self, n: int) -> np.ndarray:
        """The spline at samples ``0..n-1`` (blocked like a sifting)."""
        ws = Workspace(n)
        out = np.empty(n)
        lo, hi = self.block_ranges(ws.starts, ws.stops)
        for k, (a, b) in enumerate(zip(ws.starts.tolist(), ws.stops.tolist())):
            self.evaluate_block(a, b, int(lo[k]), int(hi[k]), ws, out[a:b])
        return out


# --------------------------------------------------------------------------- scratch


class Workspace:
    """Scratch arrays reused by every sifting of one record."""

    def __init__(self, n: int, block: int | None = None):
        self.n = n
        self.grid = np.arange(n, dtype=float)
        b = min(BLOCK if block is None else block, n)
        self.starts = np.arange(0, n, b)
        self.stops = np.minimum(self.starts + b, n)
        self.t, self.u, self.lo, self.tmp = (np.empty(b) for _ in range(4))
        self.idx, self.idx2 = np.empty(b, dtype=np.intp), np.empty(b, dtype=np.intp)
        self.d = np.empty(b + 1)  # differences of a block and the two samples before it
        self.flag = np.empty(b + 1, dtype=bool)
        self._scratch: dict[int, np.ndarray] = {}

    def scratch(self, slot: int, m: int) -> np.ndarray:
        """A ``(8, ≥ m)`` array kept for ``slot`` (one per envelope): reusing it spares the
        page faults of fresh arrays of 10⁵ knots, which cost as much as the arithmetic."""
        buf = self._scratch.get(slot)
        if buf is None or buf.shape[1] < m:
            # headroom: the knot count creeps up over the siftings of an IMF
            buf = self._scratch[slot] = np.empty((8, max(m + m // 4, 64)))
        return buf


def interval_indices(a: int, m: int, pu: np.ndarray, uk: tuple[int, int], pl: np.ndarray, lk: tuple[int, int],
                      ws: Workspace) -> tuple[np.ndarray, np.ndarray]:
    """Both envelopes' interval index of every sample of block ``[a, a + m)`` from ONE running
    count (upper knots count 1, lower knots 2³², split afterwards): a cumulative sum costs
    more than all other per-sample steps of an evaluation together."""
    both = ws.idx[:m]
    both[:] = 0
    both[pu[uk[0] + 1 : uk[1] + 1] - a] = 1
    both[pl[lk[0] + 1 : lk[1] + 1] - a] += 1 << 32  # += : a knot of both kinds counts for both
    both[0] += uk[0] + (lk[0] << 32)
    np.cumsum(both, out=both)
    il = np.right_shift(both, 32, out=ws.idx2[:m])
    return np.bitwise_and(both, 0xFFFFFFFF, out=both), il
