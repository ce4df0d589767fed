"""A file becomes a stored run: a bench export as it was, or a record made elsewhere as a run of its kind.

* **A bench export** (the JSON sidecar of ``bench runs export --format csv``, or its HDF5 file)
  is stored exactly as it was exported — id, UUID, times, status, results, events,
  attachments, samples and their chunking — so the central store sees one run whichever
  station forwards it.
* **A record** (CSV or HDF5 following :mod:`bench.app.records`' convention) becomes a
  finished (``completed``) run of procedure ``<kind>_record``: one stream ``record`` with
  the bench's columns and units, the unit's serial and labels from the metadata, the source
  file's name and SHA-256 and every column mapping in its parameters, and — for a kind with an
  analysis (``bench.app.record_analysis``) — that analysis's measurements
  (``measurement.<name>``, so ``bench fleet spc`` plots them), its result and its files
  (the thermal compensation file) attached under ``analysis/``.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import json
import math
import secrets
from pathlib import Path
from typing import Any

from bench.app.export import FORMAT, read_csv_export, read_hdf5_export
from bench.app.record_analysis import ANALYSES, RecordAnalysis, analyze_record, json_safe
from bench.app.records import Record
from bench.core.store import AttachmentInfo, Event, RunInfo, RunRecord, RunStore, StreamInfo
from bench.core.store.model import utc_now
from bench.core.version import code_version

RECORD_STREAM = "record"


def bench_export(path: str | Path) -> RunRecord | None:
    """The run in ``path`` if it is a bench export (sidecar or HDF5), else None."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".json":
        try:
            doc = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise ValueError(f"{path}: not a bench export sidecar ({exc})") from None
        if not isinstance(doc, dict) or doc.get("format") != FORMAT:
            raise ValueError(f"{path}: a JSON file that is not a bench export sidecar (format {FORMAT!r})")
        return read_csv_export(path)
    if suffix in (".h5", ".hdf5"):
        import h5py  # noqa: PLC0415 — lazy: h5py (~80 ms) only for HDF5 files

        with h5py.File(path, "r") as f:
            is_export = f.attrs.get("format") == FORMAT
        return read_hdf5_export(path) if is_export else None
    return None


def _run_id(started_utc: str) -> str:
    t = _dt.datetime.fromisoformat(started_utc.replace("Z", "+00:00")).astimezone(_dt.UTC)
    return t.strftime("%Y%m%d-%H%M%S") + "-" + secrets.token_hex(2)


def record_run(record: Record, analysis: RecordAnalysis | None) -> RunRecord:
    """The run a record becomes (module docstring)."""
    meta = record.meta
    started = meta.started_utc or utc_now()
    if not started.endswith("Z"):
        started = _dt.datetime.fromisoformat(started).astimezone(_dt.UTC).strftime("%Y-%m-%dT%H:%M:%S.%fZ")
    kind = record.kind
    columns = {c: record.units[c] for c in record.data}
    stream = StreamInfo(RECORD_STREAM, columns, dict.fromkeys(columns, "<f8"),
                        f"{kind.what}, imported from {Path(record.source).name}", record.n_rows, 0)
    parameters = {"kind": kind.name, "source": Path(record.source).name, "source_sha256": record.sha256,
                  "columns": record.conversions, "sensor": meta.sensor, "model": meta.model,
                  "output_unit": record.units.get("output"), **meta.parameters}
    results: dict[str, Any] = {}
    attachments: dict[str, tuple[AttachmentInfo, bytes]] = {}
    now = utc_now()
    events = [Event(math.nan, "import", f"imported from {Path(record.source).name} (sha256 {record.sha256[:12]}…)",
                    {"rows": record.n_rows})]
    if analysis is not None:
        results[f"{kind.procedure}.analysis"] = json_safe(analysis.result)
        for m in analysis.measurements:
            results[f"measurement.{m['name']}"] = json_safe(m)
        for note in analysis.notes:
            events.append(Event(math.nan, "note", note, {}))
        for name, (payload, mime) in analysis.attachments.items():
            attachments[f"analysis/{kind.name}/{name}"] = (
                AttachmentInfo(f"analysis/{kind.name}/{name}", mime, len(payload),
                               hashlib.sha256(payload).hexdigest(), now), payload)
    t = record.data.get("t_s")
    info = RunInfo(id=_run_id(started), procedure=kind.procedure, parameters=json_safe(parameters),
                   station={"station_id": meta.labels.get("station_id"), "source": "import"},
                   unit_serial=meta.unit_serial, seed=None, code_version=code_version(), started_utc=started,
                   ended_utc=now, status="completed", reason=None,
                   last_sample_t_s=None if t is None else float(t[-1]), results=results, uuid=None,
                   labels=dict(meta.labels))
    return RunRecord(info, {RECORD_STREAM: stream}, {RECORD_STREAM: dict(record.data)}, events, attachments)


def import_file(store: RunStore, path: str | Path, record: Record | None = None, *,
                analyse: bool = True, options: dict[str, Any] | None = None) -> tuple[str, RecordAnalysis | None]:
    """Store ``path`` (a bench export, else ``record``: the file read as a record) as a run;
    return its id and the analysis made of it (None for an export or with ``analyse=False``)."""
    exported = bench_export(path)
    if exported is not None:
        return store.import_run(exported), None
    if record is None:
        raise ValueError(f"{path}: not a bench export; say what kind of record it is (--kind or the metadata's kind)")
    for earlier in store.find_runs(record.kind.procedure, source_sha256=record.sha256):
        raise ValueError(f"{path} is already stored as run {earlier} (same content, sha256 "
                         f"{record.sha256[:12]}…): bench runs show {earlier}")
    analysis = analyze_record(record, **(options or {})) if analyse and record.kind.name in ANALYSES else None
    return store.import_run(record_run(record, analysis)), analysis


__all__ = ["RECORD_STREAM", "bench_export", "import_file", "record_run"]
