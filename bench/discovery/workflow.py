"""Discovery: find where the model and the measurement disagree, name what is missing, show the
gap shrink — one model, one criterion, one search.

:func:`discover` on a :class:`~bench.discovery.data.Record` and a starting model:

1. **Observation model.** Isolated outliers are found on the starting model's residual at a
   stated per-record false-alarm rate (:mod:`.contamination`) and left out of the likelihood
   (the deterministic fits see them replaced by the running median); the report says how many.
2. **Criterion.** Every model is weighed by its exact likelihood (Kalman: white noise plus its
   random processes) with one penalty per effect derived from the false-name rate ``alpha``
   (:mod:`.criterion`).
3. **Search.** Add, drop and swap moves over the catalogue, a beam of the best models, until no
   move lowers the criterion (:mod:`.search`).
4. **Honest answers.** Look-alikes within the criterion's noise are reported with their weights
   and the experiment that separates them; what the final model leaves is tested on its Kalman
   innovations against the model's own noise and reported as unexplained structure, with where
   it is (:func:`.localize.unexplained_structure`); a parameter at the edge of the range the
   record allows is said so; a random process whose driving noise is not the model's (steps,
   bursts, a periodic drive: :mod:`.adequacy`) stays in the model for its spectrum but is not
   named (``Step.doubt``, :attr:`Discovery.named`).

Each effect of the final model is told as a :class:`Step` of the search's path (the gap before
and after it was added); effects added on the way and later dropped or swapped out are listed
as withdrawn, with the move that replaced them.

Pure: record and model in, a :class:`Discovery` out (no files; the CLI writes the model file).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.stats import chi2

from bench.discovery import stochastic as sto
from bench.discovery.adequacy import N_STATISTICS, Doubt, process_doubts
from bench.discovery.calibration import calibrate
from bench.discovery.candidates import Candidate, Naming
from bench.discovery.contamination import cleaned, find_outliers
from bench.discovery.criterion import n_free, penalty
from bench.discovery.data import Record
from bench.discovery.effects import CATALOGUE
from bench.discovery.effects_base import HistogramEffect, Params, at_edge
from bench.discovery.effects_noise import StochasticEffect, block_mean_deficit
from bench.discovery.effects_terms import MAX_LINES, SinusoidalInterference, line_names
from bench.discovery.findings import Localization
from bench.discovery.fitting import CandidateFitter
from bench.discovery.localize import localize, unexplained_structure
from bench.discovery.mapping import MapFn
from bench.discovery.model import Model
from bench.discovery.search import (
    NU_RANGE,
    Evaluator,
    Scored,
    SearchResult,
    Tie,
    applicable,
    search,
    student_fit,
    ties,
)
from bench.discovery.separating import separating_experiment
from bench.discovery.significance import Gap, block_folds, gap_metrics
from bench.discovery.whiten import seen_only, state_space


@dataclass(frozen=True)
class Step:
    """One named effect: what, its parameters ± std, p-value, the gap before and after, the
    naming (all candidates) and the localization that motivated it; residuals for the plots."""

    effect_id: str
    params: dict
    params_std: dict
    p_value: float
    gap_before: Gap
    gap_after: Gap
    rms_before: float
    rms_after: float
    naming: Naming
    localization: Localization
    residual_before: np.ndarray = field(repr=False)
    residual_after: np.ndarray = field(repr=False)
    #: the times of the residuals (the record the search saw: a long record's block means or window)
    t_s: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    #: how the search saw the record ("" the record itself; "block means"; "full-rate window")
    scale: str = ""
    #: the model's noise rms on that record after the step (the plots' white floor)
    noise_floor: float = math.nan
    #: a random process whose driving noise is not the model's (:mod:`.adequacy`): why it is not a
    #: name ("" — named)
    doubt: str = ""

    def to_dict(self) -> dict:
        return {"id": self.effect_id, "scale": self.scale or "record", "params": self.params,
                "params_std": self.params_std,
                "gap_before": self.gap_before.rms_ratio, "gap_after": self.gap_after.rms_ratio,
                "p_value": self.p_value, "rms_before": self.rms_before, "rms_after": self.rms_after,
                "gap_table": {"before": self.gap_before.to_dict(), "after": self.gap_after.to_dict()},
                "competitors": list(self.naming.competitors),
                "separating_experiments": list(self.naming.separating),
                "localization": self.localization.descriptions(), "doubt": self.doubt or None}


@dataclass(frozen=True)
class Discovery:
    """The loop's story: the calibrated starting model, each step, the final model and gaps.

    Gap figures in JSON: ``gap.initial`` / ``gap.final`` (and each effect's ``gap_before`` /
    ``gap_after``) are residual rms relative to the model's noise rms (1 = at the floor);
    ``gap.noise_floor`` the final model's noise rms in the sensor unit, ``rms_initial`` /
    ``rms_final`` the residual rms in that unit; the full before/after table (Allan, spectral,
    whiteness) of each step is under ``effects[i].gap_table``."""

    initial_model: Model
    final_model: Model
    steps: tuple[Step, ...]
    unexplained: tuple[str, ...]
    gap_initial: Gap
    gap_final: Gap
    rms_initial: float
    rms_final: float
    noise_floor: float
    final_localization: Localization
    final_naming: Naming
    residual_initial: np.ndarray = field(repr=False)
    residual_final: np.ndarray = field(repr=False)
    notes: tuple[str, ...] = ()
    withdrawn: tuple[str, ...] = ()
    set_aside: tuple[str, ...] = ()

    @property
    def named(self) -> tuple[str, ...]:
        """The effects named: the steps less the random processes doubted (:mod:`.adequacy`)."""
        return tuple(s.effect_id for s in self.steps if not s.doubt)

    def to_dict(self, model_file: str | None = None) -> dict:
        return {"effects": [s.to_dict() for s in self.steps], "named": list(self.named),
                "withdrawn": list(self.withdrawn),
                "set_aside": list(self.set_aside),
                "gap": {"initial": self.gap_initial.rms_ratio, "final": self.gap_final.rms_ratio,
                        "noise_floor": self.noise_floor, "rms_initial": self.rms_initial,
                        "rms_final": self.rms_final,
                        "initial_table": self.gap_initial.to_dict(), "final_table": self.gap_final.to_dict()},
                "unexplained": list(self.unexplained), "model_file": model_file, "notes": list(self.notes),
                "last_naming": self.final_naming.to_dict()}


def model_noise(model: Model, rec: Record, seed: int) -> np.ndarray:
    """One realisation of the model's own noise (white + its stochastic effects) on rec's grid."""
    return model.simulate_noise(rec, np.random.default_rng(seed))


def gap_of(model: Model, rec: Record, seed: int) -> tuple[Gap, float, float, np.ndarray]:
    """(gap table, residual rms, model-noise rms, residual) of ``model`` on ``rec``."""
    r = rec.y - model.predict(rec)
    # a random process's rms varies between realisations, and a histogram-judged effect's (a
    # quantizer's rounding error) depends on where the signal sits between levels: with any
    # effect that is not a waveform the floor comes from simulating the model on this stimulus
    # (several realisations), not from a formula
    if not all(e.waveform for e, _ in model.entries()):
        noises = [model_noise(model, rec, seed + k) for k in range(8)]
        floor = float(np.sqrt(np.mean([np.mean(x ** 2) for x in noises])))
        g = gap_metrics(r, model.residual_sd(), rec.rate_hz, noises[0], floor)
    else:
        floor = float(model.residual_sd())
        g = gap_metrics(r, floor, rec.rate_hz)
    return g, float(np.sqrt(np.mean(r ** 2))), floor, r


def input_order(model: Model, rec: Record) -> Model:
    """The model with its last effect, when it acts on the input beside other input-stage effects,
    moved to the place in their chain that fits ``rec`` best (each place calibrated; the least
    residual sum of squares, the appended place on a tie). Input transforms do not commute: a
    dead zone before a low-pass swallows the small input, after it the small *filtered* input —
    named in the other order, every zero crossing of a tumble left an 8-sigma spike in the
    residual, and the random process beside them was set aside for those "jumps"."""
    entries = model.effects
    if not entries or CATALOGUE[entries[-1][0]].stage != "input":
        return model
    places = [i for i, (eid, _) in enumerate(entries[:-1]) if CATALOGUE[eid].stage == "input"]
    if not places:
        return model
    best, best_sse = model, float(np.sum((rec.y - model.predict(rec)) ** 2))
    for i in places:
        moved = calibrate(Model(model.base, entries[:i] + entries[-1:] + entries[i:-1]), rec)
        sse = float(np.sum((rec.y - moved.predict(rec)) ** 2))
        if sse < best_sse:
            best, best_sse = moved, sse
    return best



def _structure(model: Model, rec: Record, r: np.ndarray) -> Localization:
    return localize(rec, r - r.mean(), model.residual_sd())


def params_std(model: Model, rec: Record, at: int) -> dict:
    """Standard errors of effect ``at``'s parameters in ``model``: a waveform's from the
    least-squares Jacobian at the fitted values (the rest of the model refitted with it), a random
    process's from its Whittle fit on the residual the rest leaves (the other processes beside
    it), a histogram-judged effect's from its lattice fit."""
    eff, p = model.entries()[at]
    kind = model.base.kind
    try:
        if isinstance(eff, StochasticEffect):
            r = rec.y - model.predict(rec)
            others = tuple(ep for ep in model.stochastic_effects() if ep[0].id != eff.id)
            # with its bias correction: a random walk's std is its parametric bootstrap's spread
            fit = sto.fit_stochastic(r - r.mean(), rec.dt_s, eff, known=others, bootstrap=True)
            return {k: float(fit.params_std[k]) for k in p}
        if isinstance(eff, HistogramEffect):
            return dict(eff.fit_histogram(rec.y, float(model.base.noise_sd), block_folds(rec.n), kind).params_std)
        rest = Model(model.base, model.effects[:at] + model.effects[at + 1:])
        f = CandidateFitter(rest, rec, eff, noise_is_floor=False, template=p, at=at)
        return dict(f.fit([f.pack(p, model.base.bias, model.base.scale_factor)], max_nfev=1).params_std)
    except (ValueError, np.linalg.LinAlgError, FloatingPointError):
        return dict.fromkeys(p, math.nan)


#: lines whose frequencies are integer multiples of the lowest line's within this many standard
#: errors (of their difference) are said to be harmonics: a pair of unrelated lines lands there by
#: chance with probability ≈ 0.3 % per pair at the stated errors (two-sided normal, 3σ)
HARMONIC_Z = 3.0


def harmonic_notes(model: Model, recs: dict[str, Record]) -> list[str]:
    """A note for each named ``sinusoidal_interference`` whose higher lines sit at integer
    multiples of its lowest one (within :data:`HARMONIC_Z` standard errors): the lines may be one
    periodic source that is not a sine (a triangle, square or clipped wave) rather than separate
    pick-ups. ``recs``: each effect's record (the one whose search set its values)."""
    notes = []
    for at, (e, p) in enumerate(model.entries()):
        if not isinstance(e, SinusoidalInterference) or e.count(p) < 2:
            continue
        std = params_std(model, recs[e.id], at)
        freqs = sorted((float(p[line_names(k)[1]]), float(std.get(line_names(k)[1], math.nan)))
                       for k in range(1, MAX_LINES + 1) if p.get(line_names(k)[0], 0.0) != 0.0)
        (f1, s1), multiples = freqs[0], []
        for f, s in freqs[1:]:
            m = round(f / f1)
            if m >= 2 and abs(f - m * f1) <= HARMONIC_Z * math.hypot(s, m * s1):
                multiples.append(f"{f:.4g} Hz ({m}×)")
        if multiples:
            notes.append(f"{e.id}: the line{'s' if len(multiples) > 1 else ''} at {', '.join(multiples)} "
                         f"{'are' if len(multiples) > 1 else 'is'} at a multiple of the one at {f1:.4g} Hz within "
                         f"{HARMONIC_Z:g} standard errors: they may be one periodic source that is not a sine "
                         f"(a triangle, square or clipped wave at {f1:.4g} Hz) rather than separate pick-ups")
    return notes


def _gain_p(parent: Scored, child: Scored, eid: str, rec: Record) -> float:
    """The χ² tail probability of the deviance the effect ``eid`` saved (unadjusted)."""
    e = CATALOGUE[eid]
    p = dict(child.model.effects)[eid]
    return float(chi2.sf(max(parent.m2ll - child.m2ll, 0.0), max(n_free(e, p, rec, child.model.base.kind), 1)))


def _naming(parent: Scored, chosen: str | None, result: SearchResult, ties_of: dict[str, Tie], rec: Record,
            alpha: float) -> Naming:
    """What the add moves from ``parent`` found: each candidate with the deviance it saved
    (``score``), its χ² p-value, that value times the criterion's multiplicity (``q_value``: ≤
    ``alpha`` is what naming it takes), and which one the path took."""
    kind = parent.model.base.kind
    rows = []
    for key, s in result.scored.items():
        extra = key - parent.key
        if len(extra) != 1 or not parent.key <= key:
            continue
        eid = next(iter(extra))
        e = CATALOGUE[eid]
        p = dict(s.model.effects)[eid]
        gain = parent.m2ll - s.m2ll
        pen = penalty(e, p, rec, kind, result.n_candidates, alpha)
        pv = _gain_p(parent, s, eid, rec)
        q = min(1.0, pv * result.n_candidates * e.search_cells(p, rec))
        rows.append(Candidate(eid, e.stochastic, p, {}, float(gain), float(pen), pv, q, gain > pen,
                              math.nan, eid == chosen))
    rows.sort(key=lambda c: -(c.score - c.score_se))
    best = next((c for c in rows if c.named), None)
    tie = ties_of.get(chosen or "")
    competitors = tuple(a for a, _ in tie.alternatives if a) if tie else ()
    return Naming(tuple(rows), best, competitors,
                  tuple(separating_experiment(chosen, a) for a in competitors) if chosen else (),
                  null=("exact likelihood ratio (Kalman) against the model without the candidate; named when the "
                        "deviance saved exceeds its penalty χ²_k.isf(α / (C·M))"))


#: Searches at most, each with the outliers its predecessor's final residual showed set aside.
OUTLIER_PASSES = 3

#: The longest record the likelihood search runs on: a longer one is searched twice — as block
#: means (this many; its slow effects) and on a full-rate window of this many samples from its
#: middle (its fast effects). A compute budget, not a threshold: each model weighed costs a few
#: hundred Kalman passes of O(n), and the search weighs tens of models; at 2¹³ points a 3-h
#: record at 100 Hz (1.08 M samples) is weighed in under a minute on 2 cores.
SEARCH_POINTS = 8192


@dataclass(frozen=True)
class _Stage:
    """One search: the record it weighed models on, its evaluator, its result, its false-name
    rate and how it saw the record (for the report)."""

    rec: Record
    ev: Evaluator
    result: SearchResult
    alpha: float
    scale: str = ""


def _search(rec: Record, model: Model, *, alpha: float, max_effects: int, only: tuple[str, ...] | None,
            seen: np.ndarray | None, fixed: frozenset[str], say: Callable[[str], None], map_fn: MapFn,
            scale: str = "", kept: frozenset[str] = frozenset()) -> _Stage:
    kind = model.base.kind
    cands = [e.id for e in applicable(model, rec) if only is None or e.id in only]
    ev = Evaluator(rec, kind, n_candidates=len(cands) or 1, alpha=alpha, seen=seen)
    ev.given = frozenset(model.effect_ids)
    ev.fixed = fixed
    ev.kept = kept
    start = ev.score(model)
    if start is None:
        raise ValueError("the starting model cannot be calibrated on this record (bias or scale factor at the edge "
                         "of the kind's range): wrong unit, sensor kind or input column?")
    say(f"{scale + ': ' if scale else ''}{len(cands)} candidates; criterion of the starting model "
        f"{start.criterion:.2f}")
    result = search(ev, start, max_effects=max_effects, only=tuple(cands), say=say, map_fn=map_fn)
    return _Stage(rec, ev, result, alpha, scale)


def _told(stage: _Stage, told: Model, decided: dict[str, _Stage], seed: int,
          say: Callable[[str], None]) -> tuple[list[Step], list[str], dict[str, Tie]]:
    """The stage's path told as steps (each effect its best model holds, when it came in, with
    its values in ``told``, the final model, and their standard errors from the search that set
    them, ``decided``: the gap before and after on the stage's record), the effects withdrawn on
    the way, and the ties."""
    result, work, alpha = stage.result, stage.rec, stage.alpha
    values = dict(told.effects)
    ties_of = {t.effect_id: t for t in ties(result, alpha)}
    path = result.best.path()
    steps: list[Step] = []
    withdrawn: list[str] = []
    gap_cur, rms_cur, _, r_cur = gap_of(path[0].model, work, seed)
    for prev, cur in zip(path, path[1:]):
        g_prev, rms_prev, r_prev = gap_cur, rms_cur, r_cur
        gap_cur, rms_cur, floor, r_cur = gap_of(cur.model, work, seed)
        gone = [e for e in prev.model.effect_ids if e not in cur.model.effect_ids]
        new = [e for e in cur.model.effect_ids if e not in prev.model.effect_ids]
        for g in gone:
            withdrawn.append(f"{g}: {cur.move} lowered the criterion by {prev.criterion - cur.criterion:.1f}")
        for eid in new:
            if eid not in values:  # not in the final model (a later search dropped it)
                continue
            naming = _naming(prev, eid, result, ties_of, work, alpha)
            by = decided[eid].result.best.model
            std = params_std(by, decided[eid].rec, by.effect_ids.index(eid))
            steps.append(Step(eid, dict(values[eid]), std,
                              _gain_p(prev, cur, eid, work), g_prev, gap_cur, rms_prev, rms_cur, naming,
                              _structure(prev.model, work, r_prev), r_prev, r_cur, work.t_s, stage.scale, floor))
            say(f"named {eid}{' (' + stage.scale + ')' if stage.scale else ''}, "
                f"rms {_fmt(rms_prev)} → {_fmt(rms_cur)}")
    return steps, withdrawn, ties_of


def discover(rec: Record, model: Model, *, max_effects: int = 4, alpha: float = 0.05, seed: int = 0,
             only: tuple[str, ...] | None = None, progress: Callable[[str], None] | None = None,
             map_fn: MapFn = map) -> Discovery:
    """Discover on ``rec`` from ``model`` (module docstring). ``max_effects``: most effects the
    final model may add to the starting one; ``alpha``: the false-name rate; ``seed``: the
    model-noise realisations of the gap table; ``only``: the catalogue ids the search may add;
    ``progress``: called with a short message as the search goes; ``map_fn``: how one model's
    add moves are mapped (an executor's ``map``: the same answer).

    A record longer than twice :data:`SEARCH_POINTS` is searched on two scales, each at half
    the false-name rate (their union at ``alpha``): its block means (the slow effects, the
    per-reading ones left out) and then a full-rate window from its middle with the slow model
    held as it is (the fast effects: a quantizer, a line, the sensor's own output filter as a
    short Gauss–Markov)."""
    if isinstance(max_effects, bool) or not isinstance(max_effects, int) or not 0 <= max_effects <= len(CATALOGUE):
        raise ValueError(f"max_effects = {max_effects!r}; allowed: an integer in [0, {len(CATALOGUE)}]")
    if not 0 < alpha < 1:
        raise ValueError(f"alpha = {alpha!r}; allowed: (0, 1)")
    if only is not None:
        unknown = sorted(set(only) - set(CATALOGUE))
        if unknown:
            raise ValueError(f"only = {unknown}; allowed: catalogue ids {list(CATALOGUE)}")
    say = progress or (lambda _msg: None)
    kind = model.base.kind
    notes: list[str] = []
    skipped = [eid for eid, e in CATALOGUE.items() if e.needs_uniform and kind in e.kinds]
    if skipped and not rec.is_uniform():
        notes.append(f"{', '.join(skipped)} not tried: the sample intervals vary by more than 0.1 % of the median "
                     "(a sampled filter needs a uniform record; resample to try them)")
    first = calibrate(model, rec)
    prediction = first.predict(rec)
    contamination = find_outliers(rec.y - prediction)
    # the outliers are sought on the residual of the model searched with them set aside, until
    # that model's residual shows the same ones: a strong term not yet in the starting model
    # (a line) hides spikes in the scale of its own second difference
    for k in range(OUTLIER_PASSES):
        if contamination.count:
            say(contamination.describe())
        work = cleaned(rec, contamination, prediction)
        seen = ~contamination.outlier
        stages, final, scale_notes = _scales(work, model, seen, alpha=alpha, max_effects=max_effects, only=only,
                                             say=say, map_fn=map_fn)
        prediction = final.predict(rec)
        again = find_outliers(rec.y - prediction)
        if np.array_equal(again.outlier, contamination.outlier) or k == OUTLIER_PASSES - 1:
            break
        contamination = again
        say("the final model's residual shows other outliers: searched again with them set aside")
    if contamination.count:
        notes.append(contamination.describe())
    notes += scale_notes
    if len(stages) == 1:
        start_model = stages[0].result.start.model
    else:
        start_model = first
        coarse, fine = stages
        notes.append(f"{work.n} samples: searched as {coarse.rec.n} block means of {work.n // coarse.rec.n} samples "
                     f"(slow effects) and on the full-rate window {fine.rec.t_s[0]:.6g}–{fine.rec.t_s[-1]:.6g} s "
                     f"(fast effects: quantization, lines, short correlation), each at half the false-name rate; "
                     "a fast effect that comes and goes outside that window is not seen")
    # each effect's values come from the last search that moved them (a long record's window
    # refits what the block means could not resolve)
    decided = {eid: st for st in stages for eid in st.result.best.model.effect_ids if eid not in st.ev.fixed}
    steps: list[Step] = []
    withdrawn: list[str] = []
    ties_all: dict[str, Tie] = {}
    for st in stages:
        s_steps, s_withdrawn, s_ties = _told(st, final, decided, seed, say)
        steps += s_steps
        withdrawn += s_withdrawn
        ties_all.update(s_ties)
    for t in (t for t in ties_all.values() if t.effect_id in final.effect_ids):  # of what is named
        alts = ", ".join(f"{a or 'nothing'} (weight {w:.2f})" for a, w in t.alternatives)
        notes.append(f"{t.effect_id} (weight {t.weight:.2f}) is within the criterion's noise of {alts}"
                     + "".join(f"; {separating_experiment(t.effect_id, a)}" for a, _ in t.alternatives if a))
    for e, p in final.entries():  # each judged on the record whose search set its values
        for name in at_edge(e, p, decided[e.id].rec, kind):
            notes.append(f"{e.id}.{name} = {p[name]:.4g} is at the edge of the range the record allows: the "
                         "record cannot bound it (a longer or faster record would)")
    notes += harmonic_notes(final, {e.id: decided[e.id].rec for e, _ in final.entries()})
    last = stages[-1]
    final_naming = _naming(last.result.best, None, last.result, ties_all, last.rec, last.alpha)
    nu = heavy_tails(last.result.best.model, last.rec, last.ev.seen, alpha)
    if math.isfinite(nu):
        notes.append(f"the observation noise is heavy-tailed (Student-t, ν = {nu:.3g}): the criterion weighs the "
                     "innovations by that density, and single samples are judged on its tail")
    g0, rms0, _, r0 = gap_of(start_model, work, seed)
    g1, rms1, floor, r1 = gap_of(final, work, seed)
    doubts = _doubts(stages, [s.effect_id for s in steps], decided, alpha, seed)
    if doubts:
        say(f"doubted: {', '.join(doubts)} (their driving noise is not the model's)")
        steps = [replace(s, doubt=doubts[s.effect_id].describe()) if s.effect_id in doubts else s for s in steps]
    unexplained = tuple(d.describe() for d in doubts.values()) + unexplained_structure(work, r1, final, alpha=alpha,
                                                                                         nu=nu)
    if unexplained:
        say(f"unexplained structure: {len(unexplained)} finding(s)")
    say(f"done: {sum(st.result.evaluations for st in stages)} models weighed in "
        f"{sum(st.result.rounds for st in stages)} rounds")
    return Discovery(start_model, final, tuple(steps), unexplained, g0, g1, rms0, rms1, floor,
                     _structure(final, work, r1), final_naming, r0, r1, tuple(notes), tuple(withdrawn), ())


def _scales(work: Record, model: Model, seen: np.ndarray, *, alpha: float, max_effects: int,
            only: tuple[str, ...] | None, say: Callable[[str], None],
            map_fn: MapFn) -> tuple[list[_Stage], Model, list[str]]:
    """The searches of :func:`discover`, the model they make and what it says of the window's
    additions the whole record withdrew (:func:`_confirmed`): on a record of up to twice
    :data:`SEARCH_POINTS` one search; on a longer one two — the block means' model, then the
    window's additions after it, with the window's white level (per sample)."""
    if work.n <= 2 * SEARCH_POINTS:
        stage = _search(work, model, alpha=alpha, max_effects=max_effects, only=only, seen=seen,
                        fixed=frozenset(), say=say, map_fn=map_fn)
        return [stage], stage.result.best.model, []
    m = -(-work.n // SEARCH_POINTS)
    # the per-reading effects are not tried on the means, which do not keep them
    on_means = tuple(eid for eid in (CATALOGUE if only is None else only) if not CATALOGUE[eid].per_sample)
    coarse = _search(work.block_means(m), model, alpha=alpha / 2, max_effects=max_effects, only=on_means, seen=None,
                     fixed=frozenset(), say=say, map_fn=map_fn, scale="block means")
    slow = coarse.result.best.model
    a = (work.n - SEARCH_POINTS) // 2
    window = work.slice(slice(a, a + SEARCH_POINTS))
    # the readings themselves (a quantizer's lattice is in them), the slow model held as it is —
    # but for what the means cannot hold, which the window refits: an effect at the edge of the
    # range the means allow, and, where the means' white level is below what their processes need
    # beside them (``block_mean_deficit``: a process bent to stand in for the lag-0 shortfall — a
    # Gauss–Markov of a few blocks' τ, the sensor's own output filter seen from afar), every
    # process the window can resolve
    kind = model.base.kind
    # terms timed from a record's first sample (a line's phase) move from the means' first mean
    # to the window's first sample, and from there to the record's (``Effect.time_shifted``)
    shift = float(coarse.rec.t_s[0] - window.t_s[0])
    slow = _shifted(slow, shift)
    slow, folded = _unfolded(slow, window, coarse.rec.rate_hz, work.rate_hz, shift)
    released = folded | {e.id for e, p in slow.entries() if at_edge(e, p, coarse.rec, kind)}
    procs = slow.stochastic_effects()
    need = sum(block_mean_deficit(e.state_space(p, work.dt_s, work.n), m) for e, p in procs)
    if need > float(slow.base.noise_sd) ** 2:
        released |= {e.id for e, p in procs if e.identifiable(p, window)}
    held = frozenset(slow.effect_ids) - released
    # what the window refits it may not drop: whether a slow effect is there is the whole record's
    # to say (the window's additions and refits are confirmed on it below)
    fast = _search(window, slow, alpha=alpha / 2, max_effects=max_effects, only=only, seen=seen[a:a + SEARCH_POINTS],
                   fixed=held, say=say, map_fn=map_fn, scale="full-rate window",
                   kept=frozenset(released))
    got = fast.result.best.model
    # the whole record's bias and scale factor, the window's white level (per sample), and the
    # window's terms refined on the whole record (a line's frequency to the record's resolution)
    on_record = _shifted(got, float(window.t_s[0] - work.t_s[0]))
    kept = tuple((eid, p) for eid, p in on_record.effects if eid in held)
    added = tuple((eid, p) for eid, p in on_record.effects if eid not in held)
    final = Model(slow.base, kept + added).with_base(noise_sd=float(got.base.noise_sd))
    if any(CATALOGUE[eid].waveform for eid, _ in added):
        final = calibrate(final, work, noise=False, frozen=held)
    # the white level at its exact likelihood on the whole record, the processes as found (the
    # window's estimate has a window's spread: 0.8 % on 8192 samples, beyond the whole record's
    # Allan interval at its shortest τ)
    r = seen_only(work.y - final.predict(work), seen)
    white = sto.exact_white(r, work.dt_s, final.stochastic_effects(), float(final.residual_sd()))
    final = final.with_noise_floor(white)
    told: list[str] = []

    def tell(message: str) -> None:
        say(message)
        told.append(message)

    final = _confirmed(final, [eid for eid, _ in added if CATALOGUE[eid].waveform], work, seen,
                       alpha=alpha / 2, n_candidates=fast.ev.n_candidates, say=tell)
    return [coarse, fast], final, told


def _confirmed(final: Model, added: list[str], work: Record, seen: np.ndarray, *, alpha: float,
               n_candidates: int, say: Callable[[str], None]) -> Model:
    """``final`` without each waveform term the window added that the whole record does not
    want: the window names a term at its share of the false-name rate, but the model is the
    whole record's, and a term that stood in on the window for the held model's misfit there
    (a drift of 7e-10 ± 1e-6 /s after its refinement on the record) is then weighed on the record
    under the same criterion, every value as found, and withdrawn when the record without it
    scores no worse. A confirmation can only take names away."""
    if not added:
        return final
    judge = Evaluator(work, final.base.kind, n_candidates=n_candidates, alpha=alpha, seen=seen)
    judge.given = judge.fixed = frozenset(final.effect_ids)
    full = judge.score(final)
    for eid in added:
        kept = tuple((e, p) for e, p in final.effects if e != eid)
        without = judge.score(Model(final.base, kept))
        if full is not None and without is not None and without.criterion <= full.criterion:
            say(f"{eid}: found on the window, withdrawn — the whole record scores no worse without it "
                f"(criterion {without.criterion:.2f} vs {full.criterion:.2f})")
            final, full = Model(final.base, kept), without
    return final


def _shifted(model: Model, shift_s: float) -> Model:
    """``model`` with every term moved to a record starting ``shift_s`` earlier (negative: later)."""
    return Model(model.base, tuple((eid, CATALOGUE[eid].time_shifted(p, shift_s)) for eid, p in model.effects))


def _unfolded(slow: Model, window: Record, block_rate_hz: float, rate_hz: float,
              shift_s: float) -> tuple[Model, set[str]]:
    """``slow`` (its terms referenced to the ``window``'s first sample, the means' first time
    ``shift_s`` after it) with each term the block means may have seen folded
    (``Effect.aliases``: a line above their Nyquist frequency) at the alias that fits the
    full-rate ``window`` best (each refitted there, the rest held; least squares), and the ids
    of those terms. An effect of
    several lines (``Effect.components``) is unfolded one line at a time, each with the lines
    unfolded before it and without those after it (which the window may hold at another
    frequency)."""
    folded: set[str] = set()
    for i, e in enumerate(CATALOGUE[eid] for eid in slow.effect_ids):
        p = slow.effects[i][1]
        parts = e.components(p)
        if all(len(e.aliases(part, block_rate_hz, rate_hz, shift_s)) < 2 for part in parts):
            continue
        others = frozenset(slow.effect_ids) - {e.id}
        done: list[Params] = []
        best = slow
        for part in parts:  # the lines unfolded so far and this one's alias, refitted together
            best, best_sse = slow, math.inf
            for c in e.aliases(part, block_rate_hz, rate_hz, shift_s):
                try:
                    fit = calibrate(slow.with_params(i, e.joined(p, [*done, c])), window, noise=False, frozen=others)
                except ValueError:
                    continue
                sse = float(np.sum((window.y - fit.predict(window)) ** 2))
                if sse < best_sse:
                    best, best_sse = slow.with_params(i, dict(fit.effects[i][1])), sse
            done = e.components(best.effects[i][1]) if math.isfinite(best_sse) else [*done, part]
        slow = best
        folded.add(e.id)
    return slow, folded


def _doubts(stages: list[_Stage], step_ids: list[str], decided: dict[str, _Stage], alpha: float,
            seed: int) -> dict[str, Doubt]:
    """The named random processes whose driving noise departs from the model's
    (:func:`.adequacy.process_doubts`), each judged with the model and on the record of the
    search that set it; all of them together at ``alpha``."""
    tested = [i for i in step_ids if isinstance(CATALOGUE[i], StochasticEffect)]
    if not tested:
        return {}
    level = alpha / (N_STATISTICS * len(tested))
    out: dict[str, Doubt] = {}
    for st in stages:
        mine = tuple(i for i in tested if decided[i] is st)
        if mine:
            model = st.result.best.model
            seen = st.ev.seen_of(model)
            out.update(process_doubts(model, st.rec, seen, mine, level=level,
                                      nu=heavy_tails(model, st.rec, seen, alpha), seed=seed))
    return out


def heavy_tails(model: Model, rec: Record, seen: np.ndarray | None, alpha: float) -> float:
    """The Student-t degrees of freedom of ``model``'s innovations on ``rec`` when the t density
    fits them better than the Gaussian beyond the χ²₁ quantile at ``alpha`` (a likelihood-ratio
    test of the tails, one parameter), else ``inf``."""
    r = rec.y - model.predict(rec)
    procs = model.stochastic_effects()
    x = seen_only(r, seen)
    if procs:
        e, v = state_space(rec.rate_hz, x.size, procs).filter(x, float(model.base.noise_sd) ** 2)
    else:
        e, v = x, np.full(x.size, float(np.nanvar(x)))
    keep = ~np.isnan(e) & (v > 0)
    z = e[keep] / np.sqrt(v[keep])
    m2ll_t, nu, _ = student_fit(z, v[keep])
    m2ll_g = float(np.sum(np.log(v[keep]))) + z.size * (1 + math.log(2 * math.pi * float(np.mean(z * z))))
    return nu if m2ll_g - m2ll_t > chi2.isf(alpha, 1) and nu < NU_RANGE[1] else math.inf


def _fmt(v: float) -> str:
    return f"{v:.4g}"
