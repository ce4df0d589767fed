"""The central store's PostgreSQL schema: every station's runs, keyed by run UUID.

Runs arrive whole (``bench.core.store.forward``): one transaction per run, so a run is in the
central store entirely or not at all.  Tables mirror the station's SQLite store (samples stay
in their stored chunks, ``bytea``: nothing is decoded or re-encoded on the way), plus what the
fleet views query without opening JSON:

* ``runs``: the record, its ``station_id``, ``socket``, ``lot`` (labels), the unit's
  ``model`` and the ``spec_sha256`` it was judged by, the ``digest`` it was sent with;
* ``measurements``: one row per judged measurement (value, unit, limits, outcome);
* ``specs``: each spec once, by content hash (its ``version`` is the hash's first 12 hex
  digits: an edited limit is a new version whether or not somebody renamed the file).

JSON documents (parameters, station snapshot, results, event data) are kept as the station
wrote them (``text``): JSON with NaN and infinities, which ``jsonb`` would refuse, round-trips.
Times of day are the stations' ISO 8601 UTC strings (they sort as text; ``left(started_utc,
10)`` is the day).
"""

from __future__ import annotations

import uuid
from typing import Any

SCHEMA_VERSION = 1
#: any constant: the advisory lock under which one station at a time creates the tables
_DDL_LOCK = 0x62656E6368  # "bench"

DDL = [
    """CREATE TABLE IF NOT EXISTS meta (key text PRIMARY KEY, value text NOT NULL)""",
    """CREATE TABLE IF NOT EXISTS specs (
        sha256  text PRIMARY KEY,
        version text NOT NULL,
        model   text,
        kind    text,
        spec    text NOT NULL)""",
    """CREATE TABLE IF NOT EXISTS runs (
        uuid            uuid PRIMARY KEY,
        local_id        text NOT NULL,
        source_store    uuid NOT NULL,
        station_id      text NOT NULL,
        socket          text,
        lot             text,
        procedure       text NOT NULL,
        unit_serial     text,
        model           text,
        spec_sha256     text REFERENCES specs (sha256),
        parameters_json text NOT NULL,
        station_json    text NOT NULL,
        labels_json     text NOT NULL,
        seed            numeric,
        code_version    text NOT NULL,
        started_utc     text NOT NULL,
        ended_utc       text,
        status          text NOT NULL,
        reason          text,
        last_sample_t_s double precision,
        digest          text NOT NULL,
        n_samples       bigint NOT NULL,
        received_utc    timestamptz NOT NULL DEFAULT now(),
        UNIQUE (source_store, local_id))""",
    "CREATE INDEX IF NOT EXISTS runs_by_serial ON runs (unit_serial, started_utc)",
    "CREATE INDEX IF NOT EXISTS runs_by_model ON runs (model, started_utc)",
    "CREATE INDEX IF NOT EXISTS runs_by_start ON runs (started_utc)",
    "CREATE INDEX IF NOT EXISTS runs_by_local_id ON runs (local_id)",
    """CREATE TABLE IF NOT EXISTS streams (
        run_uuid     uuid NOT NULL REFERENCES runs (uuid),
        name         text NOT NULL,
        position     integer NOT NULL,
        columns_json text NOT NULL,
        description  text NOT NULL,
        PRIMARY KEY (run_uuid, name))""",
    """CREATE TABLE IF NOT EXISTS chunks (
        run_uuid uuid NOT NULL,
        stream   text NOT NULL,
        seq      integer NOT NULL,
        n_rows   integer NOT NULL CHECK (n_rows > 0),
        dtypes   text NOT NULL,
        data     bytea NOT NULL,
        PRIMARY KEY (run_uuid, stream, seq),
        FOREIGN KEY (run_uuid, stream) REFERENCES streams (run_uuid, name))""",
    """CREATE TABLE IF NOT EXISTS events (
        run_uuid  uuid NOT NULL REFERENCES runs (uuid),
        seq       integer NOT NULL,
        t_s       double precision,
        kind      text NOT NULL,
        message   text NOT NULL,
        data_json text NOT NULL,
        PRIMARY KEY (run_uuid, seq))""",
    """CREATE TABLE IF NOT EXISTS results (
        run_uuid   uuid NOT NULL REFERENCES runs (uuid),
        position   integer NOT NULL,
        key        text NOT NULL,
        value_json text NOT NULL,
        PRIMARY KEY (run_uuid, key))""",
    """CREATE TABLE IF NOT EXISTS attachments (
        run_uuid    uuid NOT NULL REFERENCES runs (uuid),
        name        text NOT NULL,
        mime        text NOT NULL,
        sha256      text NOT NULL,
        created_utc text NOT NULL,
        data        bytea NOT NULL,
        PRIMARY KEY (run_uuid, name))""",
    """CREATE TABLE IF NOT EXISTS measurements (
        run_uuid    uuid NOT NULL REFERENCES runs (uuid),
        name        text NOT NULL,
        value       double precision,
        uncertainty double precision,
        unit        text NOT NULL,
        low         double precision,
        high        double precision,
        marginal    double precision,
        outcome     text NOT NULL,
        PRIMARY KEY (run_uuid, name))""",
    "CREATE INDEX IF NOT EXISTS measurements_by_name ON measurements (name)",
]


def ensure_schema(conn: Any) -> uuid.UUID:
    """Create the tables if needed (one station at a time), check the version; return the
    central store's own UUID (what a station's ``forwarded`` table names it by)."""
    with conn.transaction():
        conn.execute("SELECT pg_advisory_xact_lock(%s)", (_DDL_LOCK,))
        for statement in DDL:
            conn.execute(statement)
        conn.execute("INSERT INTO meta (key, value) VALUES ('schema_version', %s), "
                     "('store_uuid', %s) ON CONFLICT (key) DO NOTHING",
                     (str(SCHEMA_VERSION), str(uuid.uuid4())))
        rows = dict(conn.execute("SELECT key, value FROM meta").fetchall())
    if int(rows["schema_version"]) != SCHEMA_VERSION:
        raise RuntimeError(f"central store schema_version {rows['schema_version']} but this code "
                           f"reads version {SCHEMA_VERSION}; use the matching bench version")
    return uuid.UUID(rows["store_uuid"])
