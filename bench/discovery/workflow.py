"""The discrepancy workflow (issue 7, section 2): calibrate, localize, name, add, repeat.

:func:`discover` runs, on a :class:`~bench.discovery.data.Record` and a starting model:

a. :func:`bench.discovery.calibration.calibrate` — bounded least squares of all the model's
   parameters (bias, scale factor when the input is logged and varies, and every parameter of
   the waveform effects already in it, from their current values); the white-noise sd from the
   residual's high-frequency floor;
b. :func:`bench.discovery.localize.localize` of the residual;
c. :func:`bench.discovery.naming.name_effect` over the catalogue;
d. add the named effect with its fitted parameters, re-calibrate (after a waveform, the model's
   random processes are re-estimated on the residual it leaves: :func:`refit_processes`), and
   measure the gap before and after (:class:`bench.discovery.significance.Gap`: rms / model-noise
   rms, Allan distance, spectral distance, Ljung–Box whiteness p) against a simulation of the
   model's own noise;
e. repeat until nothing is named (or ``max_effects``); then an effect whose fit is a search of
   the residual (a jump's change points) is searched again beside all the names (:func:`reseated`),
   a waveform whose look-alike fits far better in its place is swapped for it (:func:`relooked`:
   a delay named in a tie with a low-pass, before the clip beside them was known; the look-alike
   is named on its own evidence, the effect it replaced withdrawn), jumps and the processes
   beside them give way to one random process that explains them as well (:func:`unjumped`:
   jumps named while the walk's signature failed for a term still missing), and a shape named beside one
   it nests is merged into it when the nesting shape alone (with a drift for a node beyond the
   record) holds both with fewer parameters (:func:`renested`: the nested one is withdrawn, what
   the merge brings is named on its own evidence);
f. audit: every named effect's own signature on the final model (:mod:`bench.discovery.evidence`:
   a waveform's relaxed shape, a random process's innovations — and its significance at its
   last re-estimate, :func:`faded_processes`); one that does not hold is withdrawn (the worst
   first, re-calibrating each time) — a wrong name is worse than none.
g. re-choose: when the audit withdrew a name, name again (c–e) without the withdrawn effects,
   from the audited model — the next-best candidate for the structure it stood for (the nesting
   two-node warm-up after a one-exponential warm-up whose shape failed, a random process a
   withdrawn deterministic fit had taken, a look-alike) gets its turn — and audit again (f). The
   audit withdraws one effect a round (the worst) while a re-choice can follow, so the others
   are judged beside what replaced it; the last round, and a re-choice that named nothing, audit
   to the end. The withdrawn effects sit out a re-choice until it names something; beside that
   new name they may be named again (K2 withdrawn when named for an asymmetry, named again beside
   the asymmetry when both are there; a note says so). At most :data:`MAX_ROUNDS` rounds; a round
   whose audit withdraws nothing ends the loop.
   Structure left that no candidate explains is reported as "unexplained structure" with where
   it is
   (:func:`bench.discovery.localize.unexplained_structure`: the residual, or its Kalman
   innovations when the model has stochastic effects, against the model's own noise,
   family-wise at ``alpha``); nothing significant names nothing.

Pure: record and model in, a :class:`Discovery` out (no files; the CLI writes the model file).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from typing import NamedTuple

import numpy as np
from scipy import optimize
from scipy.stats import chi2 as chi2_dist

from bench.discovery import stochastic as sto
from bench.discovery.calibration import calibrate
from bench.discovery.candidates import Naming
from bench.discovery.data import Record
from bench.discovery.effects import CATALOGUE
from bench.discovery.effects_base import MIN_SNR, Effect, Params
from bench.discovery.effects_noise import StochasticEffect
from bench.discovery.evidence import Evidence, beyond_leftover, evidence
from bench.discovery.findings import Localization
from bench.discovery.fitting import CandidateFitter
from bench.discovery.localize import localize, unexplained_structure
from bench.discovery.mapping import MapFn
from bench.discovery.model import Model
from bench.discovery.naming import name_effect
from bench.discovery.significance import Gap, gap_metrics
from bench.discovery.whiten import exact_nll, seen_only


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

    def to_dict(self) -> dict:
        return {"id": self.effect_id, "params": self.params, "params_std": self.params_std,
                "gap_before": self.gap_before.rms_ratio, "gap_after": self.gap_after.rms_ratio,
                "p_value": self.p_value, "rms_before": self.rms_before, "rms_after": self.rms_after,
                "gap_table": {"before": self.gap_before.to_dict(), "after": self.gap_after.to_dict()},
                "competitors": list(self.naming.competitors),
                "separating_experiments": list(self.naming.separating),
                "localization": self.localization.descriptions()}


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

    def to_dict(self, model_file: str | None = None) -> dict:
        return {"effects": [s.to_dict() for s in self.steps], "withdrawn": list(self.withdrawn),
                "set_aside": list(self.set_aside),
                "gap": {"initial": self.gap_initial.rms_ratio, "final": self.gap_final.rms_ratio,
                        "noise_floor": self.noise_floor, "rms_initial": self.rms_initial,
                        "rms_final": self.rms_final,
                        "initial_table": self.gap_initial.to_dict(), "final_table": self.gap_final.to_dict()},
                "unexplained": list(self.unexplained), "model_file": model_file, "notes": list(self.notes),
                "last_naming": self.final_naming.to_dict()}


#: Rounds of naming then auditing: after a round whose audit withdrew a name, the loop names again
#: without the withdrawn effects (a re-choice) and audits again (one withdrawal a round but the
#: last: five rounds where three held a whole audit each).
MAX_ROUNDS = 5


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


def _fitted_in_place(model: Model, i: int, effect: Effect, rec: Record,
                     starts_of: Callable[..., list[Params]]) -> Model | None:
    """``model`` with ``effect`` fitted in the place of its ``i``-th effect — from
    ``starts_of(residual, rows=…)`` on what the others leave (the rows where the output follows
    its input) — and calibrated; None without a start or when the calibration fails."""
    without = Model(model.base, model.effects[:i] + model.effects[i + 1:])
    seen = without.follows_input(rec)
    starts = starts_of(rec.y - without.predict(rec), rows=None if seen.all() else seen)
    if not starts:
        return None
    f = CandidateFitter(without, rec, effect, template=starts[0], at=i)
    fit = f.fit([f.pack(s, without.base.bias, without.base.scale_factor) for s in starts], with_std=False)
    try:
        return calibrate(f.model_at(fit.x), rec)
    except ValueError:
        return None


def reseated(model: Model, rec: Record) -> Model:
    """The model with each effect whose fit is a search of the residual
    (``Effect.searched_starts``: a jump's change points) searched again on what the others leave
    now, refitted there at its place and the whole model calibrated — kept when the readings'
    sum of squares falls (the same parameters in use, or fewer). ``calibrate`` moves a jump's time
    within its sample only: three jumps found beside a warm-up named for a two-node transient
    kept the first at 840 s (the step is at 876 s) once the two-node replaced the warm-up, and
    the 36 s between left the level of a sixteenth of the record 16× the floor off — the audit
    withdrew the jumps, then everything else. :func:`discover` asks it once the names of a round
    are in, before the audit: searched again after every step, two spare jump slots named
    first moved onto a temperature rate's structure (143 σ² better) before the temperature
    rate was named, and a walk took what was left."""
    kind = model.base.kind
    sse = float(np.sum((rec.y - model.predict(rec)) ** 2))
    for i, (e, p) in enumerate(model.entries()):
        if not e.waveform or e.stochastic:
            continue
        moved = _fitted_in_place(model, i, e, rec, partial(e.searched_starts, p, rec, kind=kind))
        if moved is None:
            continue
        sse_moved = float(np.sum((rec.y - moved.predict(rec)) ** 2))
        if sse_moved < sse:
            model, sse = moved, sse_moved
    return model


@dataclass(frozen=True)
class Merged:
    """A named effect replaced once a round's names are in — a nested pair merged into the
    nesting shape (:func:`renested`), a nesting shape by the one it nests (:func:`unnested`), an
    effect by its look-alike (:func:`relooked`): the model with ``into`` standing for what
    ``dropped`` held (and the effects it brings, ``added``, each to be named on its own
    evidence), and why."""

    model: Model
    into: str
    dropped: str
    added: tuple[str, ...]
    why: str


def relooked(model: Model, rec: Record, exclude: frozenset[str] = frozenset()) -> Merged | None:
    """A named waveform effect whose look-alike (``Catalogue.look_alikes``: a time delay and a
    low-pass, K2 and a scale-factor asymmetry) fits far better in its place once the names of a
    round are in: the look-alike fitted to what the others leave, in the effect's place, the
    model calibrated — kept when the readings' sum of squares falls by more than the size gate
    (``n·ln(SSE/SSE') > MIN_SNR² + ln(n)·Δk``, Δk its extra parameters), the best such; None
    when none does. Look-alikes tie where the first is named (a delay of 0.189 s and a 0.84-Hz
    low-pass scored 0.6916 and 0.6914 on an accelerometer tumble); beside a clip named after it
    the delay left 7.6× the floor, which a sinusoid and K2 were then named for. ``exclude``:
    look-alikes not tried (the workflow's withdrawn effects: a temperature rate and a hysteresis
    swapped for each other in turn while a walk beside them was missing)."""
    kind = model.base.kind
    n = rec.n
    sse = float(np.sum((rec.y - model.predict(rec)) ** 2))
    ids = set(model.effect_ids)
    best: tuple[float, Merged] | None = None
    for i, (e, p) in enumerate(model.entries()):
        if not e.waveform or e.stochastic:
            continue
        for lid in CATALOGUE.look_alikes(e.id):
            look = CATALOGUE[lid]
            if (lid in ids or lid in exclude or look.stochastic or not look.waveform or kind not in look.kinds
                    or (look.needs_uniform and not rec.is_uniform()) or not look.applies_to(rec)):
                continue
            alt = _fitted_in_place(model, i, look, rec, partial(look.fit_starts, rec, kind=kind))
            if alt is None or not look.identifiable(alt.effects[i][1], rec):
                continue
            sse_alt = float(np.sum((rec.y - alt.predict(rec)) ** 2))
            dk = len(look.free_params(alt.effects[i][1], kind, rec)) - len(e.free_params(p, kind, rec))
            gain = n * math.log(sse / sse_alt) - math.log(n) * dk if sse_alt > 0 else math.inf
            if gain > MIN_SNR ** 2 and (best is None or gain > best[0]):
                why = (f"its look-alike {lid} fits far better in its place once the others are named "
                       f"(n·ln(SSE ratio) {gain:.3g} beyond its parameters, gate {MIN_SNR ** 2:.3g})")
                best = (gain, Merged(alt, lid, e.id, (lid,), why))
    return None if best is None else best[1]


def _exact_m2ll(model: Model, rec: Record, seen: np.ndarray | None) -> float:
    """−2 ln L of ``model``'s residual (the samples ``seen``; None: all) with the white level and
    each random process's parameters at their exact maximum likelihood (in turn, the others at
    their values; without a process the white level's), the constant left out."""
    x = seen_only(rec.y - model.predict(rec), seen)  # the mean over the seen samples removed
    procs = list(model.stochastic_effects())
    if not procs:
        return 2 * exact_nll(x, rec.rate_hz, float(np.nanvar(x)) or 1.0, [])
    white = float(model.residual_sd()) or float(np.nanstd(x)) or 1.0
    nll = math.inf
    for k, (eff, p) in enumerate(procs):
        others = procs[:k] + procs[k + 1:]
        ml, white, nll = sto.exact_fit(x, rec.dt_s, eff, p, white, others)
        procs[k] = (eff, {q.name: float(np.clip(ml[q.name], q.low, q.high)) for q in eff.params})
    return 2 * nll


def _size_gate(n: int, dk: int) -> float:
    """What a term must gain in −2 ln L over a random process for ``dk`` parameters more — their
    BIC and the size gate, ``ln(n/2)·dk + MIN_SNR²`` — the one gate of :func:`unjumped`,
    :func:`jumped` and :func:`grown`, read from either side."""
    return math.log(n / 2) * dk + MIN_SNR ** 2


class Swap(NamedTuple):
    """What :func:`unjumped`, :func:`jumped` and :func:`grown` return: the model with ``into``
    named in place of the effects ``gone`` (``into`` may be among them), and why."""

    model: Model
    into: str
    gone: tuple[str, ...]
    why: str


def _slow(e: Effect) -> bool:
    """Level steps or a deterministic catch-all (a drift): slow structure a random process's
    wander also makes, weighed against one process alone by :func:`unjumped`. For a drift the
    gate is not sharp: it took a walk named as drift + Gauss–Markov back to the walk on three
    records of six samples, and read a real drift beside a real Gauss–Markov as a walk on two
    (gyro drift + delay + GM, stop 29's usual 3002 and second 3005)."""
    return e.level_steps or (e.catch_all and not e.stochastic)


def unjumped(model: Model, rec: Record, exclude: frozenset[str] = frozenset(), named: frozenset[str] | None = None
             ) -> Swap | None:
    """Level steps or a drift named beside or instead of a random process (``Effect.level_steps``:
    a jump's few level changes; a deterministic catch-all: a straight line — both of which a
    process's wander also makes, :func:`_slow`) that a single catch-all process alone explains
    as well once the names of a round are in: the model without them and its processes,
    calibrated, and each catch-all process shape (not in ``exclude``) fitted to
    what it leaves by the exact likelihood — kept when the steps and processes do not beat it by
    more than the BIC of their extra parameters and the size gate
    (``Δ(−2 ln L) ≤ ln(n/2)·Δk + MIN_SNR²``: a jump's times are searched, as
    :func:`.choosing.preferred` asks of a localized term against a process). Returns a :class:`Swap` (the model
    with the process in their place, its id, the ids it replaces, why) or None. Jumps are named
    before any process whose signature fails while another term is still missing (a walk's
    innovations followed a misalignment's cross input), and a Gauss–Markov beside them takes
    the rest of the wander (accelerometer misalignment + clip + walk: three jumps and a GM beat
    the walk alone by 45.9 for 7 parameters more, the gate 76; three real jumps beside a real GM
    beat every process alone by 77–1350 on seven samples' records). A gyro walk named as a drift
    and a Gauss–Markov (τ 8.6 s) once the asymmetry and K3 were in: the walk alone costs 33.8
    for 2 parameters fewer, the gate 39.6. Behind a coarse quantizer
    too: the Gaussian likelihood does not hold there, but both explanations are judged on it.
    ``named``: the effects the discovery named (default: all) — only those are replaced; a
    process of the starting model stays, known, beside the one fitted."""
    entries = [(e, p) for e, p in model.entries() if named is None or e.id in named]
    if not any(_slow(e) for e, _ in entries):
        return None
    kind = model.base.kind
    n = rec.n
    seen = model.partly_seen(rec)
    here = _exact_m2ll(model, rec, seen)
    gone = tuple(e.id for e, _ in entries if _slow(e) or e.stochastic)
    k_here = sum(e.n_coords if isinstance(e, StochasticEffect) else len(e.free_params(p, kind, rec))
                 for e, p in entries if e.id in gone)
    try:
        rest = calibrate(Model(model.base, tuple(ep for ep in model.effects if ep[0] not in gone)), rec)
    except ValueError:
        return None
    r = rec.y - rest.predict(rec)
    seen_r = rest.partly_seen(rec)
    best: tuple[float, Model, str, str] | None = None
    for eid, eff in CATALOGUE.items():
        if (not (isinstance(eff, StochasticEffect) and eff.catch_all and kind in eff.kinds) or eid in exclude
                or eid in rest.effect_ids):
            continue
        fit = sto.fit_stochastic(r - r.mean(), rec.dt_s, eff, known=rest.stochastic_effects(), bootstrap=False)
        if not np.isfinite(fit.white_sd):
            continue
        alt = rest.with_effect(eid, fit.params_for(kind))
        there = _exact_m2ll(alt, rec, seen_r)
        dk = k_here - eff.n_coords
        gate = _size_gate(n, dk)
        if there - here <= gate and (best is None or there + math.log(n / 2) * eff.n_coords < best[0]):
            why = (f"{eid} alone explains the record as well once the others are named "
                   f"(−2 ln L {there - here:+.3g} with {dk} parameter(s) fewer; at most ln(n/2)·Δk + "
                   f"{MIN_SNR ** 2:.3g} = {gate:.3g})")
            best = (there + math.log(n / 2) * eff.n_coords, alt, eid, why)
    if best is None:
        return None
    _, alt, eid, why = best
    return Swap(alt, eid, gone, why)


def jumped(model: Model, rec: Record, exclude: frozenset[str] = frozenset(), named: frozenset[str] | None = None,
           alpha: float = 0.05) -> Swap | None:
    """The converse of :func:`unjumped`: a catch-all random process named alone for level steps
    (no level-steps effect named) that jumps in its place explain better once the names of a
    round are in — the jumps searched on what the model leaves without the process, fitted there
    and the model calibrated; taken when they beat the process by more than the BIC of their
    extra parameters and the size gate (``Δ(−2 ln L) > ln(n/2)·Δk + MIN_SNR²``, the exact
    likelihood, each jump's searched time counted twice: ``Effect.searched``; stricter than
    :func:`unjumped`'s gate from the other side, so the two never undo each other).
    A walk named for two jumps while a thermal term beside them was still missing (accelerometer
    temperature-scale-factor + hysteresis + jumps: the walk explained the jumps and the
    hysteresis's loop together until the hysteresis was named) — and only when the process,
    refitted to what the jumps leave, is not significant there (p ≥ ``alpha``, as
    :func:`.choosing.preferred` asks). One jump took a weak walk's largest step on an
    accelerometer K3 + hysteresis + walk and beat the walk by 34.2 (gate 32.3 with the time
    counted once, 39.6 twice); nothing of the walk was left beside it.
    Returns a :class:`Swap` (the model with the jumps in the process's place, their id, the process's id, why)
    or None."""
    kind = model.base.kind
    if any(e.level_steps for e, _ in model.entries()) or model.colours_residual():
        return None
    procs = [(i, e) for i, (e, _) in enumerate(model.entries())
             if isinstance(e, StochasticEffect) and e.catch_all and (named is None or e.id in named)]
    steps_ = [e for eid, e in CATALOGUE.items() if e.level_steps and eid not in exclude and kind in e.kinds]
    if len(procs) != 1 or not steps_:
        return None
    i, proc = procs[0]
    n = rec.n
    here = _exact_m2ll(model, rec, model.partly_seen(rec))
    best: tuple[float, Model, str, str] | None = None
    for eff in steps_:
        alt = _fitted_in_place(model, i, eff, rec, partial(eff.fit_starts, rec, kind=kind))
        if alt is None:
            continue
        there = _exact_m2ll(alt, rec, alt.partly_seen(rec))
        p = dict(alt.effects[alt.effect_ids.index(eff.id)][1])
        dk = len(eff.free_params(p, kind, rec)) + eff.searched(p) - proc.n_coords
        gate = _size_gate(n, dk)
        if here - there <= gate or (best is not None and there >= best[0]):
            continue
        r = rec.y - alt.predict(rec)
        if sto.fit_stochastic(r - r.mean(), rec.dt_s, proc, known=alt.stochastic_effects(),
                              bootstrap=False).p_value < alpha:
            continue  # the process holds beside them: a walk's wander, one step of which the jumps took
        why = (f"{eff.id} in its place explain the record better once the others are named "
               f"(−2 ln L {there - here:+.3g} with {dk} parameter(s) more, each searched time twice; "
               f"beyond ln(n/2)·Δk + {MIN_SNR ** 2:.3g} = {gate:.3g}), and {proc.id} keeps nothing beside them")
        best = (there, alt, eff.id, why)
    if best is None:
        return None
    _, alt, eid, why = best
    return Swap(alt, eid, (proc.id,), why)


def grown(model: Model, rec: Record, exclude: frozenset[str] = frozenset(), named: frozenset[str] | None = None
          ) -> Swap | None:
    """A named shape and the catch-all processes named beside it replaced by the shape that nests
    it alone (a warm-up and a walk by a two-node transient, ``Effect.nests``) once the names of a
    round are in: the nesting shape fitted in the named one's place on what the model leaves
    without the processes, the model calibrated; taken when it beats them on the exact likelihood
    by more than the BIC of its extra parameters and the size gate (``Δ(−2 ln L) > ln(n/2)·Δk +
    MIN_SNR²``, what :func:`unjumped` asks of a term against a process). Jumps at 48 and 170 s
    kept a two-node's fit off at the first step, a warm-up was named (the simpler shape within a
    standard error) and a walk took the slow node after the jumps (gyro jumps + misalignment +
    two-node: the two-node alone beats the warm-up and the walk by 227, gate 32). Every other warm-up
    named beside a process on ten samples (29 records, most of them real) lost 28-2360 to it. Not
    behind a coarse quantizer. Returns a :class:`Swap` (the model with the nesting shape, its id, the ids it
    replaces, why) or None."""
    if model.colours_residual():
        return None
    kind = model.base.kind
    named_ids = set(model.effect_ids if named is None else named)
    procs = [e for e, _ in model.entries() if isinstance(e, StochasticEffect) and e.catch_all and e.id in named_ids]
    if not procs:
        return None
    rest = Model(model.base, tuple(ep for ep in model.effects if ep[0] not in {e.id for e in procs}))
    here = _exact_m2ll(model, rec, model.partly_seen(rec))
    n = rec.n
    best: tuple[float, Model, str, tuple[str, ...], str] | None = None
    for i, (e, p) in enumerate(rest.entries()):
        if e.id not in named_ids or e.stochastic:
            continue
        for big in CATALOGUE.values():
            if e.id not in big.nests or kind not in big.kinds or big.id in exclude or big.id in model.effect_ids:
                continue
            alt = _fitted_in_place(rest, i, big, rec, partial(big.fit_starts, rec, kind=kind))
            if alt is None or not big.identifiable(alt.effects[i][1], rec):
                continue
            there = _exact_m2ll(alt, rec, alt.partly_seen(rec))
            dk = len(big.free_params(alt.effects[i][1], kind, rec)) - len(e.free_params(p, kind, rec)) \
                - sum(x.n_coords for x in procs)
            gate = _size_gate(n, dk)
            if here - there > gate and (best is None or there < best[0]):
                gone = (e.id, *(x.id for x in procs))
                why = (f"{big.id} alone explains the record better once the others are named (−2 ln L "
                       f"{there - here:+.3g} with {dk:+d} parameter(s); beyond ln(n/2)·Δk + {MIN_SNR ** 2:.3g} = "
                       f"{gate:.3g})")
                best = (there, alt, big.id, gone, why)
    if best is None:
        return None
    _, alt, into, gone, why = best
    return Swap(alt, into, gone, why)


def _m2ll(model: Model, rec: Record, r: np.ndarray | None = None, seen: np.ndarray | None = None) -> float:
    """−2 ln L of ``model``'s residual ``r`` (by default rec.y − its prediction) under its noise
    (Kalman innovations: white ``noise_sd`` plus its random processes at their values), the
    constant left out; ``seen``: the samples that count (the others missing: a clip's,
    ``Model.noise_seen``)."""
    r = rec.y - model.predict(rec) if r is None else r
    r = seen_only(r, seen if seen is not None and not seen.all() else None)
    return 2 * exact_nll(r, rec.rate_hz, float(model.base.noise_sd) ** 2, model.stochastic_effects())


def _waveform_params(model: Model, rec: Record) -> int:
    kind = model.base.kind
    return sum(len(e.free_params(p, kind, rec)) for e, p in model.entries() if e.waveform and not e.stochastic)


def renested(model: Model, rec: Record, alpha: float = 0.05) -> Merged | None:
    """A shape named beside one it nests (a two-node transient and a warm-up) merged into the
    nesting shape alone (``Effect.holding``: its starts), with or without the effects it declares
    may stand beside it (``Effect.stands_beside``: a two-node's slow node beyond the record is a
    drift), the model calibrated and its processes re-estimated: the alternative with fewer
    waveform parameters whose −2 ln L (:func:`_m2ll`) is higher by no more than ln(n/2) a
    parameter dropped (the BIC's weight), the best such by the BIC; None when there is none. A
    sequential search names the pair when the nesting shape came first for a drift and a
    transient's slow node (gyro drift + two-node + Gauss–Markov: the two-node's slow node at
    2500 s on 300 s, a warm-up for the fast node; merged with a drift: −2 ln L within 0.1, one
    parameter fewer, the transient's constants 2.15/18.9 s for 2.09/18.2 s). Not judged through an
    output stage (the Gaussian likelihood does not hold behind a coarse quantizer or a clip)."""
    if model.has_output_stage():
        return None
    kind = model.base.kind
    ids = model.effect_ids
    here, k_here = _m2ll(model, rec), _waveform_params(model, rec)
    weight = math.log(rec.n / 2)
    best: tuple[float, Merged] | None = None
    for i, (e, p) in enumerate(model.entries()):
        for nested in (x for x in e.nests if x in ids):
            j = ids.index(nested)
            rest = [x for k, x in enumerate(model.effects) if k not in (i, j)]
            extras = [x for x in e.stands_beside if x not in ids and kind in CATALOGUE[x].kinds]
            for start in e.holding(p, nested, model.effects[j][1], kind):
                for added in ((), *((x,) for x in extras)):
                    effects = (*rest, (e.id, start), *((x, CATALOGUE[x].reference_params(rec, kind)) for x in added))
                    try:
                        alt = calibrate(Model(model.base, tuple(effects)), rec, noise=False)
                    except ValueError:
                        continue
                    alt, _ = refit_processes(alt, rec, alpha)
                    k_alt = _waveform_params(alt, rec)
                    if k_alt >= k_here or not all(CATALOGUE[x].identifiable(q, rec) for x, q in alt.effects):
                        continue
                    grows = _m2ll(alt, rec) - here
                    bic = grows - weight * (k_here - k_alt)
                    if bic <= 0 and (best is None or bic < best[0]):
                        why = (f"{e.id} alone holds it{' with ' + ', '.join(added) if added else ''}: "
                               f"−2 ln L grows by {grows:.3g} with {k_here - k_alt} parameter(s) fewer "
                               f"(at most ln(n/2) = {weight:.3g} each)")
                        best = (bic, Merged(alt, e.id, nested, added, why))
    return None if best is None else best[1]


def _exact_refit(model: Model, i: int, eid: str, start: Params, rec: Record, seen: np.ndarray) -> Model | None:
    """``model`` with effect ``eid`` in the place of its ``i``-th, its parameters by the exact
    likelihood (:func:`_m2ll`, Nelder–Mead from ``start`` in the effect's coordinates: log for a
    log-scaled parameter), the rest as they are: beside a walk a least-squares calibration moves
    the bias and the transient far off (a warm-up's τ 1.34 s for 1.84 s, and the walk's level
    doubled), and the comparison would read the calibration's error. None when no value is
    admissible."""
    kind = model.base.kind
    eff = CATALOGUE[eid]
    qs = eff.params_for(kind)

    def params_at(x: np.ndarray) -> Params:
        return {q.name: float(np.clip(math.exp(v) if q.log else v, q.low, q.high)) for q, v in zip(qs, x)}

    def cost(x: np.ndarray) -> float:
        try:
            alt = Model(model.base, (*model.effects[:i], (eid, params_at(x)), *model.effects[i + 1:]))
            return _m2ll(alt, rec, seen=seen)
        except ValueError:
            return math.inf
    x0 = np.array([math.log(max(start[q.name], q.low)) if q.log else start[q.name] for q in qs], float)
    res = optimize.minimize(cost, x0, method="Nelder-Mead", options={"xatol": 1e-4, "fatol": 1e-2, "maxiter": 400})
    if not math.isfinite(float(res.fun)):
        return None
    return Model(model.base, (*model.effects[:i], (eid, params_at(res.x)), *model.effects[i + 1:]))


def unnested(model: Model, rec: Record, alpha: float = 0.05) -> Merged | None:
    """A nesting shape (a two-node warm-up) named before a random process, replaced by the shape it
    nests (a warm-up; ``Effect.reduced``: its starts) when, fitted in its place by the exact
    likelihood with the rest as it is (:func:`_exact_refit`), −2 ln L (:func:`_m2ll`, the
    clipped samples left out) grows by no more than ln(n/2) a parameter dropped — the process
    holds what the richer shape's extra node had followed (gyro asymmetry + warm-up + walk: a
    two-node with a 168-s slow node of share −0.24 on a 300-s record was named before the walk).
    Without any random process (the residual white, least squares its likelihood) the same test
    with the nested shape fitted in its place and the whole model calibrated: a candidate's fit
    keeps the effects named before it fixed, and a two-node (τ 6.5 s and 54 s) was named for a
    23-s warm-up whose candidate fit, beside a temperature scale factor fitted to the warming,
    went to 38 s (gyro temperature SF + warm-up + g-sensitivity; in its place and calibrated the
    warm-up costs 3.2 for 2 parameters fewer). The best such by the BIC; None when there is none,
    beside processes without a walk among them (``nonstationary``; beside the start-up run's
    Gauss–Markov of 19.5 s the rule traded the transient's fast node for the process's wander —
    the run's heater is a two-node transient), or behind an effect that colours the residual."""
    procs = model.stochastic_effects()
    white = not procs
    if not (white or any(e.nonstationary for e, _ in procs)) or model.colours_residual():
        return None
    kind = model.base.kind
    ids = model.effect_ids
    seen = model.noise_seen(rec)

    def m2ll(m: Model) -> float:  # white: n·ln(SSE), the likelihood at its own variance
        if white:
            return int(seen.sum()) * math.log(float(np.nansum(seen_only(rec.y - m.predict(rec), seen) ** 2)))
        return _m2ll(m, rec, seen=seen)
    here, k_here = m2ll(model), _waveform_params(model, rec)
    weight = math.log(rec.n / 2)
    best: tuple[float, Merged] | None = None
    for i, (e, p) in enumerate(model.entries()):
        for nested in (x for x in e.nests if x not in ids and kind in CATALOGUE[x].kinds):
            for start in e.reduced(p, nested, kind):
                if white:
                    alt = _fitted_in_place(model, i, CATALOGUE[nested], rec, lambda _r, rows=None, s=start: [s])
                else:
                    alt = _exact_refit(model, i, nested, start, rec, seen)
                if alt is None:
                    continue
                k_alt = _waveform_params(alt, rec)
                if k_alt >= k_here or not CATALOGUE[nested].identifiable(alt.effects[i][1], rec):
                    continue
                grows = m2ll(alt) - here
                bic = grows - weight * (k_here - k_alt)
                if bic <= 0 and (best is None or bic < best[0]):
                    why = (f"{nested} alone holds it{'' if white else ' beside the random process'}: −2 ln L grows "
                           f"by {grows:.3g} with {k_here - k_alt} parameter(s) fewer (at most ln(n/2) = {weight:.3g} "
                           "each)")
                    best = (bic, Merged(alt, nested, e.id, (nested,), why))
    return None if best is None else best[1]


def _named_as_merged(merged: Merged, rec: Record, alpha: float, seed: int, n_rep: int,
                     fill_map: MapFn) -> list[Step] | None:
    """The steps of the effects a merge brings in (:func:`renested`), each named on its own
    evidence beside the rest of the merged model (:func:`.naming.name_effect` with that effect
    only: significant, its signature holding for a catch-all); None when one is not."""
    out = []
    for eid in merged.added:
        at = merged.model.effect_ids.index(eid)
        without = Model(merged.model.base, merged.model.effects[:at] + merged.model.effects[at + 1:])
        naming = name_effect(without, rec, alpha=alpha, seed=seed, n_rep=n_rep, only=(eid,), fill_map=fill_map)
        if naming.best is None or naming.best.id != eid:
            return None
        g0, rms0, _, r0 = gap_of(without, rec, seed)
        g1, rms1, _, r1 = gap_of(merged.model, rec, seed)
        std = _step_std(merged.model, rec, naming.best.params_std, at)
        out.append(Step(eid, dict(merged.model.effects[at][1]), std, naming.best.p_value, g0, g1, rms0, rms1,
                        naming, _structure(without, rec, r0), r0, r1))
    return out


def refit_processes(model: Model, rec: Record, alpha: float = 0.05) -> tuple[Model, dict[str, float]]:
    """The model with each random process re-estimated (Whittle, the effect's own estimate) on
    the residual the model leaves now, the other processes beside it, and each one's p-value
    there: ``calibrate`` refits every waveform but keeps a process's values, which were estimated
    on the residual of the step that named it — before the effects named after it were known (a
    random walk named before a dead zone kept twice its level, and its innovations then fell
    short of its spectrum: its signature failed and it was withdrawn). Values clipped to the
    kind's ranges; a process no longer significant there (p ≥ ``alpha``) keeps the values it was
    named with — the audit withdraws it (a walk named for a look-alike's misfit, 3·10⁻⁷ g/√s,
    refitted to 6·10⁻⁹ at p = 1 once the right effect was named). Beside an output stage that
    clips, the values are the exact likelihood's with the clipped samples missing
    (:func:`.stochastic.censored_params`)."""
    procs = [(i, e) for i, (e, _) in enumerate(model.entries()) if e.stochastic]
    kind = model.base.kind
    p_values: dict[str, float] = {}
    r = rec.y - model.predict(rec)  # the processes are not in the prediction: one residual for all
    seen = model.partly_seen(rec) if procs else None
    for k, (i, eff) in enumerate(procs):  # k-th process of the model, its i-th effect
        others = tuple(ep for j, ep in enumerate(model.stochastic_effects()) if j != k)
        fit = sto.fit_stochastic(r - r.mean(), rec.dt_s, eff, known=others)
        params = fit.params_for(kind)
        if fit.p_value < alpha and seen is not None:  # beside a clip: the exact likelihood's values
            params = sto.censored_params(r, seen, rec.dt_s, eff, params, fit.white_sd, kind, others)
        p_values[eff.id] = float(fit.p_value)
        if fit.p_value < alpha and all(np.isfinite(v) for v in params.values()):
            model = model.with_params(i, params)
    return model, p_values


def faded_processes(model: Model, p_values: dict[str, float], named: set[str], alpha: float) -> list[Evidence]:
    """The audit's evidence against the model's named random processes that
    :func:`refit_processes` found no longer significant beside the effects named after them."""
    return [Evidence(e.id, False, p_values[e.id],
                     (f"{e.id} is no longer significant on the final model's residual (p = {p_values[e.id]:.2g}): "
                      "what it stood for was explained by an effect named after it",))
            for e, _ in model.entries()
            if e.stochastic and e.id in named and p_values.get(e.id, 0.0) >= alpha]


def faded_terms(model: Model, rec: Record, named: set[str], r: np.ndarray, alpha: float = 0.05) -> list[Evidence]:
    """The audit's evidence against named waveform terms that the effects named after them made
    redundant: removed from the final model (the others refitted, ``calibrate``, and its random
    processes re-estimated on what is left, :func:`refit_processes`) the exact Gaussian
    likelihood (Kalman innovations: white ``noise_sd`` plus the processes) drops by less than a
    χ² with the term's parameter count would at ``alpha`` — beside the others it is not
    significant. A two-node warm-up named first for the slope of a jump staircase (and a
    Gauss–Markov's wander) stayed named beside the jumps (−2·ΔlnL 3.2 on 4 parameters), an extra
    name. (A searched parameter — a jump's time, a time constant — makes the χ² reference
    generous to the term: only a clearly idle one is withdrawn. The size gate, 25, was too
    strict here: a temperature bias beside a Gauss–Markov that stretches toward it gains 22.5,
    p = 10⁻⁵.) Not judged behind an effect that colours the residual (a coarse quantizer: the
    Gaussian likelihood does not hold); behind a clip the likelihoods count the samples the final
    model's clip leaves (``Model.noise_seen``; the clipped ones hold no noise — a K2 named for a
    delay's misfit stayed beside the low-pass that replaced the delay). ``r``: the model's residual."""
    if model.colours_residual():
        return []
    seen = model.noise_seen(rec)
    here = _m2ll(model, rec, r, seen)
    out = []
    for i, (e, own) in enumerate(model.entries()):
        if e.id not in named or not e.waveform or e.stochastic:
            continue
        without = calibrate(Model(model.base, model.effects[:i] + model.effects[i + 1:]), rec, noise=False)
        without, _ = refit_processes(without, rec, alpha)
        gain = _m2ll(without, rec, seen=seen) - here
        k = max(1, len(e.free_params(own, model.base.kind, rec)))  # a jump: its used slots only
        p_value = float(chi2_dist.sf(max(gain, 0.0), k))
        if p_value >= alpha:
            out.append(Evidence(e.id, False, p_value,
                                (f"{e.id} is no longer significant beside the effects named after it: without it "
                                 f"(the others refitted, the processes re-estimated) −2 ln L grows by {gain:.3g} "
                                 f"(p = {p_value:.2g} on χ² with {k} dof)",)))
    return out


def _structure(model: Model, rec: Record, r: np.ndarray) -> Localization:
    return localize(rec, r - r.mean(), model.residual_sd())


def _step_std(model: Model, rec: Record, naming_std: dict, at: int) -> dict:
    """Std of the parameters of effect ``at`` (the one just named) at the re-calibrated model
    (the naming fit's std belonged to other values of the other parameters); the naming's for an
    effect that is not a waveform (a random process, a histogram-judged effect)."""
    eff, p = model.entries()[at]
    if not eff.waveform:
        return dict(naming_std)
    # the model's noise_sd is already the noise before any quantizer (with_noise_floor)
    rest = Model(model.base, model.effects[:at] + model.effects[at + 1:])
    f = CandidateFitter(rest, rec, eff, noise_is_floor=False, template=p, at=at)
    x = f.pack(p, model.base.bias, model.base.scale_factor)
    return dict(f.fit([x], max_nfev=1).params_std)


def _placed(alt: Model, into: str, rec: Record, alpha: float, seed: int, it: int, n_rep: int, fill_map: MapFn
            ) -> tuple[Model, dict[str, float], tuple[Gap, float, float, np.ndarray], Step] | None:
    """An effect ``into`` that took others' place in ``alt`` once the names of a round were in
    (:func:`relooked`, :func:`unjumped`, :func:`jumped`, :func:`grown`), named on its own
    evidence: ``name_effect(only=…)`` on ``alt`` without it (round ``it``'s seed) must name it,
    else None. Then (``alt`` with its
    processes refitted, their p-values, its gap, the :class:`Step` of ``into`` — the gap before
    it the model's without it)."""
    at = alt.effect_ids.index(into)
    without = Model(alt.base, alt.effects[:at] + alt.effects[at + 1:])
    naming = name_effect(without, rec, alpha=alpha, seed=seed + it, n_rep=n_rep, only=(into,), fill_map=fill_map)
    if naming.best is None or naming.best.id != into:
        return None
    model, process_p = refit_processes(alt, rec, alpha)
    after = gap_of(model, rec, seed)
    g0, rms0, _, r0 = gap_of(without, rec, seed)
    g1, rms1, _, r1 = after
    at = model.effect_ids.index(into)
    step = Step(into, dict(model.effects[at][1]), _step_std(model, rec, naming.best.params_std, at),
                naming.best.p_value, g0, g1, rms0, rms1, naming, _structure(without, rec, r0), r0, r1)
    return model, process_p, after, step


def _fmt(v: float) -> str:
    return f"{v:.3g}"


def discover(rec: Record, model: Model, *, max_effects: int = 4, alpha: float = 0.05, seed: int = 0,
             n_rep: int = 999, only: tuple[str, ...] | None = None,
             progress: Callable[[str], None] | None = None, map_fn: MapFn = map,
             fill_map: MapFn = map) -> Discovery:
    """Run the loop a..e on ``rec`` from ``model``; see the module docstring. ``progress``:
    called with a short human message as each candidate is judged and after each step;
    ``map_fn``: how each naming step maps the candidates' fits over them (:mod:`.mapping`: an
    executor's ``map`` runs them side by side; the answer is the same); ``fill_map``: how the
    nulls' noise realisations are filled in this process (a thread pool's ``map`` fills them side
    by side: the same numbers, :meth:`.Model.simulate_noise_many`)."""
    if not isinstance(max_effects, int) or not 0 <= max_effects <= len(CATALOGUE):
        raise ValueError(f"max_effects = {max_effects!r}; allowed: an integer in [0, {len(CATALOGUE)}]")
    if not 0 < alpha < 1:
        raise ValueError(f"alpha = {alpha!r}; allowed: (0, 1)")
    say = progress or (lambda _msg: None)
    skipped = [eid for eid, e in CATALOGUE.items() if e.needs_uniform and model.base.kind in e.kinds]
    if skipped and not rec.is_uniform():
        notes = [f"{', '.join(skipped)} not tried: the sample intervals vary by more than 0.1 % of the median "
                 "(a sampled filter needs a uniform record; resample to try them)"]
    else:
        notes = []
    model = calibrate(model, rec)
    initial = model
    g0, rms0, floor, r0 = gap_of(model, rec, seed)
    steps: list[Step] = []
    gap_cur, rms_cur, r_cur = g0, rms0, r0
    it = 0  # naming rounds so far (each its own seed)
    unused_followed: set[str] = set()
    withdrawn: list[str] = []
    withdrawn_ids: set[str] = set()
    set_aside: tuple[str, ...] = ()
    audit_rng = np.random.default_rng(seed + 7919)
    process_p: dict[str, float] = {}  # the processes' p-values at their last refit (refit_processes)
    for _round in range(MAX_ROUNDS):
        # c..e: name one effect at a time until nothing is significant (or max_effects)
        named_now = 0
        while True:  # ends by a break, loc and naming describing r_cur
            loc = _structure(model, rec, r_cur)

            def step_say(msg: str, _it: int = it) -> None:
                say(f"step {_it + 1}: {msg}")

            # the withdrawn effects sit out the re-choice until it names something: beside a new
            # name (the look-alike of the one that failed) they may hold again (K2 beside the
            # asymmetry it had been named for)
            naming = name_effect(model, rec, alpha=alpha, seed=seed + it, n_rep=n_rep, only=only,
                                 catch_alls=not unused_followed,
                                 exclude=frozenset(withdrawn_ids) if named_now == 0 else frozenset(),
                                 progress=step_say, map_fn=map_fn, fill_map=fill_map)
            set_aside = naming.set_aside
            # a catch-all whose innovations follow a logged column no catalogue effect reads: the
            # slow structure is that column's, out of the catalogue — no catch-all is named for it
            new_cols = sorted(set(naming.followed_columns) - CATALOGUE.columns_used(model.base.kind)
                              - unused_followed)
            if new_cols:
                unused_followed.update(new_cols)
                notes.append(f"the slow structure follows {', '.join(new_cols)}, which no catalogue effect reads: "
                             "no random process or drift is named for it")
            if naming.best is None:
                say(f"step {it + 1}: nothing significant; stopping")
                break
            if len(steps) == max_effects:
                notes.append(f"stopped after max_effects = {max_effects}; {naming.best.id} was still significant")
                break
            best = naming.best
            new = input_order(calibrate(model.with_effect(best.id, best.params), rec), rec)
            if not best.stochastic:  # the residual the model's processes were estimated on changed
                new, process_p = refit_processes(new, rec, alpha)
            g1, rms1, floor, r1 = gap_of(new, rec, seed)
            at = new.effect_ids.index(best.id)
            steps.append(Step(best.id, dict(new.effects[at][1]), _step_std(new, rec, best.params_std, at),
                              best.p_value, gap_cur, g1, rms_cur, rms1, naming, loc, r_cur, r1))
            say(f"step {it + 1}: named {best.id}, rms {_fmt(rms_cur)} → {_fmt(rms1)}")
            model, gap_cur, rms_cur, r_cur = new, g1, rms1, r1
            it += 1
            named_now += 1
        # f: every named effect's own signature on the final model: a shape that leaves structure
        # where it acts (a sinusoid on a square wave, K3 on a tanh) or a process whose innovations
        # are not white is withdrawn, the worst first, and what it stood for is reported as
        # unexplained — unless a re-choice explains it. One withdrawal a round, then the re-choice,
        # while rounds are left and the last re-choice named something: the others are judged
        # beside what replaced it (K2 named for a scale-factor asymmetry failed its shape, and a
        # temperature scale factor and a jump named beside it failed theirs while the asymmetry
        # was missing — all three were withdrawn; now K2 alone, then the asymmetry is named)
        full_audit = _round == MAX_ROUNDS - 1 or (_round > 0 and named_now == 0)
        withdrawn_now = 0
        if named_now:  # the names are in: a jump found beside a wrong shape is searched again
            moved = reseated(model, rec)
            if moved is not model:
                model, process_p = refit_processes(moved, rec, alpha)
                gap_cur, rms_cur, floor, r_cur = gap_of(model, rec, seed)
            swapped = relooked(model, rec, frozenset(withdrawn_ids))
            placed = None if swapped is None else _placed(swapped.model, swapped.into, rec, alpha, seed, it, n_rep,
                                                          fill_map)
            if swapped is not None and placed is not None:
                say(f"swapped: {swapped.dropped} for its look-alike {swapped.into}")
                withdrawn.append(f"{swapped.dropped}: {swapped.why}")
                withdrawn_ids.add(swapped.dropped)
                model, process_p, (gap_cur, rms_cur, floor, r_cur), step = placed
                steps = [st if st.effect_id != swapped.dropped else step for st in steps]
            # slow structure one random process explains as well, or level steps (or the shape
            # nesting a named one) that explain it better than the processes named for it (the
            # gates are one, from either side)
            for name, swap in (("unjumped", unjumped), ("jumped", partial(jumped, alpha=alpha)), ("grown", grown)):
                out = swap(model, rec, frozenset(withdrawn_ids), frozenset(st.effect_id for st in steps))
                placed = None if out is None else _placed(out.model, out.into, rec, alpha, seed, it, n_rep, fill_map)
                if out is None or placed is None:
                    continue
                gone = out.gone
                say(f"{name}: {', '.join(gone)} for {out.into}")
                for g in gone:
                    if g != out.into:
                        withdrawn.append(f"{g}: {out.why}")
                        withdrawn_ids.add(g)
                model, process_p, (gap_cur, rms_cur, floor, r_cur), step = placed
                steps = [st for st in steps if st.effect_id not in gone] + [step]
                break
            merged = renested(model, rec, alpha) or unnested(model, rec, alpha)
            added_steps = [] if merged is None else _named_as_merged(merged, rec, alpha, seed + it, n_rep, fill_map)
            if merged is not None and added_steps is not None:
                say(f"merged: {merged.dropped} into {merged.into}")
                withdrawn.append(f"{merged.dropped}: {merged.why}")
                withdrawn_ids.add(merged.dropped)
                steps = [st for st in steps if st.effect_id != merged.dropped] + added_steps
                model, process_p = refit_processes(merged.model, rec, alpha)
                gap_cur, rms_cur, floor, r_cur = gap_of(model, rec, seed)
        while steps:
            named_ids = {st.effect_id for st in steps}
            evs = [evidence(model, rec, i, r_cur, rng=audit_rng, n_rep=n_rep, fill_map=fill_map)
                   for i, eid in enumerate(model.effect_ids) if eid in named_ids]
            if unexplained_structure(rec, r_cur, model, alpha=alpha):
                # structure is left: a waveform must be significant beyond it, not only beyond white
                evs += [beyond_leftover(model, rec, i, r_cur)
                        for i, (e, _) in enumerate(model.entries())
                        if e.id in named_ids and e.waveform and not e.stochastic]
            evs += faded_processes(model, process_p, named_ids, alpha)
            evs += faded_terms(model, rec, named_ids, r_cur, alpha)
            failing = [ev for ev in evs if not ev.holds]
            if not failing:
                break
            worst = min(failing, key=lambda ev: ev.p_value)
            withdrawn.append(worst.describe())
            withdrawn_ids.add(worst.effect_id)
            withdrawn_now += 1
            say(f"withdrawn: {worst.effect_id} (its signature does not hold)")
            i = model.effect_ids.index(worst.effect_id)
            model, process_p = refit_processes(
                calibrate(Model(model.base, model.effects[:i] + model.effects[i + 1:]), rec), rec, alpha)
            steps = [st for st in steps if st.effect_id != worst.effect_id]
            gap_cur, rms_cur, floor, r_cur = gap_of(model, rec, seed)
            loc = _structure(model, rec, r_cur)
            if not full_audit:
                break  # re-choose before judging the others
        if not withdrawn_now:
            break
        # g: re-choose — name again without what was withdrawn: the next-best candidate for the
        # structure it stood for (the nesting shape after its special case, a random process a
        # withdrawn deterministic fit had absorbed) gets its turn, and is audited in its turn
        if _round < MAX_ROUNDS - 1:
            say("re-choosing after the withdrawal")
    for eid in sorted(withdrawn_ids & {st.effect_id for st in steps}):
        notes.append(f"{eid} was withdrawn (above) and named again beside an effect named after it; "
                     "its signature holds in the final model")
    # what no catalogue effect explained: the residual (white model) or its Kalman innovations
    # (stochastic model) against the model's own noise, family-wise at alpha
    unexplained = unexplained_structure(rec, r_cur, model, alpha=alpha)
    if unexplained:
        say(f"unexplained structure: {len(unexplained)} finding(s)")
    return Discovery(initial, model, tuple(steps), unexplained, g0, gap_cur, rms0, rms_cur, floor, loc,
                     naming, r0, r_cur, tuple(notes), tuple(withdrawn), set_aside)
