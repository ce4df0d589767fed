"""What each add move of the search found (frozen, public: the report, the JSON and the CLI read
these)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from bench.discovery.effects_base import Params


@dataclass(frozen=True)
class Candidate:
    """One add candidate's outcome under the criterion: ``score`` the deviance it saved
    (−2 ln L before minus after), ``score_se`` the penalty it had to beat, ``p_value`` the χ² tail
    of the deviance saved, ``q_value`` that times the criterion's multiplicity (C·M), ``big_enough``
    whether it lowered the criterion, ``named`` whether the search's path took it."""

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
    """All candidates of one add move (the most criterion gained first), the named one (or None),
    its look-alikes within the criterion's noise and how to separate them."""

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
