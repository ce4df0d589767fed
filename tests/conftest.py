"""Shared fixtures: hypothesis profiles and the simulated station.

Tests that need a station take one of these instead of building their own:

* ``sim_station``    — a started station (seed 7), one per test;
* ``served_station`` — a started station (seed 0), shared by the tests of one module;
* ``station_factory`` — ``station_factory(seed=0, serve=False, **config)``: a station with
  its own seed and ``SimStationConfig`` options, its devices driven directly or (``serve``)
  served on loopback; served ones are stopped when the module's tests are done.

Hypothesis tests that draw a seed build their stations in the test (a fixture is not redrawn
per example).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from typing import Any

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
