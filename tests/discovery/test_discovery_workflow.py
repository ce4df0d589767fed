"""Discrepancy workflow (issue 7): localization, significance machinery, stochastic shape fits,
calibration and the whole loop on data with a hidden effect (a fast subset of the scorecard)."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import signal
from statsmodels.stats.diagnostic import acorr_ljungbox
from statsmodels.stats.multitest import multipletests

from bench.discovery import significance as sig
from bench.discovery.calibration import calibrate, white_floor_sd
from bench.discovery.data import Record
from bench.discovery.effects import CATALOGUE
from bench.discovery.effects_base import DEFAULT_NOISE_SD
from bench.discovery.effects_terms import LinearDrift
from bench.discovery.experiments import make_experiment
from bench.discovery.fitting import CandidateFitter
from bench.discovery.localize import localize
from bench.discovery.model import BaseModel, Model, base_model
from bench.discovery.naming import name_effect
from bench.discovery.separating import separating_experiment
from bench.discovery.stochastic import fit_stochastic
from bench.discovery.workflow import (
    discover,
    faded_terms,
    gap_of,
    grown,
    input_order,
    jumped,
    refit_processes,
    relooked,
    renested,
    reseated,
    unjumped,
    unnested,
)
from bench.testing.discovery_cases import hidden_case

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"

GM, RW = CATALOGUE["gauss_markov"], CATALOGUE["rate_random_walk"]


def _white_record(seed: int, n: int = 3000, rate: float = 10.0) -> Record:
    rng = np.random.default_rng(seed)
    t = np.arange(n) / rate
    return Record(t_s=t, y=rng.normal(0, 1.0, n), input=np.sin(0.5 * t), temp_c=20 + t / t[-1])


# ---- localization -----------------------------------------------------------------------

def test_localize_white_noise_flags_nothing_mostly():
    flagged = sum(localize(r, r.y, 1.0).any_structure for r in (_white_record(s) for s in range(20)))
    assert flagged <= 2  # five tests at alpha = 0.01 each, Bonferroni inside


def test_localize_finds_line_drift_and_input_square():
    rec = _white_record(1)
    t = rec.t_s
    y = rec.y + 0.4 * np.sin(2 * np.pi * 2.0 * t)
    loc = localize(rec, y, 1.0)
    lines = [b for b in loc.bands if abs(b.peak_hz - 2.0) < 0.1]
    assert lines, loc.descriptions()
    y = rec.y + 0.004 * (t - t.mean())
    loc = localize(rec, y, 1.0)
    assert loc.segments or loc.cusum_p < 0.01
    y = rec.y + 0.5 * rec.input ** 2
    loc = localize(rec, y, 1.0)
    assert any(c.column == "input" and c.transform == "x^2" for c in loc.correlations)


# ---- significance machinery -------------------------------------------------------------

@settings(max_examples=20, deadline=None)
@given(st.lists(st.floats(0, 1), min_size=1, max_size=30), st.floats(0.01, 0.2))
def test_benjamini_hochberg_matches_statsmodels(p, alpha):
    rej, adj = sig.benjamini_hochberg(p, alpha)
    ref_rej, ref_adj, *_ = multipletests(p, alpha=alpha, method="fdr_bh")
    assert np.array_equal(rej, ref_rej)
    assert np.allclose(adj, ref_adj)


def test_block_bootstrap_keeps_blocks_and_folds_are_contiguous():
    rng = np.random.default_rng(0)
    r = np.arange(100.0)
    b = sig.block_bootstrap(r, 10, 5, rng)
    assert b.shape == (100, 5)
    d = np.diff(b[:, 0]) % 100
    assert np.mean(d == 1) >= 0.85  # consecutive inside blocks (wrapping on the circle)
    f = sig.block_folds(160, 16)
    assert np.count_nonzero(np.diff(f[10:])) == 14  # 16 contiguous blocks of 10, alternating
    assert list(f[:10]) == [0, 0, 1, 1, 0, 0, 0, 0, 1, 1]  # the first cut again: spans 2, 2, 4, 2 (cut short)
    assert np.array_equal(sig.block_edges(160, 16), np.arange(0, 161, 10))


def test_linear_scorer_matches_direct_fit():
    rng = np.random.default_rng(3)
    n = 800
    f = sig.block_folds(n)
    x0 = np.column_stack([np.ones(n), rng.normal(size=n)])
    xc = [rng.normal(size=(n, 2))] * 2
    r = rng.normal(size=n)
    got = sig.heldout_linear_scores(r, x0, xc, f)[0]
    sse_c = sse_b = 0.0
    for k in (0, 1):
        te = f == k
        x = np.hstack([x0, xc[k]])
        bc = np.linalg.lstsq(x[~te], r[~te], rcond=None)[0]
        bb = np.linalg.lstsq(x0[~te], r[~te], rcond=None)[0]
        sse_c += np.sum((r[te] - x[te] @ bc) ** 2)
        sse_b += np.sum((r[te] - x0[te] @ bb) ** 2)
    assert got == pytest.approx(1 - sse_c / sse_b, rel=1e-9)


def test_bootstrap_p_value_uniformish_on_noise_and_small_on_signal():
    rng = np.random.default_rng(5)
    n = 2000
    t = np.arange(n) / 10.0
    f = sig.block_folds(n)
    x0 = np.ones((n, 1))
    xc = [t[:, None]] * 2
    ps = []
    for s in range(10):
        r = np.random.default_rng(100 + s).normal(size=n)
        obs = sig.heldout_linear_scores(r, x0, xc, f)[0]
        ps.append(sig.bootstrap_p_value(r, x0, xc, f, obs, n_rep=199, rng=rng))
    assert np.mean(np.array(ps) < 0.05) <= 0.2
    r = np.random.default_rng(1).normal(size=n) + 0.002 * t
    obs = sig.heldout_linear_scores(r, x0, xc, f)[0]
    assert sig.bootstrap_p_value(r, x0, xc, f, obs, n_rep=199, rng=rng) <= 0.01


@settings(max_examples=40, deadline=None)
@given(observed=st.floats(-3.0, 12.0), seed=st.integers(0, 2 ** 16), n_rep=st.sampled_from([99, 199, 999]))
def test_sequential_p_value_is_the_full_runs_p_or_stops_where_it_cannot_change(observed, seed, n_rep):
    """The one Monte-Carlo loop of the package (bootstrap and projection tests): p is the full
    run's (1 + exceedances)/(n_rep + 1) unless it stopped early — after 10 exceedances (then
    exceedances/drawn, within a chunk's worth of the full run's), or at the floor when the
    observed value is beyond CLEAR_Z null sds (then no null value reached it)."""
    null = np.random.default_rng(seed).standard_normal(n_rep)
    drawn = []

    def draw(m: int) -> np.ndarray:
        out = null[len(drawn):len(drawn) + m]
        drawn.extend(out)
        return out
    p = sig.sequential_p_value(observed, draw, n_rep=n_rep)
    full = (1 + np.sum(null >= observed)) / (n_rep + 1)
    assert 1 / (n_rep + 1) <= p <= 1
    hits = int(np.sum(np.array(drawn) >= observed))
    if hits >= 10:
        assert p == pytest.approx(hits / len(drawn))
    elif len(drawn) == n_rep:
        assert p == pytest.approx(full)
    else:  # the clear early stop: nothing reached it, and nothing in the rest would have
        assert p == 1 / (n_rep + 1) and np.sum(null >= observed) == 0


@settings(max_examples=60, deadline=None)
@given(observed=st.floats(-1.0, 5.0), seed=st.integers(0, 2 ** 16), n_rep=st.sampled_from([99, 199, 999]),
       below=st.sampled_from([0.002, 0.0024, 0.01, 0.05]))
def test_a_decision_below_a_level_stops_early_and_decides_as_the_full_run(observed, seed, n_rep, below):
    """``below``: only whether p < below is asked (the workflow's deterministic term against a
    random process). The answer is the same as without it, never more replicates are drawn, and
    once one exceedance rules it out drawing stops within a chunk."""
    null = np.random.default_rng(seed).standard_normal(n_rep)

    def counted():
        drawn = []

        def draw(m: int) -> np.ndarray:
            out = null[len(drawn):len(drawn) + m]
            drawn.extend(out)
            return out
        return drawn, draw
    drawn_all, draw_all = counted()
    drawn_dec, draw_dec = counted()
    p_all = sig.sequential_p_value(observed, draw_all, n_rep=n_rep)
    p_dec = sig.sequential_p_value(observed, draw_dec, n_rep=n_rep, below=below)
    assert (p_dec < below) == (p_all < below)
    assert len(drawn_dec) <= len(drawn_all)
    first = np.flatnonzero(np.cumsum(null >= observed) + 1 >= below * (n_rep + 1))
    if first.size:  # drawing stops in the chunk of 100 where the bound reached the level
        assert len(drawn_dec) <= (first[0] // 100 + 1) * 100
    with pytest.raises(ValueError, match="below = 0"):
        sig.sequential_p_value(observed, draw_dec, n_rep=n_rep, below=0.0)


def test_gap_metrics_white_is_at_floor_and_ljung_box_matches_statsmodels():
    r = np.random.default_rng(2).normal(0, 2.0, 4000)
    g = sig.gap_metrics(r, 2.0, 10.0)
    assert g.rms_ratio == pytest.approx(1.0, abs=0.05)
    assert g.allan_distance < 0.1 and g.spectral_distance_db < 1.5
    ref = acorr_ljungbox(r - r.mean(), lags=[20])["lb_pvalue"].iloc[0]
    assert g.whiteness_p == pytest.approx(ref, rel=1e-6)


# ---- stochastic shape fits --------------------------------------------------------------

def test_gauss_markov_recovered_from_spectrum():
    rng = np.random.default_rng(4)
    n, dt, tau, s = 8000, 0.1, 3.0, 0.6
    phi = np.exp(-dt / tau)
    x = signal.lfilter([1], [1, -phi], rng.normal(0, s * np.sqrt(1 - phi ** 2), n))
    fit = fit_stochastic(x + rng.normal(0, 1, n), dt, GM)
    assert fit.p_value < 1e-6
    assert abs(fit.params["tau_s"] - tau) <= 3 * fit.params_std["tau_s"]
    assert abs(fit.params["sigma"] - s) <= 3 * fit.params_std["sigma"]
    assert fit_stochastic(rng.normal(0, 1, n), dt, GM).p_value > 1e-3


def test_white_floor_ignores_slow_structure_and_a_line():
    rng = np.random.default_rng(6)
    t = np.arange(5000) / 10.0
    r = rng.normal(0, 0.3, t.size) + 0.01 * t + np.sin(2 * np.pi * 0.7 * t)
    assert white_floor_sd(r, 10.0) == pytest.approx(0.3, rel=0.08)


# ---- calibration and the loop -----------------------------------------------------------

def _hidden(kind, effects, seed, n):
    rng = np.random.default_rng(seed)
    rec = make_experiment(kind, rng, n=n)
    sd = DEFAULT_NOISE_SD[kind]
    truth = Model(BaseModel(kind=kind, bias=20 * sd, scale_factor=1.0005, noise_sd=sd))
    for eid in effects:
        truth = truth.with_effect(eid, CATALOGUE[eid].draw(rng, rec, kind=kind, noise_sd=sd))
    return rec.replace(y=truth.simulate(rec, rng)), truth


def test_calibrate_recovers_bias_scale_factor_and_noise():
    rec, truth = _hidden("accelerometer", (), 0, 1500)
    m = calibrate(Model(base_model("accelerometer")), rec)
    sd = truth.base.noise_sd
    assert abs(m.base.bias - truth.base.bias) < 5 * sd / np.sqrt(rec.n) * 3
    assert abs(m.base.scale_factor - truth.base.scale_factor) < 1e-5
    assert m.base.noise_sd == pytest.approx(sd, rel=0.15)


@pytest.mark.parametrize("kind,eid,seed", [("accelerometer", "k2_nonlinearity", 0),
                                           ("accelerometer", "warmup_exponential", 1),
                                           ("gyro", "sinusoidal_interference", 2),
                                           ("accelerometer", "rate_random_walk", 0)])
def test_discover_names_the_hidden_effect_and_closes_the_gap(kind, eid, seed):
    rec, truth = _hidden(kind, (eid,), seed, 1500)
    d = discover(rec, Model(base_model(kind)), max_effects=2, seed=seed, n_rep=399)
    assert [s.effect_id for s in d.steps] == [eid]  # the hidden one and nothing else
    main = CATALOGUE[eid].main_param
    got, sd = d.steps[0].params[main], d.steps[0].params_std[main]
    assert abs(got - truth.effects[0][1][main]) <= 3 * sd
    assert d.gap_final.rms_ratio <= 1.1
    doc = d.to_dict("m.toml")
    assert doc["effects"][0]["id"] == eid and doc["gap"]["final"] <= 1.1


def test_discover_names_nothing_on_clean_data():
    rec, _ = _hidden("accelerometer", (), 7, 1500)
    d = discover(rec, Model(base_model("accelerometer")), max_effects=2, seed=7, n_rep=399)
    assert d.steps == () and d.unexplained == ()
    assert d.to_dict()["effects"] == []


def test_discover_names_both_hidden_effects_and_nothing_else_with_progress():
    # the audit's spurious-first pair (time_delay + k3): a missing waveform's colour must not be
    # named as Gauss–Markov noise ahead of it. A delay of 10 ms at 1 Hz is its look-alike exactly
    # (the low-pass exact for an input linear between samples, 1/ω = the delay: no delay is
    # drawable on this record, test_discovery_effects), so either is the right answer here
    rng = np.random.default_rng(3)
    rec = make_experiment("accelerometer", rng, n=1500)
    sd = DEFAULT_NOISE_SD["accelerometer"]
    truth = Model(BaseModel(kind="accelerometer", bias=20 * sd, scale_factor=1.0005, noise_sd=sd)) \
        .with_effect("time_delay", {"delay_s": 0.01}) \
        .with_effect("k3_nonlinearity", CATALOGUE["k3_nonlinearity"].draw(rng, rec, kind="accelerometer", noise_sd=sd))
    rec = rec.replace(y=truth.simulate(rec, rng))
    msgs = []
    d = discover(rec, Model(base_model("accelerometer")), max_effects=3, seed=3, n_rep=199,
                 progress=msgs.append)
    named = sorted(s.effect_id for s in d.steps)
    assert named in (["k3_nonlinearity", "time_delay"], ["k3_nonlinearity", "lowpass_bandwidth"])
    delay_like = next(s for s in d.steps if s.effect_id != "k3_nonlinearity")
    assert "time_delay" in delay_like.naming.competitors or delay_like.effect_id == "time_delay"
    assert any(m.startswith("step 1: ") and "(1/" in m for m in msgs)
    assert any(m.startswith("step 1: named ") and "→" in m for m in msgs)
    assert msgs[-1].endswith("nothing significant; stopping")


def test_separating_experiments_name_the_inputs_or_the_known_recipe():
    assert "temperature independently of time since power-on" in separating_experiment(
        "warmup_exponential", "temperature_bias")
    # declared on one effect of the pair, it holds either way round
    assert separating_experiment("temperature_bias", "warmup_exponential").startswith(
        "temperature_bias vs warmup_exponential: vary temperature independently")
    assert "vary cross_input independently of vib" in separating_experiment(
        "misalignment", "vibration_rectification")
    assert "repeat the record" in separating_experiment("k2_nonlinearity", "gauss_markov")


# ---- audit regressions ------------------------------------------------------------------

def test_calibrate_refuses_a_bias_outside_its_range_instead_of_clipping():
    rec, _ = _hidden("accelerometer", (), 0, 600)
    wrong_unit = rec.replace(y=rec.y * 1000.0 + 0.5)  # mg logged as g: bias 0.5 "g"
    with pytest.raises(ValueError, match=r"bias = .* outside the allowed range .*wrong unit or missing input"):
        calibrate(Model(base_model("accelerometer")), wrong_unit)


def test_calibrate_leaves_scale_factor_alone_when_the_input_is_constant():
    rng = np.random.default_rng(1)
    n = 600
    t = np.arange(n) * 1.0
    rec = Record(t_s=t, y=1.0 + 0.01 + rng.normal(0, 5e-6, n), input=np.ones(n))
    m = calibrate(Model(base_model("accelerometer")).with_base(scale_factor=1.0), rec)
    assert m.base.scale_factor == 1.0  # not separable from the bias: kept, not split arbitrarily
    assert m.base.bias == pytest.approx(0.01, abs=1e-5)


def test_calibrate_refits_nonlinear_parameters_of_effects_in_the_model():
    rec, truth = _hidden("accelerometer", ("warmup_exponential",), 1, 1500)
    p = dict(truth.effects[0][1])
    # from a τ 60 % off and from the truth: the same least-squares optimum (τ is refitted, not frozen)
    wrong = calibrate(Model(truth.base).with_effect("warmup_exponential", dict(p, tau_s=p["tau_s"] * 1.6)), rec)
    right = calibrate(Model(truth.base).with_effect("warmup_exponential", p), rec)
    assert wrong.effects[0][1]["tau_s"] == pytest.approx(right.effects[0][1]["tau_s"], rel=0.01)
    sse = lambda m: float(np.sum((rec.y - m.predict(rec)) ** 2))
    assert sse(wrong) <= sse(right) * 1.001


def test_min_effect_that_raises_fails_closed():
    class Boom(LinearDrift):
        def min_effect(self, *a, **k):
            raise ValueError("cannot judge")

    rec, _ = _hidden("accelerometer", (), 0, 300)
    assert LinearDrift().big_enough({"slope_per_s": 1e-6}, rec, 1e-6, kind="accelerometer")[0] is True
    big, thr = Boom().big_enough({"slope_per_s": 1e-6}, rec, 1e-6, kind="accelerometer")
    assert big is False and np.isnan(thr)


def test_step_std_is_recomputed_at_the_recalibrated_model():
    rec, _ = _hidden("accelerometer", ("linear_drift",), 0, 1500)
    d = discover(rec, Model(base_model("accelerometer")), max_effects=1, seed=0, n_rep=99,
                 only=("linear_drift", "warmup_exponential", "temperature_bias"))
    (step,) = d.steps
    m = d.final_model
    f = CandidateFitter(Model(m.base), rec, CATALOGUE["linear_drift"])
    x = f.pack(m.effects[0][1], m.base.bias, m.base.scale_factor)
    want = f.fit([x], max_nfev=1).params_std
    assert step.params_std == pytest.approx(want, rel=1e-9)
    assert step.params == m.effects[0][1]


def test_stochastic_p_value_is_calibrated_on_the_models_own_noise() -> None:
    # 20 draws of the calibrated base model's own noise: each stochastic candidate's LR p-value
    # falls below 5 % in about 5 % of them
    rec = make_experiment("accelerometer", np.random.default_rng(0), n=1500)
    m = Model(base_model("accelerometer"))
    ps: dict[str, list[float]] = {"gauss_markov": [], "rate_random_walk": []}
    for s in range(20):
        r = m.simulate(rec, np.random.default_rng(s)) - m.predict(rec)
        for eid in ps:
            # the candidate's p-value is this fit's (floored): without the held-out score's cost
            ps[eid].append(fit_stochastic(r - r.mean(), rec.dt_s, CATALOGUE[eid], bootstrap=False).p_value)
    for eid, p in ps.items():
        assert np.mean(np.array(p) < 0.05) <= 0.1, (eid, p)


def test_random_walk_std_covers_the_truth():
    rng = np.random.default_rng(11)
    n, k = 2000, 2e-7
    z = []
    for _ in range(12):
        r = np.cumsum(rng.normal(0, k, n)) + rng.normal(0, 5e-6, n)
        f = fit_stochastic(r - r.mean(), 1.0, RW)
        kk, sd = f.params["k_per_rs"], f.params_std["k_per_rs"]
        z.append((kk - k) / sd)
    assert np.mean(np.abs(z) < 2) >= 0.75
    assert abs(np.mean(z)) < 1.0  # no gross bias


def test_p_value_never_underflows_to_zero():
    rng = np.random.default_rng(2)
    r = np.cumsum(rng.normal(0, 1.0, 4000)) + rng.normal(0, 0.01, 4000)
    assert fit_stochastic(r - r.mean(), 1.0, RW).p_value == 1e-300


@pytest.mark.parametrize("seed", [0, 1])
def test_a_limit_just_under_the_input_peak_clips_a_biased_unit_and_is_named_saturation(seed):
    """Found by the power curve: with a +2 mg bias, a limit 1.3 µg under the 1 g input peak clips
    the whole 0° dwell by ≈ 2 mg. Its size was judged on the unit-gain reference (a 1.3 µg clip,
    snr 2.5: too small) and the plateau's edges lifted the floor 12×, against which the readings
    looked like a lattice: 'quantization' was named, then k3 or asymmetry. The size of an
    output-stage effect is now judged on bias + SF·input, the lattice on the readings' spread."""
    rng = np.random.default_rng(seed)
    rec = make_experiment("accelerometer", rng, n=3000)
    sd = DEFAULT_NOISE_SD["accelerometer"]
    truth = Model(BaseModel("accelerometer", 2e-3, 1.001, sd)).with_effect("saturation", {"limit": 0.9999987})
    rec = rec.replace(y=truth.simulate(rec, rng))
    d = discover(rec, Model(base_model("accelerometer")), max_effects=2, seed=seed, n_rep=199)
    assert [s.effect_id for s in d.steps] == ["saturation"]
    assert d.steps[0].params["limit"] == pytest.approx(0.9999987, abs=3 * sd)
    assert abs(d.gap_final.rms_ratio - 1) < 0.1


def _gm_series(rng, n, dt, sigma, tau):
    phi = np.exp(-dt / tau)
    e = rng.normal(0, sigma * np.sqrt(1 - phi ** 2), n)
    e[0] = rng.normal(0, sigma)
    return signal.lfilter([1.0], [1.0, -phi], e)


def test_a_stochastic_candidate_on_the_models_own_noise_is_significant_at_its_level():
    """The null of a stochastic candidate holds the model's stochastic effects with every
    parameter free (profiled): held at the previous step's estimates, their error was colour
    the candidate claimed — a GM on a model holding the walk as the workflow estimates it
    (bias-corrected by bootstrap) came out p < 0.05 in 9 of these 40 records of the model's own
    noise (now 1); a walk on a model with a GM: 0 then, 1 now."""
    dt, n, seeds = 0.1, 3000, 40
    false_gm = false_rw = 0
    for seed in range(seeds):
        rng = np.random.default_rng(seed)
        r = rng.normal(0, 1, n) + np.cumsum(rng.normal(0, 0.01, n))  # white + a weak walk
        fr = fit_stochastic(r - r.mean(), dt, RW)  # bias-corrected, as the workflow names it
        false_gm += fit_stochastic(r - r.mean(), dt, GM, known=[(RW, fr.params)]).p_value < 0.05
        r = rng.normal(0, 1, n) + _gm_series(rng, n, dt, 0.5, 5.0)  # white + a GM
        fg = fit_stochastic(r - r.mean(), dt, GM)
        false_rw += fit_stochastic(r - r.mean(), dt, RW, known=[(GM, fg.params)], bootstrap=False).p_value < 0.05
    assert false_gm <= 5 and false_rw <= 5, (false_gm, false_rw)  # ≈ 2 expected of 40 each


def test_a_gauss_markov_on_top_of_a_known_walk_is_still_found():
    dt, n = 0.1, 3000
    found = 0
    for seed in range(20):
        rng = np.random.default_rng(100 + seed)
        r = rng.normal(0, 1, n) + np.cumsum(rng.normal(0, 0.02, n)) + _gm_series(rng, n, dt, 0.4, 2.0)
        fr = fit_stochastic(r - r.mean(), dt, RW, bootstrap=False)
        found += fit_stochastic(r - r.mean(), dt, GM, known=[(RW, fr.params)]).p_value < 0.05
    assert found >= 16, found  # 18/20 now; 7/20 with the walk's parameters held fixed


@pytest.mark.parametrize("kind,eid,params", [
    ("accelerometer", "time_delay", {"delay_s": 0.0029}),
    ("mhd", "lowpass_bandwidth", {"bandwidth_hz": 297.0}),
])
def test_a_large_effect_that_looks_like_its_competitor_is_still_named(kind, eid, params):
    """Found by the power curve: a 2.9 ms delay on the tumble (57 σ rms of residual) is told
    from a low-pass by only 2.5 σ. The size gate used that distinguishing snr, so neither the
    delay nor the low-pass passed it and the structure was named sinusoidal_interference +
    gauss_markov (every seed; the same for a 297 Hz low-pass on the MHD's multitone). The gate
    now asks whether the effect matters (its plain snr); which look-alike it is stays the
    competitors' report. Since the low-pass is the continuous single pole of an input linear
    between samples, a delay d and a low-pass of 1/(2π·d) agree to second order on the tumble:
    either name is right there, provided the other is reported as its competitor."""
    rng = np.random.default_rng(0)
    rec = make_experiment(kind, rng, n=3000)
    sd = DEFAULT_NOISE_SD[kind]
    truth = Model(BaseModel(kind, 0.3 * sd, 1.0001, sd)).with_effect(eid, params)
    rec = rec.replace(y=truth.simulate(rec, rng))
    d = discover(rec, Model(base_model(kind)), max_effects=2, seed=0, n_rep=199)
    assert len(d.steps) == 1
    step = d.steps[0]
    if step.effect_id == eid:
        main = CATALOGUE[eid].main_param
        assert abs(step.params[main] - params[main]) <= 3 * step.params_std[main]
    else:  # the look-alike, with the truth as its competitor and the equivalent time constant
        assert (step.effect_id, eid) == ("lowpass_bandwidth", "time_delay")
        assert eid in step.naming.competitors
        assert 1 / (2 * math.pi * step.params["bandwidth_hz"]) == pytest.approx(params["delay_s"], rel=0.15)
    assert abs(d.gap_final.rms_ratio - 1) < 0.05


@pytest.mark.xfail(strict=True, reason="known defect: the bootstrap null of a deterministic candidate "
                   "does not hold the calibration's own error through a coarse quantizer")
def test_after_a_coarse_quantizer_the_calibrations_own_error_is_not_named_k2():
    """The scorecard's accelerometer quantization case, seed 1 (step 13.8 σ on the tumble's
    dwells): once the quantizer is in the model, the calibration's small bias/SF error leaves
    dwell-constant structure that a 3.7 ± 0.5 µg/g² k2 explains (0.9 % of the residual's
    power; p = 0.001 against the model's own noise, which is simulated around the *fitted*
    calibration and so lacks that error). Named since the size gate uses the plain snr (it was
    held back by k2's look-alike, asymmetry, before). Strict: passes → remove the mark."""
    kind, sd = "accelerometer", DEFAULT_NOISE_SD["accelerometer"]
    rng = np.random.default_rng([1, 1, list(CATALOGUE).index("quantization")])  # the scorecard's draw
    rec = make_experiment(kind, rng, n=3000)
    truth = Model(BaseModel(kind, 2e-3 * rng.uniform(-1, 1), 1.0 + rng.normal(0, 2e-3), sd))
    on_output = rec.replace(input=truth.base.bias + truth.base.scale_factor * rec.input)
    truth = truth.with_effect("quantization", CATALOGUE["quantization"].draw(rng, on_output, kind=kind, noise_sd=sd))
    rec = rec.replace(y=truth.simulate(rec, rng))
    d = discover(rec, Model(base_model(kind)), max_effects=3, seed=1)
    assert [s.effect_id for s in d.steps] == ["quantization"]


def test_a_shape_nesting_the_pick_must_add_beyond_what_an_earlier_effects_error_gives_it():
    """A warm-up beside a temperature scale factor that was fitted before the warm-up was known
    (so it carries an error): two nodes absorb more of that error than one, and the in-sample
    nesting rule took them for a second node on 3 of these 10 records (seeds 4, 6, 7); judged
    with the scale factor refitted beside each shape, one exponential on 9 of 10. The same holds
    for Occam's in-sample check when two nodes out-score one (with the first block of the folds cut
    into spans they did on seeds 6 and 7, and the check without refits kept them): 10 of 10."""
    one = 0
    for seed in range(10):
        rng = np.random.default_rng(seed)
        rec = make_experiment("gyro", rng, n=3000)
        truth = (Model(BaseModel(kind="gyro", bias=0.03, scale_factor=1.0, noise_sd=3e-3))
                 .with_effect("temperature_scale_factor", {"sf_coef_per_c": -1.4e-4})
                 .with_effect("warmup_exponential", {"amplitude": 0.052, "tau_s": 40.0}))
        rec = rec.replace(y=truth.simulate(rec, rng))
        model = calibrate(calibrate(Model(base_model("gyro")), rec)
                          .with_effect("temperature_scale_factor", {"sf_coef_per_c": 0.0}), rec)
        best = name_effect(model, rec, seed=seed,
                           only=("warmup_exponential", "thermal_two_node", "linear_drift")).best
        assert best is not None
        one += best.id == "warmup_exponential"
    assert one >= 9


def test_the_audit_withdraws_one_name_then_re_chooses_before_judging_the_others():
    """The scorecard's triple scale-factor asymmetry + temperature scale factor + bias jump
    (accelerometer, seed 3002): K2 is named for the asymmetry (its look-alike), then the scale
    factor and the jump beside it. K2's shape fails its audit; judged beside the missing
    asymmetry the scale factor and the jump failed theirs too and all were withdrawn — nothing
    named, gap 2.5. Withdrawing K2 alone and re-choosing names the asymmetry, and the three
    hold. A random walk named beside K2 for its misfit, re-estimated once the asymmetry is named
    (``workflow.refit_processes``), is no longer significant there (p = 1) and is withdrawn
    (``workflow.faded_processes``) — refitted and kept, it was an extra name."""
    hidden = ("scale_factor_asymmetry", "temperature_scale_factor", "bias_jump")
    rec, _, _, redraws = hidden_case("accelerometer", hidden, 3002, 3000)
    assert redraws == 0  # the draw this test describes
    said: list[str] = []
    d = discover(rec, Model(base_model("accelerometer")), max_effects=4, seed=3002, progress=said.append)
    assert sorted(s.effect_id for s in d.steps) == sorted(hidden)
    assert any(w.startswith("k2_nonlinearity") for w in d.withdrawn)
    # after each withdrawal but the last round's, the next thing said is the re-choice
    for i, msg in enumerate(said[:-1]):
        if msg.startswith("withdrawn"):
            assert said[i + 1] == "re-choosing after the withdrawal"


def test_a_withdrawn_effect_may_be_named_again_beside_its_look_alike():
    """The scorecard's pair scale-factor asymmetry + K2 (gyro, seed 1001): K2 is named first, with
    the asymmetry folded into it; beside that biased K2 the asymmetry is not significant, and
    K2's shape fails its audit (|input| still explains the residual). The re-choice names the
    asymmetry; K2, withdrawn, sat out every re-choice after — its shape failed the asymmetry's
    audit in turn and nothing was named (gap 14). Beside the asymmetry K2 may come back."""
    hidden = ("scale_factor_asymmetry", "k2_nonlinearity")
    rec, _, _, redraws = hidden_case("gyro", hidden, 1001, 3000)
    assert redraws == 0  # the draw this test describes
    d = discover(rec, Model(base_model("gyro")), max_effects=3, seed=1001)
    assert sorted(s.effect_id for s in d.steps) == sorted(hidden)
    assert any(w.startswith("k2_nonlinearity") for w in d.withdrawn)
    assert any(n.startswith("k2_nonlinearity was withdrawn (above) and named again") for n in d.notes)
    assert d.gap_final.rms_ratio < 1.1


def test_an_input_transform_named_after_another_takes_its_place_in_the_chain():
    """Truth: a dead zone, then a 0.9-Hz low-pass (the scorecard's accelerometer triple 3015 with a
    random walk). Named in the other order, the fit left a spike at every zero crossing of the
    tumble — the walk beside them was set aside for those "jumps" and nothing but the low-pass
    stayed named (gap 2.4). ``input_order`` moves the dead zone before the low-pass; the order that
    is right already is kept; the step's std is computed at the effect's place."""
    rec = make_experiment("accelerometer", np.random.default_rng(3), n=3000)
    dz, lp = {"half_width": 2.3e-5}, {"bandwidth_hz": 0.9}
    truth = Model(BaseModel("accelerometer", bias=1e-5, scale_factor=1.0, noise_sd=5e-6)) \
        .with_effect("dead_zone", dz).with_effect("lowpass_bandwidth", lp)
    rec = rec.replace(y=truth.simulate(rec, 4))
    named = calibrate(Model(base_model("accelerometer")).with_effect("lowpass_bandwidth", lp)
                      .with_effect("dead_zone", dz), rec)
    moved = input_order(named, rec)
    assert moved.effect_ids == ("dead_zone", "lowpass_bandwidth")

    def rms(m):
        return float(np.sqrt(np.mean((rec.y - m.predict(rec)) ** 2)))
    assert rms(moved) < 1.1 * 5e-6 < rms(named)
    with_drift = moved.with_effect("linear_drift", {"slope_per_s": 1e-9})
    assert input_order(with_drift, rec) is with_drift  # the last effect is not an input transform
    right = calibrate(Model(base_model("accelerometer")).with_effect("dead_zone", dz)
                      .with_effect("lowpass_bandwidth", lp), rec)
    assert input_order(right, rec).effect_ids == right.effect_ids
    # the fitter places the effect where asked: its prediction is the model's with it there
    rest = Model(moved.base, moved.effects[1:])
    f = CandidateFitter(rest, rec, CATALOGUE["dead_zone"], noise_is_floor=False, template=moved.effects[0][1], at=0)
    x = f.pack(moved.effects[0][1], moved.base.bias, moved.base.scale_factor)
    np.testing.assert_allclose(f.predict(x), moved.predict(rec), rtol=0, atol=1e-15)
    assert np.isfinite(f.fit([x], max_nfev=1).params_std["half_width"])
    with pytest.raises(ValueError, match="at = 3; allowed: 0..1"):
        CandidateFitter(rest, rec, CATALOGUE["dead_zone"], at=3)


def test_a_term_the_later_names_made_redundant_is_withdrawn():
    """The scorecard's accelerometer triple jumps + dead zone + Gauss–Markov (seed 3017): a
    two-node warm-up named first for the slope of the jump staircase stayed named beside the
    jumps (an extra name). On the final model without it — the others refitted, the process
    re-estimated — the likelihood hardly drops: ``faded_terms`` withdraws it; the jumps, which
    nothing else stands in for, hold. (Stop 28 also ran ``discover`` on the record and found the
    triple; since stop 29 weighs a two-node against the warm-up it nests in the innovations of
    the named process, a one-node warm-up of τ 1 486 s is named first instead, the jumps are
    never named, and the triple is one of the usual sample's misses — README, issue 15.)"""
    hidden = ("bias_jump", "dead_zone", "gauss_markov")
    rec, truth, _, _ = hidden_case("accelerometer", hidden, 3017, 3000)
    spare = truth.with_effect("warmup_exponential", {"amplitude": 2e-5, "tau_s": 300.0})
    spare = calibrate(spare, rec, noise=False)
    r = rec.y - spare.predict(rec)
    faded = faded_terms(spare, rec, set(spare.effect_ids), r)
    assert [ev.effect_id for ev in faded] == ["warmup_exponential"]
    assert "no longer significant" in faded[0].describe()


def test_the_scorecard_draws_each_effect_of_a_mixture_at_snr_15_inside_it():
    """The scorecard's gyro triple temperature bias + K3 + random walk (seed 3014): first drawn,
    the bias is 19σ against white noise but 1.8σ against the walk beside it — no method could
    name it. The mixture's draw rule (``hidden_case``) draws it again until every effect is at
    snr ≥ 15 inside its mixture (``Model.effect_snr``); ``mix_rule=False`` (``--white-draws``)
    keeps the first draw, stop 27's rule."""
    hidden = ("temperature_bias", "k3_nonlinearity", "rate_random_walk")
    rec0, truth0, snrs0, redraws0 = hidden_case("gyro", hidden, 3014, 3000, mix_rule=False)
    assert redraws0 == 0 and snrs0[0] >= 15
    assert truth0.effect_snr(rec0, 0) < 3
    rec, truth, _, redraws = hidden_case("gyro", hidden, 3014, 3000)
    assert redraws > 0
    assert all(truth.effect_snr(rec, i) >= 15 for i in range(3))
    assert not np.array_equal(rec.y, rec0.y)
    # a single is never redrawn: its rule is Effect.draw's alone
    assert hidden_case("gyro", ("temperature_bias",), 0, 3000)[3] == 0


def test_a_jump_found_beside_a_wrong_shape_is_searched_again_once_the_model_changes():
    """``calibrate`` moves a jump's time within its sample only: a jump found at 840 s (beside a
    warm-up named for a two-node transient, the scorecard's accelerometer triple 3001 of
    ``--pairs 0 --triples 30``) stays there once the transient is right, 36 s from the step.
    ``reseated`` searches its change points again on what the others leave (no more jumps than
    it has) and keeps the move when the sum of squares falls; a jump in place and an effect
    whose fit is no search are left as they are."""
    rec = make_experiment("accelerometer", np.random.default_rng(5), n=3000)
    warm = {"amplitude": -3e-4, "tau_s": 60.0}
    jumps = {"size_1": 4e-5, "time_1_s": 875.6, "size_2": -3.5e-5, "time_2_s": 1800.4, "size_3": 0.0, "time_3_s": 0.0}
    truth = Model(BaseModel("accelerometer", bias=1e-4, scale_factor=1.0, noise_sd=5e-6)) \
        .with_effect("warmup_exponential", warm).with_effect("bias_jump", jumps)
    rec = rec.replace(y=truth.simulate(rec, 8))
    wrong = calibrate(Model(base_model("accelerometer")).with_effect("warmup_exponential", warm)
                      .with_effect("bias_jump", jumps | {"time_1_s": 840.2}), rec)
    assert abs(wrong.effects[1][1]["time_1_s"] - 840.2) < 1.0  # least squares cannot move it
    moved = reseated(wrong, rec)
    p = moved.effects[1][1]
    assert abs(p["time_1_s"] - 875.6) < 1.0 and abs(p["time_2_s"] - 1800.4) < 1.0
    assert CATALOGUE["bias_jump"].count(p) == 2
    rms = float(np.sqrt(np.mean((rec.y - moved.predict(rec)) ** 2)))
    assert rms < 1.05 * 5e-6
    right = calibrate(Model(base_model("accelerometer")).with_effect("warmup_exponential", warm)
                      .with_effect("bias_jump", jumps), rec)
    again = reseated(right, rec)
    assert abs(again.effects[1][1]["time_1_s"] - right.effects[1][1]["time_1_s"]) < 0.5
    warm_only = calibrate(Model(base_model("accelerometer")).with_effect("warmup_exponential", warm), rec)
    assert reseated(warm_only, rec) is warm_only  # the warm-up's fit is no search
    # the search again holds at most as many jumps as the effect has
    starts = CATALOGUE["bias_jump"].searched_starts(jumps | {"size_2": 0.0}, rec, rec.y - truth.predict(rec)
                                                    + CATALOGUE["bias_jump"].term(jumps, rec), kind="accelerometer")
    assert CATALOGUE["bias_jump"].count(starts[0]) == 1


def _named_at_step(kind: str, hidden: tuple[str, ...], seed: int, known: int):
    """The naming step of the scorecard's triple ``hidden`` (``hidden_case(kind, hidden, seed)``)
    on the model that holds its first ``known`` effects at the truth, calibrated — the step
    ``discover`` reaches after naming them (its seed: the record's + ``known``)."""
    case = hidden_case(kind, hidden, seed, 3000)
    assert case is not None, "the scorecard's case is drawable"
    rec, truth, _, _ = case
    model = calibrate(Model(truth.base, truth.effects[:known]), rec)
    return name_effect(model, rec, seed=seed + known)


def test_a_walk_that_keeps_nothing_beside_the_jumps_does_not_take_their_name():
    """The scorecard's accelerometer triple asymmetry + temperature scale factor + two jumps of
    3e-6 g (seed 3005 of ``--pairs 0 --triples 30``): at the third step a walk of 6e-8 g/√s
    made the jumps look typical (a walk steps too) and their likelihood gain was not 25 above
    the walk's, so the walk was named. Refitted beside the jumps the walk keeps nothing of its
    evidence: the jumps are named."""
    naming = _named_at_step("accelerometer",
                            ("scale_factor_asymmetry", "temperature_scale_factor", "bias_jump"), 3005, 2)
    walk = next(c for c in naming.candidates if c.id == "rate_random_walk")
    assert walk.named  # significant and big enough on its own: the two were in contest
    assert naming.best is not None and naming.best.id == "bias_jump"


def test_a_jump_and_a_warm_up_of_as_many_parameters_tied_held_out_are_told_apart_in_sample():
    """The scorecard's MHD triple K3 + temperature scale factor + a jump at 0.73 s of a 6-s record
    (seed 3002): at the third step a warm-up of τ 0.73 s scored 0.068 held-out and the jump 0.059
    (standard error 0.024) — a held-out block that holds the jump hides its time — and the
    warm-up was named. Both have two free parameters; refitted with the model, the jump leaves
    43 white variances less: it is named (``parsimonious`` with ``rec``)."""
    naming = _named_at_step("mhd", ("k3_nonlinearity", "temperature_scale_factor", "bias_jump"), 3002, 2)
    warm = next(c for c in naming.candidates if c.id == "warmup_exponential")
    jump = next(c for c in naming.candidates if c.id == "bias_jump")
    assert warm.named and jump.named and warm.score > jump.score
    assert naming.best is not None and naming.best.id == "bias_jump"


def test_a_one_node_warm_up_beside_a_walk_is_not_taken_for_two_nodes():
    """The scorecard's gyro triple sine + warm-up + random walk (seed 3013 of ``--pairs 0
    --triples 30``): at the second step the two-node scored best held-out and its second node
    explained more than 25 white variances beyond the one-node warm-up in-sample — by following
    the walk's wander, which no effect of the model holds yet: the two-node was named. A shape and
    the one it nests are weighed in the innovations of the named process refitted beside the
    simpler (``naming.colour_beside``): there the second node adds less than the gate, and the
    warm-up is named."""
    naming = _named_at_step("gyro",
                            ("sinusoidal_interference", "warmup_exponential", "rate_random_walk"), 3013, 1)
    two = next(c for c in naming.candidates if c.id == "thermal_two_node")
    assert two.named  # in contest
    assert naming.best is not None and naming.best.id == "warmup_exponential"


def _drift_and_two_nodes(extra: tuple = ()) -> tuple[Record, Model]:
    """A gyro start-up record: a drift and a two-node transient (the scorecard's gyro triple
    3017's values), white noise only, plus ``extra`` effects."""
    rec = make_experiment("gyro", np.random.default_rng(17), n=3000)
    truth = Model(BaseModel("gyro", bias=0.0176, scale_factor=1.0, noise_sd=0.003)) \
        .with_effect("linear_drift", {"slope_per_s": 8.09e-5}) \
        .with_effect("thermal_two_node", {"amplitude": -0.1388, "fraction_slow": 0.687,
                                          "tau_fast_s": 2.09, "tau_slow_s": 18.17})
    for eid, p in extra:
        truth = truth.with_effect(eid, p)
    return rec.replace(y=truth.simulate(rec, 3)), truth


def test_a_two_node_named_for_a_drift_and_a_warm_up_for_its_fast_node_are_merged():
    """The scorecard's gyro triple drift + two-node + Gauss–Markov (seed 3017 of the usual
    sample): the two-node came first for the drift and the transient's slow node (calibrated,
    its slow node at 2 500 s on 300 s), a warm-up was named beside it for the fast node — one
    parameter more than the truth and two wrong names. ``renested`` tries the two-node alone at
    the pair's time constants, with a drift for a node beyond the record: the likelihood the same,
    a parameter fewer, the merge is kept (the transient's constants recovered); a right model has
    no nested pair, and a warm-up of its own beside the transient is not merged away."""
    rec, _ = _drift_and_two_nodes()
    named = Model(base_model("gyro")) \
        .with_effect("thermal_two_node", {"amplitude": -0.15, "fraction_slow": 0.268, "tau_fast_s": 13.8,
                                          "tau_slow_s": 227.5}) \
        .with_effect("warmup_exponential", {"amplitude": -0.041, "tau_s": 2.12})
    named = calibrate(named, rec)
    merged = renested(named, rec)
    assert merged is not None
    assert (merged.into, merged.dropped, merged.added) == ("thermal_two_node", "warmup_exponential", ("linear_drift",))
    assert sorted(merged.model.effect_ids) == ["linear_drift", "thermal_two_node"]
    p = dict(merged.model.effects[merged.model.effect_ids.index("thermal_two_node")][1])
    assert p["tau_fast_s"] == pytest.approx(2.09, rel=0.2) and p["tau_slow_s"] == pytest.approx(18.17, rel=0.2)
    assert "fewer" in merged.why
    right = calibrate(Model(base_model("gyro")).with_effect("linear_drift", {"slope_per_s": 8e-5})
                      .with_effect("thermal_two_node", p), rec)
    assert renested(right, rec) is None  # nothing nested beside the two-node
    # a warm-up of its own (τ 60 s) beside the transient and the drift: three exponentials
    rec3, truth3 = _drift_and_two_nodes((("warmup_exponential", {"amplitude": 0.05, "tau_s": 60.0}),))
    three = calibrate(Model(truth3.base, truth3.effects), rec3)
    assert renested(three, rec3) is None


def test_a_two_node_whose_slow_share_the_range_stopped_is_not_named_alone():
    """A two-node transient whose slow node's share sits at either end of its range is a hump the
    range stopped: two jumps down on the MHD's 6-s record took f = 3.0, τ 0.92/2.74 s at the second
    step of the scorecard's MHD triple jumps + saturation + Gauss–Markov (seed 3029 of ``--pairs 3
    --triples 30``), scored a hair above the jumps held-out and was named. Its shape is not a
    two-node's (``shape_inside``): not named alone, and the jumps are."""
    two = CATALOGUE["thermal_two_node"]
    p = {"amplitude": 0.2, "fraction_slow": 0.5, "tau_fast_s": 0.92, "tau_slow_s": 2.74}
    assert two.shape_inside(p) and two.shape_inside(p | {"fraction_slow": 2.9})
    assert not two.shape_inside(p | {"fraction_slow": 3.0}) and not two.shape_inside(p | {"fraction_slow": -2.0})
    rec, truth, _, _ = hidden_case("mhd", ("bias_jump", "saturation", "gauss_markov"), 3029, 3000)
    model = calibrate(Model(truth.base, truth.effects[1:2]), rec)  # the clip, as discover names it first
    naming = name_effect(model, rec, seed=3029 + 1)
    cand = next(c for c in naming.candidates if c.id == "thermal_two_node")
    assert not two.shape_inside(cand.params) and not cand.named
    assert naming.best is not None and naming.best.id == "bias_jump"


def test_a_walk_is_judged_at_its_exact_likelihood_level_not_the_whittle_one():
    """The scorecard's gyro triple asymmetry + low-pass + random walk (seed 3022 of ``--pairs 0
    --triples 30``): at the third step the walk had the best BIC gain, but its Whittle level
    (3.9e-4 °/s/√s for 2.2e-4: a finite walk's levels periodogram leaks at the record's ends)
    left innovations at 0.27× their level over the lowest bins — its signature "failed" and a
    Gauss–Markov was named. Judged at its exact-likelihood level on the same residual
    (``evidence.process_evidence``), the walk's signature holds and it is named."""
    naming = _named_at_step("gyro",
                            ("scale_factor_asymmetry", "lowpass_bandwidth", "rate_random_walk"), 3022, 2)
    assert naming.best is not None and naming.best.id == "rate_random_walk"
    assert naming.set_aside == ()


def test_behind_a_coarse_quantizer_the_null_through_it_decides_a_localized_term():
    """The scorecard's MHD triple quantizer + K3 + flicker (seed 3003 of ``--pairs 9 --triples
    30``): at the third step three jumps were typical under the flicker drawn through the
    quantizer (p = 0.06), but their Gaussian likelihood gain was 200 above the flicker's — a
    process crossing coarse steps reads as steps — and they were named, a Gauss–Markov beside
    them. Behind an effect that colours the residual (``Effect.colours_residual``) the null drawn
    through it decides: the flicker is named."""
    naming = _named_at_step("mhd", ("quantization", "k3_nonlinearity", "flicker_noise"), 3003, 2)
    jump = next(c for c in naming.candidates if c.id == "bias_jump")
    assert jump.named  # significant against white noise: in contest
    assert naming.best is not None and naming.best.id == "flicker_noise"


def test_a_process_behind_a_clip_is_carried_across_the_clipped_stretches():
    """The scorecard's accelerometer triple K3 + saturation + Gauss–Markov (seed 3015 of
    ``--pairs 1 --triples 30``; 18 % of the tumble clipped): a clipped reading is the limit
    whatever the noise, so the residual there is flat. Read as samples of the process, the flat
    stretches set the GM aside (its innovations jumped 6 σ at a stretch's end), a warm-up took
    its place, and the audit withdrew every name. With the clipped samples missing to the filter
    and the likelihood (``Model.noise_seen``) the GM is named at its exact-likelihood values."""
    naming = _named_at_step("accelerometer", ("k3_nonlinearity", "saturation", "gauss_markov"), 3015, 2)
    assert naming.best is not None and naming.best.id == "gauss_markov", naming.set_aside
    assert naming.set_aside == ()
    # truth σ 9.3e-6, τ 21.2 s (Whittle on the flat stretches: 8.6e-6, 15.2 s)
    assert naming.best.params["sigma"] == pytest.approx(9.3e-6, rel=0.15)
    assert naming.best.params["tau_s"] == pytest.approx(21.2, rel=0.3)


def _scorecard_record(kind: str, hidden: tuple[str, ...], seed: int):
    case = hidden_case(kind, hidden, seed, 3000)
    assert case is not None, "the scorecard's case is drawable"
    rec, truth, _, _ = case
    return rec, truth


def test_a_clip_that_shrinks_the_calibrated_scale_factor_is_still_fitted_held_out():
    """The scorecard's accelerometer triple clip + dead zone + vibration rectification (seed 3010
    of ``--pairs 1 --triples 30``): clipped at 0.61 g, the tumble's calibrated scale factor
    shrank to 0.73, so every limit the grid offered the held-out fits (0.86, 0.74) clipped
    nothing and could not move: held-out score 0, nothing named at all. The clip's fits start
    from the readings' own extreme on the rows they see (``Saturation.fit_starts``)."""
    rec, truth = _scorecard_record("accelerometer",
                                   ("saturation", "dead_zone", "vibration_rectification"), 3010)
    model = calibrate(Model(truth.base), rec)
    assert model.base.scale_factor < 0.8
    naming = name_effect(model, rec, seed=3010, n_rep=199, only=("saturation",))
    assert naming.best is not None and naming.best.id == "saturation"
    assert naming.best.score > 0.9
    assert naming.best.params["limit"] == pytest.approx(dict(truth.effects)["saturation"]["limit"], rel=1e-3)


def test_a_look_alike_named_first_is_swapped_once_the_others_are_named():
    """The scorecard's accelerometer triple saturation + low-pass + thermal hysteresis (seed 3006
    of ``--pairs 9 --triples 30``): a 0.189-s delay and the 0.84-Hz low-pass tied at the first
    step (held-out 0.6916 and 0.6914) and the delay was named; beside the clip named next it
    left 7.6× the floor, which a sinusoid and K2 were named for. Once the names are in, the
    low-pass in the delay's place leaves far less (``relooked``); with the truth's low-pass
    there is nothing to swap, nor for K3 (no look-alike)."""
    rec, truth = _scorecard_record("accelerometer",
                                   ("saturation", "lowpass_bandwidth", "thermal_hysteresis"), 3006)
    sat = dict(truth.effects)["saturation"]
    delayed = calibrate(Model(truth.base, (("time_delay", {"delay_s": 0.189}), ("saturation", sat))), rec)
    swapped = relooked(delayed, rec)
    assert swapped is not None and (swapped.dropped, swapped.into) == ("time_delay", "lowpass_bandwidth")
    assert swapped.model.effect_ids == ("lowpass_bandwidth", "saturation")
    assert dict(swapped.model.effects)["lowpass_bandwidth"]["bandwidth_hz"] == pytest.approx(0.839, rel=0.02)
    right = calibrate(Model(truth.base, (("lowpass_bandwidth", {"bandwidth_hz": 0.84}), ("saturation", sat))), rec)
    assert relooked(right, rec) is None


def test_a_swap_keeps_the_story_of_the_initial_model():
    """On the same record ``discover`` names the delay, then swaps it for the low-pass. The swap
    once wrote the gap, rms and residual of the model without the look-alike over the discovery's
    initial ones (``rms_initial`` 1.84e-2 for the initial model's 2.15e-2): the report's "before"
    was not the starting model. The look-alike's own step starts from that model instead."""
    rec, _ = _scorecard_record("accelerometer",
                               ("saturation", "lowpass_bandwidth", "thermal_hysteresis"), 3006)
    d = discover(rec, Model(base_model("accelerometer")), max_effects=4, seed=3006)
    assert any(w.startswith("time_delay: its look-alike lowpass_bandwidth") for w in d.withdrawn), d.withdrawn
    g0, rms0, _, r0 = gap_of(d.initial_model, rec, 3006)
    assert d.rms_initial == rms0 and d.gap_initial.rms_ratio == g0.rms_ratio
    np.testing.assert_array_equal(d.residual_initial, r0)
    low = next(st for st in d.steps if st.effect_id == "lowpass_bandwidth")
    assert low.rms_before > low.rms_after and low.rms_before != rms0


def test_a_term_idle_beside_a_clip_is_judged_on_the_samples_the_clip_leaves():
    """The same record: a K2 named for the delay's misfit stayed beside the low-pass that replaced
    it (and the hysteresis named after) — the audit's likelihood test was not run through an
    output stage. Behind a clip (no
    colour: ``Model.colours_residual``) it counts the samples the clip leaves: K2 is idle there,
    the low-pass is not."""
    rec, truth = _scorecard_record("accelerometer",
                                   ("saturation", "lowpass_bandwidth", "thermal_hysteresis"), 3006)
    sat = dict(truth.effects)["saturation"]
    hyst = dict(truth.effects)["thermal_hysteresis"]
    model = calibrate(Model(truth.base, (("lowpass_bandwidth", {"bandwidth_hz": 0.84}), ("saturation", sat),
                                         ("k2_nonlinearity", {"k2_per_u": 1.98e-5}),
                                         ("thermal_hysteresis", hyst))), rec)
    r = rec.y - model.predict(rec)
    faded = {ev.effect_id for ev in faded_terms(model, rec, {"lowpass_bandwidth", "k2_nonlinearity"}, r)}
    assert faded == {"k2_nonlinearity"}


def test_two_slow_terms_together_are_weighed_before_the_walk_that_follows_their_sum():
    """The scorecard's accelerometer triple temperature bias + drift + two-node warm-up (seed 3003
    of ``--pairs 1 --triples 30``): once the two-node is named, a walk (held-out 0.25) follows the
    sum of the other two better than either alone (drift 0.14, temperature 0.12), and was named.
    Fitted together beside the model the pair explains the record better than the walk by the
    size gate and leaves nothing of it (``choosing.pair_over_process``): the temperature bias —
    not the drift, a catch-all whose signature its partner breaks — is named, then the drift."""
    rec, truth = _scorecard_record("accelerometer",
                                   ("temperature_bias", "linear_drift", "thermal_two_node"), 3003)
    model = calibrate(Model(truth.base, truth.effects[2:]), rec)
    naming = name_effect(model, rec, seed=3004)
    walk = next(c for c in naming.candidates if c.id == "rate_random_walk")
    assert walk.named and walk.score > max(c.score for c in naming.candidates
                                           if c.id in ("temperature_bias", "linear_drift"))
    assert naming.best is not None and naming.best.id == "temperature_bias"
    then = name_effect(calibrate(model.with_effect("temperature_bias", naming.best.params), rec), rec, seed=3005)
    assert then.best is not None and then.best.id == "linear_drift"


def test_a_two_node_named_before_a_walk_gives_way_to_the_warm_up_it_nests():
    """The scorecard's gyro triple asymmetry + warm-up + walk (seed 3013 of ``--pairs 1 --triples
    30``): a two-node (slow node 168 s of share −0.24 on a 300-s record) was named before the
    walk. With the walk in the model a warm-up alone in its place, fitted by the exact
    likelihood, costs 3.4 in −2 ln L for two parameters fewer (``unnested``): it is the name, at
    the truth's values. Beside a Gauss–Markov instead of the walk the rule is not tried."""
    rec, truth = _scorecard_record("gyro",
                                   ("scale_factor_asymmetry", "warmup_exponential", "rate_random_walk"), 3013)
    two_node = {"amplitude": -0.0793, "fraction_slow": -0.2365, "tau_fast_s": 1.904, "tau_slow_s": 167.85}
    model = calibrate(Model(truth.base, (("scale_factor_asymmetry", {"asymmetry": 1.27e-3}),
                                         ("thermal_two_node", two_node),
                                         ("rate_random_walk", {"k_per_rs": 4.52e-4}))), rec)
    merged = unnested(model, rec)
    assert merged is not None and (merged.dropped, merged.into, merged.added) == (
        "thermal_two_node", "warmup_exponential", ("warmup_exponential",))
    warm = dict(merged.model.effects)["warmup_exponential"]
    true_warm = dict(truth.effects)["warmup_exponential"]
    assert warm["amplitude"] == pytest.approx(true_warm["amplitude"], rel=0.05)
    assert warm["tau_s"] == pytest.approx(true_warm["tau_s"], rel=0.1)
    beside_gm = Model(model.base, (*model.effects[:2], ("gauss_markov", {"sigma": 0.01, "tau_s": 30.0})))
    assert unnested(beside_gm, rec) is None


def test_jumps_and_a_gauss_markov_give_way_to_the_walk_that_explains_them_alone():
    """The scorecard's accelerometer triple misalignment + clip + walk (seed 3026 of ``--pairs 7
    --triples 30``): with the misalignment still missing, every process's innovations followed
    its cross input and was set aside, so three jumps were named, then the misalignment, then a
    Gauss–Markov for the rest of the wander. Once the names are in, a walk alone in place of the
    jumps and the GM costs 45.9 in −2 ln L for 7 parameters fewer — within their BIC and the size
    gate (76): ``unjumped`` names the walk. Three real jumps beside a real GM (the triple
    asymmetry + jump + GM, seed 3009 of ``--pairs 7``) beat every process alone by far more."""
    rec, truth = _scorecard_record("accelerometer", ("misalignment", "saturation", "rate_random_walk"),
                                   3026)
    jumps = {"size_1": -5.63e-6, "time_1_s": 169.82, "size_2": -3.73e-6, "time_2_s": 1780.64,
             "size_3": -7.01e-6, "time_3_s": 2527.5}
    model = calibrate(Model(truth.base, (truth.effects[1], ("bias_jump", jumps), truth.effects[0],
                                         ("gauss_markov", {"sigma": 2.06e-6, "tau_s": 81.1}))), rec)
    out = unjumped(model, rec)
    assert out is not None
    alt, into, gone, why = out
    assert into == "rate_random_walk" and set(gone) == {"bias_jump", "gauss_markov"}, why
    assert alt.effect_ids == ("saturation", "misalignment", "rate_random_walk")
    assert unjumped(model, rec, exclude=frozenset({"rate_random_walk", "gauss_markov", "flicker_noise"})) is None
    # a process of the starting model (not named by the discovery) stays, known, beside the one fitted
    kept = unjumped(model, rec, named=frozenset({"saturation", "bias_jump", "misalignment"}))
    assert kept is not None and kept[2] == ("bias_jump",) and "gauss_markov" in kept[0].effect_ids
    rec2, truth2 = _scorecard_record("accelerometer",
                                     ("scale_factor_asymmetry", "bias_jump", "gauss_markov"), 3009)
    assert unjumped(calibrate(truth2, rec2), rec2) is None


def test_a_walk_behind_a_coarse_quantizer_is_judged_where_it_moved_the_signal():
    """The scorecard's gyro triple quantizer (steps of 6 noise sd) + g-sensitivity + walk (seed
    3004 of ``--pairs 4 --triples 30``): the walk moves the signal about a step along the lattice
    in 300 s, and the readings flip only while it sits near a threshold. The innovation profile
    averaged that over the walk's whole spread, so a stretch the walk spent near a threshold read
    1.26× the floor under every process — all three were set aside and three jumps and a
    Gauss–Markov were named. Judged where the processes' one-step prediction places the signal
    (``innovations_profile(residual=…)``), a process's signature holds and a process is named."""
    naming = _named_at_step("gyro", ("quantization", "g_sensitivity", "rate_random_walk"), 3004, 2)
    assert naming.set_aside == ()
    assert naming.best is not None and naming.best.stochastic


def test_jumps_scored_below_a_term_that_lost_to_a_walk_still_have_their_turn():
    """The scorecard's accelerometer triple temperature rate + two jumps + K2 (seed 3007 of
    ``--pairs 8 --triples 30``): once the temperature rate and K2 were named, a temperature bias
    scored 0.47, the jumps (fitted to a second) 0.46 and a walk 0.57; the temperature bias lost to
    the walk and the walk was named at once — the jumps were never tested against it. Localized
    explanations are tested first: the jumps are named."""
    rec, truth = _scorecard_record("accelerometer",
                                   ("temperature_rate", "bias_jump", "k2_nonlinearity"), 3007)
    model = calibrate(Model(truth.base, (truth.effects[0], truth.effects[2])), rec)
    naming = name_effect(model, rec, seed=3007 + 2)
    assert naming.best is not None and naming.best.id == "bias_jump", naming.best
    assert abs(naming.best.params["time_1_s"] - 1592.2) < 2 and abs(naming.best.params["time_2_s"] - 2305.3) < 2


def test_jumps_that_explain_more_than_a_walk_are_named_though_a_real_process_stays_beside():
    """The scorecard's accelerometer triple three jumps + dead zone + Gauss–Markov (seed 3019 of
    ``--pairs 2 --triples 30``): beside the dead zone the jumps gain 2805 on the Whittle likelihood,
    a walk alone 2781; the walk refitted beside the jumps stayed significant (the GM is real), and
    that was read as the jumps being the walk's wander — the walk was named. Jumps that explain
    more are named; the process beside them is named at the next step."""
    rec, truth = _scorecard_record("accelerometer", ("bias_jump", "dead_zone", "gauss_markov"), 3019)
    model = calibrate(Model(truth.base, (truth.effects[1],)), rec)
    naming = name_effect(model, rec, seed=3019 + 1)
    assert naming.best is not None and naming.best.id == "bias_jump", naming.best
    after = calibrate(model.with_effect("bias_jump", naming.best.params), rec)
    naming = name_effect(after, rec, seed=3019 + 2)
    assert naming.best is not None and naming.best.id == "gauss_markov", naming.best


def test_a_walk_named_for_jumps_while_a_thermal_term_was_missing_gives_way_to_them():
    """The scorecard's accelerometer triple hysteresis + temperature scale factor + two jumps
    (seed 3025 of ``--pairs 5`` and ``--pairs 8``): before the hysteresis was named, a walk
    explained the jumps and the hysteresis loop together better than the jumps (Whittle 1699 vs
    1442) and was named; the hysteresis came next. Once the names are in, jumps in the walk's
    place beat it by 126 in −2 ln L for 5 parameters more and 3 searched times (gate 83.6), and
    the walk refitted beside them is not significant: ``jumped``."""
    rec, truth = _scorecard_record("accelerometer",
                                   ("thermal_hysteresis", "temperature_scale_factor", "bias_jump"), 3025)
    walk = Model(truth.base, truth.effects[:2] + (("rate_random_walk", {"k_per_rs": 1e-7}),))
    model, _ = refit_processes(calibrate(walk, rec), rec)
    out = jumped(model, rec)
    assert out is not None
    alt, into, gone, why = out
    assert into == "bias_jump" and gone == ("rate_random_walk",), why
    p = dict(alt.effects[alt.effect_ids.index("bias_jump")][1])
    found = [(p[f"time_{k}_s"], p[f"size_{k}"]) for k in (1, 2, 3) if abs(p[f"size_{k}"]) > 1e-6]
    assert len(found) == 2, p  # a third slot's search start shrank to the floor beside the hysteresis
    for (t, size), (t_true, size_true) in zip(found, ((1303.3, 4.69e-6), (2478.8, 3.85e-6))):
        assert abs(t - t_true) < 10 and abs(size - size_true) < 0.3 * size_true, p
    assert jumped(model, rec, exclude=frozenset({"bias_jump"})) is None
    assert jumped(model, rec, named=frozenset({"thermal_hysteresis"})) is None  # the walk was the user's
    # a weak real walk whose largest step one jump takes stays (accelerometer K3 + hysteresis + walk,
    # seed 3006 of --pairs 12: 34.2 better, the gate 39.6 with the jump's time counted twice)
    rec2, truth2 = _scorecard_record("accelerometer",
                                     ("k3_nonlinearity", "thermal_hysteresis", "rate_random_walk"), 3006)
    walk2, _ = refit_processes(calibrate(truth2, rec2), rec2)
    assert jumped(walk2, rec2) is None


def test_a_walk_named_as_a_drift_and_a_gauss_markov_gives_way_to_the_walk_alone():
    """The scorecard's gyro triple asymmetry + K3 + walk (seed 3008 of ``--pairs 5``): once K3
    and the asymmetry were in, a drift (held-out 0.240) scored above the walk (0.228) and a
    Gauss–Markov of τ 8.6 s took the rest. The walk alone in their place costs 33.8 in −2 ln L for
    2 parameters fewer, within their BIC and the size gate (39.6): ``unjumped`` names the walk.
    A real drift beside a real Gauss–Markov (gyro drift + delay + GM, seed 3004 of ``--pairs 2``)
    is kept."""
    rec, truth = _scorecard_record("gyro", ("scale_factor_asymmetry", "k3_nonlinearity",
                                                         "rate_random_walk"), 3008)
    model = calibrate(Model(truth.base, truth.effects[:2] + (("linear_drift", {"slope_per_s": 1.97e-5}),
                                                             ("gauss_markov", {"sigma": 5.49e-4, "tau_s": 8.57}))),
                      rec)
    out = unjumped(model, rec)
    assert out is not None
    _, into, gone, why = out
    assert into == "rate_random_walk" and set(gone) == {"linear_drift", "gauss_markov"}, why
    rec2, truth2 = _scorecard_record("gyro", ("linear_drift", "time_delay", "gauss_markov"), 3004)
    assert unjumped(calibrate(truth2, rec2), rec2) is None


def test_a_two_node_named_for_a_warmup_beside_a_term_fitted_to_the_warming_gives_way_to_it():
    """The scorecard's gyro triple temperature scale factor + warm-up (τ 23.3 s) + g-sensitivity
    (seed 3003 of ``--pairs 8``): a candidate's fit keeps the effects named before it fixed, and
    beside a temperature scale factor fitted to the warming the warm-up's went to τ 38 s; a
    two-node (6.5 s and 54 s) scored above it and was named. With no random process the residual
    is white: the warm-up fitted in its place and the whole model calibrated costs 3.2 in −2 ln L
    for 2 parameters fewer (ln(n/2) = 7.3 each) — ``unnested`` names it, at τ ≈ 23 s."""
    rec, truth = _scorecard_record("gyro",
                                   ("temperature_scale_factor", "warmup_exponential", "g_sensitivity"), 3003)
    two = {"amplitude": -0.03867, "fraction_slow": 0.5383, "tau_fast_s": 6.479, "tau_slow_s": 53.77}
    model = calibrate(Model(truth.base, (truth.effects[0], truth.effects[2], ("thermal_two_node", two))), rec)
    merged = unnested(model, rec)
    assert merged is not None and merged.into == "warmup_exponential" and merged.dropped == "thermal_two_node"
    p = dict(merged.model.effects[merged.model.effect_ids.index("warmup_exponential")][1])
    assert abs(p["tau_s"] - 23.3) < 2.5, p
    # a real two-node beside terms and white noise stays (mhd hysteresis + asymmetry + two-node, seed 3000
    # of --pairs 2; gyro drift + two-node + vibration rectification, seed 3007 of --pairs 2)
    for kind, hidden, seed in (("mhd", ("thermal_hysteresis", "scale_factor_asymmetry", "thermal_two_node"), 3000),
                               ("gyro", ("linear_drift", "thermal_two_node", "vibration_rectification"), 3007)):
        rec2, truth2 = _scorecard_record(kind, hidden, seed)
        assert unnested(calibrate(truth2, rec2), rec2) is None


def test_a_warmup_and_a_walk_named_for_a_two_node_transient_give_way_to_it():
    """The scorecard's gyro triple two jumps + misalignment + two-node transient (seed 3000 of
    ``--pairs 2``): with the jumps at 48 and 170 s still in the residual the two-node's fit was
    off and a warm-up was named (the simpler shape, within a standard error), and once the jumps
    were in a process took the slow node. The two-node alone in place of the warm-up and the
    process beats them by far more than its extra parameters and the size gate: ``grown``.
    A real warm-up beside a real walk (gyro asymmetry + warm-up + walk, seed 3012 of
    ``--pairs 3``) is kept."""
    rec, truth = _scorecard_record("gyro", ("bias_jump", "misalignment", "thermal_two_node"), 3000)
    model = calibrate(Model(truth.base, (("warmup_exponential", {"amplitude": 0.19, "tau_s": 7.9}), truth.effects[0],
                                         truth.effects[1], ("rate_random_walk", {"k_per_rs": 1e-3}))), rec)
    model, _ = refit_processes(model, rec)
    out = grown(model, rec)
    assert out is not None
    alt, into, gone, why = out
    assert into == "thermal_two_node" and set(gone) == {"warmup_exponential", "rate_random_walk"}, why
    assert alt.stochastic_effects() == []
    assert grown(model, rec, exclude=frozenset({"thermal_two_node"})) is None
    assert grown(model, rec, named=frozenset({"warmup_exponential", "bias_jump", "misalignment"})) is None
    rec2, truth2 = _scorecard_record("gyro", ("scale_factor_asymmetry", "warmup_exponential",
                                                           "rate_random_walk"), 3012)
    assert grown(calibrate(truth2, rec2), rec2) is None


def test_a_sine_beside_a_clip_starts_its_fold_fits_at_its_line_not_a_sideband():
    """The scorecard's gyro triple temperature bias + sine of 0.1163 Hz + clip (17 % of the
    samples; seed 3022 of ``--pairs 2``): on a fold's training blocks (6.25 s, shorter than the
    sine's period) the periodogram ranked the line's sidebands by the fold pattern (0.0367 and
    0.1967 Hz) above it, both folds started there and the sine scored −0.6 held out (its full
    fit nailed it). Ranked by what each line explains of the rows beside the clip, the line
    starts both folds: the sine is named at the third step."""
    hidden = ("temperature_bias", "sinusoidal_interference", "saturation")
    rec, truth = _scorecard_record("gyro", hidden, 3022)
    effects = dict(truth.effects)
    model = calibrate(Model(truth.base, (("saturation", effects["saturation"]),
                                         ("temperature_bias", effects["temperature_bias"]))), rec)
    r = rec.y - model.predict(rec)
    seen = model.follows_input(rec)
    assert 0.1 < 1 - seen.mean() < 0.3
    folds = sig.block_folds(rec.n)
    for k in (0, 1):
        te = folds == k
        start = CATALOGUE["sinusoidal_interference"].fit_starts(rec, r, kind="gyro", rows=~te & seen, held_out=te)[0]
        assert start["freq_hz"] == pytest.approx(effects["sinusoidal_interference"]["freq_hz"], abs=1 / rec.duration_s)
    naming = name_effect(model, rec, seed=3024)
    assert naming.best is not None and naming.best.id == "sinusoidal_interference"


def test_two_shapes_close_beside_a_clearly_worse_third_keep_the_spectrums_order():
    """A close call of shape goes to the exact likelihood only when every named process is in it.
    An independent-generator flicker record (accelerometer, seed 1 of the singles): flicker 732.5
    and Gauss–Markov 730.7 on the Whittle likelihood, the walk 29 below — its band resolves the
    shapes — and the exact likelihood preferred the GM by 3.1: the GM was named. The scorecard's
    gyro hysteresis + K3 + walk (seed 3022 of ``--pairs 11``): walk 1276.3, GM 1272.4, flicker
    1271.0 — flicker outside the tie, the exact likelihood named the GM. Both keep the Whittle
    order now; three shapes within the tie are still the exact likelihood's
    (``test_a_close_call_between_process_shapes_is_the_exact_likelihoods``)."""
    rec, truth, _, _ = hidden_case("accelerometer", ("flicker_noise",), 1, 3000, None, "independent")
    naming = name_effect(calibrate(Model(truth.base), rec), rec, seed=1)
    assert naming.best is not None and naming.best.id == "flicker_noise"
    hidden = ("thermal_hysteresis", "k3_nonlinearity", "rate_random_walk")
    rec, truth, _, _ = hidden_case("gyro", hidden, 3022, 3000)
    naming = name_effect(calibrate(Model(truth.base, truth.effects[:2]), rec), rec, seed=3024)
    assert naming.best is not None and naming.best.id == "rate_random_walk"


def test_a_sine_slower_than_the_fold_blocks_without_a_clip_keeps_the_periodograms_starts():
    """The scorecard's accelerometer triple asymmetry + temperature scale factor + a sine of
    0.0122 Hz (82 s, 74 σ; seed 3015 of ``--pairs 14``): ranking a fold's lines by what they
    explain of blocks of 62.5 s, each less its mean, put lines that fit the asymmetry's structure
    above the sine and nothing was named on the record. Without a clip the periodogram's order
    stands (the ranking is for a fold beside a clip, above): the sine is named first."""
    hidden = ("scale_factor_asymmetry", "temperature_scale_factor", "sinusoidal_interference")
    rec, truth = _scorecard_record("accelerometer", hidden, 3015)
    naming = name_effect(calibrate(Model(truth.base), rec), rec, seed=3015)
    assert naming.best is not None and naming.best.id == "sinusoidal_interference"


def test_the_shape_call_script_reads_the_rules_it_compares():
    """``benchmarks/discovery_shape_calls.py --check``: the exact likelihood decides a close call
    under ``exact-any`` whenever two shapes are in it, under ``exact-all``
    (``naming.shape_ranked``) only when every named shape is; its jobs are the scorecard's
    triples holding a random process."""
    done = subprocess.run([sys.executable, str(BENCHMARKS / "discovery_shape_calls.py"), "--check"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    lines = done.stdout.splitlines()
    assert len(lines) == 4 and all(line.startswith("ok ") for line in lines), done.stdout
