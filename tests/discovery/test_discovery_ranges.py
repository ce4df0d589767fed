"""Fit ranges from the record (bench.discovery.effects_noise / effects_transforms / stochastic):
the ranges a random process's or a quantizer's fit uses come from the record for any sensor grade
(MEMS through navigation grade), a fit recovers a MEMS-grade Gauss–Markov away from its bounds,
a MEMS accelerometer's 3.33 mg quantizer is representable, and a fit the range stopped says so."""

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.discovery import stochastic as sto
from bench.discovery.data import Record
from bench.discovery.effects import CATALOGUE
from bench.discovery.effects_base import at_edge
from bench.discovery.model import Model, base_model
from bench.discovery.significance import block_folds

#: (rate Hz, samples, white sd per sample, GM sigma, GM tau s, RRW K) of a gyro of each grade (deg/s):
#: a MEMS gyro (0.05 deg/s per sample at 100 Hz, a large walk), a navigation-grade FOG (1 h at 10 Hz)
GRADES = {
    "mems": (100.0, 150_000, 0.05, 0.02, 2.0, 1e-3),
    "navigation": (10.0, 36_000, 3e-3, 3e-5, 100.0, 1e-6),
}
PROCESSES = ("gauss_markov", "rate_random_walk")


def _gyro_record(grade, seed, scale):
    """A static gyro record of the grade: white + Gauss–Markov + random walk, each level drawn
    within ×/÷ ``scale`` of the grade's (log-uniform); (record, the true parameters by effect)."""
    rate, n, white, sigma, tau, k = GRADES[grade]
    rng = np.random.default_rng(seed)

    def jitter(v):
        return float(v * math.exp(rng.uniform(-math.log(scale), math.log(scale))))

    truth = {"gauss_markov": {"sigma": jitter(sigma), "tau_s": jitter(tau)},
             "rate_random_walk": {"k_per_rs": jitter(k)}}
    t = np.arange(n) / rate
    y = np.zeros(n) + rng.normal(0.0, jitter(white), n)
    rec = Record(t_s=t, y=y)
    for eid, p in truth.items():
        y = y + CATALOGUE[eid].noise(p, rec, rng)
    return Record(t_s=t, y=y), truth


@settings(max_examples=6, deadline=None, derandomize=True)
@given(grade=st.sampled_from(sorted(GRADES)), seed=st.integers(0, 2 ** 16))
def test_a_records_true_processes_lie_strictly_inside_its_fit_ranges_for_any_grade(grade, seed):
    rec, truth = _gyro_record(grade, seed, scale=2.0)
    for eid, p in truth.items():
        eff = CATALOGUE[eid]
        bounds = {q.name: q for q in eff.fit_params(rec, "gyro")}
        for name, v in p.items():
            assert bounds[name].low < v < bounds[name].high, (eid, name, v, bounds[name])
        assert at_edge(eff, p, rec, "gyro") == ()


@pytest.mark.parametrize("grade", sorted(GRADES))
def test_what_a_process_draws_on_a_record_is_inside_its_fit_ranges(grade):
    rec, _ = _gyro_record(grade, 7, scale=1.0)
    rng = np.random.default_rng(11)
    for eid in ("gauss_markov", "rate_random_walk", "flicker_noise", "angle_quantization"):
        eff = CATALOGUE[eid]
        try:
            p = eff.draw(rng, rec, kind="gyro")
        except ValueError:  # not detectable on this record: nothing drawn to check
            continue
        for q in eff.fit_params(rec, "gyro"):
            assert q.low < p[q.name] < q.high, (eid, q.name, p[q.name], q)


def test_the_mems_levels_lie_beyond_the_narrow_physical_ranges_but_inside_the_fit_ranges():
    """The case of the issue: a MEMS accelerometer's Gauss–Markov of 2 mg and walk of 1e-3 g/√s are
    beyond the quartz ranges (1 mg, 1e-4 g/√s) the fits were clipped to; the record's own ranges
    hold them and a model takes them."""
    rng = np.random.default_rng(3)
    n, rate = 100_000, 100.0
    t = np.arange(n) / rate
    rec0 = Record(t_s=t, y=np.zeros(n))
    gm, rw = {"sigma": 2e-3, "tau_s": 5.0}, {"k_per_rs": 1e-3}
    y = (1.0 + rng.normal(0, 3e-3, n) + CATALOGUE["gauss_markov"].noise(gm, rec0, rng)
         + CATALOGUE["rate_random_walk"].noise(rw, rec0, rng))
    rec = Record(t_s=t, y=y)
    for eid, p in (("gauss_markov", gm), ("rate_random_walk", rw)):
        eff = CATALOGUE[eid]
        name = eff.main_param
        assert p[name] > eff.params_for("accelerometer")[0].high  # beyond the physical (drawn) range
        q = eff.fit_params(rec, "accelerometer")[0]
        assert q.low < p[name] < q.high
        assert at_edge(eff, p, rec, "accelerometer") == ()
    Model(base_model("accelerometer"), (("gauss_markov", gm), ("rate_random_walk", rw)))


def _gm_record(rng, sigma, tau, n=60_000, rate=100.0, white=0.05):
    t = np.arange(n) / rate
    rec0 = Record(t_s=t, y=np.zeros(n))
    return rng.normal(0, white, n) + CATALOGUE["gauss_markov"].noise({"sigma": sigma, "tau_s": tau}, rec0, rng)


def test_fit_stochastic_recovers_a_mems_gauss_markov_within_its_stated_std_away_from_the_bounds():
    """20 records (100 Hz, 10 min, white 0.05 deg/s): σ and τ drawn around 0.02 deg/s and 2 s; the
    truth within 3 stated std of the Whittle estimate in at least 90 % of them, none at an edge."""
    rng = np.random.default_rng(2024)
    eff = CATALOGUE["gauss_markov"]
    hits = {"sigma": 0, "tau_s": 0}
    n_rec = 20
    for _ in range(n_rec):
        truth = {"sigma": 0.02 * math.exp(rng.uniform(-0.4, 0.4)), "tau_s": 2.0 * math.exp(rng.uniform(-0.5, 0.5))}
        r = _gm_record(rng, **{"sigma": truth["sigma"], "tau": truth["tau_s"]})
        fit = sto.fit_stochastic(r - r.mean(), 0.01, eff, bootstrap=False)
        assert fit.edges == () and fit.notes == ()
        for name in hits:
            hits[name] += abs(fit.params[name] - truth[name]) <= 3 * fit.params_std[name]
        held = fit.params_for("gyro")
        assert held == pytest.approx(fit.params)  # inside the range: nothing clipped
    assert all(h >= 0.9 * n_rec for h in hits.values()), hits


@settings(max_examples=4, deadline=None, derandomize=True)
@given(noise_mg=st.floats(0.6, 1.4), seed=st.integers(0, 2 ** 16))
def test_a_mems_accelerometers_3_33_mg_quantizer_is_representable(noise_mg, seed):
    """A 3.33 mg LSB (±16 g over 13 bits, say): beyond the physical 1 mg top the fit was clipped
    to; inside the record's fit range, found by the lattice fit, and held by a model."""
    step = 3.33e-3
    eff = CATALOGUE["quantization"]
    assert step > eff.params_for("accelerometer")[0].high
    rng = np.random.default_rng(seed)
    n = 30_000
    y = step * np.round((1.0 + rng.normal(0, noise_mg * 1e-3, n)) / step)
    rec = Record(t_s=np.arange(n) / 100.0, y=y)
    q = eff.fit_params(rec, "accelerometer")[0]
    assert q.low < step < q.high
    assert at_edge(eff, {"step": step}, rec, "accelerometer") == ()
    fit = eff.fit_histogram(y, noise_mg * 1e-3, block_folds(n), "accelerometer")
    assert fit.p_value < 1e-6
    assert fit.params["step"] == pytest.approx(step, rel=0.01)
    Model(base_model("accelerometer"), (("quantization", {"step": fit.params["step"]}),))


def test_at_edge_names_the_parameters_pinned_at_a_bound_by_construction():
    rng = np.random.default_rng(5)
    n = 20_000
    rec = Record(t_s=np.arange(n) / 100.0, y=rng.normal(0, 0.05, n))
    eff = CATALOGUE["gauss_markov"]
    sig, tau = (q for q in eff.fit_params(rec, "gyro"))
    mid_sigma = math.sqrt(sig.low * sig.high)
    assert at_edge(eff, {"sigma": mid_sigma, "tau_s": 1.0}, rec, "gyro") == ()
    assert at_edge(eff, {"sigma": mid_sigma, "tau_s": tau.high}, rec, "gyro") == ("tau_s",)
    assert at_edge(eff, {"sigma": mid_sigma, "tau_s": 10 * tau.high}, rec, "gyro") == ("tau_s",)
    assert at_edge(eff, {"sigma": sig.low * 1.01, "tau_s": tau.low}, rec, "gyro") == ("sigma", "tau_s")
    assert tau.high == pytest.approx(rec.duration_s) and tau.low == pytest.approx(0.5 * rec.dt_s)


def test_a_fit_beyond_its_range_is_held_at_the_bound_and_says_so():
    """A fitted correlation time beyond the record's span (the Whittle fit is unbounded in its log
    coordinates): the model takes the bound, the fit names the parameter and the report line."""
    rng = np.random.default_rng(8)
    r = _gm_record(rng, 0.02, 2.0, n=20_000)
    fit = sto.fit_stochastic(r - r.mean(), 0.01, CATALOGUE["gauss_markov"], bootstrap=False)
    assert fit.edges == ()
    span = (r.size - 1) * 0.01
    pinned = replace(fit, params={**fit.params, "tau_s": 10 * span})
    assert pinned.edges == ("tau_s",)
    assert pinned.params_for("gyro")["tau_s"] == pytest.approx(span)
    assert pinned.notes == (f"gauss_markov.tau_s at its upper bound {span:.4g} s",)
