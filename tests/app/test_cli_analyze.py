"""``bench analyze startup|run`` through a fresh argparse parser built with ``configure``."""

from __future__ import annotations

import argparse
import json

import numpy as np
import pytest
from scipy.signal import lfilter

from bench.app.commands.analyze import configure
from bench.core.store import RunStore
from bench.testing.reports import assert_self_contained


def run(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="bench")
    configure(parser.add_subparsers(dest="command", required=True).add_parser("analyze"))
    args = parser.parse_args(argv)
    return args.func(args)


def startup_csv(path, n=3000, header=("t", "y"), rows=None) -> str:
    rng = np.random.default_rng(0)
    t = np.arange(n) * 0.5
    y = 1.3 + 4e-4 * np.exp(-t / 120) + lfilter([1], [1, -0.6], rng.normal(0, 1e-5, n))
    lines = [",".join(header)] + [f"{a:.6f},{b:.10g}" for a, b in zip(t, y)]
    if rows:
        for i, row in rows.items():
            lines[i] = row
    path.write_text("\n".join(lines) + "\n")
    return str(path)


def test_json_output_has_the_issue_keys(tmp_path, capsys):
    csv_path = startup_csv(tmp_path / "trace.csv")
    assert run(["analyze", "startup", "--input", csv_path, "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    for key in ("offset", "exp_amplitude", "exp_tau_s", "linear_slope_per_s"):
        assert set(doc["trend"][key]) == {"value", "std"}
    assert set(doc["model"]) >= {"kind", "p", "q", "ar", "ma", "sigma2", "aic", "bic", "method"}
    assert (doc["model"]["kind"], doc["model"]["p"], doc["model"]["q"]) == ("AR", 1, 0)
    assert abs(doc["trend"]["exp_tau_s"]["value"] - 120) < 4 * doc["trend"]["exp_tau_s"]["std"]
    assert set(doc["denoise"]) >= {"wavelet", "level", "sigma", "threshold"}
    assert "count" in doc["outliers"] and 0 <= doc["ljung_box_p"] <= 1
    assert doc["source"] == csv_path


def test_report_files_are_written(tmp_path, capsys):
    csv_path = startup_csv(tmp_path / "trace.csv", header=("time_s", "volts"))
    out = tmp_path / "report"
    code = run(["analyze", "startup", "--input", csv_path, "--time-col", "time_s", "--value-col", "volts",
                "--report", str(out), "--ar-method", "burg"])
    text = capsys.readouterr().out
    assert code == 0
    assert "y(t) =" in text and f"report: {out / 'startup_report.html'}" in text
    names = {p.name for p in out.iterdir()}
    assert names >= {"startup_report.html", "startup_model.json", "startup_signal.png", "startup_acf_pacf.png",
                     "startup_trend_residual.png", "startup_residual_acf.png", "startup_simulated.png"}
    page = (out / "startup_report.html").read_text(encoding="utf-8")
    pngs = [n for n in names if n.endswith(".png")]
    assert all((out / png).read_bytes()[:4] == b"\x89PNG" for png in pngs)
    assert assert_self_contained(page) == len(pngs)  # each figure inline, the files beside it too
    assert "Ljung–Box" in page and "<table>" in page
    assert json.loads((out / "startup_model.json").read_text())["model"]["method"] == "burg"


@pytest.mark.parametrize(
    ("argv_extra", "csv_kwargs", "message"),
    [
        (["--value-col", "volts"], {}, "no column 'volts'; columns are t, y"),
        ([], {"rows": {10: "1.0,1.3"}}, "time is not strictly increasing at sample index 9 (4 s then 1 s)"),
        ([], {"rows": {7: "3.0,nan"}}, "value has 1 non-finite values (first at sample index 6)"),
        ([], {"rows": {7: "3.0,abc"}}, "line 8, column 'y': 'abc' is not a number"),
        ([], {"n": 20}, "trace has 20 samples; at least 64 are required"),
        (["--max-ar-order", "500"], {}, "max_ar_order = 500 is not allowed for 3000 samples"),
        (["--outlier-z", "-1"], {}, "outlier_z = -1.0 must be > 0"),
    ],
)
def test_bad_input_exits_2_with_one_line(tmp_path, capsys, argv_extra, csv_kwargs, message):
    csv_path = startup_csv(tmp_path / "trace.csv", **csv_kwargs)
    assert run(["analyze", "startup", "--input", csv_path, *argv_extra]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("bench: error: ") and message in lines[0]
    assert "Traceback" not in captured.err


def test_missing_file_exits_2(tmp_path, capsys):
    assert run(["analyze", "startup", "--input", str(tmp_path / "nope.csv")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cannot read" in err and "nope.csv" in err


def test_analyze_stored_run_uses_samples_from_power_on(tmp_path, capsys):
    store_path = str(tmp_path / "b.sqlite")
    rng = np.random.default_rng(1)
    t = -1.0 + np.arange(2200) * 0.5  # the record starts 1 s before power-on
    v = 1.3 + 3e-4 * np.exp(-np.clip(t, 0, None) / 90) + rng.normal(0, 1e-5, t.size)
    with RunStore(store_path) as store:
        with store.create_run(procedure="startup", parameters={}, station={}, unit_serial="SN1", seed=1,
                              code_version="test") as writer:
            writer.add_stream("output", {"t_s": "s", "voltage_v": "V"})
            writer.append("output", t_s=t, voltage_v=v)
            writer.finish("passed")
        run_id = writer.id
    report = tmp_path / "reports"
    assert run(["analyze", "run", "latest", "--store", store_path, "--json", "--report", str(report)]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["n_samples"] == int(np.sum(t >= 0)) and doc["source"] == f"run {run_id}"
    assert doc["trend"]["t0_s"] == 0.0
    assert (report / run_id / "startup_report.html").exists()
    assert run(["analyze", "run", run_id, "--store", store_path, "--value-col", "acceleration_g"]) == 2
    assert "no column 'acceleration_g'" in capsys.readouterr().err
