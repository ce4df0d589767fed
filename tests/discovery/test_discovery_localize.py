"""Unexplained-structure localization (issue 7, audit #10): calibrated on white noise and on the
model's own Gauss–Markov / random-walk noise (through the Kalman innovations), and it says
where a hidden sinusoid, a step or an input-driven term is when the model lacks them."""

import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from bench.discovery import localize as loc
from bench.discovery.calibration import calibrate
from bench.discovery.data import Record
from bench.discovery.effects import CATALOGUE
from bench.discovery.experiments import make_experiment
from bench.discovery.model import Model, base_model
from bench.discovery.significance import welch_nperseg, white_floor
from bench.discovery.whiten import exact_nll, innovations

SD = 5e-6
RATE_HZ = 10.0
GM = (CATALOGUE["gauss_markov"], {"sigma": 1e-5, "tau_s": 3.0})
RW = (CATALOGUE["rate_random_walk"], {"k_per_rs": 2e-6})


def _model(*effects):
    m = Model(base_model("accelerometer")).with_base(noise_sd=SD)
    for eff, p in effects:
        m = m.with_effect(eff.id, p)
    return m


def _record(n):
    t = np.arange(n) / RATE_HZ
    return Record(t_s=t, y=np.zeros(n), temp_c=20 + 5 * np.sin(2 * np.pi * t / t[-1]))


def _noise(model, rec, seed):
    return model.simulate(rec, np.random.default_rng(seed)) - model.predict(rec)


@pytest.mark.parametrize("effects", [(), (GM,), (RW,), (GM, RW)], ids=["white", "gm", "rw", "gm+rw"])
def test_false_alarms_on_the_models_own_noise_at_most_5_percent(effects):
    m = _model(*effects)
    hits, total = 0, 0
    for n, seeds in ((300, range(100)), (3000, range(40)), (10000, range(6))):
        rec = _record(n)
        hits += sum(bool(loc.unexplained_structure(rec, _noise(m, rec, 100 + s), m)) for s in seeds)
        total += len(seeds)
    # one-sided binomial test of "rate ≤ 5 %" at the 5 % level (≤ 12 of 146; the measured rate
    # is ~3.5 %, see the module docstring of localize; the old tests flagged ~10 % at n = 300)
    assert hits <= stats.binom.ppf(0.95, total, 0.05)


def _where(descs, pattern):
    return [d for d in descs if re.search(pattern, d)]


@pytest.mark.parametrize("effects", [(), (GM,), (RW,)], ids=["white", "gm", "rw"])
def test_hidden_sinusoid_is_a_spectral_line_at_its_frequency(effects):
    m = _model(*effects)
    rec = _record(6000)
    f0 = 1.37
    r = _noise(m, rec, 5) + 2.5 * SD * np.sin(2 * np.pi * f0 * rec.t_s)
    lines = _where(loc.unexplained_structure(rec, r, m), r"spectral (line|band)")
    assert lines
    peaks = [float(re.search(r"([0-9.]+) Hz", d).group(1)) if "peak" not in d
             else float(re.search(r"peak ([0-9.]+) Hz", d).group(1)) for d in lines]
    df = RATE_HZ / welch_nperseg(rec.n)
    assert min(abs(p - f0) for p in peaks) <= df


def test_step_in_the_middle_is_placed_there_white_model():
    m = _model()
    rec = _record(4000)
    r = _noise(m, rec, 6) + np.where(rec.t_s >= rec.t_s[-1] / 2, 0.5 * SD, 0.0)
    d = loc.unexplained_structure(rec, r, m)
    segs = _where(d, r"^segment")
    assert segs and _where(d, "cumulative sum")
    mid = rec.t_s[-1] / 2
    # flagged segments lie on both sides of the step (means of opposite sign), none straddles far
    starts = [float(re.search(r"segment ([0-9.]+)", s).group(1)) for s in segs]
    assert min(starts) < mid <= max(starts) + rec.t_s[-1] / 16


def test_step_in_the_middle_is_a_jump_there_random_walk_model():
    m = _model(RW)
    rec = _record(4000)
    t_step = rec.t_s[2000]
    r = _noise(m, rec, 7) + np.where(rec.t_s >= t_step, 40 * SD, 0.0)
    d = loc.unexplained_structure(rec, r, m)
    jumps = _where(d, r"jump at t = ")
    assert jumps and all(d.startswith("in the Kalman innovations") for d in d)
    times = [float(re.search(r"t = ([0-9.]+) s", j).group(1)) for j in jumps]
    assert min(abs(t - t_step) for t in times) < 1.0 / RATE_HZ


@pytest.mark.parametrize("effects,per_c", [((), 0.4), ((GM,), 4.0)], ids=["white", "gm"])
def test_input_driven_term_is_a_correlation_with_that_input(effects, per_c):
    # with GM noise a slow input must stand out of the GM's own slow wander (σ = 2 SD, τ = 3 s),
    # and the correlation's effective n allows for the innovations' leftover autocorrelation
    m = _model(*effects)
    rec = _record(5000)
    r = _noise(m, rec, 8) + per_c * SD * (rec.temp_c - 20)
    corr = _where(loc.unexplained_structure(rec, r, m), r"correlation with temp")
    assert corr


def test_white_model_step_and_line_absent_gives_nothing_on_clean_record():
    m = _model()
    rec = _record(2000)
    assert loc.unexplained_structure(rec, _noise(m, rec, 1), m) == ()


def test_allan_deficit_is_not_flagged():
    # blue noise: ADEV far below white at long τ (a deficit, not missing structure); only its
    # real excess at τ = 1 sample may be reported
    x = np.diff(np.random.default_rng(3).standard_normal(20001)) / np.sqrt(2)
    taus, tau, adev, white = loc.allan_taus(x, 1.0, 1.0, 0.01)
    assert np.sum(adev < 0.5 * white) >= 5  # deep deficit present
    assert all(t.worst_ratio > 1 and t.tau_high_s <= 2.0 for t in taus)


def test_localize_rejects_bad_floor_dof():
    rec = _record(100)
    with pytest.raises(ValueError, match="floor_dof"):
        loc.localize(rec, np.zeros(100) + 1e-6, 1e-6, floor_dof=0.0)


def test_white_floor_dof_matches_its_spread():
    rng = np.random.default_rng(0)
    est = np.array([white_floor(rng.standard_normal(4000), 1.0) for _ in range(150)])
    var_ratio = np.var(est[:, 0] ** 2) / (2 / est[0, 1])  # measured / stated variance of σ̂²
    assert 0.6 < var_ratio < 1.1 and abs(np.mean(est[:, 0] ** 2) - 1) < 0.02


def test_short_tau_gm_with_a_white_level_that_counted_it_gives_few_false_alarms():
    # the workflow's white level comes from the upper-half PSD, where a τ = 0.5 s GM at 10 Hz
    # adds ~40 % power: innovations with that level would be coloured (60 % false alarms)
    m = _model((CATALOGUE["gauss_markov"], {"sigma": 1e-5, "tau_s": 0.5}))
    rec = _record(3000)
    hits = 0
    for s in range(40):
        r = _noise(m, rec, 300 + s)
        biased = m.with_base(noise_sd=white_floor(r, RATE_HZ)[0])
        hits += bool(loc.unexplained_structure(rec, r, biased))
    assert hits <= stats.binom.ppf(0.95, 40, 0.05)


@pytest.mark.parametrize("eff", [(CATALOGUE["gauss_markov"], {"sigma": 1e-5, "tau_s": 0.5}), RW], ids=["gm", "rw"])
def test_white_floor_beside_stochastic_effects_recovers_the_white_level(eff):
    m = _model(eff)
    rec = _record(20000)
    r = _noise(m, rec, 9)
    plain, _ = white_floor(r, RATE_HZ)
    aware, _ = white_floor(r, RATE_HZ, [eff])
    assert abs(aware / SD - 1) < 0.05
    if eff[0].id == "gauss_markov":
        assert plain / SD > 1.1  # the plain median counts the GM's upper-half power as white


# --- whiten.innovations ---------------------------------------------------------------------

@pytest.mark.parametrize("effects", [(GM,), (RW,), (GM, RW)], ids=["gm", "rw", "gm+rw"])
def test_innovations_of_the_models_noise_are_white_unit_variance(effects):
    m = _model(*effects)
    rec = _record(20000)
    e = innovations(_noise(m, rec, 11), RATE_HZ, SD, m.stochastic_effects())
    assert abs(np.var(e[200:]) - 1) < 0.05
    for lag in (1, 2, 5, 30):
        assert abs(np.corrcoef(e[200:-lag], e[200 + lag:])[0, 1]) < 4 / np.sqrt(e.size)


@settings(max_examples=15, deadline=None)
@given(a=st.floats(-3, 3), b=st.floats(-3, 3), seed=st.integers(0, 2 ** 20))
def test_innovations_are_linear_in_the_residual(a, b, seed):
    rng = np.random.default_rng(seed)
    r1, r2 = rng.standard_normal((2, 500)) * SD
    eff = [GM, RW]
    lhs = innovations(a * r1 + b * r2, RATE_HZ, SD, eff)
    rhs = a * innovations(r1, RATE_HZ, SD, eff) + b * innovations(r2, RATE_HZ, SD, eff)
    assert np.allclose(lhs, rhs, rtol=1e-9, atol=1e-9)


def test_innovations_without_stochastic_effects_are_the_scaled_residual():
    r = np.arange(10.0)
    assert np.array_equal(innovations(r, 1.0, 2.0, ()), r / 2.0)


@pytest.mark.parametrize("eid,params,match", [
    ("quantization", {"step": 1.0}, "'quantization' is not stochastic"),
    ("gauss_markov", {"sigma": 1.0, "tau_s": 0.0}, r"gauss_markov sigma = 1.0, tau_s = 0.0; allowed"),
    ("rate_random_walk", {"k_per_rs": -1.0}, r"rate_random_walk k_per_rs = -1.0; allowed"),
])
def test_innovations_reject_bad_effects(eid, params, match):
    with pytest.raises(ValueError, match=match):
        innovations(np.zeros(10), 1.0, 1.0, [(CATALOGUE[eid], params)])


def test_innovations_reject_bad_arguments():
    with pytest.raises(ValueError, match="white_sd"):
        innovations(np.zeros(10), 1.0, 0.0, ())
    with pytest.raises(ValueError, match="rate_hz"):
        innovations(np.zeros(10), -1.0, 1.0, ())
    with pytest.raises(ValueError, match="non-finite"):
        innovations(np.array([0.0, np.nan]), 1.0, 1.0, ())


def _dense_nll(r, seen, effects, white_var):
    """−ln L (constant dropped) of the seen samples of ``r`` under white + ``effects``, from the
    dense covariance of the states (x₀ ~ P0, x_k = F x_{k−1} + e, cov e = Q, seen as h·x)."""
    n = r.size
    cov = np.zeros((n, n))
    for eff, p in effects:
        b = eff.state_space(p, 1.0 / RATE_HZ, n)
        ps = [b.p0]
        for _ in range(n - 1):
            ps.append(b.f @ ps[-1] @ b.f.T + b.q)
        for i in range(n):
            fk = np.eye(b.m)
            for j in range(i, n):
                cov[i, j] = cov[j, i] = cov[i, j] + b.h @ fk @ ps[i] @ b.h
                fk = b.f @ fk
    cov += white_var * np.eye(n)
    c = cov[np.ix_(seen, seen)]
    x = r[seen]
    return 0.5 * (np.linalg.slogdet(c)[1] + x @ np.linalg.solve(c, x))


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2 ** 20), which=st.sampled_from(["gm", "rw", "gm+rw"]),
       tau=st.floats(0.2, 20.0), k=st.floats(1e-7, 1e-5))
def test_exact_nll_with_missing_samples_is_the_likelihood_of_the_seen_ones(seed, which, tau, k):
    """A sample not seen (NaN: a clipped stretch) is missing to the Kalman filter: the exact
    likelihood is the Gaussian one of the others, from their dense covariance."""
    rng = np.random.default_rng(seed)
    n = 40
    effects = {"gm": [(GM[0], {"sigma": 1e-5, "tau_s": tau})], "rw": [(RW[0], {"k_per_rs": k})],
               "gm+rw": [(GM[0], {"sigma": 1e-5, "tau_s": tau}), (RW[0], {"k_per_rs": k})]}[which]
    seen = rng.random(n) < 0.6
    seen[rng.integers(n)] = True
    r = rng.standard_normal(n) * 1e-5
    got = exact_nll(np.where(seen, r, np.nan), RATE_HZ, SD ** 2, effects)
    assert got == pytest.approx(_dense_nll(r, seen, effects, SD ** 2), rel=1e-7)
    e = innovations(r, RATE_HZ, SD, effects, seen=seen)
    assert np.all(np.isnan(e[~seen])) and np.all(np.isfinite(e[seen]))
    assert np.array_equal(innovations(r, RATE_HZ, SD, effects, seen=np.ones(n, bool)),
                          innovations(r, RATE_HZ, SD, effects))


def test_innovations_carry_the_states_across_samples_not_seen():
    """A Gauss–Markov clipped for stretches of 5–20 s: filtered with those samples missing, the
    seen innovations are white with unit variance; read from the clipped stretches' flat
    residual (zeros) they jump at each stretch's end."""
    m = _model((CATALOGUE["gauss_markov"], {"sigma": 3e-5, "tau_s": 30.0}))
    rec = _record(20000)
    r = _noise(m, rec, 5)
    rng = np.random.default_rng(2)
    seen = np.ones(rec.n, bool)
    for start in rng.choice(rec.n - 200, 40, replace=False):
        seen[start:start + rng.integers(50, 200)] = False
    flat = np.where(seen, r, 0.0)
    e = innovations(flat, RATE_HZ, SD, m.stochastic_effects(), seen=seen)[seen]
    assert abs(np.var(e[200:]) - 1) < 0.05
    assert np.max(np.abs(e[200:])) < 5.0
    plain = innovations(flat, RATE_HZ, SD, m.stochastic_effects())[seen]
    assert np.max(np.abs(plain[200:])) > 8.0


def test_innovations_reject_a_bad_seen_mask():
    with pytest.raises(ValueError, match="seen has shape"):
        innovations(np.zeros(10), 1.0, 1.0, [GM], seen=np.ones(9, bool))
    with pytest.raises(ValueError, match="seen holds no sample"):
        innovations(np.zeros(10), 1.0, 1.0, [GM], seen=np.zeros(10, bool))


def _tumble(n, seed):
    """A record whose input holds 16 levels (a tumble's orientations): each sits somewhere else
    on a quantizer's lattice."""
    t = np.arange(n) / RATE_HZ
    levels = np.random.default_rng(seed).uniform(-1.0, 1.0, 16)
    return Record(t_s=t, y=np.zeros(n), input=np.repeat(levels, -(-n // 16))[:n],
                  temp_c=20 + 5 * np.sin(2 * np.pi * t / t[-1]))


@pytest.mark.parametrize("effects,step_sd", [((), 4), ((GM,), 4), ((), 12)], ids=["white", "gm", "white-coarse"])
def test_a_coarse_quantizers_heteroscedastic_noise_is_not_structure(effects, step_sd):
    # step 4 noise sd: a level that sits on the lattice barely flips, one between two levels
    # flips half the time — segments of the record differ 3× in rms, all of it the model's own
    # noise (Model.residual_profile); at 12 sd a rare flip is a whole step, many floor sd: not
    # a jump (its fourth moment, not a Gaussian tail). Ignoring it, records "depart"
    m = _model(*effects).with_effect("quantization", {"step": step_sd * SD})
    hits = 0
    for s in range(40):
        rec = _tumble(3000, s)
        hits += bool(loc.unexplained_structure(rec, _noise(m, rec, 500 + s), m))
    assert hits <= stats.binom.ppf(0.95, 40, 0.05)
    # and a segment of real excess is still found where it is
    rec = _tumble(3000, 99)
    r = _noise(m, rec, 7)
    r[1500:1687] += step_sd * SD * np.random.default_rng(8).standard_normal(187)
    assert _where(loc.unexplained_structure(rec, r, m), r"segment 1[45]\d(\.\d)?–1[67]\d(\.\d)? s")


@pytest.mark.parametrize("kind,k", [("accelerometer", 4e-7), ("gyro", 5e-4)])
def test_a_scale_factor_fitted_beside_a_walk_is_not_an_input_correlation(kind, k):
    """Calibrated by least squares beside a strong random walk, the scale factor is off by colour
    that follows the input; in the innovations under the walk that error read as "correlation
    with input". The scale factor is refitted under the process (its whitened column projected
    out, as the named waveforms' are): a walk alone leaves no input correlation."""
    reported = 0
    for seed in range(12):
        rng = np.random.default_rng(seed)
        rec = make_experiment(kind, rng, n=3000)
        walk = {"k_per_rs": k}
        rec = rec.replace(y=Model(base_model(kind)).with_effect("rate_random_walk", walk).simulate(rec, rng))
        m = calibrate(Model(base_model(kind)), rec).with_effect("rate_random_walk", walk)
        r = rec.y - m.predict(rec)
        reported += any("correlation with input" in d for d in loc.unexplained_structure(rec, r, m))
    assert reported <= 1
