"""Name the missing effect: every applicable catalogue candidate against the residual.

For the current (calibrated) model and its residual ``r = y − predict``:

1. Candidates: catalogue effects whose ``kinds`` include the model's kind, whose inputs are
   logged and vary (``t_on`` falls back to time since the first sample) and that are not yet
   in the model. When an effect of the model colours the residual with the signal
   (``Effect.colours_residual``: a coarse quantizer) a random process's likelihood ratio has
   no χ² reference: its p-value is then Monte-Carlo, against the same statistic on
   realisations of the model's own noise through that effect (:func:`fit_process`) — when
   that noise reproduces the readings (``Effect.null_holds``: on the quantizer's lattice);
   otherwise no random process is tried.
2. Each is fitted as its family says (:func:`fit_trial`):
   a waveform (:class:`~bench.discovery.effects_base.Effect`, :mod:`.fitting`): multi-start
   least squares of the model with the effect appended (bias and scale factor refitted with it)
   on the whole record for the reported parameters ± std; then on each fold's training blocks
   (interleaved contiguous blocks, :func:`.significance.block_folds`) and scored on the held-out
   blocks. p-value: circular moving-block bootstrap of the residual with the candidate's
   linearised regressors (:mod:`.significance`);
   a random process (:class:`~bench.discovery.effects_noise.StochasticEffect`, :mod:`.stochastic`):
   Whittle fit to the residual's spectrum, held-out Kalman one-step score, likelihood-ratio
   p-value against the model's own noise (white + its stochastic effects);
   histogram-judged (:class:`~bench.discovery.effects_base.HistogramEffect`): its own
   ``fit_histogram`` (quantization: readings on a lattice, Rayleigh-tail p-value).
   p-values are floored at :data:`.significance.P_FLOOR`. The fits draw no random number
   (:func:`fit_trial`, mapped over the candidates by the caller's ``map_fn``, :mod:`.mapping`:
   side by side in worker processes if it likes); the Monte-Carlo p-values follow, one
   candidate after the other on the step's generator (:func:`with_p_value`).
3. Benjamini–Hochberg over all candidates' p-values at ``alpha``; a candidate is *named* only
   if BH-significant, its held-out score is positive, its main parameter is physically
   meaningful (``Effect.big_enough``: |main| ≥ ``min_effect``, or ≤ it for a decreasing effect
   such as a bandwidth, against the sd ``Effect.size_noise_sd`` says; a size that cannot be
   judged is not big enough) and the record resolves it (``Effect.identifiable``).
4. Best: deterministic first — the highest held-out score among the named deterministic ones
   (a simpler candidate within one standard error is preferred; when the model already holds
   waveforms, the best few are weighed again with those refitted beside each:
   :func:`refitted_choice`); a named stochastic candidate
   replaces it only when it explains more on a common (Whittle) likelihood, survives the
   deterministic fit, and the deterministic one is not significant against a null that includes
   the stochastic process (:func:`.choosing.choose`) — or against another named process that,
   fitted beside it, makes the better joint explanation (the look-ahead of
   :func:`.choosing.preferred`); close competitors = other candidates whose
   score is within two jackknife standard errors (over held-out blocks) of the best's; for each
   a separating experiment.

The public outcome is a :class:`~bench.discovery.candidates.Naming` of frozen
:class:`~bench.discovery.candidates.Candidate` records; the fits' working arrays stay in the
:class:`~bench.discovery.candidates.Trial` records used here.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from functools import cache, partial

import numpy as np

from bench.discovery import significance as sig
from bench.discovery import stochastic as sto
from bench.discovery.calibration import calibrate
from bench.discovery.candidates import Candidate, Naming, Trial
from bench.discovery.choosing import choose, parsimonious
from bench.discovery.data import Record
from bench.discovery.effects import CATALOGUE
from bench.discovery.effects_base import MIN_SNR, Effect, HistogramEffect
from bench.discovery.effects_linalg import base_regressors
from bench.discovery.effects_noise import StochasticEffect
from bench.discovery.evidence import Evidence, evidence
from bench.discovery.fitting import CandidateFitter
from bench.discovery.mapping import MapFn
from bench.discovery.model import Model
from bench.discovery.separating import separating_experiment
from bench.discovery.whiten import innovations, seen_only


def applicable(model: Model, rec: Record) -> list[Effect]:
    """Catalogue effects that apply to the model's kind and record and are not in the model yet
    (a sampled filter only on a record uniform to 0.1 %: :attr:`Effect.needs_uniform`)."""
    have = set(model.effect_ids)
    out = []
    for eff in CATALOGUE.values():
        if eff.id in have or model.base.kind not in eff.kinds or (eff.needs_uniform and not rec.is_uniform()):
            continue
        if eff.applies_to(rec):
            out.append(eff)
    return out


def _block_ids(n: int, n_blocks: int) -> np.ndarray:
    """Index of each sample's contiguous block (:func:`.significance.block_edges`: the blocks of
    the folds; the first one whole, though its spans alternate between the folds)."""
    edges = sig.block_edges(n, n_blocks)
    return np.repeat(np.arange(edges.size - 1), np.diff(edges))


def base_errors(r: np.ndarray, x_nuis: np.ndarray, folds: np.ndarray) -> np.ndarray:
    """Squared held-out errors of the nuisance regressors alone (each fold fitted on the other):
    the baseline of every candidate's held-out score."""
    err = np.zeros_like(r)
    for k in (0, 1):
        te = folds == k
        beta, *_ = np.linalg.lstsq(x_nuis[~te], r[~te], rcond=None)
        err[te] = (r[te] - x_nuis[te] @ beta) ** 2
    return err


def fit_waveform(model: Model, rec: Record, effect: Effect, r: np.ndarray, folds: np.ndarray,
                 err_b: np.ndarray) -> Trial:
    """Full-record fit (reported params), fold fits (held-out score) and the linearised
    regressors of the bootstrap p-value (:func:`waveform_p_value`; p is NaN until then)."""
    kind = model.base.kind
    b0, s0 = float(model.base.bias), float(model.base.scale_factor)
    # the effect's starts share the parameters a fit moves (effect.free_params of the first);
    # they read the residual's shape where the output follows its input (a jump inside a clipped
    # stretch leaves no step in the residual; the clip's edges leave steps of their own)
    seen = model.follows_input(rec)
    starts = effect.fit_starts(rec, r, kind=kind, rows=None if seen.all() else seen)
    f = CandidateFitter(model, rec, effect, template=starts[0] if starts else None)
    full = f.fit([f.pack(p, b0, s0) for p in starts])
    err_c = np.zeros(rec.n)
    cols = []
    for k in (0, 1):
        te = folds == k
        # starts from the training blocks alone: a shape (a frequency, a time constant) chosen
        # with the held-out samples in view would leak them into the held-out score
        starts_k = effect.fit_starts(rec, r, kind=kind, rows=~te & seen, held_out=te)[:2]
        fk_fitter = CandidateFitter(model, rec, effect, template=starts_k[0] if starts_k else None, rows=~te)
        fk = fk_fitter.fit([fk_fitter.pack(p, b0, s0) for p in starts_k], rows=~te, max_nfev=40, with_std=False)
        pred = fk_fitter.predict(fk.x)
        err_c[te] = (rec.y - pred)[te] ** 2
        g = pred - fk_fitter.predict_without(fk.x)
        cols.append(np.column_stack([g, fk_fitter.jacobian(fk.x)]))
    score = 1.0 - err_c.sum() / err_b.sum() if err_b.sum() > 0 else 0.0
    lin = float(sig.heldout_linear_scores(r, base_regressors(rec), cols, folds)[0]) if score > 0 else float("nan")
    return Trial(effect, full.params, full.params_std, float(score), float("nan"), err_c=err_c, err_b=err_b,
                 resid_full=rec.y - f.predict(full.x), cols=cols, lin=lin)


def waveform_p_value(trial: Trial, model: Model, rec: Record, folds: np.ndarray, rng: np.random.Generator,
                     n_rep: int, fill_map: MapFn = map) -> float:
    """Bootstrap p-value of a fitted waveform's held-out linear score (1 without an
    out-of-sample gain: conservatively not significant); ``fill_map``: how the model's noise
    realisations are filled (:meth:`.Model.simulate_noise_many`)."""
    if not trial.score > 0 or trial.resid_full is None or trial.cols is None:
        return 1.0
    draw: Callable[[int], np.ndarray] | None = None
    if model.stochastic_effects():

        def model_noise(m: int) -> np.ndarray:  # the model's own noise: white + its stochastic effects
            return model.simulate_noise_many(rec, rng, m, fill_map=fill_map)
        draw = model_noise
    # the null's residual is the record's with the candidate's fit taken out: it keeps the
    # noise's autocorrelation but not the effect itself — a block holding a start-up
    # transient or a jump, pasted at the start by the bootstrap, would score like the data
    # (a 94-σ warm-up of 16 s got p = 0.004 from 1 in ~100 replicates starting there)
    r_null = trial.resid_full
    return sig.bootstrap_p_value(r_null - r_null.mean(), base_regressors(rec), trial.cols, folds, trial.lin,
                                 n_rep=n_rep, rng=rng, draw=draw)


#: Replicates per chunk of the Monte-Carlo null of a random process beside a coarse quantizer
#: (:func:`process_p_value`): a clear result stops after two chunks.
MC_CHUNK = 25
#: At most this many replicates of that null (each a Whittle fit, ~40 ms): p resolves to
#: 1/600, below the first Benjamini–Hochberg threshold over a kind's ~25 candidates (0.05/25).
MC_MAX_REP = 599


#: Named random processes whose Whittle BIC gains all lie within this of the best one are a close
#: call of shape: their order is the exact likelihood's (:func:`shape_ranked`).
SHAPE_TIE = 4.0


def shape_ranked(named: list[Trial], model: Model, rec: Record, r: np.ndarray) -> list[Trial]:
    """``named`` with ``shape_bic`` set on its random processes when there are two or more and the
    Whittle BIC gain of each is within :data:`SHAPE_TIE` of the best one's: their exact (Kalman)
    likelihood at the shape's own states, the model's processes beside them
    (:func:`.stochastic.exact_shape_bic`), by which :func:`.choosing.preferred` orders them. A
    Gauss–Markov whose plateau spans a few Fourier bins and a flicker band are a few Whittle
    units apart either way; the Whittle spectrum of flicker is the idealised 1/f band, its
    draw the sum of Gauss–Markov states the exact likelihood holds.
    Where the model's output stage clips (``Model.noise_seen`` False) the residual holds no
    noise: those samples are missing to the exact likelihood, and every named process is ranked
    by it — the Whittle likelihood reads the clipped stretches' flat residual as part of the
    process (accelerometer K3 + clip + GM, 18 % clipped: flicker 5.4 Whittle units above the GM,
    the GM 21 exact units above flicker with the clipped samples missing, τ 22.5 s for 21.2 s).
    Only when every named process is in the close call: where one is clearly worse on the
    spectrum (a walk below a Gauss–Markov and flicker), its band resolves the shapes and the
    Whittle order stands. At the step after the deterministic effects of 434 scorecard triples
    with a random process (``--pairs 0``…``12``, the effects at their truth) and 72 singles,
    ranking those two by the exact likelihood had the shape wrong 17 times the Whittle order had it
    right (flicker read as a Gauss–Markov 10, a walk as flicker 5, as a GM 2), and right 5 times it
    was wrong (Gauss–Markov): 443 right for 431 (``benchmarks/discovery_shape_calls.py``)."""
    procs = [t for t in named if t.effect.stochastic and np.isfinite(t.bic_gain)]
    if len(procs) < 2:
        return named
    seen = model.partly_seen(rec)
    clipped = seen is not None
    top = max(t.bic_gain for t in procs)
    if not clipped and any(t.bic_gain < top - SHAPE_TIE for t in procs):
        return named  # a shape clearly worse on the spectrum: its band resolves the shapes
    x = seen_only(r, seen)
    white = float(model.residual_sd()) or float(np.nanstd(x)) or 1.0
    known = model.stochastic_effects()
    shape = {t.id: sto.exact_shape_bic(x, rec.dt_s, t.effect, t.params, white, known) for t in procs}
    return [replace(t, shape_bic=shape[t.id]) if t.id in shape else t for t in named]


def colour_beside(det: Trial | None, named: list[Trial], model: Model, rec: Record, alpha: float = 0.05
                  ) -> Callable[[np.ndarray], np.ndarray] | None:
    """The standardized Kalman innovations of a residual under the model's noise and the best
    named random process (by BIC gain) refitted to what the deterministic candidate ``det``
    leaves (the model's processes known) — the noise :func:`.choosing.parsimonious` judges a
    nesting shape's in-sample gain in (it asks for it only then); None without a named process or ``det``'s residual, or
    when the process is not significant beside ``det`` (p ≥ ``alpha``: the colour was ``det``'s)."""
    procs = [t for t in named if t.effect.stochastic and np.isfinite(t.bic_gain)]
    if det is None or det.resid_full is None or not procs:
        return None
    eff = max(procs, key=lambda t: t.bic_gain).effect
    if not isinstance(eff, StochasticEffect):
        return None
    known = model.stochastic_effects()
    fit = sto.fit_stochastic(det.resid_full - det.resid_full.mean(), rec.dt_s, eff, known=known, bootstrap=False)
    if not (fit.p_value < alpha and np.isfinite(fit.white_sd) and fit.white_sd > 0):
        return None
    return partial(innovations, rate_hz=rec.rate_hz, white_sd=float(fit.white_sd),
                   stochastic_effects=(*known, (eff, fit.params_for(model.base.kind))))


def fit_process(model: Model, rec: Record, effect: StochasticEffect, r: np.ndarray, folds: np.ndarray) -> Trial:
    """Whittle fit, held-out score and p-value of a stochastic candidate: the LR against the
    model's own noise (white + its stochastic effects, their spectrum fixed) referred to χ²
    (a Monte-Carlo null replaces it where there is no χ² reference: :func:`process_p_value`);
    parameters clipped to the kind's ranges — beside an output stage that clips, by the exact
    likelihood with the clipped samples missing (:func:`.stochastic.censored_params`)."""
    known = model.stochastic_effects()
    full = sto.fit_stochastic(r - r.mean(), rec.dt_s, effect, known=known)
    score, err_c, err_b = sto.heldout_score(r, rec.dt_s, effect, folds, np.array(full.theta))
    params = full.params_for(model.base.kind)
    seen = model.partly_seen(rec)
    if seen is not None:  # a clip's stretches hold no noise: its values by the exact likelihood
        params = sto.censored_params(r, seen, rec.dt_s, effect, params, full.white_sd, model.base.kind, known)
    std = {name: float(full.params_std[name]) for name in params}
    return Trial(effect, params, std, score, max(full.p_value, sig.P_FLOOR), err_c=err_c, err_b=err_b,
                 lr=full.lr, bic_gain=full.lr - math.log(rec.n / 2) * effect.n_coords)


def process_p_value(trial: Trial, model: Model, rec: Record, rng: np.random.Generator, n_rep: int) -> float:
    """A fitted random process's p-value: its χ² one — or, when an effect of the model colours
    the residual with the signal (a coarse quantizer's rounding: no χ² reference), the same
    statistic on realisations of the model's own noise through it
    (:func:`.significance.sequential_p_value`, chunks of :data:`MC_CHUNK`, at most
    :data:`MC_MAX_REP`)."""
    if not model.colours_residual():
        return trial.p_value
    effect, known, dt = trial.effect, model.stochastic_effects(), rec.dt_s

    def null_lr(m: int) -> np.ndarray:
        out = []
        for _ in range(m):
            x = model.simulate_noise(rec, rng)
            out.append(sto.fit_stochastic(x - x.mean(), dt, effect, known=known, bootstrap=False).lr)
        return np.array(out)
    p_value = sig.sequential_p_value(trial.lr, null_lr, n_rep=min(n_rep, MC_MAX_REP), chunk=MC_CHUNK)
    return max(p_value, sig.P_FLOOR)


def fit_histogram(model: Model, rec: Record, effect: HistogramEffect, folds: np.ndarray) -> Trial:
    """A histogram-judged candidate: the effect's own ``fit_histogram`` on the readings."""
    fit = effect.fit_histogram(rec.y, float(model.base.noise_sd), folds, model.base.kind)
    return Trial(effect, fit.params, fit.params_std, fit.score, max(fit.p_value, sig.P_FLOOR))


def fit_trial(model: Model, rec: Record, r: np.ndarray, folds: np.ndarray, err_b: np.ndarray,
              effect: Effect) -> Trial:
    """The candidate fitted as its family says — a random process on the spectrum, a
    histogram-judged effect on the readings, any other effect as a waveform — without drawing
    a random number: a Monte-Carlo p-value is left to :func:`with_p_value`, so candidates can
    be fitted in any order, or side by side, and give the same numbers."""
    if isinstance(effect, StochasticEffect):
        return fit_process(model, rec, effect, r, folds)
    if isinstance(effect, HistogramEffect):
        return fit_histogram(model, rec, effect, folds)
    return fit_waveform(model, rec, effect, r, folds, err_b)


def with_p_value(trial: Trial, model: Model, rec: Record, folds: np.ndarray, rng: np.random.Generator,
                 n_rep: int, fill_map: MapFn = map) -> Trial:
    """``trial`` with its Monte-Carlo p-value (floored at :data:`.significance.P_FLOOR`): the
    bootstrap of a waveform's held-out score, a random process's null beside a coarse
    quantizer; the candidates take their turns on ``rng`` in the catalogue's order."""
    if isinstance(trial.effect, StochasticEffect):
        return replace(trial, p_value=process_p_value(trial, model, rec, rng, n_rep))
    if isinstance(trial.effect, HistogramEffect):
        return trial
    return replace(trial, p_value=max(waveform_p_value(trial, model, rec, folds, rng, n_rep, fill_map),
                                      sig.P_FLOOR))


def judge(trial: Trial, significant: bool, q_value: float, model: Model, rec: Record, reading_sd: float,
          blocks: np.ndarray, n_blocks: int) -> Candidate:
    """The public record of one fitted candidate: named when BH-``significant``, with a
    positive held-out score, big enough (against ``Effect.size_noise_sd`` of ``reading_sd`` —
    for a waveform no more than its held-out residual: a strong effect inflates the floor
    calibrated before it was known) and resolvable on the record."""
    eff = trial.effect
    kind = model.base.kind
    sd = eff.size_noise_sd(trial.params, reading_sd)
    if trial.err_c is not None and eff.waveform:
        sd = min(sd, float(np.sqrt(np.mean(trial.err_c))))
    # the minimum effect size only matters for a candidate that could be named (and costs)
    big, thr = (eff.big_enough(trial.params, rec, sd, kind=kind, bias=model.base.bias,
                               scale_factor=model.base.scale_factor)
                if significant and trial.score > 0 else (False, float("nan")))
    if not eff.identifiable(trial.params, rec):
        big = False
    if not eff.shape_inside(trial.params) and not set(eff.nests) & set(model.effect_ids):
        big = False  # beside a shape it nests, the merge judges the pair once the names are in
    se = float("nan")
    if trial.err_c is not None and trial.err_b is not None:
        se = sig.jackknife_ratio(np.bincount(blocks, trial.err_c, n_blocks), np.bincount(blocks, trial.err_b, n_blocks))
    return Candidate(trial.id, eff.stochastic, trial.params, trial.params_std, trial.score, se, trial.p_value,
                     q_value=q_value, big_enough=big, min_effect=thr,
                     named=bool(significant and trial.score > 0 and big))


#: A deterministic term's test against a random process (``det_p_under``) draws enough null
#: replicates to see this many exceed it before its p reaches the Bonferroni level.
DET_EXCEEDANCES = 4
#: Deterministic candidates (by held-out score) whose joint refit :func:`refitted_choice` weighs.
REFIT_TOP = 3


def refitted_choice(pick: Trial | None, named: list[Trial], model: Model, rec: Record, kind: str,
                    noise_sd: float, joint_residual: Callable[[Trial], np.ndarray]) -> Trial | None:
    """The deterministic choice once the model's waveform effects are refitted beside each of the
    best named waveform candidates (the first :data:`REFIT_TOP` by held-out score, and ``pick``):
    a candidate's fit holds the earlier effects fixed, so an effect fitted before a missing one
    has taken part of it (a two-node warm-up fitted without the drift beside it bends its slow
    node toward the ramp) and the candidate that is truly missing looks smaller than it is —
    while a shape that can follow what is left (three jumps stepping along the rest of the
    ramp) scores above it. The candidate whose joint refit leaves the least —
    ``n·ln(SSE) + ln(n)·parameters`` (its own and its fit's, the residual's mean removed) lower
    than ``pick``'s by more than ``MIN_SNR²`` (the size gate in σ², as the nesting rule) —
    replaces it (a shape nesting the pick or nested by it is not weighed here: the nesting rule
    of :func:`.choosing.parsimonious` did, with refits), and its residual is the refit's; only
    when the refit is what tells them apart:
    its own gain from the refit (the criterion of its own fit less its refit's) exceeds
    ``pick``'s by the same gate — an in-sample criterion beside a random process rewards any
    flexible shape (three jumps along a walk's wander), which the held-out score had judged.
    ``pick`` unchanged without earlier waveform effects (nothing to refit) or when no other
    waveform candidate is named. ``joint_residual(t)``: the residual, mean removed, with ``t``
    added to the model and every parameter refitted."""
    if pick is None or pick.effect.stochastic or not pick.effect.waveform or noise_sd <= 0:
        return pick
    if not any(e.waveform and not e.stochastic for e, _ in model.entries()):
        return pick
    # a shape nesting the pick, or nested by it, was weighed by the nesting rule (with refits)
    det = [t for t in named if t.effect.waveform and not t.effect.stochastic and t.resid_full is not None
           and (t is pick or (pick.id not in t.effect.nests and t.id not in pick.effect.nests))]
    pool = det[:REFIT_TOP] + ([pick] if pick not in det[:REFIT_TOP] else [])
    if len(pool) < 2:
        return pick
    n = rec.n

    def crit(t: Trial, res: np.ndarray) -> float:
        res = res - res.mean()
        return n * math.log(float(np.sum(res ** 2)) / n) + math.log(n) * len(t.effect.params_for(kind))

    fits = {id(t): (crit(t, joint_residual(t)), joint_residual(t)) for t in pool}

    def refit_gain(t: Trial) -> float:  # what refitting the earlier effects beside t adds to t's own fit
        return crit(t, np.asarray(t.resid_full, float)) - fits[id(t)][0]
    best = min(pool, key=lambda t: fits[id(t)][0])
    gate = MIN_SNR ** 2
    if best is pick or fits[id(pick)][0] - fits[id(best)][0] <= gate:
        return pick
    if refit_gain(best) - refit_gain(pick) <= gate:
        return pick  # not the refit's doing: in-sample flexibility (jumps along a walk's wander)
    return replace(best, resid_full=fits[id(best)][1])


def name_effect(model: Model, rec: Record, *, alpha: float = 0.05, seed: int = 0, n_rep: int = 999,
                n_blocks: int = sig.N_BLOCKS, only: tuple[str, ...] | None = None, catch_alls: bool = True,
                exclude: frozenset[str] = frozenset(), progress: Callable[[str], None] | None = None,
                map_fn: MapFn = map, fill_map: MapFn = map) -> Naming:
    """Fit every applicable candidate to ``rec.y − model.predict(rec)``; see module docstring.
    ``only``: restrict to these ids (tests, quick runs); ``catch_alls`` False: no catch-all is
    tried (the slow structure is known to follow a logged column no effect explains);
    ``exclude``: ids not tried (the workflow's withdrawn effects, when it re-chooses);
    ``progress``: called with a short message (``"gauss_markov (5/17)"``) as each candidate's
    p-value is drawn; ``map_fn``: how the candidates' fits (:func:`fit_trial`, no random
    numbers) are mapped over them — the builtin ``map``, or an executor's ``map`` running them
    side by side (the same numbers either way); ``fill_map``: how the nulls' noise realisations
    are filled in this process (a thread pool's ``map``: the same numbers)."""
    if not 0 < alpha < 1:
        raise ValueError(f"alpha = {alpha!r}; allowed: (0, 1)")
    rng = np.random.default_rng(seed)
    r = rec.y - model.predict(rec)
    folds = sig.block_folds(rec.n, n_blocks)
    x_nuis = base_regressors(rec)
    err_b = base_errors(r, x_nuis, folds)
    effects = applicable(model, rec)
    if only is not None:
        effects = [e for e in effects if e.id in only]
    if not catch_alls:
        effects = [e for e in effects if not e.catch_all]
    effects = [e for e in effects if e.id not in exclude]
    if not all(e.null_holds(p, rec) for e, p in model.entries() if e.colours_residual(p, model.base.noise_sd)):
        effects = [e for e in effects if not e.stochastic]  # no valid null for a process beside it
    kind = model.base.kind
    # the fits draw no random numbers: side by side when the caller's map_fn runs them so; then
    # the p-values, one candidate after the other on rng in the catalogue's order
    trials = []
    fitted = map_fn(partial(fit_trial, model, rec, r, folds, err_b), effects)
    for k, (eff, trial) in enumerate(zip(effects, fitted)):
        if progress is not None:
            progress(f"{eff.id} ({k + 1}/{len(effects)})")
        # a worker process returns a copy of the effect: the catalogue's own object is kept
        trials.append(with_p_value(replace(trial, effect=eff), model, rec, folds, rng, n_rep, fill_map))
    if not trials:
        return Naming((), None, (), ())
    reject, q = sig.benjamini_hochberg([t.p_value for t in trials], alpha)
    blocks = _block_ids(rec.n, n_blocks)
    reading_sd = float(model.residual_sd())  # a reading's sd: the noise through the model's quantizer, if any
    judged = [(t, judge(t, bool(rej), float(qv), model, rec, reading_sd, blocks, n_blocks))
              for t, rej, qv in zip(trials, reject, q)]
    judged.sort(key=lambda tc: -tc[1].score)
    candidates = tuple(c for _, c in judged)
    named = [t for t, c in judged if c.named]

    refits: dict[str, np.ndarray] = {}

    def joint_residual(t: Trial) -> np.ndarray:
        """The residual (mean removed) with ``t`` added and every parameter refitted — once a
        candidate: the nesting rule, Occam's check and :func:`refitted_choice` all weigh it."""
        if t.id not in refits:
            res = rec.y - calibrate(model.with_effect(t.id, t.params), rec).predict(rec)
            refits[t.id] = res - res.mean()
        return refits[t.id]

    def refitted_sse(t: Trial) -> float:
        return float(np.sum(joint_residual(t) ** 2))

    named = shape_ranked(named, model, rec, r)
    first_det = next((t for t in named if not t.effect.stochastic), None)
    # the process fitted beside the pick only if parsimonious weighs two nested shapes, and once
    colour = cache(partial(colour_beside, first_det, named, model, rec, alpha))
    det_pick = parsimonious(first_det, named, blocks, n_blocks, kind, reading_sd, refitted_sse, rec, colour)
    det_pick = refitted_choice(det_pick, named, model, rec, kind, reading_sd, joint_residual)
    if (det_pick is not None and det_pick.resid_full is not None and det_pick.effect.waveform
            and any(e.waveform and not e.stochastic for e, _ in model.entries())):
        # weighed against a process on what naming it leaves: the model refitted with it (a drift
        # fitted beside a two-node that had bent toward the ramp leaves the bend, which a walk
        # then explains better than the drift did)
        det_pick = replace(det_pick, resid_full=joint_residual(det_pick))
    named = ([det_pick] if det_pick is not None else []) + [t for t in named if t is not det_pick]

    # the deterministic term's significance against the process: Bonferroni over the catalogue
    # (a realisation of a walk is as trendy as 1 % of walks about 1 % of the time)
    det_alpha = alpha / max(len(trials), 1)

    def det_p_under(s: Trial, d: Trial) -> float:
        """p of ``d``'s held-out score when the model's noise includes stochastic ``s`` — drawn
        only as far as needed to tell whether it is below ``det_alpha`` (all it is used for),
        with enough replicates to tell it from that level on a few exceedances (the full run's
        floor 1/(n_rep + 1) is near a Bonferroni level over ~20 candidates otherwise: one
        replicate above the data decided); only a close call draws them all."""
        if d.cols is None or not np.isfinite(d.lin):
            return 1.0
        m_s = model.with_effect(s.id, s.params)

        def draw(m: int) -> np.ndarray:
            return m_s.simulate_noise_many(rec, rng, m, fill_map=fill_map)
        reps = max(n_rep, int(math.ceil(DET_EXCEEDANCES / det_alpha)))
        return sig.bootstrap_p_value(r, x_nuis, d.cols, folds, d.lin, n_rep=reps, rng=rng, draw=draw,
                                     below=det_alpha)

    def signature_of(t: Trial, beside: Trial | None) -> Evidence:
        """A catch-all's evidence (:mod:`.evidence`): the model with it (and with the process
        ``beside`` it, when the choice was of the two together), on the residual it leaves."""
        m_b = model if beside is None else model.with_effect(beside.id, beside.params)
        m_t = m_b.with_effect(t.id, t.params)
        # a waveform's residual is its own fit's (bias and scale factor refitted with it)
        res = t.resid_full if t.resid_full is not None else rec.y - m_t.predict(rec)
        return evidence(m_t, rec, len(m_t.effects) - 1, res, rng=rng, n_rep=n_rep, fill_map=fill_map)

    def tie(a: Trial, b: Trial) -> bool:
        """Is ``b``'s held-out score within one paired (block jackknife) standard error of ``a``'s?"""
        if a.err_c is None or b.err_c is None or a.err_b is None:
            return False
        diff, se = sig.score_difference(a.err_c, b.err_c, a.err_b, blocks, n_blocks)
        return bool(np.isfinite(se) and abs(diff) <= se)

    def pair_residual(a: Trial, b: Trial) -> np.ndarray | None:
        """The residual (mean removed) with ``a`` and ``b`` added and every parameter refitted."""
        try:
            res = rec.y - calibrate(model.with_effect(a.id, a.params).with_effect(b.id, b.params), rec).predict(rec)
        except ValueError:
            return None
        return res - res.mean()

    best, rejected = choose(named, model, rec, kind, det_p_under, det_alpha, signature_of, tie, pair_residual)
    set_aside = tuple(ev.describe() for ev in rejected)
    followed = tuple(sorted({c for ev in rejected for c in ev.columns}))
    if best is None or best.err_c is None or best.err_b is None:
        return Naming(candidates, None if best is None else _public(judged, best), (), (), set_aside=set_aside,
                      followed_columns=followed)
    comps, seps = [], []
    for t, c in judged:
        if t.id == best.id or c.score <= 0:
            continue
        if t.err_c is None:  # histogram-judged: no per-block errors to compare
            continue
        diff, se = sig.score_difference(best.err_c, t.err_c, best.err_b, blocks, n_blocks)
        if np.isfinite(se) and diff <= 2 * se:
            comps.append(t.id)
            seps.append(separating_experiment(best.id, t.id))
    return Naming(candidates, _public(judged, best), tuple(comps), tuple(seps), set_aside=set_aside,
                  followed_columns=followed)


def _public(judged: list[tuple[Trial, Candidate]], trial: Trial) -> Candidate:
    return next(c for t, c in judged if t.id == trial.id)  # trial may be a refitted copy
