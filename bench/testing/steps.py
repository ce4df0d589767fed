"""Run steps and procedures without a station: a clock that only counts, a bare station, a step.

``bench.core.procedure.execute`` needs a station with ``instruments``, a ``clock``, a
``config`` and a ``snapshot``; :func:`bare_station` is the least of one, its clock a
:class:`ManualClock` that advances only when a step sleeps. :class:`Count` is a step that needs
a ``meter`` and produces a value per simulated second: enough to exercise a runner (progress,
streams, judging, a failure mid-step) without any instrument.

Examples
--------
>>> import tempfile
>>> from pathlib import Path
>>> from bench.core.procedure import Procedure, execute
>>> from bench.core.store import RunStore
>>> class Counting(Procedure):
...     def setup(self, ctx):
...         ctx.run.add_stream("counts", {"t_s": "s", "value": "1"}, "every value")
...     def teardown(self, ctx):
...         pass
>>> with tempfile.TemporaryDirectory() as folder:
...     store = RunStore(Path(folder) / "bench.sqlite")
...     outcome = execute(Counting("counting", [Count(n=3)]), bare_station(meter=object()), store,
...                       unit_serial="U1", seed=None)
...     store.close()
>>> outcome.status, [(m.name, m.value) for m in outcome.measurements]
('passed', [('total', 6.0)])
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from types import SimpleNamespace
from typing import Any

from bench.core.step import Context, Step, parameter
from bench.values import Estimate


class ManualClock:
    """A clock at 0 s that advances only by what is slept (``bench.core.clock.Clock``)."""

    def __init__(self) -> None:
        self.t = 0.0

    def now(self) -> float:
        return self.t

    def sleep(self, seconds: float) -> None:
        self.t += seconds


def bare_station(**instruments: Any) -> Any:
    """A station with these instruments, a :class:`ManualClock`, no wiring and no site."""
    return SimpleNamespace(instruments=instruments, clock=ManualClock(),
                           config=SimpleNamespace(name="bench", wiring={}, site=None),
                           snapshot=lambda: {"name": "bench"})


@dataclasses.dataclass
class CountParameters:
    n: int = parameter(3, "values to produce")
    fail_at: int = parameter(-1, "raise at this value (-1: never)")

    def validate(self) -> None:
        if not 1 <= self.n <= 10:
            raise ValueError(f"n = {self.n} not in 1..10")


class Count(Step[CountParameters]):
    """Counts: produces ``n`` values, one per simulated second."""

    name = "count"
    requires = ("meter",)
    kinds = ("accelerometer",)
    produces = {"total": ("s", "sum of the values"), "last": ("s", "the last value")}
    Parameters = CountParameters

    def duration_s(self) -> float:
        return float(self.p.n)

    def run(self, ctx: Context) -> Mapping[str, Estimate]:
        total = 0.0
        for k in range(1, self.p.n + 1):
            if k == self.p.fail_at:
                raise RuntimeError(f"meter lost at {k}")
            ctx.clock.sleep(1.0)
            ctx.run.append("counts", t_s=[ctx.clock.now()], value=[k])
            total += k
            ctx.progress(k, self.p.n, f"value {k}")
        return {"total": Estimate(total, 0.5)}  # "last" left out: not produced
