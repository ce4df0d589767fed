"""Turn-on time, warm-up drift and turn-on repeatability from start-up records.

What a user calls::

    turn_on_metrics, TurnOnResult
    turn_on_repeatability, TurnOnRepeatability

The modules behind it are private: import from ``bench.analysis.turn_on``.
"""

from bench.analysis.turn_on._metrics import TurnOnResult, turn_on_metrics
from bench.analysis.turn_on._repeatability import TurnOnRepeatability, turn_on_repeatability

__all__ = ["TurnOnRepeatability", "TurnOnResult", "turn_on_metrics", "turn_on_repeatability"]
