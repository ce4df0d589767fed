"""A *step* is one test that produces named measurements (tumble, rate table, noise,
start-up).  It runs alone as a procedure (``bench run tumble``: every measurement recorded,
no limits) or as part of an acceptance sequence (``bench acceptance``: measurements judged
against a unit spec).

A step declares what it needs and what it produces::

    name = "tumble"
    requires = ("dmm", "supply", "turntable")      # station instruments
    kinds = ("accelerometer",)                      # sensor kinds it applies to
    produces = {"k1": ("mA/g", "scale factor K1"), ...}
    def parameters(self) -> dict                    # validated parameters, for the record
    def duration_s(self) -> float                   # simulated/real time it takes (progress)
    def run(self, ctx) -> dict[str, Estimate]       # streams data; returns produced values
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict
from typing import Any, Protocol

from bench.core.procedure import Context, Limit
from procedures.common import Estimate, level_table, make_safe


class Step(Protocol):
    name: str
    requires: tuple[str, ...]
    kinds: tuple[str, ...]
    produces: Mapping[str, tuple[str, str]]

    def parameters(self) -> dict[str, Any]: ...
    def duration_s(self) -> float: ...
    def run(self, ctx: Context) -> dict[str, Estimate]: ...


class ParameterizedStep:
    """What every step shares: a parameter dataclass (``Parameters``, with ``validate()``),
    built from keywords or given whole, validated at construction, recorded as a dict."""

    Parameters: type

    def __init__(self, params: Any = None, **overrides: Any) -> None:
        if params is not None and overrides:
            raise ValueError("give a parameter object or keywords, not both")
        self.p = params if params is not None else self.Parameters(**overrides)
        self.p.validate()

    def parameters(self) -> dict[str, Any]:
        return asdict(self.p)


def scaled_progress(progress, offset: float, weight: float, total: float, label: str):
    """A progress callback for one step inside a longer sequence (``weight`` of ``total``)."""
    def report(done: float, step_total: float, message: str = "") -> None:
        fraction = min(max(done / step_total, 0.0), 1.0) if step_total > 0 else 1.0
        progress(offset + weight * fraction, total, f"{label}: {message}" if message else label)
    return report


class StepProcedure:
    """Runs one step as a procedure: level, step, record every produced value; safe teardown."""

    def __init__(self, step: Step) -> None:
        self.step = step
        self.name = step.name
        self.requires = tuple(step.requires)

    def parameters(self) -> dict[str, Any]:
        return self.step.parameters()

    def setup(self, ctx: Context) -> None:
        make_safe(ctx)
        if "turntable" in ctx.instruments:
            level_table(ctx)

    def run(self, ctx: Context) -> None:
        results = self.step.run(ctx)
        for name, (unit, description) in self.step.produces.items():
            if name in results:
                est = results[name]
                ctx.measure(name, est.value, unit, Limit(), description, est.std)

    def teardown(self, ctx: Context) -> None:
        make_safe(ctx)
