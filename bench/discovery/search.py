"""Discovery's one search: add, drop and swap moves over the catalogue, under the one criterion.

From the calibrated starting model, each round takes the :data:`BEAM` best models found so far
and tries every move from each:

* **add** — every applicable catalogue effect not in the model, fitted on the residual the
  model leaves (a waveform by multi-start least squares from its ``fit_starts``; a random
  process by its Whittle fit, then the exact likelihood; a histogram-judged effect by its own
  lattice fit) and then refitted jointly with the rest (:func:`.calibration.calibrate`);
* **drop** — every effect of the model, the rest refitted;
* **swap** — every effect of the model for each of the :data:`SWAP_WITH` best add candidates of
  that model (the effect dropped, the candidate fitted on what the rest leaves).

Every model reached is scored once by :class:`Evaluator` (the criterion of :mod:`.criterion`);
the search ends when a round finds no model with a lower criterion than the best so far. There
is no other rule: a look-alike named first is swapped out when the right effect's criterion is
lower, a jump that a random walk explains as well is dropped when the walk (fewer, unsearched
parameters) costs less, a process that absorbed a deterministic term is dropped once the term is
in. The models the last round scored around the best give the ties (:func:`ties`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import partial

import numpy as np
from scipy.optimize import minimize_scalar
from scipy.special import gammaln

from bench.discovery import stochastic as sto
from bench.discovery.calibration import calibrate
from bench.discovery.criterion import (
    equivalent_deviance,
    n_free,
    penalty,
    relative_weight,
    tie_band,
)
from bench.discovery.data import Record
from bench.discovery.effects import CATALOGUE
from bench.discovery.effects_base import Effect, HistogramEffect, Params
from bench.discovery.effects_noise import StochasticEffect
from bench.discovery.fitting import CandidateFitter
from bench.discovery.mapping import MapFn
from bench.discovery.model import Model
from bench.discovery.significance import block_folds
from bench.discovery.whiten import seen_only, state_space

#: Models extended each round: the best and the runner-up, so a path whose first add is a
#: look-alike (or a process standing in for a term not yet found) still reaches the right set.
BEAM = 2

#: Add candidates (best first) each named effect is swapped for.
SWAP_WITH = 3


def applicable(model: Model, rec: Record, exclude: frozenset[str] = frozenset()) -> list[Effect]:
    """Catalogue effects that apply to the model's kind and to ``rec`` (their logged columns
    present and varying; a sampled filter only on a record uniform to 0.1 %) and are not in the
    model."""
    have = set(model.effect_ids) | set(exclude)
    return [e for e in CATALOGUE.values()
            if e.id not in have and model.base.kind in e.kinds and not (e.needs_uniform and not rec.is_uniform())
            and e.applies_to(rec)]


@dataclass(frozen=True, eq=False)
class Scored:
    """A model as the criterion weighs it: fitted (deterministic parameters by least squares,
    the white level and the processes at their exact maximum likelihood), ``m2ll`` its −2 ln L
    (histogram-judged effects' equivalent deviance taken off), ``penalty`` the sum of its
    effects' penalties; ``parent`` and ``move`` say how the search reached it."""

    model: Model
    m2ll: float
    penalty: float
    parent: Scored | None = field(default=None, repr=False)
    move: str = "start"

    @property
    def criterion(self) -> float:
        return self.m2ll + self.penalty

    @property
    def key(self) -> frozenset[str]:
        return frozenset(self.model.effect_ids)

    def path(self) -> list[Scored]:
        """From the start to this model."""
        out: list[Scored] = []
        s: Scored | None = self
        while s is not None:
            out.append(s)
            s = s.parent
        return out[::-1]


class Evaluator:
    """Fits and scores models on one record under one criterion (:mod:`.criterion`).

    ``rec`` the readings the deterministic fits see (outliers replaced), ``seen`` the samples
    the likelihood counts (None: all), ``n_candidates`` and ``alpha`` the criterion's
    multiplicity and false-name rate."""

    def __init__(self, rec: Record, kind: str, *, n_candidates: int, alpha: float,
                 seen: np.ndarray | None = None) -> None:
        self.rec, self.kind, self.alpha = rec, kind, alpha
        self.n_candidates = max(int(n_candidates), 1)
        self.seen = None if seen is None or seen.all() else np.asarray(seen, bool)
        self.cache: dict[frozenset[str], Scored] = {}
        #: the starting model's effects: the user's, kept as given even where the record cannot
        #: resolve them; an effect the search adds must be resolvable (``Effect.identifiable``)
        self.given: frozenset[str] = frozenset()
        #: effects estimated on the whole record (a long record's block means) that a search on
        #: a window of it keeps as they are: not refitted, not dropped or swapped
        self.fixed: frozenset[str] = frozenset()
        #: effects the whole record named that a search on a window of it refits but neither drops
        #: nor swaps: a window of a tenth of the record cannot say a slow effect is not there (a
        #: temperature term where the temperature barely moves); the whole record decides
        #: (``workflow._confirmed``)
        self.kept: frozenset[str] = frozenset()
        self._hist_p: dict[str, float] = {}

    # ---- the criterion ------------------------------------------------------------------
    def penalty(self, model: Model) -> float:
        return sum(penalty(e, p, self.rec, self.kind, self.n_candidates, self.alpha) for e, p in model.entries())

    def seen_of(self, model: Model) -> np.ndarray | None:
        """The samples the likelihood counts for ``model``: the record's (``seen``) less those its
        output stage leaves without noise (``Model.partly_seen``: a clip); None: all."""
        part = model.partly_seen(self.rec)
        if part is None:
            return self.seen
        return part if self.seen is None else part & self.seen

    def fit_noise(self, model: Model) -> tuple[Model, float]:
        """The model with its white level and random processes at their exact maximum
        likelihood on its residual (each process in turn, the others at their values), and −2 ln L
        there (the constant left out)."""
        rec = self.rec
        x = seen_only(rec.y - model.predict(rec), self.seen_of(model))
        procs = list(model.stochastic_effects())
        if not procs:
            var = float(np.nanvar(x)) or 1e-300
            z = x[~np.isnan(x)][1:]  # the first innovation measures the level (below)
            return model, student_m2ll(z / math.sqrt(var), np.full(z.size, var))
        white = float(model.residual_sd()) or float(np.nanstd(x)) or 1e-300
        if all(e.id in self.fixed for e, _ in procs):  # the white level alone, the processes as given
            white = sto.exact_white(x, rec.dt_s, procs, white)
        for k, (eff, p) in enumerate(procs):
            if eff.id in self.fixed:
                continue
            others = procs[:k] + procs[k + 1:]
            ml, white, _ = sto.exact_fit(x, rec.dt_s, eff, p, white, others)
            # kept inside the range the record allows (``Effect.fit_params``: any sensor grade)
            bounds = eff.fit_params(rec, self.kind)
            procs[k] = (eff, {q.name: float(np.clip(ml[q.name], q.low, q.high)) for q in bounds})
        at = {e.id: p for e, p in procs}
        for i, (e, _) in enumerate(model.entries()):
            if e.id in at:
                model = model.with_params(i, at[e.id])
        if not model.has_output_stage():
            model = model.with_noise_floor(white)
        innov, ivar = state_space(rec.rate_hz, x.size, procs).filter(x, white * white)
        keep = ~np.isnan(innov)
        # the bias is a free level and a walk's start is unknown: the first innovation measures
        # the level, not the noise — every model is weighed on the others (the diffuse likelihood)
        keep[np.argmax(keep)] = False
        if not np.all(ivar[keep] > 0):
            return model, math.inf
        return model, student_m2ll(innov[keep] / np.sqrt(ivar[keep]), ivar[keep])

    def histogram_p(self, effect: HistogramEffect, model: Model) -> float:
        """The lattice test's p-value of a histogram-judged effect on the readings (once)."""
        if effect.id not in self._hist_p:
            fit = effect.fit_histogram(self.rec.y, float(model.base.noise_sd), block_folds(self.rec.n), self.kind)
            self._hist_p[effect.id] = float(fit.p_value)
        return self._hist_p[effect.id]

    def score(self, model: Model, parent: Scored | None = None, move: str = "start") -> Scored | None:
        """The model fitted and weighed (None when it cannot be fitted on the record: a
        calibration at the edge of the base ranges). Scored once per set of effects: the first
        path to reach a set keeps it."""
        key = frozenset(model.effect_ids)
        if key in self.cache:
            return self.cache[key]
        try:
            fitted = calibrate(model, self.rec, frozen=self.fixed)
            fitted, m2ll = self.fit_noise(fitted)
        except (ValueError, np.linalg.LinAlgError, FloatingPointError):
            return None
        if not math.isfinite(m2ll):
            return None
        # a Gauss–Markov whose correlation time outgrew the record is a walk there, a transient
        # slower than the record a drift: the record cannot name such a fit
        if not all(e.identifiable(p, self.rec) for e, p in fitted.entries() if e.id not in self.given):
            return None
        for e, p in fitted.entries():
            if isinstance(e, HistogramEffect):
                m2ll -= equivalent_deviance(self.histogram_p(e, fitted), n_free(e, p, self.rec, self.kind))
        s = Scored(fitted, m2ll, self.penalty(fitted), parent, move)
        self.cache[key] = s
        return s

    # ---- proposals ----------------------------------------------------------------------
    def proposals(self, model: Model, effect: Effect) -> list[Params]:
        """Starting parameters for ``effect`` added to ``model``, fitted on what the model leaves:
        a waveform by multi-start least squares (a jump's searched change points, and each
        shorter prefix of them: the count is the criterion's), a random process by its Whittle
        fit beside the model's processes, a histogram-judged effect by its lattice fit."""
        rec, kind = self.rec, self.kind
        r = rec.y - model.predict(rec)
        try:
            if isinstance(effect, StochasticEffect):
                fit = sto.fit_stochastic(r - r.mean(), rec.dt_s, effect, known=model.stochastic_effects(),
                                         bootstrap=False)
                p = fit.params_for(kind)
                return [p] if all(np.isfinite(v) for v in p.values()) else []
            if isinstance(effect, HistogramEffect):
                h = effect.fit_histogram(rec.y, float(model.base.noise_sd), block_folds(rec.n), kind)
                return [dict(h.params)]
            seen = model.follows_input(rec)
            starts = effect.fit_starts(rec, r, kind=kind, rows=None if seen.all() else seen)
            if not starts:
                return []
            f = CandidateFitter(model, rec, effect, template=starts[0])
            b0, s0 = float(model.base.bias), float(model.base.scale_factor)
            full = f.fit([f.pack(p, b0, s0) for p in starts], with_std=False)
            out = [dict(full.params)]
            out += [q for q in effect.prefixes(full.params) if q != out[0]]
            return out
        except (ValueError, np.linalg.LinAlgError, FloatingPointError):
            return []

    def added(self, s: Scored, eid: str) -> Scored | None:
        """The best-scoring model of ``s`` with effect ``eid`` added (None: no fit)."""
        best: Scored | None = None
        for p in self.proposals(s.model, CATALOGUE[eid]):
            try:
                m = s.model.with_effect(eid, p)
            except ValueError:
                continue
            t = self._fresh(m, s, f"add {eid}")
            if t is not None and (best is None or t.criterion < best.criterion):
                best = t
        if best is not None:
            self.cache[best.key] = best
        return best

    def _fresh(self, model: Model, parent: Scored, move: str) -> Scored | None:
        """Score ``model`` whether or not a model with its effects was scored before (the add
        moves compare their own proposals; the cache keeps the better)."""
        key = frozenset(model.effect_ids)
        old = self.cache.pop(key, None)
        t = self.score(model, parent, move)
        if old is not None and (t is None or old.criterion <= t.criterion):
            self.cache[key] = old
            return old
        return t

    def dropped(self, s: Scored, eid: str) -> Scored | None:
        i = s.model.effect_ids.index(eid)
        return self.score(Model(s.model.base, s.model.effects[:i] + s.model.effects[i + 1:]), s, f"drop {eid}")


#: Degrees of freedom of the observation noise's Student-t density: from barely finite variance
#: (ν > 2) to a Gaussian for every practical purpose (at ν = 1000 a 5-σ sample's density is
#: within 2 % of the Gaussian's).
NU_RANGE = (2.05, 1000.0)


def student_fit(z: np.ndarray, v: np.ndarray) -> tuple[float, float, float]:
    """(−2 ln L with full constants, ν, scale²) of innovations ``z·√v`` (``z`` standardized by
    the Gaussian filter's innovation variances ``v``) under a Student-t observation density whose
    scale and degrees of freedom ν (in :data:`NU_RANGE`) are at their maximum: the observation
    noise may be heavy-tailed, so a tail sample is not a structure to fit. On Gaussian
    innovations ν goes to its top and this is the Gaussian −2 ln L."""
    z2 = np.asarray(z, float) ** 2
    log_v = float(np.sum(np.log(v)))
    n = z2.size

    def m2ll_at(nu: float) -> tuple[float, float]:
        c2 = float(np.mean(z2))  # a start: the Gaussian scale; then the t scale's fixed point
        for _ in range(30):
            w = (nu + 1) / (nu + z2 / c2)
            c2_new = float(np.mean(w * z2))
            if abs(c2_new - c2) <= 1e-10 * c2:
                break
            c2 = c2_new
        ll = n * (gammaln((nu + 1) / 2) - gammaln(nu / 2) - 0.5 * math.log(nu * math.pi * c2)) \
            - 0.5 * (nu + 1) * float(np.sum(np.log1p(z2 / (nu * c2))))
        return -2 * ll + log_v, c2

    res = minimize_scalar(lambda lnu: m2ll_at(math.exp(lnu))[0], bounds=tuple(map(math.log, NU_RANGE)),
                          method="bounded", options={"xatol": 1e-3})
    top, c2_top = m2ll_at(NU_RANGE[1])
    if top <= res.fun:
        return float(top), NU_RANGE[1], c2_top
    nu = math.exp(float(res.x))
    return float(res.fun), nu, m2ll_at(nu)[1]


def student_m2ll(z: np.ndarray, v: np.ndarray) -> float:
    """The −2 ln L of :func:`student_fit`."""
    return student_fit(z, v)[0]


def _add_one(ev: Evaluator, s: Scored, eid: str) -> Scored | None:
    return ev.added(s, eid)


@dataclass(frozen=True)
class SearchResult:
    """The best model, the start, every model scored (by set of effects), the rounds run, the
    add candidates tried (``n_candidates``: the criterion's multiplicity) and how many sets of
    effects were weighed (``evaluations``)."""

    best: Scored
    start: Scored
    scored: dict[frozenset[str], Scored] = field(repr=False)
    rounds: int
    n_candidates: int
    evaluations: int


def search(ev: Evaluator, start: Scored, *, max_effects: int, only: Sequence[str] | None = None,
           say: Callable[[str], None] = lambda _m: None, map_fn: MapFn = map) -> SearchResult:
    """Add, drop and swap from ``start`` until no move lowers the criterion (module docstring).
    ``only``: the ids the add moves may use (default: every applicable effect); ``map_fn``: how
    the add moves of one model are mapped (an executor's ``map`` runs them side by side: the
    same numbers)."""
    best = start
    frontier = [start]
    rounds = 0
    n_c = ev.n_candidates
    while True:
        rounds += 1
        children: list[Scored] = []
        for s in frontier:
            cands = [e.id for e in applicable(s.model, ev.rec) if only is None or e.id in only]
            adds: list[Scored] = []
            if len(s.model.effects) < max_effects:
                say(f"round {rounds}: {len(cands)} add moves from {_describe(s.model)}")
                adds = [a for a in map_fn(partial(_add_one, ev, s), cands) if a is not None]
                for a in adds:  # a worker process fills its own cache: keep the better of the two
                    if a.key not in ev.cache or a.criterion < ev.cache[a.key].criterion:
                        ev.cache[a.key] = a
            children += adds
            for eid in s.model.effect_ids:
                if eid in ev.fixed or eid in ev.kept:
                    continue
                d = ev.dropped(s, eid)
                if d is None:
                    continue
                children.append(d)
                for a in sorted(adds, key=lambda t: t.criterion)[:SWAP_WITH]:
                    new = a.model.effect_ids[-1]
                    if new in d.model.effect_ids:
                        continue
                    sw = ev.added(d, new)
                    if sw is not None:
                        children.append(Scored(sw.model, sw.m2ll, sw.penalty, s, f"swap {eid} for {new}"))
        pool: dict[frozenset[str], Scored] = {}
        for c in [*frontier, *children]:
            if c.key not in pool or c.criterion < pool[c.key].criterion:
                pool[c.key] = c
        ranked = sorted(pool.values(), key=lambda t: t.criterion)
        if ranked[0].criterion >= best.criterion - 1e-9 * max(1.0, abs(best.criterion)):
            say(f"round {rounds}: no move lowers the criterion; {_describe(best.model)}")
            break
        best = ranked[0]
        say(f"round {rounds}: {best.move} → {_describe(best.model)} (criterion {best.criterion:.2f})")
        frontier = ranked[:BEAM]
        if rounds > 4 * len(CATALOGUE):  # each round lowers the criterion: cannot cycle; a bound all the same
            break
    # the sets of effects weighed (the same whether the add moves ran here or in workers)
    return SearchResult(best, start, dict(ev.cache), rounds, n_c, len(ev.cache))


def _describe(model: Model) -> str:
    return "+".join(model.effect_ids) or "the base model"


@dataclass(frozen=True)
class Tie:
    """An effect of the best model and the alternatives within the criterion's noise: each the
    model with the effect swapped for another (or dropped: ``None``) and the weights, the named
    one's first."""

    effect_id: str
    alternatives: tuple[tuple[str | None, float], ...]
    weight: float

    def describe(self) -> str:
        alts = " / ".join(f"{a or 'nothing'} {w:.2f}" for a, w in self.alternatives)
        return f"{self.effect_id} {self.weight:.2f} / {alts}"


def ties(result: SearchResult, alpha: float) -> list[Tie]:
    """For each effect of the best model, the scored models that differ from it by that effect
    alone (swapped for another, or dropped) with a criterion within :func:`.criterion.tie_band`:
    their weights against the best (normalised over the group)."""
    best = result.best
    out = []
    band = tie_band(alpha)
    for eid in best.model.effect_ids:
        rest = best.key - {eid}
        group: list[tuple[str | None, float]] = []
        for key, s in result.scored.items():
            extra = key - rest
            if rest <= key and len(extra) <= 1 and key != best.key:
                delta = s.criterion - best.criterion
                if delta < band:
                    group.append((next(iter(extra)) if extra else None, relative_weight(delta)))
        if group:
            total = 1.0 + sum(w for _, w in group)
            out.append(Tie(eid, tuple((a, w / total) for a, w in sorted(group, key=lambda g: -g[1])), 1.0 / total))
    return out
