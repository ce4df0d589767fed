"""The sample records under docs/examples/ (made by ``scripts/make_record_examples.py`` from the
simulated station's own runs) are read, analysed and imported as the how-to page says, and the
file's analysis agrees with the station run's own result, within the two stated uncertainties."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest

from bench.app.cli import main
from bench.app.records import KINDS, MIN_ROWS, read_meta, read_record
from bench.testing.docs import run_block, runnable_blocks

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "docs" / "examples"
HOWTO = ROOT / "docs" / "howto" / "import.md"
#: what reference.json holds: the station run's measurements per sample (file stem)
REFERENCE: dict[str, Any] = json.loads((EXAMPLES / "reference.json").read_text(encoding="utf-8"))
#: sample (file stem) -> (kind, the station measurements its analysis must reproduce)
SAMPLES = {
    "tumble": ("tumble", ("k0", "k1", "delta_o", "delta_p")),
    "ratetable": ("ratetable", ("scale_factor_error", "bias", "nonlinearity", "asymmetry")),
    "turn_on": ("turn-on", ("turn_on_repeatability", "turn_on_raw_sd", "day_to_day", "within_day")),
    "thermal": ("thermal", ()),
}
ANALYSED = [name for name, (_, names) in SAMPLES.items() if names]
#: a sample file the docs ship stays small
MAX_BYTES = 300_000


def files(name: str) -> tuple[str, str]:
    return str(EXAMPLES / f"{name}.csv"), str(EXAMPLES / f"{name}.toml")


def cli(capsys, argv: list[str]) -> tuple[int, str, str]:
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def agree(a: dict[str, Any], b: dict[str, Any], scale: float = 1.0) -> bool:
    """|a − b| ≤ 3·√(σa² + σb²), ``a`` scaled into ``b``'s unit."""
    sa, sb = scale * (a["uncertainty"] or 0.0), b["uncertainty"] or 0.0
    return abs(scale * a["value"] - b["value"]) <= 3.0 * math.hypot(sa, sb)


def check_against_station(name: str, measurements: list[dict[str, Any]]) -> None:
    _, required = SAMPLES[name]
    found = {m["name"]: m for m in measurements}
    station = REFERENCE[name]["measurements"]
    assert set(required) <= set(found) and set(required) <= set(station)
    for key in required:
        assert found[key]["uncertainty"] is not None and found[key]["uncertainty"] >= 0
        assert agree(found[key], station[key]), (key, found[key], station[key])


@pytest.mark.parametrize("name", list(SAMPLES))
def test_each_example_parses_under_its_metadata(name):
    csv_path, toml_path = files(name)
    assert Path(csv_path).stat().st_size < MAX_BYTES
    meta = read_meta(toml_path)
    kind, _ = SAMPLES[name]
    assert meta.kind == kind and meta.sensor in ("gyro", "accelerometer") and meta.unit_serial
    record = read_record(csv_path, meta)
    assert record.n_rows >= MIN_ROWS[kind]
    assert set(record.data) >= {c.name for c in KINDS[kind].columns if c.required}
    assert all(len(v) == record.n_rows for v in record.data.values())


def test_the_examples_use_foreign_headers_the_convention_matches():
    """At least two samples are written with a logger's own headers, units in brackets."""
    foreign = 0
    for name in SAMPLES:
        csv_path, toml_path = files(name)
        record = read_record(csv_path, read_meta(toml_path))
        if any("[" in header for header in record.conversions.values()):
            foreign += 1
    assert foreign >= 2
    record = read_record(*_record_args("thermal"))
    assert record.conversions["temperature_c"] == "Case T [degC]" and record.units["temperature_c"] == "degC"


def _record_args(name: str):
    csv_path, toml_path = files(name)
    return csv_path, read_meta(toml_path)


@pytest.mark.parametrize("name", ANALYSED)
def test_example_analysis_agrees_with_the_station_run(name, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    csv_path, toml_path = files(name)
    kind, _ = SAMPLES[name]
    code, out, err = cli(capsys, ["analyze", kind, "--input", csv_path, "--meta", toml_path, "--json"])
    assert code == 0, err
    doc = json.loads(out)
    assert doc["kind"] == kind and doc["source"] == csv_path
    check_against_station(name, doc["measurements"])


def test_thermal_example_is_analysed(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    csv_path, toml_path = files("thermal")
    code, out, err = cli(capsys, ["analyze", "thermal", "--input", csv_path, "--meta", toml_path, "--json"])
    assert code == 0, err
    doc = json.loads(out)
    found = {m["name"]: m for m in doc["measurements"]}
    station = REFERENCE["thermal"]["measurements"]["bias_tc"]  # deg/h per °C: the ramp analysis reads °/h
    # without an applied input the bias TC is in the output's unit per °C: the file's is °/s
    scale = {"deg/s": 3600.0, "deg/h": 1.0}[doc["units"]["output"]]
    assert found["bias_tc"]["uncertainty"] is not None
    assert agree(found["bias_tc"], station, scale), (found["bias_tc"], station)


def import_sample(capsys, store: Path, name: str, *extra: str) -> str:
    csv_path, toml_path = files(name)
    code, out, err = cli(capsys, ["--store", str(store), "runs", "import", csv_path, "--meta", toml_path, "--json",
                                  *extra])
    assert code == 0, err
    return json.loads(out)["run_id"]


@pytest.mark.parametrize("name", list(SAMPLES))
def test_example_imports_as_a_run(name, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    store = tmp_path / "runs.sqlite"
    kind, required = SAMPLES[name]
    run_id = import_sample(capsys, store, name)
    code, out, err = cli(capsys, ["--store", str(store), "runs", "show", run_id, "--json"])
    assert code == 0, err
    doc = json.loads(out)
    record = read_record(*_record_args(name))
    assert doc["procedure"] == KINDS[kind].procedure and doc["status"] == "completed"
    assert doc["unit_serial"] == record.meta.unit_serial and doc["labels"]["station_id"] == "bench-sim"
    stream = doc["streams"]["record"]
    assert stream["n_rows"] == record.n_rows and stream["columns"] == record.units
    assert doc["parameters"]["source_sha256"] == record.sha256
    if required:
        check_against_station(name, doc["measurements"])


def test_discover_runs_on_the_imported_thermal_record(capsys, tmp_path, monkeypatch):
    """The thermal sample is a gyro at rest: discovery reads the imported record like a station's."""
    monkeypatch.chdir(tmp_path)
    store = tmp_path / "runs.sqlite"
    run_id = import_sample(capsys, store, "thermal", "--no-analysis")
    code, out, err = cli(capsys, ["--store", str(store), "discover", "--run", run_id, "--out", str(tmp_path / "d"),
                                  "--jobs", "1", "--no-progress", "--json"])
    assert code == 0, err
    doc = json.loads(out)
    assert doc["source"] == f"run {run_id} (thermal_record, stream record)"
    assert isinstance(doc["effects"], list) and Path(doc["report"]).is_file()


def test_the_import_page_runnable_block_runs(tmp_path):
    """The how-to page's runnable block works in an empty folder, as a reader pastes it."""
    for block in runnable_blocks(HOWTO):
        done = run_block(block, tmp_path)
        assert done.returncode == 0, f"{block.text}\n--- stderr\n{done.stderr[-2000:]}"
