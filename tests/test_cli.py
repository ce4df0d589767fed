"""The bench CLI: exit codes, one-line errors, JSON output, and `bench sim serve` over a pipe."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
import pyvisa

from bench.cli import main


def test_run_startup_json_then_runs_list_show_export(tmp_path, capsys):
    store = str(tmp_path / "b.sqlite")
    code = main(["--store", store, "run", "startup", "--duration-s", "30", "--off-wait-s", "5",
                 "--seed", "4", "--json"])
    doc = json.loads(capsys.readouterr().out)
    assert code == 0 and doc["status"] == "passed"
    assert {m["name"] for m in doc["measurements"]} == {"level_check_g", "readings_lost"}
    assert main(["--store", store, "runs", "list"]) == 0
    assert doc["run_id"] in capsys.readouterr().out
    assert main(["--store", store, "runs", "show", "latest", "--json"]) == 0
    shown = json.loads(capsys.readouterr().out)
    assert shown["id"] == doc["run_id"] and shown["status"] == "passed"
    assert main(["--store", store, "runs", "export", doc["run_id"], "--format", "csv",
                 "--out", str(tmp_path / "csv")]) == 0
    paths = capsys.readouterr().out.split()
    output_csv = [p for p in paths if p.endswith(".output.csv")][0]
    with open(output_csv) as f:
        assert f.readline().strip() == "t_s,voltage_v,acceleration_g"
        assert sum(1 for _ in f) == 31 * 100
    assert main(["--store", store, "runs", "export", "latest", "--format", "hdf5",
                 "--out", str(tmp_path / "r.h5")]) == 0


@pytest.mark.parametrize("argv,fragment", [
    (["run", "startup", "--rate-hz", "99999"], "rate_hz = 99999.0 not in 0.01..5000"),
    (["run", "startup", "--station", "nope.toml"], "station file 'nope.toml' not found"),
    (["runs", "show", "no-such-run"], "no-such-run"),
    (["run", "startup", "--seed", "-3"], "--seed -3"),
])
def test_user_errors_exit_2_with_one_line(tmp_path, capsys, argv, fragment):
    code = main(["--store", str(tmp_path / "b.sqlite"), *argv])
    err = capsys.readouterr().err
    assert code == 2
    assert fragment in err and err.count("\n") == 1 and "Traceback" not in err


def test_bad_station_file_is_named(tmp_path, capsys):
    bad = tmp_path / "lab.toml"
    bad.write_text('[instruments.dmm]\ndriver = "fluke_8846a"\naddress = "TCPIP::1.2.3.4::5025::SOCKET"\n')
    assert main(["--store", str(tmp_path / "b.sqlite"), "run", "startup", "--station", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "fluke_8846a" in err and "keysight_34465a" in err


def test_sim_serve_prints_resources_that_plain_pyvisa_can_use():
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen([sys.executable, "-m", "bench.cli", "sim", "serve", "--seed", "5"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        lines = [json.loads(proc.stdout.readline()) for _ in range(5)]
        by_name = {d["name"]: d for d in lines}
        assert set(by_name) == {"dmm", "dmm_temp", "supply", "turntable", "sim"}
        assert all(d["resource"].startswith("TCPIP::127.0.0.1::") and
                   d["resource"].endswith("::SOCKET") for d in lines)
        rm = pyvisa.ResourceManager("@py")
        sim = rm.open_resource(by_name["sim"]["resource"], read_termination="\n",
                               write_termination="\n", timeout=5000)
        assert sim.query("SIM:SEED?").strip() == "5"
        sim.close()
        rm.close()
    finally:
        proc.terminate()
        proc.wait(10)
    assert proc.returncode == 0
