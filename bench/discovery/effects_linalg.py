"""Linear-algebra helpers of the effect catalogue: projections away from calibration regressors
and vector products.

Vector products go through ``np.einsum``: threaded BLAS level-1/2 calls (``np.dot``, ``@``)
stall for milliseconds on a loaded 2-core machine (measured 8 ms vs 0.03 ms for a 20 000-sample
dot product), and the detectability searches make thousands of them.
"""

from __future__ import annotations

import numpy as np

from bench.discovery.data import Record


def base_regressors(rec: Record) -> np.ndarray:
    """Columns a base-model calibration fits: 1 and (when logged and varying) the input."""
    cols = [np.ones(rec.n)]
    if rec.varies("input"):
        cols.append(rec.column("input"))
    return np.column_stack(cols)


def project_out(x: np.ndarray, a: np.ndarray) -> np.ndarray:
    """x minus its least-squares fit on the columns of a."""
    return project_q(x, orthonormal(a))


def orthonormal(a: np.ndarray) -> np.ndarray:
    """An orthonormal basis of the column space of a (rank-revealing: tiny columns dropped)."""
    q, r = np.linalg.qr(a)
    keep = (np.abs(np.diag(r)) > 1e-12 * max(1.0, float(np.max(np.abs(np.diag(r))))) if r.size
            else np.zeros(0, bool))
    return q[:, keep]


def project_q(x: np.ndarray, q: np.ndarray) -> np.ndarray:
    """x minus its projection on the orthonormal columns q."""
    # einsum, not BLAS: threaded BLAS level-1/2 calls stall badly on a loaded 2-core machine
    return x - np.einsum("ij,j->i", q, np.einsum("ij,i->j", q, x))


def vdot(a: np.ndarray, b: np.ndarray) -> float:
    """Dot product of two vectors (einsum: see project_q)."""
    return float(np.einsum("i,i->", a, b))
