"""Eight stations, each its own process, write and forward runs at once while the central
server is killed and restarted: every run arrives exactly once, with the content it left with."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import psycopg

from bench.core.store import RunStore
from bench.core.store.forward import package

STATIONS, RUNS = 8, 20
ROOT = Path(__file__).resolve().parents[2]


def _count(url: str) -> int:
    try:
        with psycopg.connect(url, connect_timeout=2) as conn:
            row = conn.execute("SELECT count(*) FROM runs").fetchone()
            return -1 if row is None else int(row[0])
    except (psycopg.OperationalError, psycopg.errors.UndefinedTable):  # down, or no station yet
        return -1


def test_eight_stations_forward_through_a_server_crash_without_loss_or_duplicate(
        tmp_path, pg_server, central_url):
    procs = [subprocess.Popen([sys.executable, "-m", "tests.core.fleet_station",
                               str(tmp_path / f"st{i}.sqlite"), central_url, f"ST{i}", str(RUNS)],
                              cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for i in range(STATIONS)]
    try:
        deadline = time.monotonic() + 120
        while _count(central_url) < STATIONS * RUNS // 4 and time.monotonic() < deadline:
            time.sleep(0.2)
        assert _count(central_url) < STATIONS * RUNS, "the stations finished before the crash"
        pg_server.stop("immediate")  # as a crash: uncommitted transactions are lost
        time.sleep(2.0)
        pg_server.start()
        outputs = [p.communicate(timeout=240) for p in procs]
    finally:
        for p in procs:
            p.kill()
        pg_server.start()  # left running for the other tests, whatever happened
    reports = []
    for (out, err), p in zip(outputs, procs):
        assert p.returncode == 0, err
        reports.append(json.loads(out))
    assert all(r["final"]["pending"] == [] and r["final"]["conflicts"] == [] for r in reports)
    assert any(r["after_each"] < RUNS for r in reports), "no forward ever met the crash"
    with psycopg.connect(central_url) as conn:
        rows = conn.execute("SELECT station_id, local_id, digest, n_samples FROM runs").fetchall()
        (n_chunks,) = conn.execute("SELECT count(*) FROM chunks").fetchall()[0]
        (n_measurements,) = conn.execute("SELECT count(*) FROM measurements").fetchall()[0]
    assert len(rows) == STATIONS * RUNS  # none lost, none doubled (uuid is the primary key)
    assert len({(s, r) for s, r, _, _ in rows}) == STATIONS * RUNS
    assert n_chunks == 4 * STATIONS * RUNS and n_measurements == STATIONS * RUNS
    central = {(s, r): (d, n) for s, r, d, n in rows}
    for i, report in enumerate(reports):
        store = RunStore(tmp_path / f"st{i}.sqlite")
        assert len(report["runs"]) == RUNS and store.unforwarded_run_ids() == []
        for run_id in report["runs"]:
            pkg = package(store, run_id)
            assert central[(f"ST{i}", run_id)] == (pkg.digest, 10000)
