"""Choosing the best among the named candidates (step c of the workflow, after
:mod:`.naming` has fitted and judged each one): deterministic first, a stochastic candidate only
on evidence that the colour is a random process and not a missing waveform (:func:`choose`);
Occam among deterministic ones within a standard error (:func:`parsimonious`)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from bench.discovery import stochastic as sto
from bench.discovery.data import Record

if TYPE_CHECKING:
    from bench.discovery.naming import Candidate

# A stochastic candidate must survive the best deterministic one (see choose).
SURVIVE_P = 1e-6
SURVIVE_FRACTION = 0.1


def jackknife_ratio(num: np.ndarray, den: np.ndarray) -> float:
    """Std error of Σnum/Σden by deleting one block at a time (num, den per block)."""
    k = num.size
    if k < 3:
        return float("nan")
    loo = (num.sum() - num) / np.where(den.sum() - den > 0, den.sum() - den, np.nan)
    return float(np.sqrt((k - 1) / k * np.nansum((loo - np.nanmean(loo)) ** 2)))


def stochastic_in(model) -> list[tuple[str, dict]]:
    """The model's stochastic effects (``Effect.stochastic`` in the catalogue) with their params."""
    from bench.discovery.effects import CATALOGUE  # noqa: PLC0415

    return [(e, p) for e, p in model.effects if CATALOGUE[e].stochastic]


def choose(named: list[Candidate], model, rec: Record, catalogue: dict, kind: str,
            det_p_under=None, alpha: float = 0.05) -> Candidate | None:
    """Deterministic first: the highest held-out score among the named deterministic candidates
    (then :func:`parsimonious`). A named stochastic candidate (best BIC gain of its spectral fit)
    replaces it only if all hold:

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

    Without a named deterministic candidate, the best stochastic one."""
    if not named:
        return None
    det = [c for c in named if not c.stochastic]
    # between stochastic shapes the spectrum decides (BIC on the Whittle likelihood: a
    # Gauss–Markov needs a clearly better fit than a random walk for its extra parameter)
    sto_ = sorted((c for c in named if c.stochastic), key=lambda c: -c.aic_gain)
    if len(sto_) > 1 and sto_[0].id == "gauss_markov" and sto_[1].id == "rate_random_walk" \
            and sto_[0].params.get("tau_s", 0.0) >= rec.duration_s / 5:
        sto_ = [sto_[1], sto_[0]]  # a correlation time beyond the record is a random walk on it
    if not det:
        return sto_[0] if sto_ else None
    d = det[0]
    if not sto_ or d.resid_full is None:
        return d
    s = sto_[0]
    known = stochastic_in(model)
    r0 = rec.y - model.predict(rec)
    lr_d = 2.0 * (sto.white_nll(r0, rec.dt_s, known) - sto.white_nll(d.resid_full, rec.dt_s, known))
    bic_d = lr_d - math.log(rec.n / 2) * len(catalogue[d.id].params_for(kind))
    if s.aic_gain <= bic_d:
        return d
    stype = "gauss_markov" if s.id == "gauss_markov" else "random_walk"
    after = sto.fit_stochastic(d.resid_full - d.resid_full.mean(), rec.dt_s, stype, known=known, bootstrap=False)
    if not (after.p_value < SURVIVE_P and after.lr >= SURVIVE_FRACTION * s.lr):
        return d
    if det_p_under is not None and det_p_under(s, d) < alpha:
        return d
    return s


def parsimonious(best: Candidate | None, named: list[Candidate], blocks: np.ndarray, n_blocks: int,
                  catalogue: dict, kind: str) -> Candidate | None:
    """Among deterministic named candidates whose held-out score is within one (paired, block
    jackknife) standard error of the best's, the one with the fewest parameters (Occam: a long
    warm-up time constant is a drift on a short record)."""
    if best is None or best.stochastic or best.err_c is None:
        return best
    n_par = lambda c: len(catalogue[c.id].params_for(kind))
    pick = best
    for c in named:
        if c.stochastic or c.err_c is None or c.id == best.id or n_par(c) >= n_par(pick):
            continue
        d_num = np.bincount(blocks, c.err_c - best.err_c, n_blocks)
        den = np.bincount(blocks, best.err_b, n_blocks)
        se = jackknife_ratio(d_num, den)
        if np.isfinite(se) and d_num.sum() / den.sum() <= se:
            pick = c
    return pick
