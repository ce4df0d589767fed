"""Turn-on to turn-on repeatability: closed forms with equal noise, exact coverage of the
Q-profile interval, day-to-day against statsmodels' MixedLM (REML)."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
import statsmodels.formula.api as smf
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from bench.analysis.turn_on import turn_on_repeatability


@settings(max_examples=40, deadline=None)
@given(st.integers(3, 30), st.floats(0.1, 10.0), st.floats(0.0, 10.0), st.integers(0, 2**31 - 1))
def test_equal_within_run_noise_gives_the_closed_forms(k, u, sigma_r, seed):
    rng = np.random.default_rng(seed)
    b = 100.0 + rng.normal(0, sigma_r, k) + rng.normal(0, u, k)
    r = turn_on_repeatability(b, np.full(k, u))
    s = float(np.std(b, ddof=1))
    assert r.raw_sd.sd == pytest.approx(s, rel=1e-12)
    assert r.raw_sd.low == pytest.approx(s * math.sqrt((k - 1) / stats.chi2.ppf(0.975, k - 1)), rel=1e-12)
    assert r.repeatability.sd == pytest.approx(math.sqrt(max(s**2 - u**2, 0.0)), rel=1e-7, abs=1e-9 * u)
    # the Q-profile bounds solve (k − 1)s²/(σ² + u²) = χ² quantiles
    hi2 = (k - 1) * s**2 / stats.chi2.ppf(0.025, k - 1) - u**2
    assert r.repeatability.high == pytest.approx(math.sqrt(max(hi2, 0.0)), rel=1e-6, abs=1e-9 * u)
    assert r.within_run_rms == pytest.approx(u)
    assert r.p_value_excess == pytest.approx(stats.chi2.sf((k - 1) * s**2 / u**2, k - 1), rel=1e-9)


def test_q_profile_interval_covers_at_its_confidence_with_unequal_noise():
    """600 drawn sets of 5 – 20 cycles with within-run σ varying 10× between cycles: the 95 %
    interval holds the true σ_r at the binomial rate (±2.7 % at 3σ; measured: see the
    message, and docs/METHODS.md for 10⁴ draws)."""
    rng = np.random.default_rng(11)
    hits, n = 0, 600
    for _ in range(n):
        k = int(rng.integers(5, 21))
        sigma_r = 10 ** rng.uniform(-1, 1)
        u = 10 ** rng.uniform(-1, 0, k) * sigma_r * rng.uniform(0.2, 3.0)
        b = rng.normal(0, sigma_r, k) + rng.normal(0, 1, k) * u
        r = turn_on_repeatability(b, u).repeatability
        hits += r.low <= sigma_r <= r.high
    assert 0.923 <= hits / n <= 0.977, hits / n


def test_no_excess_scatter_gives_zero_repeatability_and_a_large_p_value():
    b = np.array([1.0, 1.1, 0.9, 1.05, 0.95])
    r = turn_on_repeatability(b, np.full(5, 1.0))
    assert r.repeatability.sd == 0.0 and r.repeatability.low == 0.0
    assert r.p_value_excess > 0.9
    assert r.mean.value == pytest.approx(1.0)


def test_day_to_day_matches_mixedlm_reml_on_a_balanced_design():
    """Equal within-run σ, 4 days × 6 cycles: the within-day σ² + u² and σ_d² are the ANOVA
    estimators, which are REML's when positive."""
    rng = np.random.default_rng(5)
    days, per_day, u = 4, 6, 0.5
    day = np.repeat(np.arange(days), per_day)
    b = 10.0 + rng.normal(0, 2.0, days)[day] + rng.normal(0, 1.0, day.size) + rng.normal(0, u, day.size)
    r = turn_on_repeatability(b, np.full(b.size, u), day=[f"day {d}" for d in day])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = smf.mixedlm("b ~ 1", {"b": b, "day": day}, groups=day).fit(reml=True)
    assert r.days is not None
    assert r.days.within_day.sd**2 + u**2 == pytest.approx(m.scale, rel=1e-4)
    assert r.days.day_to_day.sd**2 == pytest.approx(float(m.cov_re.iloc[0, 0]), rel=1e-3)
    assert r.days.day_labels == ("day 0", "day 1", "day 2", "day 3")
    assert r.days.within_day.dof == b.size - days and r.days.day_to_day.dof == days - 1
    assert r.days.day_to_day.low <= r.days.day_to_day.sd <= r.days.day_to_day.high


def test_within_day_interval_covers_with_day_effects_present():
    """Day effects do not leak into the within-day σ_r: its pooled Q is exact (400 draws of
    2 – 5 days × 2 – 5 cycles; binomial band ±3.3 % at 3σ)."""
    rng = np.random.default_rng(8)
    hits, n = 0, 400
    for _ in range(n):
        days = int(rng.integers(2, 6))
        day = np.repeat(np.arange(days), rng.integers(2, 6, days))
        u = rng.uniform(0.2, 1.0, day.size)
        b = rng.normal(0, 3.0, days)[day] + rng.normal(0, 1.0, day.size) + rng.normal(0, 1, day.size) * u
        w = turn_on_repeatability(b, u, day=day.tolist()).days.within_day
        hits += w.low <= 1.0 <= w.high
    assert 0.917 <= hits / n <= 0.983, hits / n


@pytest.mark.parametrize("args, kwargs, message", [
    (([1.0], [1.0]), {}, "bias must be a 1-D array of length ≥ 2"),
    (([1.0, 2.0], [1.0, 0.0]), {}, "bias_std[1] = 0.0 outside the allowed range (0, ∞)"),
    (([1.0, 2.0], [1.0, 1.0]), dict(confidence=1.0), "confidence = 1.0 outside the allowed range [0.5, 0.999]"),
    (([1.0, 2.0, 3.0], [1.0] * 3), dict(day=[1, 1]), "day has 2 entries; one per cycle (3) is needed"),
    (([1.0, 2.0, 3.0], [1.0] * 3), dict(day=[1, 1, 1]), "day names 1 distinct day(s) for 3 cycles: allowed 2 … 2"),
    (([1.0, 2.0, 3.0], [1.0] * 3), dict(day=[1, 2, 3]), "day names 3 distinct day(s) for 3 cycles"),
])
def test_bad_input_names_the_value_and_the_range(args, kwargs, message):
    with pytest.raises(ValueError) as err:
        turn_on_repeatability(*args, **kwargs)
    assert message in str(err.value)
