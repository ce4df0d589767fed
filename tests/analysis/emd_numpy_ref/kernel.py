"""The inner loop of :mod:`bench.analysis.emd._emd`: extrema, mirrored envelope knots and one sifting.

Speed notes (measured beside PyEMD in ``benchmarks/bench_emd.py``; the sifting count is
fixed by the stop criterion, so only the cost of one sifting can be cut):

* One sifting is a single pass over the record in cache-sized blocks: the envelopes
  (or, when knot intervals are long, one merged mean spline), the subtraction, the
  sums of the SD criterion, the extrema and the zero crossings of the result are
  computed block by block while the block is in cache.  Whole-record temporaries made
  every step memory-bound.
* The extrema of the sifted result are found in the same pass, so each sifting finds
  extrema once (PyEMD does it three times).
* Splines, their evaluation and the scratch arrays: :mod:`.emd_spline`.
* The two envelopes are merged into one mean spline only when knot intervals average
  over ~20 samples; below that the merge (a Taylor shift per merged interval) costs
  more than the second evaluation it saves.
* Sums use ``einsum``, not BLAS ``dot``: on a busy machine a BLAS call may wake its
  thread pool and cost milliseconds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tests.analysis.emd_numpy_ref.spline import BLOCK, Spline, Workspace, interval_indices, not_a_knot_slopes

__all__ = ["BLOCK", "SiftStats", "Spline", "Workspace", "count_zero_crossings", "envelope_knots", "find_extrema",
           "not_a_knot_slopes", "sift"]


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
    # the end is the start of the reversed record: reflect there and map back (only the
    # last nbsym + 1 extrema of each kind can be reflected)
    e = -(nbsym + 1)
    rpx, rvx, rpn, rvn = _mirror_start(h[-1], (n - 1 - imax[e:])[::-1], vmax[e:][::-1],
                                       (n - 1 - imin[e:])[::-1], vmin[e:][::-1], nbsym)
    px = np.concatenate([lpx, imax, (n - 1 - rpx)[::-1]])
    vx = np.concatenate([lvx, vmax, rvx[::-1]])
    pn = np.concatenate([lpn, imin, (n - 1 - rpn)[::-1]])
    vn = np.concatenate([lvn, vmin, rvn[::-1]])
    return (*_strict(px, vx, lpx.size, rpx.size), *_strict(pn, vn, lpn.size, rpn.size))


def _strict(pos: np.ndarray, val: np.ndarray, head: int, tail: int) -> tuple[np.ndarray, np.ndarray]:
    """Drop repeated knot positions (a reflection can land on an existing knot).

    The extrema in between are strictly increasing, so only the ``head`` reflected knots
    before them and the ``tail`` after them (and their junctions) are checked."""
    if (np.diff(pos[: head + 2]) > 0).all() and (np.diff(pos[-(tail + 2) :]) > 0).all():
        return pos, val
    keep = np.r_[True, np.diff(pos) > 0]
    return pos[keep], val[keep]


# --------------------------------------------------------------------------- one sifting


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
        uk = (int(ulo[k]), int(uhi[k]))
        if lower is None:
            upper.evaluate_block(a, b, *uk, ws, u)
        else:
            lk = (int(llo[k]), int(lhi[k]))
            if upper.short_intervals(a, b, *uk) and lower.short_intervals(a, b, *lk):
                iu, il = interval_indices(a, m, upper.pos, uk, lower.pos, lk, ws)
                upper.evaluate_block(a, b, *uk, ws, u, iu)
                lower.evaluate_block(a, b, *lk, ws, lo, il)
            else:
                upper.evaluate_block(a, b, *uk, ws, u)
                lower.evaluate_block(a, b, *lk, ws, lo)
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
