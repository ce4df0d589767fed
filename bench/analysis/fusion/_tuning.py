"""Tuning the fusion methods on a stretch of record that has the table reference.

:class:`ToneScorer` scores any rate estimate on that stretch (RMS error, worst excess
amplitude error over the better single sensor, feasibility) and :func:`choose` applies the
rule below to a set of scored candidates; :func:`tune_crossover` picks the complementary
filter's crossover with them.

Document B leaves the process noise, the noise thresholds and the interval functions to
the user.  :func:`tune_fusion` chooses them from data: on a *tuning* stretch (the procedure
then evaluates on the rest of the record, never on the samples it tuned on) it runs the
sequential filter for every candidate of a small grid

* ``q_factor``  — the process noise ``q`` as a multiple of the data estimate
  (:func:`~bench.analysis.fusion._sequential.estimate_process_noise`): larger follows fast motion with
  less lag and passes more noise;
* ``upper_factor`` — ``r_upper = upper_factor·σ²`` (1: a fixed R);
* ``inflate`` — the "disturbed" interval's ``R = inflate·σ²`` (≤ ``upper_factor``; 1 is a
  fixed R whatever the bound, so it is tried with ``upper_factor`` 1 only);

and scores each by its RMS error against the reference and by its worst **excess**
amplitude error over the tones: ``|fused error| − min(|MHD alone error|, |LF alone
error|)`` in percentage points (Document B's claim is that this is never positive).

**Rule**: among candidates whose excess is, at every tone, at most ``tolerance_pct``
(default: two standard errors of the excess — from the noise of the fused-minus-sensor
series at the tone, :func:`~bench.analysis.fusion._metrics.tone_noise_std`: the fused rate
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

import bench.analysis.fusion._sequential as fu
from bench.analysis.fusion._metrics import tone_noise_std
from bench.analysis.fusion._models import FusionModel

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
    """The chosen candidate, every candidate scored, and the settings it implies.

    Methods: ``params(hf_var, lf_var, discretization)`` (the chosen :class:`FusionParams`) and
    ``fixed_r()`` (the fixed-R filter's own choice by the same rule).

    Attributes
    ----------
    chosen : Candidate
        The chosen ``q_factor``, ``upper_factor``, ``inflate`` with its RMS error (rate
        units), worst excess (percentage points) and feasibility.
    candidates : list of Candidate
        Every candidate scored, in grid order.
    tolerance_pct : float
        The excess tolerance given, in percentage points; NaN: two standard errors per tone.
    n_samples : int
        Samples of the tuning stretch.
    q_base : float
        The data estimate of the process noise q, rate²/s.
    rule : str
        The rule that chose, in words.
    q : float
        Property: ``q_base · chosen.q_factor``, rate²/s.
    """

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

    def fixed_r(self) -> Candidate:
        """The conventional filter's own choice: the same rule among the fixed-R candidates
        (``upper_factor`` 1), so that a fixed R is tuned as fairly as Document B's adaptive R."""
        fixed = [c for c in self.candidates if c.upper_factor == 1.0]
        if not fixed:
            raise ValueError("the grid held no fixed-R candidate (upper_factor 1)")
        return fixed[choose(fixed)[0]]

    def to_dict(self) -> dict:
        tol = float(self.tolerance_pct)
        return {"chosen": self.chosen.to_dict(), "tolerance_pct": tol if math.isfinite(tol) else None,
                "n_samples": int(self.n_samples), "q_base": float(self.q_base), "q": float(self.q),
                "rule": self.rule, "candidates": [c.to_dict() for c in self.candidates]}


@dataclass(frozen=True)
class Score:
    """A rate estimate on the tuning stretch: RMS error against the reference, worst excess
    amplitude error over the better single sensor (pp) and whether every tone's excess is
    within its tolerance."""

    rms_error: float
    excess_pct: float
    feasible: bool


class ToneScorer:
    """Scores rate estimates against ``ref`` on one stretch (after ``settle`` samples) at fixed
    tones: least-squares phasors by a pseudo-inverse computed once (QR), so each series costs one
    matrix product; ``singles`` are the sensors alone (÷ gain), whose better error per tone is
    the bar; the excess tolerance is ``tolerance_pct`` or, if ``None``, two standard errors of
    the estimate-minus-sensor series at each tone (:func:`tone_noise_std`)."""

    def __init__(self, t_s, ref, singles, tones_hz, rate_hz: float, settle: int = 0,
                 tolerance_pct: float | None = None) -> None:
        t = np.asarray(t_s, dtype=float)[settle:]
        self.keep = slice(settle, None)
        self.tones = np.asarray(tones_hz, dtype=float)
        self.rate_hz = float(rate_hz)
        self.ref = np.asarray(ref, dtype=float)[self.keep]
        if t.size < 10 * (2 * self.tones.size + 1):
            raise ValueError(f"{t.size} samples after settling: too few to score {self.tones.size} tones")
        arg = 2 * np.pi * np.outer(t - t[0], self.tones)
        design = np.column_stack([np.ones_like(t), np.cos(arg), np.sin(arg)])
        self.q, r = np.linalg.qr(design)
        self.pinv = np.linalg.solve(r, self.q.T)
        self.a_ref = self.phasors(self.ref)
        self.singles = [np.asarray(y, dtype=float)[self.keep] for y in singles]
        self.single_resid = [self.residual(y) for y in self.singles]
        errs = np.array([self.amp_err_pct(y) for y in self.singles])
        self.which = np.argmin(errs, axis=0)
        self.best_single = errs[self.which, np.arange(self.tones.size)]
        self.tolerance_pct = tolerance_pct

    def phasors(self, y: np.ndarray) -> np.ndarray:
        c = self.pinv @ y
        n = self.tones.size
        return c[1:1 + n] - 1j * c[1 + n:1 + 2 * n]

    def residual(self, y: np.ndarray) -> np.ndarray:
        """``y`` less its least-squares fit at the tones."""
        return y - self.q @ (self.q.T @ y)

    def amp_err_pct(self, y: np.ndarray) -> np.ndarray:
        """|amplitude error| (%) per tone of a series already cut to the stretch."""
        return 100 * np.abs(np.abs(self.phasors(y) / self.a_ref) - 1)

    def score(self, rate) -> Score:
        """Score a rate estimate covering the whole stretch (settling samples included)."""
        y = np.asarray(rate, dtype=float)[self.keep]
        e = y - self.ref
        rms = float(np.sqrt(np.mean(e * e)))
        excess = self.amp_err_pct(y) - self.best_single
        if self.tolerance_pct is None:
            idx = np.arange(self.tones.size)
            resid = self.residual(y)  # the fit is linear: y − sensor's residual is the residuals' difference
            sd = np.vstack([tone_noise_std(resid - r, self.rate_hz, self.tones)
                            for r in self.single_resid])[self.which, idx]
            tol = 2 * 100 * sd / np.abs(self.a_ref)
        else:
            tol = np.full(self.tones.size, float(self.tolerance_pct))
        return Score(rms, float(np.max(excess)), bool(np.all(excess <= tol)))


def choose(scores: list) -> tuple[int, str]:
    """Index of the chosen score (anything with ``rms_error``, ``excess_pct``, ``feasible``)
    and the rule that chose it: the lowest RMS error among the feasible; if none is, the lowest
    worst excess (then RMS).  Ties go to the earlier entry."""
    if not scores:
        raise ValueError("no candidates to choose from")
    order = range(len(scores))
    feasible = [i for i in order if scores[i].feasible]
    if feasible:
        return (min(feasible, key=lambda i: (scores[i].rms_error, i)),
                "lowest RMS error among those whose excess is within tolerance at every tone")
    return (min(order, key=lambda i: (scores[i].excess_pct, scores[i].rms_error, i)),
            "none has its excess within tolerance at every tone: the lowest worst excess")


def tune_fusion(t_s, hf, lf, ref, rate_hz: float, model: FusionModel, hf_var: float, lf_var: float, tones_hz, *,
                q_factors=Q_FACTORS, upper_factors=UPPER_FACTORS, inflates=INFLATES,
                tolerance_pct: float | None = None, settle_s: float = 1.0,
                discretization: str = "euler") -> FusionTuning:
    """Document B's process noise and adaptive-R settings chosen by a grid search against a reference.

    Grid search of the module docstring on one stretch; ``model.q`` is the base ``q``.

    Runs :func:`sequential_fusion` for every ``(q_factor, upper_factor, inflate)`` of the grid
    (``inflate`` ≤ ``upper_factor``; 1 only with ``upper_factor`` 1) and picks, among those
    whose excess amplitude error over the better single sensor is within tolerance at every
    tone, the lowest RMS error; if none is, the lowest worst excess. Ties go to the smaller
    factors.

    Parameters
    ----------
    t_s : array_like, shape (n,)
        Sample times of the tuning stretch, in s.
    hf : array_like, shape (n,)
        HF sensor readings, its output unit; finite.
    lf : array_like, shape (n,)
        LF sensor readings, its output unit; finite.
    ref : array_like, shape (n,)
        The reference rate, rate unit.
    rate_hz : float
        Sample rate, in Hz.
    model : FusionModel
        Both sensor models; ``model.q`` is the base q (rate²/s) the factors multiply.
    hf_var : float
        The HF sensor's white-noise variance σ², its unit².
    lf_var : float
        The LF sensor's white-noise variance σ², its unit².
    tones_hz : array_like
        The reference's tones, in Hz, non-empty, within (0, ``rate_hz``/2).
    q_factors : sequence of float, default (1, 2, 5, 10, 20, 50)
        Multiples of the base q tried; non-empty, finite, ≥ 1e-6.
    upper_factors : sequence of float, default (1, 3, 10, 100)
        ``r_upper`` in units of σ²; non-empty, finite, ≥ 1.
    inflates : sequence of float, default (1, 3, 10)
        The disturbed interval's R in units of σ²; non-empty, finite, ≥ 1.
    tolerance_pct : float, optional
        Excess tolerance, in percentage points; default two standard errors of the
        estimate-minus-sensor series at each tone.
    settle_s : float, default 1.0
        Start-up of the stretch left out of the scores, in s.
    discretization : {"euler", "zoh"}, default "euler"
        Discretisation of the model.

    Returns
    -------
    FusionTuning
        The chosen candidate, every candidate scored, the base q and the rule.

    Raises
    ------
    ValueError
        If the series are not of one length (or not finite), the tones are empty or outside
        (0, Nyquist), a grid is empty or out of range, or the stretch is too short to score
        the tones.

    Examples
    --------
    >>> import numpy as np
    >>> from bench.analysis.fusion import FusionModel, SensorModel, tune_fusion
    >>> hf_model, lf_model = SensorModel("highpass", 1, 2.0), SensorModel("lowpass", 1, 30.0)
    >>> fs, f = 1000.0, np.array([2.0, 10.0, 50.0, 150.0])  # 1 kHz; four tones, 1 dps each
    >>> t = np.arange(4000) / fs
    >>> rng = np.random.default_rng(0)
    >>> def read(model, sd):  # the sensor's steady-state reading of the tones, plus white noise
    ...     g = model.response(f)
    ...     y = np.sum(np.abs(g) * np.sin(2 * np.pi * np.outer(t, f) + np.angle(g)), axis=1)
    ...     return y + sd * rng.standard_normal(t.size)
    >>> rate = np.sin(2 * np.pi * np.outer(t, f)).sum(axis=1)
    >>> hf, lf = read(hf_model, 0.02), read(lf_model, 0.01)
    >>> def rms(x):  # error against the true rate after the first second, dps
    ...     return round(float(np.sqrt(np.mean((x - rate)[1000:] ** 2))), 3)
    >>> rms(hf / hf_model.gain), rms(lf / lf_model.gain)  # each sensor alone loses part of the band
    (0.52, 0.949)
    >>> tuning = tune_fusion(t, hf, lf, rate, fs, FusionModel(hf_model, lf_model, 1000.0), 0.02 ** 2, 0.01 ** 2, f)
    >>> len(tuning.candidates), tuning.q == tuning.q_base * tuning.chosen.q_factor
    (36, True)
    >>> round(tuning.chosen.rms_error, 3)
    0.021
    """
    t = np.asarray(t_s, dtype=float)
    hf, lf = fu.check_series(hf, lf)
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
    scorer = ToneScorer(t, ref, [hf / model.hf.gain, lf / model.lf.gain], tones, rate_hz,
                        int(round(settle_s * rate_hz)), tolerance_pct)
    ts = 1.0 / rate_hz
    candidates = []
    for qf, up, inf in itertools.product(sorted(q_factors), sorted(upper_factors), sorted(inflates)):
        if inf > up or (inf == 1.0 and up > 1.0):  # inflate 1 is a fixed R whatever the bound
            continue
        params = fu.FusionParams(fu.AdaptiveNoise.from_noise(hf_var, 0.0, up, inf),
                                 fu.AdaptiveNoise.from_noise(lf_var, 0.0, up, inf), discretization)
        sc = scorer.score(fu.sequential_fusion(hf, lf, ts, FusionModel(model.hf, model.lf, model.q * qf), params).rate)
        candidates.append(Candidate(qf, up, inf, sc.rms_error, sc.excess_pct, sc.feasible))
    tolerance = float(tolerance_pct) if tolerance_pct is not None else math.nan
    limit = "2 standard errors of the difference" if tolerance_pct is None else f"{tolerance_pct:.3g} pp"
    # candidates are in grid order (smaller factors first), so ties go to the smaller factors
    index, rule = choose(candidates)
    chosen = candidates[index]
    rule = rule.replace("within tolerance", f"within {limit}")
    return FusionTuning(chosen, candidates, tolerance, int(t.size), float(model.q), rule)


@dataclass(frozen=True)
class SettingsTuning:
    """Result of :func:`tune_settings`: the chosen settings, every candidate with its score,
    and the rule."""

    chosen: dict
    candidates: list
    rule: str

    def to_dict(self) -> dict:
        return {"chosen": dict(self.chosen), "rule": self.rule,
                "candidates": [{**st, "rms_error": float(sc.rms_error), "excess_pct": float(sc.excess_pct),
                                "feasible": bool(sc.feasible)} for st, sc in self.candidates]}


def tune_settings(scorer: ToneScorer, settings: list, run, rms_only: bool = False) -> SettingsTuning:
    """Score ``run(**s)`` (a rate over the scorer's stretch) for every dict ``s`` of
    ``settings`` and :func:`choose` one (``rms_only``: the lowest RMS error, for a method whose
    setting trades noise against noise and not against lag, as a complementary filter's
    crossover does)."""
    if not settings:
        raise ValueError("no settings to tune over")
    scores = [scorer.score(run(**st)) for st in settings]
    if rms_only:
        index = min(range(len(scores)), key=lambda i: (scores[i].rms_error, i))
        rule = "lowest RMS error"
    else:
        index, rule = choose(scores)
    return SettingsTuning(dict(settings[index]), list(zip(settings, scores)), rule)


def crossover_grid(hf_corner_hz: float, lf_corner_hz: float, rate_hz: float, n: int = 13) -> list[dict]:
    """Complementary-filter crossovers to try: ``n`` log-spaced from a third of the HF corner to
    three times the LF corner (at most a quarter of the sample rate)."""
    lo = hf_corner_hz / 3
    hi = min(3 * lf_corner_hz, rate_hz / 4)
    if not lo < hi:
        hi = 3 * lo
    return [{"crossover_hz": float(f)} for f in np.geomspace(lo, hi, n)]


#: Document B's adaptive R on top of the complementary Kalman filter: (r_upper, disturbed R) in σ²
ADAPTIVE_SETTINGS = ({"upper_factor": 3.0, "inflate": 3.0}, {"upper_factor": 10.0, "inflate": 3.0},
                     {"upper_factor": 10.0, "inflate": 10.0}, {"upper_factor": 100.0, "inflate": 10.0},
                     {"upper_factor": 100.0, "inflate": 100.0})
