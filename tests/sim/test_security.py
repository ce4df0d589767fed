"""Security limits (issue 8 item 6): loopback by default (a warning otherwise), message and
block sizes refused without allocating them, and configuration/CSV parsing that never
evaluates its input."""

from __future__ import annotations

import ast
import socket
import time
import tracemalloc
from pathlib import Path

import pytest

from bench.app.cli import main
from bench.app.commands.analyze import read_csv_columns
from bench.app.station import StationError, load_station
from sim.scpi import MessageFramer, Oversize
from sim.server import InstrumentServer
from sim.station import SimStationConfig, SimulatedStation

ROOT = Path(__file__).resolve().parents[2]
EVIL = "__import__('os').system('touch {flag}')"


@pytest.fixture(scope="module")
def station(served_station):
    return served_station


# -- listening address ---------------------------------------------------------------------
def test_every_simulated_server_listens_on_loopback_only(station):
    """Every listener: each instrument's own port and its further wires (HiSLIP, ``Endpoint.also``)."""
    endpoints = [*station.endpoints, *(other for e in station.endpoints for other in e.also.values())]
    assert len(endpoints) > len(station.endpoints)  # the HiSLIP listeners are counted too
    assert all(e.host == "127.0.0.1" for e in endpoints)
    listeners = station.server._servers + station.server._also_servers
    bound = [s.getsockname()[0] for server in listeners for s in server.sockets]
    assert len(bound) == len(endpoints) and set(bound) == {"127.0.0.1"}


@pytest.mark.parametrize("host", ["0.0.0.0", "192.168.1.20", "::"])
def test_another_address_warns(host):
    with pytest.warns(UserWarning, match="reachable from the network"):
        InstrumentServer(host)
    with pytest.warns(UserWarning, match=host.replace(".", r"\.")):
        SimulatedStation(SimStationConfig(host=host))  # built, never started


@pytest.mark.parametrize("host", ["127.0.0.1", "localhost", "::1"])
def test_loopback_addresses_do_not_warn(host, recwarn):
    InstrumentServer(host)
    assert not [w for w in recwarn if "reachable" in str(w.message)]


# -- size limits -----------------------------------------------------------------------------
def test_huge_declared_block_is_refused_before_its_payload():
    framer = MessageFramer(1 << 20)
    assert framer.feed(b"*ESE #9999999999") == [Oversize(1 << 20)]  # at the header, at once
    tracemalloc.start()
    try:
        chunk = b"\xa5" * (1 << 20)
        base, _ = tracemalloc.get_traced_memory()
        for _ in range(64):  # 64 MiB of the announced 10 GB: discarded, never kept
            assert framer.feed(chunk) == []
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak - base < 4 << 20
    assert framer.feed(b"\n*IDN?\n") == [b"*IDN?"]  # resynchronised at the next LF


def test_over_long_message_is_dropped_and_memory_stays_bounded():
    framer = MessageFramer(1 << 16)
    out = []
    for _ in range(100):  # 6.4 MB without a terminator
        out += framer.feed(b"A" * (1 << 16))
        assert len(framer._buf) <= 1 << 16
    assert out == [Oversize(1 << 16)]
    assert framer.feed(b"\nSYST:ERR?\n") == [b"SYST:ERR?"]


def test_server_answers_oversize_at_once_and_stays_usable(station):
    with socket.create_connection(("127.0.0.1", _port(station, "dmm")), timeout=5) as s:
        s.sendall(b"*ESE #9999999999\nSYST:ERR?\n")
        assert _line(s).startswith(b'-223,"Too much data')
        s.sendall(b"*SRE " + b"9" * ((1 << 20) + 10) + b"\nSYST:ERR?\n*IDN?\n")
        assert _line(s).startswith(b'-223,"Too much data')
        assert _line(s).startswith(b"Keysight Technologies,34465A,")


def test_gyro_line_buffer_is_bounded(station):
    station.server.call(station.supply.process, b"APPL CH1,5,1;:OUTP ON,(@1)")
    with socket.create_connection(("127.0.0.1", _port(station, "gyro")), timeout=5) as s:
        for _ in range(64):  # 4 MiB without a line end
            s.sendall(b"$" * (1 << 16))
        assert len(station.server.call(lambda: bytes(station.gyro_line._rx))) <= 64 + (1 << 16)
        s.sendall(b"\r\n$ID?\r\n")
        assert _line(s).startswith(b"$ERR,4,")
        assert _line(s).startswith(b"$ID,")


def _port(sim, name):
    return next(e.port for e in sim.endpoints if e.name == name)


def _line(sock) -> bytes:
    data = b""
    deadline = time.monotonic() + 10
    while not data.endswith(b"\n") and time.monotonic() < deadline:
        data += sock.recv(1)
    return data


# -- parsing never evaluates input ------------------------------------------------------------
FORBIDDEN_CALLS = {"eval", "exec", "compile", "__import__", "execfile", "input"}
FORBIDDEN_MODULES = {"pickle", "marshal", "shelve", "yaml", "dill", "cloudpickle"}


def _python_files():
    for package in ("bench", "sim", "instruments", "procedures"):
        yield from (ROOT / package).rglob("*.py")


def test_no_code_evaluation_or_unsafe_deserialisation_in_the_code_base():
    offences = []
    for path in _python_files():
        tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) \
                    and node.func.id in FORBIDDEN_CALLS:
                offences.append(f"{path.relative_to(ROOT)}:{node.lineno} {node.func.id}()")
            if isinstance(node, ast.Import | ast.ImportFrom):
                names = [a.name for a in node.names] if isinstance(node, ast.Import) else [node.module or ""]
                offences += [f"{path.relative_to(ROOT)}:{node.lineno} import {n}" for n in names
                             if n.split(".")[0] in FORBIDDEN_MODULES]
    assert offences == []


def test_station_file_values_are_data(tmp_path):
    flag = tmp_path / "owned"
    bad_driver = tmp_path / "driver.toml"
    bad_driver.write_text('[instruments.dmm]\ndriver = "os:system"\naddress = "x"\n')
    with pytest.raises(StationError, match="driver 'os:system' not in"):
        load_station(bad_driver)
    evil = tmp_path / "evil.toml"
    evil.write_text(f'[station]\nname = "{EVIL.format(flag=flag)}"\n'
                    f'[instruments.dmm]\ndriver = "keysight_34465a"\n'
                    f'address = "{EVIL.format(flag=flag)}"\ntimeout_ms = 500\n')
    config = load_station(evil)
    assert config.instruments["dmm"].address == EVIL.format(flag=flag)  # kept as text
    assert main(["doctor", "--station", str(evil)]) == 1  # an address nothing can open
    assert not flag.exists()


def test_csv_cells_are_data(tmp_path):
    flag = tmp_path / "owned"
    path = tmp_path / "evil.csv"
    path.write_text(f't_s,v\n0,1\n1,"{EVIL.format(flag=flag)}"\n')
    with pytest.raises(ValueError, match="line 3, column 'v'.*is not a number"):
        read_csv_columns(path, "t_s", "v")
    assert not flag.exists()
