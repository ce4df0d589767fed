"""The central store on a real PostgreSQL server: forwarding is whole, once, and survives
the server going away; reading gives back exactly what the station stored."""

from __future__ import annotations

import math
import sqlite3

import numpy as np
import psycopg
import pytest

from bench.core.store import SCHEMA_VERSION, RunStore
from bench.core.store.central import CentralStore
from bench.core.store.forward import package, queued, sync
from bench.core.store.reader import is_central_url, masked


def write_run(store: RunStore, serial: str, n: int = 1000, *, status: str = "passed",
              station_id: str = "st-1", seed: int = 3) -> str:
    rng = np.random.default_rng(seed)
    with store.create_run(procedure="acceptance", parameters={"n": n, "nan": math.nan},
                          station={"name": "sim"}, unit_serial=serial, seed=2**63 + 5,
                          code_version="test", labels={"station_id": station_id, "lot": "L1",
                                                       "socket": "2"}) as run:
        run.add_stream("dmm", {"t_s": "s", "voltage_v": "V"})
        run.add_stream("flags", {"t_s": "s", "ok": ""}, dtypes={"ok": "bool"})
        for k in range(3):
            t = np.arange(k * n, (k + 1) * n) * 0.01
            run.append("dmm", t_s=t, voltage_v=rng.standard_normal(n))
            run.append("flags", t_s=t[:10], ok=np.ones(10, bool))
        run.event(1.0, "step_start", "tumble", position=3)
        run.event(float("nan"), "warning", "clock unknown")
        run.attach("raw.bin", b"\x00\x01", "application/octet-stream")
        run.set_result("acceptance.spec", {"model": "QA-T", "kind": "accelerometer",
                                           "source": "/somewhere/qa.toml", "measurements": []})
        run.set_result("measurement.k0", {"name": "k0", "value": 1.5, "unit": "mg", "low": -4.0,
                                          "high": 4.0, "marginal": 0.4, "outcome": "pass",
                                          "uncertainty": 0.01})
        run.set_result("measurement.k1", {"name": "k1", "value": None, "unit": "mA/g", "low": 1.2,
                                          "high": 1.46, "marginal": 0.0, "outcome": "fail",
                                          "uncertainty": None})
        if status == "aborted":
            run.finish("aborted", "RuntimeError: table stalled")
        else:
            run.finish(status)
    return run.id


def test_a_synced_run_reads_back_exactly(tmp_path, central_url):
    store = RunStore(tmp_path / "s.sqlite")
    run_id = write_run(store, "QA-1")
    aborted = write_run(store, "QA-2", status="aborted")
    report = sync(store, central_url)
    assert report.stored == [run_id, aborted] and report.complete and report.samples == 2 * 3030
    with CentralStore(central_url) as central:
        local, remote = store.get_run(run_id), central.get_run(store.run_uuid(run_id))
        assert remote.id == remote.uuid == local.uuid
        for key in ("procedure", "unit_serial", "seed", "code_version", "started_utc", "ended_utc",
                    "status", "reason", "labels", "results", "station"):
            assert getattr(remote, key) == getattr(local, key), key
        assert math.isnan(remote.parameters["nan"])
        assert central.get_run(run_id).uuid == local.uuid  # the station's id names it too
        assert central.streams(run_id) == store.streams(run_id)
        for stream in ("dmm", "flags"):
            got, want = central.load(run_id, stream), store.load(run_id, stream)
            assert list(got) == list(want)
            for col in want:
                assert got[col].dtype == want[col].dtype
                np.testing.assert_array_equal(got[col], want[col])
        ev_local, ev_remote = store.events(run_id), central.events(run_id)
        assert [e[1:] for e in ev_remote] == [e[1:] for e in ev_local]
        assert math.isnan(ev_remote[1].t_s)
        assert central.attachment(run_id, "raw.bin") == b"\x00\x01"
        assert central.get_run(aborted).reason == "RuntimeError: table stalled"
        rows = central.connection.execute(
            "SELECT station_id, socket, lot, model, name, value, outcome FROM runs JOIN "
            "measurements ON run_uuid = uuid WHERE local_id = %s ORDER BY name", (run_id,)).fetchall()
        assert rows == [("st-1", "2", "L1", "QA-T", "k0", 1.5, "pass"),
                        ("st-1", "2", "L1", "QA-T", "k1", None, "fail")]


def test_sync_is_idempotent_and_resumes_after_a_lost_acknowledgement(tmp_path, central_url):
    store = RunStore(tmp_path / "s.sqlite")
    first = write_run(store, "QA-1")
    assert sync(store, central_url).stored == [first]
    second = write_run(store, "QA-2")
    again = sync(store, central_url)
    assert again.stored == [second] and again.present == []  # the first is not sent again
    # The central store committed but the station never recorded it (killed in between).
    with sqlite3.connect(tmp_path / "s.sqlite") as conn:
        conn.execute("DELETE FROM forwarded WHERE run_id = ?", (second,))
    third = sync(store, central_url)
    assert third.stored == [] and third.present == [second] and third.complete
    with psycopg.connect(central_url) as conn:
        assert conn.execute("SELECT count(*) FROM runs").fetchone()[0] == 2
        assert conn.execute("SELECT count(*) FROM chunks").fetchone()[0] == 2 * 6


def test_a_run_with_other_content_under_the_same_uuid_is_never_overwritten(tmp_path, central_url):
    store = RunStore(tmp_path / "s.sqlite")
    run_id = write_run(store, "QA-1")
    with psycopg.connect(central_url) as conn:
        central = CentralStore(central_url)
        pkg = package(store, run_id)
        central.receive(pkg)
        central.close()
        conn.execute("UPDATE runs SET digest = 'tampered'")
    report = sync(store, central_url)
    assert report.conflicts == [run_id] and not report.complete and "tampered"[:8] in report.error
    assert queued(store, str(CentralStore(central_url).uuid)) == [run_id]  # still queued


def test_an_unreachable_server_leaves_every_run_queued(tmp_path):
    store = RunStore(tmp_path / "s.sqlite")
    ids = [write_run(store, f"QA-{i}") for i in range(2)]
    report = sync(store, "postgresql://bench@127.0.0.1:9/bench", connect_timeout_s=1)
    assert report.pending == ids and report.stored == [] and "OperationalError" in report.error


def test_an_analysis_attached_after_the_sync_follows_it(tmp_path, central_url):
    store = RunStore(tmp_path / "s.sqlite")
    run_id = write_run(store, "QA-1")
    sync(store, central_url)
    store.attach_analysis(run_id, "analysis/report.html", b"<html>v1</html>", "text/html")
    assert sync(store, central_url).present == [run_id]
    store.attach_analysis(run_id, "analysis/report.html", b"<html>v2</html>", "text/html")
    assert sync(store, central_url).present == [run_id]
    assert sync(store, central_url).present == []
    with CentralStore(central_url) as central:
        assert central.attachment(run_id, "analysis/report.html") == b"<html>v2</html>"


def test_urls_are_told_apart_and_passwords_masked():
    assert is_central_url("postgresql://u@h/db") and not is_central_url("bench-data/b.sqlite")
    assert masked("postgresql://u:secret@h:5/db") == "postgresql://u:***@h:5/db"
    with pytest.raises(ValueError, match="postgresql://"):
        CentralStore("bench.sqlite")


def test_a_version_1_store_is_migrated_in_place(tmp_path):
    path = tmp_path / "old.sqlite"
    store = RunStore(path)
    run_id = write_run(store, "QA-1")
    store.close()
    with sqlite3.connect(path) as conn:  # back to what version 1 wrote
        conn.execute("DROP TABLE forwarded")
        conn.execute("ALTER TABLE runs DROP COLUMN labels_json")
        conn.execute("ALTER TABLE runs DROP COLUMN origin_uuid")
        conn.execute("UPDATE meta SET value = '1' WHERE key = 'schema_version'")
        conn.execute("DELETE FROM meta WHERE key = 'store_uuid'")
    reopened = RunStore(path)
    assert reopened.schema_version() == SCHEMA_VERSION == 3  # through version 2 (sync) to 3 (import)
    assert reopened.get_run(run_id).labels == {}
    assert reopened.unforwarded_run_ids() == [run_id]
    assert reopened.run_uuid(run_id) == RunStore(path).run_uuid(run_id)  # the uuid is kept
