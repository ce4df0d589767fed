"""Procedures on a station: steps between a safe, level start and a safe end.

:class:`StationProcedure` is the procedure every run on a station is: its set-up makes the
station safe (``make_safe``) and levels the turntable when there is one; its teardown —
always, whatever happened — makes it safe again.  :func:`alone` is one step run that way
(``bench run <step>``: every value it produces recorded, no limits);
``procedures.acceptance.AcceptanceTest`` is the spec's steps run that way and judged.
"""

from __future__ import annotations

from typing import Any

from bench.core.procedure import Procedure
from bench.core.step import Context, Step
from procedures.common import level_table, make_safe


class StationProcedure(Procedure):
    """Steps in order on a station made safe and level first and left safe at the end."""

    def setup(self, ctx: Context) -> None:
        make_safe(ctx)
        if "turntable" in ctx.instruments:
            level_table(ctx)

    def teardown(self, ctx: Context) -> None:
        make_safe(ctx)


def alone(step: Step[Any]) -> StationProcedure:
    """``step`` as a procedure of its own, named after it (``bench run <step>``)."""
    return StationProcedure(step.name, (step,))


__all__ = ["StationProcedure", "alone"]
