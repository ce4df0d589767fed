"""The bench CLI: exit codes, one-line errors, JSON output, and `bench sim serve` over a pipe."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
import pyvisa

from bench.app.cli import main
from bench.core.store import RunStore


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
    (["run", "startup", "--rate-hz", "99999"], "rate_hz = 99999.0 not in 0.01..1000"),
    (["run", "startup", "--station", "nope.toml"], "station file 'nope.toml' not found"),
    (["runs", "show", "no-such-run"], "no run store at"),  # and nothing is created
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
    proc = subprocess.Popen([sys.executable, "-m", "bench.app.cli", "sim", "serve", "--seed", "5"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        lines = [json.loads(proc.stdout.readline()) for _ in range(12)]
        by_name = {d["name"]: d for d in lines}
        assert set(by_name) == {"dmm", "dmm_temp", "supply", "turntable", "gyro", "shaker", "angular_table",
                                "dmm_mhd", "lf_gyro", "chamber", "daq", "sim"}
        serial, modbus = {"gyro", "lf_gyro"}, {"chamber"}
        assert all(d["resource"].startswith("TCPIP::127.0.0.1::") and
                   d["resource"].endswith("::SOCKET") for d in lines if d["name"] not in serial | modbus)
        assert all(by_name[n]["resource"].startswith("socket://127.0.0.1:") for n in serial)  # pyserial URLs
        assert by_name["chamber"]["resource"].startswith("modbus://127.0.0.1:")  # a pymodbus client's
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


@pytest.mark.parametrize("text,fragment", [
    ("instruments = 3\n", "'instruments' = 3 must be a table"),
    ('station = "x"\n', "'station' = 'x' must be a table"),
    ("[wiring]\npositive_rail_channel = 2.5\n", "positive_rail_channel = 2.5 must be a whole number in 1..3"),
    ("[wiring]\nnegative_rail_channel = 2\n", "both channel 2"),
    ('[simulation]\nlatitude_deg = "north"\n', "latitude_deg = 'north' must be a number"),
    ("[simulation]\nseed = -4\n", "seed = -4 not in 0..2**63-1"),
    ("[simulation]\nwarp_factor = 9\n", "warp_factor"),
    ("[simulation.accelerometer]\nk1_ma_per_g = 99.0\n", "k1_ma_per_g"),
    ("[instruments.dmm]\ndriver = \"keysight_34465a\"\naddress = \"TCPIP::127.0.0.1::1::SOCKET\"\n",
     "cannot open instrument 'dmm' (keysight_34465a) at 'TCPIP::127.0.0.1::1::SOCKET'"),
    ("[calibration]\nx = 1\n", "unknown table(s) ['calibration']"),
])
def test_bad_station_files_fail_before_any_run_with_the_key_named(tmp_path, capsys, text, fragment):
    station = tmp_path / "lab.toml"
    station.write_text(text)
    store = str(tmp_path / "b.sqlite")
    assert main(["--store", store, "run", "startup", "--station", str(station)]) == 2
    err = capsys.readouterr().err
    assert fragment in err and err.count("\n") == 1, err
    # no run was created (nor, a bad station file stopping the command first, a store)
    if main(["--store", store, "runs", "list", "--json"]) == 2:
        assert "no run store at" in capsys.readouterr().err
    else:
        assert json.loads(capsys.readouterr().out) == []


def test_station_without_the_needed_instruments_is_refused_before_a_run(tmp_path, capsys):
    station = tmp_path / "lab.toml"
    station.write_text("[station]\nname = 'empty'\n")
    store = str(tmp_path / "b.sqlite")
    assert main(["--store", store, "run", "startup", "--station", str(station)]) == 2
    assert "lacks ['dmm', 'dmm_temp', 'supply', 'turntable']" in capsys.readouterr().err


def test_level_check_out_of_tolerance_is_a_failed_run_exit_1(tmp_path, capsys):
    # the simulated fixture has a 2.5 kΩ resistor while the station wiring says 5 kΩ
    station = tmp_path / "lab.toml"
    station.write_text("[simulation]\nsampling_resistor_ohm = 2500.0\nseed = 9\n"
                       "[simulation.accelerometer]\nk1_ma_per_g = 1.33\n")  # nominal K1
    store = str(tmp_path / "b.sqlite")
    code = main(["--store", store, "run", "startup", "--station", str(station), "--json"])
    doc = json.loads(capsys.readouterr().out)
    assert code == 1 and doc["status"] == "failed" and "level_check_g" in doc["reason"]
    assert doc["measurements"][0]["value"] == pytest.approx(0.5, abs=0.01)
    main(["--store", store, "runs", "show", doc["run_id"], "--json"])
    shown = json.loads(capsys.readouterr().out)
    assert shown["seed"] == 9  # the station file's seed is used when --seed is absent


def test_run_startup_analyze_attaches_the_start_up_model(tmp_path, capsys):
    store = str(tmp_path / "b.sqlite")
    code = main(["--store", store, "run", "startup", "--duration-s", "120", "--off-wait-s", "5",
                 "--seed", "6", "--analyze", "--json"])
    doc = json.loads(capsys.readouterr().out)
    assert code == 0 and doc["status"] == "passed"
    model = doc["analysis"]["model"]
    assert model["kind"] in ("AR", "MA", "ARMA") and model["p"] + model["q"] >= 1
    assert set(doc["analysis"]["trend"]) >= {"offset", "exp_amplitude", "exp_tau_s",
                                             "linear_slope_per_s"}

    with RunStore(store) as s:
        names = {a.name for a in s.attachments(doc["run_id"])}
        html = s.attachment(doc["run_id"], "analysis/startup/startup_report.html")
    assert {"analysis/startup/startup_report.html", "analysis/startup/startup_model.json"} <= names
    assert b"<html" in html.lower()


def test_unknown_run_in_an_existing_store_is_named(tmp_path, capsys):
    store = str(tmp_path / "b.sqlite")
    assert main(["--store", store, "run", "startup", "--duration-s", "5", "--off-wait-s", "1",
                 "--json"]) == 0
    capsys.readouterr()
    assert main(["--store", store, "runs", "show", "no-such-run"]) == 2
    assert "no-such-run" in capsys.readouterr().err
    assert main(["--store", str(tmp_path / "none.sqlite"), "analyze", "run", "latest"]) == 2
    assert "no run store at" in capsys.readouterr().err
    assert not (tmp_path / "none.sqlite").exists()


def test_analysis_failure_after_a_run_still_names_the_run(tmp_path, capsys):
    store = str(tmp_path / "b.sqlite")
    code = main(["--store", store, "run", "startup", "--duration-s", "5", "--rate-hz", "10",
                 "--off-wait-s", "0", "--analyze", "--json"])
    captured = capsys.readouterr()
    doc = json.loads(captured.out)
    assert code == 2 and doc["status"] == "passed" and doc["run_id"] in doc["analysis_error"]
    assert doc["run_id"] in captured.err and "samples" in captured.err
    assert main(["--store", store, "run", "startup", "--report", str(tmp_path)]) == 2
    assert "--report DIR needs --analyze" in capsys.readouterr().err


def test_attached_report_is_listed_and_exported(tmp_path, capsys):
    store = str(tmp_path / "b.sqlite")
    assert main(["--store", store, "run", "startup", "--duration-s", "60", "--off-wait-s", "1",
                 "--analyze", "--json"]) == 0
    run_id = json.loads(capsys.readouterr().out)["run_id"]
    assert main(["--store", store, "runs", "show", run_id]) == 0
    assert "analysis/startup/startup_report.html" in capsys.readouterr().out
    assert main(["--store", store, "runs", "export", run_id, "--out", str(tmp_path / "x")]) == 0
    exported = tmp_path / "x" / f"{run_id}.attachments" / "analysis" / "startup"
    assert (exported / "startup_report.html").read_bytes().lower().count(b"<html") == 1
