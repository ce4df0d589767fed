"""Tuning Document B's filter on a stretch of record that has the table reference.

Document B leaves the process noise, the noise thresholds and the interval functions to
the user.  :func:`tune_fusion` chooses them from data: on a *tuning* stretch (the procedure
then evaluates on the rest of the record, never on the samples it tuned on) it runs the
sequential filter for every candidate of a small grid

* ``q_factor``  — the process noise ``q`` as a multiple of the data estimate
  (:func:`~bench.analysis.fusion.estimate_process_noise`): larger follows fast motion with
  less lag and passes more noise;
* ``upper_factor`` — ``r_upper = upper_factor·σ²`` (1: a fixed R);
* ``inflate`` — the "disturbed" interval's ``R = inflate·σ²`` (≤ ``upper_factor``; 1 is a
  fixed R whatever the bound, so it is tried with ``upper_factor`` 1 only);

and scores each by its RMS error against the reference and by its worst **excess**
amplitude error over the tones: ``|fused error| − min(|MHD alone error|, |LF alone
error|)`` in percentage points (Document B's claim is that this is never positive).

**Rule**: among candidates whose excess is, at every tone, at most ``tolerance_pct``
(default: two standard errors of the excess — from the noise of the fused-minus-sensor
series at the tone, :func:`~bench.analysis.fusion_metrics.tone_noise_std`: the fused rate
and the sensor share most of their noise), the lowest RMS error; if none qualifies, the
lowest excess (then RMS).  Ties go to the smaller factors.  The conventional
fixed-R filter of the comparison shares the chosen ``q`` (same model), so what differs
between the two is only Document B's adaptive R.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np

from bench.analysis import fusion as fu
from bench.analysis.fusion_metrics import tone_noise_std
from bench.analysis.fusion_models import FusionModel

Q_FACTORS = (1.0, 2.0, 5.0, 10.0, 20.0, 50.0)
UPPER_FACTORS = (1.0, 3.0, 10.0, 100.0)
INFLATES = (1.0, 3.0, 10.0)


@dataclass(frozen=True)
class Candidate:
    q_factor: float
    upper_factor: float
    inflate: float
    rms_error: float
    excess_pct: float
    feasible: bool

    def to_dict(self) -> dict:
        return {k: (bool(v) if k == "feasible" else float(v)) for k, v in self.__dict__.items()}


@dataclass
class FusionTuning:
    """The chosen candidate, every candidate scored, and the settings it implies."""

    chosen: Candidate
    candidates: list = field(default_factory=list)
    tolerance_pct: float = 0.0
    n_samples: int = 0
    q_base: float = 0.0
    rule: str = ""

    def params(self, hf_var: float, lf_var: float, discretization: str = "euler") -> fu.FusionParams:
        c = self.chosen
        return fu.FusionParams(fu.AdaptiveNoise.from_noise(hf_var, 0.0, c.upper_factor, c.inflate),
                               fu.AdaptiveNoise.from_noise(lf_var, 0.0, c.upper_factor, c.inflate), discretization)

    @property
    def q(self) -> float:
        return self.q_base * self.chosen.q_factor

    def to_dict(self) -> dict:
        tol = float(self.tolerance_pct)
        return {"chosen": self.chosen.to_dict(), "tolerance_pct": tol if math.isfinite(tol) else None,
                "n_samples": int(self.n_samples), "q_base": float(self.q_base), "q": float(self.q),
                "rule": self.rule, "candidates": [c.to_dict() for c in self.candidates]}


class _Phasors:
    """Least-squares phasors at fixed tones for many series on one time axis: the design's
    pseudo-inverse is computed once (QR), each series then costs one matrix product."""

    def __init__(self, t_s: np.ndarray, tones_hz: np.ndarray) -> None:
        arg = 2 * np.pi * np.outer(t_s - t_s[0], tones_hz)
        design = np.column_stack([np.ones_like(t_s), np.cos(arg), np.sin(arg)])
        self.q, r = np.linalg.qr(design)
        self.pinv = np.linalg.solve(r, self.q.T)
        self.n = tones_hz.size

    def __call__(self, y: np.ndarray) -> np.ndarray:
        c = self.pinv @ y
        return c[1:1 + self.n] - 1j * c[1 + self.n:1 + 2 * self.n]

    def residual(self, y: np.ndarray) -> np.ndarray:
        """``y`` less its least-squares fit at the tones."""
        return y - self.q @ (self.q.T @ y)


def tune_fusion(t_s, hf, lf, ref, rate_hz: float, model: FusionModel, hf_var: float, lf_var: float, tones_hz, *,
                q_factors=Q_FACTORS, upper_factors=UPPER_FACTORS, inflates=INFLATES,
                tolerance_pct: float | None = None, settle_s: float = 1.0,
                discretization: str = "euler") -> FusionTuning:
    """Grid search of the module docstring on one stretch; ``model.q`` is the base ``q``."""
    t = np.asarray(t_s, dtype=float)
    hf, lf = fu._check_series(hf, lf)
    ref = np.asarray(ref, dtype=float)
    tones = np.asarray(tones_hz, dtype=float)
    if t.size != hf.size or ref.size != hf.size:
        raise ValueError(f"t ({t.size}), hf ({hf.size}) and ref ({ref.size}) must have one length")
    if tones.size == 0 or np.any(tones <= 0) or np.any(tones >= rate_hz / 2):
        raise ValueError(f"tones_hz must be non-empty and within (0, {rate_hz / 2:g}) Hz")
    for name, grid in (("q_factors", q_factors), ("upper_factors", upper_factors), ("inflates", inflates)):
        if len(grid) == 0 or not all(math.isfinite(v) and v >= (1.0 if name != "q_factors" else 1e-6)
                                     for v in grid):
            raise ValueError(f"{name} {grid!r} must be non-empty, finite and ≥ {'1' if name != 'q_factors' else '0'}")
    keep = slice(int(round(settle_s * rate_hz)), None)
    if t[keep].size < 10 * (2 * tones.size + 1):
        raise ValueError(f"{t[keep].size} samples after settling: too few to score {tones.size} tones")
    phasors = _Phasors(t[keep], tones)
    a_ref = phasors(ref[keep])

    def amp_err_pct(y: np.ndarray) -> np.ndarray:
        return 100 * np.abs(np.abs(phasors(y[keep]) / a_ref) - 1)

    singles = [hf / model.hf.gain, lf / model.lf.gain]
    errs = np.array([amp_err_pct(y) for y in singles])
    which = np.argmin(errs, axis=0)
    idx = np.arange(tones.size)
    best_single = errs[which, idx]
    ts = 1.0 / rate_hz
    candidates = []
    for qf, up, inf in itertools.product(sorted(q_factors), sorted(upper_factors), sorted(inflates)):
        if inf > up or (inf == 1.0 and up > 1.0):  # inflate 1 is a fixed R whatever the bound
            continue
        params = fu.FusionParams(fu.AdaptiveNoise.from_noise(hf_var, 0.0, up, inf),
                                 fu.AdaptiveNoise.from_noise(lf_var, 0.0, up, inf), discretization)
        rate = fu.sequential_fusion(hf, lf, ts, FusionModel(model.hf, model.lf, model.q * qf), params).rate
        e = rate[keep] - ref[keep]
        rms = float(np.sqrt(np.mean(e * e)))
        excess = amp_err_pct(rate) - best_single
        if tolerance_pct is None:  # 2 standard errors of the excess, from the fused-minus-sensor series
            sd = np.vstack([tone_noise_std(phasors.residual(rate[keep] - y[keep]), rate_hz, tones)
                            for y in singles])[which, idx]
            tol = 2 * 100 * sd / np.abs(a_ref)
        else:
            tol = np.full(tones.size, float(tolerance_pct))
        candidates.append(Candidate(qf, up, inf, rms, float(np.max(excess)), bool(np.all(excess <= tol))))
    tolerance = float(tolerance_pct) if tolerance_pct is not None else math.nan
    feasible = [c for c in candidates if c.feasible]
    limit = "2 standard errors of the difference" if tolerance_pct is None else f"{tolerance_pct:.3g} pp"
    if feasible:
        chosen = min(feasible, key=lambda c: (c.rms_error, c.q_factor, c.upper_factor, c.inflate))
        rule = f"lowest RMS error among candidates whose excess is within {limit} at every tone"
    else:
        chosen = min(candidates, key=lambda c: (c.excess_pct, c.rms_error, c.q_factor, c.upper_factor))
        rule = f"no candidate has its excess within {limit} at every tone: the lowest excess"
    return FusionTuning(chosen, candidates, tolerance, int(t.size), float(model.q), rule)
