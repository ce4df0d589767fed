"""The sequential Kalman filter as the per-sample numpy loop it was before its numba kernel.

The oracle of ``bench.analysis.fusion``'s compiled ``sequential_kalman``: tests ask the kernel
to agree with it to 1e-12 of the record's scale, and ``benchmarks/bench_fusion.py`` times it.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np


def reference_sequential(measurements: Sequence[Any], h_rows: Sequence[Any], noises: Sequence[Any],
                         phi: np.ndarray, q: np.ndarray, x0: np.ndarray,
                         p0: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The former numpy per-sample loop of ``sequential_kalman``: one scalar update per sensor.

    Parameters
    ----------
    measurements : sequence of array_like
        One series per sensor, all of the same length.
    h_rows : sequence of array_like
        Each sensor's observation row (states → reading).
    noises : sequence
        Each sensor's adaptive measurement noise: ``r_lower``, ``r_upper`` and per interval
        ``a``, ``b`` (R = a + b·(Hx)², clipped to the bounds), as ``AdaptiveNoise``.
    phi, q : ndarray
        State transition and process noise covariance of one sample.
    x0, p0 : ndarray
        Initial state and covariance.

    Returns
    -------
    rate : ndarray
        The first state after every sample's updates.
    nis : ndarray
        Normalised innovation squared, per sample and sensor.
    r_used : ndarray
        The measurement variance used, per sample and sensor.
    interval : ndarray of int8
        Which interval of the innovation index picked R (0, 1, 2), per sample and sensor.
    p : ndarray
        The covariance after the last sample.
    """
    ys = [np.asarray(y, dtype=float).tolist() for y in measurements]
    hs = [np.asarray(h, dtype=float).ravel() for h in h_rows]
    m, n_samples = len(ys), len(ys[0])
    phi_t = phi.T.copy()
    x, p = np.array(x0, dtype=float), np.array(p0, dtype=float)
    out, nis = np.empty(n_samples), np.empty((n_samples, m))
    r_used, interval = np.empty((n_samples, m)), np.empty((n_samples, m), dtype=np.int8)
    for k in range(n_samples):
        x = phi @ x
        p = phi @ p @ phi_t + q
        for j in range(m):
            h, nz = hs[j], noises[j]
            hx = float(h @ x)
            ph = p @ h
            hph = float(h @ ph)
            nu = ys[j][k] - hx
            idx = nu * nu - hph
            i = 0 if idx < nz.r_lower else (1 if idx <= nz.r_upper else 2)
            r = min(max(nz.a[i] + nz.b[i] * hx * hx, nz.r_lower), nz.r_upper)
            s = hph + r
            gain = ph / s
            x = x + gain * nu
            p = p - np.outer(gain, h @ p)
            nis[k, j], r_used[k, j], interval[k, j] = nu * nu / s, r, i
        out[k] = x[0]
    return out, nis, r_used, interval, p
