"""``bench run <step>``: each calibration step on its own, parameters as options."""

from __future__ import annotations

import json

from bench.app.cli import main


def test_tumble_step_from_the_command_line(tmp_path, capsys):
    code = main(["--store", str(tmp_path / "b.sqlite"), "run", "tumble", "--positions", "4",
                 "--planes", "1", "--warmup-s", "10", "--average-s", "2", "--json"])
    doc = json.loads(capsys.readouterr().out)
    assert code == 0 and doc["status"] == "passed"
    names = {m["name"] for m in doc["measurements"]}
    assert {"k0", "k1", "k2", "delta_p"} <= names and "k3" not in names  # 4-point: K3 hides in K1
    k1 = next(m for m in doc["measurements"] if m["name"] == "k1")
    assert 1.2 < k1["value"] < 1.46 and k1["unit"] == "mA/g"


def test_ratetable_step_from_the_command_line(tmp_path, capsys):
    code = main(["--store", str(tmp_path / "b.sqlite"), "run", "ratetable", "--rates-per-sign", "2",
                 "--min-record-s", "5", "--warmup-s", "10", "--frame-rate-hz", "100", "--json",
                 "--unit", "FOG-SIM-0003"])
    doc = json.loads(capsys.readouterr().out)
    assert code == 0 and {m["name"] for m in doc["measurements"]} == {
        "scale_factor_error", "bias", "nonlinearity", "asymmetry"}


def test_bad_step_parameters_exit_2_naming_the_value(tmp_path, capsys):
    assert main(["--store", str(tmp_path / "b.sqlite"), "run", "tumble", "--positions", "6"]) == 2
    assert "positions = 6 must be a multiple of 4" in capsys.readouterr().err
    assert main(["--store", str(tmp_path / "b.sqlite"), "run", "gyro_noise", "--frame-rate-hz", "0"]) == 2
    assert "frame_rate_hz = 0" in capsys.readouterr().err
