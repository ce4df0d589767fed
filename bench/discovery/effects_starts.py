"""Starting points for the nonlinear fit of a catalogue effect to a residual.

A grid over the effect's nonlinear parameters (their resolvable ranges: 9 log-spaced points for
a log parameter, 5 linear ones otherwise), the linear parameters solved by least squares at each
grid point after projecting the base model's calibration regressors out of both sides; the three
points with the lowest residual sum of squares are the starts, best first.
"""

from __future__ import annotations

import numpy as np

from bench.discovery.data import Record
from bench.discovery.effects_linalg import base_regressors, product_grid, project_out

N_STARTS = 3


def grid_starts(effect, rec: Record, residual: np.ndarray, kind: str) -> list[dict]:
    """The :data:`N_STARTS` best grid points (parameter dicts) of ``effect`` for ``residual``."""
    r = np.asarray(residual, dtype=float)
    qs = effect.params_for(kind)
    lin = [q for q in qs if q.linear]
    grids = []
    for q in qs:
        if q.linear:
            continue
        lo, hi = (effect.drawable_range(q, rec, kind) if q.name != effect.main_param
                  else effect.main_grid_range(rec, kind))
        pts = np.geomspace(lo, hi, 9) if q.log else np.linspace(lo, hi, 5)
        grids.append((q.name, pts))
    a = base_regressors(rec)
    r_perp = project_out(r, a)
    y0 = effect.reference_output(rec)
    cands = []
    for combo in product_grid(grids):
        p = {q.name: 0.0 for q in lin} | combo
        if lin:
            cols = []
            for q in lin:
                pu = dict(p)
                pu[q.name] = 1.0
                cols.append(project_out(effect.apply(pu, rec, y0) - y0, a))
            coef, *_ = np.linalg.lstsq(np.column_stack(cols), r_perp, rcond=None)
            for q, c in zip(lin, coef):
                p[q.name] = float(np.clip(c, q.low, q.high))
        d = project_out(effect.apply(p, rec, y0) - y0, a)
        cands.append((float(np.sum((r_perp - d) ** 2)), p))
    cands.sort(key=lambda c: c[0])
    return [c[1] for c in cands[:N_STARTS]]
