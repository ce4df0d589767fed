"""Shared fixtures: hypothesis profiles and the simulated station.

Tests that need a station take one of these instead of building their own:

* ``sim_station``    — a started station (seed 7), one per test;
* ``served_station`` — a started station (seed 0), shared by the tests of one module;
* ``station_factory`` — ``station_factory(seed=0, serve=False, **config)``: a station with
  its own seed and ``SimStationConfig`` options, its devices driven directly or (``serve``)
  served on loopback; served ones are stopped when the module's tests are done.

Hypothesis tests that draw a seed build their stations in the test (a fixture is not redrawn
per example).

The central store's tests take a real PostgreSQL server, started once per test session (per
xdist worker) by ``scripts/pg`` in a temporary folder on a free port:

* ``pg_server``  — the server (``url(database)``, ``stop()``, ``start()``: a test may stop and
  restart it, and must leave it running);
* ``central_url`` — a fresh, empty database on it, one per test.
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import tempfile
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import psycopg
import pytest
from hypothesis import HealthCheck, settings

from sim.station import SimStationConfig, SimulatedStation

# Fixed seeds in CI: every hypothesis run derandomised, no flaky deadlines on 2 cores.
settings.register_profile("ci", derandomize=True, deadline=None, print_blob=True,
                          suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("dev", deadline=None)
settings.load_profile("ci" if os.environ.get("CI") else os.environ.get("HYPOTHESIS_PROFILE", "dev"))

StationFactory = Callable[..., SimulatedStation]


@pytest.fixture
def sim_station() -> Iterator[SimulatedStation]:
    """A started simulated station (world + servers on free loopback ports)."""
    with SimulatedStation(SimStationConfig(seed=7)) as station:
        yield station


@pytest.fixture(scope="module")
def served_station() -> Iterator[SimulatedStation]:
    """A started simulated station with the default configuration, shared by a module."""
    with SimulatedStation() as station:
        yield station


@pytest.fixture(scope="module")
def station_factory() -> Iterator[StationFactory]:
    """Build stations with their own seed and options; served ones stop with the module."""
    started: list[SimulatedStation] = []

    def make(seed: int = 0, *, serve: bool = False, **config: Any) -> SimulatedStation:
        station = SimulatedStation(SimStationConfig(seed=seed, **config))
        if serve:
            station.start()
            started.append(station)
        return station

    yield make
    for station in started:
        station.stop()


PG_SCRIPT = Path(__file__).resolve().parent.parent / "scripts" / "pg"


class PgServer:
    """A PostgreSQL server of the test session, driven by ``scripts/pg``."""

    def __init__(self, data: Path, port: int) -> None:
        self.data, self.port = data, port

    def _pg(self, *args: str) -> str:
        done = subprocess.run([sys.executable, str(PG_SCRIPT), *args, "--dir", str(self.data)],
                              capture_output=True, text=True)
        if done.returncode != 0:
            raise RuntimeError(f"scripts/pg {' '.join(args)}: {done.stderr.strip()}")
        return done.stdout.strip()

    def start(self) -> str:
        return self._pg("start", "--port", str(self.port))

    def stop(self, mode: str = "fast") -> None:
        self._pg("stop", "--mode", mode)

    def url(self, database: str = "bench") -> str:
        return f"postgresql://bench@127.0.0.1:{self.port}/{database}"


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture(scope="session")
def pg_server() -> Iterator[PgServer]:
    """A PostgreSQL server for this test session (``scripts/pg``; as root it runs as postgres)."""
    parent = Path(tempfile.mkdtemp(prefix="bench-pg-"))
    parent.chmod(0o755)  # the postgres user must reach its data folder when we are root
    server = PgServer(parent / "data", _free_port())
    server.start()
    try:
        yield server
    finally:
        server.stop("immediate")
        subprocess.run(["rm", "-rf", str(parent)], check=False)


@pytest.fixture
def central_url(pg_server: PgServer) -> str:
    """A fresh, empty database on the session's server: its URL."""
    name = f"t_{uuid.uuid4().hex[:12]}"
    with psycopg.connect(pg_server.url("postgres"), autocommit=True) as conn:
        conn.execute(f"CREATE DATABASE {name}")
    return pg_server.url(name)
