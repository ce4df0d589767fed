"""``bench analyze allan`` through ``bench.app.cli.main``: JSON, table, report, one-line errors."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from matplotlib.figure import Figure

from bench.analysis.allan import overlapping_adev
from bench.app.cli import main
from bench.app.reports.allan_plot import model_segments, plot_allan
from bench.testing.reports import assert_self_contained

FS_HZ = 100.0
N_DEG_PER_SQRT_S = 0.01


def write_csv(path, n=20_000, header=("t", "y"), time=None, rows=None, value=None) -> str:
    """White rate noise of angle random walk N = 0.01 °/√s (0.6 °/√h) sampled at 100 Hz."""
    rng = np.random.default_rng(0)
    t = np.arange(n) / FS_HZ if time is None else time
    y = N_DEG_PER_SQRT_S * math.sqrt(FS_HZ) * rng.normal(size=t.size) if value is None else value
    lines = [",".join(header)] + [f"{a:.6f},{b:.10g}" for a, b in zip(t, y)]
    for i, row in (rows or {}).items():
        lines[i] = row
    path.write_text("\n".join(lines) + "\n")
    return str(path)


def test_json_has_the_issue_keys_with_units(tmp_path, capsys):
    csv_path = write_csv(tmp_path / "static.csv")
    assert main(["analyze", "allan", "--input", csv_path, "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    n = len(doc["tau"])
    assert n == 14 and len(doc["adev"]) == n and len(doc["adev_ci"]) == n  # octaves of 20 000 samples
    assert doc["tau"][0] == pytest.approx(0.01) and all(lo < a < hi for a, (lo, hi) in zip(doc["adev"], doc["adev_ci"]))
    coef = doc["coefficients"]
    assert set(coef) == {"Q", "N", "B", "K", "R"}
    assert {c["unit"] for c in coef.values()} == {"arcsec", "deg/sqrt(h)", "deg/h", "deg/h/sqrt(h)", "deg/h^2"}
    assert coef["N"]["value"] == pytest.approx(60 * N_DEG_PER_SQRT_S, rel=0.05)
    assert coef["N"]["alt"]["unit"] == "deg/sqrt(s)" and coef["N"]["read_off"] == pytest.approx(0.6, rel=0.05)
    assert doc["units"]["adev"] == "deg/s" and doc["source"] == csv_path
    assert doc["sample_rate_hz"] == pytest.approx(FS_HZ)


def test_table_and_report(tmp_path, capsys):
    csv_path = write_csv(tmp_path / "static.csv", header=("time_s", "rate_dps"))
    out = tmp_path / "report"
    code = main(["analyze", "allan", "--input", csv_path, "--time-col", "time_s", "--value-col", "rate_dps",
                 "--report", str(out)])
    text = capsys.readouterr().out
    assert code == 0
    assert "20000 samples at 100 Hz" in text and "tau (s)" in text and "N angle random walk" in text
    assert f"report: {out / 'allan_report.html'}" in text
    assert {p.name for p in out.iterdir()} == {"allan_report.html", "allan_report.pdf", "allan_plot.png",
                                               "allan_result.json"}
    assert (out / "allan_plot.png").read_bytes()[:4] == b"\x89PNG"
    page = (out / "allan_report.html").read_text(encoding="utf-8")
    assert assert_self_contained(page) == 1 and "deg/sqrt(h)" in page
    assert json.loads((out / "allan_result.json").read_text())["coefficients"]["N"]["unit"] == "deg/sqrt(h)"


def test_tau_list_unit_and_phase_options(tmp_path, capsys):
    csv_path = write_csv(tmp_path / "static.csv")
    assert main(["analyze", "allan", "--input", csv_path, "--json", "--taus", "0.01, 0.05,1", "--unit", "g"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["tau"] == pytest.approx([0.01, 0.05, 1.0])
    assert doc["coefficients"]["N"]["unit"] == "g/sqrt(Hz)" and doc["units"]["adev"] == "g"
    assert main(["analyze", "allan", "--input", csv_path, "--json", "--taus", "log", "--points-per-decade", "5"]) == 0
    tau = json.loads(capsys.readouterr().out)["tau"]  # m = round(10^(k/5)) up to (N − 1)/2 = 9999
    assert len(tau) == 20 and tau[:6] == pytest.approx([0.01, 0.02, 0.03, 0.04, 0.06, 0.1]) and tau[-1] == 63.1

    rng = np.random.default_rng(1)
    angle = np.cumsum(N_DEG_PER_SQRT_S * math.sqrt(FS_HZ) * rng.normal(size=20_000)) / FS_HZ
    phase_path = write_csv(tmp_path / "angle.csv", value=angle)
    assert main(["analyze", "allan", "--input", phase_path, "--json", "--data-type", "phase"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["data_type"] == "phase" and doc["coefficients"]["N"]["value"] == pytest.approx(0.6, rel=0.05)


def _gap_time() -> np.ndarray:
    t = np.arange(400) / FS_HZ
    t[200:] += 0.01  # one dropped sample
    return t


@pytest.mark.parametrize(
    ("argv_extra", "csv_kwargs", "message"),
    [
        ([], {"time": _gap_time()}, "sampling is not uniform: the interval after sample index 199 is 0.02 s"),
        ([], {"rows": {11: "0.05,1.0"}}, "time is not strictly increasing at sample index 10"),
        (["--value-col", "rate"], {}, "no column 'rate'; columns are t, y"),
        ([], {"rows": {7: "0.06,nan"}}, "the record has 1 non-finite values (first at sample index 6)"),
        ([], {"rows": {7: "0.06,abc"}}, "line 8, column 'y': 'abc' is not a number"),
        ([], {"n": 5}, "the record has 5 samples; at least 8 rate samples are required"),
        (["--taus", "0.01,150"], {}, "τ = 150 s is outside the allowed range [0.01, 100] s"),
        (["--taus", "0.1,fast"], {}, "--taus '0.1,fast' must be 'octave', 'log' or comma-separated τ in s"),
        (["--unit", "furlongs"], {}, "unit = 'furlongs' is not supported (allowed: 'dps', 'dph'"),
        (["--confidence", "1.2"], {}, "confidence = 1.2 must lie in (0, 1)"),
        (["--terms", "N,Z"], {}, "terms = ('N', 'Z') must be distinct names from"),
    ],
)
def test_bad_input_exits_2_with_one_line(tmp_path, capsys, argv_extra, csv_kwargs, message):
    csv_path = write_csv(tmp_path / "static.csv", **csv_kwargs)
    assert main(["analyze", "allan", "--input", csv_path, *argv_extra]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("bench: error: ")
    assert message in lines[0]


def test_plot_allan_draws_curve_slope_lines_and_read_offs():
    rng = np.random.default_rng(2)
    y = 0.01 * math.sqrt(FS_HZ) * rng.normal(size=2**17) + np.cumsum(1e-4 / math.sqrt(FS_HZ) * rng.normal(size=2**17))
    result = overlapping_adev(y, FS_HZ)
    ax = plot_allan(Figure().add_subplot(), result, title="gyro X")
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert ax.get_title() == "gyro X" and ax.get_xscale() == "log" and ax.get_yscale() == "log"
    assert "ADEV" in labels and "fitted model (where within the intervals)" in labels
    assert any(label.startswith("N = ") and "deg/sqrt(h), slope −1/2" in label for label in labels)
    assert any(label.startswith("K = ") for label in labels)
    assert any(label.startswith("read-off N = ") and "at τ = 1 s" in label for label in labels)
    marker = next(line for line in ax.get_lines() if line.get_label().startswith("read-off N"))
    assert marker.get_xdata()[0] == 1.0
    assert marker.get_ydata()[0] == pytest.approx(result.coefficients["N"].read_off_input)
    flat = plot_allan(Figure().add_subplot(), overlapping_adev(np.zeros(64), 1.0))
    assert "constant record" in flat.texts[0].get_text()


@pytest.mark.parametrize("seed", range(6))
def test_the_plotted_model_lies_within_the_intervals_where_it_is_drawn(seed):
    """Drawn records (white + a random walk + a Gauss–Markov of drawn sizes, some the model cannot
    follow): wherever the plot draws the fitted model, at every measured τ inside the drawn span the
    model lies within that τ's interval; the read-off values are the legend's only numbers when the
    page's table gives them (``fit_values=False``)."""
    rng = np.random.default_rng([77, seed])
    n = 2**15
    phi = math.exp(-1 / (FS_HZ * rng.uniform(1.0, 50.0)))
    gm = np.zeros(n)
    kick = rng.uniform(0.0, 0.05) * math.sqrt(1 - phi**2) * rng.normal(size=n)
    for i in range(1, n):
        gm[i] = phi * gm[i - 1] + kick[i]
    y = (0.01 * math.sqrt(FS_HZ) * rng.normal(size=n) + gm
         + np.cumsum(rng.uniform(0.0, 3e-4) / math.sqrt(FS_HZ) * rng.normal(size=n)))
    result = overlapping_adev(y, FS_HZ)
    ax = plot_allan(Figure().add_subplot(), result, fit_values=False)
    ok = result.adev > 0
    tau, lo, hi = result.tau_s[ok], result.adev_ci[ok, 0], result.adev_ci[ok, 1]
    drawn = [line for line in ax.get_lines() if line.get_color() == "C3"]
    assert len(drawn) == len(model_segments(result))
    for line in drawn:
        x = np.asarray(line.get_xdata())
        inside = (tau >= x.min() * (1 - 1e-9)) & (tau <= x.max() * (1 + 1e-9))
        assert inside.sum() >= 2
        model = np.interp(np.log(tau[inside]), np.log(x), np.asarray(line.get_ydata()))
        assert np.all(model >= lo[inside] * (1 - 1e-6)) and np.all(model <= hi[inside] * (1 + 1e-6))
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert not any(label.startswith(("N = ", "K = ", "B = ")) for label in labels)


def test_robust_flag_and_checks_in_json_table_and_report(tmp_path, capsys):
    """`--robust` on a record with 8 % spikes: JSON says robust, the flagged fraction and each
    term's check; the table and the report show both."""
    rng = np.random.default_rng(5)
    y = N_DEG_PER_SQRT_S * math.sqrt(FS_HZ) * rng.normal(size=20_000)
    y += (rng.random(y.size) < 0.08) * rng.choice([-3.0, 3.0], y.size)
    csv_path = write_csv(tmp_path / "spiky.csv", value=y)
    assert main(["analyze", "allan", "--input", csv_path, "--json", "--robust"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["robust"] is True and doc["outliers"]["fraction"] == pytest.approx(0.08, abs=0.01)
    assert doc["outliers"]["false_alarm"] == 0.01 and doc["notes"][0].endswith("robust estimate used")
    assert doc["checks"]["N"]["status"] == "agrees"
    assert doc["coefficients"]["N"]["value"] == pytest.approx(0.6, rel=0.05)
    assert main(["analyze", "allan", "--input", csv_path, "--json"]) == 0
    plain = json.loads(capsys.readouterr().out)
    assert plain["robust"] is False and plain["coefficients"]["N"]["value"] > 3.0
    out = tmp_path / "report"
    assert main(["analyze", "allan", "--input", csv_path, "--robust", "--report", str(out)]) == 0
    text = capsys.readouterr().out
    assert "robust: outliers replaced" in text and "| agrees (slope -0.4" in text
    page = (out / "allan_report.html").read_text(encoding="utf-8")
    assert "Checks against the curve" in page and "robust estimate" in page


def _white_and_gm(path, seed, n=30_000):
    """White rate noise N = 0.01 °/√s and a Gauss–Markov of 0.05 °/s, τ 20 s, at 100 Hz (drawn here)."""
    rng = np.random.default_rng([31, seed])
    phi = math.exp(-1 / (FS_HZ * 20.0))
    gm = np.zeros(n)
    e = rng.normal(size=n) * 0.05 * math.sqrt(1 - phi * phi)
    for k in range(1, n):
        gm[k] = phi * gm[k - 1] + e[k]
    return write_csv(path, n=n, value=N_DEG_PER_SQRT_S * math.sqrt(FS_HZ) * rng.normal(size=n) + gm)


def test_the_noise_model_gives_n_and_reproduces_the_curve(tmp_path, capsys):
    """``--model``: bench discover's estimator on three records of white noise and a Gauss–Markov
    (long enough for its two scales): N within 3 % of the truth, the Gauss–Markov named, and the
    model's Allan deviation inside the data's 99 % interval at ≥ 90 % of the τ over the records;
    the progress of the estimator goes to stderr beside the JSON."""
    inside = total = 0
    for seed in range(3):
        csv_path = _white_and_gm(tmp_path / f"gm{seed}.csv", seed)
        assert main(["analyze", "allan", "--input", csv_path, "--unit", "dps", "--model", "--confidence", "0.99",
                     "--json"]) == 0
        captured = capsys.readouterr()
        nm = json.loads(captured.out)["noise_model"]
        assert "discover:" in captured.err
        n_model = nm["terms"]["N"]["value"] / 60.0  # deg/sqrt(h) → deg/sqrt(s)
        assert abs(n_model / N_DEG_PER_SQRT_S - 1) < 0.03, nm["terms"]["N"]
        assert "gauss_markov" in [e["id"] for e in nm["effects"]], nm["effects"]
        inside, total = inside + nm["within"], total + nm["taus"]
    assert inside >= 0.9 * total, (inside, total)


def test_the_noise_model_needs_a_sensor_unit(tmp_path, capsys):
    csv_path = write_csv(tmp_path / "static.csv")
    assert main(["analyze", "allan", "--input", csv_path, "--unit", "none", "--model"]) == 2
    assert "--model needs --unit" in capsys.readouterr().err
