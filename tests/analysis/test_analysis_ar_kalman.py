"""Document C steps 2–4: per-IMF tests against statsmodels, AR order recovery, the Kalman
filter (exact vs steady state, estimate vs truth) and the whole vibration pipeline."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.signal import lfilter
from statsmodels.regression.linear_model import yule_walker as sm_yule_walker
from statsmodels.tsa.stattools import adfuller, kpss

from bench.analysis.vibration import analyze_vibration
from bench.analysis.vibration._ar_kalman import ar_predict, companion, kalman_ar_fit
from bench.analysis.vibration._ar_models import adf_constant, kpss_level, model_imf, whiteness

FS_HZ = 2000.0


def ar_process(phi, n: int, rng: np.random.Generator, sigma: float = 1.0) -> np.ndarray:
    burn = 500
    return lfilter([1.0], np.r_[1.0, -np.asarray(phi)], rng.normal(0, sigma, n + burn))[burn:]


def stable_ar(rng: np.random.Generator, p: int) -> np.ndarray:
    """AR coefficients from real poles drawn in 0.3 ≤ |z| ≤ 0.85 (well inside the unit circle)."""
    poles = rng.uniform(0.3, 0.85, p) * rng.choice([-1.0, 1.0], p)
    return -np.poly(poles)[1:]


def document_c_like(n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """AR noise + white measurement noise + periodic term + linear trend, in °/s."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS_HZ
    x = ar_process([0.6, -0.2], n, rng, 0.003)
    periodic = 0.004 * np.sin(2 * np.pi * 2.5 * t + 0.3)
    return t, x + rng.normal(0, 0.002, n) + periodic + 2e-4 * t + 0.01, periodic


# --------------------------------------------------------------------------- tests of one IMF


@settings(max_examples=12, deadline=None)
@given(st.integers(0, 2**31), st.integers(1, 6), st.integers(300, 3000))
def test_yule_walker_equals_statsmodels(seed, p, n):
    rng = np.random.default_rng(seed)
    x = ar_process(stable_ar(rng, p), n, rng) + rng.normal()
    model = model_imf(x, p_max=min(8, n // 40), lb_lags=10)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        rho, sigma = sm_yule_walker(x, order=model.p, method="mle", demean=True)
    np.testing.assert_allclose(model.ar, rho, rtol=0, atol=1e-10)
    assert model.sigma2 == pytest.approx(sigma**2, rel=1e-10)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_adf_and_kpss_equal_statsmodels(seed):
    rng = np.random.default_rng(seed)
    x = ar_process([1.5, -0.7], 1500, rng) + 0.3
    if seed == 2:
        x = np.cumsum(rng.normal(size=1500))  # a unit root: ADF must not reject, KPSS must
    ours = adf_constant(x, 6)
    stat, pval, *_ = adfuller(x, maxlag=6, autolag=None, regression="c", result_object=False)
    assert ours.statistic == pytest.approx(stat, rel=1e-10)
    assert ours.p_value == pytest.approx(pval, rel=1e-8, abs=1e-300)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # statsmodels' look-up-table boundary warning
        kstat, kp, klags, _ = kpss(x, regression="c", nlags="auto", result_object=False)
    k = kpss_level(x)
    assert (k.statistic, k.p_value, k.lags) == (pytest.approx(kstat, rel=1e-10), pytest.approx(kp), klags)
    if seed == 2:
        assert ours.p_value > 0.05 and k.p_value <= 0.05


def test_whiteness_criteria():
    rng = np.random.default_rng(4)
    white = whiteness(rng.normal(size=4000), 20)
    coloured = whiteness(ar_process([0.5], 4000, rng), 20)
    assert white.white and white.ljung_box_p > 0.01
    assert not coloured.white and coloured.ljung_box_p < 1e-6 and coloured.acf_outside > 0.05


def test_order_selection_recovers_simulated_order():
    """BIC picks the simulated order in most of 24 draws (p = 1..4, n = 4000)."""
    rng = np.random.default_rng(12)
    hits = 0
    for trial in range(24):
        p = 1 + trial % 4
        phi = stable_ar(rng, p)
        model = model_imf(ar_process(phi, 4000, rng), p_max=10)
        hits += model.bic_order == p
        assert model.bic_order <= model.aic_order or model.aic_order >= p  # BIC is the more parsimonious
    assert hits >= 20


# --------------------------------------------------------------------------- Kalman filter


def test_companion_matrix():
    np.testing.assert_array_equal(companion([0.5, -0.2, 0.1]), [[0.5, -0.2, 0.1], [1, 0, 0], [0, 1, 0]])


@settings(max_examples=10, deadline=None)
@given(st.integers(0, 2**31), st.integers(1, 8), st.floats(0.05, 20.0))
def test_steady_state_filter_equals_exact_recursion(seed, p, r_ratio):
    rng = np.random.default_rng(seed)
    phi = stable_ar(rng, p)
    z = ar_process(phi, 3000, rng) + rng.normal(0, 0.5, 3000) + 1.0
    fast = kalman_ar_fit(z, phi, 1.0, r_ratio=r_ratio)
    slow = kalman_ar_fit(z, phi, 1.0, r_ratio=r_ratio, steady_state=False)
    assert fast.steady_from < z.size  # the gain froze: the IIR path ran
    np.testing.assert_allclose(fast.filtered, slow.filtered, rtol=0, atol=1e-10)
    np.testing.assert_array_equal(fast.filtered[:p], z[:p])  # X0 = the first p samples


def test_kalman_estimate_is_closer_to_the_truth():
    """With R the true measurement-noise variance, x̂(n|n) beats both the raw samples and the AR prediction."""
    rng = np.random.default_rng(8)
    phi = np.array([1.2, -0.5, 0.1])
    truth = ar_process(phi, 20000, rng)
    z = truth + rng.normal(0, 0.8, truth.size)
    fit = kalman_ar_fit(z, phi, 1.0, r=0.64, mean=0.0)
    pred = ar_predict(z, phi, 0.0)
    s = slice(3, None)
    err_k = np.std(fit.filtered[s] - truth[s])
    assert err_k < 0.9 * np.std(z[s] - truth[s])
    assert err_k < 0.6 * np.std(pred[s] - truth[s])


def test_kalman_fit_error_is_scaled_innovation():
    """In steady state z − x̂(n|n) = (1 − K₁)·innovation, so its std is below the AR residual's."""
    rng = np.random.default_rng(9)
    phi = np.array([0.7, -0.3])
    z = ar_process(phi, 5000, rng)
    fit = kalman_ar_fit(z, phi, 1.0)
    pred = ar_predict(z, phi, float(z.mean()))
    s = slice(fit.steady_from + 50, None)
    ratio = np.std(z[s] - fit.filtered[s]) / np.std(z[s] - pred[s])
    assert 0.2 < ratio < 1 - fit.gain[0] + 0.05


# --------------------------------------------------------------------------- the whole method


@pytest.fixture(scope="module")
def vibration_analysis():
    t, y, _ = document_c_like(8000, 3)
    return analyze_vibration(t, y)


def test_kalman_fit_beats_ar_fit_on_document_c_like_data(vibration_analysis):
    a = vibration_analysis
    assert a.error_ar_kalman.std < a.error_ar.std
    assert 0.3 < a.std_ratio < 0.7  # Document C: 0.44 with R = σ_a²
    assert abs(a.error_ar.mean) < 0.1 * a.error_ar.std and abs(a.error_ar_kalman.mean) < 0.1 * a.error_ar_kalman.std
    periodic = [c for c in a.terms.components if c.kind == "periodic"]
    assert len(periodic) == 1 and periodic[0].frequency_hz == pytest.approx(2.5, rel=0.03)
    assert a.terms.components[-1].kind == "trend"
    # the two fits and the non-random terms share the decomposition exactly
    imfs = a.decomposition.imfs
    np.testing.assert_allclose(a.terms.signal + imfs[[i - 1 for i in a.terms.random_indices]].sum(axis=0), a.y,
                               atol=1e-12)


def test_to_dict_is_json_safe_with_the_issue_keys(vibration_analysis):
    d = json.loads(json.dumps(vibration_analysis.to_dict(), allow_nan=False))
    assert d["imfs"] == vibration_analysis.decomposition.n_imfs
    assert d["nonrandom"] and all({"component", "kind", "frequency_hz", "amplitude", "reason"} <= set(c)
                                  for c in d["nonrandom"])
    for m in d["imf_models"]:
        assert {"index", "p", "ar", "white_residual_p", "stationary_p", "aic_order", "bic_order"} <= set(m)
        assert len(m["ar"]) == m["p"] and 0 <= m["white_residual_p"] <= 1
    for fit in ("ar", "ar_kalman"):
        assert set(d["fit_error"][fit]) >= {"mean", "std"}


def test_non_uniform_sampling_is_refused():
    t, y, _ = document_c_like(1000, 1)
    t = t.copy()
    t[500:] += 0.01  # a gap
    with pytest.raises(ValueError, match="not uniform"):
        analyze_vibration(t, y)
    with pytest.raises(ValueError, match="r_ratio"):
        analyze_vibration(*document_c_like(1000, 1)[:2], r_ratio=0)
