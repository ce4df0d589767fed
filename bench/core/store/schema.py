"""The SQLite schema of the run store and the opening of a connection to it.

Durability choice: WAL journal with ``synchronous=FULL``.  In WAL mode ``NORMAL`` already
survives ``kill -9`` of the writer at any instant without losing a commit (a commit is in the
WAL file, hence in the OS, before COMMIT returns) and never corrupts; what it can lose is the
last commits before a *power cut or kernel crash*.  A bench PC losing power mid-run (a
tripped breaker, a pulled plug) is credible and "nothing acquired is ever lost" includes it,
so the default is ``FULL``: one fsync of the WAL per appended chunk, i.e. per ~10^4 samples,
which costs well under a millisecond to a few ms against chunk periods of seconds.  Bulk
imports may pass ``synchronous="NORMAL"``.

Samples are stored one row per appended chunk per stream: ``data`` holds the chunk's columns'
raw little-endian bytes one after another in the stream's column order, ``dtypes`` their
numpy dtype strings, ``n_rows`` the length shared by every column.

Version 2 (``bench sync``): each run has ``labels_json`` (station id, test socket, lot: what
the factory sorts runs by) and the ``forwarded`` table records which finished runs reached
which central store, with the digest they were sent with.  The store's own UUID
(``meta.store_uuid``) names it to the central store; a run's UUID is derived from it and the
run id (``RunStore.run_uuid``).  A version-1 file is migrated in place when opened (two added
columns and a table; nothing rewritten).

Version 3 (``bench runs import``): ``runs.origin_uuid`` keeps the UUID a run imported from
another store's export had there, so the run keeps one identity across stores (NULL for a
run made here or imported from a file that never was in a store).  Version 2 is migrated in
place (one added column).
"""

from __future__ import annotations

import os
import sqlite3
import uuid
from pathlib import Path

from .model import STATUSES, SchemaVersionError, utc_now

SCHEMA_VERSION = 3
SYNCHRONOUS_MODES = ("NORMAL", "FULL", "EXTRA")

_STATUS_CHECK = ", ".join(f"'{s}'" for s in STATUSES)

DDL = f"""
CREATE TABLE IF NOT EXISTS meta (
    key   TEXT PRIMARY KEY,
    value TEXT NOT NULL
);
CREATE TABLE IF NOT EXISTS runs (
    id              TEXT PRIMARY KEY,
    procedure       TEXT NOT NULL,
    parameters_json TEXT NOT NULL,
    station_json    TEXT NOT NULL,
    unit_serial     TEXT,
    seed            TEXT,             -- decimal text: seeds may exceed SQLite's 64-bit integers
    code_version    TEXT NOT NULL,
    started_utc     TEXT NOT NULL,
    ended_utc       TEXT,
    last_write_utc  TEXT NOT NULL,    -- time of the run's last commit: the writer was alive then
    status          TEXT NOT NULL CHECK (status IN ({_STATUS_CHECK})),
    reason          TEXT,
    last_sample_t_s REAL,
    writer_host     TEXT NOT NULL,
    writer_pid      INTEGER NOT NULL,
    -- labels_json: {"station_id", "socket", "lot"} as text, what a factory sorts runs by
    labels_json     TEXT NOT NULL DEFAULT '{{}}',
    -- writer_start: see liveness.py, NULL where the OS does not tell
    -- origin_uuid: an imported run's UUID in the store it came from (NULL: made here)
    writer_start    TEXT,
    origin_uuid     TEXT
);
CREATE INDEX IF NOT EXISTS runs_by_start ON runs (started_utc);
CREATE INDEX IF NOT EXISTS runs_running ON runs (status) WHERE status = 'running';
CREATE TABLE IF NOT EXISTS streams (
    run_id       TEXT NOT NULL REFERENCES runs (id),
    name         TEXT NOT NULL,
    position     INTEGER NOT NULL,    -- declaration order within the run
    columns_json TEXT NOT NULL,       -- [[column, unit, dtype], ...] in column order
    description  TEXT NOT NULL,
    PRIMARY KEY (run_id, name)
);
CREATE TABLE IF NOT EXISTS chunks (
    run_id  TEXT NOT NULL,
    stream  TEXT NOT NULL,
    seq     INTEGER NOT NULL,         -- 0, 1, 2, ... within the stream
    n_rows  INTEGER NOT NULL CHECK (n_rows > 0),
    dtypes  TEXT NOT NULL,            -- comma-separated numpy dtype strings, column order
    data    BLOB NOT NULL,
    PRIMARY KEY (run_id, stream, seq),
    FOREIGN KEY (run_id, stream) REFERENCES streams (run_id, name)
);
CREATE TABLE IF NOT EXISTS events (
    run_id    TEXT NOT NULL REFERENCES runs (id),
    seq       INTEGER NOT NULL,
    t_s       REAL,                 -- NULL: the bench clock could not be read
    kind      TEXT NOT NULL,
    message   TEXT NOT NULL,
    data_json TEXT NOT NULL,
    PRIMARY KEY (run_id, seq)
);
CREATE TABLE IF NOT EXISTS attachments (
    run_id      TEXT NOT NULL REFERENCES runs (id),
    name        TEXT NOT NULL,
    mime        TEXT NOT NULL,
    sha256      TEXT NOT NULL,
    created_utc TEXT NOT NULL,
    data        BLOB NOT NULL,
    PRIMARY KEY (run_id, name)
);
CREATE TABLE IF NOT EXISTS results (
    run_id     TEXT NOT NULL REFERENCES runs (id),
    key        TEXT NOT NULL,
    value_json TEXT NOT NULL,
    PRIMARY KEY (run_id, key)
);
CREATE TABLE IF NOT EXISTS forwarded (
    run_id        TEXT NOT NULL REFERENCES runs (id),
    target        TEXT NOT NULL,      -- the central store's UUID
    digest        TEXT NOT NULL,      -- sha256 of the run's acquired content as sent
    manifest      TEXT NOT NULL,      -- sha256 of its attachment list as sent (analyses change it)
    forwarded_utc TEXT NOT NULL,
    PRIMARY KEY (run_id, target)
);
"""
#: version -> statements that bring a store of that version to the next one
MIGRATIONS = {
    1: ["ALTER TABLE runs ADD COLUMN labels_json TEXT NOT NULL DEFAULT '{}'",
        DDL[DDL.index("CREATE TABLE IF NOT EXISTS forwarded"):]],
    2: ["ALTER TABLE runs ADD COLUMN origin_uuid TEXT"],
}
TABLES = ("meta", "runs", "streams", "chunks", "events", "attachments", "results", "forwarded")


def connect(path: Path, synchronous: str, busy_timeout_s: float) -> sqlite3.Connection:
    """Open (creating if needed) the store at ``path`` in WAL mode and check its schema."""
    if synchronous not in SYNCHRONOUS_MODES:
        raise ValueError(f"synchronous={synchronous!r}; allowed: {', '.join(SYNCHRONOUS_MODES)}")
    if not busy_timeout_s >= 0:
        raise ValueError(f"busy_timeout_s={busy_timeout_s!r} must be >= 0 seconds")
    path.parent.mkdir(parents=True, exist_ok=True)
    # isolation_level=None: we issue BEGIN/COMMIT ourselves, so each append is exactly one
    # transaction; check_same_thread=False because RunStore serialises access with a lock.
    conn = sqlite3.connect(
        os.fspath(path), timeout=busy_timeout_s, isolation_level=None, check_same_thread=False
    )
    try:
        mode = conn.execute("PRAGMA journal_mode=WAL").fetchone()[0]
        if mode.lower() != "wal":
            raise sqlite3.OperationalError(f"{path}: could not enable WAL (journal_mode={mode})")
        conn.execute(f"PRAGMA synchronous={synchronous}")
        conn.execute("PRAGMA foreign_keys=ON")
        _ensure_schema(conn, path)
    except BaseException:
        conn.close()
        raise
    return conn


def _ensure_schema(conn: sqlite3.Connection, path: Path) -> None:
    conn.execute("BEGIN IMMEDIATE")  # two processes creating the same new store must not race
    try:
        has_meta = conn.execute(
            "SELECT 1 FROM sqlite_master WHERE type='table' AND name='meta'"
        ).fetchone()
        version = None
        if has_meta:
            row = conn.execute("SELECT value FROM meta WHERE key='schema_version'").fetchone()
            version = int(row[0]) if row else None
        if version is None:
            foreign = conn.execute(
                "SELECT name FROM sqlite_master WHERE type='table' AND name NOT IN "
                f"({', '.join(repr(t) for t in TABLES)})"
            ).fetchall()
            if foreign:  # never write our tables into somebody else's database
                raise SchemaVersionError(
                    f"{path} is not a run store: it has tables {[r[0] for r in foreign]} and no "
                    "schema_version"
                )
            for statement in DDL.split(";"):  # executescript would COMMIT our transaction
                if statement.strip():
                    conn.execute(statement)
            conn.execute(
                "INSERT OR REPLACE INTO meta (key, value) VALUES ('schema_version', ?), "
                "('created_utc', ?)",
                (str(SCHEMA_VERSION), utc_now()),
            )
        elif version != SCHEMA_VERSION:
            if version not in MIGRATIONS:
                raise SchemaVersionError(
                    f"{path}: schema_version {version} but this code reads versions "
                    f"{sorted(MIGRATIONS)} (migrated) and {SCHEMA_VERSION}; use the matching "
                    "bench version"
                )
            while version in MIGRATIONS:
                for statement in MIGRATIONS[version]:
                    conn.execute(statement)
                version += 1
            conn.execute("UPDATE meta SET value = ? WHERE key = 'schema_version'", (str(version),))
        # The store's identity towards a central store, made once (older stores get theirs now).
        conn.execute("INSERT OR IGNORE INTO meta (key, value) VALUES ('store_uuid', ?)",
                     (str(uuid.uuid4()),))
        conn.execute("COMMIT")
    except BaseException:
        conn.execute("ROLLBACK")
        raise
