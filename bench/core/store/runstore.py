"""RunStore: the SQLite file that keeps every run's samples, events, attachments and results.

Readers and the writer may be in different processes at once (WAL): a reader sees every
chunk committed before its query began, never a half-written one.  Within one process a
RunStore serialises its own connection with a lock, so it may be shared between threads.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import secrets
import sqlite3
import time
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from . import codec, liveness
from .database import Database
from .model import (
    INTERRUPTED,
    AttachmentInfo,
    Event,
    RunClosedError,
    RunInfo,
    RunRecord,
    StreamInfo,
    UnknownAttachmentError,
    UnknownRunError,
    UnknownStreamError,
    check_attachment_name,
    check_column_dtype,
    check_labels,
    check_stream_name,
    from_json,
    to_json,
    utc_now,
)
from .writer import RunWriter

DEFAULT_PATH = Path("bench-data/bench.sqlite")
#: attachments under this prefix are analysis products (``attach_analysis``), made after the run
ANALYSIS_PREFIX = "analysis/"
#: rows per stored chunk when an imported run does not say how its samples were chunked
IMPORT_BLOCK_ROWS = 1 << 16

_RUN_COLUMNS = (
    "id, procedure, parameters_json, station_json, unit_serial, seed, code_version, "
    "started_utc, ended_utc, status, reason, last_sample_t_s, labels_json, origin_uuid"
)


def _check_analysis_name(name: object) -> None:
    if (not isinstance(name, str) or not name.startswith(ANALYSIS_PREFIX) or len(name) > 200
            or any(part in ("", ".", "..") for part in name.split("/")[1:])):
        raise ValueError(f"analysis attachment name {name!r} must be 'analysis/<path>' "
                         "without empty, '.' or '..' parts")


class RunStore:
    """The run store at ``path`` (folders created as needed; WAL journal).

    ``synchronous``: "FULL" (default: a commit survives power loss) or "NORMAL" (survives a
    killed process only); see ``bench.core.store.schema``.  ``busy_timeout_s``: how long a write
    waits for another process's transaction.  Opening recovers runs left ``running`` by dead
    writers (``recover_interrupted``).
    """

    def __init__(
        self,
        path: str | os.PathLike[str] = DEFAULT_PATH,
        *,
        synchronous: str = "FULL",
        busy_timeout_s: float = 30.0,
    ) -> None:
        self.path = Path(path)
        self._db = Database(self.path, synchronous, busy_timeout_s)
        # Strong references: a writer dropped unfinished is still aborted by close().
        self._open_writers: dict[str, RunWriter] = {}
        (store_uuid,) = self._db.connection().execute(
            "SELECT value FROM meta WHERE key = 'store_uuid'").fetchone()
        #: this store's identity towards a central store (made when the file was created)
        self.uuid = uuid.UUID(store_uuid)
        self.recover_interrupted()

    @property
    def location(self) -> str:
        """Where the store is, as a message names it."""
        return os.fspath(self.path)

    def run_uuid(self, run_id: str) -> str:
        """The run's globally unique id: UUID 5 of its id in this store's namespace (ids are
        unique in a store, store UUIDs are random, so the pair is unique in every fleet)."""
        return str(uuid.uuid5(self.uuid, run_id))

    def __repr__(self) -> str:
        return f"RunStore({os.fspath(self.path)!r})"

    def __enter__(self) -> RunStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Finish this store's unfinished writers as aborted ("store closed") and close."""
        with self._db.lock:
            if self._db.closed:
                return
            for writer in list(self._open_writers.values()):
                with contextlib.suppress(RunClosedError):  # a run closed elsewhere stays as is
                    writer.finish("aborted", "store closed before the run was finished")
            self._db.close()

    # -- writing -------------------------------------------------------------------------
    def create_run(
        self,
        *,
        procedure: str,
        parameters: dict[str, Any],
        station: dict[str, Any],
        unit_serial: str | None,
        seed: int | None,
        code_version: str,
        labels: dict[str, str] | None = None,
    ) -> RunWriter:
        """Start a run (status ``running``) and return its writer.  ``labels``: the run's
        ``station_id``, test ``socket``, unit ``lot`` and ``operator`` where known (text)."""
        if not isinstance(procedure, str) or not procedure:
            raise ValueError(f"procedure must be a non-empty str, got {procedure!r}")
        for name, value in (("parameters", parameters), ("station", station)):
            if not isinstance(value, dict):
                raise TypeError(f"{name} must be a dict, got {type(value).__name__}")
        if unit_serial is not None and not isinstance(unit_serial, str):
            raise TypeError(f"unit_serial must be str or None, got {unit_serial!r}")
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, (int, np.integer))):
            raise TypeError(f"seed must be an int or None, got {seed!r}")
        if not isinstance(code_version, str):
            raise TypeError(f"code_version must be str, got {code_version!r}")
        parameters_json = to_json(parameters, "parameters")
        station_json = to_json(station, "station")
        labels_json = to_json(check_labels(labels), "labels")
        me = liveness.current_process()
        for _ in range(100):  # a 16-bit suffix collides rarely; retry with a fresh one
            now = time.time()
            run_id = time.strftime("%Y%m%d-%H%M%S", time.gmtime(now)) + "-" + secrets.token_hex(2)
            started = utc_now()
            try:
                with self._db.write_transaction() as conn:
                    conn.execute(
                        "INSERT INTO runs (id, procedure, parameters_json, station_json, "
                        "unit_serial, seed, code_version, started_utc, last_write_utc, status, "
                        "writer_host, writer_pid, writer_start, labels_json) "
                        "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, 'running', ?, ?, ?, ?)",
                        (run_id, procedure, parameters_json, station_json, unit_serial,
                         None if seed is None else str(int(seed)), code_version, started,
                         started, me.host, me.pid, me.start_token, labels_json),
                    )
            except sqlite3.IntegrityError:
                continue
            writer = RunWriter(self._db, self, run_id, on_finish=self._open_writers.pop)
            self._open_writers[run_id] = writer
            return writer
        raise RuntimeError(f"{self.path}: could not allocate a unique run id")  # pragma: no cover

    def import_run(self, record: RunRecord, *, block_rows: int = IMPORT_BLOCK_ROWS) -> str:
        """Store a whole finished run (an export read back, or a file made into a run) in one
        transaction, as it was: its id, times, status, results, events, attachments and
        samples (in ``record.chunk_rows``'s chunks when given, else blocks of ``block_rows``).

        A run from another store keeps its UUID there (``origin_uuid``), so both copies sync
        to one central run.  Returns the run id.  ValueError if the run is not finished, its
        id is already here, or a column does not match its stream's declaration.
        """
        info = record.run
        if info.status == "running":
            raise ValueError(f"run {info.id} is still running: only a finished run can be imported")
        if not isinstance(block_rows, int) or block_rows < 1:
            raise ValueError(f"block_rows={block_rows!r} must be an int >= 1")
        layouts = []
        for name, stream in record.streams.items():
            check_stream_name(name)
            if set(record.data.get(name, {})) != set(stream.columns):
                raise ValueError(f"run {info.id}: stream {name!r} has columns "
                                 f"{sorted(record.data.get(name, {}))}, declared {list(stream.columns)}")
            dtypes = {c: check_column_dtype(stream.dtypes[c], f"stream {name!r} column {c!r}")
                      for c in stream.columns}
            n = len(next(iter(record.data[name].values())))
            sizes = list(record.chunk_rows.get(name) or
                         [min(block_rows, n - k) for k in range(0, n, block_rows)])
            if sum(sizes) != n or any(k <= 0 for k in sizes):
                raise ValueError(f"run {info.id}: stream {name!r} chunk sizes {sizes[:5]}… do not "
                                 f"add up to its {n} rows")
            layouts.append((name, stream, dtypes, sizes))
        origin = None if info.uuid in (None, "") or info.uuid == self.run_uuid(info.id) else info.uuid
        me = liveness.current_process()
        with self._db.lock, self._db.write_transaction() as conn:
            if conn.execute("SELECT 1 FROM runs WHERE id = ?", (info.id,)).fetchone():
                raise ValueError(f"run {info.id} is already in {self.path}")
            conn.execute(
                "INSERT INTO runs (id, procedure, parameters_json, station_json, unit_serial, seed, "
                "code_version, started_utc, ended_utc, last_write_utc, status, reason, "
                "last_sample_t_s, writer_host, writer_pid, writer_start, labels_json, origin_uuid) "
                "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                (info.id, info.procedure, to_json(info.parameters, "parameters"),
                 to_json(info.station, "station"), info.unit_serial,
                 None if info.seed is None else str(int(info.seed)), info.code_version,
                 info.started_utc, info.ended_utc, info.ended_utc or utc_now(), info.status,
                 info.reason, info.last_sample_t_s, me.host, me.pid, me.start_token,
                 to_json(check_labels(info.labels), "labels"), origin))
            for position, (name, stream, dtypes, sizes) in enumerate(layouts):
                layout = [[c, stream.columns[c], dtypes[c].str] for c in stream.columns]
                conn.execute(
                    "INSERT INTO streams (run_id, name, position, columns_json, description) "
                    "VALUES (?, ?, ?, ?, ?)",
                    (info.id, name, position, to_json(layout, "columns"), stream.description))
                start = 0
                for seq, size in enumerate(sizes):
                    cols = {c: np.asarray(record.data[name][c])[start:start + size] for c in dtypes}
                    n_rows, dts, blob = codec.encode_chunk(name, dtypes, cols)
                    conn.execute("INSERT INTO chunks (run_id, stream, seq, n_rows, dtypes, data) "
                                 "VALUES (?, ?, ?, ?, ?, ?)", (info.id, name, seq, n_rows, dts, blob))
                    start += size
            conn.executemany(
                "INSERT INTO events (run_id, seq, t_s, kind, message, data_json) VALUES (?, ?, ?, ?, ?, ?)",
                [(info.id, k, None if math.isnan(e.t_s) else e.t_s, e.kind, e.message,
                  to_json(e.data, f"data of event {e.kind!r}")) for k, e in enumerate(record.events)])
            for name, (a, payload) in record.attachments.items():
                if isinstance(name, str) and name.startswith(ANALYSIS_PREFIX):
                    _check_analysis_name(name)
                else:
                    check_attachment_name(name)
                digest = hashlib.sha256(payload).hexdigest()
                if a.sha256 and a.sha256 != digest:
                    raise ValueError(f"run {info.id}: attachment {name!r} has sha256 {digest}, "
                                     f"its record says {a.sha256}")
                conn.execute("INSERT INTO attachments (run_id, name, mime, sha256, created_utc, data) "
                             "VALUES (?, ?, ?, ?, ?, ?)",
                             (info.id, name, a.mime, digest, a.created_utc or utc_now(), payload))
            conn.executemany("INSERT INTO results (run_id, key, value_json) VALUES (?, ?, ?)",
                             [(info.id, k, to_json(v, f"result {k!r}")) for k, v in info.results.items()])
        return info.id

    # -- recovery ------------------------------------------------------------------------
    def recover_interrupted(self, *, include_other_hosts: bool = False) -> list[str]:
        """Mark runs left ``running`` by a writer process that no longer exists as
        ``aborted`` with reason ``"interrupted"``; ``ended_utc`` becomes the time of the
        run's last commit.  A writer is judged by host, pid and process start time (see
        ``liveness``); runs written from another host or pid namespace are left alone unless
        ``include_other_hosts``.  Returns the recovered run ids, oldest first."""
        with self._db.lock:
            conn = self._db.connection()
            rows = conn.execute(
                "SELECT id, writer_host, writer_pid, writer_start FROM runs "
                "WHERE status = 'running' ORDER BY started_utc, rowid"
            ).fetchall()
            recovered = []
            for run_id, host, pid, start in rows:
                state = liveness.liveness(liveness.ProcessIdentity(host, pid, start))
                if state is liveness.Liveness.DEAD or (
                    include_other_hosts and state is liveness.Liveness.UNKNOWN
                ):
                    with self._db.write_transaction() as tx:
                        cursor = tx.execute(
                            "UPDATE runs SET status = 'aborted', reason = ?, "
                            "ended_utc = last_write_utc WHERE id = ? AND status = 'running'",
                            (INTERRUPTED, run_id),
                        )
                    if cursor.rowcount == 1:  # another process may have recovered it first
                        recovered.append(run_id)
            return recovered

    # -- reading -------------------------------------------------------------------------
    def list_runs(self, limit: int | None = None) -> list[RunInfo]:
        """Runs, newest first; at most ``limit`` (>= 1) of them if given."""
        if limit is not None and (
            isinstance(limit, bool) or not isinstance(limit, int) or limit < 1
        ):
            raise ValueError(f"limit must be None or an int >= 1, got {limit!r}")
        with self._db.read_snapshot() as conn:
            rows = conn.execute(
                f"SELECT {_RUN_COLUMNS} FROM runs ORDER BY started_utc DESC, rowid DESC LIMIT ?",
                (-1 if limit is None else limit,),
            ).fetchall()
            return [self._run_info(conn, row) for row in rows]

    def find_runs(self, procedure: str, **parameters: Any) -> list[str]:
        """Ids of the runs of ``procedure`` whose parameters hold each of ``parameters`` (equal
        values), newest first — reading only those runs' rows, not their results."""
        with self._db.read_snapshot() as conn:
            rows = conn.execute(
                "SELECT id, parameters_json FROM runs WHERE procedure = ? "
                "ORDER BY started_utc DESC, rowid DESC", (procedure,)).fetchall()
        found = []
        for run_id, text in rows:
            stored = json.loads(text)
            if all(stored.get(k) == v for k, v in parameters.items()):
                found.append(run_id)
        return found

    def get_run(self, run_id: str) -> RunInfo:
        """The run ``run_id``; UnknownRunError (a LookupError) if there is none."""
        with self._db.read_snapshot() as conn:
            return self._run_info(conn, self._run_row(conn, run_id))

    def streams(self, run_id: str) -> dict[str, StreamInfo]:
        """The run's streams by name, in declaration order, with row and chunk counts."""
        with self._db.read_snapshot() as conn:
            self._run_row(conn, run_id)
            rows = conn.execute(
                "SELECT s.name, s.columns_json, s.description, "
                "(SELECT COALESCE(SUM(n_rows), 0) FROM chunks c "
                " WHERE c.run_id = s.run_id AND c.stream = s.name), "
                "(SELECT COUNT(*) FROM chunks c WHERE c.run_id = s.run_id AND c.stream = s.name) "
                "FROM streams s WHERE s.run_id = ? ORDER BY s.position",
                (run_id,),
            ).fetchall()
        result = {}
        for name, columns_json, description, n_rows, n_chunks in rows:
            layout = from_json(columns_json)
            result[name] = StreamInfo(
                name=name,
                columns={c: unit for c, unit, _ in layout},
                dtypes={c: dt for c, _, dt in layout},
                description=description,
                n_rows=int(n_rows),
                n_chunks=int(n_chunks),
            )
        return result

    def load(self, run_id: str, stream: str) -> dict[str, np.ndarray]:
        """Every committed sample of ``stream``: column name -> 1-D array of its stored
        dtype (float64 unless declared otherwise), in column order."""
        with self._db.read_snapshot() as conn:
            self._run_row(conn, run_id)
            row = conn.execute(
                "SELECT columns_json FROM streams WHERE run_id = ? AND name = ?", (run_id, stream)
            ).fetchone()
            if row is None:
                known = [r[0] for r in conn.execute(
                    "SELECT name FROM streams WHERE run_id = ? ORDER BY position", (run_id,))]
                raise UnknownStreamError(f"run {run_id} has no stream {stream!r}; it has {known}")
            dtypes = {c: np.dtype(dt) for c, _, dt in from_json(row[0])}
            (total,) = conn.execute(
                "SELECT COALESCE(SUM(n_rows), 0) FROM chunks WHERE run_id = ? AND stream = ?",
                (run_id, stream),
            ).fetchone()
            cursor = conn.execute(
                "SELECT n_rows, dtypes, data FROM chunks WHERE run_id = ? AND stream = ? "
                "ORDER BY seq",
                (run_id, stream),
            )
            return codec.decode_chunks(dtypes, int(total), cursor)

    def events(self, run_id: str) -> list[Event]:
        """The run's events in the order they were logged."""
        with self._db.read_snapshot() as conn:
            self._run_row(conn, run_id)
            rows = conn.execute(
                "SELECT t_s, kind, message, data_json FROM events WHERE run_id = ? ORDER BY seq",
                (run_id,),
            ).fetchall()
        return [Event(math.nan if t is None else t, kind, message, from_json(data))
                for t, kind, message, data in rows]

    def attachments(self, run_id: str) -> list[AttachmentInfo]:
        """Descriptions of the run's attachments, by name."""
        with self._db.read_snapshot() as conn:
            self._run_row(conn, run_id)
            rows = conn.execute(
                "SELECT name, mime, length(data), sha256, created_utc FROM attachments "
                "WHERE run_id = ? ORDER BY name",
                (run_id,),
            ).fetchall()
        return [AttachmentInfo(n, m, int(size), h, c) for n, m, size, h, c in rows]

    def attachment(self, run_id: str, name: str) -> bytes:
        """The bytes of attachment ``name``; UnknownAttachmentError if absent."""
        with self._db.read_snapshot() as conn:
            self._run_row(conn, run_id)
            row = conn.execute(
                "SELECT data FROM attachments WHERE run_id = ? AND name = ?", (run_id, name)
            ).fetchone()
            if row is None:
                known = [r[0] for r in conn.execute(
                    "SELECT name FROM attachments WHERE run_id = ? ORDER BY name", (run_id,))]
                raise UnknownAttachmentError(
                    f"run {run_id} has no attachment {name!r}; it has {known}")
        return bytes(row[0])

    def attach_analysis(self, run_id: str, name: str, data: bytes, mime: str) -> None:
        """Attach an analysis product (report, model file) to a run, finished or not.

        Acquired data stay immutable: analysis products live under the ``analysis/`` name
        prefix, and re-analysing a run replaces its earlier product of the same name.
        """
        _check_analysis_name(name)
        if not isinstance(data, (bytes, bytearray, memoryview)):
            raise TypeError(f"attachment {name!r}: data must be bytes-like")
        if not isinstance(mime, str) or "/" not in mime:
            raise ValueError(f"attachment {name!r}: mime must look like 'type/subtype', got {mime!r}")
        payload = bytes(data)
        with self._db.write_transaction() as conn:
            self._run_row(conn, run_id)
            conn.execute("DELETE FROM attachments WHERE run_id = ? AND name = ?", (run_id, name))
            conn.execute(
                "INSERT INTO attachments (run_id, name, mime, sha256, created_utc, data) "
                "VALUES (?, ?, ?, ?, ?, ?)",
                (run_id, name, mime, hashlib.sha256(payload).hexdigest(), utc_now(), payload))

    def results(self, run_id: str) -> dict[str, Any]:
        """The run's results, key -> JSON value."""
        with self._db.read_snapshot() as conn:
            self._run_row(conn, run_id)
            return self._results(conn, run_id)

    def chunk_sizes(self, run_id: str) -> dict[str, list[int]]:
        """Per stream, the row count of each stored chunk in order (how the samples arrived)."""
        with self._db.read_snapshot() as conn:
            self._run_row(conn, run_id)
            rows = conn.execute("SELECT stream, n_rows FROM chunks WHERE run_id = ? ORDER BY stream, seq",
                                (run_id,)).fetchall()
        out: dict[str, list[int]] = {}
        for stream, n in rows:
            out.setdefault(stream, []).append(int(n))
        return out

    # -- forwarding to a central store (bench.core.store.forward) ---------------------------
    def chunk_rows(self, run_id: str) -> Iterator[tuple[str, int, int, str, bytes]]:
        """The run's stored chunks as they are, ``(stream, seq, n_rows, dtypes, data)`` in
        stream-declaration and seq order: what a central store copies without decoding."""
        with self._db.read_snapshot() as conn:
            self._run_row(conn, run_id)
            rows = conn.execute(
                "SELECT c.stream, c.seq, c.n_rows, c.dtypes, c.data FROM chunks c "
                "JOIN streams s ON s.run_id = c.run_id AND s.name = c.stream "
                "WHERE c.run_id = ? ORDER BY s.position, c.seq", (run_id,)).fetchall()
        for stream, seq, n_rows, dtypes, data in rows:
            yield stream, int(seq), int(n_rows), dtypes, bytes(data)

    def forwarded(self, target: str) -> dict[str, tuple[str, str]]:
        """Runs already sent to the central store ``target`` (its UUID): run id -> (digest,
        attachment manifest) as sent."""
        with self._db.read_snapshot() as conn:
            rows = conn.execute("SELECT run_id, digest, manifest FROM forwarded WHERE target = ?",
                                (target,)).fetchall()
        return {run_id: (digest, manifest) for run_id, digest, manifest in rows}

    def finished_run_ids(self) -> list[str]:
        """Ids of every finished run (any status but ``running``), oldest first."""
        with self._db.read_snapshot() as conn:
            rows = conn.execute("SELECT id FROM runs WHERE status != 'running' "
                                "ORDER BY started_utc, rowid").fetchall()
        return [r[0] for r in rows]

    def attachment_index(self) -> dict[str, list[tuple[str, str]]]:
        """Every run's attachments as ``(name, sha256)`` by name, in one query (what the
        forwarding compares with what it sent)."""
        with self._db.read_snapshot() as conn:
            rows = conn.execute("SELECT run_id, name, sha256 FROM attachments "
                                "ORDER BY run_id, name").fetchall()
        index: dict[str, list[tuple[str, str]]] = {}
        for run_id, name, sha in rows:
            index.setdefault(run_id, []).append((name, sha))
        return index

    def unforwarded_run_ids(self) -> list[str]:
        """Finished runs no central store has acknowledged, oldest first."""
        with self._db.read_snapshot() as conn:
            rows = conn.execute("SELECT id FROM runs WHERE status != 'running' AND id NOT IN "
                                "(SELECT run_id FROM forwarded) ORDER BY started_utc, rowid").fetchall()
        return [r[0] for r in rows]

    def mark_forwarded(self, run_id: str, target: str, digest: str, manifest: str) -> None:
        """Record that ``run_id`` is in the central store ``target`` as ``digest``/``manifest``."""
        with self._db.write_transaction() as conn:
            self._run_row(conn, run_id)
            conn.execute("INSERT OR REPLACE INTO forwarded (run_id, target, digest, manifest, "
                         "forwarded_utc) VALUES (?, ?, ?, ?, ?)",
                         (run_id, target, digest, manifest, utc_now()))

    def schema_version(self) -> int:
        with self._db.lock:
            (value,) = self._db.connection().execute(
                "SELECT value FROM meta WHERE key = 'schema_version'").fetchone()
        return int(value)

    # -- row helpers ---------------------------------------------------------------------
    def _run_row(self, conn: sqlite3.Connection, run_id: str) -> tuple[Any, ...]:
        row = conn.execute(f"SELECT {_RUN_COLUMNS} FROM runs WHERE id = ?", (run_id,)).fetchone()
        if row is None:
            raise UnknownRunError(f"no run with id {run_id!r} in {self.path}")
        return row

    @staticmethod
    def _results(conn: sqlite3.Connection, run_id: str) -> dict[str, Any]:
        rows = conn.execute(
            "SELECT key, value_json FROM results WHERE run_id = ? ORDER BY rowid", (run_id,)
        ).fetchall()
        return {key: from_json(value) for key, value in rows}

    def _run_info(self, conn: sqlite3.Connection, row: tuple[Any, ...]) -> RunInfo:
        (run_id, procedure, parameters, station, unit_serial, seed, code_version, started,
         ended, status, reason, last_t, labels, origin_uuid) = row
        return RunInfo(
            id=run_id,
            procedure=procedure,
            parameters=from_json(parameters),
            station=from_json(station),
            unit_serial=unit_serial,
            seed=None if seed is None else int(seed),
            code_version=code_version,
            started_utc=started,
            ended_utc=ended,
            status=status,
            reason=reason,
            last_sample_t_s=last_t,
            results=self._results(conn, run_id),
            uuid=origin_uuid or self.run_uuid(run_id),
            labels=from_json(labels),
        )
