"""Long records: searched on two scales — block means for the slow effects, a full-rate window
for the fast ones (:func:`bench.discovery.workflow.discover`, ``SEARCH_POINTS``).

The records here are drawn with numpy, apart from the catalogue's own ``draw``: a warm-up the
block means see, a line above their Nyquist frequency (they hold its alias), a sensor's output
filter they cannot resolve, white noise; and plain white noise for the false-name count.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.signal import lfilter

from bench.discovery.criterion import FALSE_NAME_RATE
from bench.discovery.data import Record
from bench.discovery.effects import CATALOGUE
from bench.discovery.model import Model, base_model
from bench.discovery.stochastic import fit_stochastic
from bench.discovery.workflow import SEARCH_POINTS, discover, params_std
from bench.testing.discovery_nulls import binomial_allowance

RATE_HZ = 100.0
#: five blocks' worth of the search budget: means of 5 samples (20 Hz)
N_LONG = 5 * SEARCH_POINTS - 960
SD = 1e-3


@settings(max_examples=40, deadline=None)
@given(n=st.integers(4, 400), m_frac=st.floats(0, 1), seed=st.integers(0, 2 ** 16))
def test_block_means_average_every_column_and_keep_the_time_since_power_on(n, m_frac, seed):
    rng = np.random.default_rng(seed)
    m = 1 + int(m_frac * (n // 2 - 1))
    t = 5.0 + np.cumsum(rng.uniform(0.5, 1.5, n))
    rec = Record(t_s=t, y=rng.standard_normal(n), temp_c=rng.uniform(20, 30, n))
    c = rec.block_means(m)
    k = n // m
    assert c.n == k
    for name in ("t_s", "y", "temp_c"):
        np.testing.assert_allclose(getattr(c, name), getattr(rec, name)[:k * m].reshape(k, m).mean(axis=1))
    np.testing.assert_allclose(c.column("t_on"), (t - t[0])[:k * m].reshape(k, m).mean(axis=1))


@pytest.mark.parametrize("m", [0, -1, 2.0, True, 51])
def test_block_means_name_a_bad_block_length(m):
    rec = Record(t_s=np.arange(100.0), y=np.zeros(100))
    with pytest.raises(ValueError, match=r"block length m = .*allowed: an integer in \[1, 50\]"):
        rec.block_means(m)


def _long(seed: int, effects: bool) -> tuple[Record, float, float]:
    rng = np.random.default_rng([17, seed])
    t = np.arange(N_LONG) / RATE_HZ
    f = 11.0 + 8.0 * rng.random()  # above the means' Nyquist frequency (10 Hz): they hold its alias
    phase = 2 * np.pi * rng.random() - np.pi
    y = 0.1 + SD * rng.standard_normal(N_LONG)
    if effects:
        y += 0.3 * SD * np.exp(-t / 60.0) + 0.3 * SD * np.sin(2 * np.pi * f * t + phase)
    return Record(t_s=t, y=y), f, phase


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2 ** 16), shift=st.floats(0.05, 500.0))
def test_a_term_moved_to_an_earlier_start_is_the_same_term(seed, shift):
    """``Effect.time_shifted``: every additive waveform effect timed by the record's clock, its
    parameters moved to a record starting ``shift`` s earlier, predicts there what it predicted
    on its own record, sample for sample, up to a constant (the bias's part); moved back
    (``-shift``) it predicts its own term again."""
    rng = np.random.default_rng(seed)
    t = 1000.0 + np.arange(4000) / 20.0
    own = Record(t_s=t, y=SD * rng.standard_normal(t.size))
    earlier = Record(t_s=np.concatenate([[t[0] - shift], t]), y=np.zeros(t.size + 1))
    checked = 0
    for e in (CATALOGUE[eid] for eid in sorted(CATALOGUE)):
        if not (e.waveform and e.stage == "additive" and "t" in e.inputs and "gyro" in e.kinds):
            continue
        p = e.draw(rng, own, kind="gyro")
        q = e.time_shifted(p, shift)
        scale = max(1e-12, float(np.ptp(e.term(p, own))))
        there, here = e.term(q, earlier)[1:], e.term(p, own)
        np.testing.assert_allclose(there - there.mean(), here - here.mean(), atol=1e-7 * scale, err_msg=e.id)
        back = e.term(e.time_shifted(q, -shift), own)
        np.testing.assert_allclose(back - back.mean(), here - here.mean(), atol=1e-7 * scale, err_msg=e.id)
        checked += 1
    assert checked >= 3  # a jump, a drift, a line


@pytest.mark.parametrize("seed", range(3))
def test_a_long_record_names_its_slow_effect_on_block_means_and_its_fast_one_on_the_window(seed):
    """A warm-up of 0.3 σ (τ 60 s) and an 11–19 Hz line of 0.3 σ in 40 000 samples: the warm-up
    named from the block means (of 5 samples, 20 Hz), the line — which the means hold only as its
    alias below 10 Hz — at its own frequency, refined on the whole record within 3 σ of the
    truth; nothing else named and nothing left unexplained."""
    rec, f, phase = _long(seed, True)
    d = discover(rec, Model(base_model("gyro")))
    got = {s.effect_id: s for s in d.steps}
    assert set(got) == {"warmup_exponential", "sinusoidal_interference"}, (list(got), d.notes)
    assert got["warmup_exponential"].scale == "block means"
    line = got["sinusoidal_interference"]  # named on either scale: at its alias on the means, unfolded
    assert abs(line.params["freq_hz"] - f) <= 3 * line.params_std["freq_hz"], (line.params, line.params_std, f)
    # its amplitude and phase at the record's first sample too: a window's phase moved to the record
    assert abs(line.params["amplitude"] - 0.3 * SD) <= 3 * line.params_std["amplitude"], (line.params, line.params_std)
    dphi = (line.params["phase_rad"] - phase + np.pi) % (2 * np.pi) - np.pi
    assert abs(dphi) <= 3 * line.params_std["phase_rad"], (line.params, line.params_std, phase)
    assert not d.unexplained, d.unexplained
    assert any("block means" in n and "full-rate window" in n for n in d.notes), d.notes
    assert d.residual_final.size == rec.n  # the final residual is the whole record's


def test_long_null_records_name_nothing_beyond_the_stated_rate():
    """White Gaussian noise, 40 000 samples, two searches at α/2 each: records that name
    anything within the binomial allowance of α."""
    records = 6
    named = [[s.effect_id for s in discover(_long(100 + k, False)[0], Model(base_model("gyro"))).steps]
             for k in range(records)]
    hits = [n for n in named if n]
    assert len(hits) <= binomial_allowance(records, FALSE_NAME_RATE), hits


@pytest.mark.parametrize("seed", range(2))
def test_a_process_the_block_means_cannot_resolve_is_refitted_on_the_window(seed):
    """A sensor's output filter (white through a 0.05-s first-order low-pass, 2 × the white
    level) under a warm-up, in 40 000 samples at 100 Hz: the block means (of 5 samples) see the
    filter only as a Gauss–Markov at the shortest τ they resolve; the window refits it, and the
    final Gauss–Markov's σ and τ lie within 3 of their standard errors of the truth, with no
    parameter reported at the edge of its range."""
    rng = np.random.default_rng([23, seed])
    t = np.arange(N_LONG) / RATE_HZ
    phi = np.exp(-1 / (RATE_HZ * 0.05))
    gm = lfilter([1.0], [1.0, -phi], rng.standard_normal(N_LONG) * 2 * SD * np.sqrt(1 - phi ** 2))
    y = 0.1 + SD * rng.standard_normal(N_LONG) + gm + 3 * SD * np.exp(-t / 60.0)
    d = discover(Record(t_s=t, y=y), Model(base_model("gyro")))
    got = {s.effect_id: s for s in d.steps}
    assert "gauss_markov" in got, (list(got), d.notes)
    g = got["gauss_markov"]
    for name, truth in (("sigma", 2 * SD), ("tau_s", 0.05)):
        assert abs(g.params[name] - truth) <= 3 * g.params_std[name], (g.params, g.params_std)
    assert not any("at the edge" in n for n in d.notes), d.notes


@pytest.mark.parametrize("seed", range(2))
def test_a_jump_outside_the_window_is_kept_from_the_block_means(seed):
    """A bias jump of 0.75 σ in the first or last third of 40 000 samples, outside the full-rate
    window: named from the block means, held while the window is searched (the window cannot see
    it, so it must not drop it), its size and time within 3 of their standard errors."""
    rng = np.random.default_rng([29, seed])
    t = np.arange(N_LONG) / RATE_HZ
    at = float(t[-1]) * (rng.uniform(0.1, 0.3) if seed % 2 == 0 else rng.uniform(0.7, 0.9))
    y = 0.1 + SD * rng.standard_normal(N_LONG) + 0.75 * SD * (t > at)
    d = discover(Record(t_s=t, y=y), Model(base_model("gyro")))
    got = {s.effect_id: s for s in d.steps}
    assert set(got) == {"bias_jump"}, (list(got), d.notes)
    j = got["bias_jump"]
    assert abs(j.params["size_1"] - 0.75 * SD) <= 3 * j.params_std["size_1"], (j.params, j.params_std)
    assert abs(j.params["time_1_s"] - at) <= max(3 * j.params_std["time_1_s"], 1 / RATE_HZ), (j.params, at)


@pytest.mark.parametrize("seed", range(2))
def test_a_window_addition_the_whole_record_does_not_want_is_withdrawn(seed):
    """A bias that follows the logged temperature through a 100-s lag, 60 000 samples at 100 Hz:
    the lag is named from the block means; the window (82 s of it) sees the held lag's misfit at
    full rate as a slope, but the whole record, weighed under the same criterion, does not want a
    drift — so the lag is named alone, its coefficient within 3 of its standard errors."""
    rng = np.random.default_rng([31, seed])
    n, dt = 60_000, 0.01
    t = np.arange(n) * dt
    temp = 25.0 + 15.0 * np.clip(t / 300.0, 0.0, 1.0)
    a = np.exp(-dt / 100.0)
    element = lfilter([1 - a], [1, -a], temp, zi=[25.0 * a])[0]
    y = 0.01 + 2e-3 * rng.standard_normal(n) + 3e-4 * (element - 25.0)
    d = discover(Record(t_s=t, y=y, temp_c=temp), Model(base_model("gyro")))
    got = {s.effect_id: s for s in d.steps}
    assert set(got) == {"thermal_lag"}, (list(got), d.notes)
    lag = got["thermal_lag"]
    assert abs(lag.params["coef_per_c"] - 3e-4) <= 3 * lag.params_std["coef_per_c"], (lag.params, lag.params_std)


def test_a_random_walks_standard_error_is_its_bootstrap_spread():
    """A named rate random walk reports a standard error (its parametric bootstrap's spread), not
    NaN; over draws of the walk the estimate lies within 2 of its standard errors of the truth as
    often as a 95 % interval should (the binomial allowance at 1 %)."""
    k, n, dt, draws = 2e-5, 8000, 0.8, 20
    misses = 0
    for seed in range(draws):
        rng = np.random.default_rng([41, seed])
        y = 7e-4 * rng.standard_normal(n) + np.cumsum(rng.normal(0.0, k * np.sqrt(dt), n))
        rec = Record(t_s=np.arange(n) * dt, y=y)
        model = Model(base_model("gyro"), (("rate_random_walk", {"k_per_rs": k}),))
        std = params_std(model, rec, 0)["k_per_rs"]
        assert np.isfinite(std) and std > 0, std
        fit = fit_stochastic(y - y.mean(), dt, CATALOGUE["rate_random_walk"], bootstrap=True)
        misses += abs(fit.params["k_per_rs"] - k) > 2 * fit.params_std["k_per_rs"]
    assert misses <= binomial_allowance(draws, 0.05), misses
