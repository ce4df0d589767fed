"""The inner loop of :mod:`bench.analysis.emd._emd`, compiled with numba: extrema, mirrored
envelope knots, one sifting, and the whole sifting loop of one IMF.

Speed notes (measured beside PyEMD in ``benchmarks/bench_emd.py``; the sifting count is
fixed by the stop criterion, so only the cost of one sifting can be cut):

* One compiled call (:func:`sift_imf`) sifts one IMF to the end: no Python, no
  temporaries between siftings; all buffers are allocated once per IMF.
* One sifting is two loops over the record: the envelope mean (two interval pointers
  walking their knots, Horner; Rilling's counts), then ``h − mean`` with the sums of
  the SD criterion and the extrema and zero crossings of the result.  One fused loop
  measured twice as slow; both loops are branch-free (the extrema of noise are
  unpredictable).  The spline set-up is O(knots) (:mod:`.emd_spline`).
* The extrema of the result are written, with their values, straight into the knot
  arrays of the next sifting (room left in front for the mirrored knots), so each
  sifting finds extrema once (PyEMD: three times) and copies no knots.
* Measured on 3.5·10⁵ samples, about a third of a sifting each: the two spline solves
  (bound by division throughput: six divisions per knot), the envelope mean and the
  scan.  numba helpers that take arrays are not inlined into hot loops: an inlined
  call pays reference counting each time (measured 5× slower).

The arithmetic repeats the previous numpy implementation's operation by operation, so
the IMFs are the same bit for bit (``tests/analysis/test_analysis_emd_compiled.py``); only the
order of the two energy sums differs, which moves the SD ratio by rounding.

numba's on-disk cache does not notice a change in another module: after editing
:mod:`.emd_spline` or :mod:`.emd_extrema`, delete ``bench/analysis/__pycache__/emd_*.nb?``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from bench.analysis.emd._extrema import count_zero_crossings, count_zero_crossings_kernel, extrema_into, find_extrema
from bench.analysis.emd._spline import Spline, evaluate, not_a_knot_slopes, spline_pair

__all__ = ["SiftStats", "Spline", "count_zero_crossings", "envelope_knots", "evaluate", "find_extrema",
           "not_a_knot_slopes", "sift", "sift_imf", "STOP_CODES"]

STOP_CODES = {"sd": 0, "rilling": 1, "s-number": 2}
DEGENERATE, CONVERGED, MAX_SIFTS = 0, 1, 2  # how sift_imf ended
TINY = float(np.finfo(float).tiny)


# --------------------------------------------------------------------------- ends


@numba.njit(cache=True)
def _mirror_start(first, imax, vmax, imin, vmin, nbsym):
    """Knots reflected before sample 0: ``(pos_max, val_max, pos_min, val_min)``, ascending.

    Rilling's rule: reflect about the first extremum unless the first sample lies beyond
    the first extremum of the other kind, in which case sample 0 itself acts as an
    extremum of that kind and the reflection is about it.  Falls back to reflecting the
    first ``nbsym`` extrema about sample 0 when the reflected knots would not reach it.
    """
    extra_max = extra_min = False
    if imax[0] < imin[0]:  # the first extremum is a maximum
        if first > vmin[0]:
            sym, a0, a1, b0, b1 = imax[0], 1, nbsym + 1, 0, nbsym
        else:  # sample 0 acts as a minimum
            sym, a0, a1, b0, b1, extra_min = 0, 0, nbsym, 0, nbsym - 1, True
    elif first < vmax[0]:
        sym, a0, a1, b0, b1 = imin[0], 0, nbsym, 1, nbsym + 1
    else:  # sample 0 acts as a maximum
        sym, a0, a1, b0, b1, extra_max = 0, 0, nbsym - 1, 0, nbsym, True
    pmax, qmax = _with_extra(imax[a0:a1], vmax[a0:a1], extra_max, first)
    pmin, qmin = _with_extra(imin[b0:b1], vmin[b0:b1], extra_min, first)
    tmax, tmin = 2 * sym - pmax, 2 * sym - pmin
    if tmax.size == 0 or tmin.size == 0 or tmax.min() > 0 or tmin.min() > 0:
        tmax, qmax = -imax[:nbsym], vmax[:nbsym].copy()
        tmin, qmin = -imin[:nbsym], vmin[:nbsym].copy()
    return tmax[::-1].copy(), qmax[::-1].copy(), tmin[::-1].copy(), qmin[::-1].copy()


@numba.njit(cache=True)
def _with_extra(p, q, extra, first):
    k = 1 if extra else 0
    pos, val = np.empty(p.size + k, dtype=np.int64), np.empty(p.size + k)
    if extra:
        pos[0], val[0] = 0, first
    pos[k:], val[k:] = p, q
    return pos, val


@numba.njit(cache=True)
def _place(pos, val, off, count, lp, lv, rp, rv, n):
    """Around the extrema at ``pos/val[off : off + count]``: the left reflections before them
    and the right ones (mapped back) after, in place; a knot whose position does not
    exceed the one before it is dropped (a reflection landing on a knot; by the
    reflection rules it does not happen, so the check is cheap and the compaction rare).
    Returns ``(first, number)`` of the knots."""
    first = off - lp.size
    pos[first:off] = lp
    val[first:off] = lv
    end = off + count
    for j in range(rp.size):
        pos[end + j] = n - 1 - rp[rp.size - 1 - j]
        val[end + j] = rv[rv.size - 1 - j]
    m = end + rp.size - first
    strict = True
    for j in range(first + 1, min(off + 1, first + m)):  # the left knots and the first junction
        strict &= pos[j] > pos[j - 1]
    for j in range(max(end, first + 1), first + m):  # the last junction and the right knots
        strict &= pos[j] > pos[j - 1]
    if strict:
        return first, m
    prev = pos[first]
    w = first + 1
    for j in range(first + 1, first + m):
        p = pos[j]
        if p > prev:
            pos[w] = p
            val[w] = val[j]
            w += 1
        prev = p
    return first, w - first


@numba.njit(cache=True)
def _side(pos, val, off, count, nbsym, reverse, n):
    """The first ``nbsym + 1`` extrema at ``pos/val[off : off + count]`` or, with ``reverse``,
    the last ``nbsym + 1`` in the reversed record's coordinates (``n − 1 − i``, ascending):
    all that a reflection can use."""
    k = min(count, nbsym + 1)
    p, v = np.empty(k, dtype=np.int64), np.empty(k)
    for j in range(k):
        i = off + count - 1 - j if reverse else off + j
        p[j] = n - 1 - pos[i] if reverse else pos[i]
        v[j] = val[i]
    return p, v


@numba.njit(cache=True)
def _knots_in_place(h0, h1, n, px, vx, nmax, pn, vn, nmin, nbsym, off):
    """Envelope knots with mirrored ends around the extrema stored at ``[off : off + count]``
    of ``px/vx`` (maxima) and ``pn/vn`` (minima); ``h0, h1`` the first and last samples:
    ``(first_max, m_max, first_min, m_min)``."""
    fmx, fvx = _side(px, vx, off, nmax, nbsym, False, n)
    fmn, fvn = _side(pn, vn, off, nmin, nbsym, False, n)
    lpx, lvx, lpn, lvn = _mirror_start(h0, fmx, fvx, fmn, fvn, nbsym)
    # the end is the start of the reversed record: reflect there and map back
    bmx, bvx = _side(px, vx, off, nmax, nbsym, True, n)
    bmn, bvn = _side(pn, vn, off, nmin, nbsym, True, n)
    rpx, rvx, rpn, rvn = _mirror_start(h1, bmx, bvx, bmn, bvn, nbsym)
    sx, mx = _place(px, vx, off, nmax, lpx, lvx, rpx, rvx, n)
    sn, mn = _place(pn, vn, off, nmin, lpn, lvn, rpn, rvn, n)
    return sx, mx, sn, mn


def envelope_knots(h: np.ndarray, imax: np.ndarray, imin: np.ndarray, nbsym: int
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Envelope knots ``(pos_max, val_max, pos_min, val_min)`` with mirrored ends.

    Needs at least one maximum and one minimum; positions are strictly increasing
    integers whose first is ≤ 0 and last ≥ ``h.size - 1``.
    """
    h = np.ascontiguousarray(h, dtype=float)
    imax, imin = (np.ascontiguousarray(i, dtype=np.int64) for i in (imax, imin))
    if imax.size < 1 or imin.size < 1:
        raise ValueError(f"envelopes need ≥ 1 maximum and ≥ 1 minimum, got {imax.size} and {imin.size}")
    off = nbsym + 2
    px = np.empty(off + imax.size + nbsym + 2, dtype=np.int64)
    pn = np.empty(off + imin.size + nbsym + 2, dtype=np.int64)
    vx, vn = np.empty(px.size), np.empty(pn.size)
    px[off : off + imax.size], vx[off : off + imax.size] = imax, h[imax]
    pn[off : off + imin.size], vn[off : off + imin.size] = imin, h[imin]
    sx, mx, sn, mn = _knots_in_place(h[0], h[-1], h.size, px, vx, imax.size, pn, vn, imin.size, nbsym, off)
    return px[sx : sx + mx].copy(), vx[sx : sx + mx].copy(), pn[sn : sn + mn].copy(), vn[sn : sn + mn].copy()


# --------------------------------------------------------------------------- one sifting


@numba.njit(cache=True)
def _envelope_mean(out, px, vx, mx, u1, u2, u3, pn, vn, mn, l1, l2, l3, rilling, th1, th2):
    """``out = (upper + lower)/2`` at every sample; with ``rilling``, the counts of samples
    where ``|mean| > θ1·a`` and ``> θ2·a`` (``a = |lower − mean|``, the envelope half-range).

    Branch-free: knot positions are distinct integers, so an interval pointer moves at
    most once per sample (a data-dependent branch per sample and envelope cost more
    than all the arithmetic)."""
    ju = jl = over1 = over2 = 0
    eu, el = mx - 2, mn - 2
    n = out.size
    for i in range(n):
        if i < n - 1:  # the last knots lie at n − 1 or later: no pointer passes its last interval here
            ju += px[ju + 1] <= i
            jl += pn[jl + 1] <= i
        else:
            ju += (ju < eu) & (px[ju + 1] <= i)
            jl += (jl < el) & (pn[jl + 1] <= i)
        t = float(i - px[ju])
        up = ((u3[ju] * t + u2[ju]) * t + u1[ju]) * t + vx[ju]
        t = float(i - pn[jl])
        lo = ((l3[jl] * t + l2[jl]) * t + l1[jl]) * t + vn[jl]
        mean = (up + lo) * 0.5
        out[i] = mean
        if rilling:
            half = abs(lo - mean)
            over1 += abs(mean) > th1 * half
            over2 += abs(mean) > th2 * half
    return over1, over2


@numba.njit(cache=True)
def _subtract_scan(h, out, imax, imin, vmax, vmin):
    """``out = h − out`` (``out`` holding the envelope mean) with ``(Σ mean², Σ h², n_max,
    n_min, zero crossings)``; the extrema of the result go to ``imax``/``imin`` and their
    values to ``vmax``/``vmin`` (one spare slot each).

    Without flat runs or exact zeros (the rule for every sifting of a noisy record) an
    extremum is a sign change of consecutive differences: branch-free, as the extrema of
    noise are unpredictable, every candidate is written and the counts decide.  Otherwise
    the general rules of :func:`extrema_into` and :func:`count_zero_crossings` decide."""
    e_mean = e_in = 0.0
    nmax = nmin = zc = 0
    flat = False
    prev = dprev = 0.0
    for i in range(2):  # the first two samples: no extremum can end there yet
        mean = out[i]
        hi = h[i]
        e_mean += mean * mean
        e_in += hi * hi
        v = hi - mean
        out[i] = v
        if i == 1:
            dprev = v - prev
            zc += (v > 0.0) != (prev > 0.0)
            flat |= dprev == 0.0
        flat |= v == 0.0
        prev = v
    for i in range(2, h.size):
        mean = out[i]
        hi = h[i]
        e_mean += mean * mean
        e_in += hi * hi
        v = hi - mean
        out[i] = v
        d = v - prev
        imax[nmax] = i - 1
        imin[nmin] = i - 1
        vmax[nmax] = prev
        vmin[nmin] = prev
        nmax += (dprev > 0.0) & (d < 0.0)
        nmin += (dprev < 0.0) & (d > 0.0)
        zc += (v > 0.0) != (prev > 0.0)
        flat |= (d == 0.0) | (v == 0.0)
        dprev = d
        prev = v
    if flat:
        nmax, nmin = extrema_into(out, imax, imin)
        zc = count_zero_crossings_kernel(out)
        for j in range(nmax):
            vmax[j] = out[imax[j]]
        for j in range(nmin):
            vmin[j] = out[imin[j]]
    return e_mean, e_in, nmax, nmin, zc


@numba.njit(cache=True)
def _sift_pass(h, out, px, vx, mx, u1, u2, u3, pn, vn, mn, l1, l2, l3, rilling, th1, th2,
               imax, imin, vmax, vmin):
    """``out = h − (upper + lower)/2`` with ``(Σ mean², Σ h², n_max, n_min, zero crossings,
    Rilling's counts over θ1 and θ2)`` of the result; its extrema go to ``imax``/``imin``,
    their values to ``vmax``/``vmin``.

    Two loops over the record (envelope mean; subtraction, sums, extrema and zero
    crossings): one fused loop measured twice as slow (register pressure), and a
    cache-blocked version gained nothing."""
    over1, over2 = _envelope_mean(out, px, vx, mx, u1, u2, u3, pn, vn, mn, l1, l2, l3, rilling, th1, th2)
    e_mean, e_in, nmax, nmin, zc = _subtract_scan(h, out, imax, imin, vmax, vmin)
    return e_mean, e_in, nmax, nmin, zc, over1, over2


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


def sift(h: np.ndarray, imax: np.ndarray, imin: np.ndarray, nbsym: int = 2,
         thetas: tuple[float, float] = (0.05, 0.5)) -> tuple[np.ndarray, SiftStats]:
    """One sifting of ``h`` (extrema ``imax``, ``imin``): ``(h − mean envelope, stats)``."""
    h = np.ascontiguousarray(h, dtype=float)
    px, vx, pn, vn = envelope_knots(h, imax, imin, nbsym)
    up, lo = Spline.through(px, vx), Spline.through(pn, vn)
    out = np.empty_like(h)
    ext_max, ext_min = np.empty(h.size // 2 + 2, dtype=np.int64), np.empty(h.size // 2 + 2, dtype=np.int64)
    e_mean, e_in, nmax, nmin, zc, o1, o2 = _sift_pass(
        h, out, up.pos, up.c0, up.pos.size, up.c1, up.c2, up.c3, lo.pos, lo.c0, lo.pos.size, lo.c1, lo.c2, lo.c3,
        True, float(thetas[0]), float(thetas[1]), ext_max, ext_min, np.empty(ext_max.size), np.empty(ext_min.size))
    return out, SiftStats(e_mean, e_in, ext_max[:nmax].copy(), ext_min[:nmin].copy(), zc, o1, o2)


# --------------------------------------------------------------------------- one IMF


@numba.njit(cache=True)
def sift_imf(r, buf0, buf1, imax0, imin0, stop_code, max_sifts, sd_threshold, th1, th2, alpha,
             s_number, nbsym):
    """Sift one IMF out of ``r`` (extrema ``imax0``, ``imin0``), ping-ponging between
    ``buf0`` and ``buf1``: ``(how, siftings, where)`` with ``how`` one of DEGENERATE,
    CONVERGED, MAX_SIFTS (or −1: singular spline system) and ``where`` the buffer holding
    the IMF (0, 1; −1: ``r`` itself).  Stop rules and codes: :data:`STOP_CODES`,
    :mod:`bench.analysis.emd._emd`."""
    n = r.size
    off = nbsym + 2  # room for the left reflections before the extrema
    cap = off + n // 2 + 2 + nbsym + 2  # + extrema of one kind (one spare) + right reflections
    # two sets (this sifting's knots, the next one's extrema) of maxima and minima: the
    # sifting pass writes the extrema of its result where they become the next knots
    kp = np.empty((4, cap), dtype=np.int64)
    kv = np.empty((4, cap))
    coef = np.empty((6, cap))
    nmax, nmin = imax0.size, imin0.size
    for j in range(nmax):
        kp[0, off + j], kv[0, off + j] = imax0[j], r[imax0[j]]
    for j in range(nmin):
        kp[1, off + j], kv[1, off + j] = imin0[j], r[imin0[j]]
    cur, which, k, stable, c_ext, c_zc = 0, -1, 0, 0, -1, -1
    rilling = stop_code == 1
    h = r
    while True:
        px, vx, pn, vn = kp[2 * cur], kv[2 * cur], kp[2 * cur + 1], kv[2 * cur + 1]
        sx, mx, sn, mn = _knots_in_place(h[0], h[n - 1], n, px, vx, nmax, pn, vn, nmin, nbsym, off)
        px, vx, pn, vn = px[sx:], vx[sx:], pn[sn:], vn[sn:]
        if spline_pair(px, vx, mx, coef[0], coef[1], coef[2], pn, vn, mn, coef[3], coef[4], coef[5]) != 0:
            return -1, k, which
        dest = 1 if which == 0 else 0
        out = buf1 if dest == 1 else buf0
        nxt = 1 - cur
        e_mean, e_in, nmax, nmin, zc, over1, over2 = _sift_pass(
            h, out, px, vx, mx, coef[0], coef[1], coef[2], pn, vn, mn, coef[3], coef[4], coef[5],
            rilling, th1, th2, kp[2 * nxt, off:], kp[2 * nxt + 1, off:], kv[2 * nxt, off:], kv[2 * nxt + 1, off:])
        if rilling:
            if over1 <= alpha * n and over2 == 0:
                return CONVERGED, k, which  # h's own envelopes are symmetric enough: h is the IMF
            if k == max_sifts:
                return MAX_SIFTS, k, which
        k += 1
        cur = nxt
        n_ext = nmax + nmin
        if n_ext < 3:
            return DEGENERATE, k, which
        balanced = abs(n_ext - zc) <= 1
        if stop_code == 0:
            shaped = vx[:mx].min() >= 0.0 and vn[:mn].max() <= 0.0  # h's knots, mirrored ones included
            if shaped and balanced and e_mean / max(e_in, TINY) < sd_threshold:
                return CONVERGED, k, dest
        elif stop_code == 2:
            stable = stable + 1 if n_ext == c_ext and zc == c_zc and balanced else 0
            c_ext, c_zc = n_ext, zc
            if stable >= s_number:
                return CONVERGED, k, dest
        h = out
        which = dest
        if not rilling and k == max_sifts:
            return MAX_SIFTS, k, which
