"""Export a stored run to CSV (+ JSON sidecar) or HDF5, and read such exports back.

CSV layout for run ``R`` exported to a folder ``D`` (or to a file path ``D/P.csv``, which
sets the prefix ``P`` instead of ``R``):

- ``D/R.<stream>.csv`` per stream: a header row of column names (units are in the names by
  the bench's convention, e.g. ``t_s,voltage_v``; the unit strings themselves are in the
  sidecar), then one row per sample.  Floats are written as the shortest text that reads
  back to the identical value (NaN/±inf as ``nan``/``inf``/``-inf``; NaN payload bits are
  not kept), integers in full, bools as 0/1.
- ``D/R.json``: the run record, per-stream units, dtypes, row counts, chunk sizes and file
  names, the events, and the attachment list.  Non-finite floats in metadata are written as Python's
  JSON does (``NaN``, ``Infinity``).
- ``D/R.attachments/<name>``: each attachment's bytes.

HDF5 layout: root attributes ``run_json`` (the full run record) plus browsable scalars
(``id``, ``procedure``, ``status`` ...); ``/streams/<stream>/<column>`` datasets in the
stored dtype with a ``unit`` attribute (group attributes ``description``, ``column_order``,
``n_chunks``, ``chunk_rows``);
``/events/{t_s,kind,message,data_json}``; ``/attachments/<name>`` uint8 datasets with
``mime``, ``sha256`` and ``created_utc`` attributes.  Sample bytes round-trip exactly, and
so does the chunking (``chunk_rows``): ``bench runs import`` of an export stores the run as it
was, and its digest towards a central store is the original's.
"""

from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from bench.core.store import AttachmentInfo, Event, RunInfo, RunRecord, StreamInfo
from bench.core.store.reader import RunReader

FORMAT = "inertial-bench run export"
FORMAT_VERSION = 1
_CSV_BLOCK_ROWS = 1 << 16  # rows formatted per write: bounds the memory of string conversion


def _snapshot(store: RunReader, run_id: str) -> RunRecord:
    streams = store.streams(run_id)
    data = {name: store.load(run_id, name) for name in streams}
    # A running run may have grown between streams() and load(): report what was exported.
    streams = {
        name: dataclasses.replace(info, n_rows=len(next(iter(data[name].values()))))
        for name, info in streams.items()
    }
    attachments = {a.name: (a, store.attachment(run_id, a.name)) for a in store.attachments(run_id)}
    sizes = store.chunk_sizes(run_id)
    chunk_rows = {name: _cut(sizes.get(name, []), streams[name].n_rows) for name in streams}
    return RunRecord(store.get_run(run_id), streams, data, store.events(run_id), attachments, chunk_rows)


def _cut(sizes: list[int], n_rows: int) -> list[int]:
    """The chunk sizes of the first ``n_rows`` rows (a running run may have grown)."""
    out, total = [], 0
    for k in sizes:
        if total >= n_rows:
            break
        out.append(min(k, n_rows - total))
        total += out[-1]
    return out


# -- CSV -------------------------------------------------------------------------------------
def _csv_prefix(run_id: str, out_dir_or_file: str | os.PathLike[str]) -> Path:
    out = Path(out_dir_or_file)
    if out.is_dir() or not out.suffix:
        return out / run_id
    if out.suffix.lower() not in (".csv", ".json"):
        raise ValueError(f"CSV export target {out} must be a folder or end in .csv or .json")
    return out.with_suffix("")


def _column_text(values: np.ndarray) -> np.ndarray:
    # numpy's float -> str is the shortest repr that reads back identically (dragon4 unique).
    return values.astype(np.uint8).astype(str) if values.dtype.kind == "b" else values.astype(str)


def _write_csv(path: Path, columns: dict[str, np.ndarray]) -> None:
    names = list(columns)
    n_rows = len(columns[names[0]])
    with open(path, "w", encoding="utf-8", newline="\n") as f:
        f.write(",".join(names) + "\n")
        for start in range(0, n_rows, _CSV_BLOCK_ROWS):
            stop = min(start + _CSV_BLOCK_ROWS, n_rows)
            lines = _column_text(columns[names[0]][start:stop])
            for name in names[1:]:
                text = _column_text(columns[name][start:stop])
                lines = np.char.add(np.char.add(lines, ","), text)
            f.write("\n".join(lines.tolist()) + "\n")


def export_csv(store: RunReader, run_id: str, out_dir_or_file: str | os.PathLike[str]) -> list[Path]:
    """Write run ``run_id`` as CSV files plus a JSON sidecar (see the module docstring).
    Returns the written paths: the CSVs in stream order, the sidecar, then attachments."""
    snap = _snapshot(store, run_id)
    prefix = _csv_prefix(run_id, out_dir_or_file)
    prefix.parent.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    stream_meta = {}
    for name, info in snap.streams.items():
        path = prefix.parent / f"{prefix.name}.{name}.csv"
        _write_csv(path, snap.data[name])
        written.append(path)
        stream_meta[name] = {
            "file": path.name,
            "columns": info.columns,
            "dtypes": info.dtypes,
            "description": info.description,
            "n_rows": info.n_rows,
            "n_chunks": len(snap.chunk_rows[name]),
            "chunk_rows": snap.chunk_rows[name],
        }
    attachment_dir = prefix.parent / f"{prefix.name}.attachments"
    attachment_meta, attachment_paths = [], []
    for name, (attachment, payload) in snap.attachments.items():
        path = attachment_dir / name  # names may hold folders, e.g. analysis/startup/x.html
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(payload)
        attachment_paths.append(path)
        relative = f"{attachment_dir.name}/{name}"
        attachment_meta.append({**dataclasses.asdict(attachment), "file": relative})
    sidecar = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "run": dataclasses.asdict(snap.run),
        "streams": stream_meta,
        "events": [e._asdict() for e in snap.events],
        "attachments": attachment_meta,
    }
    sidecar_path = prefix.parent / f"{prefix.name}.json"
    sidecar_path.write_text(json.dumps(sidecar, indent=2), encoding="utf-8")
    return written + [sidecar_path] + attachment_paths


def _read_csv(path: Path, dtypes: dict[str, str], n_rows: int) -> dict[str, np.ndarray]:
    with open(path, encoding="utf-8") as f:
        header = f.readline().rstrip("\n").split(",")
        if header != list(dtypes):
            raise ValueError(f"{path}: header {header} does not match the sidecar's {list(dtypes)}")
        text = np.loadtxt(f, delimiter=",", dtype=str, ndmin=2) if n_rows else None
    if text is None:
        return {c: np.empty(0, dtype=np.dtype(dt).newbyteorder("=")) for c, dt in dtypes.items()}
    if text.shape != (n_rows, len(dtypes)):
        raise ValueError(
            f"{path}: {text.shape} values where ({n_rows}, {len(dtypes)}) were expected")
    out = {}
    for i, (column, dt) in enumerate(dtypes.items()):
        dtype = np.dtype(dt).newbyteorder("=")
        # bools were written as 0/1: parse as integers first
        values = text[:, i].astype(np.uint8) if dtype.kind == "b" else text[:, i]
        out[column] = values.astype(dtype)
    return out


def read_csv_export(sidecar: str | os.PathLike[str]) -> RunRecord:
    """Read back what ``export_csv`` wrote, given the path of its JSON sidecar."""
    sidecar = Path(sidecar)
    meta = json.loads(sidecar.read_text(encoding="utf-8"))
    if meta.get("format") != FORMAT or meta.get("format_version") != FORMAT_VERSION:
        raise ValueError(f"{sidecar} is not a version-{FORMAT_VERSION} {FORMAT!r} sidecar")
    streams, data, chunk_rows = {}, {}, {}
    for name, s in meta["streams"].items():
        streams[name] = StreamInfo(
            name, s["columns"], s["dtypes"], s["description"], s["n_rows"], s["n_chunks"])
        data[name] = _read_csv(sidecar.parent / s["file"], s["dtypes"], s["n_rows"])
        if "chunk_rows" in s:
            chunk_rows[name] = [int(k) for k in s["chunk_rows"]]
    attachments = {}
    for a in meta["attachments"]:
        payload = (sidecar.parent / a.pop("file")).read_bytes()
        attachments[a["name"]] = (AttachmentInfo(**a), payload)
    events = [Event(**e) for e in meta["events"]]
    return RunRecord(RunInfo(**meta["run"]), streams, data, events, attachments, chunk_rows)


# -- HDF5 ------------------------------------------------------------------------------------
def export_hdf5(
    store: RunReader, run_id: str, path: str | os.PathLike[str], *, compression: str | None = None
) -> Path:
    """Write run ``run_id`` to the HDF5 file ``path`` (replaced if present; layout in the
    module docstring).  ``compression``: None or an h5py filter name such as "gzip"."""
    if compression not in (None, "gzip", "lzf"):
        raise ValueError(f"compression={compression!r}; allowed: None, 'gzip', 'lzf'")
    # lazy: h5py (~80 ms) only for HDF5; `bench runs list` and `show` import this module
    import h5py  # noqa: PLC0415 — lazy, see above

    snap = _snapshot(store, run_id)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    text = h5py.string_dtype()
    with h5py.File(path, "w") as f:
        f.attrs["format"] = FORMAT
        f.attrs["format_version"] = FORMAT_VERSION
        f.attrs["run_json"] = json.dumps(dataclasses.asdict(snap.run))
        for key in ("id", "procedure", "status", "reason", "unit_serial", "code_version",
                    "started_utc", "ended_utc", "last_sample_t_s"):
            value = getattr(snap.run, key)
            if value is not None:  # HDF5 attributes have no null; run_json is complete
                f.attrs[key] = value
        streams = f.create_group("streams", track_order=True)  # keep declaration order
        for name, info in snap.streams.items():
            group = streams.create_group(name)
            group.attrs["description"] = info.description
            group.attrs["column_order"] = json.dumps(list(info.columns))
            group.attrs["n_chunks"] = len(snap.chunk_rows[name])  # how the store received the samples
            group.attrs["chunk_rows"] = json.dumps(snap.chunk_rows[name])
            for column, unit in info.columns.items():
                values = snap.data[name][column].astype(np.dtype(info.dtypes[column]), copy=False)
                use = compression if values.size else None  # filters need a chunked, non-empty set
                ds = group.create_dataset(column, data=values, compression=use)
                ds.attrs["unit"] = unit
        events = f.create_group("events")
        events.create_dataset("t_s", data=np.array([e.t_s for e in snap.events], dtype=np.float64))
        for field in ("kind", "message"):
            events.create_dataset(field, data=[getattr(e, field) for e in snap.events], dtype=text)
        data_json = [json.dumps(e.data) for e in snap.events]
        events.create_dataset("data_json", data=data_json, dtype=text)
        attachments = f.create_group("attachments")
        for name, (attachment, payload) in snap.attachments.items():
            ds = attachments.create_dataset(name, data=np.frombuffer(payload, dtype=np.uint8))
            for key in ("mime", "sha256", "created_utc"):
                ds.attrs[key] = getattr(attachment, key)
    return path


def read_hdf5_export(path: str | os.PathLike[str]) -> RunRecord:
    """Read back what ``export_hdf5`` wrote."""
    # lazy: h5py only for HDF5 (as in export_hdf5)
    import h5py  # noqa: PLC0415 — lazy, see above

    with h5py.File(path, "r") as f:
        if f.attrs.get("format") != FORMAT or f.attrs.get("format_version") != FORMAT_VERSION:
            raise ValueError(f"{path} is not a version-{FORMAT_VERSION} {FORMAT!r} HDF5 file")
        run = RunInfo(**json.loads(f.attrs["run_json"]))
        streams, data, chunk_rows = {}, {}, {}
        for name, group in f["streams"].items():
            order = json.loads(group.attrs["column_order"])
            if "chunk_rows" in group.attrs:
                chunk_rows[name] = [int(k) for k in json.loads(group.attrs["chunk_rows"])]
            data[name] = {c: group[c][()] for c in order}
            streams[name] = StreamInfo(
                name,
                {c: _text(group[c].attrs["unit"]) for c in order},
                {c: group[c].dtype.newbyteorder("<").str for c in order},
                _text(group.attrs["description"]),
                n_rows=len(group[order[0]]),
                n_chunks=int(group.attrs["n_chunks"]),
            )
        ev = f["events"]
        events = [
            Event(float(t), k, m, json.loads(d))
            for t, k, m, d in zip(ev["t_s"][()], ev["kind"].asstr()[()], ev["message"].asstr()[()],
                                  ev["data_json"].asstr()[()])
        ]
        attachments = {}
        found: list[tuple[str, Any]] = []  # names with folders (analysis/startup/x.html) are nested groups
        f["attachments"].visititems(lambda name, obj: found.append((name, obj)) if isinstance(obj, h5py.Dataset)
                                    else None)
        for name, ds in sorted(found):
            payload = ds[()].tobytes()
            info = AttachmentInfo(name, _text(ds.attrs["mime"]), len(payload),
                                  _text(ds.attrs["sha256"]), _text(ds.attrs["created_utc"]))
            attachments[name] = (info, payload)
    return RunRecord(run, streams, data, events, attachments, chunk_rows)


def _text(value: Any) -> str:
    return value.decode("utf-8") if isinstance(value, bytes) else str(value)
