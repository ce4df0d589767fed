"""Running a procedure: set-up, steps, a teardown that always runs, and one run record.

Measurements are declared as data beside the step that takes them (OpenHTF style): a name,
a unit, limits and an optional marginal band.  The runner records every measurement's
value and outcome in the run store, and the run's status follows from them:

* ``passed``  – every measurement inside its limits,
* ``failed``  – at least one outside,
* ``aborted`` – an exception (instrument error, limit violation by the station, Ctrl-C):
  the reason and the time of the last good sample are kept with everything acquired.
"""

from __future__ import annotations

import math
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

from bench.core.clock import Clock
from bench.core.site import DEFAULT_SITE
from bench.core.store import RunStore, RunWriter
from bench.core.version import code_version


@dataclass(frozen=True)
class Limit:
    """Inclusive limits with an optional marginal band inside them (same unit)."""

    low: float | None = None
    high: float | None = None
    marginal: float = 0.0

    def outcome(self, value: float) -> str:
        if value is None or not math.isfinite(value):
            return "fail"
        if (self.low is not None and value < self.low) or (self.high is not None and value > self.high):
            return "fail"
        if self.marginal and ((self.low is not None and value < self.low + self.marginal)
                              or (self.high is not None and value > self.high - self.marginal)):
            return "marginal"
        return "pass"


@dataclass
class Measurement:
    name: str
    value: float
    unit: str
    limit: Limit = field(default_factory=Limit)
    description: str = ""
    uncertainty: float | None = None  # standard uncertainty, same unit (None: not known)

    @property
    def outcome(self) -> str:
        return self.limit.outcome(self.value)

    def to_dict(self) -> dict[str, Any]:
        value = self.value if math.isfinite(self.value) else None  # JSON has no NaN: null
        return {"name": self.name, "value": value, "unit": self.unit,
                "low": self.limit.low, "high": self.limit.high, "marginal": self.limit.marginal,
                "outcome": self.outcome, "description": self.description,
                "uncertainty": self.uncertainty}


class Progress(Protocol):
    def __call__(self, done: float, total: float, message: str = "") -> None: ...


def _no_progress(done: float, total: float, message: str = "") -> None:
    return None


@dataclass
class Context:
    """What a procedure gets: the station's instruments, its clock and the open run."""

    instruments: dict[str, Any]
    clock: Clock
    run: RunWriter
    wiring: dict[str, Any]
    progress: Progress = _no_progress
    measurements: list[Measurement] = field(default_factory=list)
    #: latitude_deg, height_m and optionally local_g_mps2 of the station
    site: dict[str, Any] = field(default_factory=lambda: dict(DEFAULT_SITE))

    def measure(self, name: str, value: float, unit: str, limit: Limit | None = None,
                description: str = "", uncertainty: float | None = None) -> Measurement:
        u = None if uncertainty is None or not math.isfinite(uncertainty) else float(uncertainty)
        m = Measurement(name, float(value), unit, limit or Limit(), description, u)
        self.measurements.append(m)
        self.run.set_result(f"measurement.{name}", m.to_dict())
        return m


class Procedure(Protocol):
    name: str

    def parameters(self) -> dict[str, Any]: ...
    def setup(self, ctx: Context) -> None: ...
    def run(self, ctx: Context) -> None: ...
    def teardown(self, ctx: Context) -> None: ...


@dataclass
class RunOutcome:
    run_id: str
    status: str
    reason: str | None
    measurements: list[Measurement]
    store_path: str

    def to_dict(self) -> dict[str, Any]:
        return {"run_id": self.run_id, "status": self.status, "reason": self.reason,
                "store": self.store_path,
                "measurements": [m.to_dict() for m in self.measurements]}


def execute(procedure: Procedure, station, store: RunStore, *, unit_serial: str | None,
            seed: int | None, progress: Progress = _no_progress) -> RunOutcome:
    """Run ``procedure`` on an open station; always tears down; always leaves a record.

    A station that lacks an instrument the procedure needs is refused before a run is
    created (ValueError naming what is missing).
    """
    missing = [n for n in getattr(procedure, "requires", ()) if n not in station.instruments]
    if missing:
        raise ValueError(f"station {station.config.name!r} lacks {missing} needed by "
                         f"{procedure.name!r}; it has {sorted(station.instruments)}")
    run = store.create_run(procedure=procedure.name, parameters=procedure.parameters(),
                           station=station.snapshot(), unit_serial=unit_serial, seed=seed,
                           code_version=code_version())
    ctx = Context(station.instruments, station.clock, run, station.config.wiring, progress,
                  site=dict(getattr(station.config, "site", None) or DEFAULT_SITE))
    status, reason = "aborted", None
    try:
        procedure.setup(ctx)
        procedure.run(ctx)
        failed = [m.name for m in ctx.measurements if m.outcome == "fail"]
        status = "failed" if failed else "passed"
        reason = f"out of limits: {', '.join(failed)}" if failed else None
    except KeyboardInterrupt:
        reason = "interrupted by the operator"
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


__all__ = ["Limit", "Measurement", "Context", "Procedure", "RunOutcome", "execute",
           "each_safely"]
