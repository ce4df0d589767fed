"""What a user reads off `bench sim serve` and hands to a driver: the addresses it prints (one
JSON line per address: the raw sockets first, then the HiSLIP address of each of the same
instruments) and the VISA options each address form needs."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager

SEED = 7
#: what a user who wants a meter and a supply for their own scripts starts
ONLY = "dmm,supply"
#: the two address forms of every SCPI instrument, by the "transport" its line names: the raw
#: socket (``TCPIP::host::PORT::SOCKET``) and HiSLIP (``TCPIP::host::hislip0,PORT::INSTR``)
TRANSPORTS = ("scpi", "hislip")
#: what the tests call them (``test_x[socket]``, ``test_x[hislip]``)
TRANSPORT_IDS = ("socket", "hislip")

#: pyvisa options per address form: a raw socket has no end-of-message, so a user sets the LF
#: terminations every SCPI-over-socket script sets; over HiSLIP the defaults (a message ends with
#: its DataEnd).  The same generous timeout on both: the suite shares 2 cores in CI.
PYVISA_OPTIONS: dict[str, dict[str, object]] = {
    "scpi": dict(read_termination="\n", write_termination="\n", timeout=10_000),
    "hislip": dict(timeout=10_000),
}


def pymeasure_options(transport: str) -> dict[str, object]:
    """The keyword arguments a PyMeasure driver takes for an address of this form."""
    return dict(visa_library="@py", **PYVISA_OPTIONS[transport])


@contextmanager
def serve(*options: str) -> Iterator[dict[tuple[str, str], str]]:
    """``bench sim serve --seed SEED --only ONLY [options]`` in its own process, until the block
    ends: ``{(name, transport): VISA resource}`` from every line it printed — the sockets of the
    instruments and of ``sim``, then their HiSLIP addresses."""
    expected = {(name, transport) for name in (*ONLY.split(","), "sim") for transport in TRANSPORTS}
    command = [sys.executable, "-m", "bench.app.cli", "sim", "serve", "--seed", str(SEED), "--only", ONLY,
               *options]
    with tempfile.TemporaryFile("w+") as stderr, subprocess.Popen(
            command, stdout=subprocess.PIPE, stderr=stderr, text=True,
            env={**os.environ, "PYTHONUNBUFFERED": "1"}) as proc:
        assert proc.stdout is not None
        try:
            resources: dict[tuple[str, str], str] = {}
            while not expected <= resources.keys():
                line = proc.stdout.readline()
                if not line:
                    proc.wait(10)
                    stderr.seek(0)
                    raise RuntimeError(f"bench sim serve ended after {sorted(resources)}: {stderr.read()}")
                entry = json.loads(line)
                resources[(entry["name"], entry["transport"])] = entry["resource"]
            yield resources
        finally:
            proc.terminate()
            proc.wait(10)


def qcodes_parameters(instrument) -> dict:
    """Every parameter of a QCoDeS driver and its submodules (channels), by dotted name."""
    found = dict(instrument.parameters)
    for sub_name, sub in instrument.submodules.items():
        found.update({f"{sub_name}.{n}": p for n, p in sub.parameters.items()})
    return found
