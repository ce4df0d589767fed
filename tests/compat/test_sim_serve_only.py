"""`bench sim serve --only`: just the instruments a user's own scripts need."""

from __future__ import annotations

import pytest

from bench.app.cli import main
from sim.station import SimulatedStation


def test_only_the_named_instruments_and_the_sim_endpoint_are_served(served):
    assert set(served) == {"dmm", "supply", "sim"}


def test_an_unknown_name_is_one_line_naming_the_allowed_ones(capsys):
    assert main(["sim", "serve", "--only", "dmm,psu"]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1
    assert "psu" in err and "allowed: dmm, dmm_temp, supply" in err


def test_the_world_is_the_same_whatever_is_served():
    with pytest.raises(ValueError, match="instrument lamp not on the simulated station"):
        SimulatedStation(only=["lamp"])
    whole, part = SimulatedStation(), SimulatedStation(only=["dmm"])
    for station in (whole, part):
        station.dmm.process(b"CONF:VOLT:DC 10;:SAMP:COUN 50")
    assert whole.dmm.process(b"READ?") == part.dmm.process(b"READ?")  # same seed, same bytes
