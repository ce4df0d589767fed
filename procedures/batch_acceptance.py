"""Factory acceptance of a fixture of units at once: the spec's steps run as a batch
(``procedures.batch_steps``), each socket judged against the spec into its own record.

The set-up (station safe, table level) and the teardown (station safe) run once for the
batch; the spec, the judging and the record of each unit are those of a single unit's
acceptance (``procedures.acceptance``), so a socket's run is an ``acceptance`` run like any
other and the reports read it unchanged.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from bench.core.batch import BatchProcedure, BatchStep
from bench.core.spec import UnitSpec
from bench.core.step import Catalogue, Context
from bench.values import Estimate
from procedures.acceptance import AcceptanceTest
from procedures.batch_steps import BATCHED
from procedures.catalogue import CATALOGUE
from procedures.common import level_table, make_safe


class BatchAcceptance(BatchProcedure):
    """A unit spec's steps for a fixture of units, each judged against the spec."""

    def __init__(self, spec: UnitSpec, catalogue: Catalogue = CATALOGUE) -> None:
        self.single = AcceptanceTest(spec, catalogue)  # the steps built and validated as for one unit
        missing = [s.name for s in self.single.steps if s.name not in BATCHED]
        if missing:
            raise ValueError(f"spec {spec.model!r}: step(s) {missing} cannot run on a fixture "
                             f"of sockets; batch steps: {sorted(BATCHED)}")
        super().__init__("acceptance", [BATCHED[s.name](s) for s in self.single.steps])
        self.spec = spec

    def parameters(self) -> dict[str, Any]:
        return {**self.single.parameters(), "batch": True}

    def prompt_before(self, step: BatchStep) -> str | None:
        return self.single.prompt_before(step.step)

    def setup(self, shared: Context) -> None:
        make_safe(shared)
        level_table(shared)
        shared.run.set_result("acceptance.spec", self.spec.to_dict())

    def teardown(self, shared: Context) -> None:
        make_safe(shared)

    def judge(self, unit: Context, step: BatchStep, produced: Mapping[str, Estimate]) -> None:
        self.single.judge(unit, step.step, produced)


__all__ = ["BatchAcceptance"]
