"""Parameter uncertainties of the candidate fits (bench.discovery.fitting): the finite-difference
Jacobian, the HAC covariance against statsmodels and a dense-matrix reference, and the coverage
of the stated standard errors on white and on coloured (Gauss–Markov) residual noise."""

import math

import numpy as np
import pytest
import statsmodels.api as sm
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import toeplitz

from bench.discovery import significance as sig
from bench.discovery.data import Record
from bench.discovery.effects import CATALOGUE
from bench.discovery.effects_thermal import NODE_SEEN
from bench.discovery.experiments import make_experiment
from bench.discovery.fitting import CandidateFitter, finite_difference_jacobian, hac_bandwidth, hac_covariance
from bench.discovery.model import BaseModel, Model, base_model


def _gm(rng, n, sigma, tau_samples):
    phi = math.exp(-1.0 / tau_samples)
    x = np.empty(n)
    x[0] = sigma * rng.standard_normal()
    e = rng.standard_normal(n) * sigma * math.sqrt(1 - phi ** 2)
    for k in range(1, n):
        x[k] = phi * x[k - 1] + e[k]
    return x


def test_finite_difference_jacobian_matches_the_derivative_and_steps_back_at_the_bound():
    t = np.linspace(0, 1, 50)
    f = lambda x: x[0] * np.exp(-t / x[1])
    x = np.array([2.0, 0.5])
    exact = np.column_stack([np.exp(-t / x[1]), x[0] * t / x[1] ** 2 * np.exp(-t / x[1])])
    j = finite_difference_jacobian(f, x, np.array([1e-6, 1e-7]))
    assert np.allclose(j, exact, rtol=1e-5, atol=1e-6)
    # at an upper bound the step goes backwards: the same derivative to first order
    jb = finite_difference_jacobian(f, x, np.array([1e-6, 1e-7]), upper=x.copy())
    assert np.allclose(jb, exact, rtol=1e-5, atol=1e-6)
    assert finite_difference_jacobian(f, x, np.array([1e-6, 1e-7]), columns=[1]).shape == (50, 1)
    with pytest.raises(ValueError, match="steps"):
        finite_difference_jacobian(f, x, np.array([0.0, 1e-7]))


@pytest.mark.parametrize("lag", [0, 1, 7, 40])
@pytest.mark.parametrize("coloured", [False, True])
def test_newey_west_equals_statsmodels_hac_for_a_linear_drift(lag, coloured):
    rng = np.random.default_rng(3)
    n = 600
    t = np.arange(n) * 0.5
    x = np.column_stack([np.ones(n), t])
    noise = _gm(rng, n, 1.0, 15.0) if coloured else rng.standard_normal(n)
    y = 1e-3 + 2e-6 * t + 5e-6 * noise
    ols = sm.OLS(y, x).fit(cov_type="HAC", cov_kwds={"maxlags": lag, "use_correction": True})
    ours = hac_covariance(x, ols.resid, lag)
    assert np.allclose(ours, ols.cov_params(), rtol=1e-10, atol=0)


def test_stationary_hac_equals_the_dense_toeplitz_sandwich():
    rng = np.random.default_rng(4)
    n, lag = 400, 25
    j = np.column_stack([np.ones(n), np.exp(-np.arange(n) / 40.0), rng.standard_normal(n)])
    e = _gm(rng, n, 1.0, 8.0) + 0.5 * rng.standard_normal(n)
    ez = e - e.mean()
    gam = np.array([ez[k:] @ ez[: n - k] / n for k in range(n)])
    w = np.clip(1 - np.arange(n) / (lag + 1.0), 0, None)
    gam = gam + (gam[0] + 2 * np.sum(w[1:] * gam[1:])) / (n - lag - 1)  # demeaning's bias undone
    sigma = toeplitz(gam * w)
    b = np.linalg.inv(j.T @ j)
    dense = b @ j.T @ sigma @ j @ b * n / (n - 3)
    assert np.allclose(hac_covariance(j, e, lag, stationary=True), dense, rtol=1e-9, atol=0)


def test_rows_outside_the_fit_are_gaps_not_neighbours():
    rng = np.random.default_rng(5)
    n = 500
    j = np.column_stack([np.ones(n), np.linspace(0, 1, n)])
    e = rng.standard_normal(n)
    rows = np.zeros(n, bool)
    rows[100:350] = True
    for stationary in (False, True):
        masked = hac_covariance(j, e, 9, rows, stationary=stationary)
        cut = hac_covariance(j[rows], e[rows], 9, stationary=stationary)
        assert np.allclose(masked, cut, rtol=1e-10)
    with pytest.raises(ValueError, match="max_lag"):
        hac_covariance(j, e, -1)


@settings(max_examples=15, deadline=None)
@given(tau=st.floats(3.0, 60.0), seed=st.integers(0, 2 ** 16))
def test_bandwidth_grows_with_the_correlation_time(tau, seed):
    rng = np.random.default_rng(seed)
    n = 4000
    white = hac_bandwidth(rng.standard_normal(n))
    coloured = hac_bandwidth(_gm(rng, n, 1.0, tau) + 0.3 * rng.standard_normal(n))
    assert white <= 12  # n^(1/4) = 8 floor, a few lags more by chance
    assert coloured >= min(2 * tau, n // 4)


def _coverage(eid: str, truth_params: dict, start: dict, main: str, gm: dict | None, seeds: int):
    """Estimates, stated sds and 2σ coverage of ``main`` over seeds (fixed): a 1 Hz accelerometer
    record of 1800 samples, white noise 5 µg, optionally a Gauss–Markov component."""
    n = 1800
    t = np.arange(n, dtype=float)
    rec0 = Record(t_s=t, y=np.zeros(n), t_on_s=t)
    truth = Model(BaseModel("accelerometer", 1e-3, 1.0, 5e-6)).with_effect(eid, truth_params)
    if gm:
        truth = truth.with_effect("gauss_markov", gm)
    fits = []
    for s in range(seeds):
        rec = rec0.replace(y=truth.simulate(rec0, np.random.default_rng(1000 + s)))
        f = CandidateFitter(Model(truth.base), rec, CATALOGUE[eid])
        fit = f.fit([f.pack(start, 1e-3, 1.0)])
        fits.append((fit.params[main], fit.params_std[main]))
    est, sds = np.array(fits).T
    return est, sds, float(np.mean(np.abs(est - truth_params[main]) / sds < 2))


GM = {"sigma": 4e-6, "tau_s": 20.0}
#: 2σ coverage floors over the 40 fixed seeds. Measured on 200 seeds (/tmp/h7/cov_big.py): white
#: 96 % (tau) and 95 % (slope); Gauss–Markov 86 % and 89 % (stated sd ≈ 0.75-0.8 of the spread:
#: the Bartlett taper and the fit's projection still shorten the residual's long-lag correlation);
#: the white-noise formula s²(JᵀJ)⁻¹ gave 30 % under Gauss–Markov (sd ratio 0.25).
FLOOR = {"white": 0.88, "gauss_markov": 0.75}


@pytest.mark.parametrize("gm", [None, GM], ids=["white", "gauss_markov"])
def test_warmup_tau_standard_error_covers_the_truth(gm):
    est, sds, cover = _coverage("warmup_exponential", {"amplitude": 6e-5, "tau_s": 150.0},
                                {"amplitude": 5e-5, "tau_s": 120.0}, "tau_s", gm, 40)
    assert cover >= FLOOR["gauss_markov" if gm else "white"]
    ratio = float(np.median(sds) / np.std(est, ddof=1))
    assert 0.55 <= ratio <= 1.5, ratio  # 40 seeds: the spread itself is known to ±12 %; white formula 0.25


@pytest.mark.parametrize("gm", [None, GM], ids=["white", "gauss_markov"])
def test_linear_drift_standard_error_covers_the_truth(gm):
    est, sds, cover = _coverage("linear_drift", {"slope_per_s": 3e-8}, {"slope_per_s": 1e-8},
                                "slope_per_s", gm, 40)
    assert cover >= FLOOR["gauss_markov" if gm else "white"]
    ratio = float(np.median(sds) / np.std(est, ddof=1))
    assert 0.55 <= ratio <= 1.5, ratio  # 40 seeds: the spread itself is known to ±12 %; white formula 0.25


def test_a_two_node_transient_keeps_its_fast_node_where_the_rows_see_it():
    """A fit on rows that start after power-on cannot resolve a node faster than the first row's
    t_on / NODE_SEEN: the fast node's range starts there; from power-on it is the physical one."""
    p = {"amplitude": -0.0375, "fraction_slow": 0.43, "tau_fast_s": 3.15, "tau_slow_s": 75.0}
    two = CATALOGUE["thermal_two_node"]
    rec = make_experiment("gyro", np.random.default_rng(0), n=3000)
    folds = sig.block_folds(rec.n)
    # the bound itself: only on rows that start after power-on (training rows without the first
    # block — the folds now cut that block into spans both see), never above a quarter of the range
    rows = rec.column("t_on") > 6.2
    t_first = float(rec.column("t_on")[rows].min())
    q = {x.name: x for x in two.free_params(p, "gyro", rec, rows)}["tau_fast_s"]
    assert t_first > 0 and q.low == pytest.approx(t_first / NODE_SEEN)
    assert two.free_params(p, "gyro", rec) == two.params_for("gyro")
    assert two.free_params(p, "gyro", rec, folds == 0) == two.params_for("gyro")  # rows from power-on


@settings(max_examples=40, deadline=None)
@given(th1=st.floats(-10.0, 2000.0), dt=st.floats(1e-3, 10.0))
def test_gauss_markov_tau_std_holds_where_phi_rounds_to_one(th1, dt):
    """τ's delta-method std: finite at every correlation coordinate (a null replicate's fit ran to
    φ = 1, where (ln φ)² underflowed and the std divided by zero), and the derivative dτ/dth1 of
    the τ it reports (central difference) elsewhere."""
    gm = CATALOGUE["gauss_markov"]
    est = gm.estimate(np.zeros(10), np.array([0.0, th1]), np.diag([1.0, 1.0]), dt, alone=True, bootstrap=False)
    assert math.isfinite(est.params_std["tau_s"]) and est.params_std["tau_s"] >= 0
    if th1 < 25:
        h = 1e-5 * max(1.0, abs(th1))

        def tau(x):
            est = gm.estimate(np.zeros(10), np.array([0.0, x]), np.eye(2), dt, alone=True, bootstrap=False)
            return est.params["tau_s"]
        assert est.params_std["tau_s"] == pytest.approx(abs(tau(th1 + h) - tau(th1 - h)) / (2 * h), rel=1e-4)


def test_a_fit_whose_bias_must_move_less_than_its_jump_times_scale_still_converges():
    """A held-out fold's fit of three jumps (times ≈ 500-1500 s) from a start whose bias is two
    noise sd off (the jumps' sizes were found with the level projected out): scipy's ``xtol``
    compares a step with the whole coordinate vector, which the jump times dominate, so a bias
    step of 1e-5 g "converged" after three evaluations and left the training rows 1.5× the floor
    (the scorecard's accelerometer jump + dead zone + GM, seed 3019 of ``--pairs 2``: held-out
    score −0.13 for jumps the full fit placed to a second). The fits end on ``ftol``/``gtol``."""
    rng = np.random.default_rng(1)
    n = 3000
    t = np.arange(n) * 1.0
    u = np.sin(2 * np.pi * t / 600)
    jumps = {"size_1": -1.6e-5, "time_1_s": 509.0, "size_2": -8e-6, "time_2_s": 1146.5,
             "size_3": 1.4e-5, "time_3_s": 1475.9}
    eff = CATALOGUE["bias_jump"]
    flat = Record(t_s=t, y=np.zeros(n), input=u)
    rec = Record(t_s=t, y=1e-3 + 1.0005 * u + eff.term(jumps, flat) + rng.normal(0, 5e-6, n), input=u)
    base = base_model("accelerometer")
    model = Model(BaseModel("accelerometer", base.bias, base.scale_factor, 5e-6))
    rows = sig.block_folds(n) != 1
    f = CandidateFitter(model, rec, eff, template=jumps, rows=rows)
    fit = f.fit([f.pack(jumps | {"time_1_s": 508.5}, 1e-3 - 1.1e-5, 1.0005)], rows=rows, with_std=False)
    assert abs(fit.bias - 1e-3) < 2e-6
    assert np.sqrt(np.mean((rec.y - f.predict(fit.x))[rows] ** 2)) < 1.1 * 5e-6
