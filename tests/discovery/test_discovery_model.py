"""Record validation, Model prediction/simulation and the TOML model file (issue 7)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.special import ndtr, ndtri

from bench.app.files import read_model, write_model
from bench.discovery.data import Record
from bench.discovery.effects import CATALOGUE
from bench.discovery.effects_base import KINDS
from bench.discovery.effects_transforms import (
    clipped_variance,
    expected_quantized,
    quantized_moments,
    quantized_variance,
)
from bench.discovery.experiments import make_experiment
from bench.discovery.model import BaseModel, Model, base_model, model_from_toml, model_to_toml


def _rec(n=1000, rate=10.0, **cols):
    return Record(t_s=np.arange(n) / rate, y=np.zeros(n), **cols)


# ---- Record ------------------------------------------------------------------------------------

@pytest.mark.parametrize("cols,message", [
    ({"t": [0, 1, 1], "y": [0, 0, 0]}, r"t: not strictly increasing at row 2 \(t=1.0 after 1.0\)"),
    ({"t": [0, 2, 1], "y": [0, 0, 0]}, "t: not strictly increasing"),
    ({"t": [0, 1, 2], "y": [0, 0]}, "y: length 2 differs from t's length 3"),
    ({"t": [0, 1, 2], "y": [0, float("nan"), 0]}, "y: non-finite value nan at row 1"),
    ({"t": [0, float("inf")], "y": [0, 0]}, "t: non-finite value inf"),
    ({"t": [0, 1], "y": [0, 0], "vib": [-1, 0]}, r"vib: value -1.0 at row 0 outside the allowed range \[0.0, 1000.0\]"),
    ({"t": [0, 1], "y": [0, 0], "temp": [25, 900]}, r"temp: value 900.0 at row 1 outside the allowed range"),
    ({"t": [0, 1], "y": [0, 0], "t_on": [-5, 1]}, "t_on: value -5.0"),
    ({"t": [0, 1], "y": [0, 0], "input": [[1, 2], [3, 4]]}, r"input: shape \(2, 2\)"),
    ({"t": [0, 1], "y": [0, 0], "input": ["a", "b"]}, "input: not numeric"),
    ({"t": [0, 1], "y": [0, 0], "speed": [1, 2]}, "unknown column 'speed'"),
    ({"t": [0, 1]}, "missing required column 'y'"),
    ({"t": [0], "y": [0]}, "at least 2"),
])
def test_record_rejects_bad_columns_naming_column_value_and_range(cols, message):
    with pytest.raises(ValueError, match=message):
        Record.from_columns(cols)


def test_record_columns_fallbacks_and_slices():
    rec = Record.from_columns({" T ": [10.0, 11.0, 12.0, 13.0], "y": [1, 2, 3, 4], "temp": [20, 21, 22, 23],
                               "accel": [0, 1, 0, -1], "cross_input": [0, 0, 1, 1]})
    np.testing.assert_array_equal(rec.column("t_on"), [0, 1, 2, 3])  # starts at power-on by default
    assert rec.has("t_on") and not rec.logged("t_on") and rec.has("accel") and not rec.has("vib")
    with pytest.raises(ValueError, match="column 'vib' was not logged in this record; logged: "):
        rec.column("vib")
    with pytest.raises(ValueError, match="unknown column name 'wind'"):
        rec.has("wind")
    part = rec.slice(slice(2, 4))
    np.testing.assert_array_equal(part.column("t_on"), [2, 3])  # time since power-on survives the slice
    np.testing.assert_array_equal(rec.slice(np.array([0, 3])).y, [1, 4])
    assert set(rec.to_columns()) == {"t", "y", "temp", "accel", "cross_input"}
    assert Record.from_columns(rec.to_columns()).temp_c.tolist() == [20, 21, 22, 23]
    assert rec.replace(y=np.zeros(4)).y.sum() == 0 and rec.rate_hz == pytest.approx(1.0)
    with pytest.raises(ValueError):
        rec.y[0] = 5.0  # columns are read-only


# ---- Model ---------------------------------------------------------------------------------------

def test_base_model_validates_and_predicts_bias_plus_scale_factor():
    assert base_model("gyro") == BaseModel("gyro", 0.0, 1.0, 3e-3)
    with pytest.raises(ValueError, match=r"base.kind = 'sonar'; allowed: \['accelerometer', 'gyro', 'mhd'\]"):
        BaseModel("sonar")
    with pytest.raises(ValueError, match=r"base.scale_factor = 7.0 outside the allowed range \[0.5, 2.0\]"):
        BaseModel("gyro", scale_factor=7.0)
    u = np.linspace(-1, 1, 100)
    rec = _rec(100, input=u)
    m = Model(BaseModel("accelerometer", bias=2e-3, scale_factor=1.01, noise_sd=0.0))
    np.testing.assert_allclose(m.predict(rec), 2e-3 + 1.01 * u)
    np.testing.assert_allclose(m.predict(_rec(100)), 2e-3)  # no input logged: input 0


def test_model_rejects_effects_outside_the_kind():
    m = Model(base_model("accelerometer"))
    with pytest.raises(ValueError, match="'g_sensitivity' does not apply to a accelerometer"):
        m.with_effect("g_sensitivity", {"coef_per_g": 1e-4})
    with pytest.raises(ValueError,
                       match=r"k2_nonlinearity.k2_per_u = 0.5 outside the allowed range \[-0.001, 0.001\] 1/g"):
        m.with_effect("k2_nonlinearity", {"k2_per_u": 0.5})
    with pytest.raises(ValueError, match=r"unknown parameter\(s\) \['k9'\]"):
        m.with_effect("k2_nonlinearity", {"k2_per_u": 1e-5, "k9": 1.0})
    with pytest.raises(ValueError, match=r"missing parameter\(s\) \['tau_s'\]"):
        m.with_effect("warmup_exponential", {"amplitude": 1e-5})


def test_predict_composes_stages_input_then_additive_then_output():
    rng = np.random.default_rng(1)
    u = np.repeat(rng.uniform(-1, 1, 50), 20)
    rec = _rec(1000, input=u, temp_c=25 + np.linspace(0, 5, 1000))
    m = (Model(BaseModel("accelerometer", bias=1e-3, scale_factor=2.0, noise_sd=1e-5))
         .with_effect("lowpass_bandwidth", {"bandwidth_hz": 0.5})
         .with_effect("temperature_bias", {"coef_per_c": 1e-5, "coef_per_c2": 0.0})
         .with_effect("quantization", {"step": 1e-4}))
    lp = CATALOGUE["lowpass_bandwidth"].transform_input({"bandwidth_hz": 0.5}, rec, u)
    expect = 1e-3 + 2.0 * lp + 1e-5 * (rec.temp_c - 25.0)  # the bias is not low-passed; SF scales the filtered input
    # readings are Q(signal + noise): predict is their mean, the dithered quantizer
    np.testing.assert_allclose(m.predict(rec), expected_quantized(expect, 1e-4, 1e-5), rtol=1e-12)
    noiseless = Model(replace(m.base, noise_sd=0.0), m.effects)
    np.testing.assert_allclose(noiseless.predict(rec), 1e-4 * np.round(expect / 1e-4))


def test_simulate_is_deterministic_and_streams_are_independent():
    rec = make_experiment("gyro", np.random.default_rng(0), n=3000)
    m = Model(base_model("gyro")).with_effect("gauss_markov", {"sigma": 1e-3, "tau_s": 20.0})
    a, b = m.simulate(rec, 7), m.simulate(rec, np.random.default_rng(7))
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(a, m.simulate(rec, 7))
    assert not np.array_equal(a, m.simulate(rec, 8))
    # adding a deterministic effect changes the prediction, not the noise realisation
    m2 = m.with_effect("k2_nonlinearity", {"k2_per_u": 1e-6})
    np.testing.assert_allclose(m2.simulate(rec, 7) - m2.predict(rec), a - m.predict(rec), atol=1e-12)
    white = Model(base_model("gyro")).simulate(rec, 3) - rec.input
    assert np.std(white) == pytest.approx(3e-3, rel=0.05)
    with pytest.raises(ValueError, match="rng = 'x'"):
        m.simulate(rec, "x")


def test_simulated_quantization_acts_on_the_noisy_output():
    rec = _rec(2000, input=np.zeros(2000))
    m = Model(BaseModel("gyro", noise_sd=0.01)).with_effect("quantization", {"step": 0.004})
    y = m.simulate(rec, 1)
    np.testing.assert_allclose(y / 0.004, np.round(y / 0.004), atol=1e-9)
    assert len(np.unique(np.round(y / 0.004))) > 5  # the noise spreads over several steps


@settings(max_examples=15, deadline=None, derandomize=True)
@given(tau=st.floats(0.02, 1.5), x=st.floats(-3.0, 3.0), wander=st.sampled_from([0.0, 0.1, 0.4]))
def test_quantized_variance_matches_the_spread_of_simulated_readings(tau, x, wander):
    # Var[Q(x + φ + n) | φ] averaged over a slow offset φ ~ N(0, w²), by Monte Carlo
    rng = np.random.default_rng(3)
    phi = wander * ndtri((np.arange(1000) + 0.5) / 1000) if wander else np.zeros(1)  # stratified
    draws = [np.round(x + f + tau * rng.standard_normal(4000)) for f in phi]
    mc = np.mean([np.var(d) for d in draws])
    mc4 = np.mean([np.mean((d - d.mean()) ** 4) for d in draws])
    got, got4 = (float(m[0]) for m in quantized_moments(np.array([x]), 1.0, tau, wander))
    assert got == pytest.approx(mc, rel=0.08, abs=2e-3)
    assert got == pytest.approx(float(quantized_variance(np.array([x]), 1.0, tau, wander)[0]))
    assert got4 == pytest.approx(mc4, rel=0.15, abs=2e-3)


def test_quantized_variance_averages_to_the_phase_averaged_level_and_flattens_with_dither():
    q = CATALOGUE["quantization"]
    u = (np.arange(4096) + 0.5) / 4096 * 2e-3  # uniform phases over two steps of 1e-3
    for sd in (5e-5, 2e-4, 6e-4):
        v = quantized_variance(u, 1e-3, sd)
        assert np.mean(v) == pytest.approx(q.residual_var({"step": 1e-3}, sd), rel=1e-3)
        assert np.mean(quantized_variance(u, 1e-3, sd, 3e-4)) == pytest.approx(np.mean(v), rel=1e-3)
    coarse = quantized_variance(u, 1e-3, 5e-5)
    assert coarse.min() < 1e-3 * coarse.max()  # on a level nothing flips, between two levels half
    assert coarse.max() == pytest.approx(0.25e-6, rel=1e-3)
    np.testing.assert_allclose(quantized_variance(u, 1e-3, 1.2e-3), q.residual_var({"step": 1e-3}, 1.2e-3))
    with pytest.raises(ValueError, match="wander_sd = -1"):
        quantized_variance(u, 1e-3, 1e-4, -1)


def test_clipped_variance_matches_simulated_clipping():
    rng = np.random.default_rng(4)
    x = np.array([-3.0, -1.05, 0.0, 0.95, 1.0, 1.2, 4.0])
    mc = [np.var(np.clip(v + 0.1 * rng.standard_normal(200_000), -1.0, 1.0)) for v in x]
    np.testing.assert_allclose(clipped_variance(x, 1.0, 0.1), mc, rtol=0.02, atol=1e-6)


def test_residual_profile_follows_the_quantizer_lattice_and_is_flat_without_one():
    rec = _rec(2000, input=np.linspace(-1e-2, 1e-2, 2000))
    plain = Model(BaseModel("gyro", noise_sd=1e-4))
    v0, m40 = plain.residual_profile(rec)
    np.testing.assert_array_equal(v0, np.full(2000, 1e-8))
    np.testing.assert_allclose(m40, 3e-16)
    m = plain.with_effect("quantization", {"step": 1e-3})
    prof, m4 = m.residual_profile(rec)
    assert np.mean(prof) == pytest.approx(m.residual_sd() ** 2, rel=0.02)
    assert prof.max() > 20 * prof.min()  # readings on a level barely move
    # the profile is the readings' own spread: realisations around the prediction
    sims = np.array([m.simulate(rec, s) for s in range(300)]) - m.predict(rec)
    np.testing.assert_allclose(np.var(sims, axis=0).reshape(20, 100).mean(axis=1),
                               prof.reshape(20, 100).mean(axis=1), rtol=0.15)
    central = sims - sims.mean(axis=0)
    np.testing.assert_allclose(np.mean(central ** 4, axis=0).reshape(20, 100).mean(axis=1),
                               m4.reshape(20, 100).mean(axis=1), rtol=0.3)
    # a clipping: quiet where the signal is beyond the limit
    sat = Model(BaseModel("gyro", noise_sd=1e-4)).with_effect("saturation", {"limit": 1.0})
    rec2 = _rec(1000, input=np.r_[np.zeros(500), np.full(500, 5.0)])
    prof2 = sat.residual_profile(rec2)[0]
    assert prof2[:500] == pytest.approx(1e-8) and np.all(prof2[500:] < 1e-12)


@settings(max_examples=20, deadline=None)
@given(shift=st.floats(-5e-3, 5e-3), seed=st.integers(0, 2 ** 16))
def test_a_profile_moved_by_an_offset_is_the_profile_of_the_moved_signal(shift, seed):
    """``residual_profile(offset=…)``: the signal before the output stage moved sample by sample
    (where a random process took it) — a constant offset is a bias, and a varying one moves each
    sample on the lattice: the profile of an offset path is the moved model's sample by sample."""
    rng = np.random.default_rng(seed)
    rec = _rec(400, input=np.linspace(-1e-2, 1e-2, 400))
    m = Model(BaseModel("gyro", noise_sd=1e-4)).with_effect("quantization", {"step": 1e-3})
    moved = m.with_base(bias=m.base.bias + shift)
    for got, want in zip(m.residual_profile(rec, offset=np.full(400, shift)), moved.residual_profile(rec)):
        np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-30)
    path = rng.normal(0.0, 2e-3, 400)
    v, _ = m.residual_profile(rec, offset=path)
    for i in rng.integers(0, 400, 5):
        at = m.with_base(bias=m.base.bias + path[i]).residual_profile(rec)[0][i]
        assert v[i] == pytest.approx(at, rel=1e-9, abs=1e-30)


@settings(max_examples=5, deadline=None)
@given(step_sd=st.floats(1.0, 17.0), slope=st.floats(5e-9, 5e-8), seed=st.integers(0, 2 ** 16))
def test_predict_of_a_quantized_record_is_its_mean_reading(step_sd, slope, seed):
    # the audit's case (/tmp/audit7/quant_predict.py): with predict = Q(signal) the residual's
    # 200-sample moving mean was 0.82 sd; the mean over many realisations of the readings must
    # equal predict at every sample (within its sampling error, below), with no staircase left
    sd, n, reps = 5e-6, 1500, 300
    t = np.arange(n) * 0.5
    rec = Record(t_s=t, y=np.zeros(n), t_on_s=t)
    m = (Model(BaseModel("accelerometer", 1e-3, 1.0, sd)).with_effect("linear_drift", {"slope_per_s": slope})
         .with_effect("quantization", {"step": step_sd * sd}))
    rng = np.random.default_rng(seed)
    ys = np.array([m.simulate(rec, rng) for _ in range(reps)])
    bias = ys.mean(axis=0) - m.predict(rec)
    # the standard error from the reading's exact distribution (the levels within 9 σ): a
    # sample sd of 300 coarse readings with a handful of flips understates it; and where flips
    # are rare (≲ 1 expected) their count is Poisson, not normal — 6 flips where 0.74 were
    # expected (p ≈ 2e-4, one of 1500 samples) is 6 σ — so 8 extra flips are allowed on top
    step = step_sd * sd
    x = 1e-3 + slope * t  # the signal before the quantizer: bias + drift
    k = int(math.ceil(9 / step_sd)) + 2
    levels = step * (np.round(x / step)[:, None] + np.arange(-k, k + 1)[None, :])
    p = ndtr((levels + step / 2 - x[:, None]) / sd) - ndtr((levels - step / 2 - x[:, None]) / sd)
    mean = np.sum(p * levels, axis=1)
    se = np.sqrt(np.maximum(np.sum(p * levels ** 2, axis=1) - mean ** 2, 0.0) / reps)
    np.testing.assert_allclose(mean, m.predict(rec), rtol=0, atol=1e-9 * step)  # the same mean reading
    assert np.all(np.abs(bias) <= 5.5 * se + 8 * step / reps)


@pytest.mark.parametrize("tau", [0.05, 0.2, 0.5, 2.0])
def test_noise_floor_with_quantization_gives_the_noise_before_the_quantizer(tau):
    # the residual floor a calibration measures holds the rounding error; the model needs σ
    step, n = 2e-5, 40000
    t = np.arange(n, dtype=float)
    rec = Record(t_s=t, y=np.zeros(n), t_on_s=t)
    m = (Model(BaseModel("accelerometer", 1e-3, 1.0, tau * step)).with_effect("linear_drift", {"slope_per_s": 3e-9})
         .with_effect("quantization", {"step": step}))
    floor = float(np.std(m.simulate(rec, 4) - m.predict(rec)))
    back = m.with_base(noise_sd=1e-6).with_noise_floor(floor)
    assert back.base.noise_sd == pytest.approx(tau * step, rel=0.05)
    assert back.residual_sd() == pytest.approx(floor, rel=1e-9)  # the floor the model expects
    assert m.residual_sd() == pytest.approx(floor, rel=0.03)
    assert Model(base_model("gyro")).with_noise_floor(0.01).base.noise_sd == 0.01
    with pytest.raises(ValueError, match="floor_sd = nan"):
        m.with_noise_floor(float("nan"))


def test_effects_listed_twice_are_refused_naming_the_id():
    m = Model(base_model("gyro")).with_effect("linear_drift", {"slope_per_s": 1e-6})
    with pytest.raises(ValueError, match=r"effects\[1\]: effect 'linear_drift' is listed twice \(also effects\[0\]\)"):
        m.with_effect("linear_drift", {"slope_per_s": 2e-6})



# ---- an effect's snr inside its model ------------------------------------------------------------

def _gls_snr(delta, a, cov):
    """sqrt(δᵀΣ⁻¹δ − the part the columns a absorb), by Cholesky of Σ: code apart from the Kalman
    filter ``Model.effect_snr`` whitens with."""
    lw = np.linalg.cholesky(cov)
    d = np.linalg.solve(lw, delta)
    w = np.linalg.solve(lw, a)
    coef, *_ = np.linalg.lstsq(w, d, rcond=None)
    return float(np.linalg.norm(d - w @ coef))


def test_effect_snr_alone_is_the_effects_own_snr_and_a_process_is_judged_behind_the_quantizer():
    rec = make_experiment("gyro", np.random.default_rng(2), n=1500)
    m = Model(base_model("gyro")).with_effect("linear_drift", {"slope_per_s": 2e-7})
    assert m.effect_snr(rec, 0) == pytest.approx(CATALOGUE["linear_drift"].snr({"slope_per_s": 2e-7}, rec, 3e-3),
                                                 rel=1e-9)
    gm = {"sigma": 1e-3, "tau_s": 20.0}
    with_gm = m.with_effect("gauss_markov", gm)
    assert with_gm.effect_snr(rec, 1) == pytest.approx(CATALOGUE["gauss_markov"].snr(gm, rec, 3e-3), rel=1e-12)
    m = with_gm.with_effect("quantization", {"step": 2e-2})  # steps of 6.7 noise sd
    behind = m.effect_snr(rec, 1)
    assert behind == pytest.approx(CATALOGUE["gauss_markov"].snr(gm, rec, m.residual_sd()), rel=1e-6)
    assert behind < 0.5 * with_gm.effect_snr(rec, 1)
    assert math.isnan(m.effect_snr(rec, 2))
    with pytest.raises(ValueError, match="effect index 3; allowed: 0..2"):
        m.effect_snr(rec, 3)


@settings(max_examples=12, deadline=None)
@given(sigma=st.floats(1e-4, 3e-2), tau=st.floats(2.0, 200.0), amp=st.floats(1e-4, 1e-2),
       freq=st.floats(0.002, 1.0))
def test_effect_snr_is_the_generalised_least_squares_snr_and_a_process_only_hides(sigma, tau, amp, freq):
    """Against a Gauss–Markov process the Kalman-whitened snr equals the GLS snr computed from the
    process's covariance matrix (Cholesky; the base regressors out), and never exceeds the snr
    against white noise alone (Σ ≥ σ²I)."""
    n, rate, sd = 300, 10.0, 3e-3
    t = np.arange(n) / rate
    rec = Record(t_s=t, y=np.zeros(n), input=np.repeat([0.0, 50.0, -50.0], n // 3))
    sine = {"amplitude": amp, "freq_hz": freq, "phase_rad": 0.3}
    alone = Model(BaseModel("gyro", noise_sd=sd)).with_effect("sinusoidal_interference", sine)
    mixed = alone.with_effect("gauss_markov", {"sigma": sigma, "tau_s": tau})
    delta = alone.predict(rec) - Model(alone.base).predict(rec)
    lag = np.abs(t[:, None] - t[None, :])
    cov = sd ** 2 * np.eye(n) + sigma ** 2 * np.exp(-lag / tau)
    a = np.column_stack([np.ones(n), rec.input])
    got = mixed.effect_snr(rec, 0)
    assert got == pytest.approx(_gls_snr(delta, a, cov), rel=1e-6)
    assert got <= alone.effect_snr(rec, 0) * (1 + 1e-9)


def test_effect_snr_takes_out_what_the_other_effects_can_absorb():
    """A drift beside a warm-up whose time constant is longer than the record: the warm-up's slope
    there is the drift's, and the drift keeps a small part of its white-noise snr; beside a sine
    it keeps nearly all of it. A temperature bias beside a strong random walk (the scorecard's
    gyro triple 3014 as first drawn, 19σ against white noise) holds a few σ at most."""
    rec = make_experiment("gyro", np.random.default_rng(5), n=3000)
    drift = Model(base_model("gyro")).with_effect("linear_drift", {"slope_per_s": 2e-6})
    alone = drift.effect_snr(rec, 0)
    beside_slow = drift.with_effect("warmup_exponential", {"amplitude": 0.01, "tau_s": 5 * rec.duration_s})
    beside_sine = drift.with_effect("sinusoidal_interference", {"amplitude": 0.01, "freq_hz": 0.2, "phase_rad": 0.0})
    assert beside_slow.effect_snr(rec, 0) < 0.1 * alone
    assert beside_sine.effect_snr(rec, 0) > 0.95 * alone
    tb = Model(base_model("gyro")).with_effect("temperature_bias", {"coef_per_c": 4e-4, "coef_per_c2": 0.0})
    walk = tb.with_effect("rate_random_walk", {"k_per_rs": 4e-4})
    assert tb.effect_snr(rec, 0) > 15 and walk.effect_snr(rec, 0) < 0.3 * tb.effect_snr(rec, 0)

# ---- model file ------------------------------------------------------------------------------

@st.composite
def models(draw):
    kind = draw(st.sampled_from(KINDS))
    lo_b, hi_b = {"accelerometer": (-0.05, 0.05), "gyro": (-1.0, 1.0), "mhd": (-100.0, 100.0)}[kind]
    base = BaseModel(kind, draw(st.floats(lo_b, hi_b)), draw(st.floats(0.5, 2.0)), draw(st.floats(0.0, 0.1)))
    effects = []
    for e in draw(st.lists(st.sampled_from(CATALOGUE.for_kind(kind)), max_size=5, unique_by=lambda e: e.id)):
        effects.append((e.id, {q.name: draw(st.floats(q.low, q.high)) for q in e.params_for(kind)}))
    rate = draw(st.one_of(st.none(), st.floats(1e-3, 1e6)))
    return Model(replace(base, rate_hz=rate), tuple(effects))


@settings(max_examples=60)
@given(model=models())
def test_model_file_round_trips_exactly(model):
    text = model_to_toml(model)
    back = model_from_toml(text)
    assert back == model
    for (_, p), (_, q) in zip(back.effects, model.effects):  # bit for bit, signs of zero included
        assert all(math.copysign(1, p[k]) == math.copysign(1, q[k]) for k in p)


def test_model_file_on_disk(tmp_path):
    m = (Model(base_model("accelerometer")).with_effect("warmup_exponential", {"amplitude": 6e-5, "tau_s": 180.0})
         .with_effect("sinusoidal_interference", {"amplitude": 1e-6, "freq_hz": 0.05, "phase_rad": -1.0}))
    write_model(m, tmp_path / "unit.toml")
    assert read_model(tmp_path / "unit.toml") == m
    with pytest.raises(ValueError, match="cannot read model file"):
        read_model(tmp_path / "missing.toml")


def test_model_file_records_the_rate_its_noise_sd_is_per_sample_at(tmp_path):
    m = Model(base_model("gyro"))  # 3e-3 deg/s per sample
    write_model(m, tmp_path / "g.toml", rate_hz=10.0)
    assert "rate_hz = 10.0" in (tmp_path / "g.toml").read_text()
    back = read_model(tmp_path / "g.toml")
    assert back.base.rate_hz == 10.0 and back.base.noise_sd == 3e-3
    # the same unit read at 40 Hz: the density is kept, the per-sample sd doubles
    assert read_model(tmp_path / "g.toml", rate_hz=40.0).base.noise_sd == pytest.approx(6e-3, rel=1e-12)
    # files written before the rate was recorded still read, with no rate
    assert model_from_toml(_GOOD_BASE).base.rate_hz is None
    assert model_from_toml(_GOOD_BASE).at_rate(40.0).base.noise_sd == 0.003
    with pytest.raises(ValueError, match=r"base.rate_hz = -1.0 outside the allowed range"):
        model_from_toml(_GOOD_BASE + "rate_hz = -1.0\n")


_GOOD_BASE = '[base]\nkind = "gyro"\nbias = 0.0\nscale_factor = 1.0\nnoise_sd = 0.003\n'


@pytest.mark.parametrize("text,message", [
    ("[base\nkind=1", "not valid TOML"),
    ('[base]\nkind = "gyro"\n', r"\[base\] keys \['kind'\]; required: .*optional: \['rate_hz'\]"),
    (_GOOD_BASE + "rate = 1.0\n", r"\[base\] keys .*'rate'"),
    (_GOOD_BASE + ('[[effects]]\nid = "linear_drift"\n[effects.params]\nslope_per_s = 1e-9\n') * 2,
     r"effects\[1\]: effect 'linear_drift' is listed twice"),
    (_GOOD_BASE + '[[effects]]\nid = "warmup_exponential"\n[effects.params]\namplitude = 1e-5\n',
     r"effect 'warmup_exponential': missing parameter\(s\) \['tau_s'\]"),
    (_GOOD_BASE + '[[effects]]\nid = "linear_drift"\n[effects.params]\nslope_per_s = 1e-9\nk = 1.0\n',
     r"effect 'linear_drift': unknown parameter\(s\) \['k'\]"),
    (_GOOD_BASE.replace("0.003", "-1.0"), r"base.noise_sd = -1.0 outside the allowed range \[0.0, 10.0\]"),
    (_GOOD_BASE + "[extra]\na = 1\n", r"unknown top-level key\(s\) \['extra'\]"),
    (_GOOD_BASE + '[[effects]]\nid = "warp_drive"\n[effects.params]\n', "unknown effect id 'warp_drive'"),
    (_GOOD_BASE + '[[effects]]\nid = "highpass_rolloff"\n[effects.params]\ncorner_hz = 1.0\n',
     "'highpass_rolloff' does not apply to a gyro"),
    (_GOOD_BASE + '[[effects]]\nid = "time_delay"\n[effects.params]\ndelay_s = 5.0\n',
     r"time_delay.delay_s = 5.0 outside the allowed range \[1e-05, 1.0\] s"),
    (_GOOD_BASE + '[[effects]]\nid = "time_delay"\n[effects.params]\ndelay_s = "soon"\n',
     r"effects\[0\].params.delay_s = 'soon' is not a number"),
    (_GOOD_BASE + '[[effects]]\nid = "time_delay"\nhow = 1\n', r"effects\[0\] = .* allowed keys: id"),
])
def test_bad_model_files_name_the_key_value_and_range(text, message):
    with pytest.raises(ValueError, match=message):
        model_from_toml(text)


@settings(max_examples=20, deadline=None)
@given(limit=st.floats(0.3, 1.2), step=st.floats(1e-6, 1e-3), seed=st.integers(0, 2 ** 16))
def test_noise_seen_is_false_exactly_where_a_saturation_clips_the_mean_signal(limit, step, seed):
    """``Model.noise_seen``: a reading carries the noise where the mean signal before the output
    stage lies inside the clip; a quantizer behind it (whose flips carry the noise) removes
    nothing, nor does one alone."""
    rng = np.random.default_rng(seed)
    rec = _rec(400, input=np.repeat(rng.uniform(-1.0, 1.0, 20), 20))
    base = Model(base_model("accelerometer"))
    clipped = base.with_effect("saturation", {"limit": limit})
    signal = base.predict(rec)
    assert np.array_equal(clipped.noise_seen(rec), np.abs(signal) < limit)
    assert np.array_equal(clipped.with_effect("quantization", {"step": step}).noise_seen(rec), np.abs(signal) < limit)
    assert base.with_effect("quantization", {"step": step}).noise_seen(rec).all()
    assert base.noise_seen(rec).all()
