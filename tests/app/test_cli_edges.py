"""The command line's rough edges, each pinned by its exit code and message: ``--store`` after the
command, a store that is not there, exports under ``bench-data/exports/``, a run's attachment
by name, a spec mistake named by its measurement, a refused connection said as refused, a port
in use named in one line."""

from __future__ import annotations

import json
import socket

import numpy as np
import pytest

from bench.app.cli import main
from bench.core.spec import SpecError, parse_spec
from bench.core.store import RunStore
from instruments.wire import InstrumentConnectionError
from procedures.catalogue import CATALOGUE


def cli(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.fixture
def store(tmp_path) -> str:
    path = tmp_path / "s.sqlite"
    with RunStore(path) as s, s.create_run(procedure="thermal_sweep", parameters={}, station={}, unit_serial="U1",
                                           seed=1, code_version="t") as run:
        run.add_stream("dmm", {"t_s": "s", "voltage_v": "V"})
        run.append("dmm", t_s=np.arange(3.0), voltage_v=np.ones(3))
        run.attach("thermal_compensation.toml", b"[bias]\nc0 = 1.0\n", "application/toml")
        run.finish("completed")
    return str(path)


def test_store_is_taken_after_the_command_too(store, capsys):
    before = cli(capsys, "--store", store, "runs", "list", "--json")
    after = cli(capsys, "runs", "list", "--json", "--store", store)
    assert before[0] == after[0] == 0 and json.loads(before[1]) == json.loads(after[1])
    assert json.loads(after[1])[0]["unit_serial"] == "U1"


def test_a_store_that_is_not_there_is_an_error(tmp_path, capsys):
    missing = str(tmp_path / "typo.sqlite")
    for argv in (["runs", "list"], ["runs", "show", "latest"], ["runs", "export", "latest"]):
        code, out, err = cli(capsys, "--store", missing, *argv)
        assert code == 2 and not out and err == f"bench: error: no run store at {missing} (run a procedure " \
                                                "first, or --store PATH)\n", (argv, err)
    assert not (tmp_path / "typo.sqlite").exists()  # reading never creates one


def test_export_goes_under_bench_data_exports(store, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    code, out, _ = cli(capsys, "--store", store, "runs", "export", "latest")
    run_id = json.loads(cli(capsys, "--store", store, "runs", "list", "--json")[1])[0]["id"]
    assert code == 0 and out.splitlines()[0] == f"bench-data/exports/{run_id}/{run_id}.dmm.csv"
    code, out, _ = cli(capsys, "--store", store, "runs", "export", "latest", "--format", "hdf5")
    assert code == 0 and out.strip() == f"bench-data/exports/{run_id}.h5"
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(("export-", run_id))]  # nothing in the folder


def test_an_attachment_comes_out_by_name(store, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    code, out, _ = cli(capsys, "--store", store, "runs", "attachment", "latest")
    assert code == 0 and out.split()[0] == "thermal_compensation.toml"
    code, out, _ = cli(capsys, "--store", store, "runs", "attachment", "latest", "thermal_compensation.toml")
    assert code == 0 and (tmp_path / "thermal_compensation.toml").read_bytes() == b"[bias]\nc0 = 1.0\n"
    code, out, _ = cli(capsys, "--store", store, "runs", "attachment", "latest", "thermal_compensation.toml",
                       "--out", str(tmp_path / "unit" / "u1.toml"))
    assert code == 0 and (tmp_path / "unit" / "u1.toml").read_bytes() == b"[bias]\nc0 = 1.0\n"
    code, _, err = cli(capsys, "--store", store, "runs", "attachment", "latest", "report.html")
    assert code == 2 and "has no attachment 'report.html'; it has ['thermal_compensation.toml']" in err


def test_a_spec_mistake_is_named_by_its_measurement():
    spec = {"unit": {"model": "M", "kind": "accelerometer", "serial_pattern": "M-*"},
            "procedures": {"tumble": {"positions": 8, "planes": 1}},
            "measurements": [{"name": "k0", "procedure": "tumble", "unit": "mg", "low": -4, "hihg": 4}]}
    with pytest.raises(SpecError, match=r"x.toml: measurement 'k0': unknown key\(s\) \['hihg'\]"):
        parse_spec(spec, CATALOGUE, "x.toml")
    del spec["measurements"][0]["name"]
    with pytest.raises(SpecError, match=r"x.toml: measurement #1 \(no name\): unknown key\(s\)"):
        parse_spec(spec, CATALOGUE, "x.toml")


def test_a_refused_connection_is_said_as_refused():
    refused = InstrumentConnectionError("dmm", "open", ConnectionRefusedError(111, "Connection refused"))
    lost = InstrumentConnectionError("dmm", "READ?", ConnectionResetError(104, "Connection reset by peer"))
    assert str(refused).startswith("dmm: connection refused at 'open'")
    assert str(lost).startswith("dmm: connection lost at 'READ?'")


def test_a_port_in_use_is_one_line_and_exit_2(tmp_path, capsys):
    with socket.socket() as holder:
        holder.bind(("127.0.0.1", 0))
        holder.listen()
        port = holder.getsockname()[1]
        code, out, err = cli(capsys, "--store", str(tmp_path / "s.sqlite"), "station", "serve", "--port", str(port))
    assert code == 2 and not out  # the success line is never printed
    assert err == (f"bench: error: --port {port}: 127.0.0.1:{port} is in use by another program; stop it or "
                   "give another --port (0: any free one)\n")
