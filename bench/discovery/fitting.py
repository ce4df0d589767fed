"""Least-squares fits of a model with one more catalogue effect, on chosen rows of a record.

The fitted vector is ``[bias, scale_factor (when the input is logged), effect params...]``;
log parameters are fitted in log coordinates, every effect parameter is bounded by its
physical range for the sensor kind. The prediction is the model's own
(``Model.predict`` with the effect appended), so transforms (saturation, dead zone, delay,
filters) are fitted exactly as they act. Standard errors come from the Gauss–Newton
covariance ``s²(JᵀJ)⁻¹`` at the optimum (s² the mean squared residual of the fitted rows,
white-noise assumption; mapped from log coordinates by the delta method).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy import optimize

from bench.discovery.data import Record


def _periodic(q) -> bool:
    """A phase parameter spanning one full turn."""
    return q.unit == "rad" and "phase" in q.name and q.high - q.low >= 2 * math.pi - 1e-9


@dataclass(frozen=True)
class Fit:
    """An effect fitted together with bias and scale factor."""

    params: dict
    params_std: dict
    bias: float
    scale_factor: float
    sse: float
    x: np.ndarray
    ok: bool


class CandidateFitter:
    """Fits effect ``effect_id`` (appended to ``model``) to ``rec`` on row masks."""

    def __init__(self, model, rec: Record, effect, effect_id: str):
        self.model, self.rec, self.effect, self.id = model, rec, effect, effect_id
        self.kind = model.base.kind
        self.qs = effect.params_for(self.kind)
        self.with_sf = rec.logged("input")
        self.n_base = 2 if self.with_sf else 1
        sd = max(float(model.base.noise_sd), 1e-300)
        sf = float(model.base.scale_factor)
        self.base_scale = [sd, max(abs(sf) * 1e-4, 1e-12)][: self.n_base]

    # ---- coordinates ------------------------------------------------------------------
    def pack(self, p: dict, bias: float, sf: float) -> np.ndarray:
        v = [bias, sf][: self.n_base]
        for q in self.qs:
            x = float(np.clip(p[q.name], q.low, q.high))
            v.append(math.log(max(x, q.low)) if q.log else x)
        return np.array(v, dtype=float)

    def unpack(self, x: np.ndarray) -> tuple[dict, float, float]:
        lo, hi = self.bounds()
        bias = float(np.clip(x[0], lo[0], hi[0]))
        sf = float(np.clip(x[1], lo[1], hi[1])) if self.with_sf else float(self.model.base.scale_factor)
        p = {}
        for q, v in zip(self.qs, x[self.n_base:]):
            val = math.exp(v) if q.log else float(v)
            if _periodic(q):  # a phase wraps: the optimiser must not stall at ±π
                val = (val + math.pi) % (2 * math.pi) - math.pi
            p[q.name] = float(np.clip(val, q.low, q.high))
        return p, bias, sf

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        from bench.discovery.model import BASE_RANGES  # noqa: PLC0415

        rng = BASE_RANGES[self.kind]
        base = [rng["bias"], rng["scale_factor"]][: self.n_base]
        lo = [b[0] for b in base] + [-8 * math.pi if _periodic(q) else math.log(q.low) if q.log else q.low
                                     for q in self.qs]
        hi = [b[1] for b in base] + [8 * math.pi if _periodic(q) else math.log(q.high) if q.log else q.high
                                     for q in self.qs]
        return np.array(lo), np.array(hi)

    def x_scale(self) -> np.ndarray:
        sc = list(self.base_scale)
        for q in self.qs:
            sc.append(0.3 if q.log else max((q.high - q.low) * 1e-3, 1e-300))
        return np.array(sc)

    # ---- predictions ------------------------------------------------------------------
    def model_at(self, x: np.ndarray):
        p, bias, sf = self.unpack(x)
        base = replace(self.model.base, bias=bias, scale_factor=sf)
        return replace(self.model, base=base).with_effect(self.id, p)

    def predict(self, x: np.ndarray) -> np.ndarray:
        return self.model_at(x).predict(self.rec)

    def predict_without(self, x: np.ndarray) -> np.ndarray:
        _, bias, sf = self.unpack(x)
        return replace(self.model, base=replace(self.model.base, bias=bias, scale_factor=sf)).predict(self.rec)

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        """(n, q) derivatives of the full-record prediction w.r.t. the effect coordinates."""
        lo, hi = self.bounds()
        f0 = self.predict(x)
        cols = []
        for j in range(self.n_base, x.size):
            h = 1e-4 * max(abs(x[j]), 1.0) if self.qs[j - self.n_base].log else 1e-3 * self.x_scale()[j]
            xp = x.copy()
            xp[j] = min(x[j] + h, hi[j])
            if xp[j] == x[j]:
                xp[j] = x[j] - h
            cols.append((self.predict(xp) - f0) / (xp[j] - x[j]))
        return np.column_stack(cols) if cols else np.zeros((self.rec.n, 0))

    # ---- fitting ----------------------------------------------------------------------
    def fit(self, starts: list[np.ndarray], rows: np.ndarray | None = None, max_nfev: int = 60) -> Fit:
        """Best of a bounded trust-region fit from each start (and the start itself) on ``rows``."""
        y = self.rec.y
        rows = np.ones(self.rec.n, bool) if rows is None else rows
        lo, hi = self.bounds()
        best_x, best_cost = None, np.inf
        fun = lambda x: (y - self.predict(x))[rows]  # noqa: E731
        for x0 in starts:
            x0 = np.clip(x0, lo + 1e-12 * np.abs(lo), hi - 1e-12 * np.abs(hi))
            c0 = float(np.sum(fun(x0) ** 2))
            if c0 < best_cost:
                best_x, best_cost = x0, c0
            try:
                res = optimize.least_squares(fun, x0, bounds=(lo, hi), x_scale=self.x_scale(),
                                             max_nfev=max_nfev, method="trf")
            except (ValueError, np.linalg.LinAlgError):
                continue
            c = float(np.sum(res.fun ** 2))
            if np.isfinite(c) and c < best_cost:
                best_x, best_cost = res.x, c
        p, bias, sf = self.unpack(best_x)
        std = self._std(best_x, rows, best_cost)
        return Fit(p, std, bias, sf, best_cost, best_x, bool(np.isfinite(best_cost)))

    def _std(self, x: np.ndarray, rows: np.ndarray, sse: float) -> dict:
        """Gauss–Newton standard errors of the effect parameters (NaN when singular)."""
        n_rows = int(rows.sum())
        lo, hi = self.bounds()
        f0 = self.predict(x)
        cols = []
        for j in range(x.size):
            h = 1e-4 * max(abs(x[j]), 1.0) if j >= self.n_base and self.qs[j - self.n_base].log \
                else 1e-3 * self.x_scale()[j]
            xp = x.copy()
            xp[j] = x[j] + h if x[j] + h <= hi[j] else x[j] - h
            cols.append(((self.predict(xp) - f0) / (xp[j] - x[j]))[rows])
        jac = np.column_stack(cols)
        s2 = sse / max(n_rows - x.size, 1)
        try:
            cov = np.linalg.pinv(jac.T @ jac) * s2
        except np.linalg.LinAlgError:
            return {q.name: float("nan") for q in self.qs}
        out = {}
        for k, q in enumerate(self.qs):
            j = self.n_base + k
            sd = float(np.sqrt(max(cov[j, j], 0.0)))
            out[q.name] = sd * math.exp(x[j]) if q.log else sd
        return out
