"""Store and forward: a station's finished runs go from its SQLite store to the central store.

The station's SQLite store is the queue.  ``sync`` sends every finished (passed, failed,
completed or aborted) run that the central store has not acknowledged, oldest first:

1. the run is read from SQLite in one snapshot and its **digest** computed
   (:mod:`bench.core.store.digest`: sha256 over the run record, streams, every chunk's bytes,
   events, results and acquired attachments — everything but the ``analysis/`` attachments,
   which may change after the run);
2. one PostgreSQL transaction inserts it under its **UUID** (``RunStore.run_uuid``) or, when
   that UUID is already there, checks the stored digest is the same (a conflict is reported,
   never overwritten); either way the attachments are brought up to date; COMMIT;
3. the station records ``(run, central store UUID, digest, attachment manifest)`` in its
   ``forwarded`` table.

Idempotent: a run sent twice (two processes at once, or a crash between 2 and 3) is found by
its UUID and only acknowledged; concurrent inserts of one UUID are serialised by the primary
key.  Resumable: what is acknowledged is never sent again; a run is atomic (one transaction),
so a server lost mid-run leaves nothing of it and it is sent again whole.  While the server is
unreachable ``sync`` retries, backing off from 0.2 s to 5 s, for ``retry_for_s`` seconds, then
leaves the rest queued (they go with the next sync).  A run is re-sent (attachments only) when
its attachment manifest changed since (an analysis attached later).
"""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import psycopg

from .central import CentralStore, DigestConflictError, RunPackage
from .digest import run_digest
from .runstore import RunStore


def package(store: RunStore, run_id: str) -> RunPackage:
    """Everything of the finished run ``run_id`` as the central store receives it."""
    info = store.get_run(run_id)
    if info.status == "running":
        raise ValueError(f"run {run_id} is still running: only finished runs are forwarded")
    streams = store.streams(run_id)
    chunks = list(store.chunk_rows(run_id))
    events = store.events(run_id)
    attachments = [(a, store.attachment(run_id, a.name)) for a in store.attachments(run_id)]
    digest = run_digest(info, streams, chunks, events, (a for a, _ in attachments))
    return RunPackage(info, str(store.uuid), streams, chunks, events, attachments, digest)


def manifest(store: RunStore, run_id: str) -> str:
    """sha256 of the run's attachment list (names and contents' hashes)."""
    return _manifest(sorted((a.name, a.sha256) for a in store.attachments(run_id)))


def _manifest(listing: list[tuple[str, str]]) -> str:
    return hashlib.sha256(json.dumps([list(item) for item in listing]).encode()).hexdigest()


@dataclass
class SyncReport:
    """What one ``sync`` did: runs stored, found already there, still queued; why it stopped."""

    central: str
    stored: list[str] = field(default_factory=list)
    present: list[str] = field(default_factory=list)
    pending: list[str] = field(default_factory=list)
    conflicts: list[str] = field(default_factory=list)
    samples: int = 0
    seconds: float = 0.0
    attempts: int = 0
    error: str | None = None

    @property
    def complete(self) -> bool:
        return not self.pending and not self.conflicts

    def to_dict(self) -> dict[str, object]:
        return {"central": self.central, "stored": self.stored, "present": self.present,
                "pending": self.pending, "conflicts": self.conflicts, "samples": self.samples,
                "seconds": round(self.seconds, 3), "attempts": self.attempts, "error": self.error}


def queued(store: RunStore, target: str) -> list[str]:
    """Finished runs the central store ``target`` has not acknowledged as they are now."""
    done = store.forwarded(target)
    attachments = store.attachment_index()  # one query, not one per run
    return [run_id for run_id in store.finished_run_ids()
            if run_id not in done or done[run_id][1] != _manifest(attachments.get(run_id, []))]


def sync(store: RunStore, url: str, *, retry_for_s: float = 0.0, connect_timeout_s: float = 5.0,
         limit: int | None = None, on_run: Callable[[str, str], None] | None = None) -> SyncReport:
    """Forward every queued finished run of ``store`` to the central store at ``url``.

    Retries while the server cannot be reached or drops the connection, for ``retry_for_s``
    seconds of wall time (0: one attempt); ``limit`` sends at most that many runs;
    ``on_run(run_id, "stored"|"present")`` is told of each acknowledged run."""
    if not retry_for_s >= 0:
        raise ValueError(f"retry_for_s={retry_for_s!r} must be >= 0 seconds")
    if limit is not None and limit < 1:
        raise ValueError(f"limit={limit!r} must be >= 1")
    started = time.monotonic()
    deadline = started + retry_for_s
    report = SyncReport(central=url)
    backoff_s = 0.2
    central: CentralStore | None = None
    todo: list[str] | None = None
    try:
        while True:
            report.attempts += 1
            try:
                if central is None:
                    central = CentralStore(url, connect_timeout_s=connect_timeout_s)
                    report.central = central.location
                if todo is None:
                    todo = queued(store, str(central.uuid))[:limit]
                while todo:
                    run_id = todo[0]
                    pkg = package(store, run_id)
                    try:
                        outcome = central.receive(pkg)
                    except DigestConflictError as exc:
                        report.conflicts.append(run_id)
                        report.error = str(exc)
                        todo.pop(0)
                        continue
                    store.mark_forwarded(run_id, str(central.uuid), pkg.digest,
                                         manifest(store, run_id))
                    (report.stored if outcome == "stored" else report.present).append(run_id)
                    if outcome == "stored":
                        report.samples += pkg.n_samples
                    todo.pop(0)
                    if on_run is not None:
                        on_run(run_id, outcome)
                break
            except psycopg.OperationalError as exc:  # unreachable, restarting, connection lost
                report.error = f"{type(exc).__name__}: {str(exc).strip().splitlines()[0] if str(exc).strip() else ''}"
                if central is not None:
                    central.close()
                    central = None
                if time.monotonic() + backoff_s > deadline:
                    break
                time.sleep(backoff_s)  # wall-clock back-off: this waits for a server, not a unit
                backoff_s = min(2 * backoff_s, 5.0)
    finally:
        if central is not None:
            central.close()
    report.pending = list(todo) if todo is not None else store.unforwarded_run_ids()
    if report.complete:
        report.error = None
    report.seconds = time.monotonic() - started
    return report

