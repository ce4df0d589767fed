"""Robust Allan deviation and the checks of each fitted term against the curve: outliers
flagged at the stated false-alarm rate, N recovered under spikes, K (not R) named for a
rate random walk, a forced-wrong fit named, the white term of a low-passed output."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.signal import lfilter

from bench.analysis.allan import DEFAULT_FALSE_ALARM, overlapping_adev, screen_outliers

FS_HZ = 100.0
N_TRUE = 0.01  # deg/√s


def white(rng: np.random.Generator, n: int) -> np.ndarray:
    return N_TRUE * math.sqrt(FS_HZ) * rng.normal(size=n)


def spiked(rng: np.random.Generator, y: np.ndarray, fraction: float) -> np.ndarray:
    """Isolated spikes of 10–50 σ, random sign, at ``fraction`` of the samples."""
    hit = rng.random(y.size) < fraction
    size = rng.uniform(10.0, 50.0, y.size) * rng.choice([-1.0, 1.0], y.size) * np.std(y)
    return y + hit * size


def n_within_interval(result) -> bool:
    lo, hi = result.checks["N"].fit_interval_input
    return lo <= N_TRUE <= hi


def spiky_records(trials: int = 20):
    rng = np.random.default_rng(2024)
    for _ in range(trials):
        fraction = rng.uniform(0.05, 0.10)
        y = spiked(rng, white(rng, 2**14), fraction)
        yield fraction, overlapping_adev(y, FS_HZ, robust=True), overlapping_adev(y, FS_HZ)


def test_robust_recovers_n_under_spikes_where_the_plain_estimate_does_not():
    """Over 20 records with 5–10 % spikes: the robust N within 5 % of the truth in all, the plain
    N outside its 99 % interval in all (spikes of 10–50 σ inflate it several-fold); the result
    says what fraction was flagged, and the plain one points to --robust."""
    for fraction, robust, plain in spiky_records():
        assert robust.coefficients["N"].fit_input == pytest.approx(N_TRUE, rel=0.05)
        assert not n_within_interval(plain)
        assert robust.robust and robust.outliers is not None
        assert robust.outliers.fraction == pytest.approx(fraction, abs=0.02)
        assert robust.notes[0].startswith(f"{robust.outliers.fraction:.1%} of samples are outliers")
        assert any("isolated outliers" in note and "--robust" in note for note in plain.notes)


@pytest.mark.xfail(strict=True, reason="replacing a sample by its neighbour median biases the Allan variance "
                   "by about the flagged fraction (low at τ0, high at long τ): N comes out 1.5–3 % low, "
                   "1–3 of its standard errors (module docstring of _robust); in its 99 % interval in 13 of 20")
def test_robust_n_lies_in_its_interval_in_nine_records_of_ten():
    hits = sum(n_within_interval(robust) for _, robust, _ in spiky_records())
    assert hits >= 18, hits


def test_clean_white_noise_is_flagged_at_most_at_the_stated_rate():
    """300 short clean records: records with any flag stay within the binomial bound of the
    stated 1 % (P(Binom(300, 0.01) ≥ 9) = 0.4 %)."""
    rng = np.random.default_rng(7)
    flagged = sum(screen_outliers(rng.normal(size=256)).n_flagged > 0 for _ in range(300))
    assert DEFAULT_FALSE_ALARM == 0.01
    assert flagged <= 8, flagged


@settings(max_examples=6, deadline=None)
@given(corner_s=st.floats(0.3, 3.0), seed=st.integers(0, 2**16))
def test_white_plus_rate_random_walk_names_k_not_r(corner_s, seed):
    """A rate random walk rises with slope +1/2: K is fitted and agrees with the curve; no ramp R
    is reported (left out or zero), whatever the last, scattered octaves do."""
    rng = np.random.default_rng(seed)
    n = 2**16
    k_true = math.sqrt(3.0) * N_TRUE / corner_s
    y = white(rng, n) + np.cumsum(k_true / math.sqrt(FS_HZ) * rng.normal(size=n))
    res = overlapping_adev(y, FS_HZ)
    assert res.coefficients["K"].fit_input > 0 and res.checks["K"].status == "agrees"
    assert res.checks["K"].shows == "K"
    assert not res.coefficients["R"].fit_input
    assert not any(c.status in ("disagrees", "other slope") for c in res.checks.values()), res.notes


def rrw_record(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    n = 2**16
    return white(rng, n) + np.cumsum(math.sqrt(3.0) * N_TRUE / math.sqrt(FS_HZ) * rng.normal(size=n))


def test_a_ramp_forced_onto_a_rate_random_walk_is_named():
    res = overlapping_adev(rrw_record(3), FS_HZ, terms=("N", "R"))
    check = res.checks["R"]
    assert check.status == "other slope" and check.shows == "K"
    assert check.message.startswith("R fitted") and "that is K (+1/2), not R (+1)" in check.message
    assert check.message in res.notes


def test_a_missing_term_is_named_with_the_read_off_interval():
    res = overlapping_adev(rrw_record(4), FS_HZ, terms=("N",))
    check = res.checks["K"]
    assert check.status == "disagrees"
    lo, hi = check.read_off_interval_input
    assert lo < check.read_off_input < hi
    assert check.message.startswith("K not fitted but the curve's slope +1/2 region reads")
    assert "the fit does not describe the curve there" in check.message


def test_a_bias_instability_too_large_for_the_flat_region_is_named():
    """B forced with N alone onto white noise: the fit puts B where the curve has no plateau."""
    rng = np.random.default_rng(5)
    res = overlapping_adev(white(rng, 2**15), FS_HZ, terms=("B",))
    assert res.checks["B"].status in ("disagrees", "other slope")
    assert res.checks["B"].message.startswith("B fitted")


@pytest.mark.parametrize("phi", [0.17, 0.4])
def test_low_passed_white_noise_gives_n_at_its_long_tau_level(phi):
    """White noise through a first-order low-pass (lag-1 correlation φ): N = σ_e·√τ0/(1 − φ)
    lies in its 99 % interval over 8 records, and a note says the output is correlated."""
    hits = 0
    for seed in range(8):
        e = np.random.default_rng(100 + seed).normal(size=2**16)
        y = lfilter([1.0], [1.0, -phi], e) * 0.1
        res = overlapping_adev(y, FS_HZ)
        n_true = 0.1 / math.sqrt(FS_HZ) / (1.0 - phi)
        lo, hi = res.checks["N"].fit_interval_input
        hits += lo <= n_true <= hi
        assert res.lag1 == pytest.approx(phi, abs=0.03) and res.lag1_model == res.lag1
        assert any("correlated sample to sample" in note for note in res.notes)
    assert hits >= 7


def test_white_noise_is_not_called_correlated():
    calls = sum(overlapping_adev(np.random.default_rng(s).normal(size=4096), FS_HZ).lag1_model != 0
                for s in range(40))
    assert calls <= 3  # 1 % per record: P(Binom(40, 0.01) ≥ 4) < 1e-4


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [({"false_alarm": 0.0}, "false_alarm = 0.0 must lie in (0, 1)"),
     ({"false_alarm": 1.5}, "false_alarm = 1.5 must lie in (0, 1)")],
)
def test_bad_false_alarm(kwargs, message):
    with pytest.raises(ValueError, match=r"false_alarm = .* must lie in \(0, 1\)") as err:
        overlapping_adev(np.ones(100), 1.0, **kwargs)
    assert message in str(err.value)
    with pytest.raises(ValueError, match="must lie in"):
        screen_outliers(np.ones(100), **kwargs)
