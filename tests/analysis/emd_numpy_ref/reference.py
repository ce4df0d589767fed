"""The numpy EMD of bench.analysis.emd._emd before its sifting moved to numba (commit 799e66a),
kept ONLY as a test reference: the compiled path must give the same IMFs."""

from __future__ import annotations

import numpy as np

from bench.analysis.emd._emd import MIN_SAMPLES, STOP_RULES, EmdResult, check_parameter
from tests.analysis.emd_numpy_ref.kernel import (
    Spline,
    Workspace,
    count_zero_crossings,
    envelope_knots,
    find_extrema,
    sift,
)

__all__ = ["emd", "find_extrema", "count_zero_crossings", "envelope_knots", "Spline", "Workspace", "sift"]

StopRule = str
MERGE_MEAN = True  # tests set False: every sifting then evaluates both envelopes, as the compiled path does


def emd(x: np.ndarray, *, max_imfs: int | None = None, max_sifts: int = 1000, stop: StopRule = "sd",
        sd_threshold: float = 0.2, rilling_thresholds: tuple[float, float, float] = (0.05, 0.5, 0.05),
        s_number: int = 4, nbsym: int = 2, range_tol: float = 1e-10) -> EmdResult:
    """Decompose ``x`` into IMFs and a residue (module docstring for every rule).

    ``max_imfs`` (default: no limit) caps the number of IMFs; ``max_sifts`` the siftings
    per IMF; ``stop`` picks the sifting stop criterion with its thresholds
    ``sd_threshold``, ``rilling_thresholds = (θ1, θ2, α)`` or ``s_number``; ``nbsym``
    extrema are mirrored at each end.
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
    ws = Workspace(n)
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
        h = _sift_one(r, imax, imin, ws, buffers, stop=stop, max_sifts=max_sifts, sd_threshold=sd_threshold,
                      thetas=(th1, th2, alpha), s_number=s_number, nbsym=nbsym)
        if h is None:
            break  # the proto-IMF lost its oscillation: it belongs to the residue
        imf, k, done = h
        imfs.append(imf.copy())
        sifts.append(k)
        converged.append(done)
        r -= imfs[-1]
    stack = np.array(imfs) if imfs else np.empty((0, n))
    residue = x - stack.sum(axis=0)  # exact reconstruction by construction
    settings = {"max_imfs": max_imfs, "max_sifts": max_sifts, "stop": stop, "sd_threshold": sd_threshold,
                "rilling_thresholds": [th1, th2, alpha], "s_number": s_number, "nbsym": nbsym,
                "range_tol": range_tol}
    return EmdResult(stack, residue, tuple(sifts), tuple(converged), stop, settings)


def _sift_one(r: np.ndarray, imax: np.ndarray, imin: np.ndarray, ws: Workspace,
              buffers: tuple[np.ndarray, np.ndarray], *, stop: str, max_sifts: int, sd_threshold: float,
              thetas: tuple[float, float, float], s_number: int, nbsym: int
              ) -> tuple[np.ndarray, int, bool] | None:
    """Sift one IMF out of ``r``: ``(imf, siftings, converged)``, or None if it degenerates."""
    h, k, stable, counts = r, 0, 0, (-1, -1)
    rilling = stop == "rilling"
    while True:
        px, vx, pn, vn = envelope_knots(h, imax, imin, nbsym)
        out = buffers[0] if h is not buffers[0] else buffers[1]
        upper = Spline.through(px, vx, ws.scratch(0, px.size))
        lower = Spline.through(pn, vn, ws.scratch(1, pn.size))
        if MERGE_MEAN and not rilling and 10 * (px.size + pn.size) < h.size:
            # long knot intervals (over ~20 samples): one merged mean spline halves the
            # per-sample work; below that, merging costs more than it saves (measured)
            st = sift(h, out, Spline.average(upper, lower), None, ws)
        else:
            st = sift(h, out, upper, lower, ws, thetas[:2] if rilling else None)
        if rilling:
            if st.over_theta1 <= thetas[2] * h.size and st.over_theta2 == 0:
                return h, k, True  # h's own envelopes are symmetric enough: h is the IMF
            if k == max_sifts:
                return h, k, False
        k += 1
        imax, imin = st.imax, st.imin
        n_ext = imax.size + imin.size
        if n_ext < 3:
            return None
        balanced = abs(n_ext - st.zero_crossings) <= 1
        if stop == "sd":
            shaped = vx.min() >= 0 and vn.max() <= 0  # the input's knots, mirrored ones included
            sd = st.mean_energy / max(st.input_energy, np.finfo(float).tiny)
            if shaped and balanced and sd < sd_threshold:
                return out, k, True
        elif stop == "s-number":
            stable = stable + 1 if (n_ext, st.zero_crossings) == counts and balanced else 0
            counts = (n_ext, st.zero_crossings)
            if stable >= s_number:
                return out, k, True
        h = out
        if not rilling and k == max_sifts:
            return h, k, False
