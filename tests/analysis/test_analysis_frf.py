"""Stepped-sine FRF, fit with delay, clock alignment and resampling (bench.analysis.frf._stepped_sine*)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.signal import lfilter

from bench.analysis.frf import apply_time_base, estimate_time_base, frf, frf_point, resample, sine_fit
from bench.analysis.fusion import SensorModel, fit_transfer_function
from bench.analysis.fusion._metrics import sine_phasors


def tones(t, freqs, amps):
    """``Σ Re(A·e^{j2πft})`` at absolute times ``t``."""
    return sum(np.real(a * np.exp(2j * np.pi * f * t)) for f, a in zip(freqs, amps))


def ar1(rng, n, rho, sigma):
    return lfilter([math.sqrt(1 - rho * rho)], [1, -rho], rng.normal(size=n)) * sigma


def mhd(f):
    """The simulator's MHD: first-order high-pass 2.5 Hz times a first-order low-pass at 8 kHz (V per dps)."""
    return SensorModel("highpass", 1, 2.5, 0.01).response(f) / (1 + 1j * np.asarray(f) / 8000.0)


def lf(f):
    """The simulator's LF sensor: second-order low-pass 40 Hz, ζ 0.7, 0.6 ms latency (dps per dps)."""
    return SensorModel("lowpass", 2, 40.0, 1.0, 0.7).response(f) * np.exp(-2j * np.pi * np.asarray(f) * 6e-4)


# ---------------------------------------------------------------- sine_fit


def test_sine_fit_is_exact_on_noiseless_tones_with_harmonics_and_matches_sine_phasors():
    fs, f = 1000.0, 7.0
    t = 12.345 + np.arange(3000) / fs
    amps = [1.3 * np.exp(0.7j), 0.05 * np.exp(-2j), 0.02j]
    y = 0.4 + tones(t, [f, 2 * f, 3 * f], amps)
    fit = sine_fit(t, y, f)
    assert fit.amplitude == pytest.approx(amps[0], abs=1e-10)  # phase quoted at absolute t = 0
    np.testing.assert_allclose(fit.harmonics, amps[1:], atol=1e-10)
    assert fit.offset == pytest.approx(0.4, abs=1e-10)
    assert fit.residual_rms < 1e-10
    # the reference: sine_phasors quotes phases at t[0]; same window, same tones
    ref = sine_phasors(t, y, [f, 2 * f, 3 * f])
    at_t0 = sine_fit(t, y, f, t0_s=t[0])
    assert at_t0.amplitude == pytest.approx(ref[0], abs=1e-10)
    assert at_t0.mag == pytest.approx(1.3) and at_t0.phase_deg == pytest.approx(np.degrees(np.angle(ref[0])))


def test_sine_fit_window_keeps_whole_periods():
    fs, f = 1000.0, 3.0
    t = np.arange(int(2.5 * fs)) / fs  # 7.5 periods
    fit = sine_fit(t, np.cos(2 * np.pi * f * t), f)
    assert fit.n_periods == 7 and fit.window_s[1] - fit.window_s[0] == pytest.approx(7 / f)
    assert fit.n_samples == round(7 / f * fs)
    loose = sine_fit(t, np.cos(2 * np.pi * f * t), f, whole_periods=False)
    assert loose.n_periods == pytest.approx(7.5) and loose.n_samples == t.size


@pytest.mark.parametrize("fs, f, dwell_s", [(1000.0, 0.1, 30.0), (10_000.0, 1000.0, 2.0)])
def test_sine_fit_works_from_a_few_periods_at_0p1_hz_to_thousands_at_1_khz(fs, f, dwell_s):
    rng = np.random.default_rng(5)
    t = 100.0 + np.arange(int(dwell_s * fs)) / fs
    a = 2.0 * np.exp(-1.1j)
    y = tones(t, [f, 2 * f], [a, 0.1]) + 0.3 * rng.normal(size=t.size)
    fit = sine_fit(t, y, f)
    assert abs(fit.amplitude - a) < 4 * fit.amplitude_std
    assert fit.amplitude_std < 0.01


def _coverage(draws):
    """Fractions of |error| < 1σ and < 3σ, magnitude and phase pooled."""
    z = np.abs(np.concatenate(draws))
    return float(np.mean(z < 1)), float(np.mean(z < 3))


def test_sine_fit_standard_errors_cover_the_truth_under_white_and_correlated_noise():
    rng = np.random.default_rng(11)
    zs = []
    for i in range(160):
        fs = 1000.0
        f = float(np.exp(rng.uniform(np.log(0.5), np.log(300))))
        n_per = max(3, min(int(rng.integers(3, 60)), int(5000 * f / fs)))  # ≤ ~5000 samples
        t = rng.uniform(0, 100) + np.arange(int(n_per / f * fs) + int(rng.integers(0, 20))) / fs
        a = rng.uniform(0.2, 2) * np.exp(1j * rng.uniform(-np.pi, np.pi))
        rho = rng.choice([0.0, 0.8, 0.97, -0.5])
        y = 0.3 + tones(t, [f, 2 * f], [a, 0.05]) + ar1(rng, t.size, rho, 0.3) + 0.01 * (t - t[0]) * (i % 2)
        fit = sine_fit(t, y, f, trend=bool(i % 2))
        zs.append([(fit.mag - abs(a)) / fit.mag_std,
                   math.degrees(np.angle(fit.amplitude / a)) / fit.phase_std_deg])
    one, three = _coverage(zs)
    assert three >= 0.95
    assert 0.55 <= one <= 0.85  # σ neither much too small nor much too large


def test_correlated_noise_raises_the_standard_error_where_its_spectrum_is_high():
    rng = np.random.default_rng(2)
    fs = 1000.0
    t = np.arange(20_000) / fs
    e = ar1(rng, t.size, 0.95, 0.3)  # red noise: strong at 1 Hz, weak at 300 Hz
    low = sine_fit(t, np.cos(2 * np.pi * 1.0 * t) + e, 1.0)
    high = sine_fit(t, np.cos(2 * np.pi * 300.0 * t) + e, 300.0)
    assert low.noise_factor > 10 and high.noise_factor < 0.2


def test_trend_term_absorbs_a_drifting_bias():
    fs, f = 2000.0, 0.5
    t = np.arange(int(8 / f * fs)) / fs
    a = 0.8 * np.exp(0.3j)
    y = tones(t, [f], [a]) + 0.05 + 0.02 * t
    with_trend = sine_fit(t, y, f, trend=True)
    assert with_trend.amplitude == pytest.approx(a, abs=1e-9)
    assert with_trend.trend_per_s == pytest.approx(0.02, rel=1e-9)
    assert abs(sine_fit(t, y, f).amplitude - a) > 1e-4  # without it the drift leaks into the tone


def test_sine_fit_rejects_bad_input_naming_the_range():
    t = np.arange(1000) / 1000.0
    y = np.cos(2 * np.pi * 5 * t)
    with pytest.raises(ValueError, match=r"freq_hz 600.*\(0, 500\) Hz"):
        sine_fit(t, y, 600.0)
    with pytest.raises(ValueError, match=r"freq_hz -1"):
        sine_fit(t, y, -1.0)
    with pytest.raises(ValueError, match=r"0.5 periods.*at least 1"):
        sine_fit(t, y, 0.5)
    with pytest.raises(ValueError, match="strictly increasing"):
        sine_fit(t[::-1], y, 5.0)
    with pytest.raises(ValueError, match="finite"):
        sine_fit(t, np.where(t > 0.5, np.nan, y), 5.0)
    with pytest.raises(ValueError, match="must match"):
        sine_fit(t, y[:-1], 5.0)
    with pytest.raises(ValueError, match=r"harmonics 0 must be an integer in \[1, 20\]"):
        sine_fit(t, y, 5.0, harmonics=0)
    with pytest.raises(ValueError, match="samples in the window"):
        sine_fit(t[:12], y[:12], 100.0)


# ---------------------------------------------------------------- FRF


def _dwell(rng, f, g, *, fs_ref=5000.0, fs_y=4000.0, t_start=0.0, noise_ref=0.02, noise_y=0.002,
           amp_dps=1.0, harmonic=0.03):
    """Table rate (tone + 2f, 3f harmonics) on the reference grid, and the sensor's response
    ``g(f)`` to all three on its own grid (different rate and start), both with noise."""
    dwell = max(3.0 / f, 0.4)
    t_ref = t_start + np.arange(int(dwell * fs_ref)) / fs_ref
    t_y = t_start + 0.37e-3 + np.arange(int((dwell - 1e-3) * fs_y)) / fs_y
    freqs = [f, 2 * f, 3 * f]
    amps = [amp_dps * np.exp(1j * rng.uniform(-np.pi, np.pi)), harmonic * amp_dps, -0.5j * harmonic * amp_dps]
    ref = tones(t_ref, freqs, amps) + noise_ref * rng.normal(size=t_ref.size)
    y = tones(t_y, freqs, [g(fr) * a for fr, a in zip(freqs, amps)]) + noise_y * rng.normal(size=t_y.size)
    return t_ref, ref, t_y, y, f


def test_frf_point_recovers_a_known_complex_gain_within_its_uncertainty():
    rng = np.random.default_rng(21)
    zs = []
    for _ in range(60):
        gain, delay = rng.uniform(0.005, 0.02), rng.uniform(0, 1e-3)
        phase = rng.uniform(-np.pi, np.pi)
        f = float(np.exp(rng.uniform(np.log(1.0), np.log(400.0))))

        def g(fr, gain=gain, phase=phase, delay=delay):
            return gain * np.exp(1j * phase - 2j * np.pi * fr * delay)

        p = frf_point(*_dwell(rng, f, g, noise_y=gain * 0.05))
        true = g(f)
        assert -180 < p.phase_deg <= 180
        zs.append([(p.mag - abs(true)) / p.mag_std, math.degrees(np.angle(p.h / true)) / p.phase_std_deg])
    one, three = _coverage(zs)
    assert three >= 0.95 and 0.55 <= one <= 0.85


def test_frf_point_uses_the_common_span_and_rejects_disjoint_records():
    rng = np.random.default_rng(3)
    t_ref, ref, t_y, y, f = _dwell(rng, 10.0, lambda fr: 0.5 + 0 * fr)
    p = frf_point(t_ref, ref, t_y[200:], y[200:], f)
    assert p.ref_fit.window_s == p.y_fit.window_s and p.y_fit.window_s[0] == pytest.approx(t_y[200])
    assert p.mag == pytest.approx(0.5, rel=0.01)
    with pytest.raises(ValueError, match="share no time"):
        frf_point(t_ref, ref, t_y + 10.0, y, f)
    with pytest.raises(ValueError, match="skip_s -1"):
        frf_point(t_ref, ref, t_y, y, f, skip_s=-1.0)
    with pytest.raises(ValueError, match="reference amplitude .* must exceed 3× its standard error"):
        frf_point(t_ref, 0.01 * rng.normal(size=t_ref.size), t_y, y, f)


def test_frf_over_dwells_is_json_safe_and_gives_positive_weights():
    rng = np.random.default_rng(4)
    dwells = [_dwell(rng, f, mhd, t_start=10.0 * i, noise_y=2e-4) for i, f in enumerate([5.0, 50.0, 500.0])]
    res = frf(dwells)
    np.testing.assert_allclose(res.freq_hz, [5.0, 50.0, 500.0])
    np.testing.assert_allclose(res.mag, np.abs(mhd(res.freq_hz)), rtol=0.01)
    assert np.all(res.weights > 0) and np.all(np.isfinite(res.weights))
    d = json.loads(json.dumps(res.to_dict()))
    assert d["points"][0]["y_fit"]["harmonics"][0] is not None and len(d["h_re"]) == 3
    with pytest.raises(ValueError, match="no dwells"):
        frf([])


# ---------------------------------------------------------------- transfer-function fit with delay

GRID_HZ = np.logspace(-1, 3, 25)


def test_fit_with_delay_represents_the_simulators_mhd_and_lf_sensor():
    hf = fit_transfer_function(GRID_HZ, mhd(GRID_HZ), "highpass", fit_delay=True)
    assert hf.order == 1 and hf.corner_hz == pytest.approx(2.5, rel=0.005) and hf.gain == pytest.approx(0.01, rel=0.01)
    assert hf.delay_s == pytest.approx(1 / (2 * np.pi * 8000), rel=0.05)  # the 8 kHz pole ≈ a 20 µs delay
    ratio = hf.response(GRID_HZ) / mhd(GRID_HZ)
    assert np.max(np.abs(np.abs(ratio) - 1)) < 0.01 and np.max(np.abs(np.degrees(np.angle(ratio)))) < 0.1
    lo = fit_transfer_function(GRID_HZ, lf(GRID_HZ), "lowpass", fit_delay=True)
    assert lo.order == 2 and lo.corner_hz == pytest.approx(40.0, rel=1e-4)
    assert lo.model.zeta == pytest.approx(0.7, rel=1e-4)
    assert lo.delay_s == pytest.approx(6e-4, rel=1e-4) and lo.residual < 1e-6
    # without the delay the same LF data cannot be represented
    assert fit_transfer_function(GRID_HZ, lf(GRID_HZ), "lowpass").residual > 0.3
    assert json.loads(json.dumps(lo.to_dict()))["delay_s"] == pytest.approx(6e-4)


def test_fit_without_delay_is_unchanged_and_reports_zero_delay():
    g = SensorModel("lowpass", 1, 30.0, 2.0).response(GRID_HZ)
    fit = fit_transfer_function(GRID_HZ, g, "lowpass")
    assert fit.delay_s == 0.0 and fit.chi2_reduced is None and fit.corner_hz == pytest.approx(30.0)


@settings(max_examples=15, deadline=None)
@given(kind=st.sampled_from(["highpass", "lowpass"]), order=st.sampled_from([1, 2]),
       corner_hz=st.floats(1.0, 60.0), gain=st.floats(0.01, 3.0), zeta=st.floats(0.4, 1.0),
       delay_s=st.floats(0.0, 1e-3), seed=st.integers(0, 10_000))
def test_fit_with_delay_recovers_drawn_models(kind, order, corner_hz, gain, zeta, delay_s, seed):
    rng = np.random.default_rng(seed)
    true = SensorModel(kind, order, corner_hz, gain, zeta)
    sigma = 0.005 * np.abs(true.response(GRID_HZ))
    g = true.response(GRID_HZ) * np.exp(-2j * np.pi * GRID_HZ * delay_s)
    g = g + sigma * (rng.normal(size=g.size) + 1j * rng.normal(size=g.size))
    fit = fit_transfer_function(GRID_HZ, g, kind, fit_delay=True, weights=1 / sigma)
    assert fit.order == order
    assert fit.corner_hz == pytest.approx(corner_hz, rel=0.02)
    assert fit.gain == pytest.approx(gain, rel=0.02)
    assert fit.delay_s == pytest.approx(delay_s, abs=1e-5)
    assert 0.4 < fit.chi2_reduced < 2.0  # the weights are the noise's σ


def test_fit_transfer_function_rejects_bad_weights():
    g = lf(GRID_HZ)
    with pytest.raises(ValueError, match="weights must be 25 finite values > 0"):
        fit_transfer_function(GRID_HZ, g, "lowpass", weights=np.zeros(25))
    with pytest.raises(ValueError, match="at least 6 are needed"):
        fit_transfer_function(GRID_HZ[:5], g[:5], "lowpass", fit_delay=True)


# ---------------------------------------------------------------- time base


@settings(max_examples=10, deadline=None)
@given(ppm=st.floats(-300.0, 300.0), offset_s=st.floats(-2e-3, 2e-3), f=st.floats(5.0, 40.0),
       phase=st.floats(-3.0, 3.0), seed=st.integers(0, 10_000))
def test_time_base_recovers_a_drawn_clock_error(ppm, offset_s, f, phase, seed):
    rng = np.random.default_rng(seed)
    t_ref = np.arange(24_000) / 2000.0
    ref = tones(t_ref, [f, 2 * f], [1.0, 0.03]) + 0.05 * rng.normal(size=t_ref.size)
    t_y = 0.02 + np.arange(11_900) / 1000.0  # the sensor's own stamps
    t_true = t_y + offset_s + ppm * 1e-6 * (t_y - 5.0)  # when each sample was really taken
    y = tones(t_true, [f], [0.4 * np.exp(1j * phase)]) + 0.02 * rng.normal(size=t_y.size)
    tb = estimate_time_base(t_ref, ref, t_y, y, f, 1.0)
    assert abs(tb.rate_ppm - ppm) < 3 * tb.rate_std_ppm and tb.rate_std_ppm < 20.0
    # the offset is the clock's plus the sensor's phase (here `phase`), modulo one period
    true_offset = offset_s + ppm * 1e-6 * (tb.epoch_s - 5.0) + phase / (2 * np.pi * f)
    miss = (tb.offset_s - true_offset + 0.5 / f) % (1 / f) - 0.5 / f
    assert abs(miss) < 3 * tb.offset_std_s + 1e-9
    corrected = apply_time_base(t_y, tb)
    bound = 3 * tb.rate_std_ppm * 1e-6 * np.max(np.abs(t_y - tb.epoch_s))  # the rate's σ over the record
    assert np.max(np.abs(corrected - (t_true - offset_s - ppm * 1e-6 * (tb.epoch_s - 5.0)))) < bound
    assert json.loads(json.dumps(tb.to_dict()))["n_blocks"] == tb.n_blocks


def test_time_base_needs_three_blocks():
    t = np.arange(5000) / 1000.0
    y = np.sin(2 * np.pi * 10 * t)
    with pytest.raises(ValueError, match=r"holds 2 blocks of 2 s; at least 3"):
        estimate_time_base(t, y, t, y, 10.0, 2.0)
    with pytest.raises(ValueError, match="block_s 0"):
        estimate_time_base(t, y, t, y, 10.0, 0.0)


# ---------------------------------------------------------------- resampling


@pytest.mark.parametrize("ratio, sinc_max, cubic_max", [(0.02, 2e-5, 2e-6), (0.1, 2e-5, 1e-3),
                                                        (0.25, 2e-5, 0.03), (0.4, 2e-5, 0.4)])
def test_resample_error_at_the_frequencies_that_matter(ratio, sinc_max, cubic_max):
    fs = 2000.0  # the LF frames
    t = 0.25e-3 + np.arange(3000) / fs
    t_dst = np.arange(t[0], t[-1], 1 / 10_000.0 * (1 + 50e-6))  # an HF grid on another clock
    f = ratio * fs
    y = np.cos(2 * np.pi * f * t + 0.3)
    truth = np.cos(2 * np.pi * f * t_dst + 0.3)
    inner = (t_dst > t[0] + 16 / fs) & (t_dst < t[-1] - 16 / fs)
    err_sinc = np.abs(resample(t, y, t_dst) - truth)[inner].max()
    err_cubic = np.abs(resample(t, y, t_dst, "cubic") - truth)[inner].max()
    assert err_sinc < sinc_max and err_cubic < cubic_max
    if ratio >= 0.1:
        assert err_sinc < err_cubic / 20  # why the band-limited method is the default
    # the ends fall back to the spline: the error there stays the spline's
    assert np.abs(resample(t, y, t_dst) - truth)[~inner].max() <= 3 * max(
        np.abs(resample(t, y, t_dst, "cubic") - truth)[~inner].max(), 1e-12)


def test_resample_passes_the_source_samples_and_constants_exactly():
    t = np.arange(500) / 100.0
    y = np.random.default_rng(0).normal(size=500)
    np.testing.assert_allclose(resample(t, y, t[20:-20]), y[20:-20], atol=1e-12)
    np.testing.assert_allclose(resample(t, np.full(500, 3.5), t[:-1] + 0.003), 3.5, rtol=1e-12)


def test_resample_rejects_bad_input():
    t = np.arange(100) / 100.0
    y = np.zeros(100)
    with pytest.raises(ValueError, match=r"must lie within the source's \[0, 0.99\] s"):
        resample(t, y, [1.5])
    jitter = t + np.r_[0, 0.003, np.zeros(98)]
    with pytest.raises(ValueError, match="uniform grid"):
        resample(jitter, y, [0.5])
    assert np.isfinite(resample(jitter, y, [0.5], "cubic")).all()
    with pytest.raises(ValueError, match="method 'linear' must be one of sinc, cubic"):
        resample(t, y, [0.5], "linear")


# ---------------------------------------------------------------- end to end


def test_stepped_sine_with_an_off_clock_dmm_yields_both_sensor_models():
    """Table reference on its clock; MHD read by a DMM, triggered at each dwell's start, whose
    timer runs 80 ppm slow; LF frames (interval means at 2 kHz, mid-interval stamps).  The time
    base from one dwell corrects the DMM's rate in every dwell; the FRFs fitted with delay give
    back both sensors."""
    rng = np.random.default_rng(8)
    grid = np.logspace(-1, 3, 13)
    ppm = 80.0
    hf_dwells, lf_dwells, starts = [], [], []
    for i, f in enumerate(grid):
        start = 100.0 * i
        dwell = max(3.0 / f, 0.5)
        fs_ref = 4000.0 if f < 300 else 10_000.0
        t_ref = start + np.arange(int(dwell * fs_ref)) / fs_ref
        freqs = np.array([f, 2 * f, 3 * f])
        amps = np.array([np.exp(1j * rng.uniform(-np.pi, np.pi)), 0.02, 0.01j])
        keep = freqs < 0.45 * fs_ref
        ref = tones(t_ref, freqs[keep], amps[keep]) + 0.01 * rng.normal(size=t_ref.size)
        t_dmm = start + np.arange(int(dwell * 5000.0)) / 5000.0  # stamps: trigger + n × nominal interval
        t_true = t_dmm + ppm * 1e-6 * (t_dmm - start)
        v = tones(t_true, freqs[keep], mhd(freqs[keep]) * amps[keep]) + 2e-5 * rng.normal(size=t_dmm.size)
        t_lf = start + (np.arange(int(dwell * 2000.0)) + 0.5) / 2000.0
        box = np.sinc(freqs / 2000.0)  # an interval mean of a sine over 0.5 ms
        w = tones(t_lf, freqs, lf(freqs) * box * amps) + 0.002 * rng.normal(size=t_lf.size)
        hf_dwells.append((t_ref, ref, t_dmm, v, f))
        if f < 1000:  # 1 kHz is the Nyquist of the 2 kHz frames: no information there
            lf_dwells.append((t_ref, ref, t_lf, w, f))
        starts.append(start)
    t_ref, ref, t_dmm, v, f = hf_dwells[-1]  # 1 kHz: 80 ppm drifts 0.25 rad over the 0.5 s dwell
    tb = estimate_time_base(t_ref, ref, t_dmm, v, f, 0.05)
    assert abs(tb.rate_ppm - ppm) < 3 * tb.rate_std_ppm and tb.rate_std_ppm < 2.0
    raw_hf = hf_dwells
    hf_dwells = [(a, b, apply_time_base(c, tb, epoch_s=s0), d, e) for (a, b, c, d, e), s0 in zip(hf_dwells, starts)]
    hf_frf, lf_frf = frf(hf_dwells), frf(lf_dwells)
    hf_fit = fit_transfer_function(hf_frf.freq_hz, hf_frf.h, "highpass", fit_delay=True, weights=hf_frf.weights)
    assert hf_fit.order == 1 and hf_fit.corner_hz == pytest.approx(2.5, rel=0.01)
    assert hf_fit.delay_s == pytest.approx(20e-6, abs=3e-6)
    band = lf_frf.freq_hz <= 200  # above, the LF output is buried in its noise and the frame roll-off
    lf_fit = fit_transfer_function(lf_frf.freq_hz[band], lf_frf.h[band], "lowpass", fit_delay=True,
                                   weights=lf_frf.weights[band])
    assert lf_fit.order == 2 and lf_fit.corner_hz == pytest.approx(40.0, rel=0.03)
    assert lf_fit.delay_s == pytest.approx(6e-4, abs=5e-5)
    # uncorrected, the DMM's drift (≈ +20 µs at the middle of the short high-frequency dwells)
    # cancels the MHD's 20 µs apparent delay
    raw = frf(raw_hf)
    raw_fit = fit_transfer_function(raw.freq_hz, raw.h, "highpass", fit_delay=True, weights=raw.weights)
    assert abs(raw_fit.delay_s - 20e-6) > 10e-6
