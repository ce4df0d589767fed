"""The pair's alignment finds an LF sensor whose samples are means over their interval (an
integrating converter), on pairs from the independent generator (tests/analysis/fusion_pairs.py),
and does not see one where the sensor samples."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.signal import freqs

from bench.analysis.fusion_alignment import fit_and_align, inverse_sinc_taps, undo_interval_mean
from tests.analysis.fusion_pairs import analog_prototype, draw_spec, make_pair


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
