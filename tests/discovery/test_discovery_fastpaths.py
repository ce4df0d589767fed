"""The fast lattice visibility, held-out scorer, block bootstrap and model-noise realisations
equal the straightforward implementations they replaced to floating-point noise — the noise
draws to the bit, for a fixed seed. The references are kept here, but for those the benchmark
times too (``bench.testing.references.discovery``)."""

import math
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.discovery import lattice as lat
from bench.discovery import significance as sig
from bench.discovery.data import Record
from bench.discovery.effects import CATALOGUE
from bench.discovery.experiments import make_experiment
from bench.discovery.fitting import CandidateFitter
from bench.discovery.localize import autocorrelation
from bench.discovery.model import Model, base_model
from bench.discovery.whiten import state_space
from bench.testing.references.discovery import (
    LinearScorerReference,
    block_bootstrap_reference,
    visibility_reference,
)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2 ** 31), step_sd=st.sampled_from([0.0, 0.3, 1.0, 2.5, 4.0]),
       n=st.sampled_from([40, 2000, 30000]), offset=st.floats(-50, 50))
def test_visibility_equals_reference(seed, step_sd, n, offset):
    rng = np.random.default_rng(seed)
    y = offset + rng.standard_normal(n)
    if step_sd:
        y = np.round(y / step_sd) * step_sd
    grid = np.geomspace(0.25, 4.2, 60)
    assert np.allclose(lat.visibility(y, grid), visibility_reference(y, grid), rtol=0, atol=1e-11)
    cf = lat.CharFun(y, 2 * np.pi / 0.2)
    assert np.allclose(lat.visibility(y, grid, cf=cf), visibility_reference(y, grid), rtol=0, atol=1e-11)


def test_charfun_refuses_frequencies_beyond_its_bins():
    cf = lat.CharFun(np.random.default_rng(0).standard_normal(5000), 10.0)
    try:
        cf(np.array([11.0]))
    except ValueError as e:
        assert "omega" in str(e)
    else:
        raise AssertionError("no ValueError")


def test_fit_lattice_finds_step_of_quantized_record():
    rng = np.random.default_rng(4)
    sd, step = 1.0, 1.7
    y = np.round((3.0 + sd * rng.standard_normal(20000)) / step) * step
    fit = lat.fit_lattice(y, sd, 0.01, 10.0)
    assert abs(fit.step - step) < 1e-3 * step and fit.p_value < 1e-6


def _scorer_case(seed, n, n_cand, with_input):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.1
    folds = sig.block_folds(n)
    cols = [np.ones(n)] + ([np.sin(t / 7.0) + 0.1 * rng.standard_normal(n)] if with_input else [])
    x_nuis = np.column_stack(cols)
    x_cand = [np.column_stack([np.exp(-t / (20 + k)) * t ** j for j in range(n_cand)]) for k in (0, 1)]
    r = 0.3 * x_cand[0][:, 0] + rng.standard_normal(n)
    return r, x_nuis, x_cand, folds


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2 ** 31), n=st.sampled_from([200, 3001, 20000]), n_cand=st.integers(1, 3),
       with_input=st.booleans())
def test_linear_scorer_equals_reference(seed, n, n_cand, with_input):
    r, x_nuis, x_cand, folds = _scorer_case(seed, n, n_cand, with_input)
    reps = sig.block_bootstrap(r, sig.default_block_len(n), 30, np.random.default_rng(seed))
    fast = sig.LinearScorer(x_nuis, x_cand, folds)
    ref = LinearScorerReference(x_nuis, x_cand, folds)
    # the expansion ‖r‖² − 2βᵀXᵀr + βᵀGβ cancels to ~ε·cond(X)² of ‖r_te‖²: with these columns
    # (cond ≈ 10³ at n = 200) a score is off by up to 2.7e-11 (1 500 seeds × 3 shapes; seed 712,
    # three candidate columns, was 1.2e-11 beyond atol 1e-11) — nothing a p-value could see
    assert np.allclose(fast.scores(reps), ref.scores(reps), rtol=1e-9, atol=1e-10)
    assert np.allclose(fast.scores(r), ref.scores(r), rtol=1e-9, atol=1e-10)


def test_linear_scorer_exact_fit_uses_direct_error():
    # a residual the candidate explains entirely: the expansion would be all cancellation
    r, x_nuis, x_cand, folds = _scorer_case(1, 3000, 2, False)
    exact = x_cand[0][:, 0] * 1e3 + 1e-9 * np.random.default_rng(2).standard_normal(r.size)
    both = np.column_stack([exact, r])
    fast = sig.LinearScorer(x_nuis, x_cand, folds).scores(both)
    ref = LinearScorerReference(x_nuis, x_cand, folds).scores(both)
    assert np.allclose(fast, ref, rtol=1e-9, atol=1e-12)


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2 ** 31), n=st.integers(1, 500), block_len=st.integers(1, 600),
       n_rep=st.integers(1, 7))
def test_block_bootstrap_equals_reference(seed, n, block_len, n_rep):
    r = np.random.default_rng(seed).standard_normal(n)
    a = sig.block_bootstrap(r, block_len, n_rep, np.random.default_rng(seed))
    b = block_bootstrap_reference(r, block_len, n_rep, np.random.default_rng(seed))
    assert a.shape == (n, n_rep) and np.array_equal(a, b)


def acf_reference(x, max_lag):
    """The original: FFT of length exactly 2n (slow when 2n has a large prime factor)."""
    x = x - x.mean()
    spec = np.fft.rfft(x, 2 * x.size)
    c = np.fft.irfft(spec * np.conj(spec))[:max_lag + 1]
    return c / c[0] if c[0] > 0 else np.zeros(max_lag + 1)


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2 ** 31), n=st.integers(2, 5000), frac=st.floats(0.0, 1.0))
def test_acf_equals_reference(seed, n, frac):
    x = np.cumsum(np.random.default_rng(seed).standard_normal(n))
    lag = int(frac * (n - 1))
    assert np.allclose(autocorrelation(x, lag), acf_reference(x, lag), rtol=0, atol=1e-12)


def gauss_markov_reference(dt, w, sigma, tau):
    """The original: φ = exp(−dt/τ) and its gain recomputed at every sample."""
    x = np.empty(w.size)
    x[0] = sigma * w[0]
    for k in range(1, w.size):
        phi = math.exp(-dt[k - 1] / tau)
        x[k] = phi * x[k - 1] + sigma * math.sqrt(1.0 - phi * phi) * w[k]
    return x


def flicker_reference(p, rec, rng):
    """The original: one state after the other, each its own draw and recursion, summed."""
    taus, s = CATALOGUE["flicker_noise"]._terms(p, rec.dt_s, rec.n)
    out = np.zeros(rec.n)
    for tau in taus:
        out += gauss_markov_reference(np.diff(rec.t_s), rng.standard_normal(rec.n), s, float(tau))
    return out


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2 ** 31), n=st.integers(2, 3000), jitter=st.sampled_from([0.0, 1e-6, 0.3]),
       tau_min=st.floats(0.01, 30.0))
def test_flicker_and_gauss_markov_equal_the_per_sample_recursion(seed, n, jitter, tau_min):
    # uniform (intervals repeat: φ reused), nearly uniform (ulps apart) and irregular time stamps
    dt = 0.1 * (1 + jitter * np.random.default_rng(seed + 1).uniform(0, 1, n - 1))
    rec = Record(t_s=np.concatenate([[0.0], np.cumsum(dt)]), y=np.zeros(n))
    flicker, gm = CATALOGUE["flicker_noise"], CATALOGUE["gauss_markov"]
    p = {"b": 1e-5, "tau_min_s": tau_min}
    fast = flicker.noise(p, rec, np.random.default_rng(seed))
    assert np.allclose(fast, flicker_reference(p, rec, np.random.default_rng(seed)), rtol=1e-12, atol=0)
    q = {"sigma": 2e-6, "tau_s": tau_min}
    ref = gauss_markov_reference(np.diff(rec.t_s), np.random.default_rng(seed).standard_normal(n), 2e-6, tau_min)
    assert np.allclose(gm.noise(q, rec, np.random.default_rng(seed)), ref, rtol=1e-12, atol=0)


@pytest.mark.parametrize("effects", [
    (("flicker_noise", {"b": 3e-6, "tau_min_s": 0.05}), ("gauss_markov", {"sigma": 4e-6, "tau_s": 20.0})),
    (("rate_random_walk", {"k_per_rs": 1e-7}),),
    (("gauss_markov", {"sigma": 4e-6, "tau_s": 2.0}), ("quantization", {"step": 2e-5})),  # an output stage
])
def test_simulate_noise_many_is_the_successive_draws(effects):
    rec = make_experiment("accelerometer", np.random.default_rng(0), n=2000)
    model = Model(base_model("accelerometer"))
    for eid, p in effects:
        model = model.with_effect(eid, p)
    rng = np.random.default_rng(11)
    ref = np.column_stack([model.simulate_noise(rec, rng) for _ in range(5)])
    after = rng.integers(0, 2 ** 63)
    rng = np.random.default_rng(11)
    many = model.simulate_noise_many(rec, rng, 5)
    assert many.shape == (rec.n, 5) and np.array_equal(many, ref)
    assert many.T.flags.c_contiguous  # each realisation contiguous: the scorer reads rows
    assert rng.integers(0, 2 ** 63) == after  # the caller's generator moved on exactly as before
    assert model.simulate_noise_many(rec, 3, 0).shape == (rec.n, 0)
    with pytest.raises(ValueError, match="m = -1"):
        model.simulate_noise_many(rec, 3, -1)
    # filled side by side by threads (each realisation from its own pre-drawn root): the same numbers
    with ThreadPoolExecutor(max_workers=3) as pool:
        threaded = model.simulate_noise_many(rec, np.random.default_rng(11), 5, fill_map=pool.map)
    assert np.array_equal(threaded, ref)


@pytest.mark.parametrize("eid,p", [
    ("warmup_exponential", {"amplitude": 7e-5, "tau_s": 120.0}),
    ("thermal_two_node", {"amplitude": 8e-5, "fraction_slow": 0.7, "tau_fast_s": 18.0, "tau_slow_s": 160.0}),
    ("sinusoidal_interference", {"amplitude": 3e-6, "freq_hz": 0.37, "phase_rad": 1.1}),
])
@pytest.mark.parametrize("kind", ["accelerometer", "gyro"])
def test_analytic_jacobian_equals_the_differenced_prediction(eid, p, kind):
    rec = make_experiment(kind, np.random.default_rng(3), n=4000)
    model = Model(base_model(kind))
    f = CandidateFitter(model, rec, CATALOGUE[eid], template=p)
    assert f._analytic
    x = f.pack(p, 1e-3, float(model.base.scale_factor))
    ana = f.analytic_jacobian(x)
    # the prediction is linear in bias and scale factor: their columns are 1 and the input
    assert np.all(ana[:, 0] == 1.0) and (not f.with_sf or np.array_equal(ana[:, 1], model.stages(rec)[0]))
    # the effect's coordinates: central differences of its term through the fitter's own
    # coordinates (log ones included), steps of 1e-6 of their scales — the straightforward Jacobian,
    # to its rounding (a sinusoid's phase of thousands of radians leaves ~1e-5 of the column)

    def term(xx):
        return f.effect.term(f.unpack(xx)[0], rec)

    h = 1e-6 * f.x_scale() * np.eye(x.size)
    num = np.column_stack([(term(x + h[j]) - term(x - h[j])) / (2 * h[j, j]) for j in range(f.n_base, x.size)])
    assert np.all(np.abs(ana[:, f.n_base:] - num) <= 1e-3 * np.max(np.abs(num), axis=0))
    # an output-stage effect (saturation) has no term: its fit differences the prediction
    assert not CandidateFitter(model, rec, CATALOGUE["saturation"])._analytic


def kalman_reference(y, ss, white_var):
    """The textbook filter in matrix form, every covariance update done (no steady-state switch)."""
    x, p = np.zeros(ss.m), ss.p0.copy()
    e, s = np.empty(y.size), np.empty(y.size)
    for k in range(y.size):
        ph = p @ ss.h
        s[k] = white_var + ss.h @ ph
        e[k] = y[k] - ss.h @ x
        x = ss.f @ (x + ph * e[k] / s[k])
        p = ss.f @ (p - np.outer(ph, ph) / s[k]) @ ss.f.T + ss.q
    return e, s


@pytest.mark.parametrize("kind,effects,steady", [
    ("accelerometer", (("gauss_markov", {"sigma": 4e-6, "tau_s": 2.0}),), True),
    ("accelerometer", (("rate_random_walk", {"k_per_rs": 1e-7}),), True),
    # flicker's slowest state outlives the record: no steady state, every update done
    ("accelerometer", (("flicker_noise", {"b": 3e-6, "tau_min_s": 0.05}),
                       ("gauss_markov", {"sigma": 4e-6, "tau_s": 20.0})), False),
    # white angle noise: a moving-average block, F not diagonal (the general kernel)
    ("gyro", (("angle_quantization", {"q_angle": 2e-4}), ("gauss_markov", {"sigma": 1e-3, "tau_s": 5.0})), True),
], ids=["gm", "rw", "flicker+gm", "angle-quantization+gm"])
def test_the_kalman_filter_is_the_full_recursion(kind, effects, steady):
    """The compiled filters (F diagonal, or block-diagonal) give the textbook recursion's
    innovations and variances; once a covariance update leaves P bit for bit unchanged they only
    propagate the state (the same gain from there on)."""
    rate_hz, n = 10.0, 6000
    sd = base_model(kind).noise_sd
    model = Model(base_model(kind))
    for eid, p in effects:
        model = model.with_effect(eid, p)
    rec = make_experiment(kind, np.random.default_rng(1), n=n, rate_hz=rate_hz)
    y = model.simulate_noise(rec, np.random.default_rng(5))
    ss = state_space(rate_hz, n, model.stochastic_effects())
    e, s = ss.filter(y, sd ** 2)
    e_ref, s_ref = kalman_reference(y, ss, sd ** 2)
    assert np.allclose(s, s_ref, rtol=1e-9, atol=0) and np.allclose(e, e_ref, rtol=1e-7, atol=1e-9 * sd)
    # where it is reached, the steady state comes well inside the record: the switch is exercised
    assert np.all(s[n // 2:] == s[-1]) == steady
