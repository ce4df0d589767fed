"""Overlapping Allan deviation: equality with allantools (NBS14 included), recovery of the
IEEE 952 terms from simulated noise, confidence-interval coverage, bad input."""

from __future__ import annotations

import json
import math

import allantools
import numpy as np
import pytest
from allantools import ci as at_ci
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import nnls
from scipy.signal import lfilter
from scipy.stats import chi2

import bench.analysis.allan._core as allan_core
from bench.analysis.allan import overlapping_adev
from bench.analysis.allan._noise import B_FACTOR, design_matrix, nnls_enumerated
from bench.analysis.allan._stats import adev_interval, chi2_ppf, edf_greenhall

REL = 1e-10


def nbs14_1000() -> np.ndarray:
    """The NBS14 1000-point frequency set: Lehmer generator of Riley's test suite."""
    n = [1234567890]
    for _ in range(999):
        n.append((16807 * n[-1]) % 2147483647)
    assert n[1:4] == [395529916, 1209410747, 633705974]  # the values printed in the paper
    return np.array(n, dtype=float) / 2147483647.0


def record(kind: str, n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    white = rng.normal(size=n)
    if kind == "white":
        return 3.0 + white
    if kind == "random-walk":  # a wandering rate: the case a running sum handles worst
        return 100.0 + np.cumsum(rng.normal(size=n)) + 1e-3 * white
    return white + 0.02 * np.cumsum(rng.normal(size=n)) + 1e-4 * np.arange(n)  # mixed with a ramp


def assert_rel(ours: np.ndarray, ref: np.ndarray, rel: float = REL) -> None:
    np.testing.assert_allclose(ours, ref, rtol=rel, atol=0)


# --- equality with allantools ---------------------------------------------------------

@pytest.mark.parametrize("kind", ["white", "random-walk", "mixed"])
@pytest.mark.parametrize(("n", "rate_hz"), [(1000, 1.0), (65_537, 100.0), (40_000, 3.7)])
def test_octave_equals_allantools_oadev(kind, n, rate_hz):
    y = record(kind, n, seed=n)
    ours = overlapping_adev(y, rate_hz, "octave", unit=None)
    taus, dev, _, ns = allantools.oadev(y, rate=rate_hz, data_type="freq", taus="octave")
    assert_rel(ours.tau_s, taus)
    assert_rel(ours.adev, dev)
    np.testing.assert_array_equal(ours.n_terms, ns)


@pytest.mark.parametrize("kind", ["white", "random-walk"])
def test_any_tau_and_log_list_equal_allantools(kind):
    y = record(kind, 30_001, seed=5)
    tau = np.array([0.1, 0.3, 0.7, 1.3, 2.9, 10.0, 77.7, 1500.0])
    ours = overlapping_adev(y, 10.0, tau, unit=None)
    taus, dev, _, _ = allantools.oadev(y, rate=10.0, data_type="freq", taus=tau)
    assert_rel(ours.tau_s, taus)
    assert_rel(ours.adev, dev)
    log = overlapping_adev(y, 10.0, "log", points_per_decade=7, unit=None)
    assert np.all(np.diff(log.tau_s) > 0) and log.tau_s[0] == 0.1
    ref = allantools.oadev(y, rate=10.0, data_type="freq", taus=log.tau_s)
    assert_rel(log.adev, ref[1])


def test_phase_input_equals_allantools_phase():
    rng = np.random.default_rng(11)
    angle = np.cumsum(0.01 + rng.normal(size=20_000)) * 1e-3  # integrated rate, 1 kHz
    ours = overlapping_adev(angle, 1000.0, data_type="phase", unit=None)
    taus, dev, _, _ = allantools.oadev(angle, rate=1000.0, data_type="phase", taus="octave")
    assert_rel(ours.tau_s, taus)
    assert_rel(ours.adev, dev, rel=1e-9)  # phase differences carry the angle's rounding


def test_nbs14_10_point_published_values():
    freq = [892.0, 809.0, 823.0, 798.0, 671.0, 644.0, 883.0, 903.0, 677.0]
    ours = overlapping_adev(freq, 1.0, [1, 2], unit=None)
    np.testing.assert_allclose(ours.adev, [91.22945, 85.95287], rtol=1e-6)
    assert_rel(ours.adev, allantools.oadev(np.array(freq), data_type="freq", taus=[1, 2])[1])


def test_nbs14_1000_point_published_values():
    freq = nbs14_1000()
    ours = overlapping_adev(freq, 1.0, [1, 10, 100], unit=None)
    np.testing.assert_allclose(ours.adev, [2.922319e-01, 9.159953e-02, 3.241343e-02], rtol=2e-6)
    assert_rel(ours.adev, allantools.oadev(freq, data_type="freq", taus=[1, 10, 100])[1])
    octave = overlapping_adev(freq, 1.0, unit=None)
    assert_rel(octave.adev, allantools.oadev(freq, data_type="freq", taus="octave")[1])
    phase = overlapping_adev(allantools.frequency2phase(freq, 1.0), 1.0, [1, 10, 100], data_type="phase", unit=None)
    np.testing.assert_allclose(phase.adev, [2.922319e-01, 9.159953e-02, 3.241343e-02], rtol=2e-6)


def longdouble_sums(y: np.ndarray, ms: np.ndarray) -> np.ndarray:
    """Σ of squared second differences of the running sum, in extended precision."""
    yl = y.astype(np.longdouble)
    s = np.concatenate([[np.longdouble(0)], np.cumsum(yl - yl.mean())])
    return np.array([np.sum((s[2 * k:] - 2 * s[k:s.size - k] + s[:s.size - 2 * k]) ** 2) for k in ms]).astype(float)


def test_octave_engine_is_exact_where_a_running_sum_loses_digits():
    """A pure random walk of rate on a large offset against an extended-precision reference."""
    n = 100_000
    y = 1e4 + np.cumsum(np.random.default_rng(2).normal(size=n))
    ours = overlapping_adev(y, 1.0, unit=None)
    m = ours.averaging_factor
    ref = np.sqrt(longdouble_sums(y, m) / (2 * (n + 1 - 2 * m) * m.astype(float) ** 2))
    assert_rel(ours.adev, ref, rel=1e-13)


@pytest.mark.parametrize("chunk", [16, 256, 4096])
@pytest.mark.parametrize("kind", ["white", "random-walk", "mixed"])
def test_octave_engine_paths(kind, chunk):
    """Small chunks drive every path of the engine — chunk totals with edge pieces
    (m < chunk) and whole-chunk lookups (m ≥ chunk), the per-chunk direct sum, and the
    switch to direct levels with in-place writes — against extended precision."""
    y = record(kind, 5001, seed=chunk)
    levels = allan_core.octave_levels(y.size)
    ms = 2 ** np.arange(levels)
    assert_rel(allan_core.octave_sums(y, levels, chunk=chunk), longdouble_sums(y, ms), rel=1e-12)
    assert_rel(allan_core.cumsum_sums(y, ms, chunk=chunk), longdouble_sums(y, ms), rel=1e-9)


# --- statistics against scipy / allantools ---------------------------------------------

@pytest.mark.parametrize("p", [0.001, 0.025, 0.158655, 0.5, 0.841345, 0.975, 0.999])
def test_chi2_quantile_matches_scipy(p):
    dof = np.array([0.4, 1.0, 2.2, 7.0, 31.5, 480.0, 9_999.0, 99_999.0, 2e5, 4e7])
    np.testing.assert_allclose(chi2_ppf(p, dof), chi2.ppf(p, dof), rtol=1e-7)


def test_greenhall_edf_matches_allantools():
    for alpha in (2, 1, 0, -1, -2):
        for n_phase in (10, 101, 1001, 100_001):
            for m in (1, 2, 3, 8, 33, 34, 100, 1000, 4096):
                if n_phase - 2 * m < 2 or (alpha == 2 and math.ceil((n_phase - 2 * m) / m) <= 2):
                    continue  # allantools has no formula for white PM at r ≤ 2
                ref = at_ci.edf_greenhall(alpha=alpha, d=2, m=m, N=n_phase, overlapping=True, modified=False)
                assert edf_greenhall(alpha, m, n_phase) == pytest.approx(ref, rel=1e-12), (alpha, n_phase, m)


def test_interval_is_the_chi_squared_interval():
    lo, hi = adev_interval(np.array([2.0]), np.array([12.5]), 0.9)[0]
    assert lo == pytest.approx(2.0 * math.sqrt(12.5 / chi2.ppf(0.95, 12.5)), rel=1e-9)
    assert hi == pytest.approx(2.0 * math.sqrt(12.5 / chi2.ppf(0.05, 12.5)), rel=1e-9)


def test_enumerated_nnls_reaches_scipy_residual():
    rng = np.random.default_rng(0)
    for _ in range(100):
        tau = np.geomspace(10 ** rng.uniform(-3, 0), 10 ** rng.uniform(2, 5), int(rng.integers(8, 40)))
        a = design_matrix(tau) * rng.uniform(0.1, 10, size=(tau.size, 1))
        b = a @ (rng.uniform(0, 1, 5) * (rng.uniform(size=5) < 0.6)) * (1 + 0.1 * rng.normal(size=tau.size))
        x, _ = nnls_enumerated(a, b)
        ref, _ = nnls(a, b, maxiter=1000)
        assert np.all(x >= 0)
        assert np.linalg.norm(a @ x - b) <= np.linalg.norm(a @ ref - b) * (1 + 1e-9) + 1e-12 * np.linalg.norm(b)


# --- recovery of simulated noise ------------------------------------------------------

@settings(max_examples=8, deadline=None)
@given(log_n=st.floats(-3.0, -1.0), corner_s=st.floats(0.5, 5.0), seed=st.integers(0, 2**16))
def test_white_plus_random_walk_recovers_n_and_k(log_n, corner_s, seed):
    """Angle random walk N within 10 % (fit and read-off) over drawn values; rate random walk
    K within 4 of its stated standard errors, which are under 5 % of K — the record is ≥ 2000
    corner times long so that the K region spans three decades.  (K's scatter from one record
    is 1.5–4 %: a fixed 10 % bound fails on the tail of honest draws, e.g. seed 8696.)"""
    fs, n = 100.0, 2**20
    n_true = 10.0 ** log_n                     # deg/s·√s = deg/√s
    k_true = math.sqrt(3.0) * n_true / corner_s  # deg/s/√s; N²/τ = K²τ/3 at the corner
    rng = np.random.default_rng(seed)
    y = n_true * math.sqrt(fs) * rng.normal(size=n) + np.cumsum(k_true / math.sqrt(fs) * rng.normal(size=n))
    res = overlapping_adev(y, fs, unit="dps")
    n_fit, k_fit = res.coefficients["N"], res.coefficients["K"]
    assert n_fit.fit_input == pytest.approx(n_true, rel=0.10)
    assert k_fit.fit_std_input < 0.05 * k_true
    assert n_fit.read_off_input == pytest.approx(n_true, rel=0.10)
    assert n_fit.fit == pytest.approx(60.0 * n_fit.fit_input) and n_fit.unit == "deg/sqrt(h)"
    assert k_fit.fit == pytest.approx(216000.0 * k_fit.fit_input) and k_fit.unit == "deg/h/sqrt(h)"
    assert abs(k_fit.fit_input - k_true) < 4 * k_fit.fit_std_input  # the stated uncertainty is honest


def gauss_markov_sum(rng, n: int, fs: float, b_true: float) -> tuple[np.ndarray, np.ndarray]:
    """Flicker-like rate: Gauss–Markov terms, two per decade of correlation time from
    0.03 s to 1e5 s, each of variance B²·ln(√10)/π, so their two-sided PSD sum
    approximates B²/(2π f) (IEEE 952's bias-instability spectrum) across the band."""
    times = 10.0 ** np.arange(-1.5, 5.01, 0.5)
    var = b_true ** 2 * math.log(math.sqrt(10.0)) / math.pi
    y = np.zeros(n)
    for t_c in times:
        a = math.exp(-1.0 / (fs * t_c))
        start = [a * math.sqrt(var) * rng.normal()]  # stationary from the first sample
        y += lfilter([1.0], [1.0, -a], rng.normal(size=n) * math.sqrt(var * (1 - a * a)), zi=start)[0]
    return y, times


@pytest.mark.parametrize("seed", [1, 4])
def test_flicker_bias_instability_recovered(seed):
    """B of a sum of Gauss–Markov terms: fit within 10 %; the classical read-off (curve
    minimum / 0.664) within 50 % — the minimum of a scattered flicker plateau sits low."""
    fs, n, b_true = 10.0, 2**19, 2e-3  # deg/s
    rng = np.random.default_rng(seed)
    flicker, _ = gauss_markov_sum(rng, n, fs, b_true)
    n_true = B_FACTOR * b_true * math.sqrt(3.0)  # ARW meets the plateau at τ = 3 s
    res = overlapping_adev(flicker + n_true * math.sqrt(fs) * rng.normal(size=n), fs, unit="dps")
    b = res.coefficients["B"]
    assert b.fit_input == pytest.approx(b_true, rel=0.10)
    assert b.read_off_input == pytest.approx(b_true, rel=0.50)
    assert b.fit == pytest.approx(3600.0 * b.fit_input) and b.unit == "deg/h"
    assert res.coefficients["N"].fit_input == pytest.approx(n_true, rel=0.10)
    assert set(res.noise_alpha.tolist()) >= {0, -1}  # white FM early, flicker FM on the plateau


@pytest.mark.parametrize("quantizer", ["white", "rounding"])
def test_quantization_and_ramp_recovered(quantizer):
    """Q and a rate ramp R from an angle record.  IEEE 952's quantization is white angle
    noise of variance q²/12 (Q = q/√12): recovered within 10 % with N and R.  Rounding a
    slowly moving angle gives a correlated error the model does not describe; the fit
    still lands Q and R within 20 % (the model allowance keeps it from bending)."""
    fs, n = 200.0, 2**19
    rng = np.random.default_rng(8)
    t = np.arange(n + 1) / fs
    step_deg, n_true, r_true = 1e-3, 2e-4, 1e-5  # quantum (deg), deg/√s, deg/s²
    angle = np.concatenate([[0.0], np.cumsum(n_true * math.sqrt(fs) * rng.normal(size=n) / fs)]) + r_true * t**2 / 2
    if quantizer == "white":
        measured, tol = angle + step_deg * rng.uniform(-0.5, 0.5, size=n + 1), 0.10
    else:
        measured, tol = np.round(angle / step_deg) * step_deg, 0.20
    res = overlapping_adev(measured, fs, data_type="phase", unit="dps")
    assert res.coefficients["Q"].fit_input == pytest.approx(step_deg / math.sqrt(12.0), rel=tol)
    assert res.coefficients["R"].fit_input == pytest.approx(r_true, rel=tol)
    if quantizer == "white":
        assert res.coefficients["N"].fit_input == pytest.approx(n_true, rel=tol)
    assert res.coefficients["Q"].unit == "arcsec" and res.coefficients["R"].unit == "deg/h^2"


def test_units_follow_the_input_unit():
    y = np.random.default_rng(3).normal(size=50_000) * 0.05
    dps = overlapping_adev(y, 100.0, unit="dps")
    dph = overlapping_adev(y * 3600.0, 100.0, unit="dph")
    for name in ("N", "B", "K"):
        assert dph.coefficients[name].fit == pytest.approx(dps.coefficients[name].fit, rel=1e-9, abs=1e-15)
    assert dph.units["adev"] == "deg/h" and dps.units["N"] == "deg/sqrt(h)"
    acc = overlapping_adev(y, 100.0, unit="g").coefficients["N"]
    assert acc.unit == "g/sqrt(Hz)" and acc.alt_unit == "m/s/sqrt(h)"
    assert acc.to_dict()["alt"]["value"] == pytest.approx(acc.fit_input * 9.80665 * 60.0)
    assert overlapping_adev(y, 100.0, unit="mg").coefficients["N"].fit == pytest.approx(acc.fit / 1000.0)


# --- confidence intervals -------------------------------------------------------------

@pytest.mark.parametrize("kind", ["white", "random-walk"])
def test_interval_covers_the_true_adev_at_the_nominal_rate(kind):
    """Over 200 records the 68.3 % (and 95 %) intervals hold the exact ADEV about that often.

    Exact Allan variance per sample: white, σ²/m; random walk of rate with unit steps,
    (2m² + 1)/(6m).  Tolerance: 4 binomial standard deviations per τ, 3 for the pool."""
    trials, n = 200, 2048
    hits68 = hits95 = 0
    for seed in range(trials):
        rng = np.random.default_rng(10_000 + seed)
        y = rng.normal(size=n) if kind == "white" else np.cumsum(rng.normal(size=n))
        res = overlapping_adev(y, 1.0, unit=None)
        m = res.averaging_factor.astype(float)
        true = np.sqrt(1.0 / m) if kind == "white" else np.sqrt((2 * m * m + 1) / (6 * m))
        hits68 = hits68 + ((res.adev_ci[:, 0] <= true) & (true <= res.adev_ci[:, 1]))
        ci95 = adev_interval(res.adev, res.edf, 0.95)
        hits95 = hits95 + ((ci95[:, 0] <= true) & (true <= ci95[:, 1]))
    assert np.all(res.noise_alpha == (0 if kind == "white" else -2))
    rate68, rate95 = hits68 / trials, hits95 / trials
    per_tau = 4 * math.sqrt(0.683 * 0.317 / trials)
    assert np.all(np.abs(rate68 - 0.683) < per_tau), rate68
    assert abs(rate68.mean() - 0.683) < 3 * math.sqrt(0.683 * 0.317 / trials), rate68
    assert abs(rate95.mean() - 0.95) < 3 * math.sqrt(0.95 * 0.05 / trials), rate95


# --- result form and bad input --------------------------------------------------------

def test_to_dict_is_strict_json_with_units():
    res = overlapping_adev(np.random.default_rng(0).normal(size=5000), 50.0)
    doc = json.loads(json.dumps(res.to_dict(), allow_nan=False))
    assert len(doc["tau"]) == len(doc["adev"]) == len(doc["adev_ci"])
    assert all(lo <= a <= hi for a, (lo, hi) in zip(doc["adev"], doc["adev_ci"]))
    assert set(doc["coefficients"]) == {"Q", "N", "B", "K", "R"}
    assert doc["units"]["adev"] == "deg/s" and doc["coefficients"]["K"]["unit"] == "deg/h/sqrt(h)"
    flat = overlapping_adev(np.full(100, 2.5), 1.0).to_dict()  # constant: zeros, read-offs absent
    json.dumps(flat, allow_nan=False)
    assert flat["adev"] == [0.0] * len(flat["tau"]) and flat["coefficients"]["N"]["read_off"] is None
    assert any("constant" in note for note in flat["notes"])


@pytest.mark.parametrize(
    ("y", "rate", "kwargs", "message"),
    [
        (np.ones(5), 1.0, {}, "the record has 5 samples; at least 8 rate samples are required"),
        (np.r_[np.ones(20), np.nan], 1.0, {}, "1 non-finite values (first at sample index 20)"),
        (np.ones(20), 0.0, {}, "rate_hz = 0.0 must be a finite number > 0"),
        (np.ones(20), -5.0, {}, "rate_hz = -5.0 must be a finite number > 0"),
        (np.ones(20), float("inf"), {}, "rate_hz = inf must be a finite number > 0"),
        (np.ones(100), 10.0, {"taus": [0.5, 5.1]}, "τ = 5.1 s is outside the allowed range [0.1, 5] s"),
        (np.ones(100), 10.0, {"taus": [0.01]}, "τ = 0.01 s is outside the allowed range [0.1, 5] s"),
        (np.ones(100), 10.0, {"taus": "decade"}, "taus = 'decade' must be 'octave', 'log'"),
        (np.ones(100), 10.0, {"taus": "log", "points_per_decade": 0},
         "points_per_decade = 0 must be an integer in [1, 100]"),
        (np.ones(100), 1.0, {"data_type": "freq"}, "data_type = 'freq' is not one of 'rate', 'phase'"),
        (np.ones(100), 1.0, {"unit": "deg/s"}, "unit = 'deg/s' is not supported (allowed: 'dps'"),
        (np.ones(100), 1.0, {"confidence": 1.5}, "confidence = 1.5 must lie in (0, 1)"),
        (np.ones(100), 1.0, {"terms": ("N", "X")}, "terms = ('N', 'X') must be distinct names from"),
        (np.ones((10, 2)), 1.0, {}, "must be one-dimensional, got shape (10, 2)"),
    ],
)
def test_bad_input_names_value_and_range(y, rate, kwargs, message):
    with pytest.raises(ValueError) as err:
        overlapping_adev(y, rate, **kwargs)
    assert message in str(err.value)
