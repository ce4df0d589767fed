"""The fleet's questions, asked of the central store in SQL: yield counts by group, one
measurement's values in time order, every run of one unit.  Statistics on the answers are the
library's (``bench.analysis.quality._proportion``, ``bench.analysis.quality._control_chart``)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from .central import CentralStore

#: --by choice -> the SQL expression that groups runs
GROUPS = {
    "model": "COALESCE(r.model, r.procedure)",
    "spec": "COALESCE(r.model || ' ' || s.version, '-')",
    "lot": "COALESCE(r.lot, '-')",
    "station": "r.station_id",
    "day": "left(r.started_utc, 10)",
}


@dataclass(frozen=True)
class YieldCount:
    group: str
    passed: int
    failed: int
    aborted: int


def yield_counts(central: CentralStore, by: str, *, model: str | None = None) -> list[YieldCount]:
    """Acceptance runs per group: passed, failed, aborted (a unit re-tested counts each time)."""
    if by not in GROUPS:
        raise ValueError(f"--by {by!r} not in {', '.join(GROUPS)}")
    rows = central.connection.execute(
        f"SELECT {GROUPS[by]} AS g, count(*) FILTER (WHERE r.status = 'passed'), "
        "count(*) FILTER (WHERE r.status = 'failed'), count(*) FILTER (WHERE r.status = 'aborted') "
        "FROM runs r LEFT JOIN specs s ON s.sha256 = r.spec_sha256 "
        "WHERE r.procedure = 'acceptance' AND (%s::text IS NULL OR r.model = %s) "
        "GROUP BY g ORDER BY g", (model, model)).fetchall()
    return [YieldCount(str(g), int(p), int(f), int(a)) for g, p, f, a in rows]


@dataclass(frozen=True)
class MeasurementPoint:
    started_utc: str
    value: float
    unit: str
    low: float | None
    high: float | None
    outcome: str
    station_id: str
    lot: str | None
    unit_serial: str | None
    run_uuid: str


def measurement_series(central: CentralStore, name: str, *, model: str | None = None,
                       station: str | None = None) -> list[MeasurementPoint]:
    """Every produced value of measurement ``name`` (finished runs), oldest first."""
    rows = central.connection.execute(
        "SELECT r.started_utc, m.value, m.unit, m.low, m.high, m.outcome, r.station_id, r.lot, "
        "r.unit_serial, r.uuid::text FROM measurements m JOIN runs r ON r.uuid = m.run_uuid "
        "WHERE m.name = %s AND m.value IS NOT NULL AND (%s::text IS NULL OR r.model = %s) "
        "AND (%s::text IS NULL OR r.station_id = %s) ORDER BY r.started_utc, r.uuid",
        (name, model, model, station, station)).fetchall()
    return [MeasurementPoint(*row) for row in rows]


def measurement_names(central: CentralStore) -> list[str]:
    return [r[0] for r in central.connection.execute(
        "SELECT DISTINCT name FROM measurements ORDER BY name").fetchall()]


def unit_runs(central: CentralStore, serial: str) -> list[dict[str, Any]]:
    """Every run of the unit ``serial`` on every station, oldest first, with its measurements."""
    runs = central.connection.execute(
        "SELECT uuid::text, local_id, station_id, socket, lot, procedure, model, started_utc, "
        "ended_utc, status, reason, n_samples FROM runs WHERE unit_serial = %s "
        "ORDER BY started_utc, uuid", (serial,)).fetchall()
    keys = ("uuid", "run_id", "station_id", "socket", "lot", "procedure", "model", "started_utc",
            "ended_utc", "status", "reason", "n_samples")
    out = []
    for row in runs:
        doc = dict(zip(keys, row))
        doc["measurements"] = [
            dict(zip(("name", "value", "unit", "low", "high", "outcome"), m))
            for m in central.connection.execute(
                "SELECT name, value, unit, low, high, outcome FROM measurements WHERE run_uuid = %s "
                "ORDER BY name", (doc["uuid"],)).fetchall()]
        out.append(doc)
    return out
