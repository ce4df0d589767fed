"""Document B's sequential Kalman fusion: models, discretisation, FRF fit, filters, metrics,
and :func:`analyze_fusion` (every method tuned on the first part, judged on the rest).

Synthetic data: a multi-tone true rate 0.1 Hz – 1 kHz (1 dps per tone) at 4 kHz; the HF
sensor is a first-order high-pass at 2 Hz plus white noise (σ 0.02 dps); the LF sensor a
first-order low-pass at 30 Hz, 0.2 ms late, plus white noise (σ 0.01 dps) and a 0.01 dps
bias.  Sensor outputs are computed per tone from the exact frequency response.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad_vec
from scipy.linalg import expm
from scipy.signal import cont2discrete

import bench.analysis.fusion._sequential as fu
from bench.analysis.fusion import (
    BASELINES,
    METHODS,
    AdaptiveNoise,
    FusionModel,
    FusionParams,
    SensorModel,
    analyze_fusion,
    fit_transfer_function,
)
from bench.analysis.fusion._metrics import detect_tones, nis_check, sine_phasors

FS_HZ = 4000.0
TONES_HZ = np.array([0.1, 0.3, 1.0, 3.0, 10.0, 30.0, 100.0, 300.0, 1000.0])
HF = SensorModel("highpass", 1, 2.0, 1.0)
LF = SensorModel("lowpass", 1, 30.0, 1.0)


def synth(seed=0, duration_s=10.0, hf_sigma=0.02, lf_sigma=0.01, bias=0.01, lf_delay_s=2e-4, tones_hz=TONES_HZ):
    rng = np.random.default_rng(seed)
    t = np.arange(int(duration_s * FS_HZ)) / FS_HZ
    phase = rng.uniform(0, 2 * np.pi, TONES_HZ.size)[:len(tones_hz)]

    def through(model, delay_s):
        g = model.response(tones_hz) * np.exp(-2j * np.pi * tones_hz * delay_s)
        return np.sum(np.abs(g) * np.sin(2 * np.pi * np.outer(t, tones_hz) + phase + np.angle(g)), axis=1)

    ref = np.sum(np.sin(2 * np.pi * np.outer(t, tones_hz) + phase), axis=1)
    hf = through(HF, 0.0) + hf_sigma * rng.normal(size=t.size)
    lf = through(LF, lf_delay_s) + lf_sigma * rng.normal(size=t.size) + bias
    return t, hf, lf, ref


@pytest.fixture(scope="module")
def analysis():
    # from 1 Hz (the judged 60 % of 12 s holds 7 periods of the lowest tone) to 300 Hz (fs/13)
    t, hf, lf, ref = synth(duration_s=12.0, tones_hz=TONES_HZ[2:-1])
    return analyze_fusion(t, hf, lf, ref, FS_HZ, tones_hz=TONES_HZ[2:-1], settle_s=0.5)


def test_every_method_is_judged_and_the_recommended_beats_each_sensor_and_the_complementary_filter(analysis):
    rms = analysis.rms_error
    assert set(rms) == set(METHODS)
    best = analysis.recommended
    assert best in METHODS and rms[best] < 0.05 * min(rms["hf"], rms["lf"])  # neither sensor covers the band
    assert rms[best] <= rms["complementary"]
    # Document B claims better than fixed-R; measured here: equal within ±2 % (noise-limited data)
    assert rms["fused"] == pytest.approx(rms["fixed_r_kf"], rel=0.02)
    # the noise floor: the HF sensor's white noise passes to ~1 kHz, the LF bias at DC
    assert 0.01 < rms[best] < 0.04
    # the recommendation follows its rule: among those no worse in RMS than the baselines, the lowest
    # RMS within 2σ of the excess, else within 2σ of the better sensor's own error
    j = analysis.judgement
    eligible = [k for k in METHODS if rms[k] <= min(rms[b] for b in BASELINES)]
    for tier in (j.feasible, j.feasible_sensor):
        ok = [k for k in eligible if tier[k]]
        if ok:
            assert best == min(ok, key=rms.get)
            break


def test_the_complementary_kalman_filter_does_not_lag_the_top_of_the_band(analysis):
    j = analysis.judgement
    top = int(np.argmax(j.tones_hz))
    for method in ("complementary_kf", "complementary_smoother"):
        # as good as the HF sensor alone where it is the better sensor, within 2σ and the fitted
        # models' own error (their gain is known to ~1e-4 from the tuning part: 0.01 pp)
        assert j.excess_pct[method][top] <= 2 * j.excess_std_pct[method][top] + 0.01
        assert abs(j.phase_error_deg[method][top]) < 0.05
    # Document B's random-walk rate model lags there
    assert j.excess_pct["fused"][top] > max(0.05, 10 * j.excess_std_pct["fused"][top])


def test_fused_amplitude_no_worse_than_the_better_sensor_at_every_tone(analysis):
    amp = analysis.judgement.amplitude_error_pct
    better = np.minimum(np.abs(amp["hf"]), np.abs(amp["lf"]))
    for method in ("fused", "complementary_kf", "complementary_smoother"):
        assert np.all(np.abs(amp[method]) <= np.maximum(better, 1.5))
        assert np.all(np.abs(analysis.judgement.phase_error_deg[method]) < 1.0)
    assert np.abs(amp["hf"][0]) > 40 and np.abs(amp["lf"][-1]) > 90  # each alone loses one end of the band


def test_fitted_models_alignment_and_to_dict_are_json_safe(analysis):
    doc = analysis.to_dict()
    json.dumps(doc, allow_nan=False)
    assert doc["model"]["hf"]["corner_hz"] == pytest.approx(2.0, rel=0.01)
    assert doc["alignment"]["lf_fit"]["delay_s"] == pytest.approx(2e-4, abs=2e-5)  # the LF's 0.2 ms, removed
    assert doc["rms_error"]["fused"] == analysis.rms_error["fused"]
    assert doc["recommended"] == analysis.recommended and set(doc["methods"]) == set(METHODS)
    assert len(doc["amplitude_error_pct"]["fused"]) == TONES_HZ.size - 3
    lo, hi = doc["r_range"]["hf"]
    p = analysis.params.hf_noise
    assert p.r_lower <= lo <= hi <= p.r_upper
    assert sum(doc["r_interval_fraction"]["lf"]) == pytest.approx(1.0)
    assert not doc["nis"]["fused"]["diverged"]
    # the complementary filter's noise came from the data: near the truth (σ 0.02 and 0.01)
    assert doc["complementary_noise"]["hf_var"] == pytest.approx(0.02 ** 2, rel=0.3)
    assert doc["complementary_noise"]["lf_var"] == pytest.approx(0.01 ** 2, rel=0.3)


def test_without_a_reference_the_smoother_is_recommended_and_nothing_is_judged():
    t, hf, lf, _ = synth(duration_s=3.0, lf_delay_s=0.0)
    a = analyze_fusion(t, hf, lf, None, FS_HZ, hf_model=HF, lf_model=LF)
    assert a.judgement is None and a.rms_error is None and a.tune_samples == 0
    assert a.recommended == "complementary_smoother" and a.recommended_rate.size == t.size
    json.dumps(a.to_dict(), allow_nan=False)


def test_the_judged_part_must_hold_three_periods_of_the_lowest_tone():
    t, hf, lf, ref = synth(duration_s=4.0)
    with pytest.raises(ValueError, match="3 periods"):
        analyze_fusion(t, hf, lf, ref, FS_HZ, tones_hz=TONES_HZ, hf_model=HF, lf_model=LF)
    with pytest.raises(ValueError, match="tune_fraction"):
        analyze_fusion(t, hf, lf, ref, FS_HZ, tones_hz=TONES_HZ[3:], hf_model=HF, lf_model=LF, tune_fraction=0.9)


def test_euler_and_zoh_agree_for_small_steps_and_differ_for_large():
    model = FusionModel(HF, LF, q=100.0)
    a, b, _, _ = model.continuous()
    phi_zoh, _ = model.discretize(1e-5, "zoh")
    ref_phi = cont2discrete((a, b, np.eye(a.shape[0]), 0 * b), 1e-5, method="zoh")[0]
    np.testing.assert_allclose(phi_zoh, ref_phi, atol=1e-13)
    phi_euler, q_euler = model.discretize(1e-5, "euler")
    assert np.max(np.abs(phi_euler - phi_zoh)) < 1e-4  # O((A·Ts)²): ωl·Ts ≈ 0.002
    phi_e, _ = model.discretize(5e-3, "euler")  # ωl·Ts ≈ 0.94
    phi_z, _ = model.discretize(5e-3, "zoh")
    assert np.max(np.abs(phi_e - phi_z)) > 0.3
    assert max(abs(np.linalg.eigvals(phi_z))) <= 1 + 1e-12  # ZOH keeps the stable LF pole stable


def test_van_loan_q_matches_the_integral():
    model = FusionModel(HF, LF, q=3.0)
    ts = 2e-3
    a, b, _, _ = model.continuous()
    _, q = model.discretize(ts, "zoh")

    integral, _ = quad_vec(lambda s: expm(a * s) @ (3.0 * b @ b.T) @ expm(a * s).T, 0, ts)
    np.testing.assert_allclose(q, integral, rtol=1e-6, atol=1e-14)


@settings(max_examples=15, deadline=None)
@given(kind=st.sampled_from(["highpass", "lowpass"]), order=st.sampled_from([1, 2]),
       corner_hz=st.floats(1.0, 50.0), gain=st.floats(0.5, 2.0), seed=st.integers(0, 10_000))
def test_frf_fit_recovers_corner_and_gain_from_a_noisy_frf(kind, order, corner_hz, gain, seed):
    rng = np.random.default_rng(seed)
    f = np.logspace(-1, 3, 40)
    true = SensorModel(kind, order, corner_hz, gain, zeta=0.6)
    g = true.response(f) * (1 + 0.01 * (rng.normal(size=f.size) + 1j * rng.normal(size=f.size)))
    fit = fit_transfer_function(f, g, kind)
    assert fit.order == order
    assert fit.corner_hz == pytest.approx(corner_hz, rel=0.03)
    assert fit.gain == pytest.approx(gain, rel=0.03)
    assert fit.residual < 0.03


def test_frf_fit_rejects_bad_input():
    with pytest.raises(ValueError, match="kind"):
        fit_transfer_function([1, 2, 3, 4, 5], np.ones(5), "bandpass")
    with pytest.raises(ValueError, match="must match"):
        fit_transfer_function([1, 2, 3, 4, 5], np.ones(4), "lowpass")


def test_sequential_with_fixed_r_and_one_sensor_equals_the_textbook_filter():
    rng = np.random.default_rng(3)
    model = FusionModel(HF, LF, q=50.0)
    phi, q = model.discretize(1 / 1000, "zoh")
    _, _, h1, _ = model.continuous()
    y = rng.normal(size=500)
    x0, p0 = np.zeros(3), np.eye(3)
    run = fu.sequential_kalman([y], [h1], [AdaptiveNoise.fixed(0.04)], phi, q, x0, p0)
    x, p, out = x0.copy(), p0.copy(), []
    for yk in y:  # textbook Kalman filter, matrix form
        x, p = phi @ x, phi @ p @ phi.T + q
        s = h1 @ p @ h1.T + 0.04
        k = p @ h1.T @ np.linalg.inv(s)
        x = x + (k @ (yk - h1 @ x)).ravel()
        p = (np.eye(3) - k @ h1) @ p
        out.append(x[0])
    np.testing.assert_allclose(run.rate, out, rtol=0, atol=1e-12)


def test_sequential_with_fixed_r_equals_the_stacked_fixed_r_filter():
    t, hf, lf, _ = synth(duration_s=0.5)
    model = FusionModel(HF, LF, q=2000.0)
    params = FusionParams(AdaptiveNoise.fixed(0.02 ** 2), AdaptiveNoise.fixed(0.01 ** 2))
    seq = fu.sequential_fusion(hf, lf, 1 / FS_HZ, model, params)
    kf = fu.fixed_r_kalman(hf, lf, 1 / FS_HZ, model, params)
    np.testing.assert_allclose(seq.rate, kf.rate, rtol=0, atol=1e-10)


def _model_data(n, q, r1, r2, seed, ts=1 / 1000):
    """Data drawn from the discrete model itself: the filter that knows q, R is consistent."""
    rng = np.random.default_rng(seed)
    model = FusionModel(HF, LF, q)
    phi, qd = model.discretize(ts, "zoh")
    _, _, h1, h2 = model.continuous()
    chol = np.linalg.cholesky(qd + 1e-300 * np.eye(3)) if np.all(np.linalg.eigvalsh(qd) > 0) else None
    x = np.zeros(3)
    y1, y2 = np.empty(n), np.empty(n)
    for k in range(n):
        w = chol @ rng.normal(size=3) if chol is not None else np.sqrt(qd[0, 0]) * rng.normal() * np.eye(3)[0]
        x = phi @ x + w
        y1[k] = (h1 @ x)[0] + math.sqrt(r1) * rng.normal()
        y2[k] = (h2 @ x)[0] + math.sqrt(r2) * rng.normal()
    return model, y1, y2


def test_nis_inside_chi2_bounds_for_a_consistent_filter_and_outside_when_mistuned():
    model, y1, y2 = _model_data(6000, q=4.0, r1=0.01, r2=0.0025, seed=5)
    phi, qd = model.discretize(1 / 1000, "zoh")
    _, _, h1, h2 = model.continuous()
    x0, p0 = np.zeros(3), 1e-6 * np.eye(3)
    good = fu.sequential_kalman([y1, y2], [h1, h2], [AdaptiveNoise.fixed(0.01), AdaptiveNoise.fixed(0.0025)],
                                phi, qd, x0, p0)
    stats = nis_check(good.nis.sum(axis=1), 2, alpha=0.01)
    assert stats.consistent and not stats.diverged
    bad = fu.sequential_kalman([y1, y2], [h1, h2], [AdaptiveNoise.fixed(0.001), AdaptiveNoise.fixed(0.00025)],
                               phi, qd, x0, p0)
    stats = nis_check(bad.nis.sum(axis=1), 2, alpha=0.01)
    assert not stats.consistent and stats.mean > stats.upper


def test_nis_check_flags_a_growing_nis_as_divergence():
    nis = np.concatenate([np.full(900, 1.0), np.full(100, 1e4)])
    assert nis_check(nis, 1).diverged
    assert not nis_check(np.full(1000, 5.0), 1).diverged  # inconsistent but steady
    assert nis_check(np.array([1.0, np.nan]), 1).diverged


@settings(max_examples=30, deadline=None)
@given(sigma2=st.floats(1e-6, 1.0), upper=st.floats(1.0, 1e3), inflate=st.floats(0.0, 1e3), eps=st.floats(0, 1),
       reading=st.floats(-1e4, 1e4), predicted=st.floats(-1e4, 1e4), pvar=st.floats(0, 1e4))
def test_r_stays_within_its_thresholds(sigma2, upper, inflate, eps, reading, predicted, pvar):
    noise = AdaptiveNoise.from_noise(sigma2, eps, upper, inflate)
    i, r = noise.evaluate(reading, predicted, pvar)
    assert i in (0, 1, 2)
    assert noise.r_lower <= r <= noise.r_upper


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 1000), amp=st.floats(0.01, 40.0), scale=st.floats(0.1, 10.0))
def test_filter_never_diverges_on_drawn_profiles(seed, amp, scale):
    t, hf, lf, ref = synth(seed=seed, duration_s=0.3)
    model, params = fu.tune_fusion_params(HF, LF, 4e-4 * scale, 1e-4 * scale, amp * hf, amp * lf, 1 / FS_HZ)
    run = fu.sequential_fusion(amp * hf, amp * lf, 1 / FS_HZ, model, params)
    assert np.all(np.isfinite(run.rate))
    assert not nis_check(run.nis.sum(axis=1), 2, rate=run.rate).diverged
    assert np.all(run.r >= [params.hf_noise.r_lower, params.lf_noise.r_lower])
    assert np.all(run.r <= [params.hf_noise.r_upper, params.lf_noise.r_upper])


def test_complementary_filter_reconstructs_noiseless_exact_models():
    t, hf, lf, ref = synth(duration_s=2.0, hf_sigma=0, lf_sigma=0, bias=0, lf_delay_s=0)
    model = FusionModel(HF, LF, 1.0)
    est = fu.complementary_filter(hf, lf, FS_HZ, model, 7.7)
    keep = t > 0.5  # past the start transient of the HF path
    assert np.sqrt(np.mean((est[keep] - ref[keep]) ** 2)) < 0.02  # bilinear warping near 1 kHz only


def test_sine_phasors_and_tone_detection():
    t = np.arange(8000) / 1000.0
    y = 2 * np.cos(2 * np.pi * 5 * t + 0.3) + 0.5 * np.cos(2 * np.pi * 50 * t - 1.0) + 0.1
    a = sine_phasors(t, y, [5, 50])
    np.testing.assert_allclose(a, [2 * np.exp(0.3j), 0.5 * np.exp(-1j)], atol=1e-9)
    np.testing.assert_allclose(detect_tones(y, 1000.0), [5, 50], atol=0.01)


def test_bad_input_raises_value_error():
    with pytest.raises(ValueError, match="must match"):
        fu.sequential_fusion(np.ones(10), np.ones(9), 1e-3, FusionModel(HF, LF, 1.0),
                             FusionParams(AdaptiveNoise.fixed(1.0), AdaptiveNoise.fixed(1.0)))
    with pytest.raises(ValueError, match="non-finite"):
        fu.fixed_r_kalman(np.array([1.0, np.nan]), np.ones(2), 1e-3, FusionModel(HF, LF, 1.0),
                          FusionParams(AdaptiveNoise.fixed(1.0), AdaptiveNoise.fixed(1.0)))
    with pytest.raises(ValueError, match="r_upper"):
        AdaptiveNoise(1.0, 2.0, 1.0)
    with pytest.raises(ValueError, match="corner_hz"):
        SensorModel("lowpass", 1, -3.0)
    with pytest.raises(ValueError, match="discretization"):
        FusionModel(HF, LF, 1.0).discretize(1e-3, "tustin")
