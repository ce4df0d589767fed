"""The operator station's live state: what a batch is doing now, as every page sees it.

One :class:`LiveBatch` per server, written by the batch's thread and read (as a JSON
snapshot) by every page: sockets and serials, the seed, the step list with progress and a
steady time left (``time_left``), the decimated samples of each socket's current stream (time
in seconds since the stream began), the measurements as they are judged (with the spec's
labels and the text the page shows, ``wording``), the verdicts, and the operator prompt.  A
reload or a second browser gets the same snapshot.

The samples and measurements are tapped where they are stored: :class:`LiveStore` is the run
store whose writers (:class:`TappedWriter`) hand each appended chunk and each judged
measurement to the live state after storing it, so the page shows exactly what the record holds.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bench.app.operator.time_left import TimeLeft
from bench.app.wording import measurement_row, plain_name, time_left_text
from bench.core.operator import OperatorAbort
from bench.core.store import RunStore, RunWriter

PLOT_POINTS = 600        # points kept per socket for the live plot
CHUNK_POINTS = 120       # an appended chunk is decimated to at most this many points
#: stream → the column plotted and its label
PLOTTED = {"output": ("acceleration_g", "output, g"), "noise": ("voltage_v", "static record, V"),
           "tumble": ("voltage_v", "tumble position means, V")}
#: the plots' time axis: station seconds since the plotted stream began (its step's record)
TIME_AXIS = "time since step start, s"


@dataclass
class SocketView:
    socket: int
    serial: str
    run_id: str | None = None
    status: str = "waiting"            # waiting | running | passed | failed | aborted
    reason: str | None = None
    verdict: str | None = None         # PASS | PASS (marginal) | FAIL | ABORTED
    report: str | None = None          # the report's URL path
    stream: str | None = None          # the stream plotted now
    t0: float = 0.0                    # the stream's first sample time (the plot's zero)
    t: deque = field(default_factory=lambda: deque(maxlen=PLOT_POINTS))
    y: deque = field(default_factory=lambda: deque(maxlen=PLOT_POINTS))
    measurements: list[dict[str, Any]] = field(default_factory=list)

    def reason_text(self) -> str | None:
        """Why the unit stopped, a failure named by the measurements' labels."""
        failed = [m["label"] for m in self.measurements if m.get("outcome") == "fail"]
        if self.status == "failed" and failed:
            return "out of limits: " + ", ".join(failed)
        return self.reason

    def to_dict(self) -> dict[str, Any]:
        return {"socket": self.socket, "serial": self.serial, "run_id": self.run_id,
                "status": self.status, "reason": self.reason_text(), "verdict": self.verdict,
                "report": self.report, "stream": self.stream,
                "label": PLOTTED.get(self.stream or "", ("", ""))[1], "x_label": TIME_AXIS,
                "t": list(self.t), "y": list(self.y), "measurements": list(self.measurements)}


class LiveBatch:
    """Thread-safe live state of the station's batch (one at a time); ``clock`` is the wall
    clock in seconds (a test passes its own)."""

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self._lock = threading.Lock()
        self.clock = clock
        self.version = 0
        self._clear()

    def _clear(self) -> None:
        self.state = "idle"                # idle | prompt | running | done | aborted
        self.operator = ""
        self.spec = ""
        self.sockets: dict[int, SocketView] = {}
        self.steps: list[dict[str, Any]] = []
        self.done_s = 0.0
        self.total_s = 0.0
        self.message = ""
        self.seed: int | None = None
        self.labels: dict[str, str] = {}
        self.started_wall = 0.0
        self.paused_s = 0.0                # wall time spent waiting at mid-run prompts
        self.time_left = TimeLeft()
        self.prompt: dict[str, Any] | None = None
        self.abort_requested = False
        self.error: str | None = None
        self._answer = threading.Event()
        self._continue = False

    # -- written by the batch ----------------------------------------------------------
    def begin(self, operator: str, spec: str, sockets: dict[int, str],
              steps: list[tuple[str, float]], *, seed: int | None = None,
              labels: Mapping[str, str] | None = None,
              wall_per_planned_s: float | None = None) -> None:
        """A new batch: its sockets, its steps (name, planned station seconds), its ``seed``,
        the spec's measurement ``labels``; ``wall_per_planned_s`` is 1.0 on a station whose
        clock is the wall clock (its plan is its time), None where the pace is read from the run."""
        with self._lock:
            self._clear()
            self.state, self.operator, self.spec = "prompt", operator, spec
            self.seed, self.labels = seed, dict(labels or {})
            self.sockets = {n: SocketView(n, s) for n, s in sorted(sockets.items())}
            self.steps = [{"name": name, "title": plain_name(name), "duration_s": d} for name, d in steps]
            self.total_s = sum(d for _, d in steps)
            self.time_left = TimeLeft(wall_per_planned_s)
            self._touch()

    def ask(self, text: str) -> bool:
        """Show a prompt and wait for the operator: True on Continue, False on Abort.  The
        wait is not the station's pace: it is left out of the time-left estimate."""
        with self._lock:
            if self.abort_requested:  # Abort pressed before the prompt came up: it stands
                return False
            if self.state == "running":
                self.time_left.at(self._active_s())  # shown as it stands until the answer
            self.prompt = {"text": text, "id": self.version + 1}
            self._answer.clear()
            self._touch()
            asked = self.clock()
        self._answer.wait()
        with self._lock:
            self.prompt = None
            if self.state == "running":
                self.paused_s += self.clock() - asked
            self._touch()
            return self._continue

    def running(self) -> None:
        with self._lock:
            self.state, self.started_wall, self.paused_s = "running", self.clock(), 0.0
            self.time_left.report(0.0, self.done_s, self.total_s)  # the plan, where it is the time
            for view in self.sockets.values():
                view.status = "running"
            self._touch()

    def _active_s(self) -> float:
        """Wall seconds the batch has been running, prompts left out."""
        return self.clock() - self.started_wall - self.paused_s

    def progress(self, done: float, total: float, message: str = "") -> None:
        """``done`` of ``total`` planned seconds; ``message`` "<step>: what it does", the step
        named in words."""
        step, sep, rest = message.partition(":")
        if sep and step in (s["name"] for s in self.steps):
            message = plain_name(step) + sep + rest
        with self._lock:
            self.done_s, self.total_s, self.message = float(done), float(total), message
            if self.state == "running":
                self.time_left.report(self._active_s(), self.done_s, self.total_s)
            self._touch()

    def run_created(self, socket: int, run_id: str) -> None:
        with self._lock:
            if socket in self.sockets:
                self.sockets[socket].run_id = run_id
                self._touch()

    def samples(self, socket: int, stream: str, t: np.ndarray, y: np.ndarray) -> None:
        if socket not in self.sockets or stream not in PLOTTED or t.size == 0:
            return
        step = max(1, int(np.ceil(t.size / CHUNK_POINTS)))
        with self._lock:
            view = self.sockets[socket]
            if view.stream != stream:
                finite = t[np.isfinite(t)]
                view.stream, view.t0 = stream, float(finite[0]) if finite.size else 0.0
                view.t.clear()
                view.y.clear()
            keep = np.isfinite(y[::step])
            view.t.extend(np.round(t[::step][keep] - view.t0, 4).tolist())
            view.y.extend(y[::step][keep].tolist())
            self._touch()

    def measured(self, socket: int, measurement: dict[str, Any]) -> None:
        with self._lock:
            if socket in self.sockets:
                self.sockets[socket].measurements.append(measurement_row(measurement, self.labels))
                self._touch()

    def socket_ended(self, socket: int, status: str, reason: str | None) -> None:
        with self._lock:
            view = self.sockets[socket]
            view.status, view.reason = status, reason
            self._touch()

    def verdict(self, socket: int, verdict: str, report: str | None) -> None:
        with self._lock:
            self.sockets[socket].verdict, self.sockets[socket].report = verdict, report
            self._touch()

    def finish(self, state: str, error: str | None = None) -> None:
        with self._lock:
            self.state, self.error = state, error
            self.prompt = None
            self._touch()

    def _touch(self) -> None:
        self.version += 1

    # -- written by the operator -------------------------------------------------------
    def answer(self, go_on: bool) -> bool:
        """Continue / Abort at the prompt; False when no prompt is open."""
        with self._lock:
            if self.prompt is None:
                return False
            self._continue = go_on
            if not go_on:
                self.abort_requested = True
            self._answer.set()
            return True

    def request_abort(self) -> bool:
        with self._lock:
            if self.state not in ("prompt", "running"):
                return False
            self.abort_requested = True
            self._continue = False
            self._answer.set()
            self._touch()
            return True

    @property
    def name(self) -> str:
        """Who answers the prompts (``bench.core.operator.Operator``): the operator's name."""
        return self.operator or "operator page"

    @property
    def busy(self) -> bool:
        return self.state in ("prompt", "running")

    # -- read by the pages -------------------------------------------------------------
    def snapshot(self) -> dict[str, Any]:
        with self._lock:
            fraction = self.done_s / self.total_s if self.total_s > 0 else 0.0
            left = None
            if self.state == "running":  # held while a prompt waits for the operator
                left = self.time_left.shown_s if self.prompt else self.time_left.at(self._active_s())
            start = 0.0
            steps = []
            for s in self.steps:
                end = start + s["duration_s"]
                state = ("done" if self.done_s >= end - 1e-9 else
                         "running" if self.done_s >= start and self.state == "running" else "waiting")
                steps.append({**s, "state": state})
                start = end
            return {"version": self.version, "state": self.state, "operator": self.operator,
                    "spec": self.spec, "seed": self.seed, "message": self.message,
                    "seed_text": "" if self.seed is None else str(self.seed),  # JS loses digits past 2**53
                    "fraction": fraction, "wall_left_s": left, "time_left": time_left_text(left),
                    "steps": steps, "prompt": self.prompt,
                    "abort_requested": self.abort_requested, "error": self.error,
                    "sockets": [v.to_dict() for v in self.sockets.values()]}


class TappedWriter(RunWriter):
    """A socket's run writer (the one ``RunStore.create_run`` made) that also hands what it
    stored to the live state (plot samples, measurements).  Everything is written by that
    writer; this one only listens (as ``bench.core.batch.SharedRun`` stands for its units)."""

    def __init__(self, writer: RunWriter, live: LiveBatch, socket: int) -> None:  # no record of its own
        self.writer, self.live, self.socket = writer, live, socket
        self.id, self.store = writer.id, writer.store

    @property
    def last_sample_t_s(self) -> float | None:  # type: ignore[override]  # read from the writer
        return self.writer.last_sample_t_s

    @property
    def finished_status(self) -> str | None:  # type: ignore[override]  # read from the writer
        return self.writer.finished_status

    def add_stream(self, *args: Any, **kwargs: Any) -> None:
        self.writer.add_stream(*args, **kwargs)

    def append(self, stream: str, /, **columns: Any) -> None:
        self.writer.append(stream, **columns)
        column = PLOTTED.get(stream, (None,))[0]
        if column in columns and "t_s" in columns:
            self.live.samples(self.socket, stream, np.asarray(columns["t_s"], float),
                              np.asarray(columns[column], float))

    def event(self, t_s: float, kind: str, message: str = "", **data: Any) -> None:
        self.writer.event(t_s, kind, message, **data)

    def attach(self, name: str, data: bytes, mime: str) -> None:
        self.writer.attach(name, data, mime)

    def set_result(self, key: str, value: Any) -> None:
        self.writer.set_result(key, value)
        if key.startswith("measurement.") and isinstance(value, dict):
            self.live.measured(self.socket, value)

    def finish(self, status: str, reason: str | None = None) -> None:
        self.writer.finish(status, reason)


class LiveStore(RunStore):
    """The run store whose socket runs are tapped for the live state."""

    def __init__(self, path: Any, live: LiveBatch) -> None:
        super().__init__(path)
        self.live = live

    def create_run(self, **kwargs: Any) -> RunWriter:
        writer = super().create_run(**kwargs)
        socket = (kwargs.get("labels") or {}).get("socket")
        if socket is None:
            return writer
        self.live.run_created(int(socket), writer.id)
        return TappedWriter(writer, self.live, int(socket))


class AbortableClock:
    """The station's clock, with the operator's Abort checked at every wait."""

    def __init__(self, clock: Any, live: LiveBatch) -> None:
        self.clock, self.live = clock, live

    def now(self) -> float:
        return self.clock.now()

    def sleep(self, seconds: float) -> None:
        if self.live.abort_requested:
            raise OperatorAbort("aborted by the operator")
        self.clock.sleep(seconds)


__all__ = ["LiveBatch", "LiveStore", "TappedWriter", "AbortableClock", "SocketView",
           "PLOTTED", "TIME_AXIS"]
