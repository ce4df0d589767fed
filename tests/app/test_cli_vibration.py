"""``bench analyze vibration``: JSON keys, text summary, report files (HTML, its PDF, the input's
SHA-256 at the foot), one-line errors with exit 2."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest
from scipy.signal import lfilter

from bench.app.cli import main
from bench.testing.reports import assert_self_contained, assert_signable


def vibration_csv(path, n: int = 4000, header=("t", "y"), gap: bool = False) -> str:
    rng = np.random.default_rng(2)
    t = np.arange(n) / 2000.0
    if gap:
        t[n // 2 :] += 0.05
    y = (lfilter([1.0], [1.0, -0.6, 0.2], rng.normal(0, 0.003, n)) + rng.normal(0, 0.002, n)
         + 0.006 * np.sin(2 * np.pi * 20 * t) + 1e-4 * t)
    lines = [",".join(header)] + [f"{a:.6f},{b:.9g}" for a, b in zip(t, y)]
    path.write_text("\n".join(lines) + "\n")
    return str(path)


@pytest.fixture(scope="module")
def csv_file(tmp_path_factory):
    return vibration_csv(tmp_path_factory.mktemp("vib") / "rate.csv")


def test_json_has_the_issue_keys(csv_file, capsys):
    assert main(["analyze", "vibration", "--input", csv_file, "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert isinstance(doc["imfs"], int) and doc["imfs"] >= 3
    assert any(c["kind"] == "periodic" and abs(c["frequency_hz"] - 20) < 0.5 for c in doc["nonrandom"])
    assert doc["imf_models"]
    for m in doc["imf_models"]:
        assert {"index", "p", "ar", "white_residual_p", "stationary_p", "aic_order", "bic_order"} <= set(m)
    ar, kal = doc["fit_error"]["ar"], doc["fit_error"]["ar_kalman"]
    assert kal["std"] < ar["std"]
    assert doc["source"] == csv_file


def test_text_summary_and_report(csv_file, tmp_path, capsys):
    out = tmp_path / "report"
    code = main(["analyze", "vibration", "--input", csv_file, "--report", str(out), "--criterion", "aic",
                 "--p-max", "10"])
    text = capsys.readouterr().out
    assert code == 0
    assert "AR + Kalman fit" in text and f"report: {out / 'vibration_report.html'}" in text
    names = {p.name for p in out.iterdir()}
    assert names >= {"vibration_report.html", "vibration_analysis.json", "vibration_imfs.png",
                     "vibration_orders.png", "vibration_fit.png", "vibration_error_hist.png"}
    page = (out / "vibration_report.html").read_text(encoding="utf-8")
    assert assert_self_contained(page) == len([n for n in names if n.endswith(".png")])
    assert "Document C" in page
    assert (out / "vibration_report.pdf").read_bytes()[:5] == b"%PDF-"  # the signable copy beside it
    assert "reviewed by" in page  # the approval block
    assert_signable(page, hashlib.sha256(Path(csv_file).read_bytes()).hexdigest())  # the input's digest
    saved = json.loads((out / "vibration_analysis.json").read_text())
    assert saved["settings"]["criterion"] == "aic" and saved["settings"]["p_max"] == 10


@pytest.mark.parametrize("kind, message", [
    ("gap", "sampling is not uniform"),
    ("column", "no column 'rate'"),
    ("short", "at least"),
])
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, kind, message):
    if kind == "gap":
        path = vibration_csv(tmp_path / "gap.csv", 600, gap=True)
        argv = ["--input", path]
    elif kind == "column":
        path = vibration_csv(tmp_path / "cols.csv", 600)
        argv = ["--input", path, "--value-col", "rate"]
    else:
        path = vibration_csv(tmp_path / "short.csv", 100)
        argv = ["--input", path]
    assert main(["analyze", "vibration", *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("bench: error:") and message in err and err.count("\n") == 1
