"""Name the missing effect: every applicable catalogue candidate against the residual.

For the current (calibrated) model and its residual ``r = y − predict``:

1. Candidates: catalogue effects whose ``kinds`` include the model's kind, whose inputs are
   logged and vary (``t_on`` falls back to time since the first sample) and that are not yet
   in the model.
2. Deterministic candidates (:mod:`.fitting`): multi-start least squares of the model with the
   effect appended (bias and scale factor refitted with it) on the whole record for the
   reported parameters ± std; then on each fold's training blocks (interleaved contiguous
   blocks, :func:`.significance.block_folds`) and scored on the held-out blocks.
   p-value: circular moving-block bootstrap of the residual with the candidate's linearised
   regressors (:mod:`.significance`).
3. Stochastic candidates (:mod:`.stochastic`): Whittle fit to the residual's spectrum, held-out
   Kalman one-step score, likelihood-ratio p-value against the model's own noise (white + its
   stochastic effects), floored at ``P_FLOOR``. Quantization (:mod:`.lattice`): judged on
   the output histogram (readings on a lattice), Rayleigh-tail p-value.
4. Benjamini–Hochberg over all candidates' p-values at ``alpha``; a candidate is *named* only
   if BH-significant, its held-out score is positive, and its main parameter is physically
   meaningful (``Effect.min_effect``: |main| ≥ it, or ≤ it for a decreasing effect such as a
   bandwidth; a size that cannot be judged — min_effect raising — is not big enough).
5. Best: deterministic first — the highest held-out score among the named deterministic ones
   (a simpler candidate within one standard error is preferred); a named stochastic candidate
   replaces it only when it explains more on a common (Whittle) likelihood, survives the
   deterministic fit, and the deterministic one is not significant against a null that includes
   the stochastic process (:func:`choose`); close competitors = other candidates whose
   score is within two jackknife standard errors (over held-out blocks) of the best's; for each
   a separating experiment.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from bench.discovery import lattice as lat
from bench.discovery import significance as sig
from bench.discovery import stochastic as sto
from bench.discovery.choosing import choose, jackknife_ratio, parsimonious, stochastic_in
from bench.discovery.data import Record
from bench.discovery.effects_linalg import base_regressors
from bench.discovery.fitting import CandidateFitter
from bench.discovery.separating import separating_experiment

#: Smallest p-value reported: a χ² or Rayleigh tail below it underflows to 0.0 in floating point;
#: "p < 1e-300" is what such a value means.
P_FLOOR = 1e-300

@dataclass(frozen=True)
class Candidate:
    """One candidate's outcome: held-out score (variance reduction, ± jackknife se), p-value,
    BH-adjusted q, whether its main parameter reaches the minimum effect size, and whether it
    is named (significant, positive score, big enough)."""

    id: str
    stochastic: bool
    params: dict
    params_std: dict
    score: float
    score_se: float
    p_value: float
    q_value: float = 1.0
    big_enough: bool = False
    min_effect: float = float("nan")
    named: bool = False
    err_c: np.ndarray = field(default=None, repr=False)
    err_b: np.ndarray = field(default=None, repr=False)
    aic_gain: float = float("nan")  # stochastic: LR statistic − ln(n/2)·(extra parameters) (BIC)
    lr: float = float("nan")  # stochastic: likelihood-ratio statistic against the model's noise
    resid_full: np.ndarray = field(default=None, repr=False)  # deterministic: y − fitted prediction
    cols: list = field(default=None, repr=False)  # deterministic: per-fold linearised regressors
    lin: float = float("nan")  # deterministic: held-out score of the linearised regressors

    def to_dict(self) -> dict:
        return {"id": self.id, "stochastic": self.stochastic, "params": self.params,
                "params_std": self.params_std, "heldout_score": self.score, "heldout_score_se": self.score_se,
                "p_value": self.p_value, "q_value": self.q_value, "big_enough": self.big_enough,
                "min_effect": self.min_effect, "named": self.named}


@dataclass(frozen=True)
class Naming:
    """All candidates (best score first), the named best (or None), close competitors and how
    to separate them."""

    candidates: tuple[Candidate, ...]
    best: Candidate | None
    competitors: tuple[str, ...]
    separating: tuple[str, ...]
    null: str = "circular moving-block bootstrap of the residual (linearised regressors)"

    def to_dict(self) -> dict:
        return {"best": None if self.best is None else self.best.to_dict(),
                "competitors": list(self.competitors), "separating_experiments": list(self.separating),
                "candidates": [c.to_dict() for c in self.candidates], "null": self.null}


def applicable(model, rec: Record, catalogue: dict) -> list[str]:
    """Catalogue ids that apply to the model's kind and record and are not in the model yet (a
    sampled filter only on a record uniform to 0.1 %: :attr:`Effect.needs_uniform`)."""
    have = {eid for eid, _ in model.effects}
    out = []
    for eid, eff in catalogue.items():
        if eid in have or model.base.kind not in eff.kinds or (eff.needs_uniform and not rec.is_uniform()):
            continue
        # an input held constant cannot show an effect of it (it is one with the bias)
        if all(n in ("t", "t_on") or (rec.logged(n) and np.ptp(rec.column(n)) > 0) for n in eff.inputs):
            out.append(eid)
    return out


def _block_ids(n: int, n_blocks: int) -> np.ndarray:
    """Index of each sample's contiguous block: the blocks of :func:`.significance.block_folds`."""
    folds = sig.block_folds(n, n_blocks)
    return np.concatenate([[0], np.cumsum(np.diff(folds) != 0)]).astype(int)


#: A quantizer step above this many white-noise sd makes the residual's colour follow the signal.
COARSE_STEP_SD = 2.0


def _coarse_quantizer(model) -> bool:
    """The model quantizes with a step well above its white noise: readings then are Q(signal +
    noise) with little dither, the residual around E[Q] is a deterministic function of the
    signal (its colour follows the input's), and a spectral-shape test of a stochastic
    candidate has no valid null on it — stochastic candidates are not tried."""
    return any(eid == "quantization" and p["step"] > COARSE_STEP_SD * float(model.base.noise_sd)
               for eid, p in model.effects)


def _nuisance(rec: Record) -> np.ndarray:
    return base_regressors(rec)


def _base_errors(r: np.ndarray, x_nuis: np.ndarray, folds: np.ndarray) -> np.ndarray:
    err = np.zeros_like(r)
    for k in (0, 1):
        te = folds == k
        beta, *_ = np.linalg.lstsq(x_nuis[~te], r[~te], rcond=None)
        err[te] = (r[te] - x_nuis[te] @ beta) ** 2
    return err


def fit_deterministic(model, rec: Record, effect, eid: str, r: np.ndarray, folds: np.ndarray,
                      err_b: np.ndarray, rng: np.random.Generator, n_rep: int) -> Candidate:
    """Full-record fit (reported params), fold fits (held-out score), bootstrap p-value."""
    kind = model.base.kind
    f = CandidateFitter(model, rec, effect, eid)
    b0, s0 = float(model.base.bias), float(model.base.scale_factor)
    starts = [f.pack(p, b0, s0) for p in effect.fit_starts(rec, r, kind=kind)]
    full = f.fit(starts)
    err_c = np.zeros(rec.n)
    cols = []
    for k in (0, 1):
        te = folds == k
        # starts from the training blocks alone: a shape (a frequency, a time constant) chosen
        # with the held-out samples in view would leak them into the held-out score
        starts_k = [f.pack(p, b0, s0) for p in effect.fit_starts(rec, np.where(te, 0.0, r), kind=kind)[:2]]
        fk = f.fit(starts_k, rows=~te, max_nfev=40)
        pred = f.predict(fk.x)
        err_c[te] = (rec.y - pred)[te] ** 2
        g = pred - f.predict_without(fk.x)
        cols.append(np.column_stack([g, f.jacobian(fk.x)]))
    score = 1.0 - err_c.sum() / err_b.sum() if err_b.sum() > 0 else 0.0
    x_nuis = _nuisance(rec)
    lin = float("nan")
    if score > 0:
        lin = float(sig.heldout_linear_scores(r, x_nuis, cols, folds)[0])
        draw = None
        if stochastic_in(model):
            base = model.predict(rec)  # once: each draw is only the model's noise around it

            def draw(m):  # the model's own noise: white + its stochastic effects
                return np.column_stack([model.simulate(rec, rng) - base for _ in range(m)])
        p = sig.bootstrap_p_value(r, x_nuis, cols, folds, lin, n_rep=n_rep, rng=rng, draw=draw)
    else:
        p = 1.0  # no out-of-sample gain: conservatively not significant
    return Candidate(eid, False, full.params, full.params_std, float(score), float("nan"), float(p),
                     err_c=err_c, err_b=err_b, resid_full=rec.y - f.predict(full.x), cols=cols, lin=lin)


def _to_effect_params(effect, kind: str, fit: sto.StochasticFit, dt_s: float) -> tuple[dict, dict]:
    """Map a spectral fit onto the effect's parameters by their units: a correlation time (s),
    a level σ (u), or a random-walk density K (u/√s: per-sample variance q = K²·dt)."""
    p, s = {}, {}
    for q in effect.params_for(kind):
        name = q.name
        if name.endswith("_s") or q.unit == "s":
            val, sd = fit.tau_s, fit.tau_std_s
        elif fit.kind == "random_walk":
            val = math.sqrt(fit.q / dt_s)
            sd = 0.5 * fit.q_std / max(math.sqrt(fit.q * dt_s), 1e-300)
        else:
            val, sd = fit.sigma, fit.sigma_std
        p[name] = float(np.clip(val, q.low, q.high))
        s[name] = float(sd)
    return p, s


def fit_stochastic_candidate(model, rec: Record, effect, eid: str, r: np.ndarray,
                             folds: np.ndarray, rng: np.random.Generator | None = None) -> Candidate:
    """Whittle fit, held-out score and p-value of a stochastic candidate: the LR against the
    model's own noise (white + its stochastic effects, their spectrum fixed) referred to χ²."""
    kind = "gauss_markov" if eid == "gauss_markov" else "random_walk"
    dt = rec.dt_s
    known = stochastic_in(model)
    full = sto.fit_stochastic(r - r.mean(), dt, kind, known=known)
    score, err_c, err_b = sto.heldout_score(r, dt, kind, folds, np.array(full.theta))
    params, std = _to_effect_params(effect, model.base.kind, full, dt)
    df = 2 if kind == "gauss_markov" else 1
    p = full.p_value
    return Candidate(eid, True, params, std, score, float("nan"), max(p, P_FLOOR), err_c=err_c, err_b=err_b,
                     aic_gain=full.lr - math.log(rec.n / 2) * df, lr=full.lr)


def fit_lattice_candidate(model, rec: Record, effect, eid: str, folds: np.ndarray) -> Candidate:
    """Quantization on the output histogram (:mod:`.lattice`)."""
    q = effect.params_for(model.base.kind)[0]
    sd = float(model.base.noise_sd)
    fit = lat.fit_lattice(rec.y, sd, q.low, q.high)
    if not np.isfinite(fit.step):
        return Candidate(eid, False, {q.name: q.low}, {q.name: float("nan")}, 0.0, float("nan"), 1.0)
    score = lat.heldout_score(rec.y, sd, folds, q.low, q.high)
    return Candidate(eid, False, {q.name: float(np.clip(fit.step, q.low, q.high))}, {q.name: fit.step_std},
                     score, float("nan"), max(float(fit.p_value), P_FLOOR))


def _big_enough(effect, kind: str, params: dict, rec: Record, noise_sd: float,
                base=None) -> tuple[bool, float]:
    """(main parameter beyond the minimum size?, that size). An output-stage effect (clipping,
    rounding) acts on the output itself: its size is judged on ``bias + SF·input`` of ``base``
    (the calibrated base model), not on the unit-gain reference — a limit just under the input's
    peak clips every reading of a unit with a positive bias."""
    if base is not None and effect.stage == "output" and rec.logged("input"):
        rec = rec.replace(input=base.bias + base.scale_factor * rec.input)
    try:
        thr = effect.min_effect(rec, noise_sd, kind=kind, params=params, distinct=False)
    except (ValueError, ZeroDivisionError, FloatingPointError):
        return False, float("nan")  # fail closed: a size that cannot be judged is not big enough
    v = abs(float(params[effect.main_param]))
    return (v >= thr if effect.increasing else v <= thr), float(thr)


def name_effect(model, rec: Record, *, catalogue: dict | None = None, alpha: float = 0.05,
                seed: int = 0, n_rep: int = 999, n_blocks: int = sig.N_BLOCKS,
                only: tuple[str, ...] | None = None,
                progress: Callable[[str], None] | None = None) -> Naming:
    """Fit every applicable candidate to ``rec.y − model.predict(rec)``; see module docstring.
    ``only``: restrict to these ids (tests, quick runs); ``progress``: called with a short
    message (``"gauss_markov (5/17)"``) before each candidate's fit."""
    if catalogue is None:
        from bench.discovery.effects import CATALOGUE as catalogue  # noqa: N811
    if not 0 < alpha < 1:
        raise ValueError(f"alpha = {alpha!r}; allowed: (0, 1)")
    rng = np.random.default_rng(seed)
    r = rec.y - model.predict(rec)
    folds = sig.block_folds(rec.n, n_blocks)
    x_nuis = _nuisance(rec)
    err_b = _base_errors(r, x_nuis, folds)
    ids = applicable(model, rec, catalogue)
    if _coarse_quantizer(model):
        ids = [i for i in ids if not catalogue[i].stochastic]
    if only is not None:
        ids = [i for i in ids if i in only]
    kind = model.base.kind
    cands = []
    for k, eid in enumerate(ids):
        if progress is not None:
            progress(f"{eid} ({k + 1}/{len(ids)})")
        eff = catalogue[eid]
        if eff.stochastic:
            c = fit_stochastic_candidate(model, rec, eff, eid, r, folds, rng)
        elif eid == "quantization":
            c = fit_lattice_candidate(model, rec, eff, eid, folds)
        else:
            c = fit_deterministic(model, rec, eff, eid, r, folds, err_b, rng, n_rep)
        cands.append(c)
    if not cands:
        return Naming((), None, (), ())
    reject, q = sig.benjamini_hochberg([c.p_value for c in cands], alpha)
    blocks = _block_ids(rec.n, n_blocks)
    out = []
    reading_sd = float(model.residual_sd())  # a reading's sd: the noise through the model's quantizer, if any
    for c, rej, qv in zip(cands, reject, q):
        eff = catalogue[c.id]
        # the minimum effect size only matters for a candidate that could be named (and costs)
        sd = reading_sd
        if c.id == "quantization":  # the calibrated white level includes the steps' own s²/12
            sd = math.sqrt(max(sd ** 2 - c.params["step"] ** 2 / 12, (0.05 * sd) ** 2))
        elif c.err_c is not None and not c.stochastic:
            # a strong effect inflates the floor calibrated before it was known: judge its size
            # against the held-out residual once it is explained
            sd = min(sd, float(np.sqrt(np.mean(c.err_c))))
        big, thr = (_big_enough(eff, kind, c.params, rec, sd, model.base) if rej and c.score > 0
                    else (False, float("nan")))
        if c.id == "gauss_markov" and c.params.get("tau_s", 0.0) >= rec.duration_s / 5:
            big = False  # a correlation time beyond a fifth of the record is not identifiable on it
        se = float("nan")
        if c.err_c is not None:
            se = jackknife_ratio(np.bincount(blocks, c.err_c, n_blocks), np.bincount(blocks, c.err_b, n_blocks))
        out.append(Candidate(c.id, c.stochastic, c.params, c.params_std, c.score, se, c.p_value, float(qv),
                             big, thr, bool(rej and c.score > 0 and big), c.err_c, c.err_b, c.aic_gain,
                             c.lr, c.resid_full, c.cols, c.lin))
    out.sort(key=lambda c: -c.score)
    named = [c for c in out if c.named]
    det_pick = parsimonious(next((c for c in named if not c.stochastic), None), named, blocks, n_blocks,
                             catalogue, kind)
    named = ([det_pick] if det_pick is not None else []) + [c for c in named if c is not det_pick]

    def det_p_under(s: Candidate, d: Candidate) -> float:
        """p of ``d``'s held-out score when the model's noise includes stochastic ``s``."""
        if d.cols is None or not np.isfinite(d.lin):
            return 1.0
        m_s = model.with_effect(s.id, s.params)
        base = m_s.predict(rec)

        def draw(m):
            return np.column_stack([m_s.simulate(rec, rng) - base for _ in range(m)])
        return sig.bootstrap_p_value(r, x_nuis, d.cols, folds, d.lin, n_rep=n_rep, rng=rng, draw=draw)

    # the deterministic term's significance against the process: Bonferroni over the catalogue
    # (a realisation of a walk is as trendy as 1 % of walks about 1 % of the time)
    best = choose(named, model, rec, catalogue, kind, det_p_under, alpha / max(len(cands), 1))
    if best is None:
        return Naming(tuple(out), None, (), ())
    comps, seps = [], []
    for c in out:
        if c.id == best.id or c.score <= 0:
            continue
        if c.err_c is None or best.err_c is None:  # histogram-judged: no per-block errors to compare
            continue
        d_num = np.bincount(blocks, c.err_c - best.err_c, n_blocks)
        den = np.bincount(blocks, best.err_b, n_blocks)
        diff = d_num.sum() / den.sum()
        se = jackknife_ratio(d_num, den)
        if np.isfinite(se) and diff <= 2 * se:
            comps.append(c.id)
            seps.append(separating_experiment(best.id, c.id, catalogue))
    return Naming(tuple(out), best, tuple(comps), tuple(seps))
