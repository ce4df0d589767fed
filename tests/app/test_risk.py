"""``bench risk`` on a real two-process Dask cluster (scheduler and workers as their own
processes on loopback): the verdicts are the serial ones, unit for unit, even when a worker
is killed mid-run and its unit runs again elsewhere."""

from __future__ import annotations

import json
import os
import signal
import socket
import sqlite3
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from distributed import Client

from bench.app.cli import main
from bench.app.risk import assess, run_unit, unit_seeds
from bench.core.spec import load_spec
from procedures.catalogue import CATALOGUE

SPEC = str(Path(__file__).resolve().parents[2] / "bench" / "specs" / "qa2000-sim.toml")
UNITS, SEED = 2, 11


def test_unit_seeds_depend_on_seed_and_index_only():
    assert unit_seeds(11, 2) == unit_seeds(11, 2)
    seeds = {unit_seeds(s, i) for s in (0, 1) for i in range(50)}
    assert len(seeds) == 100 and all(0 <= w < 2**63 for w, _ in seeds)
    with pytest.raises(ValueError, match="index"):
        unit_seeds(0, -1)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _running(store: Path) -> int:
    if not store.exists():
        return 0
    try:
        with sqlite3.connect(f"file:{store}?mode=ro", uri=True, timeout=5) as conn:
            return int(conn.execute("SELECT count(*) FROM runs WHERE status = 'running'").fetchone()[0])
    except sqlite3.OperationalError:
        return 0


@pytest.fixture
def cluster():
    """A scheduler and two workers, each its own process; no nanny: a killed worker stays dead."""
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    env = dict(os.environ, DASK_DISTRIBUTED__WORKER__DAEMON="False")
    scheduler = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host",
                                  "127.0.0.1", "--port", str(port), "--no-dashboard"],
                                 stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
    workers = [subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", address,
                                 "--nthreads", "1", "--no-nanny", "--no-dashboard", "--host",
                                 "127.0.0.1"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                env=env) for _ in range(2)]

    with Client(address, timeout="60s") as client:
        client.wait_for_workers(2, timeout=60)
    try:
        yield address, workers
    finally:
        for p in [*workers, scheduler]:
            p.kill()
            p.wait()


def test_cluster_verdicts_are_the_serial_ones_through_a_killed_worker(tmp_path, cluster):
    address, workers = cluster
    store, out = tmp_path / "risk.sqlite", tmp_path / "out.json"
    codes: list[int] = []

    def command() -> None:  # `bench risk --scheduler` as a user runs it
        with open(out, "w") as f:
            stdout, sys.stdout = sys.stdout, f
            try:
                codes.append(main(["--store", str(store), "risk", "--spec", SPEC, "--units",
                                   str(UNITS), "--seed", str(SEED), "--scheduler", address, "--json"]))
            finally:
                sys.stdout = stdout

    serial: list[dict] = []  # the reference, run here meanwhile (the units mostly wait on sockets)
    reference = threading.Thread(target=lambda: serial.extend(
        run_unit(SPEC, i, SEED, str(tmp_path / "serial.sqlite")) for i in range(UNITS)))
    runner = threading.Thread(target=command)
    runner.start()
    reference.start()
    deadline = time.monotonic() + 120
    while _running(store) < 2 and time.monotonic() < deadline:  # both workers inside a unit
        time.sleep(0.1)
    workers[0].send_signal(signal.SIGKILL)
    runner.join(timeout=300)
    reference.join(timeout=300)
    assert not runner.is_alive() and codes == [0] and len(serial) == UNITS
    with sqlite3.connect(store) as conn:  # the killed unit's partial run is kept, and was redone
        statuses = [s for (s,) in conn.execute("SELECT status FROM runs")]
    assert len(statuses) == UNITS + 1 and statuses.count("running") + statuses.count("aborted") == 1

    doc = json.loads(out.read_text())
    assert doc["verdicts"] == [s["status"] for s in serial]
    for c, s in zip(doc["units_detail"], serial):
        assert (c["index"], c["serial"], c["seed"], c["truth"]) == (s["index"], s["serial"], s["seed"],
                                                                    s["truth"])
        assert c["measurements"] == s["measurements"]  # same floats, bit for bit
    report = assess(load_spec(SPEC, CATALOGUE), SEED, serial)
    assert report.to_dict()["measurements"] == doc["measurements"]
    assert doc["yield"]["trials"] == UNITS and np.isfinite(doc["measurements"]["k1"]["error_sd"])
    assert doc["measurements"]["k0"]["error_sd"] < 0.1  # mg: the tumble finds K0 far better


def test_risk_refuses_bad_arguments_before_any_worker(tmp_path, capsys):
    assert main(["--store", str(tmp_path / "s.sqlite"), "risk", "--spec", SPEC, "--units", "1"]) == 2
    assert "--units 1 not in 2..1000000" in capsys.readouterr().err
    assert main(["--store", str(tmp_path / "s.sqlite"), "risk", "--spec", SPEC, "--units", "5",
                 "--scheduler", "localhost:1"]) == 2
    assert "tcp://HOST:PORT" in capsys.readouterr().err
