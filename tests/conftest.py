"""Shared fixtures: hypothesis profiles and the simulated station."""

from __future__ import annotations

import os

import pytest
from hypothesis import HealthCheck, settings

# Fixed seeds in CI: every hypothesis run derandomised, no flaky deadlines on 2 cores.
settings.register_profile("ci", derandomize=True, deadline=None, print_blob=True,
                          suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("dev", deadline=None)
settings.load_profile("ci" if os.environ.get("CI") else os.environ.get("HYPOTHESIS_PROFILE", "dev"))


@pytest.fixture
def sim_station():
    """A started simulated station (world + servers on free loopback ports)."""
    from sim.station import SimStationConfig, SimulatedStation

    station = SimulatedStation(SimStationConfig(seed=7))
    station.start()
    yield station
    station.stop()
