"""The robustness battery's generator checked on its own, and a small fixed-seed subset of the
battery (the full ≥ 50 pairs run in ``benchmarks/fusion_battery.py``).

The generator (``bench.testing.generators.fusion_pairs``) is the judge's ground truth, so it is tested
against the analog prototypes it claims to simulate, and for its independence from the code it
grades.
"""

from __future__ import annotations

import ast
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.signal import lfilter

from bench.analysis.fusion import BASELINES, analyze_fusion
from bench.testing.generators import fusion_pairs
from bench.testing.generators.fusion_pairs import (
    alone_noise_free_pct,
    analog_prototype,
    draw_spec,
    judge,
    make_pair,
    sample_instants,
)


def test_the_generator_imports_nothing_of_the_bench_or_the_simulator():
    tree = ast.parse(Path(fusion_pairs.__file__).read_text(encoding="utf-8"))
    roots = {(node.module or "").split(".")[0] for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)}
    roots |= {alias.name.split(".")[0] for node in ast.walk(tree) if isinstance(node, ast.Import)
              for alias in node.names}
    assert roots <= {"__future__", "math", "dataclasses", "numpy", "scipy"}


@pytest.mark.parametrize("seed", [3, 7, 21])
def test_generated_sensors_respond_as_their_analog_prototypes(seed):
    """Noise-free, no delay, no clock error, sampled (not averaged): each sensor's FRF at the tones
    equals its prototype's response to within the bilinear transform's warping at 16× the rate."""
    spec = draw_spec(seed, max_samples=60_000)
    quiet = {"noise_sd": 0.0, "offset": 0.0, "spikes": (), "dropouts": (), "delay_s": 0.0, "clock_ppm": 0.0,
             "averaging": False}
    spec = replace(spec, hf=replace(spec.hf, **quiet), lf=replace(spec.lf, **quiet))
    rec = make_pair(spec)
    t, f = rec["t"], spec.tones_hz
    design = np.column_stack([np.ones_like(t)] + [fn(2 * np.pi * fk * t) for fk in f for fn in (np.cos, np.sin)])
    coef = np.linalg.lstsq(design, np.column_stack([rec["ref"], rec["hf"], rec["lf"]]), rcond=None)[0]
    phasor = coef[1::2] - 1j * coef[2::2]
    for col, sensor in ((1, spec.hf), (2, spec.lf)):
        num, den = analog_prototype(sensor)
        s = 2j * np.pi * f
        expected = np.polyval(num, s) / np.polyval(den, s)
        measured = phasor[:, col] / phasor[:, 0]
        big = np.abs(expected) > 1e-3 * abs(sensor.gain)  # where the response is not buried in rounding
        rel = np.abs(measured[big] / expected[big] - 1)
        assert np.max(rel) < 2e-3 * (1 + np.max(f) / spec.rate_hz * 10)


def test_pairs_are_reproducible_and_span_the_regimes():
    a, b = make_pair(draw_spec(5, 20_000)), make_pair(draw_spec(5, 20_000))
    assert all(np.array_equal(a[k], b[k]) for k in a)
    specs = [draw_spec(seed) for seed in range(60)]
    ratios = [s.regime["corner_ratio"] for s in specs]
    rates = [s.rate_hz for s in specs]
    noise = [s.regime["hf_noise_rel"] for s in specs] + [s.regime["lf_noise_rel"] for s in specs]
    assert min(ratios) < 5 and max(ratios) > 100
    assert min(rates) < 1500 and max(rates) > 15_000
    assert min(noise) < 3e-4 and max(noise) > 3e-2
    assert sum(s.regime["spikes"] != "none" for s in specs) >= 10
    assert sum(s.regime["dropouts"] != "none" for s in specs) >= 5
    assert sum(s.lf.clock_ppm != 0 for s in specs) >= 15 and sum(s.lf.averaging for s in specs) >= 15
    assert all(max(s.tones_hz) <= 0.2 * s.rate_hz * (1 + 1e-9) for s in specs)
    assert all(math.isclose(s.duration_s, min(40.0, 400_000 / s.rate_hz), rel_tol=1e-6) for s in specs)


#: a fixed subset, short records (≤ 80 000 samples): HF spikes with an 86-ppm LF clock, an 80-ppm LF
#: clock at 10⁻⁴ HF noise, a plain pair, and an LF sensor 100× quieter than the HF (seed 15: the
#: smoother leans on it up to 1.8 kHz at 16.5 kHz, where without the hold correction the model's LF
#: prediction carried the interpolation's images and the output was +0.12 % off). A regression guard
#: on pairs where the criteria hold — the full battery (benchmarks/fusion_battery.py) reports how
#: often they hold over all regimes.
SUBSET = (4, 15, 40, 46)


@pytest.mark.parametrize("seed", SUBSET)
def test_the_recommendation_meets_the_criteria_on_independent_pairs(seed):
    spec = draw_spec(seed, max_samples=80_000)
    rec = make_pair(spec)
    analysis = analyze_fusion(rec["t"], rec["hf"], rec["lf"], rec["ref"], spec.rate_hz, tones_hz=spec.tones_hz)
    judged = slice(analysis.judged_from, None)
    grades = judge(spec, analysis.t_s[judged], {k: v[judged] for k, v in analysis.estimates.items()}, record=rec)
    best = grades[analysis.recommended]
    assert best.rms_error <= min(grades[k].rms_error for k in BASELINES) * (1 + 1e-9)
    assert best.within_2_sigma and best.within_2_sensor_sigma, (analysis.recommended, best.excess_pct,
                                                                best.excess_std_pct, best.sensor_std_pct)
    assert best.within_2_own_sigma_of_exact, (analysis.recommended, best.exact_excess_pct, best.own_std_pct)
    # and far better than either sensor alone: neither covers the band
    assert best.rms_error < 0.5 * min(grades["hf"].rms_error, grades["lf"].rms_error)
    replaced = analysis.alignment.outliers_replaced
    if spec.hf.spikes or spec.lf.spikes:  # seed 4: HF spikes; the cleaned record wins, and by far
        assert replaced[0] >= len(spec.hf.spikes) and analysis.recommended.endswith("_clean")
        assert best.rms_error < 0.05 * min(g.rms_error for k, g in grades.items() if not k.endswith("_clean"))
    else:  # nothing to replace: the cleaned methods are the ones they clean
        assert replaced == (0, 0)
        assert analysis.estimates["complementary_smoother_clean"] is analysis.estimates["complementary_smoother"]


def test_another_noise_draw_is_the_same_pair_with_other_noise():
    spec = draw_spec(5, 20_000)
    a, b, again = make_pair(spec), make_pair(spec, 1), make_pair(spec, 1)
    assert all(np.array_equal(b[k], again[k]) for k in b)  # a redraw is reproducible too
    assert np.array_equal(a["t"], b["t"]) and np.array_equal(a["ref"], b["ref"])
    for name, sensor in (("hf", spec.hf), ("lf", spec.lf)):
        diff = a[name] - b[name]  # the signal cancels: two independent realisations of the white noise
        assert np.std(diff) == pytest.approx(math.sqrt(2) * sensor.noise_sd, rel=0.05)
    with pytest.raises(ValueError, match="noise_draw"):
        make_pair(spec, -1)


@pytest.mark.parametrize("seed", [8, 22])
def test_the_noise_free_bar_is_what_a_linear_estimate_reads_without_noise(seed):
    """A single-sensor estimate made by any linear operation the judge does not know (here a
    two-tap average and a gain, on the sensor's true instants): the bar the judge derives from
    the estimate, the raw reading and its noise-free twin equals that operation applied to the
    noise-free reading — to 2·10⁻⁴ pp, a hundredth of what the noisy estimate's own error is off by."""
    spec = draw_spec(seed, max_samples=40_000)
    rec = make_pair(spec)
    quiet = replace(spec, hf=replace(spec.hf, noise_sd=0.0, spikes=(), dropouts=()),
                    lf=replace(spec.lf, noise_sd=0.0, spikes=(), dropouts=()))
    twin = make_pair(quiet)
    for which in ("hf", "lf"):
        gain = getattr(spec, which).gain
        t = sample_instants(spec, getattr(spec, which))[100:-100]
        alone = lfilter([0.6, 0.4], [1.0], rec[which])[100:-100] / (0.97 * gain)
        clean = lfilter([0.6, 0.4], [1.0], twin[which])[100:-100] / (0.97 * gain)
        bar = alone_noise_free_pct(spec, rec, t, alone, which)
        expected = judge(spec, t, {"hf": clean, "lf": clean})["hf"].amplitude_error_pct
        measured = judge(spec, t, {"hf": alone, "lf": alone})["hf"].amplitude_error_pct
        passed = np.abs(expected) < 99  # tones the sensor passes at all
        off = np.abs(bar - expected)[passed]  # what is left: the record's two ends (a tap's noise over N samples)
        noise = np.abs(measured - expected)[passed]  # what the bar leaves out
        assert off.max() < 1e-3 and off.max() < 0.02 * noise.max()
