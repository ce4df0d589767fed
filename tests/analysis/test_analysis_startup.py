"""The whole start-up pipeline (Document A) and the StartupModel it returns."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.signal import lfilter

from bench.analysis.startup import StartupModel, analyze_startup, validate_trace
from bench.values import Estimate

DT_S = 0.5


def ar_from_pacf(kappas) -> np.ndarray:
    phi = np.zeros(0)
    for k in kappas:
        phi = np.r_[phi - k * phi[::-1], k]
    return phi


def startup_trace(n, tau, amp, slope, phi, theta, sigma, rng):
    t = 10.0 + np.arange(n) * DT_S
    u = t - t[0]
    noise = lfilter(np.r_[1.0, theta], np.r_[1.0, -np.asarray(phi)], rng.normal(0, sigma, n + 3000))[3000:]
    return t, 1.3 + amp * np.exp(-u / tau) + slope * u + noise


kappa = st.floats(0.15, 0.8).flatmap(lambda v: st.sampled_from([v, -v]))


@settings(max_examples=6, deadline=None, derandomize=True)
@given(st.lists(kappa, min_size=1, max_size=3).map(ar_from_pacf), st.floats(np.log(30), np.log(600)).map(np.exp),
       st.integers(0, 2**32 - 1))
def test_pipeline_recovers_trend_and_ar_noise(phi, tau, seed):
    rng = np.random.default_rng(seed)
    sigma = 1e-5
    t, y = startup_trace(20_000, tau, 50 * sigma, 2e-9, phi, [], sigma, rng)
    a = analyze_startup(t, y)
    m = a.model
    # the ACF/PACF rule may call a chance exceedance "tailing off"; the BIC table then decides
    assert a.identification.kind in ("AR", "ARMA") and (m.kind, m.p, m.q) == ("AR", phi.size, 0)
    assert m.method == "ulrych-clayton"
    assert np.all(np.abs(np.asarray(m.ar) - phi) < 4 * np.asarray(m.ar_std))
    tau_hat = m.trend["exp_tau_s"]
    assert abs(tau_hat.value - tau) < 4 * tau_hat.std
    # innovations back in volts: sigma2 is on the standardised scale
    assert np.sqrt(m.sigma2) * m.noise_std == pytest.approx(sigma, rel=0.05)
    assert a.ljung_box.p_value > 1e-3 and a.ljung_box.dof == a.ljung_box.lags - phi.size
    assert set(a.ar_estimates) == {"ulrych-clayton", "burg", "yule-walker"}


def test_pipeline_identifies_ma_noise_and_fits_it_by_ml():
    rng = np.random.default_rng(21)
    t, y = startup_trace(5000, 200.0, 1e-3, 0.0, [], [0.8], 1e-5, rng)
    a = analyze_startup(t, y)
    assert (a.model.kind, a.model.p, a.model.q) == ("MA", 0, 1)
    assert a.model.method == "ml" and a.order_selection.method == "css"
    assert abs(a.model.ma[0] - 0.8) < 4 * a.model.ma_std[0]


def test_outliers_are_counted_located_and_interpolated_on_the_same_time_base():
    rng = np.random.default_rng(5)
    t, y = startup_trace(4000, 120.0, 5e-4, 0.0, [0.5], [], 1e-5, rng)
    spikes = [300, 1500, 2222, 3999]
    y[spikes] += 5e-4  # ~40 sigma
    a = analyze_startup(t, y)
    out = a.outliers
    assert set(spikes) <= set(out.indices) and out.count == len(out.indices)
    assert out.times_s == tuple(t[list(out.indices)])
    assert a.standardized.size == y.size  # time base kept
    assert np.all(np.abs(a.standardized[spikes]) <= 3.0)
    k = 1500  # an isolated spike: AR(1) interpolator φ/(1+φ²)·(neighbours), φ ≈ 0.5
    assert a.standardized[k] == pytest.approx(0.4 * (a.standardized[k - 1] + a.standardized[k + 1]), abs=0.05)
    assert a.to_dict()["outliers"]["count"] == out.count


def test_model_simulates_traces_that_reanalyse_to_the_same_model():
    model = StartupModel(
        trend={"offset": _e(1.3), "exp_amplitude": _e(4e-4), "exp_tau_s": _e(150.0), "linear_slope_per_s": _e(1e-9)},
        t0_s=0.0, sample_interval_s=DT_S, kind="AR", ar=(0.6, -0.2), ma=(), ar_std=(0.0, 0.0), ma_std=(),
        sigma2=0.7, aic=0.0, bic=0.0, method="given", noise_mean=0.0, noise_std=1e-5, measurement_noise_std=0.0)
    t = np.arange(30_000) * DT_S
    y = model.simulate(t, np.random.default_rng(1))
    np.testing.assert_array_equal(y, model.simulate(t, np.random.default_rng(1)))  # seeded, reproducible
    a = analyze_startup(t, y)
    m = a.model
    assert (m.p, m.q) == (2, 0)
    assert np.all(np.abs(np.asarray(m.ar) - (0.6, -0.2)) < 4 * np.asarray(m.ar_std))
    assert abs(m.trend["exp_tau_s"].value - 150.0) < 4 * m.trend["exp_tau_s"].std
    # stationary noise with the model's variance: sigma2/(1 - Σφρ) for AR(2), in volts
    rho1 = 0.6 / 1.2
    var_z = 0.7 / (1 - 0.6 * rho1 + 0.2 * (0.6 * rho1 + 0.2))
    assert np.var(y - model.trend_at(t)) == pytest.approx(var_z * 1e-10, rel=0.1)


def _e(v):
    return Estimate(v, 0.0)


def test_simulate_rejects_a_different_sample_interval():
    a = analyze_startup(*startup_trace(1000, 60.0, 1e-3, 0.0, [0.3], [], 1e-5, np.random.default_rng(0)))
    with pytest.raises(ValueError, match=r"equal the model's 0.5 s"):
        a.model.simulate(np.arange(100) * 0.1, np.random.default_rng(0))
    with pytest.raises(ValueError, match="already includes it"):
        a.model.simulate(np.arange(100) * 0.5, np.random.default_rng(0), measurement_noise=True)


def test_json_dict_has_issue_keys_equation_and_round_trips():
    a = analyze_startup(*startup_trace(3000, 100.0, 1e-3, 1e-8, [0.4], [], 1e-5, np.random.default_rng(9)))
    d = json.loads(json.dumps(a.to_dict(), allow_nan=False))
    for key in ("offset", "exp_amplitude", "exp_tau_s", "linear_slope_per_s"):
        assert set(d["trend"][key]) == {"value", "std"}
    assert set(d["model"]) >= {"kind", "p", "q", "ar", "ma", "sigma2", "aic", "bic", "method"}
    assert d["model"]["kind"] in ("AR", "MA", "ARMA")
    assert set(d["denoise"]) >= {"wavelet", "level", "sigma", "threshold"}
    assert isinstance(d["outliers"]["count"], int) and 0 <= d["ljung_box_p"] <= 1
    assert {row["p"] for row in d["order_selection"]["table"]} == set(range(11))
    again = StartupModel.from_dict(d)
    assert again.equation() == a.model.equation() == d["equation"]
    assert "exp(−u/(" in d["equation"] and f"{a.model.ar[0]:.4f}" in d["equation"]


def test_document_a_literal_route_models_a_smoothing_artefact_on_white_noise():
    # pins the reason the default models raw − trend (see bench.analysis.startup._pipeline)
    t, y = startup_trace(3600, 300.0, 2e-4, 1e-9, [], [], 1e-5, np.random.default_rng(1))
    literal = analyze_startup(t, y, noise_source="denoised", trend_source="denoised")
    default = analyze_startup(t, y)
    assert literal.settings["noise_source"] == "denoised" and literal.model.noise_source == "denoised"
    poles = np.abs(np.roots(np.r_[1.0, -np.asarray(literal.model.ar)]))
    assert literal.model.p >= 1 and poles.max() > 0.95  # near-unit-root AR for white sensor noise
    assert literal.ljung_box.p_value < 1e-6 and any("Ljung–Box" in n for n in literal.notes)
    assert (default.model.p, default.model.q) == (0, 0) and default.ljung_box.p_value > 1e-3
    assert not default.notes
    assert literal.model.measurement_noise_std == pytest.approx(1e-5, rel=0.1)
    # with the removed white noise added back, a literal-route trace has the measured spread
    sim = literal.model.simulate(t, np.random.default_rng(2), measurement_noise=True)
    assert np.std(sim - literal.model.trend_at(t)) == pytest.approx(np.std(y - literal.trend.fitted), rel=0.15)


@pytest.mark.parametrize(
    ("t", "y", "kwargs", "match"),
    [
        (np.arange(10.0), np.ones(10), {}, "at least 64"),
        (np.arange(100.0), np.r_[np.ones(99), np.nan], {}, r"non-finite values \(first at sample index 99\)"),
        (np.r_[np.arange(50.0), np.arange(50.0) + 49], np.ones(100), {}, "not strictly increasing at sample index 50"),
        (np.r_[np.arange(50.0), 50.5 + np.arange(50.0)], np.ones(100), {}, r"deviates 50.000% .*allowed ≤ 1.000%"),
        (np.arange(100.0), np.sin(np.arange(100.0)), {"max_ar_order": 30}, r"max_ar_order = 30 .*allowed 0..10"),
        (np.arange(100.0), np.sin(np.arange(100.0)), {"criterion": "hqic"}, "criterion = 'hqic' is not one of"),
    ],
)
def test_bad_input_names_the_problem(t, y, kwargs, match):
    with pytest.raises(ValueError, match=match):
        analyze_startup(t, y, **kwargs)


def test_validate_trace_returns_the_sampling_interval():
    assert validate_trace(np.arange(100) * 0.25 + 3, np.zeros(100)) == pytest.approx(0.25)


def _trace(n=3000, dt=0.1):
    return np.arange(n) * dt


@pytest.mark.parametrize("y,fragment", [
    (lambda t: np.ones_like(t), "the signal is constant"),
    (lambda t: 1e200 * (1 + 0.1 * np.exp(-t / 20)) + 1e198 * np.sin(t), "outside the analysable range"),
    (lambda t: 1e-300 * (1 + 0.1 * np.exp(-t / 20)), "outside the analysable range"),
    (lambda t: 1 + 0.5 * np.exp(-t / 20) + 1e-4 * t, "no noise left after the trend"),
])
def test_degenerate_traces_are_refused_with_the_reason(y, fragment):
    t = _trace()
    with pytest.raises(ValueError, match=fragment):
        analyze_startup(t, y(t))


def test_a_trace_without_a_transient_says_so():
    t = _trace()
    y = 1 + 1e-3 * t + np.random.default_rng(4).normal(0, 0.01, t.size)
    notes = " ".join(analyze_startup(t, y).notes)
    assert "exponential term is not significant" in notes


def test_too_many_arma_parameters_for_the_samples_is_refused():
    t = _trace(100)
    y = 1 + np.random.default_rng(1).normal(0, 0.01, t.size)
    with pytest.raises(ValueError, match="10 samples per parameter"):
        analyze_startup(t, y, max_arma_order=6)
