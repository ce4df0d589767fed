"""Linear-algebra helpers of the effect catalogue: projections away from calibration regressors,
vector products, the best-matching competitor signature, parameter grids.

Vector products go through ``np.einsum``: threaded BLAS level-1/2 calls (``np.dot``, ``@``)
stall for milliseconds on a loaded 2-core machine (measured 8 ms vs 0.03 ms for a 20 000-sample
dot product), and the detectability searches make thousands of them.
"""

from __future__ import annotations

import math

import numpy as np

from bench.discovery.data import Record


def base_regressors(rec: Record) -> np.ndarray:
    """Columns a base-model calibration fits: 1 and (when logged and varying) the input."""
    cols = [np.ones(rec.n)]
    if rec.varies("input"):
        cols.append(rec.input)
    return np.column_stack(cols)


def project_out(x: np.ndarray, a: np.ndarray) -> np.ndarray:
    """x minus its least-squares fit on the columns of a."""
    return project_q(x, orthonormal(a))


def orthonormal(a: np.ndarray) -> np.ndarray:
    """An orthonormal basis of the column space of a (rank-revealing: tiny columns dropped)."""
    q, r = np.linalg.qr(a)
    keep = np.abs(np.diag(r)) > 1e-12 * max(1.0, float(np.max(np.abs(np.diag(r))))) if r.size else []
    return q[:, keep]


def project_q(x: np.ndarray, q: np.ndarray) -> np.ndarray:
    """x minus its projection on the orthonormal columns q."""
    # einsum, not BLAS: threaded BLAS level-1/2 calls stall badly on a loaded 2-core machine
    return x - np.einsum("ij,j->i", q, np.einsum("ij,i->j", q, x))


def vdot(a: np.ndarray, b: np.ndarray) -> float:
    """Dot product of two vectors (einsum: see project_q)."""
    return float(np.einsum("i,i->", a, b))


def competitor_direction(comp, rec: Record, delta: np.ndarray, q: np.ndarray, kind: str) -> np.ndarray:
    """The competitor's signature (projected away from the orthonormal columns ``q``, unit norm)
    that best matches ``delta`` (already orthogonal to q) up to a scale: all-linear competitors
    have one direction; otherwise a 13-point log grid of its main parameter over its resolvable
    range, then 8 golden-section steps."""
    if kind not in comp.ranges:
        kind = comp.kinds[0]
    y0 = comp.reference_output(rec)
    base = comp.reference_params(rec, kind)

    def direction(v: float) -> np.ndarray:
        d = project_q(comp.apply(comp._with_main(base, v), rec, y0) - y0, q)
        nrm = math.sqrt(vdot(d, d))
        return d / nrm if nrm > 0 else d

    if all(p.linear for p in comp.params_for(kind)):
        return direction(1.0)

    def fit(logv: float) -> float:  # captured fraction of delta (maximise)
        return abs(vdot(direction(math.exp(logv)), delta))

    lo, hi = comp.main_grid_range(rec, kind)
    grid = np.linspace(math.log(lo), math.log(hi), 13)
    vals = [fit(g) for g in grid]
    i = int(np.argmax(vals))
    x0, x1 = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
    g = (math.sqrt(5) - 1) / 2
    c, d = x1 - g * (x1 - x0), x0 + g * (x1 - x0)
    fc, fd = fit(c), fit(d)
    for _ in range(8):
        if fc > fd:
            x1, d, fd = d, c, fc
            c = x1 - g * (x1 - x0)
            fc = fit(c)
        else:
            x0, c, fc = c, d, fd
            d = x0 + g * (x1 - x0)
            fd = fit(d)
    return direction(math.exp(0.5 * (x0 + x1)))


def product_grid(grids):
    if not grids:
        yield {}
        return
    (name, pts), rest = grids[0], grids[1:]
    for v in pts:
        for tail in product_grid(rest):
            yield {name: float(v)} | tail
