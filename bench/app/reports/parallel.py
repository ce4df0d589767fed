"""A batch's acceptance reports written side by side, in worker processes.

A report is mostly matplotlib (figures laid out and rendered: ~0.9 s a unit), all of it
holding the interpreter lock, so a batch of units writes its reports one after the other on
one core while the other cores idle.  :class:`ReportWriters` runs them in worker processes:

* the pool is started **when the batch starts**: its server process imports the report
  modules (matplotlib, fonts) while the station runs, on a core the simulated station leaves
  idle, so the reports begin at once when the units end;
* each worker opens the run store by its path and writes one unit's report folder: the store
  is made for readers in other processes (SQLite WAL; a reader never marks a live writer's
  runs interrupted, see ``RunStore.recover_interrupted``);
* the workers are forked from a ``forkserver`` (never from the caller, which may be a server
  with threads running); a worker that dies is the report's error, not the batch's.

What a report holds does not depend on where it was written: the folder is the same as
``write_acceptance_report`` writes in-process.
"""

from __future__ import annotations

import io
import multiprocessing
import os
import threading
from concurrent.futures import Future, ProcessPoolExecutor
from multiprocessing import forkserver
from pathlib import Path
from typing import Any

from matplotlib.figure import Figure

from bench.app.reports.acceptance_report import write_acceptance_report
from bench.core.store import RunStore

#: imported once by the forkserver, inherited by every worker it forks
PRELOAD = ["bench.app.reports.acceptance_report", "matplotlib.backends.backend_agg"]


def _warm() -> None:
    """A first task, run while the batch still runs: the worker has its imports, and its
    fonts and renderer loaded (a small figure drawn and thrown away: ~0.5 s a worker that the
    first report would otherwise pay)."""
    fig = Figure(figsize=(2, 1.5))
    ax = fig.add_subplot()
    ax.loglog([1, 10, 100], [3, 2, 1], "o-", label="warm")
    ax.set(xlabel="τ (s)", ylabel="σ (g)", title="warm-up")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(io.BytesIO(), format="png", dpi=110)


def _write(store_path: str, run_id: str, folder: str) -> str:
    store = RunStore(store_path)
    try:
        return str(write_acceptance_report(store, run_id, folder))
    finally:
        store.close()


def report_workers(units: int) -> int:
    """Worker processes worth starting for ``units`` reports: one per core, at most one per
    unit; 0 (write in-process) for a single unit, where a pool only adds its start-up."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return 0 if units < 2 or cores < 2 else min(units, cores)


def _context() -> Any:
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(PRELOAD)
    return context


def start_report_server() -> threading.Thread:
    """Start the process the report workers are forked from (it imports ``PRELOAD``: seconds
    of matplotlib and analysis imports) in the background; a server process (the operator
    station) calls this once when it starts, so its batches' workers fork at once."""
    def start() -> None:
        _context()
        forkserver.ensure_running()
    thread = threading.Thread(target=start, name="report-server", daemon=True)
    thread.start()
    return thread


class ReportWriters:
    """Worker processes writing acceptance reports; a context manager (the pool is shut down
    on exit, after every submitted report is written).  Creating it does not wait: the
    workers are started (and warmed) by a background thread."""

    def __init__(self, workers: int) -> None:
        if workers < 1:
            raise ValueError(f"workers {workers!r} must be >= 1")
        self.executor = ProcessPoolExecutor(max_workers=workers, mp_context=_context())
        self._starting = threading.Thread(target=self._start, args=(workers,), name="report-writers",
                                          daemon=True)
        self._starting.start()

    def _start(self, workers: int) -> None:
        for _ in range(workers):  # blocks until the fork server has its imports: not the caller
            self.executor.submit(_warm)

    def submit(self, store: RunStore, run_id: str, folder: Path) -> Future[str]:
        """Write the report of ``run_id`` (a finished run of ``store``) into ``folder``; the
        future's result is the report's path."""
        return self.executor.submit(_write, os.fspath(store.path), run_id, os.fspath(folder))

    def __enter__(self) -> ReportWriters:
        return self

    def __exit__(self, *exc: object) -> None:
        self._starting.join()
        self.executor.shutdown(wait=True, cancel_futures=exc[0] is not None)


__all__ = ["ReportWriters", "report_workers", "start_report_server", "PRELOAD"]
