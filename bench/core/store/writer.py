"""RunWriter: the one object through which a procedure records a run as it happens.

Every call commits its own transaction before returning, so whatever a writer has been
told survives the writer's process being killed a moment later.  Used as a context manager
a run that leaves the ``with`` block by an exception is finished ``aborted`` with the
exception as its reason; one that leaves normally without ``finish`` is ``completed``.
"""

from __future__ import annotations

import hashlib
import math
import sqlite3
from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt

from . import codec
from .database import Database
from .model import (
    FINAL_STATUSES,
    RunClosedError,
    UnknownStreamError,
    check_attachment_name,
    check_column_dtype,
    check_column_name,
    check_finite_time,
    check_stream_name,
    to_json,
    utc_now,
)
from .reader import RunReader

#: Name of the column whose last finite value updates ``last_sample_t_s``.
TIME_COLUMN = "t_s"


class RunWriter:
    """Writes one run.  Obtain it from ``RunStore.create_run``; do not construct directly.

    Attributes: ``id`` (the run id), ``last_sample_t_s`` (bench time in s of the last finite
    ``t_s`` sample appended to any stream, or None), ``finished_status`` (None while running).
    """

    def __init__(self, db: Database, store: RunReader, run_id: str, *,
                 on_finish: Callable[[str], object] | None = None) -> None:
        """``db``: the store's open file, written through; ``store``: the store to read the run
        back from while it is written; ``on_finish(run_id)``: called once the run is finished
        (the store forgets its open writer)."""
        self._db = db
        self.store = store
        self._on_finish = on_finish
        self.id = run_id
        self.last_sample_t_s: float | None = None
        self.finished_status: str | None = None
        self._finished_reason: str | None = None
        self._dtypes: dict[str, dict[str, np.dtype]] = {}  # stream -> column -> storage dtype
        self._next_seq: dict[str, int] = {}
        self._n_events = 0

    def __repr__(self) -> str:
        return f"RunWriter(id={self.id!r}, status={self.finished_status or 'running'!r})"

    # -- context manager -----------------------------------------------------------------
    def __enter__(self) -> RunWriter:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: Any
    ) -> None:
        if self.finished_status is not None:
            return  # finished inside the block; an exception after that still propagates
        if exc is None:
            self.finish("completed")
        else:
            text = str(exc)
            reason = f"{type(exc).__name__}: {text}" if text else type(exc).__name__
            try:
                self.finish("aborted", reason)
            except RunClosedError:
                pass  # closed elsewhere (e.g. recovered); the original exception matters more

    # -- writing -------------------------------------------------------------------------
    def add_stream(
        self,
        name: str,
        columns: dict[str, str],
        description: str = "",
        dtypes: dict[str, Any] | None = None,
    ) -> None:
        """Declare stream ``name`` with ``columns`` (column name -> unit, e.g.
        ``{"t_s": "s", "voltage_v": "V"}``; the order is kept).  Columns are float64 unless
        ``dtypes`` names another bool/integer/float dtype for them."""
        self._check_open()
        check_stream_name(name)
        if name in self._dtypes:
            raise ValueError(f"run {self.id}: stream {name!r} is already declared")
        if not isinstance(columns, dict) or not columns:
            raise ValueError(f"stream {name!r}: columns must be a non-empty dict name -> unit")
        if not isinstance(description, str):
            raise TypeError(f"stream {name!r}: description must be str, got {description!r}")
        dtypes = dict(dtypes or {})
        unknown = sorted(set(dtypes) - set(columns))
        if unknown:
            raise ValueError(f"stream {name!r}: dtypes given for undeclared columns {unknown}")
        spec: dict[str, np.dtype] = {}
        layout = []
        for column, unit in columns.items():
            check_column_name(column)
            if not isinstance(unit, str):
                raise TypeError(f"stream {name!r}: unit of {column!r} must be str, got {unit!r}")
            where = f"stream {name!r} column {column!r}"
            dt = check_column_dtype(dtypes.get(column, np.float64), where)
            spec[column] = dt
            layout.append([column, unit, dt.str])
        with self._db.lock:
            if name in self._dtypes:  # declared meanwhile by another thread
                raise ValueError(f"run {self.id}: stream {name!r} is already declared")
            with self._transaction() as conn:
                conn.execute(
                    "INSERT INTO streams (run_id, name, position, columns_json, description) "
                    "VALUES (?, ?, ?, ?, ?)",
                    (self.id, name, len(self._dtypes), to_json(layout, "columns"), description),
                )
                self._touch(conn)
            self._dtypes[name] = spec
            self._next_seq[name] = 0

    def append(self, stream: str, /, **columns: npt.ArrayLike) -> None:
        """Append one chunk: every declared column of ``stream`` as an equal-length 1-D
        array, castable without loss to its dtype.  Committed before returning.  A chunk of
        length 0 is accepted and stores nothing."""
        self._check_open()
        try:
            dtypes = self._dtypes[stream]
        except KeyError:
            raise UnknownStreamError(
                f"run {self.id}: no stream {stream!r} declared; declared: {sorted(self._dtypes)}"
            ) from None
        n_rows, dtype_text, blob = codec.encode_chunk(stream, dtypes, columns)
        if n_rows == 0:
            return
        chunk_last_t = None
        if TIME_COLUMN in columns:
            times = np.asarray(columns[TIME_COLUMN], dtype=np.float64)
            finite = times[np.isfinite(times)]
            chunk_last_t = float(finite[-1]) if finite.size else None
        # The store's lock keeps this writer's counters in step with its commits across threads.
        with self._db.lock:
            last_t = self.last_sample_t_s
            if chunk_last_t is not None:
                last_t = chunk_last_t if last_t is None else max(last_t, chunk_last_t)
            with self._transaction() as conn:
                conn.execute(
                    "INSERT INTO chunks (run_id, stream, seq, n_rows, dtypes, data) "
                    "VALUES (?, ?, ?, ?, ?, ?)",
                    (self.id, stream, self._next_seq[stream], n_rows, dtype_text, blob),
                )
                self._touch(conn, last_sample_t_s=last_t)
            self._next_seq[stream] += 1
            self.last_sample_t_s = last_t

    def event(self, t_s: float, kind: str, message: str = "", **data: Any) -> None:
        """Log an event at bench time ``t_s`` (s; NaN when the clock could not be read) of
        ``kind`` (e.g. "step", "limit", "warning") with a human ``message`` and
        JSON-serialisable ``data``."""
        self._check_open()
        t = check_finite_time(t_s, "event t_s", allow_nan=True)
        if not isinstance(kind, str) or not kind:
            raise ValueError(f"event kind must be a non-empty str, got {kind!r}")
        if not isinstance(message, str):
            raise TypeError(f"event message must be str, got {message!r}")
        data_json = to_json(data, f"data of event {kind!r}")
        with self._db.lock, self._transaction() as conn:
            conn.execute(
                "INSERT INTO events (run_id, seq, t_s, kind, message, data_json) "
                "VALUES (?, ?, ?, ?, ?, ?)",
                (self.id, self._n_events, None if math.isnan(t) else t, kind, message, data_json),
            )
            self._touch(conn)
            self._n_events += 1  # only reached if the insert worked; a failed COMMIT leaves a gap

    def attach(self, name: str, data: bytes, mime: str) -> None:
        """Store ``data`` (bytes-like) under a unique ``name`` with MIME type ``mime``."""
        self._check_open()
        check_attachment_name(name)
        if not isinstance(data, (bytes, bytearray, memoryview)):
            raise TypeError(
                f"attachment {name!r}: data must be bytes-like, got {type(data).__name__}")
        if not isinstance(mime, str) or "/" not in mime:
            raise ValueError(
                f"attachment {name!r}: mime must look like 'type/subtype', got {mime!r}")
        payload = bytes(data)
        try:
            with self._transaction() as conn:
                conn.execute(
                    "INSERT INTO attachments (run_id, name, mime, sha256, created_utc, data) "
                    "VALUES (?, ?, ?, ?, ?, ?)",
                    (self.id, name, mime, hashlib.sha256(payload).hexdigest(), utc_now(), payload),
                )
                self._touch(conn)
        except sqlite3.IntegrityError:
            raise ValueError(f"run {self.id}: attachment {name!r} already exists") from None

    def set_result(self, key: str, value: Any) -> None:
        """Record (or replace) result ``key`` with a JSON-serialisable ``value``."""
        self._check_open()
        if not isinstance(key, str) or not key:
            raise ValueError(f"result key must be a non-empty str, got {key!r}")
        value_json = to_json(value, f"result {key!r}")
        with self._transaction() as conn:
            conn.execute(
                "INSERT OR REPLACE INTO results (run_id, key, value_json) VALUES (?, ?, ?)",
                (self.id, key, value_json),
            )
            self._touch(conn)

    def finish(self, status: str, reason: str | None = None) -> None:
        """End the run with ``status`` (passed, failed, aborted, completed); ``aborted``
        needs a ``reason``.  Repeating the same call is a no-op; a different one after the
        run is finished raises RunClosedError."""
        if status not in FINAL_STATUSES:
            raise ValueError(f"finish status {status!r}; allowed: {', '.join(FINAL_STATUSES)}")
        if reason is not None and not isinstance(reason, str):
            raise TypeError(f"finish reason must be str or None, got {reason!r}")
        if status == "aborted" and not reason:
            raise ValueError("finish('aborted') needs a reason saying why the run stopped")
        if self.finished_status is not None:
            if (status, reason) == (self.finished_status, self._finished_reason):
                return
            raise RunClosedError(
                f"run {self.id} already finished as {self.finished_status!r} "
                f"(reason {self._finished_reason!r}); cannot finish it again as {status!r}"
            )
        now = utc_now()
        with self._transaction() as conn:
            cursor = conn.execute(
                "UPDATE runs SET status = ?, reason = ?, ended_utc = ?, last_write_utc = ? "
                "WHERE id = ? AND status = 'running'",
                (status, reason, now, now, self.id),
            )
            if cursor.rowcount != 1:
                raise self._closed_error(conn)
        self.finished_status, self._finished_reason = status, reason
        if self._on_finish is not None:
            self._on_finish(self.id)

    # -- internals -----------------------------------------------------------------------
    def _check_open(self) -> None:
        if self.finished_status is not None:
            raise RunClosedError(
                f"run {self.id} is finished ({self.finished_status}); it takes no more data")

    def _transaction(self):
        return self._db.write_transaction()

    def _touch(self, conn: sqlite3.Connection, **extra: Any) -> None:
        """Mark the run as written now, in the caller's transaction; refuse if not running."""
        sets = ", ".join(["last_write_utc = ?"] + [f"{k} = ?" for k in extra])
        cursor = conn.execute(
            f"UPDATE runs SET {sets} WHERE id = ? AND status = 'running'",
            (utc_now(), *extra.values(), self.id),
        )
        if cursor.rowcount != 1:
            raise self._closed_error(conn)

    def _closed_error(self, conn: sqlite3.Connection) -> RunClosedError:
        row = conn.execute("SELECT status, reason FROM runs WHERE id = ?", (self.id,)).fetchone()
        status, reason = row if row else ("missing", None)
        return RunClosedError(
            f"run {self.id} is {status} (reason {reason!r}) in the store; this writer may not "
            "write to it any more"
        )
