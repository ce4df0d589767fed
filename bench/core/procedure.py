"""Running steps: a procedure's set-up, its steps, a teardown that always runs, one run record.

A **procedure** (:class:`Procedure`) is what the runner (:func:`execute`) runs: one step
(``bench.core.step``) or a sequence of them, between a set-up that brings the station to its
start state and a teardown that always runs and leaves it safe, with a *judge* that turns
each step's produced values into the run's measurements (on its own: every value, no limits;
in acceptance: against the unit spec's limits).  The run's status follows from the
measurements:

* ``passed``  – every measurement inside its limits,
* ``failed``  – at least one outside,
* ``aborted`` – an exception (instrument error, limit violation by the station, Ctrl-C):
  the reason and the time of the last good sample are kept with everything acquired.
"""

from __future__ import annotations

import traceback
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

from bench.core.clock import Clock
from bench.core.operator import Operator, OperatorAbort, Unattended
from bench.core.site import DEFAULT_SITE
from bench.core.step import Context, Limit, Measurement, Progress, Step, no_progress
from bench.core.store import RunStore
from bench.core.version import code_version
from bench.values import Estimate


def scaled_progress(progress: Progress, offset: float, weight: float, whole: float,
                    label: str) -> Progress:
    """A progress callback for one step inside a longer sequence (``weight`` of ``whole``)."""
    def report(done: float, total: float, message: str = "") -> None:
        fraction = min(max(done / total, 0.0), 1.0) if total > 0 else 1.0
        progress(offset + weight * fraction, whole, f"{label}: {message}" if message else label)
    return report


class Procedure(ABC):
    """What the runner runs: ``steps`` in order, between :meth:`setup` (the station to its
    start state) and :meth:`teardown` (always runs: the station left safe); :meth:`judge`
    turns each step's produced values into measurements."""

    def __init__(self, name: str, steps: Sequence[Step[Any]]) -> None:
        if not steps:
            raise ValueError(f"procedure {name!r} has no steps")
        self.name = name
        self.steps = tuple(steps)

    @property
    def requires(self) -> tuple[str, ...]:
        return tuple(sorted({r for s in self.steps for r in s.requires}))

    def parameters(self) -> dict[str, Any]:
        """The run's recorded parameters: a step's own when it runs alone, each step's by name
        in a sequence."""
        if len(self.steps) == 1:
            return self.steps[0].parameters()
        return {s.name: s.parameters() for s in self.steps}

    def duration_s(self) -> float:
        return sum(s.duration_s() for s in self.steps)

    @abstractmethod
    def setup(self, ctx: Context) -> None:
        """Bring the station to the start state the steps expect."""

    @abstractmethod
    def teardown(self, ctx: Context) -> None:
        """Leave the station safe; runs whatever happened, and should try everything."""

    def judge(self, ctx: Context, step: Step[Any], produced: Mapping[str, Estimate]) -> None:
        """Record what ``step`` produced as measurements: by default every produced value in
        its own unit, without limits (a step run on its own)."""
        for name, (unit, description) in step.produces.items():
            if name in produced:
                est = produced[name]
                ctx.measure(name, est.value, unit, Limit(), description, est.std, est.bound)

    def prompt_before(self, step: Step[Any]) -> str | None:
        """What the operator is asked before ``step`` (None: nothing); a spec's prompts."""
        return None

    def run(self, ctx: Context) -> None:
        """Each step in turn, its progress a share of the whole, bracketed by events, judged;
        the operator prompted first where the procedure says (``prompt_before``)."""
        total = self.duration_s()
        done = 0.0
        outer = ctx.progress
        for step in self.steps:
            text = self.prompt_before(step)
            if text:
                ctx.ask(text)
            ctx.run.event(ctx.clock.now(), "step_start", step.name)
            weight = step.duration_s()
            ctx.progress = scaled_progress(outer, done, weight, total, step.name)
            try:
                produced = step.run(ctx)
            finally:
                ctx.progress = outer
            done += weight
            ctx.run.event(ctx.clock.now(), "step_end", step.name)
            self.judge(ctx, step, produced)
        ctx.progress(total, total, "done")


class OpenStation(Protocol):
    """What the runner needs of an open station (``bench.app.station.Station``)."""

    instruments: dict[str, Any]
    clock: Clock

    @property
    def config(self) -> Any: ...

    def snapshot(self) -> dict[str, Any]: ...


@dataclass
class RunOutcome:
    run_id: str
    status: str
    reason: str | None
    measurements: list[Measurement]
    store_path: str

    def measurement(self, name: str) -> Measurement:
        """The measurement ``name`` (value, unit, standard uncertainty, limits, outcome)."""
        for m in self.measurements:
            if m.name == name:
                return m
        raise LookupError(f"run {self.run_id} has no measurement {name!r} "
                          f"(it has: {', '.join(m.name for m in self.measurements) or 'none'})")

    def to_dict(self) -> dict[str, Any]:
        return {"run_id": self.run_id, "status": self.status, "reason": self.reason,
                "store": self.store_path,
                "measurements": [m.to_dict() for m in self.measurements]}


def execute(procedure: Procedure, station: OpenStation, store: RunStore, *, unit_serial: str | None,
            seed: int | None, progress: Progress = no_progress,
            labels: dict[str, str] | None = None, operator: Operator | None = None) -> RunOutcome:
    """Run ``procedure`` on an open station; always tears down; always leaves a record.
    ``labels`` (station id, test socket, lot) go into the run record as they are; ``operator``
    answers the procedure's prompts (default: :class:`Unattended`).

    A station that lacks an instrument the procedure needs is refused before a run is
    created (ValueError naming what is missing).
    """
    missing = [n for n in procedure.requires if n not in station.instruments]
    if missing:
        raise ValueError(f"station {station.config.name!r} lacks {missing} needed by "
                         f"{procedure.name!r}; it has {sorted(station.instruments)}")
    run = store.create_run(procedure=procedure.name, parameters=procedure.parameters(),
                           station=station.snapshot(), unit_serial=unit_serial, seed=seed,
                           code_version=code_version(), labels=labels)
    ctx = Context(station.instruments, station.clock, run, station.config.wiring, progress,
                  site=dict(getattr(station.config, "site", None) or DEFAULT_SITE),
                  operator=operator or Unattended())
    status, reason = "aborted", None
    try:
        procedure.setup(ctx)
        procedure.run(ctx)
        failed = [m.name for m in ctx.measurements if m.outcome == "fail"]
        status = "failed" if failed else "passed"
        reason = f"out of limits: {', '.join(failed)}" if failed else None
    except KeyboardInterrupt as exc:
        reason = interrupt_reason(exc)
        raise
    except Exception as exc:  # any fault: abort path, data kept, reason recorded
        reason = f"{type(exc).__name__}: {exc}"
        run.attach("traceback.txt", traceback.format_exc().encode(), "text/plain")
    finally:
        teardown_error = _safe_teardown(procedure, ctx)
        if teardown_error:
            run.event(_safe_now(ctx.clock), "teardown_error", teardown_error)
            if status != "aborted":
                status, reason = "aborted", f"teardown failed: {teardown_error}"
        run.finish(status, reason)
    return RunOutcome(run.id, status, reason, ctx.measurements, str(store.path))


def interrupt_reason(exc: KeyboardInterrupt) -> str:
    """Why an interrupted run stopped: the operator's Abort says where, Ctrl-C does not."""
    if isinstance(exc, OperatorAbort) and str(exc):
        return str(exc)
    return "interrupted by the operator"


def _safe_teardown(procedure: Procedure, ctx: Context) -> str | None:
    try:
        procedure.teardown(ctx)
        return None
    except Exception as exc:
        return f"{type(exc).__name__}: {exc}"


def _safe_now(clock: Clock) -> float:
    try:
        return clock.now()
    except Exception:
        return float("nan")


def each_safely(actions: list[tuple[str, Callable[[], Any]]]) -> None:
    """Run every teardown action even if some fail; raise one error naming all failures."""
    errors = []
    for label, action in actions:
        try:
            action()
        except Exception as exc:
            errors.append(f"{label}: {exc}")
    if errors:
        raise RuntimeError("; ".join(errors))



__all__ = ["scaled_progress", "Procedure", "OpenStation", "RunOutcome", "execute", "each_safely",
           "interrupt_reason"]
