"""Choosing the best among the named candidates (step c of the workflow, after
:mod:`.naming` has fitted and judged each one): a catch-all only on the evidence of its own
signature (:func:`choose`); deterministic first, localized explanations before any process, a
stochastic candidate only on evidence that the colour is a random process and not a missing
waveform — the deterministic candidate judged also against the process that, fitted beside it,
explains the record best together with it (:func:`preferred`, :func:`joint_alternative`); Occam
among deterministic ones within a standard error (:func:`parsimonious`)."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np

from bench.discovery import stochastic as sto
from bench.discovery.candidates import Trial
from bench.discovery.data import Record
from bench.discovery.effects import CATALOGUE
from bench.discovery.effects_base import MIN_SNR
from bench.discovery.effects_noise import Processes
from bench.discovery.evidence import Evidence
from bench.discovery.model import Model
from bench.discovery.significance import score_difference

# A stochastic candidate must survive the best deterministic one (see choose).
SURVIVE_P = 1e-6
SURVIVE_FRACTION = 0.1


def choose(named: Sequence[Trial], model: Model, rec: Record, kind: str,
           det_p_under: Callable[[Trial, Trial], float] | None = None, alpha: float = 0.05,
           holds: Callable[[Trial, Trial | None], Evidence] | None = None,
           tie: Callable[[Trial, Trial], bool] | None = None,
           pair: Callable[[Trial, Trial], np.ndarray | None] | None = None,
           ) -> tuple[Trial | None, tuple[Evidence, ...]]:
    """The best of the named candidates and the catch-alls set aside on the way.

    A catch-all (``Effect.catch_all``: a random process, a drift) is named only on the evidence
    of its own signature: ``holds(trial, beside)`` (:mod:`.evidence`; ``beside``: the process
    :func:`preferred`'s look-ahead fitted beside it, part of the noise it is judged against, or
    None) — a catch-all that would be chosen
    but whose signature does not hold is set aside (its evidence returned) and the choice made
    again among the others; when none is left, nothing is named (its structure is reported as
    unexplained). Among the rest, :func:`preferred` (``tie`` and ``pair`` passed on)."""
    remaining = list(named)
    rejected: list[Evidence] = []
    while remaining:
        pick, beside = preferred(remaining, model, rec, kind, det_p_under, alpha, tie, pair)
        if pick is None:
            break
        if holds is not None and pick.effect.catch_all:
            ev = holds(pick, beside)
            if not ev.holds:
                rejected.append(ev)
                remaining = [t for t in remaining if t is not pick]
                continue
        return pick, tuple(rejected)
    return None, tuple(rejected)


def preferred(named: Sequence[Trial], model: Model, rec: Record, kind: str,
              det_p_under: Callable[[Trial, Trial], float] | None = None,
              alpha: float = 0.05, tie: Callable[[Trial, Trial], bool] | None = None,
              pair: Callable[[Trial, Trial], np.ndarray | None] | None = None,
              ) -> tuple[Trial | None, Trial | None]:
    """Deterministic first: the highest held-out score among the named deterministic candidates
    (then :func:`parsimonious`). A localized one (``Effect.localized``: a jump, a warm-up once
    power-on is logged) is tested first: a random process replaces it only when it is not
    significant against a null that includes the process, and it does not explain the record
    better than the process on their common likelihood (its BIC gain defined below above the
    process's by ``MIN_SNR²``: a walk fitted alone grows to follow a warm-up, and against that
    walk the warm-up looks typical) — nor, explaining more than the process at all, leaves
    nothing of the process's evidence beside it (the process refitted to its residual is not
    significant, p ≥ ``alpha``; a walk of 6e-8 g/√s made two 3e-6-g jumps look typical and
    vanished beside them, p = 1; level steps explaining more are taken at once: a process that
    holds beside them is named next, and ``workflow.unjumped`` weighs both against one process
    alone once the names are in). A localized candidate has this turn even when a non-localized
    one scored above it and lost to the process (a temperature bias scored 0.01 above two jumps
    a walk had taken). When it is the process's, a named non-localized
    deterministic candidate whose held-out score ties with it (``tie(localized, other)``: within
    one paired standard error) is judged in its place (three jumps along a Gauss–Markov's wander
    scored 0.001 above a temperature term) — not one it clearly out-scored (a temperature term
    that follows a start-up's warming is not judged for the two-node transient a walk made look
    typical). Any other is replaced by a named stochastic candidate (best BIC gain of its
    spectral fit) only if all hold:

    * it explains more: its BIC gain over the model's noise (Whittle likelihood ratio −
      ln(n/2)·parameters) exceeds the deterministic one's on the same likelihood (the white +
      known-stochastic Whittle likelihood of the residual before and after the deterministic
      fit, less ln(n/2) per parameter). A missing waveform that leaves the residual
      coloured (a delay, a saturation) explains far more as itself than as noise colour;
    * the deterministic candidate is NOT significant (p ≥ ``alpha``, ``det_p_under``; the
      caller passes alpha / number of candidates) when the
      null is the model's noise plus the stochastic candidate: a drift that a random walk
      produces anyway is not evidence of a drift, whereas a temperature or input term stays
      significant against any noise that ignores temperature and input — the colour then came
      from the waveform (two missing terms colour the residual more than one removes);
    * it survives the deterministic fit: refitted to the residual that fit leaves it stays
      clearly significant (p < ``SURVIVE_P``) and keeps a tenth of its likelihood-ratio
      statistic (a random walk stays a random walk once a straight line is removed).

    When all three hold, a look-ahead (:func:`joint_alternative`): a named process of another
    shape that, fitted beside the deterministic candidate, makes the best joint explanation of
    the record (above the best process alone and above the deterministic one beside it) becomes
    the null instead — at its parameters beside it — and if the deterministic candidate is
    significant against that null it is chosen after all (a Gauss–Markov that loses to flicker or
    a walk alone only because, fitted alone, it stretched its correlation time to take a drift or
    temperature term beside it).

    Returns (the choice, the process fitted beside it or None): a deterministic (non-localized)
    catch-all (a drift: the only choice whose signature :func:`choose` judges) chosen over named
    processes comes with the one that, fitted to the residual it leaves, makes
    the best joint explanation and is clearly significant there (the look-ahead's, or else
    :func:`joint_alternative` over all of them) — the process named next; :func:`choose` judges
    the choice's signature with that process in the noise, as the joint explanation claims (the
    wander beside a drift is then that process, not the drift's misfit).

    Before a process is chosen over the named deterministic candidates, two of them together
    (:func:`pair_over_process`, ``pair``: the residual with both fitted beside the model) may
    explain what neither does alone (a temperature bias and a drift, each weaker than the walk
    that follows their sum).

    Without a named deterministic candidate, the best stochastic one. (Between stochastic
    shapes the spectrum decides: BIC on the Whittle likelihood, so a Gauss–Markov needs a
    clearly better fit than a random walk for its extra parameter; one whose parameters the
    record cannot resolve — ``Effect.identifiable`` — was not named; shapes within a few units
    of each other are ordered by their exact likelihood, ``Trial.shape_bic``.)"""
    if not named:
        return None, None
    det = [c for c in named if not c.effect.stochastic]
    sto_ = sorted((c for c in named if c.effect.stochastic), key=lambda c: -c.bic_gain)
    close = sorted((c for c in sto_ if math.isfinite(c.shape_bic)), key=lambda c: -c.shape_bic)
    if len(close) > 1:  # a close call of shape: the exact likelihood's order (naming.shape_ranked)
        sto_ = close + [c for c in sto_ if not math.isfinite(c.shape_bic)]
    if not det:
        return (sto_[0] if sto_ else None), None
    if not sto_ or det[0].resid_full is None:
        return det[0], None
    s = sto_[0]
    known = model.stochastic_effects()
    white0 = sto.white_nll(rec.y - model.predict(rec), rec.dt_s, known)
    failed: Trial | None = None  # the first localized candidate the process made look typical
    coloured = model.colours_residual()
    lost = False  # a non-localized candidate lost to the process: the localized ones still have their turn
    for d in det:
        if d.resid_full is None:
            continue
        if failed is not None and d.effect.localized(rec):
            continue  # another localized shape for the structure the process made look typical
        if failed is not None and (tie is None or not tie(failed, d)):
            break
        if lost and not d.effect.localized(rec):
            continue
        lr_d = 2.0 * (white0 - sto.white_nll(d.resid_full, rec.dt_s, known))
        bic_d = lr_d - math.log(rec.n / 2) * len(d.effect.params_for(kind))
        r_d = d.resid_full - d.resid_full.mean()
        if not d.effect.localized(rec):
            pick, beside = _versus_process(d, s, sto_, rec, kind, known, bic_d, r_d, det_p_under, alpha)
            if pick is s:
                # a localized explanation scored below it is still tested first (a temperature
                # bias lost to a walk that had taken two jumps, scored 0.01 above them)
                lost = True
                continue
            return pick, beside
        if det_p_under is None or det_p_under(s, d) < alpha:
            return d, None
        if coloured:
            # behind a coarse quantizer a process crossing its steps reads as steps and the
            # Gaussian likelihoods below do not hold: the null drawn through it has decided
            failed = failed or d
            continue
        # the process fitted alone took the term's structure (a walk's level grown to follow a
        # warm-up) and makes it look typical; on the common likelihood the term alone explains
        # the record clearly better than that process (by the size gate, MIN_SNR²: a jump's times
        # are searched, which the BIC's ln(n/2) a parameter does not count — three jumps along a
        # Gauss–Markov's wander came 10-24 above it). Not the term with a process beside it: a
        # walk's levels periodogram leaks at the record's ends, and a warm-up fitted to a walk's
        # first excursion "improved" the walk's own likelihood by 57 on a record of a walk alone
        if bic_d > s.bic_gain + MIN_SNR ** 2:
            return d, None
        # level steps (jumps) that explain more than the process on their common likelihood: a
        # process that holds beside them is named next, and once the names are in
        # workflow.unjumped weighs the steps and processes against one process alone (three jumps
        # beside a real Gauss–Markov lost here to a walk that stayed significant beside them)
        if bic_d > s.bic_gain and d.effect.level_steps:
            return d, None
        # another term (a warm-up) explains more than the process, and the process refitted beside
        # it is not significant there at all (p ≥ alpha): its colour was the term's (the stricter
        # test of a non-localized term — p < SURVIVE_P and a tenth of its statistic kept — named a
        # term for a walk's wander, and the walk was named beside it at the next step)
        if bic_d > s.bic_gain:
            after = sto.fit_stochastic(r_d, rec.dt_s, s.effect, known=known, bootstrap=False)
            if after.p_value >= alpha:
                return d, None
        failed = failed or d
        # the process explains this one (jumps along a walk's wander): a deterministic
        # candidate that ties with it has its turn (a temperature term scored a hair below them)
    return pair_over_process(det, s, rec, kind, known, white0, pair, alpha) or s, None


#: Deterministic candidates (non-localized, by held-out score) whose pairs
#: :func:`pair_over_process` weighs.
PAIR_TOP = 3


def pair_over_process(det: Sequence[Trial], s: Trial, rec: Record, kind: str, known: Processes, white0: float,
                      pair: Callable[[Trial, Trial], np.ndarray | None] | None, alpha: float) -> Trial | None:
    """Of the first :data:`PAIR_TOP` named non-localized waveform candidates (``det``, held-out
    order), the pair that, fitted together beside the model (``pair(a, b)``: the residual, or
    None when the joint fit fails), explains the record better than process ``s`` by the size
    gate on their common likelihood (BIC gain on the white + known-stochastic Whittle likelihood,
    ``white0`` the model's, above ``s``'s by ``MIN_SNR²``) and leaves nothing of the process's
    evidence (refitted to that residual it is not significant, p ≥ ``alpha``): its member with
    the better held-out score — or the one that is not a catch-all, whose signature its partner
    would break (named now; the other is then judged beside it). None when there
    is no such pair. A walk follows the sum of two slow terms better than either alone (a
    temperature bias and a drift beside a two-node warm-up: each 0.12–0.14 held-out against the
    walk's 0.25), so each term alone lost to it."""
    if pair is None:
        return None
    top = [d for d in det if d.resid_full is not None and d.effect.waveform and not d.effect.localized(rec)]
    top = top[:PAIR_TOP]
    weight = math.log(rec.n / 2)
    best: tuple[float, Trial] | None = None
    for i, a in enumerate(top):
        for b in top[i + 1:]:
            if b.id in CATALOGUE.look_alikes(a.id):
                continue
            r_ab = pair(a, b)
            if r_ab is None:
                continue
            lr = 2.0 * (white0 - sto.white_nll(r_ab, rec.dt_s, known))
            bic = lr - weight * (len(a.effect.params_for(kind)) + len(b.effect.params_for(kind)))
            if not bic > s.bic_gain + MIN_SNR ** 2 or (best is not None and bic <= best[0]):
                continue
            after = sto.fit_stochastic(r_ab - r_ab.mean(), rec.dt_s, s.effect, known=known, bootstrap=False)
            if after.p_value >= alpha:
                # a catch-all (a drift) is judged on its own signature, which its partner breaks
                # until it is named: the other member first
                best = (bic, b if a.effect.catch_all and not b.effect.catch_all else a)
    return None if best is None else best[1]


def _versus_process(d: Trial, s: Trial, sto_: Sequence[Trial], rec: Record, kind: str, known: Processes,
                    bic_d: float, r_d: np.ndarray, det_p_under: Callable[[Trial, Trial], float] | None,
                    alpha: float) -> tuple[Trial, Trial | None]:
    """:func:`preferred`'s judgement of a non-localized deterministic candidate ``d`` against the
    best named process ``s`` (the three conditions and the look-ahead of its docstring)."""

    def with_companion() -> tuple[Trial, Trial | None]:
        # d chosen over the processes: what it leaves may still hold one (named next), in the
        # noise of d's signature — judged only for a catch-all, so only then fitted
        if not d.effect.catch_all:
            return d, None
        return d, joint_alternative(r_d, sto_, rec, kind, known, bic_d, floor=bic_d)
    if s.bic_gain <= bic_d:
        return with_companion()
    after = sto.fit_stochastic(r_d, rec.dt_s, s.effect, known=known, bootstrap=False)
    if not (after.p_value < SURVIVE_P and after.lr >= SURVIVE_FRACTION * s.lr):
        return with_companion()
    if det_p_under is not None and det_p_under(s, d) < alpha:
        return with_companion()
    beside = joint_alternative(r_d, sto_[1:], rec, kind, known, bic_d,
                               floor=max(s.bic_gain, bic_d + after.lr - (s.lr - s.bic_gain)))
    if beside is not None and det_p_under is not None and det_p_under(beside, d) < alpha:
        return d, beside
    return s, None


def joint_alternative(r_d: np.ndarray, processes: Sequence[Trial], rec: Record, kind: str, known: Processes,
                      bic_d: float, floor: float) -> Trial | None:
    """The process of ``processes`` that, fitted beside a deterministic candidate (to ``r_d``, the
    residual its fit leaves, mean removed), makes the best joint explanation of the record: joint
    BIC gain ``bic_d`` + its likelihood-ratio statistic there − ln(n/2) per coordinate (the same
    white + known-stochastic Whittle likelihood) above ``floor`` and clearly significant there
    (p < ``SURVIVE_P``) — returned with its parameters beside the candidate (clipped to the kind's
    ranges), if the record resolves them (``Effect.identifiable``); None when there is none.

    A process fitted alone takes whatever slow structure the record has: a Gauss–Markov whose
    correlation time grows to absorb a drift beside it loses to a walk or flicker alone, and a
    null holding that stretched process makes the drift look typical. Fitted beside the drift it
    keeps its own correlation time: :func:`preferred` judges the drift against that, and the
    drift's signature is judged with it in the noise."""
    best, best_gain = None, floor
    for c in processes:
        fit = sto.fit_stochastic(r_d, rec.dt_s, c.effect, known=known, bootstrap=False)
        gain = bic_d + fit.lr - (c.lr - c.bic_gain)  # its own penalty: ln(n/2) per coordinate
        if gain > best_gain and fit.p_value < SURVIVE_P and c.effect.identifiable(fit.params, rec):
            best, best_gain = replace(c, params=fit.params_for(kind)), gain
    return best


def parsimonious(best: Trial | None, named: Sequence[Trial], blocks: np.ndarray, n_blocks: int,
                 kind: str, noise_sd: float = 0.0,
                 refitted_sse: Callable[[Trial], float] | None = None,
                 rec: Record | None = None,
                 colour: Callable[[], Callable[[np.ndarray], np.ndarray] | None] | None = None) -> Trial | None:
    """Among deterministic named candidates whose held-out score is within one (paired, block
    jackknife) standard error of the best's, the one with the fewest parameters (Occam: a long
    warm-up time constant is a drift on a short record) — unless the best explains, in-sample,
    more than ``MIN_SNR²·noise_sd²`` beyond it: what the richer shape adds is then an effect of
    its own size (a two-node warm-up's fast node lives in the first blocks of the record, where
    held-out blocks barely see it). That gain — here and in the nesting rule below — is judged on
    ``refitted_sse`` when given — the sum of squares with the model's other effects refitted
    beside each shape: a shape that nests the pick also absorbs the error an earlier effect was
    fitted with (a temperature scale factor fitted
    before a warm-up was known: two nodes explained 30 σ² more than one — the gate is 25 — and
    12 once both had the scale factor refitted). With ``rec``, a candidate with as many free
    parameters as the held-out best (``Effect.free_params``: a jump's used slots), within one
    standard error of it held-out, that explains more than the same gate beyond it in-sample —
    both refitted — replaces it (the first such by held-out score): held-out blocks hide a
    jump's time when they hold it, and a warm-up of the same size scored a hair above it.

    ``colour``: gives (asked only when two nested shapes are weighed) the map of a residual to
    its standardized innovations under a named random process the model does not hold yet, or
    None (:func:`.naming.colour_beside`). A shape and the one it nests (a
    two-node and a one-node warm-up) are then weighed in them as well: what the richer adds must
    pass the gate, ``MIN_SNR²`` innovation variances, there too — beside a walk a two-node's
    second node gained more than 25 white variances on a warm-up by following the wander.
    Shapes that do not nest each other keep the white-noise gate alone (early in the loop the
    "process" is often the colour of terms still missing: a hysteresis lost to a temperature
    rate when every comparison was whitened)."""
    if best is None or best.effect.stochastic or best.err_c is None or best.err_b is None:
        return best

    def n_par(c: Trial) -> int:
        return len(c.effect.params_for(kind))

    def sse(c: Trial) -> float:
        return float(np.sum((c.resid_full - c.resid_full.mean()) ** 2)) if c.resid_full is not None else math.inf

    gate = MIN_SNR ** 2 * noise_sd ** 2

    def whitened_gain(simple: Trial, rich: Trial) -> float:
        """What ``rich`` adds to ``simple`` in-sample in the innovations of the named process
        (``colour``; inf without one: the white-noise gate alone decides)."""
        whiten = colour() if colour is not None else None
        if whiten is None or simple.resid_full is None or rich.resid_full is None:
            return math.inf
        return float(np.sum(whiten(simple.resid_full - simple.resid_full.mean()) ** 2)
                     - np.sum(whiten(rich.resid_full - rich.resid_full.mean()) ** 2))
    pick = best
    for c in named:
        if c.effect.stochastic or c.err_c is None or c.id == best.id or n_par(c) >= n_par(pick):
            continue
        diff, se = score_difference(best.err_c, c.err_c, best.err_b, blocks, n_blocks)
        if not (np.isfinite(se) and diff <= se):
            continue
        if noise_sd > 0 and sse(c) - sse(best) > gate and (
                refitted_sse is None or refitted_sse(c) - refitted_sse(best) > gate) and not (
                c.id in best.effect.nests and whitened_gain(c, best) <= MIN_SNR ** 2):
            continue
        pick = c
    # as many free parameters, a tie held-out: the one that explains more than the size gate
    # beyond the pick in-sample (both refitted) is the better name — a jump at 0.73 s of a 6-s
    # record out-fitted a warm-up of τ 0.73 s by 43 white variances, their held-out scores
    # 0.009 apart on a standard error of 0.024 (a held-out block that holds the jump hides its time)
    if rec is not None and noise_sd > 0 and refitted_sse is not None and pick is best:
        def n_free(c: Trial) -> int:
            return len(c.effect.free_params(c.params, kind, rec))
        for c in named:
            if (c.effect.stochastic or c.err_c is None or c.id == pick.id or c.resid_full is None
                    or n_free(c) != n_free(pick)):
                continue
            diff, se = score_difference(best.err_c, c.err_c, best.err_b, blocks, n_blocks)
            if np.isfinite(se) and diff <= se and refitted_sse(pick) - refitted_sse(c) > gate:
                pick = c
                break
    # a named shape that holds the pick as a special case (Effect.nests) and adds more than the
    # size gate to it in-sample is the better name, whatever the held-out blocks say — judged in
    # the innovations of a named process beside the pick when there is one (``colour``: what
    # the richer shape adds must not be the process's wander)
    for c in named:
        if pick.id in c.effect.nests and noise_sd > 0 and sse(pick) - sse(c) > gate:
            if refitted_sse is None or refitted_sse(pick) - refitted_sse(c) > gate:
                if whitened_gain(pick, c) <= MIN_SNR ** 2:
                    continue
                pick = c
    return pick
