"""The digest of a finished run: the SHA-256 over its record, streams, every chunk's bytes,
events, results and acquired attachments — everything but the ``analysis/`` attachments, which
may change after the run. The central store checks it when a run is forwarded
(``bench.core.store.forward``); a signed report prints it so a printed copy can be matched to the
stored run. Computing it needs no PostgreSQL client."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable, Mapping

from .model import AttachmentInfo, Event, RunInfo, StreamInfo
from .runstore import ANALYSIS_PREFIX, RunStore

#: the run record's fields the digest covers
RECORD_FIELDS = ("id", "uuid", "procedure", "parameters", "station", "unit_serial", "seed", "code_version",
                 "started_utc", "ended_utc", "status", "reason", "last_sample_t_s", "results", "labels")


def run_digest(info: RunInfo, streams: Mapping[str, StreamInfo],
               chunks: Iterable[tuple[str, int, int, str, bytes]], events: Iterable[Event],
               attachments: Iterable[AttachmentInfo]) -> str:
    """The digest of a run from its parts as the store holds them (``RunStore.chunk_rows``'s
    chunks, in order)."""
    h = hashlib.sha256()
    h.update(json.dumps({k: getattr(info, k) for k in RECORD_FIELDS}, sort_keys=True, default=str).encode())
    for s in streams.values():
        h.update(json.dumps([s.name, list(s.columns.items()), list(s.dtypes.items()),
                             s.description]).encode())
    for stream, seq, n_rows, dtypes, data in chunks:
        h.update(f"{stream}|{seq}|{n_rows}|{dtypes}|{len(data)}|".encode())
        h.update(data)
    for e in events:
        h.update(json.dumps(list(e), sort_keys=True, default=str).encode())
    for a in attachments:
        if not a.name.startswith(ANALYSIS_PREFIX):
            h.update(f"{a.name}|{a.mime}|{a.sha256}".encode())
    return h.hexdigest()


def stored_digest(store: RunStore, run_id: str) -> str:
    """The digest of the finished run ``run_id`` of ``store`` (ValueError while it runs)."""
    info = store.get_run(run_id)
    if info.status == "running":
        raise ValueError(f"run {run_id} is still running: only a finished run has a digest")
    return run_digest(info, store.streams(run_id), store.chunk_rows(run_id), store.events(run_id),
                      store.attachments(run_id))
