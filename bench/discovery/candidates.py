"""What the naming step reports (frozen, public: the report, the JSON and the CLI read these)
and the working state it keeps per candidate while judging (:class:`Trial`, internal)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from bench.discovery.effects_base import Effect, Params


@dataclass(frozen=True)
class Candidate:
    """One candidate's outcome: held-out score (variance reduction, ± jackknife se), p-value,
    BH-adjusted q, whether its main parameter reaches the minimum effect size, and whether it
    is named (significant, positive score, big enough)."""

    id: str
    stochastic: bool
    params: Params
    params_std: Params
    score: float
    score_se: float
    p_value: float
    q_value: float = 1.0
    big_enough: bool = False
    min_effect: float = math.nan
    named: bool = False

    def to_dict(self) -> dict:
        return {"id": self.id, "stochastic": self.stochastic, "params": self.params,
                "params_std": self.params_std, "heldout_score": self.score, "heldout_score_se": self.score_se,
                "p_value": self.p_value, "q_value": self.q_value, "big_enough": self.big_enough,
                "min_effect": self.min_effect, "named": self.named}


@dataclass(frozen=True)
class Naming:
    """All candidates (best score first), the named best (or None), close competitors and how
    to separate them; ``set_aside``: catch-alls that would have been chosen but whose own
    signature does not hold on the record (why, and where)."""

    candidates: tuple[Candidate, ...]
    best: Candidate | None
    competitors: tuple[str, ...]
    separating: tuple[str, ...]
    null: str = ("circular moving-block bootstrap of the residual with the candidate's fit taken out "
                 "(linearised regressors)")
    set_aside: tuple[str, ...] = ()
    #: logged columns a set-aside catch-all's innovations still followed
    followed_columns: tuple[str, ...] = ()

    def to_dict(self) -> dict:
        return {"best": None if self.best is None else self.best.to_dict(),
                "competitors": list(self.competitors), "separating_experiments": list(self.separating),
                "candidates": [c.to_dict() for c in self.candidates], "null": self.null,
                "set_aside": list(self.set_aside)}


@dataclass(frozen=True, eq=False)
class Trial:
    """A candidate as fitted, before it is judged: the effect, its parameters ± std, held-out
    score and p-value, and what judging and choosing need of the fit (none of it reported).

    ``err_c`` / ``err_b``: per-sample held-out squared errors with the candidate and without it
    (None for a histogram-judged effect: no per-block errors). A waveform fit adds
    ``resid_full`` (y − the fitted prediction), ``cols`` (per fold, its linearised regressors)
    and ``lin`` (their held-out score, the bootstrap's statistic); a random process ``lr`` (its
    likelihood-ratio statistic against the model's noise) and ``bic_gain`` (lr − ln(n/2)·its
    parameters), and when its shape is a close call with another process's ``shape_bic`` (the
    exact likelihood's, :func:`.stochastic.exact_shape_bic`: the order among those)."""

    effect: Effect
    params: Params
    params_std: Params
    score: float
    p_value: float
    err_c: np.ndarray | None = field(default=None, repr=False)
    err_b: np.ndarray | None = field(default=None, repr=False)
    resid_full: np.ndarray | None = field(default=None, repr=False)
    cols: list[np.ndarray] | None = field(default=None, repr=False)
    lin: float = math.nan
    lr: float = math.nan
    bic_gain: float = math.nan
    shape_bic: float = math.nan

    @property
    def id(self) -> str:
        return self.effect.id
