"""The complementary Kalman filter (bench.analysis.fusion._complementary): the compiled filter and
smoother against the textbook recursions, no lag on exact data, the noise by maximum
likelihood, Document B's adaptive R on top, and the discretisation's droop correction.

Synthetic data: tones through each sensor's exact frequency response (closed form per tone)
plus white noise; the models are the true ones unless said otherwise.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import bench.analysis.fusion._complementary as fc
import bench.analysis.fusion._complementary_kernel as kernel
from bench.analysis.fusion import AdaptiveNoise, SensorModel
from bench.analysis.fusion._metrics import sine_phasors


def tones_record(hf_model, lf_model, tones_hz, fs_hz, n, hf_sd, lf_sd, seed=0, hf_offset=0.0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / fs_hz
    phase = rng.uniform(0, 2 * np.pi, len(tones_hz))
    ref, hf, lf = np.zeros(n), np.zeros(n), np.zeros(n)
    for f, ph, g1, g2 in zip(tones_hz, phase, hf_model.response(tones_hz), lf_model.response(tones_hz)):
        arg = 2 * np.pi * f * t + ph
        ref += np.sin(arg)
        hf += abs(g1) * np.sin(arg + np.angle(g1))
        lf += abs(g2) * np.sin(arg + np.angle(g2))
    return t, hf + hf_offset + hf_sd * rng.standard_normal(n), lf + lf_sd * rng.standard_normal(n), ref


def textbook(u_model, u_out, z, system, q, r, x0, p0):
    """Kalman filter with a known input (matrix form, posterior at every sample) and the
    Rauch–Tung–Striebel smoother with its explicit inverse: the rates they give (output from
    the posterior, no look-ahead) and the smoothed rate."""
    phi, g0, g1, h, h_rate = system.phi, system.g0, system.g1, system.h, system.h_rate
    x, p = np.array(x0, dtype=float), np.array(p0, dtype=float)
    xf, pf, xp, pp = [], [], [], []
    for k in range(z.size):
        if k:
            x = phi @ x + g0 * u_model[k - 1] + g1 * u_model[k]
            p = phi @ p @ phi.T + q
        xp.append(x)
        pp.append(p)
        s = h @ p @ h + r
        gain = p @ h / s
        x = x + gain * (z[k] - h @ x)
        p = (np.eye(x.size) - np.outer(gain, h)) @ p
        xf.append(x)
        pf.append(p)
    xs = [None] * z.size
    xs[-1] = xf[-1]
    for k in range(z.size - 2, -1, -1):
        c = pf[k] @ phi.T @ np.linalg.inv(pp[k + 1])
        xs[k] = xf[k] + c @ (xs[k + 1] - xp[k + 1])
    rate = np.array([u_out[k] + h_rate @ xf[k] for k in range(z.size)])
    smoothed = np.array([u_out[k] + h_rate @ xs[k] for k in range(z.size)])
    return rate, smoothed


@settings(max_examples=6, deadline=None)
@given(hf_order=st.sampled_from([1, 2]), lf_order=st.sampled_from([1, 2]), offset_rw=st.sampled_from([1e-6, 1.0]),
       seed=st.integers(0, 1000))
def test_compiled_filter_and_smoother_equal_the_textbook_recursions(hf_order, lf_order, offset_rw, seed):
    hf_model, lf_model = SensorModel("highpass", hf_order, 2.0, 0.5), SensorModel("lowpass", lf_order, 30.0, 1.2)
    fs = 1000.0
    _, hf, lf, _ = tones_record(hf_model, lf_model, [0.5, 5.0, 50.0], fs, 2500, 0.02, 0.01, seed, hf_offset=0.01)
    noise = fc.ComplementaryNoise(4e-4, 1e-4, offset_rw)  # 1.0: P converges within the record (steady gain)
    system = fc.complementary_system(hf_model, lf_model, 1 / fs)
    x0, p0 = fc.initial_state(hf_model, lf_model, hf, lf, noise, fs)
    u = hf / hf_model.gain
    um = fc.inverse_foh_droop(u)
    q = system.q(noise)
    args = (um, u, fc.near_inverse_droop(u), lf, system.phi, system.row_kind, system.g0, system.g1, q, system.h,
            system.h_rate, 1e-4, 1e-4, np.zeros(3), np.zeros(3), False, tuple(x0), p0, 256)
    ref_rate, ref_smooth = textbook(um, u, lf, system, q, 1e-4, x0, p0)
    for tol in (0.0, fc.STEADY_TOL):
        rate, nu, s, r, iv, ck_x, ck_p, k_steady, p, gain = kernel.complementary_forward(*args, tol, 0)
        scale = np.max(np.abs(ref_rate))
        # exact without the steady-state gain; with it, the gain frozen once P moves < 1e-10 of itself
        np.testing.assert_allclose(rate, ref_rate, rtol=0, atol=(1e-12 if tol == 0 else 1e-7) * scale)
        smooth = kernel.complementary_smooth(um, u, lf, system.phi, system.row_kind, system.g0, system.g1, q,
                                             system.h, system.h_rate, r, ck_x, ck_p, 256, k_steady, p, gain,
                                             float(s[min(k_steady, s.size - 1)]))
        np.testing.assert_allclose(smooth, ref_smooth, rtol=0, atol=(1e-10 if tol == 0 else 1e-7) * scale)
    assert (k_steady < 2500) == (offset_rw == 1.0)


def test_the_causal_output_uses_no_reading_after_its_sample():
    hf_model, lf_model = SensorModel("highpass", 1, 2.0), SensorModel("lowpass", 2, 30.0)
    _, hf, lf, _ = tones_record(hf_model, lf_model, [1.0, 10.0, 100.0], 1000.0, 3000, 0.02, 0.01)
    noise = fc.ComplementaryNoise(4e-4, 1e-4, 1e-6)
    base = fc.complementary_kalman(hf, lf, 1e-3, hf_model, lf_model, noise).rate
    hf2, lf2 = hf.copy(), lf.copy()
    hf2[2000:] += 5.0  # change the future: the past output must not move
    lf2[2000:] -= 5.0
    changed = fc.complementary_kalman(hf2, lf2, 1e-3, hf_model, lf_model, noise).rate
    np.testing.assert_array_equal(changed[:2000], base[:2000])
    assert np.all(changed[2000:2005] != base[2000:2005])


@settings(max_examples=8, deadline=None)
@given(hf_order=st.sampled_from([1, 2]), lf_order=st.sampled_from([1, 2]), fh=st.floats(0.5, 5.0),
       ratio=st.floats(3.0, 300.0), fs_per_fl=st.floats(20.0, 200.0), seed=st.integers(0, 1000))
def test_no_lag_anywhere_in_the_band_on_exact_models(hf_order, lf_order, fh, ratio, fs_per_fl, seed):
    fl = fh * ratio
    fs = fl * fs_per_fl
    hf_model, lf_model = SensorModel("highpass", hf_order, fh, 2.0), SensorModel("lowpass", lf_order, fl, 0.7)
    duration = 8.0 / fh
    n = int(duration * fs)
    if n > 400_000:
        fs, n = 400_000 / duration, 400_000
    tones = np.geomspace(fh / 2, fs / 10, 6)
    t, hf, lf, ref = tones_record(hf_model, lf_model, tones, fs, n, 1e-4, 1e-4, seed)
    run = fc.complementary_kalman(hf, lf, 1 / fs, hf_model, lf_model, fc.ComplementaryNoise(1e-8, 1e-8, 1e-12),
                                  smooth=True)
    keep = slice(n // 2, None)  # past the start-up
    a = sine_phasors(t[keep], np.column_stack([ref[keep], run.rate[keep], run.smoothed[keep]]), tones)
    for col in (1, 2):
        ratio_ = a[:, col] / a[:, 0]
        # a signal model would lag the top of the band; the complementary form passes it through
        # both sensors' inverted models: amplitude within 0.05 %, phase within 0.05° up to fs/10
        assert np.max(np.abs(np.abs(ratio_) - 1)) < 5e-4
        assert np.max(np.abs(np.degrees(np.angle(ratio_)))) < 0.05


@pytest.mark.parametrize("hf_order, lf_order", [(1, 1), (2, 1), (1, 2), (2, 2)])
def test_the_smoother_on_a_quiet_lf_sensor_is_exact_up_to_an_eighth_of_the_rate(hf_order, lf_order):
    """A quiet LF sensor (10⁴ times less noise variance than the HF: as a FOG beside an MHD), so
    the smoother leans on the LF reading far above its corner, where the first-order hold's
    images are a visible part of the model's LF prediction (module docstring): corrected, every
    tone up to fs/8 within 3·10⁻⁵ in amplitude and 0.003° (without the correction a first-order LF
    is 1.6·10⁻³ off at the top tone and the test fails; a second-order one's images are smaller)."""
    fh, fl, fs = 2.0, 60.0, 16_000.0
    hf_model, lf_model = SensorModel("highpass", hf_order, fh, 1.5, 0.8), SensorModel("lowpass", lf_order, fl, 0.9)
    tones = np.geomspace(fh / 2, fs / 8, 7)
    n = int(4.0 * fs)
    t, hf, lf, ref = tones_record(hf_model, lf_model, tones, fs, n, 1e-4, 1e-6, 3)
    run = fc.complementary_kalman(hf, lf, 1 / fs, hf_model, lf_model, fc.ComplementaryNoise(1e-8, 1e-12, 1e-12),
                                  smooth=True)
    keep = slice(n // 2, None)
    a = sine_phasors(t[keep], np.column_stack([ref[keep], run.smoothed[keep]]), tones)
    ratio_ = a[:, 1] / a[:, 0]
    assert np.max(np.abs(np.abs(ratio_) - 1)) < 3e-5
    assert np.max(np.abs(np.degrees(np.angle(ratio_)))) < 0.003


@settings(max_examples=10, deadline=None)
@given(hf_order=st.sampled_from([1, 2]), lf_order=st.sampled_from([1, 2]), fh=st.floats(0.5, 5.0),
       ratio=st.floats(3.0, 300.0), fs_per_fl=st.floats(10.0, 200.0), zeta=st.floats(0.5, 1.0),
       x=st.floats(0.02, 0.25))
def test_the_hold_correction_makes_the_models_lf_prediction_exact(hf_order, lf_order, fh, ratio, fs_per_fl, zeta, x):
    """Open loop, no noise: a sampled tone at ``x``·fs through the exact HF response drives the
    discrete model (through the inverse droop, as the filter does); the tone in its LF prediction
    ``h·x`` equals the tone in the exact LF reading put through the hold correction, to 10⁻⁵ of
    that reading — and is the raw reading's tone times ``hold_response``, off by its image sum."""
    fl = fh * ratio
    fs = fl * fs_per_fl
    hf_model = SensorModel("highpass", hf_order, fh, 1.7, zeta)
    lf_model = SensorModel("lowpass", lf_order, fl, 0.8, zeta)
    f = x * fs
    n = 3000  # the LF states settle within ~40 samples; the HF inverse's integrators (open loop) only
    t = np.arange(n) / fs  # add a polynomial of the order of the HF model, fitted out below
    g_h, g_l = hf_model.response(f), lf_model.response(f)
    hf = abs(g_h) * np.sin(2 * np.pi * f * t + np.angle(g_h))
    lf = abs(g_l) * np.sin(2 * np.pi * f * t + np.angle(g_l))
    system = fc.complementary_system(hf_model, lf_model, 1 / fs)
    u = fc.inverse_foh_droop(hf / hf_model.gain)
    xs = np.zeros(system.phi.shape[0])
    pred = np.empty(n)
    for k in range(n):
        if k:
            xs = system.phi @ xs + system.g0 * u[k - 1] + system.g1 * u[k]
        pred[k] = system.h @ xs
    tail = slice(1000, n - fc.HOLD_HALF_WIDTH)
    tt = t[tail] - t[tail].mean()
    design = np.column_stack([tt ** j for j in range(hf_order + 1)]
                             + [np.cos(2 * np.pi * f * tt), np.sin(2 * np.pi * f * tt)])
    held = fc.hold_corrected(lf, fc.hold_correction_taps(hf_model, lf_model, fs))

    def tone(y):
        c = np.linalg.lstsq(design, y[tail], rcond=None)[0]
        return complex(c[-2], -c[-1])

    d = complex(fc.hold_response(hf_model, lf_model, fs, f)[0])
    assert abs(tone(pred) - tone(held)) < 1e-5 * abs(g_l)
    assert abs(tone(pred) - d * tone(lf)) < 1e-5 * abs(g_l)  # what the correction corrects
    if x >= 0.15:  # ... the images: ten times the tolerance and more by fs/7 (first order: 1.7 % at fs/5)
        assert abs(d - 1) > 1e-4


def test_hold_response_rejects_frequencies_outside_the_band():
    hf_model, lf_model = SensorModel("highpass", 1, 2.0), SensorModel("lowpass", 1, 30.0)
    for f in (0.0, 500.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match="freq_hz"):
            fc.hold_response(hf_model, lf_model, 1000.0, f)
    with pytest.raises(ValueError, match="rate_hz"):
        fc.hold_response(hf_model, lf_model, 0.0, 10.0)


@pytest.mark.parametrize("hf_sd, lf_sd, seed", [(0.02, 0.02, 0), (0.25, 0.003, 1), (0.005, 0.005, 2)])
def test_maximum_likelihood_recovers_the_noise_with_the_tones_fitted_out(hf_sd, lf_sd, seed):
    # (where the HF noise is far below the LF's at every frequency the LF reading sees, its level is
    # not identifiable from the innovations — and, for the same reason, does not matter to the filter)
    hf_model, lf_model = SensorModel("highpass", 1, 2.0, 0.5), SensorModel("lowpass", 2, 30.0)
    tones = np.array([1.0, 4.0, 15.0, 60.0, 240.0])
    fs = 4000.0
    t, hf, lf, _ = tones_record(hf_model, lf_model, tones, fs, 120_000, hf_sd, lf_sd, seed, hf_offset=0.05)
    fit = fc.fit_complementary_noise(hf, lf, 1 / fs, hf_model, lf_model, tones_hz=tones, t_s=t)
    assert fit.decimation == 4  # to ≥ 20× the LF corner: 1 kHz
    assert fit.noise.hf_var == pytest.approx(hf_sd ** 2, rel=0.25)
    assert fit.noise.lf_var == pytest.approx(lf_sd ** 2, rel=0.25)


def test_adaptive_r_stays_in_its_bounds_and_the_smoother_replays_it():
    hf_model, lf_model = SensorModel("highpass", 1, 2.0), SensorModel("lowpass", 1, 30.0)
    _, hf, lf, ref = tones_record(hf_model, lf_model, [1.0, 10.0, 100.0], 2000.0, 8000, 0.02, 0.01)
    lf[3000:3003] += 5.0  # LF spikes: the innovation index goes above r_upper
    noise = fc.ComplementaryNoise(4e-4, 1e-4, 1e-8)
    lf_noise = AdaptiveNoise.from_noise(1e-4, 0.0, 10.0, 10.0)
    run = fc.complementary_kalman(hf, lf, 5e-4, hf_model, lf_model, noise, lf_noise=lf_noise, smooth=True)
    assert set(np.unique(run.interval)) == {0, 1, 2}
    assert np.all((run.r >= lf_noise.r_lower) & (run.r <= lf_noise.r_upper))
    assert run.k_steady == hf.size  # an adaptive R never freezes the gain
    fixed = fc.complementary_kalman(hf, lf, 5e-4, hf_model, lf_model, noise, smooth=True)
    spike = slice(3000, 3100)
    # the inflated R weighs the spikes less: a smaller error just after them
    assert np.max(np.abs(run.rate[spike] - ref[spike])) < np.max(np.abs(fixed.rate[spike] - ref[spike]))
    assert np.all(np.isfinite(run.smoothed))


def test_inverse_droop_undoes_linear_interpolation_to_fourth_order():
    taps = np.array(fc.INVERSE_DROOP_TAPS)
    for x in (0.01, 0.025, 0.05, 0.1):
        theta = 2 * math.pi * x
        response = taps[0] + 2 * taps[1] * math.cos(theta) + 2 * taps[2] * math.cos(2 * theta)
        assert abs(response * np.sinc(x) ** 2 - 1) < 0.15 * (math.pi * x) ** 6  # 1e-4 at fs/10, 2e-6 at fs/20
    y = np.sin(2 * np.pi * 0.05 * np.arange(200))
    out = fc.inverse_foh_droop(y)
    assert np.array_equal(out[:2], y[:2]) and np.array_equal(out[-2:], y[-2:])


def test_decimation_for_the_likelihood():
    lf_model = SensorModel("lowpass", 2, 40.0)
    assert fc.likelihood_decimation(10_000.0, lf_model, 1_000_000) == 8  # 12.5 → the power of two below
    assert fc.likelihood_decimation(10_000.0, lf_model, 20_000) == 4  # keeps ≥ 4096 samples
    assert fc.likelihood_decimation(500.0, lf_model, 1_000_000) == 1
    a, b = fc.decimate_pair(np.ones(1000), np.arange(1000.0), 16)
    assert a.size == b.size == 63 and np.allclose(a[10:-10], 1.0, atol=1e-3)  # a constant passes (the ends ring)
    with pytest.raises(ValueError, match="power of two"):
        fc.decimate_pair(np.ones(100), np.ones(100), 6)


def test_bad_input_raises_value_error_naming_it():
    hf_model, lf_model = SensorModel("highpass", 1, 2.0), SensorModel("lowpass", 1, 30.0)
    with pytest.raises(ValueError, match="hf_var"):
        fc.ComplementaryNoise(0.0, 1.0, 1.0)
    with pytest.raises(ValueError, match="high-pass"):
        fc.complementary_system(lf_model, hf_model, 1e-3)
    with pytest.raises(ValueError, match="ts_s"):
        fc.complementary_system(hf_model, lf_model, -1.0)
    with pytest.raises(ValueError, match="must match"):
        fc.complementary_kalman(np.ones(10), np.ones(9), 1e-3, hf_model, lf_model,
                                fc.ComplementaryNoise(1.0, 1.0, 1.0))
