"""Extrema and zero crossings for :mod:`bench.analysis.emd._emd`, compiled with numba.

Rules (as PyEMD's): an extremum is a sample above (below) both neighbours; a flat run of
equal samples between a rise and a fall (or a fall and a rise) counts once, at its
middle rounded half to even; flat runs touching an end of the record are not extrema.
Zero crossings are sign changes between consecutive samples, exact zeros skipped.  The
sifting pass (:mod:`.emd_kernel`) finds the extrema of its result in its own loop and
falls back on :func:`extrema_into` when it meets flat runs or exact zeros.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["count_zero_crossings", "find_extrema"]


@numba.njit(cache=True, inline="always")
def _flat_middle(a, b):
    """``rint((a + b) / 2)`` with halves to even (numpy's ``rint``), for ``a + b ≥ 0``."""
    s = a + b
    q = s // 2
    if s % 2 == 1 and q % 2 == 1:
        q += 1
    return q


@numba.njit(cache=True)
def extrema_into(h, imax, imin):
    """Maxima and minima of ``h`` into ``imax``/``imin``: ``(n_max, n_min)`` (rules of :func:`find_extrema`)."""
    nmax = nmin = 0
    last_dir = 0  # sign of the last nonzero difference
    last_nz = -1  # its index (d[j] = h[j+1] - h[j])
    for i in range(1, h.size):
        d = h[i] - h[i - 1]
        if d == 0.0:
            continue
        up = 1 if d > 0.0 else -1
        if last_dir != 0 and up != last_dir:
            idx = _flat_middle(last_nz + 1, i - 1)
            if last_dir > 0:
                imax[nmax] = idx
                nmax += 1
            else:
                imin[nmin] = idx
                nmin += 1
        last_dir = up
        last_nz = i - 1
    return nmax, nmin


@numba.njit(cache=True)
def count_zero_crossings_kernel(h):
    zc = 0
    last = 0  # sign of the last nonzero sample
    for v in h:
        if v == 0.0:
            continue
        s = 1 if v > 0.0 else -1
        if last != 0 and s != last:
            zc += 1
        last = s
    return zc


def find_extrema(h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the local maxima and minima of ``h``.

    A flat run of equal samples between a rise and a fall (or a fall and a rise) counts
    once, at its middle rounded half to even (as PyEMD); flat runs touching an end of
    the record are not extrema.
    """
    h = np.ascontiguousarray(h, dtype=float)
    imax = np.empty(h.size // 2 + 1, dtype=np.int64)
    imin = np.empty(h.size // 2 + 1, dtype=np.int64)
    nmax, nmin = extrema_into(h, imax, imin)
    return imax[:nmax].copy(), imin[:nmin].copy()


def count_zero_crossings(h: np.ndarray) -> int:
    """Sign changes of ``h`` between consecutive samples, exact zeros skipped."""
    return int(count_zero_crossings_kernel(np.ascontiguousarray(h, dtype=float)))
