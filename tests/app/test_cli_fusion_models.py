"""``bench analyze fusion`` without a reference: sensor models on the command line (``--hf-model``,
``--lf-model``) or in a file (``--models FILE.toml``), what the JSON says of the checks, clocks and
spikes, and one-line errors (exit 2) naming the bad value and its range."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.app.cli import main
from bench.app.commands.analyze_fusion import MODEL_KEYS, sensor_model
from bench.testing.generators.fusion_pairs import draw_random_spec, make_pair

SEED = 1010  # a random-vibration rig: both sensors second order, spikes in both, the LF clock 68 ppm slow


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    spec = draw_random_spec(SEED, 8000, spikes=True)
    rec = make_pair(spec)
    path = tmp_path_factory.mktemp("rig") / "random.csv"
    np.savetxt(path, np.column_stack([rec["t"], rec["hf"], rec["lf"]]), delimiter=",", header="t,hf,lf",
               comments="", fmt="%.10g")
    return spec, str(path)


def spec_text(sensor, delay_ms=None) -> str:
    text = (f"order={sensor.order},corner_hz={float(sensor.corner_hz)!r},zeta={float(sensor.zeta)!r},"
            f"gain={float(sensor.gain)!r}")
    return text + ("" if delay_ms is None else f",delay_ms={float(delay_ms)!r}")


def test_models_on_the_command_line_reach_the_analysis(rig, capsys):
    spec, src = rig
    assert spec.hf.order == 2 and spec.lf.order == 2  # what --hf-corner-hz cannot say
    code = main(["analyze", "fusion", "--input", src, "--rate-hz", repr(spec.rate_hz), "--json",
                 "--hf-model", spec_text(spec.hf), "--lf-model", spec_text(spec.lf, delay_ms=0.5)])
    assert code == 0
    doc = json.loads(capsys.readouterr().out)
    for name, sensor in (("hf", spec.hf), ("lf", spec.lf)):
        assert doc["model"][name]["order"] == sensor.order
        assert doc["model"][name]["corner_hz"] == pytest.approx(sensor.corner_hz)
        assert doc["model"][name]["zeta"] == pytest.approx(sensor.zeta)
    assert doc["model_source"] == "given" and doc["rms_error"] is None
    # without a reference: the checks that gate the recommendation, the clock, the spikes
    checks = doc["checks"]
    best = doc["recommended"]
    assert best in ("complementary", "complementary_clean") or checks[best]["passed"]
    assert doc["timing"]["skew_corrected"]
    truth = spec.lf.clock_ppm - spec.hf.clock_ppm
    assert abs(doc["timing"]["skew_ppm"] - truth) < 4 * doc["timing"]["skew_std_ppm"]
    found = doc["spikes"]["hf"]["count"] + doc["spikes"]["lf"]["count"]
    assert found == len(spec.hf.spikes) + len(spec.lf.spikes)


def test_a_models_file_gives_both_and_the_command_line_wins(rig, tmp_path, capsys):
    spec, src = rig
    models = tmp_path / "models.toml"
    hf = spec.hf
    models.write_text(f"[hf]\norder = {hf.order}\ncorner_hz = {float(hf.corner_hz)!r}\nzeta = {float(hf.zeta)!r}\n"
                      f"gain = {float(hf.gain)!r}\n\n[lf]\norder = {spec.lf.order}\ncorner_hz = 999.0\n"
                      f"delay_ms = 1.0\n")
    argv = ["analyze", "fusion", "--input", src, "--rate-hz", repr(spec.rate_hz), "--models", str(models), "--json"]
    assert main(argv + ["--lf-model", spec_text(spec.lf)]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["model"]["hf"]["order"] == spec.hf.order and doc["model"]["hf"]["gain"] == pytest.approx(spec.hf.gain)
    assert doc["model"]["lf"]["corner_hz"] == pytest.approx(spec.lf.corner_hz)  # not the file's 999
    assert main(argv) == 0  # the file alone
    assert json.loads(capsys.readouterr().out)["model"]["lf"]["corner_hz"] == 999.0


def test_the_text_summary_names_each_check(rig, capsys):
    spec, src = rig
    assert main(["analyze", "fusion", "--input", src, "--rate-hz", repr(spec.rate_hz),
                 "--hf-model", spec_text(spec.hf), "--lf-model", spec_text(spec.lf)]) == 0
    text = capsys.readouterr().out
    assert "check complementary_smoother_clean:" in text and "LF clock relative to HF" in text
    assert "spikes replaced in the cleaned copy" in text


@pytest.mark.parametrize("args, message", [
    (["--hf-model", "order=3,corner_hz=1"], "--hf-model: order 3 must be 1 or 2"),
    (["--hf-model", "corner_hz=0"], "--hf-model: corner_hz 0 must be in (0, "),
    (["--lf-model", "corner_hz=40,zeta=-1"], "--lf-model: zeta -1 must be in (0, 10]"),
    (["--lf-model", "corner_hz=40,delay_ms=5000"], "--lf-model: delay_ms 5000 must be in [-1000, 1000] ms"),
    (["--lf-model", "corner_hz=40,gain=0"], "--lf-model: gain 0 must be finite and non-zero"),
    (["--hf-model", "corner_hz=1,corner=2"], "unknown key 'corner'; allowed: order, corner_hz, zeta, gain, delay_ms"),
    (["--hf-model", "order=2"], "--hf-model: corner_hz is required"),
    (["--hf-model", "corner_hz"], "--hf-model 'corner_hz' must be key=value"),
    (["--hf-model", "corner_hz=abc"], "--hf-model corner_hz='abc' is not a number"),
    (["--hf-model", "corner_hz=1", "--hf-corner-hz", "1"], "--hf-model and --hf-corner-hz both given"),
    (["--hf-corner-hz", "-2"], "--hf-corner-hz: corner_hz -2 must be in (0, "),
])
def test_bad_model_values_are_one_line_naming_the_value_and_range(rig, capsys, args, message):
    spec, src = rig
    assert main(["analyze", "fusion", "--input", src, "--rate-hz", repr(spec.rate_hz)] + args) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("bench: error:") and message in err and "\n" not in err, err


@pytest.mark.parametrize("text, message", [
    ("[hf]\ncorner_hz = 1.0\n[mid]\ncorner_hz = 3.0\n", "unknown table [mid]; allowed: [hf], [lf]"),
    ("[lf]\ncorner_hz = 40.0\norder = 4\n", "[lf] of"),
    ("[lf]\ncorner_hz = 'fast'\n", "corner_hz 'fast' must be a number"),
    ("hf = 3\n", "hf must be a table [hf]"),
    ("[hf\n", "is not valid TOML"),
])
def test_bad_models_files_are_one_line_errors(rig, tmp_path, capsys, text, message):
    spec, src = rig
    models = tmp_path / "models.toml"
    models.write_text(text)
    assert main(["analyze", "fusion", "--input", src, "--rate-hz", repr(spec.rate_hz), "--models", str(models)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("bench: error:") and message in err and "\n" not in err, err


def test_a_missing_models_file_is_exit_2(rig, tmp_path, capsys):
    spec, src = rig
    assert main(["analyze", "fusion", "--input", src, "--rate-hz", repr(spec.rate_hz), "--models",
                 str(tmp_path / "none.toml")]) == 2
    assert "not found" in capsys.readouterr().err


@settings(max_examples=60, deadline=None, derandomize=True)
@given(key=st.sampled_from(sorted(MODEL_KEYS)), value=st.floats(-1e4, 1e4, allow_nan=False),
       rate_hz=st.floats(100.0, 20_000.0))
def test_every_model_value_is_accepted_inside_its_range_and_named_outside(key, value, rate_hz):
    values = {"corner_hz": 1.0, key: value}
    allowed, ok = MODEL_KEYS[key]
    inside = bool(math.isfinite(value) and ok(value, rate_hz))
    if inside:
        model, delay_s = sensor_model(values, "lowpass", "--lf-model", rate_hz)
        assert delay_s == pytest.approx(values.get("delay_ms", 0.0) * 1e-3)
        if key != "delay_ms":
            assert getattr(model, key) == pytest.approx(value)
    else:
        with pytest.raises(ValueError) as err:
            sensor_model(values, "lowpass", "--lf-model", rate_hz)
        assert f"--lf-model: {key} {value:g} must be" in str(err.value)


@pytest.mark.parametrize("rows", [16, 300])
def test_a_record_too_short_to_check_gets_the_complementary_filter(tmp_path, capsys, rows):
    t = np.arange(rows) / 1000.0
    path = tmp_path / "short.csv"
    np.savetxt(path, np.column_stack([t, np.sin(50 * t), np.sin(50 * t)]), delimiter=",", header="t,hf,lf",
               comments="", fmt="%.10g")
    assert main(["analyze", "fusion", "--input", str(path), "--rate-hz", "1000", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["recommended"] == "complementary"
    assert all(not c["passed"] and "too short" in c["reason"] for c in doc["checks"].values())
