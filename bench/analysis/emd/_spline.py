"""Envelope splines of :mod:`bench.analysis.emd._emd`: not-a-knot cubic splines through integer
knots, compiled with numba (the sifting loop in :mod:`.emd_kernel` calls these kernels).

A spline through knots ``(pos_i, y_i)`` is stored as per-interval polynomials
``y_i + c1_i·t + c2_i·t² + c3_i·t³`` in ``t = sample − pos_i``; a sample lying on a knot
uses the interval starting there (so it returns the knot value exactly).

The arithmetic follows the previous numpy implementation operation by operation (and
LAPACK's ``dpttrf``/``dptts2`` for the tridiagonal solve), so the slopes and values are
the same numbers; knot spacings are integers, which keeps most steps exact anyway.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

__all__ = ["Spline", "evaluate", "not_a_knot_slopes", "spline_coefficients", "spline_pair"]


@numba.njit(cache=True)
def spline_coefficients(pos, val, m, c1, c2, c3):
    """Not-a-knot cubic spline through the first ``m ≥ 2`` knots ``(pos, val)`` (``pos``
    integer, strictly increasing): slopes into ``c1[:m]``, ``c2, c3`` into ``[:m-1]``.

    Two knots give the line and three the parabola
    through them (scipy's ``CubicSpline`` special cases).  From four knots: the slope
    equations ``h_i s_{i-1} + 2(h_{i-1} + h_i) s_i + h_{i-1} s_{i+1} = 3(h_i δ_{i-1} +
    h_{i-1} δ_i)`` (``h`` knot spacings, ``δ`` secant slopes) divided by ``h_{i-1} h_i``,
    with the end slopes eliminated by the not-a-knot conditions, form a symmetric,
    strictly diagonally dominant tridiagonal system, solved by LDLᵀ without pivoting
    (LAPACK ``dptsv``'s recurrences).  Returns 0, or ``i + 1`` if pivot ``i`` is not
    positive (then the system is singular and the coefficients are undefined).
    """
    if m == 2:  # the line
        c1[0] = (val[1] - val[0]) / float(pos[1] - pos[0])
        c1[1] = c1[0]
        c2[0] = 0.0
        c3[0] = 0.0
        return 0
    if m == 3:  # the parabola: s1 from h1 s0 + 2(h0 + h1) s1 + h0 s2 = 3(h1 δ0 + h0 δ1), s0 = 2δ0 - s1, s2 = 2δ1 - s1
        h0, h1 = float(pos[1] - pos[0]), float(pos[2] - pos[1])
        d0, d1 = (val[1] - val[0]) / h0, (val[2] - val[1]) / h1
        c1[1] = (h0 * d1 + h1 * d0) / (h0 + h1)
        c1[0] = 2.0 * d0 - c1[1]
        c1[2] = 2.0 * d1 - c1[1]
        c2[0], c3[0] = _interval(h0, val[1] - val[0], c1[0], c1[1])
        c2[1], c3[1] = _interval(h1, val[2] - val[1], c1[1], c1[2])
        return 0
    diag, low = c2, c3  # D and L of LDLᵀ until the back substitution overwrites them
    h0, h1, hb, ha, d0, d1, r0, r1 = _ends(pos, val, m)
    k = m - 2  # unknown inner slopes s_1..s_{m-2}; row j holds s_{j+1}
    inv_a = 1.0 / h0
    ra = (val[1] - val[0]) * inv_a * inv_a
    y = lw = 0.0  # the previous substituted value and L entry
    bad = 0
    for j in range(k):
        inv_a, ra, dj, lw, y = _row(j, k, float(pos[j + 2] - pos[j + 1]), val[j + 2] - val[j + 1], inv_a, ra, y,
                                    lw, r0, r1)
        bad = j + 1 if dj <= 0.0 and bad == 0 else bad
        diag[j], low[j], c1[j + 1] = dj, lw, y
    if bad:
        return bad
    # back substitution, with each interval's c2, c3 as soon as both its slopes are known
    # (interval j+1's are written after row j's D and L are read)
    s1 = c1[k] = c1[k] / diag[k - 1]
    c1[m - 1] = (r1 - d1 * s1) / hb
    c2[m - 2], c3[m - 2] = _interval(ha, val[m - 1] - val[m - 2], s1, c1[m - 1])
    for j in range(k - 2, -1, -1):
        s2, s1 = s1, c1[j + 1] / diag[j] - s1 * low[j]
        c1[j + 1] = s1
        c2[j + 1], c3[j + 1] = _interval(float(pos[j + 2] - pos[j + 1]), val[j + 2] - val[j + 1], s1, s2)
    c1[0] = (r0 - d0 * s1) / h1
    c2[0], c3[0] = _interval(h0, val[1] - val[0], c1[0], s1)
    return 0


@numba.njit(cache=True)
def spline_pair(pu, vu, mu, u1, u2, u3, pl, vl, ml, l1, l2, l3):
    """:func:`spline_coefficients` of both envelopes: 0 or the first failing spline's code.

    The two recurrences run interleaved in one loop: each LDLᵀ step waits on a division,
    so two independent chains side by side cost little more than one."""
    if mu < 4 or ml < 4:
        info = spline_coefficients(pu, vu, mu, u1, u2, u3)
        return info if info else spline_coefficients(pl, vl, ml, l1, l2, l3)
    hu0, hu1, hub, hua, du0, du1, ru0, ru1 = _ends(pu, vu, mu)
    hl0, hl1, hlb, hla, dl0, dl1, rl0, rl1 = _ends(pl, vl, ml)
    ku, kl = mu - 2, ml - 2
    iu, il = 1.0 / hu0, 1.0 / hl0
    rau, ral = (vu[1] - vu[0]) * iu * iu, (vl[1] - vl[0]) * il * il
    yu = lu = yl = ll = 0.0
    bad = False
    for j in range(max(ku, kl)):
        if j < ku:
            iu, rau, dj, lu, yu = _row(j, ku, float(pu[j + 2] - pu[j + 1]), vu[j + 2] - vu[j + 1], iu, rau, yu,
                                       lu, ru0, ru1)
            bad |= dj <= 0.0
            u2[j], u3[j], u1[j + 1] = dj, lu, yu
        if j < kl:
            il, ral, dj, ll, yl = _row(j, kl, float(pl[j + 2] - pl[j + 1]), vl[j + 2] - vl[j + 1], il, ral, yl,
                                       ll, rl0, rl1)
            bad |= dj <= 0.0
            l2[j], l3[j], l1[j + 1] = dj, ll, yl
    if bad:  # the failing one's code
        info = spline_coefficients(pu, vu, mu, u1, u2, u3)
        return info if info else spline_coefficients(pl, vl, ml, l1, l2, l3)
    su = u1[ku] = u1[ku] / u2[ku - 1]
    u1[mu - 1] = (ru1 - du1 * su) / hub
    u2[mu - 2], u3[mu - 2] = _interval(hua, vu[mu - 1] - vu[mu - 2], su, u1[mu - 1])
    sl = l1[kl] = l1[kl] / l2[kl - 1]
    l1[ml - 1] = (rl1 - dl1 * sl) / hlb
    l2[ml - 2], l3[ml - 2] = _interval(hla, vl[ml - 1] - vl[ml - 2], sl, l1[ml - 1])
    for t in range(max(ku, kl) - 1):
        j = ku - 2 - t
        if j >= 0:
            s2, su = su, u1[j + 1] / u2[j] - su * u3[j]
            u1[j + 1] = su
            u2[j + 1], u3[j + 1] = _interval(float(pu[j + 2] - pu[j + 1]), vu[j + 2] - vu[j + 1], su, s2)
        j = kl - 2 - t
        if j >= 0:
            s2, sl = sl, l1[j + 1] / l2[j] - sl * l3[j]
            l1[j + 1] = sl
            l2[j + 1], l3[j + 1] = _interval(float(pl[j + 2] - pl[j + 1]), vl[j + 2] - vl[j + 1], sl, s2)
    u1[0] = (ru0 - du0 * su) / hu1
    u2[0], u3[0] = _interval(hu0, vu[1] - vu[0], u1[0], su)
    l1[0] = (rl0 - dl0 * sl) / hl1
    l2[0], l3[0] = _interval(hl0, vl[1] - vl[0], l1[0], sl)
    return 0


@numba.njit(cache=True)
def _ends(pos, val, m):
    """Spacings ``h0, h1, hb, ha`` at the ends and the not-a-knot end terms ``d0, d1, r0, r1``:
    ``s0 = (r0 − d0 s1)/h1``, ``s_end = (r1 − d1 s_{end−1})/hb`` (scipy's end rows)."""
    h0, h1 = float(pos[1] - pos[0]), float(pos[2] - pos[1])
    hb, ha = float(pos[m - 2] - pos[m - 3]), float(pos[m - 1] - pos[m - 2])
    d0, d1 = h0 + h1, hb + ha
    e0, e1 = (val[1] - val[0]) * (1.0 / h0), (val[2] - val[1]) * (1.0 / h1)
    eb, ea = (val[m - 2] - val[m - 3]) * (1.0 / hb), (val[m - 1] - val[m - 2]) * (1.0 / ha)
    r0 = ((h0 + 2 * d0) * h1 * e0 + h0 * h0 * e1) / d0
    r1 = (ha * ha * eb + (2 * d1 + ha) * hb * ea) / d1
    return h0, h1, hb, ha, d0, d1, r0, r1


@numba.njit(cache=True, inline="always")
def _row(j, k, h, dy, inv_a, ra, y, lw, r0, r1):
    """Row ``j`` (slope ``s_{j+1}``) of the slope system divided by ``h_j h_{j+1}``, its LDLᵀ
    step (dpttrf) and forward substitution (dptts2), by the same operations as the LAPACK
    route.  ``h, dy``: interval ``j+1``; ``inv_a, ra``: ``1/h_j`` and ``δ_j/h_j``; ``y, lw``:
    the previous row's substituted value and L entry.  Returns ``1/h_{j+1}``, ``δ_{j+1}/h_{j+1}``,
    the pivot D_j, L_j and the substituted value.  Scalars only: an inlined helper taking
    arrays pays reference counting per call (measured 5× slower)."""
    inv_b = 1.0 / h
    rb = dy * inv_b * inv_b
    rhs = (ra + rb) * 3.0
    dj = (inv_a + inv_b) * 2.0
    if j == 0:
        dj *= 0.5  # the end rows lose half their diagonal to the eliminated end slopes
        rhs -= r0 * inv_a * inv_b
    else:
        if j == k - 1:
            dj *= 0.5
            rhs -= r1 * inv_a * inv_b
        dj = dj - lw * inv_a  # inv_a: the off-diagonal of rows j-1, j
        rhs = rhs - y * lw
    return inv_b, rb, dj, inv_b / dj, rhs


@numba.njit(cache=True, inline="always")
def _interval(h, dy, s0, s1):
    """``c2, c3`` of an interval of length ``h``, rise ``dy`` and end slopes ``s0, s1``
    (scalars only: no reference counting when inlined)."""
    delta = dy / h
    return (3.0 * delta - 2.0 * s0 - s1) / h, (s0 + s1 - 2.0 * delta) / (h * h)


@numba.njit(cache=True)
def evaluate(pos, c0, c1, c2, c3, m, n, out):
    """The spline with ``m`` knots at samples ``0..n-1`` into ``out`` (``pos[0] ≤ 0``:
    samples past the last knot use the last interval)."""
    j = 0
    for i in range(n):
        while j < m - 2 and pos[j + 1] <= i:
            j += 1
        t = float(i - pos[j])
        out[i] = ((c3[j] * t + c2[j]) * t + c1[j]) * t + c0[j]


def _coefficients(pos: np.ndarray, val: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    pos = np.ascontiguousarray(pos, dtype=np.int64)
    val = np.ascontiguousarray(val, dtype=float)
    m = pos.size
    if m < 2 or val.size != m:
        raise ValueError(f"a spline needs ≥ 2 knots with one value each, got {m} positions and {val.size} values")
    if np.any(np.diff(pos) <= 0):
        raise ValueError("knot positions must be strictly increasing")
    c1, c2, c3 = np.empty(m), np.empty(m), np.empty(m)
    info = spline_coefficients(pos, val, m, c1, c2, c3)
    if info != 0:
        raise ValueError(f"envelope spline system is singular (pivot {info} not positive)")
    return c1, c2, c3


def not_a_knot_slopes(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """First derivatives at the integer knots ``x`` of the not-a-knot cubic spline through ``(x, y)``
    (the same slopes as scipy's ``CubicSpline`` to rounding)."""
    x = np.asarray(x)
    if np.any(x != np.round(x)):
        raise ValueError("knot positions must be integers (sample indices)")
    return _coefficients(x.astype(np.int64), y)[0]


@dataclass(frozen=True, eq=False)
class Spline:
    """A not-a-knot cubic spline through integer knots (diagnostics and tests; the
    sifting keeps its coefficients in reused buffers instead)."""

    pos: np.ndarray  # knot positions (int64)
    c0: np.ndarray  # knot values
    c1: np.ndarray
    c2: np.ndarray
    c3: np.ndarray

    @classmethod
    def through(cls, pos: np.ndarray, val: np.ndarray) -> Spline:
        """The spline through ``(pos, val)``, ``pos`` strictly increasing integers."""
        pos = np.ascontiguousarray(pos, dtype=np.int64)
        val = np.ascontiguousarray(val, dtype=float)
        return cls(pos, val, *_coefficients(pos, val))

    def __call__(self, n: int) -> np.ndarray:
        """The spline at samples ``0..n-1`` (``pos[0] ≤ 0`` expected: earlier samples use the first interval)."""
        out = np.empty(n)
        evaluate(self.pos, self.c0, self.c1, self.c2, self.c3, self.pos.size, n, out)
        return out
