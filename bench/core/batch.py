"""Running a batch: several units in test sockets of one fixture, one run record per unit.

A **batch procedure** (:class:`BatchProcedure`) runs its steps once for the whole fixture —
the shared actions (levelling the table, each turntable position, powering the fixture's
rails) happen once — and each **batch step** (:class:`BatchStep`) returns what it produced
*per socket*.  The runner (:func:`execute_batch`) keeps, for every socket:

* its own run record (``procedure``, parameters, station, serial, the run labels with its
  ``socket``): the same kind of record a single unit's run is, so ``bench runs``, the
  reports and the exports read it unchanged;
* its own measurements, judged by the procedure (the unit spec's limits), and its status:
  ``passed`` / ``failed`` as a single run, ``aborted`` when *its* data could not be taken or
  reduced (an overloaded channel, a fit that failed): one socket's fault does not stop the
  others, which carry on to their verdicts;
* every event of the shared actions (``step_start``, ``levelled``, ``supply_on``...) in its
  record, as if it had been run alone.

A fault of the shared station (the turntable trips, the scanner stops answering) aborts
every socket still running; the teardown runs once, always, and a teardown failure aborts
every socket that had not ended.
"""

from __future__ import annotations

import traceback
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from bench.core.operator import Operator, Unattended
from bench.core.procedure import OpenStation, RunOutcome, interrupt_reason, scaled_progress
from bench.core.site import DEFAULT_SITE
from bench.core.step import Context, Progress, Step, no_progress
from bench.core.store import RunStore, RunWriter
from bench.core.version import code_version
from bench.values import Estimate

#: what a batch step produced for one socket: its values, or why the socket could not go on
SocketResult = Mapping[str, Estimate] | Exception


class SharedRun(RunWriter):
    """The record of the batch's shared actions: each event and result goes into the record of
    every socket still running (``units()``), so each unit's record reads as a run of its own.
    Streams belong to a socket, never to the batch."""

    def __init__(self, units: Callable[[], Sequence[RunWriter]]) -> None:  # no record of its own
        self._units = units
        self.id = "batch"

    def event(self, t_s: float, kind: str, message: str = "", **data: Any) -> None:
        for run in self._units():
            run.event(t_s, kind, message, **data)

    def set_result(self, key: str, value: Any) -> None:
        for run in self._units():
            run.set_result(key, value)

    def attach(self, name: str, data: bytes, mime: str) -> None:
        for run in self._units():
            run.attach(name, data, mime)

    def add_stream(self, *args: Any, **kwargs: Any) -> None:
        raise TypeError("a batch's shared actions have no stream; a step streams per socket")

    def append(self, stream: str, /, **columns: Any) -> None:
        raise TypeError("a batch's shared actions have no stream; a step streams per socket")

    def finish(self, status: str, reason: str | None = None) -> None:
        raise TypeError("a batch ends per socket (execute_batch)")


class BatchStep(ABC):
    """A step of the catalogue run for a whole fixture at once: ``step`` is the single-unit
    step it batches (its name, parameters, what it produces and its duration)."""

    #: station instruments it needs (a fixture's scanner, not the single unit's meters)
    requires: tuple[str, ...] = ()

    def __init__(self, step: Step[Any]) -> None:
        self.step = step

    @property
    def name(self) -> str:
        return self.step.name

    def duration_s(self) -> float:
        return self.step.duration_s()

    @abstractmethod
    def run_batch(self, shared: Context, units: Mapping[int, Context]) -> dict[int, SocketResult]:
        """Take the step for every socket of ``units`` at once (shared actions through
        ``shared``, each socket's streams, results and guards through its own context) and
        return, per socket, what it produced or the exception that stopped that socket."""


class BatchProcedure(ABC):
    """What :func:`execute_batch` runs: batch steps between a shared set-up and teardown,
    each socket's produced values judged into its own measurements."""

    def __init__(self, name: str, steps: Sequence[BatchStep]) -> None:
        if not steps:
            raise ValueError(f"batch procedure {name!r} has no steps")
        self.name = name
        self.steps = tuple(steps)

    @property
    def requires(self) -> tuple[str, ...]:
        return tuple(sorted({r for s in self.steps for r in s.requires}))

    def duration_s(self) -> float:
        return sum(s.duration_s() for s in self.steps)

    def parameters(self) -> dict[str, Any]:
        return {s.name: s.step.parameters() for s in self.steps}

    def prompt_before(self, step: BatchStep) -> str | None:
        """What the operator is asked before ``step`` (None: nothing)."""
        return None

    @abstractmethod
    def setup(self, shared: Context) -> None:
        """The fixture to its start state, once for the batch."""

    @abstractmethod
    def teardown(self, shared: Context) -> None:
        """The station left safe, once, whatever happened."""

    @abstractmethod
    def judge(self, unit: Context, step: BatchStep, produced: Mapping[str, Estimate]) -> None:
        """One socket's produced values into its measurements."""


def execute_batch(procedure: BatchProcedure, station: OpenStation, store: RunStore, *,
                  sockets: Mapping[int, str], seed: int | None, progress: Progress = no_progress,
                  labels: dict[str, str] | None = None,
                  on_socket: Callable[[int, str, str | None], None] | None = None,
                  operator: Operator | None = None) -> dict[int, RunOutcome]:
    """Run ``procedure`` for the units in ``sockets`` (socket → serial) on an open station:
    one run record per unit (its labels: ``labels`` plus ``socket``), the shared actions once,
    every socket to its own verdict.  ``on_socket(socket, status, reason)`` is told as each
    socket ends (a live view); ``operator`` answers the procedure's prompts, once for the
    batch (default: :class:`Unattended`).  A station lacking an instrument the procedure needs is refused
    before any run exists."""
    if not sockets:
        raise ValueError("no sockets: give at least one socket = serial")
    missing = [n for n in procedure.requires if n not in station.instruments]
    if missing:
        raise ValueError(f"station {station.config.name!r} lacks {missing} needed by "
                         f"{procedure.name!r}; it has {sorted(station.instruments)}")
    snapshot = station.snapshot()
    site = dict(getattr(station.config, "site", None) or DEFAULT_SITE)
    units: dict[int, Context] = {}
    for n, serial in sorted(sockets.items()):
        run = store.create_run(procedure=procedure.name, parameters=procedure.parameters(),
                               station=snapshot, unit_serial=serial, seed=seed,
                               code_version=code_version(),
                               labels={**(labels or {}), "socket": str(n)})
        units[n] = Context(station.instruments, station.clock, run, station.config.wiring, site=site)
    live: dict[int, Context] = dict(units)
    ended: dict[int, tuple[str, str | None]] = {}

    def end(n: int, status: str, reason: str | None) -> None:
        live.pop(n, None)
        ended[n] = (status, reason)
        if on_socket is not None:
            on_socket(n, status, reason)

    def abort(n: int, reason: str) -> None:
        units[n].run.attach("traceback.txt", traceback.format_exc().encode(), "text/plain")
        end(n, "aborted", reason)

    shared = Context(station.instruments, station.clock,
                     SharedRun(lambda: [c.run for c in live.values()]),
                     station.config.wiring, progress, site=site, operator=operator or Unattended())
    total = procedure.duration_s()
    try:
        procedure.setup(shared)
        done = 0.0
        for step in procedure.steps:
            if not live:
                break
            text = procedure.prompt_before(step)
            if text:
                shared.ask(text)  # into every running socket's record
            shared.run.event(shared.clock.now(), "step_start", step.name)
            shared.progress = scaled_progress(progress, done, step.duration_s(), total, step.name)
            try:
                results = step.run_batch(shared, dict(live))
            finally:
                shared.progress = progress
            done += step.duration_s()
            shared.run.event(shared.clock.now(), "step_end", step.name)
            for n in list(live):
                result = results.get(n, RuntimeError(f"step {step.name} returned nothing for socket {n}"))
                if isinstance(result, Exception):
                    try:
                        raise result
                    except Exception as exc:  # its traceback into the socket's record
                        abort(n, f"{type(exc).__name__}: {exc}")
                else:
                    procedure.judge(units[n], step, result)
        progress(total, total, "done")
        for n in list(live):
            failed = [m.name for m in units[n].measurements if m.outcome == "fail"]
            end(n, "failed" if failed else "passed",
                f"out of limits: {', '.join(failed)}" if failed else None)
    except KeyboardInterrupt as exc:
        for n in list(live):
            end(n, "aborted", interrupt_reason(exc))
        raise
    except Exception as exc:  # a fault of the shared station: every running socket stops
        for n in list(live):
            abort(n, f"{type(exc).__name__}: {exc}")
    finally:
        everyone = list(units)
        live.update({n: units[n] for n in everyone})  # the teardown's events go to every record
        teardown_error = None
        try:
            procedure.teardown(shared)
        except Exception as exc:
            teardown_error = f"{type(exc).__name__}: {exc}"
        live.clear()
        for n in everyone:
            status, reason = ended.get(n, ("aborted", "interrupted by the operator"))
            if teardown_error:
                units[n].run.event(_now(shared), "teardown_error", teardown_error)
                if status != "aborted":
                    status, reason = "aborted", f"teardown failed: {teardown_error}"
            units[n].run.finish(status, reason)
            ended[n] = (status, reason)
    return {n: RunOutcome(units[n].run.id, ended[n][0], ended[n][1], units[n].measurements,
                          str(store.path)) for n in units}


def _now(ctx: Context) -> float:
    try:
        return ctx.clock.now()
    except Exception:
        return float("nan")


__all__ = ["SharedRun", "BatchStep", "BatchProcedure", "SocketResult", "execute_batch"]
