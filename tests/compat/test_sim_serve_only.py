"""`bench sim serve --only`: just the instruments a user's own scripts need."""

from __future__ import annotations

import re

import pytest

from bench.app.cli import main
from sim.station import SimulatedStation


def test_only_the_named_instruments_and_the_sim_endpoint_are_served(served):
    assert {name for name, _ in served} == {"dmm", "supply", "sim"}


def test_each_is_served_on_a_raw_socket_and_on_hislip(served):
    assert set(served) == {(name, form) for name in ("dmm", "supply", "sim") for form in ("scpi", "hislip")}
    for (name, form), resource in served.items():
        if form == "scpi":
            assert re.fullmatch(r"TCPIP::127\.0\.0\.1::\d+::SOCKET", resource), name
        else:
            assert re.fullmatch(r"TCPIP::127\.0\.0\.1::hislip0,\d+::INSTR", resource), name
    assert len(set(served.values())) == 6  # a port of its own each


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
