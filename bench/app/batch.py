"""Batch acceptance from the application: sockets from the operator, the spec by serial
pattern, the station opened with its fixture, one record and one report per unit.

Used by ``bench acceptance --sockets`` and by the operator station (``bench station serve``).
"""

from __future__ import annotations

import contextlib
import re
import time
from collections.abc import Callable, Mapping
from concurrent.futures import Future
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bench.app.commands.common import attach_folder
from bench.app.reports.acceptance_report import acceptance_document, write_acceptance_report
from bench.app.reports.parallel import ReportWriters, report_workers
from bench.app.session import choose_spec
from bench.app.station import Station
from bench.core.batch import execute_batch
from bench.core.operator import Operator
from bench.core.step import Progress, no_progress
from bench.core.store import RunStore
from procedures.batch_acceptance import BatchAcceptance

MAX_SOCKETS = 8
_SERIAL = re.compile(r"[A-Za-z0-9][A-Za-z0-9._\-/]{0,63}")


def parse_sockets(text: str) -> dict[int, str]:
    """``"1=QA-SIM-0001,2=QA-SIM-0002"`` → ``{1: "QA-SIM-0001", 2: "QA-SIM-0002"}``;
    ValueError naming the bad entry and what is allowed."""
    sockets: dict[int, str] = {}
    for item in (text or "").split(","):
        item = item.strip()
        if not item:
            continue
        socket, sep, serial = item.partition("=")
        if not sep:
            raise ValueError(f"socket entry {item!r} must be SOCKET=SERIAL (e.g. 1=QA-SIM-0001)")
        sockets.update(check_socket(socket.strip(), serial.strip(), sockets))
    if not sockets:
        raise ValueError("no sockets given: SOCKET=SERIAL[,SOCKET=SERIAL...] with sockets 1..8")
    return sockets


def check_socket(socket: Any, serial: Any, taken: Mapping[int, str]) -> dict[int, str]:
    """One socket entry checked against those already given: ``{socket: serial}``."""
    try:
        n = int(socket)
    except (TypeError, ValueError):
        raise ValueError(f"socket {socket!r} not in 1..{MAX_SOCKETS}") from None
    if not 1 <= n <= MAX_SOCKETS:
        raise ValueError(f"socket {socket!r} not in 1..{MAX_SOCKETS}")
    if n in taken:
        raise ValueError(f"socket {n} given twice")
    if not isinstance(serial, str) or not _SERIAL.fullmatch(serial):
        raise ValueError(f"socket {n}: serial {serial!r} must be 1..64 letters, digits or ._-/ "
                         "(starting with a letter or digit)")
    if serial in taken.values():
        raise ValueError(f"socket {n}: serial {serial!r} is already in another socket")
    return {n: serial}


def spec_for_sockets(sockets: Mapping[int, str], spec_path: str | None = None):
    """The spec of the batch: ``spec_path``'s, else the one built-in spec whose serial pattern
    every socket's serial matches; ValueError naming a socket that matches none or another."""
    if spec_path is not None:
        return choose_spec(spec_path, None)
    specs = {n: choose_spec(None, serial) for n, serial in sorted(sockets.items())}
    first_socket, first = next(iter(specs.items()))
    for n, spec in specs.items():
        if spec.model != first.model:
            raise ValueError(f"socket {n} ({sockets[n]}) is a {spec.model} but socket "
                             f"{first_socket} a {first.model}: one spec per batch")
    return first


@dataclass
class BatchResult:
    """What a batch left: per socket its acceptance document (``acceptance_document`` plus
    ``report``), the wall time."""

    documents: dict[int, dict[str, Any]] = field(default_factory=dict)
    wall_time_s: float = 0.0

    @property
    def exit_code(self) -> int:
        statuses = {d["status"] for d in self.documents.values()}
        return 2 if "aborted" in statuses else 1 if "failed" in statuses else 0


def run_batch(config, sockets: Mapping[int, str], spec, store: RunStore, *, seed: int | None,
              report_root: Path | None, labels: dict[str, str], progress: Progress = no_progress,
              on_socket: Callable[[int, str, str | None], None] | None = None,
              on_station: Callable[[Any], None] | None = None,
              operator: Operator | None = None) -> BatchResult:
    """Open the station with ``sockets`` in its fixture, run the spec's batch acceptance, write
    each unit's report; ``on_station(station)`` is called once it is open (a live view's hook);
    ``operator`` answers the spec's prompts (default: nobody, every prompt continues)."""
    started = time.perf_counter()
    procedure = BatchAcceptance(spec)  # every step validated before the station opens
    workers = report_workers(len(sockets)) if report_root is not None else 0
    with contextlib.ExitStack() as stack:
        # started now: the workers import matplotlib while the station runs, on an idle core
        writers = stack.enter_context(ReportWriters(workers)) if workers else None
        pending: dict[int, Future[str]] = {}  # reports being written by the workers
        with Station(config, seed=seed, unit_kind=spec.kind, fixture=sockets) as station:
            if on_station is not None:
                on_station(station)
            outcomes = execute_batch(procedure, station, store, sockets=sockets, seed=seed,
                                     progress=progress, labels=labels, on_socket=on_socket,
                                     operator=operator)
            if writers is not None and report_root is not None:  # the workers start as the station closes
                pending = {n: writers.submit(store, o.run_id, report_root / o.run_id)
                           for n, o in sorted(outcomes.items())}
        result = BatchResult()
        for n, outcome in sorted(outcomes.items()):
            doc = acceptance_document(store, outcome.run_id)
            doc.update(socket=n, report=None, store=str(store.path))
            if report_root is not None:
                folder = report_root / outcome.run_id
                try:
                    doc["report"] = (pending[n].result() if n in pending
                                     else str(write_acceptance_report(store, outcome.run_id, folder)))
                    attach_folder(store, outcome.run_id, folder, "analysis/acceptance/")
                except (OSError, BrokenProcessPool) as exc:
                    doc["report_error"] = (f"run {outcome.run_id} is stored, but the report could "
                                           f"not be written: {type(exc).__name__}: {exc}")
            result.documents[n] = doc
    result.wall_time_s = time.perf_counter() - started
    return result


__all__ = ["parse_sockets", "check_socket", "spec_for_sockets", "BatchResult", "run_batch", "MAX_SOCKETS"]
