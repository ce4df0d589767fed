"""Records returned by the run store, its errors, and the validation of names and JSON values.

Conventions: times of day are ISO 8601 UTC strings with microseconds and a ``Z`` suffix
(``2026-11-22T15:30:12.123456Z``); sample and event times are bench-clock seconds (``t_s``).
Metadata (parameters, station, event data, results) is stored as JSON, so it round-trips
as JSON does: tuples come back as lists and dict keys as strings; NaN and ±inf survive.
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import re
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import DTypeLike

#: Every status a run can have; ``running`` is the only one that is not final.
STATUSES = ("running", "completed", "passed", "failed", "aborted")
#: Statuses a writer may finish a run with.
FINAL_STATUSES = ("passed", "failed", "aborted", "completed")
#: Reason recorded for runs whose writer process died without finishing them.
INTERRUPTED = "interrupted"

# Stream names become file names and HDF5 group names; column names are keyword arguments.
_STREAM_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_-]{0,63}")
_ATTACHMENT_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]{0,127}")
#: numpy dtype kinds a column may hold: bool, signed and unsigned integers, floats.
COLUMN_KINDS = "biuf"


class UnknownRunError(LookupError):
    """No run with the given id exists in the store."""


class UnknownStreamError(LookupError):
    """The run has no stream (or the stream has no column) with the given name."""


class UnknownAttachmentError(LookupError):
    """The run has no attachment with the given name."""


class RunClosedError(RuntimeError):
    """A write was attempted on a run that is no longer ``running``."""


class SchemaVersionError(RuntimeError):
    """The database was written by a store with a schema this code does not understand."""


@dataclass(frozen=True)
class RunInfo:
    """One run's record.  ``last_sample_t_s`` is the bench time (s) of the last finite ``t_s``
    sample committed by the run, over all its streams; ``None`` if none was."""

    id: str
    procedure: str
    parameters: dict[str, Any]
    station: dict[str, Any]
    unit_serial: str | None
    seed: int | None
    code_version: str
    started_utc: str
    ended_utc: str | None
    status: str
    reason: str | None
    last_sample_t_s: float | None
    results: dict[str, Any] = field(default_factory=dict)
    #: globally unique id (the central store's key; derived from the store's UUID and ``id``)
    uuid: str | None = None
    #: what a factory sorts runs by: ``station_id``, ``socket``, ``lot``, ``operator`` (text) when given
    labels: dict[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class StreamInfo:
    """A stream's declaration: ``columns`` maps column name -> unit (in declaration order),
    ``dtypes`` maps column name -> numpy dtype string (little-endian as stored)."""

    name: str
    columns: dict[str, str]
    dtypes: dict[str, str]
    description: str
    n_rows: int
    n_chunks: int


class Event(NamedTuple):
    """A logged event at bench time ``t_s`` (s; NaN if the time was unknown); unpacks as
    ``(t_s, kind, message, data)``."""

    t_s: float
    kind: str
    message: str
    data: dict[str, Any]


@dataclass(frozen=True)
class AttachmentInfo:
    """An attachment's description (its bytes come from ``RunStore.attachment``)."""

    name: str
    mime: str
    size_bytes: int
    sha256: str
    created_utc: str


@dataclass(frozen=True)
class RunRecord:
    """A whole run as one value: what an export holds and what ``RunStore.import_run`` takes.

    ``chunk_rows``: per stream, the row count of each chunk the samples were stored in (the
    digest a central store checks covers the chunking); empty for a record that never was
    in a store (an imported file), whose samples are then stored in blocks.
    """

    run: RunInfo
    streams: dict[str, StreamInfo]
    data: dict[str, dict[str, Any]]  # stream -> column -> samples (numpy arrays)
    events: list[Event]
    attachments: dict[str, tuple[AttachmentInfo, bytes]]
    chunk_rows: dict[str, list[int]] = field(default_factory=dict)


#: the labels a run may carry (``RunStore.create_run(labels=...)``)
LABELS = ("station_id", "socket", "lot", "operator")


def check_labels(labels: object) -> dict[str, str]:
    """``labels`` as a dict of known keys to non-empty text (at most 128 characters)."""
    if labels is None:
        return {}
    if not isinstance(labels, dict):
        raise TypeError(f"labels must be a dict, got {type(labels).__name__}")
    unknown = sorted(set(labels) - set(LABELS))
    if unknown:
        raise ValueError(f"labels {unknown} unknown; allowed: {', '.join(LABELS)}")
    for key, value in labels.items():
        if not isinstance(value, str) or not value or len(value) > 128 or not value.isprintable():
            raise ValueError(f"label {key} = {value!r} must be printable text of 1..128 characters")
    return {k: labels[k] for k in LABELS if k in labels}


def utc_now() -> str:
    """Current UTC time as ``YYYY-MM-DDTHH:MM:SS.ffffffZ``."""
    return _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def check_stream_name(name: object) -> str:
    if not isinstance(name, str) or not _STREAM_NAME.fullmatch(name):
        raise ValueError(
            f"stream name {name!r} is invalid: use 1-64 characters of letters, digits, '_' "
            "or '-', starting with a letter or '_'"
        )
    return name


def check_column_name(name: object) -> str:
    if not isinstance(name, str) or not name.isidentifier() or len(name) > 64:
        raise ValueError(
            f"column name {name!r} is invalid: it must be a Python identifier of at most "
            "64 characters (it is passed as a keyword to append)"
        )
    return name


def check_attachment_name(name: object) -> str:
    if not isinstance(name, str) or not _ATTACHMENT_NAME.fullmatch(name) or name in (".", ".."):
        raise ValueError(
            f"attachment name {name!r} is invalid: use 1-128 characters of letters, digits, "
            "'_', '.' or '-', starting with a letter, digit or '_'"
        )
    return name


def check_column_dtype(dtype: DTypeLike, where: str) -> np.dtype:
    """Return the little-endian storage dtype for ``dtype`` or raise naming the allowed kinds."""
    try:
        dt = np.dtype(dtype)
    except TypeError as exc:
        raise TypeError(f"{where}: {dtype!r} is not a numpy dtype") from exc
    if dt.kind not in COLUMN_KINDS:
        raise TypeError(
            f"{where}: dtype {dt} is not storable; allowed are bool, signed/unsigned integers "
            "and floats"
        )
    return dt.newbyteorder("<")  # stored bytes are little-endian whatever the host


def check_finite_time(t_s: object, what: str, allow_nan: bool = False) -> float:
    """``t_s`` as a float of seconds; finite (or NaN, meaning unknown, if ``allow_nan``)."""
    if isinstance(t_s, bool) or not isinstance(t_s, (int, float, np.integer, np.floating)):
        raise TypeError(f"{what} must be a real number of seconds, got {t_s!r}")
    value = float(t_s)
    if not (math.isfinite(value) or (allow_nan and math.isnan(value))):
        allowed = "finite or NaN (unknown)" if allow_nan else "finite"
        raise ValueError(f"{what} must be {allowed}, got {value!r}")
    return value


def _json_default(obj: object) -> object:
    # numpy scalars and arrays are what procedures naturally produce; store them as plain JSON.
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    raise TypeError(f"value of type {type(obj).__name__} is not JSON-serialisable: {obj!r:.80}")


def to_json(value: object, what: str) -> str:
    """Serialise ``value`` (numpy scalars/arrays allowed) or raise a TypeError naming ``what``."""
    try:
        return json.dumps(value, default=_json_default, sort_keys=False)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{what} is not JSON-serialisable: {exc}") from exc


def from_json(text: str | None) -> Any:
    return None if text is None else json.loads(text)
