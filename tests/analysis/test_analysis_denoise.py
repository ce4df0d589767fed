"""Wavelet denoising (Document A, step 2) against a direct PyWavelets computation."""

from __future__ import annotations

import numpy as np
import pytest
import pywt
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.analysis.startup._denoise import choose_level, choose_wavelet, wavelet_denoise

FAST = settings(max_examples=30, deadline=None, derandomize=True)


def reference_denoise(x: np.ndarray, wavelet: str, level: int) -> tuple[np.ndarray, float, float]:
    """Document A written out independently: σ from level-1 details, universal λ, soft rule by hand."""
    coeffs = pywt.wavedec(x, wavelet, mode="symmetric", level=level)
    sigma = np.median(np.abs(coeffs[-1])) / 0.6745
    lam = np.sqrt(2 * sigma**2 * np.log(len(x)))
    out = [coeffs[0]]
    for d in coeffs[1:]:
        out.append(np.where(np.abs(d) >= lam, np.sign(d) * (np.abs(d) - lam), 0.0))
    return pywt.waverec(out, wavelet, mode="symmetric")[: len(x)], sigma, lam


@st.composite
def traces(draw):
    n = draw(st.integers(16, 3000))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    t = np.arange(n)
    x = draw(st.floats(-5, 5)) * np.exp(-t / draw(st.floats(2, 500))) + rng.normal(0, draw(st.floats(1e-3, 10)), n)
    wavelet = draw(st.sampled_from(["db1", "db2", "db4", "db6", "db8"]))
    max_level = max(1, pywt.dwt_max_level(n, pywt.Wavelet(wavelet).dec_len))
    return x, wavelet, draw(st.integers(1, max_level))


@pytest.mark.filterwarnings("ignore:Level value of 1 is too high")  # short trace, long filter: allowed
@FAST
@given(traces())
def test_denoise_equals_direct_pywavelets_computation(case):
    x, wavelet, level = case
    res = wavelet_denoise(x, wavelet, level)
    ref, sigma, lam = reference_denoise(x, wavelet, level)
    assert res.sigma == pytest.approx(sigma, rel=1e-12)
    assert res.threshold == pytest.approx(lam, rel=1e-12)
    np.testing.assert_allclose(res.denoised, ref, rtol=0, atol=1e-10 * (1 + np.max(np.abs(x))))
    assert res.thresholded_levels == tuple(range(1, level + 1))
    assert (res.wavelet, res.level, res.n) == (wavelet, level, x.size)


@FAST
@given(st.integers(16, 200_000))
def test_default_wavelet_and_level_come_from_the_length(n):
    wavelet = choose_wavelet(n)
    level = choose_level(n, wavelet)
    expected = "db8" if n >= 2**14 else "db6" if n >= 2**11 else "db4" if n >= 2**8 else "db2"
    assert wavelet == expected
    assert 1 <= level <= max(1, pywt.dwt_max_level(n, pywt.Wavelet(wavelet).dec_len))
    assert level <= max(1, int(np.log2(n)) // 2)


def test_defaults_are_reported_and_used():
    x = np.random.default_rng(1).normal(size=5000)
    res = wavelet_denoise(x)
    ref, _, _ = reference_denoise(x, "db6", choose_level(5000, "db6"))
    assert res.wavelet == "db6" and res.level == choose_level(5000, "db6")
    np.testing.assert_allclose(res.denoised, ref, atol=1e-12)


def test_sigma_estimates_white_noise_and_smooth_signal_is_recovered():
    rng = np.random.default_rng(7)
    n = 8192
    t = np.linspace(0, 1, n)
    clean = 3 * np.exp(-t / 0.05) + np.sin(2 * np.pi * 3 * t)
    noisy = clean + rng.normal(0, 0.2, n)
    res = wavelet_denoise(noisy)
    assert res.sigma == pytest.approx(0.2, rel=0.05)  # the transient does not leak into level 1
    rms_raw = np.sqrt(np.mean((noisy - clean) ** 2))
    rms_dn = np.sqrt(np.mean((res.denoised - clean) ** 2))
    assert rms_dn < rms_raw / 3


def test_input_untouched_and_result_read_only():
    x = np.random.default_rng(2).normal(size=300)
    before = x.copy()
    res = wavelet_denoise(x)
    np.testing.assert_array_equal(x, before)
    with pytest.raises(ValueError):
        res.denoised[0] = 1.0


@pytest.mark.parametrize(
    ("x", "kwargs", "match"),
    [
        (np.ones(10), {}, "at least 16"),
        (np.r_[np.ones(40), np.nan], {}, "non-finite"),
        (np.ones((20, 2)), {}, "one-dimensional"),
        (np.ones(100), {"wavelet": "sym4"}, "Daubechies"),
        (np.ones(100), {"wavelet": "db2", "level": 9}, r"level = 9 must be an integer in \[1, 5\]"),
        (np.ones(100), {"wavelet": "db2", "level": 0}, r"\[1, 5\]"),
    ],
)
def test_bad_input_names_value_and_range(x, kwargs, match):
    with pytest.raises(ValueError, match=match):
        wavelet_denoise(x, **kwargs)
