"""Factory statistics: yield with its interval, control charts, and the decision risk of a limit.

:func:`wilson_interval` puts a confidence interval on a proportion from counts (a yield, a
false-accept rate). :func:`individuals_chart` and :func:`xbar_r_charts` draw Shewhart control
charts of production results and flag the Western Electric rules (:func:`western_electric`,
:data:`RULES`). :func:`decision_risk` judges a pass/fail limit against known true values:
probability of false accept and false reject, counted and modelled, and the guard band that
holds false accept to the ANSI/NCSL Z540.3 target; :func:`overall_risk` does the same over
all of a unit's parameters.

What a user calls::

    individuals_chart, xbar_r_charts, western_electric, ControlChart, RULES
    decision_risk, overall_risk, inside, DecisionRisk
    wilson_interval, Proportion

The modules behind it are private: import from ``bench.analysis.quality``.
"""

from bench.analysis.quality._control_chart import (
    RULES,
    ControlChart,
    individuals_chart,
    western_electric,
    xbar_r_charts,
)
from bench.analysis.quality._decision_risk import DecisionRisk, decision_risk, inside, overall_risk
from bench.analysis.quality._proportion import Proportion, wilson_interval

__all__ = [
    "ControlChart",
    "DecisionRisk",
    "Proportion",
    "RULES",
    "decision_risk",
    "individuals_chart",
    "inside",
    "overall_risk",
    "western_electric",
    "wilson_interval",
    "xbar_r_charts",
]
