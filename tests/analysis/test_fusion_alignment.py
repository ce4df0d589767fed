"""The pair's alignment finds an LF sensor whose samples are means over their interval (an
integrating converter), on pairs from the independent generator (bench.testing.generators.fusion_pairs),
and does not see one where the sensor samples."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.signal import freqs

from bench.analysis.fusion._alignment import fit_and_align, inverse_sinc_taps, undo_interval_mean
from bench.analysis.fusion._models import fit_transfer_function, min_frf_points
from bench.testing.generators.fusion_pairs import Sensor, analog_prototype, draw_spec, make_pair


def quiet_pair(seed: int, averaging: bool):
    """Pair ``seed``'s regime with low noise, no spikes or dropouts, the LF sensor averaging or not."""
    spec = draw_spec(seed, 80_000)
    hf = dataclasses.replace(spec.hf, noise_sd=1e-4 * abs(spec.hf.gain), spikes=(), dropouts=())
    lf = dataclasses.replace(spec.lf, noise_sd=1e-4 * spec.lf.gain, spikes=(), dropouts=(), averaging=averaging)
    return dataclasses.replace(spec, hf=hf, lf=lf)


@pytest.mark.parametrize("seed", [5, 8, 21, 23])
def test_an_averaging_lf_sensor_is_found_and_its_model_recovered(seed):
    found = {}
    for averaging in (True, False):
        spec = quiet_pair(seed, averaging)
        rec = make_pair(spec)
        _, alignment = fit_and_align(rec["t"], rec["hf"], rec["lf"], rec["ref"], spec.tones_hz, spec.rate_hz)
        found[averaging] = alignment
        # the fitted model's gain at the tones is the sensor's own (an overdamped 2nd order may stand
        # for a 1st: compare responses, not corners)
        true_gain = np.abs(freqs(*analog_prototype(spec.lf), worN=2 * np.pi * spec.tones_hz)[1])
        assert np.abs(alignment.lf_fit.response(spec.tones_hz)) == pytest.approx(true_gain, rel=2e-3)
    assert found[True].lf_interval_mean and not found[False].lf_interval_mean
    assert found[True].to_dict()["lf_interval_mean"] is True


def test_the_inverse_of_an_interval_mean_restores_a_tone():
    taps = inverse_sinc_taps()
    theta = np.linspace(0.0, 2 * np.pi * 0.25, 200)
    response = taps[0] + 2 * sum(c * np.cos(m * theta) for m, c in enumerate(taps[1:], start=1))
    assert np.max(np.abs(response * np.sinc(theta / (2 * np.pi)) - 1)) < 1e-6
    fs, f = 1000.0, 180.0
    fine = np.arange(16 * 4000) / (16 * fs)
    x = np.sin(2 * np.pi * f * fine)
    means = x.reshape(-1, 16).mean(axis=1)  # each sample the mean of its interval, stamped at its middle
    t_mid = fine.reshape(-1, 16).mean(axis=1)
    restored = undo_interval_mean(means)
    truth = np.sin(2 * np.pi * f * t_mid)
    inner = slice(10, -10)
    assert np.max(np.abs(means[inner] - truth[inner])) > 0.05  # the droop is there (sinc(0.18) ≈ 0.947)
    assert np.max(np.abs(restored[inner] - truth[inner])) < 2e-3  # 16-point means are not the exact interval mean
    with pytest.raises(ValueError, match="must be"):
        undo_interval_mean(np.ones((3, 3)))


@pytest.mark.parametrize("seed", [13, 38])
def test_the_cleaned_copy_replaces_spikes_and_only_them(seed):
    """Pairs with spikes on both sensors (seed 13 also an HF upper pole and an averaging LF
    sensor: both look-ahead filters run after the cleaning): the cleaned copy is the record the
    same pair without its spikes would give, to a few noise σ; the raw record keeps them."""
    spec = draw_spec(seed, 80_000)
    assert spec.hf.spikes and spec.lf.spikes and not spec.hf.dropouts and not spec.lf.dropouts
    calm = dataclasses.replace(spec, hf=dataclasses.replace(spec.hf, spikes=()),
                               lf=dataclasses.replace(spec.lf, spikes=()))
    rec, rec_calm = make_pair(spec), make_pair(calm)
    fit_part = slice(0, int(0.4 * rec["t"].size))
    aligned, alignment = fit_and_align(rec["t"], rec["hf"], rec["lf"], rec["ref"], spec.tones_hz, spec.rate_hz,
                                       fit_part)
    calm_aligned, calm_alignment = fit_and_align(rec_calm["t"], rec_calm["hf"], rec_calm["lf"], rec_calm["ref"],
                                                 spec.tones_hz, spec.rate_hz, fit_part)
    assert calm_alignment.outliers_replaced == (0, 0) and calm_aligned["hf_clean"] is calm_aligned["hf"]
    assert alignment.outliers_replaced == (len({i for i, _ in spec.hf.spikes}), len({i for i, _ in spec.lf.spikes}))
    assert alignment.to_dict()["outliers_replaced"]["hf"] == alignment.outliers_replaced[0]
    assert aligned["t_s"].size == calm_aligned["t_s"].size
    for name, sensor in (("hf", spec.hf), ("lf", spec.lf)):
        spike = min(abs(s) for _, s in sensor.spikes)
        assert np.max(np.abs(aligned[name] - calm_aligned[name])) > 0.3 * spike  # the raw record keeps them
        assert np.max(np.abs(aligned[f"{name}_clean"] - calm_aligned[name])) < 8 * sensor.noise_sd + 1e-3 * spike


def test_six_tones_identify_a_second_order_hf_sensor_with_its_upper_pole():
    """Six FRF points (the fewest a pair carries) fit an order-2 high-pass, a delay and an upper
    pole — five real parameters on twelve numbers; below six the fit refuses."""
    sensor = Sensor("highpass", 2, 0.54, 0.97, -0.62, 926.0, 0.0, 0.0, 0.0, 0.0, False)
    tones = np.array([0.225, 0.925, 3.95, 15.65, 72.2, 308.8])
    delay_s = 2.8e-5
    g = freqs(*analog_prototype(sensor), worN=2 * np.pi * tones)[1] * np.exp(-2j * np.pi * tones * delay_s)
    fit = fit_transfer_function(tones, g, "highpass", max_order=2, fit_delay=True, upper_pole=True)
    assert fit.upper_hz == pytest.approx(926.0, rel=1e-3) and fit.delay_s == pytest.approx(delay_s, rel=1e-2)
    assert fit.model.corner_hz == pytest.approx(0.54, rel=1e-3) and fit.model.gain == pytest.approx(-0.62, rel=1e-4)
    assert min_frf_points(2, True, True) == 6 and min_frf_points(1, True, True) == 5
    with pytest.raises(ValueError, match="at least 6"):
        fit_transfer_function(tones[:5], g[:5], "highpass", max_order=2, fit_delay=True, upper_pole=True)
