"""Overlapping Allan variance sums: the numerical core of :mod:`bench.analysis.allan._adev`.

Conventions.  ``y`` are rate samples (any unit ``u``) taken every ``τ0`` seconds; a
phase (angle) record ``x`` of ``N + 1`` samples is the same thing as the ``N`` rate
samples ``diff(x)/τ0``.  At ``τ = m·τ0`` the overlapping estimator (NIST SP 1065 eq. 11,
written with window sums ``D_m[n] = y[n] + … + y[n+m-1]``) is::

    σ²(τ) = Σ_{n=0}^{M-1} (D_m[n+m] − D_m[n])² / (2 M m²),     M = N + 1 − 2m terms.

Two engines, both O(N) per τ and vectorised in cache-sized chunks:

* **Octave τ** (``m = 2^k``): the window sums double level by level, ``D_2m[n] = D_m[n] +
  D_m[n+m]``, in place.  The window sums are formed from neighbouring samples, so their
  rounding error is relative to the window sum and not to a running total (a cumulative
  sum of a wandering rate loses digits; this does not).  Per chunk the sum of squares
  uses ``Σ(a−b)² = 2Σa² + 2Σb² − Σ(a+b)²``: ``Σb²`` and ``Σa²`` are the previous level's
  ``Σ(a+b)²`` per chunk (plus short edge pieces), so a level costs one add and one dot
  product instead of a subtract, an add and a dot product.  The identity cancels when
  ``a ≈ b`` (a rate that wanders slowly compared with its Allan deviation); wherever
  the cancellation factor ``(2Σa² + 2Σb² + Σ(a+b)²) / Σ(a−b)²`` exceeds
  :data:`KAPPA_MAX` that chunk is summed directly, so the rounding error stays
  ≲ ``KAPPA_MAX · 1e-14`` relative.
* **Any τ**: the running sum ``S`` of the mean-removed rate (allantools' "phase") and
  ``v = (S[n+2m] − S[n+m]) − (S[n+m] − S[n])``.  Its rounding error is
  ``≈ ε·max|S| / rms(v) / √M`` relative: negligible for noise-like records, up to ~1e-9
  for 10⁷ samples of a pure random walk of rate.

Sums of squares go through BLAS ``ddot`` in rows of at most 8192 elements: OpenBLAS
keeps such calls single-threaded, and a threaded dot per chunk stalls badly when other
processes share the cores.
"""

from __future__ import annotations

import numpy as np

#: chunk length (elements) of the streamed passes: 256 KiB of float64, cache-resident
CHUNK = 1 << 15
#: largest accepted cancellation factor of the fast sum-of-squares identity
KAPPA_MAX = 16.0
_ROW = 8192


def sumsq(v: np.ndarray) -> float:
    """``Σ v²`` of a contiguous float64 vector (single-threaded BLAS calls)."""
    n = v.size
    k = n // _ROW
    total = 0.0
    if k:
        rows = v[:k * _ROW].reshape(k, _ROW)
        total = sum(np.vecdot(rows, rows).tolist())  # a Python sum of k floats: less call overhead
    if n > k * _ROW:
        tail = v[k * _ROW:]
        total += float(np.dot(tail, tail))
    return total


def octave_levels(n_rate: int, min_terms: int = 2) -> int:
    """Number of octave levels ``m = 1, 2, 4, …`` with at least ``min_terms`` terms."""
    levels, m = 0, 1
    while n_rate + 1 - 2 * m >= min_terms:
        levels += 1
        m *= 2
    return levels


def octave_sums(y: np.ndarray, levels: int, chunk: int = CHUNK) -> np.ndarray:
    """``Σ_n (D_m[n+m] − D_m[n])²`` for ``m = 2^k``, ``k < levels`` (module docstring).

    ``y`` is a finite float64 rate record (not modified); ``chunk`` a power of two.
    A chunk's new window sums go to a buffer and are copied back, so that the old ones
    stay available for a direct sum.  Once more than half the chunks of a level needed
    the direct sum, the remaining levels sum directly (a slowly wandering rate dominates
    ever more as τ grows), keep no chunk totals and write the new sums in place.
    """
    d = y - y.mean()  # window sums of length 1; the mean is removed for precision only
    length, c = d.size, chunk
    # totals[j] = Σ d[jc : min((j+1)c, length)]², kept for the current level
    totals = np.array([sumsq(d[s:s + c]) for s in range(0, length, c)])
    add_buf, sub_buf = np.empty(c), np.empty(c)
    out = np.zeros(levels)
    direct = False
    for k in range(levels):
        m = 1 << k
        terms = length - m  # also the valid length of the next level's window sums
        next_totals = np.empty(-(-terms // c))
        acc, fallbacks = 0.0, 0
        for j, s in enumerate(range(0, terms, c)):
            e, end = min(s + c, terms), min(s + c, length)
            a, b = d[s + m:e + m], d[s:e]
            if direct:
                diff = sub_buf[:e - s]
                np.subtract(a, b, out=diff)
                acc += sumsq(diff)
                np.add(a, b, out=b)  # numpy buffers the operands itself if a overlaps b
                continue
            nxt = add_buf[:e - s]
            np.add(a, b, out=nxt)
            w = sumsq(nxt)
            next_totals[j] = w
            # Σb² and Σa² from this level's chunk totals (a is b shifted by m)
            sbb = totals[j] - (sumsq(d[e:end]) if e < end else 0.0)
            if m >= c:
                saa = totals[j + m // c]
            else:
                saa = totals[j] - sumsq(d[s:s + m]) + (sumsq(d[end:e + m]) if e + m > end else 0.0)
            fast = 2.0 * (saa + sbb) - w
            if fast <= 0.0 or 2.0 * (saa + sbb) + w > KAPPA_MAX * fast:
                diff = sub_buf[:e - s]  # cancellation: sum the differences directly
                np.subtract(a, b, out=diff)
                fast = sumsq(diff)
                fallbacks += 1
            acc += fast
            d[s:e] = nxt  # later chunks read only d[e:], still this level's sums
        out[k] = acc
        direct = direct or 2 * fallbacks > len(next_totals)
        totals, length = next_totals, terms
    return out


def cumsum_sums(y: np.ndarray, ms: np.ndarray, chunk: int = CHUNK) -> np.ndarray:
    """``Σ_n v²`` with ``v = S[n+2m] − 2S[n+m] + S[n]`` for each averaging factor in ``ms``."""
    s_run = np.empty(y.size + 1)
    s_run[0] = 0.0
    np.subtract(y, y.mean(), out=s_run[1:])
    np.cumsum(s_run[1:], out=s_run[1:])
    b1, b2 = np.empty(chunk), np.empty(chunk)
    out = np.zeros(len(ms))
    for i, m in enumerate(int(v) for v in ms):
        terms = s_run.size - 2 * m
        acc = 0.0
        for s in range(0, terms, chunk):
            e = min(s + chunk, terms)
            late, early = b1[:e - s], b2[:e - s]
            np.subtract(s_run[s + 2 * m:e + 2 * m], s_run[s + m:e + m], out=late)
            np.subtract(s_run[s + m:e + m], s_run[s:e], out=early)
            late -= early
            acc += sumsq(late)
        out[i] = acc
    return out
