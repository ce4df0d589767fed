"""Factory acceptance: run what a unit spec needs, judge every measurement, one record.

The spec (``bench.core.spec``) lists procedures in run order with their parameters, and the
measurements with limits.  Each procedure is a step (``procedures.steps``); its produced
values are converted to the spec's unit and judged pass / marginal / fail.  Everything the
steps acquire streams into the one run; each step's fit or analysis is kept in the run's
results under ``<step>.*``.  Any fault aborts the sequence through the runner's abort path
(data kept, reason recorded, station left safe).
"""

from __future__ import annotations

import dataclasses
from typing import Any

from bench.core.procedure import Context, Limit
from bench.core.spec import CatalogueEntry, UnitSpec, convert
from procedures.common import level_table, make_safe
from procedures.noise import AccelerometerNoise, GyroNoise
from procedures.ratetable import RateTableCalibration
from procedures.steps import Step, scaled_progress
from procedures.tumble import TumbleCalibration
from procedures.turn_on import GyroTurnOnTest, TurnOnTest
from procedures.vibration import VibrationTest

#: step name → step class (constructed with the spec's parameter table as keywords)
STEPS: dict[str, type] = {
    "startup": TurnOnTest,
    "gyro_startup": GyroTurnOnTest,
    "tumble": TumbleCalibration,
    "ratetable": RateTableCalibration,
    "accelerometer_noise": AccelerometerNoise,
    "gyro_noise": GyroNoise,
    "vibration": VibrationTest,
}


def _build(cls: type, params: dict[str, Any]):
    allowed = [f.name for f in dataclasses.fields(cls.Parameters)]
    unknown = sorted(set(params) - set(allowed))
    if unknown:
        raise ValueError(f"unknown parameter(s) {unknown}; allowed: {allowed}")
    return cls(**params)


def _checker(cls: type):
    def check(params: dict[str, Any]) -> None:
        _build(cls, params)
    return check


def _producible(cls: type):
    def producible(params: dict[str, Any]) -> set[str]:
        step = _build(cls, params)
        return step.producible() if hasattr(step, "producible") else set(cls.produces)
    return producible


#: what each step offers a spec (measurements, sensor kinds, parameter check, what a given
#: parameter set can produce — e.g. a 4-position tumble cannot separate K3 from K1)
CATALOGUE: dict[str, CatalogueEntry] = {
    name: CatalogueEntry(cls.produces, cls.kinds, _checker(cls), _producible(cls))
    for name, cls in STEPS.items()
}


def make_step(name: str, params: dict[str, Any]) -> Step:
    if name not in STEPS:
        raise ValueError(f"procedure {name!r} unknown; known: {sorted(STEPS)}")
    return _build(STEPS[name], params)


class AcceptanceTest:
    """A procedure for ``bench.core.procedure.execute``: the spec's steps in order."""

    name = "acceptance"

    def __init__(self, spec: UnitSpec) -> None:
        self.spec = spec
        self.steps = [make_step(name, params) for name, params in spec.procedures.items()]
        self.requires = tuple(sorted({r for s in self.steps for r in s.requires}))

    def parameters(self) -> dict[str, Any]:
        return {"spec": self.spec.to_dict(),
                "steps": {s.name: s.parameters() for s in self.steps}}

    def setup(self, ctx: Context) -> None:
        make_safe(ctx)
        level_table(ctx)
        ctx.run.set_result("acceptance.spec", self.spec.to_dict())

    def run(self, ctx: Context) -> None:
        total = sum(s.duration_s() for s in self.steps)
        done = 0.0
        outer = ctx.progress
        for step in self.steps:
            ctx.run.event(ctx.clock.now(), "step_start", step.name)
            ctx.progress = scaled_progress(outer, done, step.duration_s(), total, step.name)
            try:
                results = step.run(ctx)
            finally:
                ctx.progress = outer
            done += step.duration_s()
            ctx.run.event(ctx.clock.now(), "step_end", step.name)
            for m in self.spec.for_procedure(step.name):
                produced_unit, description = step.produces[m.name]
                est = results.get(m.name)
                if est is None:  # a step that could not produce a spec'd value fails it
                    ctx.measure(m.name, float("nan"), m.unit, Limit(m.low, m.high, m.marginal),
                                f"{m.description} — not produced")
                    continue
                value = convert(est.value, produced_unit, m.unit)
                unc = None if est.std is None else abs(convert(est.std, produced_unit, m.unit))
                ctx.measure(m.name, value, m.unit, Limit(m.low, m.high, m.marginal),
                            m.description or description, unc)
        ctx.progress(total, total, "done")

    def teardown(self, ctx: Context) -> None:
        make_safe(ctx)
