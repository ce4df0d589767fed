"""``bench analyze fusion`` through ``bench.app.cli.main``: JSON keys, fused CSV, one-line errors (exit 2)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bench.analysis.fusion import METHODS
from bench.app.cli import main

FS_HZ = 2000.0
TONES_HZ = (0.5, 2.0, 8.0, 40.0, 200.0)


def write_csv(path, n=24000, with_ref=True, rows=None, header=None) -> str:
    """Tones through a 2 Hz first-order high-pass (hf) and a 30 Hz first-order low-pass (lf)."""
    rng = np.random.default_rng(1)
    t = np.arange(n) / FS_HZ
    ref = sum(np.sin(2 * np.pi * f * t + f) for f in TONES_HZ)
    hf = sum(np.abs(g) * np.sin(2 * np.pi * f * t + f + np.angle(g))
             for f, g in ((f, 1j * f / 2 / (1 + 1j * f / 2)) for f in TONES_HZ)) + 0.02 * rng.normal(size=n)
    lf = sum(np.abs(g) * np.sin(2 * np.pi * f * t + f + np.angle(g))
             for f, g in ((f, 1 / (1 + 1j * f / 30)) for f in TONES_HZ)) + 0.01 * rng.normal(size=n)
    cols = [t, hf, lf] + ([ref] if with_ref else [])
    names = header or (["t", "hf", "lf"] + (["ref"] if with_ref else []))
    lines = [",".join(names)] + [",".join(f"{v:.10g}" for v in row) for row in zip(*cols)]
    for i, row in (rows or {}).items():
        lines[i] = row
    path.write_text("\n".join(lines) + "\n")
    return str(path)


def test_json_with_ref_judges_every_method_and_writes_the_recommended_rate(tmp_path, capsys):
    src = write_csv(tmp_path / "rec.csv")
    out = tmp_path / "fused.csv"
    code = main(["analyze", "fusion", "--input", src, "--rate-hz", str(FS_HZ), "--json", "--output", str(out),
                 "--tones-hz", ",".join(map(str, TONES_HZ))])
    assert code == 0
    doc = json.loads(capsys.readouterr().out)
    assert set(doc["rms_error"]) == set(METHODS) == set(doc["methods"])
    best = doc["recommended"]
    assert doc["rms_error"][best] < min(doc["rms_error"]["hf"], doc["rms_error"]["lf"], doc["rms_error"]["fused"])
    assert {"hf_noise", "lf_noise", "discretization"} <= set(doc["params"])
    assert doc["model"]["hf"]["kind"] == "highpass" and doc["source"] == src
    assert doc["tune_samples"] == 9600 - doc["alignment"]["trimmed_start"]
    rate = np.loadtxt(out, delimiter=",", skiprows=1)
    assert out.read_text().splitlines()[0] == f"t,{best}"  # the column says which method
    assert rate.shape == (doc["n_samples"], 2) and 23990 <= doc["n_samples"] <= 24000


def test_text_without_ref_uses_given_corners(tmp_path, capsys):
    src = write_csv(tmp_path / "rec.csv", with_ref=False)
    code = main(["analyze", "fusion", "--input", src, "--rate-hz", str(FS_HZ), "--hf-corner-hz", "2",
                 "--lf-corner-hz", "30"])
    text = capsys.readouterr().out
    assert code == 0 and "models given" in text and "NIS fused" in text and "RMS error" not in text
    assert "recommended: complementary smoother (offline)" in text


@pytest.mark.parametrize("kwargs, args, message", [
    ({"rows": {7: "0.003,abc,1,1"}}, [], "line 8, column 'hf': 'abc' is not a number"),
    ({"header": ["t", "hf", "x", "ref"]}, [], "no column 'lf'"),
    ({}, ["--rate-hz", "1000"], "time step"),
    ({}, ["--rate-hz", "-5"], "--rate-hz -5"),
    ({}, ["--tones-hz", "1,x"], "--tones-hz"),
])
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, kwargs, args, message):
    src = write_csv(tmp_path / "rec.csv", n=200, **kwargs)
    argv = ["analyze", "fusion", "--input", src] + (args if "--rate-hz" in args else ["--rate-hz", str(FS_HZ)] + args)
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("bench: error:") and message in err and "\n" not in err


def test_missing_file_is_exit_2(tmp_path, capsys):
    assert main(["analyze", "fusion", "--input", str(tmp_path / "none.csv"), "--rate-hz", "100"]) == 2
    assert "cannot read" in capsys.readouterr().err
