"""Rate-table calibration: exact recovery on the gyro model, statsmodels WLS, coverage."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import statsmodels.api as sm
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.analysis.ratetable._fit import (
    EARTH_RATE_DPS,
    earth_rate_vertical_dps,
    fit_rate_table,
    rate_plan,
    whole_revolution_duration_s,
)


def gyro_output(rate_dps, eps, asym, cubic, bias_dps, fs_dps, sf_nominal=1.0):
    """The gyro model: SF_nom·(B + ω(1 + ε + A/2·sign ω) + n·FS·(ω/FS)³)."""
    w = np.asarray(rate_dps, dtype=float)
    return sf_nominal * (bias_dps + w * (1 + eps + asym / 2 * np.sign(w)) + cubic * fs_dps * (w / fs_dps) ** 3)


def input_rates(fs_dps, n_per_sign, latitude_deg):
    return rate_plan(fs_dps, n_per_sign) + earth_rate_vertical_dps(latitude_deg)


def reference_line(w, y, sigma):
    """Independent WLS (numpy lstsq on the whitened system): (intercept, slope), residuals."""
    x = np.column_stack([np.ones_like(w), w])
    beta = np.linalg.lstsq(x / sigma[:, None], y / sigma, rcond=None)[0]
    return beta, y - x @ beta


def reference_asymmetry_ppm(w, y, sigma, sf_nominal):
    x = np.column_stack([np.ones_like(w), w, np.abs(w)])
    beta = np.linalg.lstsq(x / sigma[:, None], y / sigma, rcond=None)[0]
    return 1e6 * 2 * beta[2] / sf_nominal


ppm = st.floats(-1000, 1000).map(lambda v: v * 1e-6)
gyro = st.fixed_dictionaries({
    "eps": ppm, "asym": ppm, "cubic": ppm,
    "bias_dps": st.floats(-50, 50).map(lambda v: v / 3600),  # ±50 °/h
    "fs_dps": st.sampled_from([100.0, 300.0, 500.0, 1000.0]),
    "sf_nominal": st.sampled_from([1.0, 3600.0 / 4.85, 0.37]),  # °/s, pulses/s at 4.85″/pulse, volts
    "n_per_sign": st.integers(2, 10), "latitude_deg": st.floats(-80, 80),
})


def reference_line_with_asymmetry(w, y, sigma):
    x = np.column_stack([np.ones_like(w), w, np.abs(w)])
    coef = np.linalg.lstsq(x / sigma[:, None], y / sigma, rcond=None)[0]
    return coef, y - x @ coef


@settings(max_examples=60, deadline=None, derandomize=True)
@given(gyro)
def test_noiseless_fit_is_the_least_squares_line_of_the_model(g):
    w = input_rates(g["fs_dps"], g["n_per_sign"], g["latitude_deg"])
    y = gyro_output(w, g["eps"], g["asym"], g["cubic"], g["bias_dps"], g["fs_dps"], g["sf_nominal"])
    sigma = np.full(w.size, 1e-3 * g["sf_nominal"])
    r = fit_rate_table(w, y, sigma, full_scale_dps=g["fs_dps"], nominal_scale_factor=g["sf_nominal"])
    (b, sf), resid = reference_line(w, y, sigma)
    assert r.scale_factor.value == pytest.approx(sf, rel=1e-9)
    assert r.intercept.value == pytest.approx(b, rel=1e-9, abs=1e-12 * abs(sf) * g["fs_dps"])
    (b3, _, _), _ = reference_line_with_asymmetry(w, y, sigma)  # the bias is that model's intercept
    assert r.bias_dph.value == pytest.approx(3600 * b3 / g["sf_nominal"], rel=1e-9, abs=1e-9)
    nonlin_ppm = 1e6 * np.abs(resid).max() / abs(sf * g["fs_dps"])  # the definition, by hand
    assert r.nonlinearity_ppm.value == pytest.approx(nonlin_ppm, rel=1e-6, abs=1e-6)
    np.testing.assert_allclose(r.residuals_ppm_fs, 1e6 * resid / (sf * g["fs_dps"]), atol=1e-6)
    assert r.asymmetry_ppm.value == pytest.approx(
        reference_asymmetry_ppm(w, y, sigma, g["sf_nominal"]), abs=1e-6)


@settings(max_examples=60, deadline=None, derandomize=True)
@given(gyro)
def test_without_cubic_term_the_model_parameters_come_back(g):
    w = input_rates(g["fs_dps"], g["n_per_sign"], g["latitude_deg"])
    y = gyro_output(w, g["eps"], g["asym"], 0.0, g["bias_dps"], g["fs_dps"], g["sf_nominal"])
    r = fit_rate_table(w, y, np.ones(w.size), full_scale_dps=g["fs_dps"], nominal_scale_factor=g["sf_nominal"])
    assert r.asymmetry_ppm.value == pytest.approx(1e6 * g["asym"], abs=1e-6)
    assert r.scale_factor_positive.value == pytest.approx(g["sf_nominal"] * (1 + g["eps"] + g["asym"] / 2), rel=1e-9)
    assert r.scale_factor_negative.value == pytest.approx(g["sf_nominal"] * (1 + g["eps"] - g["asym"] / 2), rel=1e-9)
    assert r.bias_dph.value == pytest.approx(3600 * g["bias_dps"], rel=1e-9, abs=1e-9)  # any asymmetry
    if g["asym"] == 0.0:  # symmetric and linear: the line is the model itself
        assert r.scale_factor_error_ppm.value == pytest.approx(1e6 * g["eps"], abs=1e-6)
        assert r.nonlinearity_ppm.value < 1e-6


def test_linear_symmetric_gyro_exact():
    """A = n = 0 with drawn-like values: SF = SF_nom(1+ε), bias = B, to 1e-9 relative."""
    w = input_rates(400.0, 7, 48.0)
    y = gyro_output(w, 321e-6, 0.0, 0.0, 12.5 / 3600, 400.0, 3600 / 4.85)
    r = fit_rate_table(w, y, np.full(w.size, 0.1), full_scale_dps=400.0, nominal_scale_factor=3600 / 4.85)
    assert r.scale_factor.value == pytest.approx(3600 / 4.85 * (1 + 321e-6), rel=1e-9)
    assert r.bias_dph.value == pytest.approx(12.5, rel=1e-9)
    assert r.scale_factor_error_ppm.value == pytest.approx(321.0, abs=1e-6)


def test_fits_match_statsmodels_wls():
    rng = np.random.default_rng(4)
    w = input_rates(300.0, 8, 45.0)
    sigma = rng.uniform(0.5, 3.0, w.size) * 1e-4
    y = gyro_output(w, 200e-6, 150e-6, -300e-6, 5 / 3600, 300.0) + rng.normal(0, sigma)
    r = fit_rate_table(w, y, sigma, full_scale_dps=300.0)
    line = sm.WLS(y, sm.add_constant(w), weights=sigma**-2).fit(cov_type="fixed scale", cov_kwds={"scale": 1.0})
    np.testing.assert_allclose([r.intercept.value, r.scale_factor.value], line.params, rtol=1e-10)
    np.testing.assert_allclose([r.intercept.std, r.scale_factor.std], line.bse, rtol=1e-8)
    np.testing.assert_allclose(r.line_covariance, line.cov_params(), rtol=1e-8)
    np.testing.assert_allclose(r.residuals, line.resid, atol=1e-12)
    x3 = np.column_stack([np.ones_like(w), w, np.abs(w)])
    joint = sm.WLS(y, x3, weights=sigma**-2).fit(cov_type="fixed scale", cov_kwds={"scale": 1.0})
    assert r.asymmetry_ppm.value == pytest.approx(2e6 * joint.params[2], rel=1e-8)
    assert r.asymmetry_ppm.std == pytest.approx(2e6 * joint.bse[2], rel=1e-8)
    # Residual standard errors: σ_k²(1 − h_kk) with statsmodels' hat matrix of the whitened fit.
    whitened = sm.OLS(y / sigma, sm.add_constant(w) / sigma[:, None]).fit()
    hat = whitened.get_influence().hat_matrix_diag
    np.testing.assert_allclose(r.residual_std_ppm_fs,
                               1e6 * sigma * np.sqrt(1 - hat) / abs(r.scale_factor.value * 300.0), rtol=1e-8)


def noisy_runs(g, sigma_dps, draws, seed):
    """Yield (result, truths) over seeded noise draws; truths = the definitions on the noiseless model."""
    w = input_rates(g["fs_dps"], g["n_per_sign"], g["latitude_deg"])
    clean = gyro_output(w, g["eps"], g["asym"], g["cubic"], g["bias_dps"], g["fs_dps"], g["sf_nominal"])
    rng = np.random.default_rng(seed)
    sigma = g["sf_nominal"] * sigma_dps * rng.uniform(0.5, 2.0, w.size)  # unequal per rate
    (b, sf), resid = reference_line(w, clean, sigma)
    (b3, _, _), _ = reference_line_with_asymmetry(w, clean, sigma)  # the bias's model
    truth = {"scale_factor": sf, "bias_dph": 3600 * b3 / g["sf_nominal"],
             "asymmetry_ppm": reference_asymmetry_ppm(w, clean, sigma, g["sf_nominal"]),
             "nonlinearity_ppm": 1e6 * np.abs(resid).max() / abs(sf * g["fs_dps"])}
    for _ in range(draws):
        yield fit_rate_table(w, clean + rng.normal(0, sigma), sigma, full_scale_dps=g["fs_dps"],
                             nominal_scale_factor=g["sf_nominal"]), truth


@settings(max_examples=4, deadline=None, derandomize=True)
@given(gyro, st.sampled_from([1e-4, 1e-3, 1e-2]), st.integers(0, 2**32 - 1))
def test_truth_within_1_96_stated_errors_in_95_percent(g, sigma_dps, seed):
    """1000 seeded noise draws per drawn gyro: binomial sd 0.7 %, so 92-98 % is a 4σ band."""
    names = ("scale_factor", "bias_dph", "asymmetry_ppm")
    inside = dict.fromkeys(names, 0)
    for r, truth in noisy_runs(g, sigma_dps, 1000, seed):
        for name in names:
            est = getattr(r, name)
            inside[name] += abs(est.value - truth[name]) <= 1.96 * est.std
    for name, k in inside.items():
        assert 0.92 <= k / 1000 <= 0.98, (name, k)


def test_clear_nonlinearity_matches_truth_within_its_uncertainty():
    """500 ppm cubic against 1 ppm-of-FS noise: the argmax is stable and the stated error covers."""
    g = {"eps": 100e-6, "asym": 50e-6, "cubic": 500e-6, "bias_dps": 3 / 3600, "fs_dps": 500.0,
         "sf_nominal": 1.0, "n_per_sign": 8, "latitude_deg": 52.0}
    runs = list(noisy_runs(g, 500.0 * 1e-6, 1000, 9))
    hits = [abs(r.nonlinearity_ppm.value - t["nonlinearity_ppm"]) <= 1.96 * r.nonlinearity_ppm.std
            for r, t in runs]
    assert 0.92 <= np.mean(hits) <= 0.98
    r, truth = runs[0]
    assert truth["nonlinearity_ppm"] > 50 * r.nonlinearity_ppm.std  # the regime the claim is about


def test_to_dict_is_json():
    w = input_rates(100.0, 3, 45.0)
    r = fit_rate_table(w, gyro_output(w, 1e-4, 1e-4, 1e-4, 1e-3, 100.0), np.full(w.size, 1e-5), full_scale_dps=100.0)
    d = json.loads(json.dumps(r.to_dict(), allow_nan=False))
    assert d["asymmetry_ppm"]["std"] > 0 and len(d["residuals_ppm_fs"]) == 6 and d["dof"] == 4


def test_rate_plan_interleaves_log_spaced_rates():
    plan = rate_plan(300.0, 5, min_fraction=0.01)
    assert plan.tolist()[:2] == [3.0, -3.0] and plan.tolist()[-2:] == [300.0, -300.0]
    mags = plan[::2]
    np.testing.assert_allclose(mags[1:] / mags[:-1], 10 ** 0.5, rtol=1e-12)
    np.testing.assert_array_equal(plan[1::2], -mags)
    assert rate_plan(50.0, 1).tolist() == [50.0, -50.0]
    below = rate_plan(490.0, 4, min_fraction=0.01, max_fraction=0.99)
    assert below[0] == pytest.approx(4.9, rel=1e-12) and below[-2] == pytest.approx(485.1, rel=1e-15)


@settings(max_examples=200, deadline=None, derandomize=True)
@given(st.floats(1e-3, 1e3) | st.floats(-1e3, -1e-3), st.floats(1e-3, 1e5))
def test_whole_revolutions_is_the_shortest_long_enough(rate, min_s):
    t = whole_revolution_duration_s(rate, min_s)
    period = 360.0 / abs(rate)
    revs = t / period
    assert abs(revs - round(revs)) < 1e-9 and round(revs) >= 1
    assert t >= min_s or math.isclose(t, min_s, rel_tol=1e-12)
    assert round(revs) == 1 or (round(revs) - 1) * period < min_s


def test_whole_revolution_exact_cases():
    assert whole_revolution_duration_s(10.0, 36.0) == 36.0
    assert whole_revolution_duration_s(-10.0, 37.0) == 72.0
    assert whole_revolution_duration_s(100.0, 1.0) == 3.6


def test_earth_rate():
    assert earth_rate_vertical_dps(90.0) * 3600 == pytest.approx(15.041, abs=1e-3)
    assert earth_rate_vertical_dps(-30.0) == pytest.approx(-EARTH_RATE_DPS / 2, rel=1e-12)


W = np.array([-10.0, 0.0, 10.0, 100.0])


@pytest.mark.parametrize("call, words", [
    (lambda: fit_rate_table(W, W, np.ones(4), full_scale_dps=50.0), "beyond the allowed range"),
    (lambda: fit_rate_table(W, W, np.ones(4), full_scale_dps=-1.0), "full_scale_dps=-1.0"),
    (lambda: fit_rate_table(abs(W), W, np.ones(4), full_scale_dps=100.0), "positive and negative"),
    (lambda: fit_rate_table(W, W[:3], np.ones(4), full_scale_dps=100.0), "output must be finite"),
    (lambda: fit_rate_table(W, W, np.zeros(4), full_scale_dps=100.0), "output_sigma"),
    (lambda: fit_rate_table(W[:2], W[:2], np.ones(2), full_scale_dps=100.0), "≥ 3 rates"),
    (lambda: fit_rate_table([-10.0, 10.0, 10.0], [-10.0, 10.0, 10.0], np.ones(3), full_scale_dps=100.0),
     "two magnitudes"),
    (lambda: fit_rate_table(W, W * 500, np.ones(4), full_scale_dps=100.0), "nominal_scale_factor=1.0"),
    (lambda: fit_rate_table(W, W, np.ones(4), full_scale_dps=100.0, nominal_scale_factor=0.0),
     "nominal_scale_factor=0.0"),
    (lambda: rate_plan(100.0, 0), "n_per_sign=0"),
    (lambda: rate_plan(100.0, 3, min_fraction=1.5), "min_fraction=1.5"),
    (lambda: rate_plan(100.0, 3, max_fraction=1.2), "max_fraction=1.2"),
    (lambda: whole_revolution_duration_s(0.0, 10.0), "rate_dps=0.0"),
    (lambda: whole_revolution_duration_s(10.0, -1.0), "min_duration_s=-1.0"),
    (lambda: earth_rate_vertical_dps(91.0), "latitude_deg=91.0"),
])
def test_bad_input_raises_value_error_naming_it(call, words):
    with pytest.raises(ValueError) as err:
        call()
    assert words in str(err.value)
