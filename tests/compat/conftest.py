"""The simulated station as a user meets it: `bench sim serve` in its own process, reached
only through the addresses it prints (one JSON line per address: every instrument's raw socket,
then its HiSLIP address).  The drivers' fixtures take ``addresses`` and so run once per address
form; ``raw`` sets the scene around them over the sockets."""

from __future__ import annotations

import pytest
import pyvisa

from tests.compat.serving import PYVISA_OPTIONS, TRANSPORT_IDS, TRANSPORTS, serve


@pytest.fixture(scope="session")
def served():
    """``{(name, transport): VISA resource}`` of ``bench sim serve --only dmm,supply`` (plus
    ``sim``), both address forms: one server for the session (per worker); every test starts
    from ``*RST``."""
    with serve() as resources:
        yield resources


@pytest.fixture(scope="module", params=TRANSPORTS, ids=TRANSPORT_IDS)
def transport(request) -> str:
    """The address form a module's drivers use: each runs over the raw socket, then HiSLIP."""
    return request.param


@pytest.fixture(scope="module")
def addresses(served, transport) -> dict[str, str]:
    """``{name: VISA resource}`` in the address form under test."""
    return {name: resource for (name, form), resource in served.items() if form == transport}


@pytest.fixture(scope="session")
def raw(served):
    """Plain pyvisa sessions over the raw sockets by instrument name, for setting the scene
    around a driver."""
    rm = pyvisa.ResourceManager("@py")
    sessions = {name: rm.open_resource(res, **PYVISA_OPTIONS["scpi"])
                for (name, form), res in served.items() if form == "scpi"}
    yield sessions
    for s in sessions.values():
        s.close()
    rm.close()


@pytest.fixture
def powered(raw):
    """±15 V on the accelerometer's rails (CH2, CH3), 100 mA limits: its output, about
    6.6 V across the sampling resistor, reaches the DMM.  Switched off afterwards."""
    raw["supply"].write("APPL CH2,15,0.1;APPL CH3,15,0.1;:OUTP ON,(@2,3)")
    assert raw["supply"].query("SYST:ERR?") == '+0,"No error"'
    yield raw
    raw["supply"].write("OUTP OFF,(@1:3)")
