"""The simulated station as a user meets it: `bench sim serve` in its own process, reached
only through the addresses it prints (one JSON line per instrument)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
import pyvisa

SEED = 7
#: what a user who wants a meter and a supply for their own scripts starts
ONLY = "dmm,supply"


@pytest.fixture(scope="session")
def served():
    """``{name: VISA resource}`` of ``bench sim serve --only dmm,supply`` (plus ``sim``): one
    server for the session (per worker); every test starts from ``*RST``."""
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen([sys.executable, "-m", "bench.app.cli", "sim", "serve", "--seed", str(SEED),
                             "--only", ONLY], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=env)
    try:
        resources = {}
        for _ in range(len(ONLY.split(",")) + 1):  # the instruments, then the sim-control endpoint
            line = proc.stdout.readline()
            if not line:
                raise RuntimeError(f"bench sim serve ended: {proc.stderr.read()}")
            entry = json.loads(line)
            resources[entry["name"]] = entry["resource"]
        yield resources
    finally:
        proc.terminate()
        proc.wait(10)


@pytest.fixture(scope="session")
def raw(served):
    """Plain pyvisa sessions by instrument name, for setting the scene around a driver."""
    rm = pyvisa.ResourceManager("@py")
    sessions = {name: rm.open_resource(res, read_termination="\n", write_termination="\n",
                                       timeout=10_000) for name, res in served.items()}
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
