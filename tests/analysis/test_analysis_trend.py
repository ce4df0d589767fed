"""Start-up trend fit: recovery of drawn truth within the stated standard errors."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.signal import lfilter

from bench.analysis.startup import fit_trend, wavelet_denoise

DURATION_S = 6 * 1800.0  # six of the slowest time constants: the transient always settles


def ar1_noise(n: int, phi: float, sigma: float, rng: np.random.Generator) -> np.ndarray:
    """AR(1) noise with marginal std ``sigma`` (stationary start)."""
    return lfilter([1.0], [1.0, -phi], rng.normal(0, sigma * np.sqrt(1 - phi**2), n + 500))[500:]


def trace(n, tau, amp, slope, phi, sigma, rng, t0=100.0):
    t = t0 + np.arange(n) * DURATION_S / n
    y = 2.5 + amp * np.exp(-(t - t0) / tau) + slope * (t - t0) + ar1_noise(n, phi, sigma, rng)
    return t, y


truth = st.fixed_dictionaries({
    "tau": st.floats(np.log(30), np.log(1800)).map(np.exp),   # 30 s to 30 min
    "snr": st.floats(20, 500),                                # |a| / noise std
    "sign": st.sampled_from([-1.0, 1.0]),
    "slope": st.floats(-1e-3, 1e-3),
    "phi": st.floats(-0.5, 0.9),
    "sigma": st.sampled_from([1e-6, 1e-3, 1.0]),              # several noise levels (units of y)
    "seed": st.integers(0, 2**32 - 1),
})


@settings(max_examples=15, deadline=None, derandomize=True)
@given(truth)
def test_drawn_trend_recovered_within_4_standard_errors(d):
    amp = d["sign"] * d["snr"] * d["sigma"]
    slope = d["slope"] * d["sigma"]
    t, y = trace(2048, d["tau"], amp, slope, d["phi"], d["sigma"], np.random.default_rng(d["seed"]))
    fit = fit_trend(t, y)
    assert fit.kind == "exp1"  # one exponential in, one out: the BIC margin holds
    for est, true in ((fit.exp_tau_s, d["tau"]), (fit.exp_amplitude, amp),
                      (fit.linear_slope_per_s, slope), (fit.offset, 2.5)):
        assert abs(est.value - true) < 4 * est.std, (est, true)
    assert fit.t0_s == 100.0
    np.testing.assert_allclose(fit.evaluate(t), fit.fitted, rtol=1e-12)


def test_tau_inside_3_standard_errors_in_95_percent_of_draws():
    rng = np.random.default_rng(42)
    inside = 0
    draws = 40
    for _ in range(draws):
        tau = float(np.exp(rng.uniform(np.log(30), np.log(1800))))
        sigma = float(rng.choice([1e-5, 1.0]))
        amp = float(rng.choice([-1, 1]) * rng.uniform(10, 200) * sigma)
        t, y = trace(1024, tau, amp, 1e-4 * sigma, float(rng.uniform(-0.5, 0.9)), sigma, rng)
        fit = fit_trend(t, y, allow_two_exponentials=False)
        inside += abs(fit.exp_tau_s.value - tau) < 3 * fit.exp_tau_s.std
    assert inside >= 0.95 * draws


def test_standard_errors_allow_for_coloured_noise():
    # strongly correlated noise: white-noise errors would be ~4x too small and miss the truth
    rng = np.random.default_rng(8)
    z = []
    for _ in range(12):
        t, y = trace(2048, 600.0, 5.0, 0.0, 0.9, 1.0, rng)
        fit = fit_trend(t, y, allow_two_exponentials=False)
        assert fit.noise_ar and fit.noise_ar[0] == pytest.approx(0.9, abs=0.05)
        z.append((fit.exp_tau_s.value - 600.0) / fit.exp_tau_s.std)
    assert 0.4 < np.std(z) < 1.8  # calibrated, neither inflated nor ~4x too small


def test_two_exponentials_kept_when_the_data_demand_them():
    rng = np.random.default_rng(3)
    t = np.arange(4000) * 2.0
    y = 1.0 + 0.5 * np.exp(-t / 40.0) + 0.5 * np.exp(-t / 900.0) + 2e-6 * t + rng.normal(0, 0.005, t.size)
    fit = fit_trend(t, y)
    assert fit.kind == "exp2" and fit.bic_exp2 < fit.bic_exp1 - 10
    assert fit.exp_tau_s.value < fit.exp2_tau_s.value  # faster one first
    for est, true in ((fit.exp_tau_s, 40.0), (fit.exp2_tau_s, 900.0), (fit.exp_amplitude, 0.5),
                      (fit.exp2_amplitude, 0.5), (fit.linear_slope_per_s, 2e-6)):
        assert abs(est.value - true) < 4 * est.std
    assert fit.covariance.shape == (6, 6)
    assert set(fit.to_dict()) >= {"exp2_amplitude", "exp2_tau_s", "offset", "exp_tau_s"}


def test_no_transient_gives_uninformative_tau_not_a_crash():
    rng = np.random.default_rng(4)
    t = np.arange(500) * 1.0
    fit = fit_trend(t, 3.0 + 1e-3 * t + rng.normal(0, 0.01, t.size))
    assert abs(fit.linear_slope_per_s.value - 1e-3) < 4 * fit.linear_slope_per_s.std
    assert not abs(fit.exp_amplitude.value) > 3 * fit.exp_amplitude.std  # no significant transient


def test_fitting_the_denoised_trace_biases_tau_which_is_why_raw_is_the_default():
    # Document A's literal order: soft thresholding shrinks the transient's coefficients by λ
    rng = np.random.default_rng(12)
    z_raw, z_dn = [], []
    for _ in range(8):
        t, y = trace(2048, 300.0, 30.0, 0.0, 0.0, 1.0, rng)
        for src, out in ((y, z_raw), (wavelet_denoise(y).denoised, z_dn)):
            fit = fit_trend(t, src, allow_two_exponentials=False)
            out.append((fit.exp_tau_s.value - 300.0) / fit.exp_tau_s.std)
    assert np.all(np.abs(z_raw) < 3)
    assert np.mean(np.abs(z_dn)) > 2 * np.mean(np.abs(z_raw))


@pytest.mark.parametrize(
    ("t", "y", "match"),
    [
        (np.arange(10.0), np.ones(10), "at least 32"),
        (np.arange(50.0), np.ones(49), "equal length"),
        (np.r_[np.arange(49.0), 10.0], np.ones(50), "strictly increasing"),
        (np.arange(50.0), np.r_[np.ones(49), np.nan], "finite"),
        # squared residuals overflow at every τ of the scan: a clear error, not a TypeError
        (np.arange(100.0), 1e200 * (1.0 + np.exp(-np.arange(100.0) / 10.0)), "rescale"),
    ],
)
def test_bad_input(t, y, match):
    with pytest.raises(ValueError, match=match):
        fit_trend(t, y)


def test_kind_and_second_exponential_agree():
    """A TrendFit whose ``kind`` disagrees with its exp2 fields is refused at construction."""
    t = np.arange(200.0)
    fit = fit_trend(t, 1.0 + np.exp(-t / 20.0) + 1e-3 * np.cos(t), allow_two_exponentials=False)
    assert fit.kind == "exp1"
    with pytest.raises(ValueError, match="both set"):
        dataclasses.replace(fit, kind="exp2")
    with pytest.raises(ValueError, match="both None"):
        dataclasses.replace(fit, exp2_amplitude=fit.exp_amplitude, exp2_tau_s=fit.exp_tau_s)


def test_long_trace_two_exponential_screen():
    """Past 4·16384 samples the two-exponential fit is screened on block means: a real second
    exponential must still be found, and a single one must not trigger the full fit."""
    rng = np.random.default_rng(31)
    t = np.arange(80_000) * 0.1
    noise = ar1_noise(t.size, 0.8, 0.01, rng)
    y2 = 1.0 + 0.2 * np.exp(-t / 30.0) + 0.2 * np.exp(-t / 1500.0) + 1e-6 * t + noise
    fit2 = fit_trend(t, y2)
    assert fit2.kind == "exp2" and fit2.bic_exp2 < fit2.bic_exp1 - 10
    assert abs(fit2.exp_tau_s.value - 30.0) < 4 * fit2.exp_tau_s.std
    assert abs(fit2.exp2_tau_s.value - 1500.0) < 4 * fit2.exp2_tau_s.std
    y1 = 1.0 + 0.2 * np.exp(-t / 300.0) + 1e-6 * t + noise
    fit1 = fit_trend(t, y1)
    assert fit1.kind == "exp1" and fit1.bic_exp2 is None  # screened out, not fitted
    assert abs(fit1.exp_tau_s.value - 300.0) < 4 * fit1.exp_tau_s.std
