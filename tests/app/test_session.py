"""``bench.app.session``: the station from Python, as the CLI uses it."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bench.app import session
from bench.core.store import RunStore

ROOT = Path(__file__).resolve().parents[2]


def test_make_step_validates_parameters_before_any_station_opens():
    step = session.make_step("tumble", positions=24, planes=2)
    assert step.p.positions == 24 and step.p.planes == 2
    with pytest.raises(ValueError, match=r"no parameter bogus.*positions"):
        session.make_step("tumble", bogus=1)
    with pytest.raises(LookupError):
        session.make_step("no_such_step")


def test_seed_and_unit_rules_name_the_allowed_range():
    config = session.station_config("sim")
    assert session.station_seed(config, None) == 0
    assert session.station_seed(config, 5) == 5
    with pytest.raises(ValueError, match=r"seed -1 not in 0\.\.2\*\*63-1"):
        session.station_seed(config, -1)
    assert session.station_unit(config, "gyro") == "FOG-SIM-0001"
    assert session.station_unit(config, "gyro", "FOG-X") == "FOG-X"
    with pytest.raises(ValueError, match="unit kind 'laser'"):
        session.station_unit(config, "laser")


def test_choose_spec_by_serial_and_a_clear_error_for_an_unknown_one():
    assert session.choose_spec(None, "QA-SIM-0003").kind == "accelerometer"
    assert session.choose_spec(None, "FOG-SIM-0002").kind == "gyro"
    with pytest.raises(ValueError) as error:
        session.choose_spec(None, "XYZ-1")
    assert str(error.value) == ("no built-in spec matches unit 'XYZ-1' (serials it knows: FOG-SIM-* → FOG-T-SIM, "
                                "QA-SIM-* → QA-2000-SIM); give a spec file")  # no None among them


def test_a_step_run_from_python_is_stored_and_read_back_whole(tmp_path):
    store = tmp_path / "runs.sqlite"
    outcome = session.run_step("tumble", unit="QA-SIM-0003", seed=3, store=store, positions=12, planes=2)
    assert outcome.status == "passed"
    k1 = outcome.measurement("k1")
    assert k1.unit == "mA/g" and 1.2 < k1.value < 1.46 and 0 < k1.uncertainty < 1e-3
    with pytest.raises(LookupError, match="no measurement 'k9'"):
        outcome.measurement("k9")

    run = session.read_run("latest", store=store)
    assert run.run_id == outcome.run_id and run.info.seed == 3 and run.info.unit_serial == "QA-SIM-0003"
    assert run.measurement("k1").value == k1.value and run.measurement("k1").std == k1.uncertainty
    arrays = run.arrays("tumble")
    assert len(arrays["voltage_v"]) == 24  # 12 positions x 2 planes, every one stored
    frame = run.frame("tumble")
    assert list(frame.columns) == list(arrays) and np.array_equal(frame["voltage_v"].to_numpy(), arrays["voltage_v"])
    # the same seed gives the same run: a script is as reproducible as the CLI
    again = session.run_step("tumble", unit="QA-SIM-0003", seed=3, store=RunStore(store), positions=12, planes=2)
    assert again.measurement("k1").value == k1.value


def test_read_run_names_what_is_missing(tmp_path):
    with pytest.raises(LookupError, match="no run store at"):
        session.read_run(store=tmp_path / "none.sqlite")


def test_the_documented_script_runs_and_prints_k0_and_k1(tmp_path):
    """docs/examples/tumble_from_python.py, the API page's example, run as a user would."""
    script = ROOT / "docs" / "examples" / "tumble_from_python.py"
    assert len(script.read_text().splitlines()) <= 15
    env = {k: v for k, v in os.environ.items() if k != "BENCH_STORE"}
    done = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[0].endswith(": passed")
    assert lines[1].startswith("k0 = ") and lines[1].endswith(" g")
    assert lines[2].startswith("k1 = ") and lines[2].endswith(" mA/g") and " ± " in lines[2]
    assert (tmp_path / "bench-data" / "bench.sqlite").is_file()
