"""Empirical mode decomposition (Huang et al. 1998) for Document C, step 1.

:func:`emd` splits a uniformly sampled series ``x`` into intrinsic mode functions (IMFs,
fastest first) and a residue.  Conventions and choices:

* Time is the sample index: extrema, spline knots and envelopes live on the integer
  grid ``0..n-1`` (the sampling rate matters only to :mod:`._nonrandom`).
* **Extrema**: a sample above (below) both neighbours; a flat run of equal samples that
  rises before and falls after (or vice versa) counts once, at its middle.  Zero
  crossings are sign changes between consecutive samples, exact zeros skipped.
* **Envelopes**: not-a-knot cubic splines through the maxima and through the minima (as
  MATLAB's ``spline`` and scipy's ``CubicSpline`` default).
* **Ends**: mirrored extrema (Rilling, Flandrin & Gonçalves 2003): ``nbsym`` extrema are
  reflected about the first (last) extremum, or about the end sample — which then acts
  as an extremum itself — when the record's end lies beyond the nearest extremum of the
  other kind, so both envelopes span the whole record.
* **Sifting stop criteria** (``stop``):

  - ``"sd"`` (default): Huang's Cauchy-type criterion in its global form
    ``SD = Σ(h_{k-1} − h_k)² / Σ h_{k-1}² < sd_threshold`` (0.2; Huang suggests 0.2–0.3;
    the point-wise form ``Σ (Δ/h)²`` blows up at zero crossings), confirmed by the IMF
    shape on both sides of the last sifting: every envelope knot of ``h_{k-1}`` (maxima
    ≥ 0, minima ≤ 0) and ``h_k``'s numbers of extrema and zero crossings within one.
    This is PyEMD's default test too, so on signals of order one (PyEMD's variance
    tests use absolute thresholds) the two libraries give the same IMFs.
  - ``"rilling"``: Rilling's evaluation function ``σ(t) = |m(t)| / a(t)`` (``m`` the
    envelope mean, ``a`` the envelope half-range): the proto-IMF is accepted when
    ``σ > θ1`` on at most a fraction ``α`` of the record and ``σ ≤ θ2`` everywhere
    (θ1, θ2, α = 0.05, 0.5, 0.05, as in Rilling's ``emd.m``).
  - ``"s-number"``: after ``s_number`` consecutive siftings in which the numbers of
    extrema and zero crossings stay the same and differ by at most one (Huang et al.
    2003, S = 3–8).

  ``max_sifts`` bounds the siftings per IMF (the IMF is then taken as it is; the
  result's ``converged`` says so).
* **End of the decomposition**: when the residue has fewer than three extrema (a
  trend), when ``max_imfs`` IMFs exist, or when the residue's range falls below
  ``range_tol`` times the signal's.  A proto-IMF that loses its extrema while being
  sifted stays in the residue (as PyEMD does).
* **Exact reconstruction by construction**: ``residue = x − Σ imfs``, so
  ``Σ imfs + residue`` returns ``x`` up to one floating-point rounding.

The sifting itself (compiled with numba: envelopes, extrema and sums in one pass per
sifting, one call per IMF) lives in :mod:`._kernel` and :mod:`._spline`; the choice of
the non-random components (:func:`nonrandom_terms`) in :mod:`._nonrandom`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from bench.analysis.emd._kernel import CONVERGED, DEGENERATE, STOP_CODES, count_zero_crossings, find_extrema, sift_imf
from bench.analysis.emd._nonrandom import Component, NonRandomTerms, nonrandom_terms

StopRule = Literal["sd", "rilling", "s-number"]
STOP_RULES: tuple[StopRule, ...] = ("sd", "rilling", "s-number")
MIN_SAMPLES = 8

__all__ = ["Component", "EmdResult", "NonRandomTerms", "STOP_RULES", "count_zero_crossings", "emd", "find_extrema",
           "nonrandom_terms"]


@dataclass(frozen=True, eq=False)
class EmdResult:
    """IMFs (rows, fastest first), residue and how each IMF's sifting ended.

    Returned by :func:`emd`; ``imfs.sum(axis=0) + residue`` is the input (:meth:`reconstruct`).

    Attributes
    ----------
    imfs : ndarray of float, shape (n_imfs, n)
        Intrinsic mode functions, fastest first, in the unit of the input.
    residue : ndarray of float, shape (n,)
        ``x − Σ imfs``: the trend left after the last IMF, in the unit of the input.
    sifts : tuple of int
        Siftings spent on each IMF.
    converged : tuple of bool
        Per IMF: the stop criterion was met (False: ended by ``max_sifts``).
    stop : str
        Stop rule used: ``"sd"``, ``"rilling"`` or ``"s-number"``.
    settings : dict
        Every option of the decomposition (``max_imfs``, ``max_sifts``, thresholds, ``nbsym``, …).
    n_imfs : int
        Property: number of IMFs.
    """

    imfs: np.ndarray  # shape (n_imfs, n), units of the input
    residue: np.ndarray  # shape (n,)
    sifts: tuple[int, ...]  # siftings spent on each IMF
    converged: tuple[bool, ...]  # stop criterion met (False: ended by max_sifts)
    stop: str
    settings: dict = field(default_factory=dict)

    @property
    def n_imfs(self) -> int:
        """Number of IMFs."""
        return int(self.imfs.shape[0])

    def reconstruct(self) -> np.ndarray:
        """``Σ imfs + residue`` — the input signal."""
        return self.imfs.sum(axis=0) + self.residue


def check_parameter(name: str, value, low, high=None, kind=float):
    if kind is int and (isinstance(value, bool) or int(value) != value):
        raise ValueError(f"{name} = {value!r} must be an integer")
    if not (low <= value and (high is None or value <= high)):
        raise ValueError(f"{name} = {value!r} must be in [{low}, {'∞' if high is None else high}]")
    return kind(value)


def emd(x: np.ndarray, *, max_imfs: int | None = None, max_sifts: int = 1000, stop: StopRule = "sd",
        sd_threshold: float = 0.2, rilling_thresholds: tuple[float, float, float] = (0.05, 0.5, 0.05),
        s_number: int = 4, nbsym: int = 2, range_tol: float = 1e-10) -> EmdResult:
    """Decompose ``x`` into IMFs and a residue (module docstring for every rule).

    ``max_imfs`` (default: no limit) caps the number of IMFs; ``max_sifts`` the siftings
    per IMF; ``stop`` picks the sifting stop criterion with its thresholds
    ``sd_threshold``, ``rilling_thresholds = (θ1, θ2, α)`` or ``s_number``; ``nbsym``
    extrema are mirrored at each end.

    Huang et al. (1998) sifting with not-a-knot cubic spline envelopes and mirrored end
    extrema (Rilling, Flandrin & Gonçalves 2003); time is the sample index.  The
    decomposition ends when the residue has fewer than three extrema, ``max_imfs`` IMFs
    exist, or the residue's range falls below ``range_tol`` times the signal's.

    Parameters
    ----------
    x : array_like of float, shape (n,)
        Uniformly sampled series in any unit; finite, n ≥ 8.
    max_imfs : int, optional
        Largest number of IMFs, an integer ≥ 1; default no limit.
    max_sifts : int, default 1000
        Largest number of siftings per IMF, an integer ≥ 1.
    stop : {"sd", "rilling", "s-number"}, default "sd"
        Sifting stop criterion: Huang's global SD confirmed by the IMF shape, Rilling's
        evaluation function, or Huang's S-number.
    sd_threshold : float, default 0.2
        ``"sd"``: sifting stops when ``Σ(h_{k-1} − h_k)² / Σ h_{k-1}²`` falls below it; ≥ 0.
    rilling_thresholds : tuple of float, default (0.05, 0.5, 0.05)
        ``"rilling"``: ``(θ1, θ2, α)`` with ``0 < θ1 ≤ θ2`` and ``0 < α < 1``.
    s_number : int, default 4
        ``"s-number"``: consecutive siftings with unchanged extrema and zero-crossing counts, ≥ 1.
    nbsym : int, default 2
        Extrema mirrored at each end, an integer in [1, 10].
    range_tol : float, default 1e-10
        Stop when the residue's range is at most this fraction of the signal's; ≥ 0.

    Returns
    -------
    EmdResult
        IMFs (fastest first) and residue in the unit of ``x``, with the siftings per IMF;
        ``Σ imfs + residue`` returns ``x`` up to one rounding.

    Raises
    ------
    ValueError
        If ``x`` is not 1-D, has fewer than 8 samples or a non-finite value, ``stop`` is not
        one of :data:`STOP_RULES`, an option is outside its range above, or an envelope
        spline system is singular.

    Examples
    --------
    A 20 Hz and a 2 Hz tone sampled at 100 Hz come apart into the first two IMFs:

    >>> import numpy as np
    >>> from bench.analysis.emd import emd
    >>> t = np.arange(2000) / 100.0
    >>> fast, slow = np.sin(2 * np.pi * 20.0 * t), 0.5 * np.sin(2 * np.pi * 2.0 * t)
    >>> r = emd(fast + slow)
    >>> r.imfs.shape, all(r.converged)
    ((4, 2000), True)
    >>> bool(np.std(r.imfs[0] - fast) < 0.02), bool(np.std(r.imfs[1] - slow) < 0.1)
    (True, True)
    >>> bool(np.max(np.abs(r.reconstruct() - (fast + slow))) < 1e-12)
    True
    """
    x = np.asarray(x, dtype=float)
    if x.ndim != 1:
        raise ValueError(f"x must be one-dimensional, got shape {x.shape}")
    if x.size < MIN_SAMPLES:
        raise ValueError(f"x has {x.size} samples; at least {MIN_SAMPLES} are required")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"x contains {int(np.sum(~np.isfinite(x)))} non-finite values; all must be finite")
    if stop not in STOP_RULES:
        raise ValueError(f"stop = {stop!r} is not one of {STOP_RULES}")
    max_imfs = None if max_imfs is None else check_parameter("max_imfs", max_imfs, 1, kind=int)
    max_sifts = check_parameter("max_sifts", max_sifts, 1, kind=int)
    nbsym = check_parameter("nbsym", nbsym, 1, 10, kind=int)
    s_number = check_parameter("s_number", s_number, 1, kind=int)
    sd_threshold = check_parameter("sd_threshold", sd_threshold, 0.0)
    th1, th2, alpha = (float(v) for v in rilling_thresholds)
    if not (0 < th1 <= th2 and 0 < alpha < 1):
        raise ValueError(f"rilling_thresholds = {rilling_thresholds!r} must satisfy 0 < θ1 ≤ θ2 and 0 < α < 1")
    range_tol = check_parameter("range_tol", range_tol, 0.0)

    n = x.size
    buffers = (np.empty(n), np.empty(n))  # sifting ping-pongs between these
    scale = float(np.ptp(x))
    imfs: list[np.ndarray] = []
    sifts: list[int] = []
    converged: list[bool] = []
    r = x.copy()
    while max_imfs is None or len(imfs) < max_imfs:
        if np.ptp(r) <= range_tol * scale:
            break
        imax, imin = find_extrema(r)
        if imax.size + imin.size < 3:
            break  # the residue is a trend
        how, k, where = sift_imf(r, *buffers, imax, imin, STOP_CODES[stop], max_sifts, sd_threshold, th1, th2,
                                 alpha, s_number, nbsym)
        if how == DEGENERATE:
            break  # the proto-IMF lost its oscillation: it belongs to the residue
        if how < 0:
            raise ValueError("an envelope spline system is singular (knot positions not increasing)")
        imfs.append((r if where < 0 else buffers[where]).copy())
        sifts.append(int(k))
        converged.append(how == CONVERGED)
        r -= imfs[-1]
    stack = np.array(imfs) if imfs else np.empty((0, n))
    residue = x - stack.sum(axis=0)  # exact reconstruction by construction
    settings = {"max_imfs": max_imfs, "max_sifts": max_sifts, "stop": stop, "sd_threshold": sd_threshold,
                "rilling_thresholds": [th1, th2, alpha], "s_number": s_number, "nbsym": nbsym,
                "range_tol": range_tol}
    return EmdResult(stack, residue, tuple(sifts), tuple(converged), stop, settings)
