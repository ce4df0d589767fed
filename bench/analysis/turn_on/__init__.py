"""Turn-on time, warm-up drift and turn-on repeatability from start-up records.

:func:`turn_on_metrics` reads one start-up record (output against time from power-on): the
settled value, the time from which a moving average stays within a band of it, and the
warm-up drift of the fitted start-up trend. :func:`turn_on_repeatability` takes the biases of
K power cycles with their within-run uncertainties and returns the turn-on to turn-on
repeatability (IEEE Std 952 / 1293) with the within-run noise removed (Paule–Mandel, Q-profile
intervals), optionally split into within-day and day-to-day parts.

What a user calls::

    turn_on_metrics, TurnOnResult
    turn_on_repeatability, TurnOnRepeatability

The modules behind it are private: import from ``bench.analysis.turn_on``.
"""

from bench.analysis.turn_on._metrics import TurnOnResult, turn_on_metrics
from bench.analysis.turn_on._repeatability import TurnOnRepeatability, turn_on_repeatability

__all__ = ["TurnOnRepeatability", "TurnOnResult", "turn_on_metrics", "turn_on_repeatability"]
