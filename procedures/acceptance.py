"""Factory acceptance: run what a unit spec needs, judge every measurement, one record.

The spec (``bench.core.spec``) lists procedures in run order with their parameters, and the
measurements with limits.  Each procedure is a step of the catalogue
(``procedures.catalogue``); its produced values are converted to the spec's unit and judged
pass / marginal / fail.  Everything the steps acquire streams into the one run; each step's
fit or analysis is kept in the run's results.  Any fault aborts the sequence through the
runner's abort path (data kept, reason recorded, station left safe).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from bench.core.spec import UnitSpec, convert
from bench.core.step import Catalogue, Context, Limit, Step
from bench.values import Estimate
from procedures.catalogue import CATALOGUE
from procedures.running import StationProcedure


class AcceptanceTest(StationProcedure):
    """A procedure for ``bench.core.procedure.execute``: the spec's steps in order, judged
    against the spec."""

    def __init__(self, spec: UnitSpec, catalogue: Catalogue = CATALOGUE) -> None:
        super().__init__("acceptance", [catalogue.build(name, params)
                                        for name, params in spec.procedures.items()])
        self.spec = spec

    def parameters(self) -> dict[str, Any]:
        return {"spec": self.spec.to_dict(),
                "steps": {s.name: s.parameters() for s in self.steps}}

    def prompt_before(self, step: Step[Any]) -> str | None:
        return self.spec.prompts.get(step.name)

    def setup(self, ctx: Context) -> None:
        super().setup(ctx)
        ctx.run.set_result("acceptance.spec", self.spec.to_dict())

    def judge(self, ctx: Context, step: Step[Any], produced: Mapping[str, Estimate]) -> None:
        """Each of the spec's measurements of ``step`` in the spec's unit against its limits; a
        value the step could not produce fails."""
        for m in self.spec.for_procedure(step.name):
            produced_unit, description = step.produces[m.name]
            est = produced.get(m.name)
            if est is None:
                ctx.measure(m.name, float("nan"), m.unit, Limit(m.low, m.high, m.marginal),
                            f"{m.description} — not produced")
                continue
            value = convert(est.value, produced_unit, m.unit)
            unc = None if est.std is None else abs(convert(est.std, produced_unit, m.unit))
            ctx.measure(m.name, value, m.unit, Limit(m.low, m.high, m.marginal),
                        m.description or description, unc, est.bound)


__all__ = ["AcceptanceTest"]
