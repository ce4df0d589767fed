"""``bench run <step>``: each calibration step on its own, parameters as options."""

from __future__ import annotations

import dataclasses
import json

import pytest

from bench.app.cli import main
from bench.app.commands.follow_ups import ANALYSES
from procedures.catalogue import CATALOGUE


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


def _help(argv: list[str], capsys, monkeypatch) -> str:
    """``bench <argv> --help`` as printed, unwrapped and whitespace normalised."""
    monkeypatch.setenv("COLUMNS", "2000")
    with pytest.raises(SystemExit) as done:
        main([*argv, "--help"])
    assert done.value.code == 0
    return " ".join(capsys.readouterr().out.split())


@pytest.mark.parametrize("name", list(CATALOGUE))
def test_every_step_is_a_command_with_an_option_per_parameter_each_with_help(name, capsys, monkeypatch):
    step = CATALOGUE.step(name)
    assert f"{name} {' '.join(step.summary().split())}" in _help(["run"], capsys, monkeypatch)  # listed, with its help
    text = _help(["run", name], capsys, monkeypatch)
    for f in dataclasses.fields(step.Parameters):
        kind = "INT" if f.type == "int" else "FLOAT"
        shown = "the station's" if f.default is None else (f"{f.default:g}" if kind == "FLOAT" else str(f.default))
        help_text = " ".join(f.metadata["help"].split())
        assert f"--{f.name.replace('_', '-')} {kind}" in text and f"{help_text} [{shown}]" in text, (name, f.name)
    if step.follow_up is not None:
        assert step.follow_up.analysis in ANALYSES and "--report DIR" in text
        assert ("--analyze" in text) == step.follow_up.on_request
        assert " ".join(step.follow_up.summary.split()) in text
    if name == "vibration":
        assert "--frame-rate-hz INT, --rate-hz INT" in text  # the option users know, kept


def test_an_old_step_name_is_told_the_new_one(tmp_path, capsys):
    assert main(["--store", str(tmp_path / "b.sqlite"), "run", "gyro_startup", "--duration-s", "300"]) == 2
    err = capsys.readouterr().err
    assert "bench run gyro_startup is now bench run gyro_turn_on" in err and err.count("\n") == 1
    assert main(["--store", str(tmp_path / "b.sqlite"), "run", "vibration", "--report", str(tmp_path)]) == 2
    assert "--report DIR needs --analyze (the report is the vibration model's)" in capsys.readouterr().err
    assert not (tmp_path / "b.sqlite").exists()  # refused before any run
