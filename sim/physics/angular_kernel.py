"""Compiled evaluation of the angular table's motion at many times (numba).

Per sample: find nothing (the piece index is given), loop over the piece's components and
accumulate rate, angle and acceleration together — one sine and one cosine per component,
no (samples × components) temporaries.  The reference is :class:`MotionPiece`'s own numpy
evaluation (``tests/sim/test_angular_table.py`` compares them).
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True)
def motion_at(t, idx, starts, counts, freq, alpha, beta, phase, base, rate, angle, accel):  # pragma: no cover
    """Fill ``rate``, ``angle``, ``accel`` at times ``t`` in pieces ``idx`` (rows of the
    padded per-piece parameter tables; ``counts`` components used per row; ``base`` the
    piece's start angle minus its antiderivative at τ = 0, see :func:`angle_base`)."""
    two_pi = 2.0 * math.pi
    for j in range(t.size):
        i = idx[j]
        tau = t[j] - starts[i]
        r = 0.0
        c = 0.0
        g = base[i]
        for k in range(counts[i]):
            w = two_pi * freq[i, k]
            a, b, p = alpha[i, k], beta[i, k], phase[i, k]
            arg = w * tau + p
            s, co = math.sin(arg), math.cos(arg)
            env = a + b * tau
            r += env * s
            c += b * s + env * w * co
            # ∫₀^τ (α+βu) sin(wu+φ) du = [−(α+βu) cos/w + β sin/w²]₀^τ; the τ = 0 end is in base
            g += -env * co / w + b * s / (w * w)
        rate[j] = r
        angle[j] = g
        accel[j] = c


def angle_base(angle0, freq, alpha, beta, phase) -> np.ndarray:
    """Per piece: start angle − Σ antiderivative at τ = 0 = angle0 + Σ (α cos φ/w − β sin φ/w²)
    (padding has α = β = 0)."""
    w = 2 * np.pi * freq
    return angle0 + np.sum(alpha * np.cos(phase) / w - beta * np.sin(phase) / w ** 2, axis=1)


def evaluate(t: np.ndarray, starts, counts, freq, alpha, beta, phase, base):
    """(rate, angle, accel) at times ``t`` (1-D float array, any order)."""
    idx = np.maximum(np.searchsorted(starts, t, side="right") - 1, 0)
    out = np.empty((3, t.size))
    motion_at(t, idx, starts, counts, freq, alpha, beta, phase, base, out[0], out[1], out[2])
    return out[0], out[1], out[2]
