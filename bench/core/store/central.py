"""CentralStore: every station's runs in one PostgreSQL database (psycopg 3).

Stations never write here while a run goes on: they write their local SQLite store and
forward finished runs (``bench.core.store.forward``), each in one transaction that inserts the
run under its UUID or, when that UUID is already there, checks that the digest is the same.
So a run is here whole or not at all, once, however often and from however many processes it
is sent.  Reading mirrors ``RunStore`` (``list_runs``, ``get_run``, ``streams``, ``load``,
``events``, ``attachments``, ``attachment``, ``results``): ``bench runs … --store
postgresql://…`` and the exports read either.  A run is named by its UUID, or by its station
id when that names one run only.

    central = CentralStore("postgresql://bench@127.0.0.1:54329/bench")
    central.list_runs(limit=10)
"""

from __future__ import annotations

import hashlib
import json
import math
import re
import uuid as uuidlib
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np
import psycopg

from . import codec
from .central_schema import ensure_schema
from .model import (
    AttachmentInfo,
    Event,
    RunInfo,
    StreamInfo,
    UnknownAttachmentError,
    UnknownRunError,
    UnknownStreamError,
    from_json,
    to_json,
)
from .reader import is_central_url, masked

_UUID = re.compile(r"[0-9a-fA-F]{8}-[0-9a-fA-F]{4}-[0-9a-fA-F]{4}-[0-9a-fA-F]{4}-[0-9a-fA-F]{12}")


class DigestConflictError(RuntimeError):
    """A run UUID already in the central store with other content: never overwritten."""


@dataclass(frozen=True)
class RunPackage:
    """A finished run as the central store receives it (``forward.package`` builds it)."""

    info: RunInfo
    source_store: str                 # the station store's UUID
    streams: dict[str, StreamInfo]    # in declaration order
    chunks: list[tuple[str, int, int, str, bytes]]  # (stream, seq, n_rows, dtypes, data)
    events: list[Event]
    attachments: list[tuple[AttachmentInfo, bytes]]
    digest: str                       # sha256 of the acquired content (``forward.digest``)

    @property
    def n_samples(self) -> int:
        return sum(n for _, _, n, _, _ in self.chunks)


def spec_identity(spec: dict[str, Any]) -> tuple[str, str]:
    """(sha256, version) of a spec as recorded by acceptance: its content without the file
    path it was read from (stations keep their copies in different places)."""
    content = {k: v for k, v in spec.items() if k != "source"}
    sha = hashlib.sha256(json.dumps(content, sort_keys=True).encode()).hexdigest()
    return sha, sha[:12]


def _finite(x: Any) -> float | None:
    return float(x) if isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) \
        else None


_RUN_COLUMNS = ("uuid, procedure, parameters_json, station_json, unit_serial, seed, code_version, "
                "started_utc, ended_utc, status, reason, last_sample_t_s, labels_json")


class CentralStore:
    """The central run store at ``url`` (``postgresql://user@host:port/db``); creates its
    tables on first use.  One connection, autocommit for reads; ``receive`` writes one run in
    one transaction."""

    def __init__(self, url: str, *, connect_timeout_s: float = 10.0) -> None:
        if not is_central_url(url):
            raise ValueError(f"central store URL {url!r} must start with postgresql://")
        if not connect_timeout_s > 0:
            raise ValueError(f"connect_timeout_s={connect_timeout_s!r} must be > 0")
        self.url = url
        self._location = masked(url)
        self._conn = psycopg.connect(url, autocommit=True,
                                     connect_timeout=max(1, math.ceil(connect_timeout_s)))
        try:
            self.uuid = ensure_schema(self._conn)
        except BaseException:
            self._conn.close()
            raise

    @property
    def location(self) -> str:
        """The URL, password masked."""
        return self._location

    def __repr__(self) -> str:
        return f"CentralStore({self.location!r})"

    def __enter__(self) -> CentralStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        self._conn.close()

    @property
    def connection(self) -> psycopg.Connection[Any]:
        """The store's connection, for the fleet queries (``bench.core.store.fleet``)."""
        return self._conn

    # -- receiving ----------------------------------------------------------------------
    def receive(self, package: RunPackage) -> str:
        """Store ``package`` unless its UUID is here; return ``"stored"`` or ``"present"``.
        A present run with another digest raises DigestConflictError (nothing changes).  In
        both cases the run's attachments are brought up to date (analyses attached after
        the run was first sent)."""
        info = package.info
        run_uuid = info.uuid
        if run_uuid is None:
            raise ValueError(f"run {info.id} has no UUID")
        spec = info.results.get("acceptance.spec")
        with self._conn.transaction():
            spec_sha = None
            if isinstance(spec, dict):
                spec_sha, version = spec_identity(spec)
                self._conn.execute(
                    "INSERT INTO specs (sha256, version, model, kind, spec) VALUES (%s, %s, %s, "
                    "%s, %s) ON CONFLICT (sha256) DO NOTHING",
                    (spec_sha, version, spec.get("model"), spec.get("kind"),
                     to_json(spec, "spec")))
            inserted = self._conn.execute(
                f"INSERT INTO runs ({_RUN_COLUMNS}, local_id, source_store, station_id, socket, "
                "lot, model, spec_sha256, digest, n_samples) VALUES (%s, %s, %s, %s, %s, %s, %s, "
                "%s, %s, %s, %s, %s, %s, %s, %s, %s, %s, %s, %s, %s, %s, %s) "
                "ON CONFLICT (uuid) DO NOTHING RETURNING uuid",
                (run_uuid, info.procedure, to_json(info.parameters, "parameters"),
                 to_json(info.station, "station"), info.unit_serial,
                 None if info.seed is None else str(info.seed), info.code_version,
                 info.started_utc, info.ended_utc, info.status, info.reason,
                 info.last_sample_t_s, to_json(info.labels, "labels"), info.id,
                 package.source_store, info.labels.get("station_id", package.source_store),
                 info.labels.get("socket"), info.labels.get("lot"),
                 spec.get("model") if isinstance(spec, dict) else info.parameters.get("model"), spec_sha,
                 package.digest, package.n_samples)).fetchone()
            if inserted is None:
                row = self._conn.execute("SELECT digest FROM runs WHERE uuid = %s",
                                         (run_uuid,)).fetchone()
                digest = "" if row is None else str(row[0])
                if digest != package.digest:
                    raise DigestConflictError(
                        f"run {info.id} ({run_uuid}) is in {self.location} with digest "
                        f"{digest[:12]}… but the station's copy has {package.digest[:12]}…; "
                        "not overwritten")
            else:
                self._insert_content(run_uuid, package)
            self._update_attachments(run_uuid, package.attachments)
        return "stored" if inserted is not None else "present"

    def _insert_content(self, run_uuid: str, package: RunPackage) -> None:
        with self._conn.cursor() as cur:
            cur.executemany(
                "INSERT INTO streams (run_uuid, name, position, columns_json, description) "
                "VALUES (%s, %s, %s, %s, %s)",
                [(run_uuid, s.name, i, json.dumps([[c, s.columns[c], s.dtypes[c]] for c in s.columns]),
                  s.description) for i, s in enumerate(package.streams.values())])
            with cur.copy("COPY chunks (run_uuid, stream, seq, n_rows, dtypes, data) "
                          "FROM STDIN (FORMAT BINARY)") as copy:
                copy.set_types(["uuid", "text", "int4", "int4", "text", "bytea"])
                key = uuidlib.UUID(run_uuid)
                for stream, seq, n_rows, dtypes, data in package.chunks:
                    copy.write_row((key, stream, seq, n_rows, dtypes, data))
            cur.executemany(
                "INSERT INTO events (run_uuid, seq, t_s, kind, message, data_json) "
                "VALUES (%s, %s, %s, %s, %s, %s)",
                [(run_uuid, i, None if math.isnan(e.t_s) else e.t_s, e.kind, e.message,
                  to_json(e.data, "event data")) for i, e in enumerate(package.events)])
            results = package.info.results
            cur.executemany(
                "INSERT INTO results (run_uuid, position, key, value_json) VALUES (%s, %s, %s, %s)",
                [(run_uuid, i, k, to_json(v, f"result {k}")) for i, (k, v) in enumerate(results.items())])
            cur.executemany(
                "INSERT INTO measurements (run_uuid, name, value, uncertainty, unit, low, high, "
                "marginal, outcome) VALUES (%s, %s, %s, %s, %s, %s, %s, %s, %s)",
                [(run_uuid, m["name"], _finite(m.get("value")), _finite(m.get("uncertainty")),
                  m.get("unit", ""), _finite(m.get("low")), _finite(m.get("high")),
                  _finite(m.get("marginal")), m.get("outcome", ""))
                 for k, m in results.items() if k.startswith("measurement.") and isinstance(m, dict)])

    def _update_attachments(self, run_uuid: str,
                            attachments: Iterable[tuple[AttachmentInfo, bytes]]) -> None:
        with self._conn.cursor() as cur:
            cur.executemany(
                "INSERT INTO attachments (run_uuid, name, mime, sha256, created_utc, data) "
                "VALUES (%s, %s, %s, %s, %s, %s) ON CONFLICT (run_uuid, name) DO UPDATE SET "
                "mime = EXCLUDED.mime, sha256 = EXCLUDED.sha256, created_utc = "
                "EXCLUDED.created_utc, data = EXCLUDED.data WHERE attachments.sha256 <> "
                "EXCLUDED.sha256",
                [(run_uuid, a.name, a.mime, a.sha256, a.created_utc, data) for a, data in attachments])

    def digests(self, run_uuids: Iterable[str]) -> dict[str, str]:
        """The stored digest of each of ``run_uuids`` that is here."""
        rows = self._conn.execute("SELECT uuid::text, digest FROM runs WHERE uuid = ANY(%s::uuid[])",
                                  (list(run_uuids),)).fetchall()
        return dict(rows)

    # -- reading ------------------------------------------------------------------------
    def list_runs(self, limit: int | None = None) -> list[RunInfo]:
        """Runs of every station, newest first; at most ``limit`` (>= 1) if given."""
        if limit is not None and (isinstance(limit, bool) or not isinstance(limit, int) or limit < 1):
            raise ValueError(f"limit must be None or an int >= 1, got {limit!r}")
        rows = self._conn.execute(
            f"SELECT {_RUN_COLUMNS} FROM runs ORDER BY started_utc DESC, uuid LIMIT %s",
            (limit,)).fetchall()
        return [self._run_info(row) for row in rows]

    def resolve(self, run_id: str) -> str:
        """The UUID of the run named ``run_id``: its UUID, or a station's run id that names
        one run only (LookupError naming the candidates otherwise)."""
        if not isinstance(run_id, str):
            raise UnknownRunError(f"no run with id {run_id!r} in {self.location}")
        if _UUID.fullmatch(run_id):
            row = self._conn.execute("SELECT uuid::text FROM runs WHERE uuid = %s",
                                     (run_id,)).fetchone()
            if row is None:
                raise UnknownRunError(f"no run with UUID {run_id} in {self.location}")
            return str(row[0])
        rows = self._conn.execute("SELECT uuid::text, station_id FROM runs WHERE local_id = %s",
                                  (run_id,)).fetchall()
        if not rows:
            raise UnknownRunError(f"no run with id {run_id!r} in {self.location}")
        if len(rows) > 1:
            raise UnknownRunError(f"run id {run_id!r} names {len(rows)} runs in {self.location}; "
                                  "give the UUID: " + ", ".join(f"{u} ({s})" for u, s in rows))
        return str(rows[0][0])

    def get_run(self, run_id: str) -> RunInfo:
        row = self._conn.execute(f"SELECT {_RUN_COLUMNS} FROM runs WHERE uuid = %s",
                                 (self.resolve(run_id),)).fetchone()
        if row is None:
            raise UnknownRunError(f"no run with id {run_id!r} in {self.location}")
        return self._run_info(row)

    def results(self, run_id: str) -> dict[str, Any]:
        return self._results(self.resolve(run_id))

    def streams(self, run_id: str) -> dict[str, StreamInfo]:
        run_uuid = self.resolve(run_id)
        rows = self._conn.execute(
            "SELECT s.name, s.columns_json, s.description, COALESCE(SUM(c.n_rows), 0), COUNT(c.seq) "
            "FROM streams s LEFT JOIN chunks c ON c.run_uuid = s.run_uuid AND c.stream = s.name "
            "WHERE s.run_uuid = %s GROUP BY s.name, s.columns_json, s.description, s.position "
            "ORDER BY s.position", (run_uuid,)).fetchall()
        out = {}
        for name, columns_json, description, n_rows, n_chunks in rows:
            layout = from_json(columns_json)
            out[name] = StreamInfo(name, {c: u for c, u, _ in layout}, {c: d for c, _, d in layout},
                                   description, int(n_rows), int(n_chunks))
        return out

    def load(self, run_id: str, stream: str) -> dict[str, np.ndarray]:
        run_uuid = self.resolve(run_id)
        row = self._conn.execute("SELECT columns_json FROM streams WHERE run_uuid = %s AND name = %s",
                                 (run_uuid, stream)).fetchone()
        if row is None:
            known = [r[0] for r in self._conn.execute(
                "SELECT name FROM streams WHERE run_uuid = %s ORDER BY position", (run_uuid,))]
            raise UnknownStreamError(f"run {run_id} has no stream {stream!r}; it has {known}")
        dtypes = {c: np.dtype(dt) for c, _, dt in from_json(row[0])}
        chunks = self._conn.execute(
            "SELECT n_rows, dtypes, data FROM chunks WHERE run_uuid = %s AND stream = %s ORDER BY seq",
            (run_uuid, stream)).fetchall()
        return codec.decode_chunks(dtypes, sum(int(n) for n, _, _ in chunks),
                                   ((int(n), d, bytes(b)) for n, d, b in chunks))

    def chunk_sizes(self, run_id: str) -> dict[str, list[int]]:
        """Per stream, the row count of each stored chunk in order (as the station stored them)."""
        rows = self._conn.execute("SELECT stream, n_rows FROM chunks WHERE run_uuid = %s ORDER BY stream, seq",
                                  (self.resolve(run_id),)).fetchall()
        out: dict[str, list[int]] = {}
        for stream, n in rows:
            out.setdefault(stream, []).append(int(n))
        return out

    def events(self, run_id: str) -> list[Event]:
        rows = self._conn.execute(
            "SELECT t_s, kind, message, data_json FROM events WHERE run_uuid = %s ORDER BY seq",
            (self.resolve(run_id),)).fetchall()
        return [Event(math.nan if t is None else t, k, m, from_json(d)) for t, k, m, d in rows]

    def attachments(self, run_id: str) -> list[AttachmentInfo]:
        rows = self._conn.execute(
            "SELECT name, mime, length(data), sha256, created_utc FROM attachments "
            "WHERE run_uuid = %s ORDER BY name", (self.resolve(run_id),)).fetchall()
        return [AttachmentInfo(n, m, int(size), h, c) for n, m, size, h, c in rows]

    def attachment(self, run_id: str, name: str) -> bytes:
        run_uuid = self.resolve(run_id)
        row = self._conn.execute("SELECT data FROM attachments WHERE run_uuid = %s AND name = %s",
                                 (run_uuid, name)).fetchone()
        if row is None:
            known = [a.name for a in self.attachments(run_uuid)]
            raise UnknownAttachmentError(f"run {run_id} has no attachment {name!r}; it has {known}")
        return bytes(row[0])

    def _results(self, run_uuid: str) -> dict[str, Any]:
        rows = self._conn.execute(
            "SELECT key, value_json FROM results WHERE run_uuid = %s ORDER BY position",
            (run_uuid,)).fetchall()
        return {k: from_json(v) for k, v in rows}

    def _run_info(self, row: tuple[Any, ...]) -> RunInfo:
        (run_uuid, procedure, parameters, station, unit_serial, seed, code_version, started,
         ended, status, reason, last_t, labels) = row
        run_uuid = str(run_uuid) if isinstance(run_uuid, uuidlib.UUID) else run_uuid
        return RunInfo(id=run_uuid, procedure=procedure, parameters=from_json(parameters),
                       station=from_json(station), unit_serial=unit_serial,
                       seed=None if seed is None else int(seed), code_version=code_version,
                       started_utc=started, ended_utc=ended, status=status, reason=reason,
                       last_sample_t_s=last_t, results=self._results(run_uuid), uuid=run_uuid,
                       labels=from_json(labels))
