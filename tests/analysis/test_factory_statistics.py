"""Wilson intervals against statsmodels, control charts and Western Electric rules against
hand-computed cases, decision risk against cases whose answer is known in closed form."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.stats import norm
from statsmodels.stats.proportion import proportion_confint

from bench.analysis.quality import wilson_interval
from bench.analysis.quality._control_chart import XBAR_R_CONSTANTS, individuals_chart, western_electric, xbar_r_charts
from bench.analysis.quality._decision_risk import decision_risk, model_rates, overall_risk


@given(st.integers(1, 5000).flatmap(lambda n: st.tuples(st.integers(0, n), st.just(n))),
       st.sampled_from([0.8, 0.9, 0.95, 0.99]))
def test_wilson_interval_is_statsmodels(counts, confidence):
    k, n = counts
    got = wilson_interval(k, n, confidence)
    low, high = proportion_confint(k, n, alpha=1 - confidence, method="wilson")
    assert got.low == pytest.approx(low, abs=1e-12) and got.high == pytest.approx(high, abs=1e-12)
    assert got.low <= got.p <= got.high


def test_wilson_hand_case_and_refusals():
    # 0 of 10 at 95 %: [0, z²/(n + z²)] = [0, 3.8415/13.8415]
    z2 = norm.ppf(0.975) ** 2
    assert wilson_interval(0, 10).high == pytest.approx(z2 / (10 + z2))
    assert wilson_interval(0, 0).low == 0.0 and wilson_interval(0, 0).high == 1.0
    with pytest.raises(ValueError, match="successes=11 must be <= trials=10"):
        wilson_interval(11, 10)
    with pytest.raises(ValueError, match="confidence"):
        wilson_interval(1, 10, 1.0)


def test_individuals_chart_by_hand():
    x = np.array([10.0, 12.0, 11.0, 13.0, 12.0])
    chart = individuals_chart(x)
    # moving ranges 2, 1, 2, 1: MR̄ = 1.5; σ̂ = 1.5/1.128; centre 11.6
    sigma = 1.5 / 1.128
    assert chart.centre == pytest.approx(11.6) and chart.sigma == pytest.approx(sigma)
    assert chart.ucl == pytest.approx(11.6 + 3 * sigma) and chart.lcl == pytest.approx(11.6 - 3 * sigma)
    assert chart.violations == ()


def test_western_electric_rules_each_fire_where_written():
    assert western_electric([0, 0, 3.5, 0], 0.0, 1.0) == ((2, 1),)
    assert western_electric([2.5, 0, 2.5], 0.0, 1.0) == ((2, 2),)
    assert western_electric([2.5, 0, -2.5], 0.0, 1.0) == ()  # opposite sides: no rule 2
    assert western_electric([1.5, 1.5, 0, 1.5, 1.5], 0.0, 1.0) == ((4, 3),)
    eight = western_electric([0.5] * 8, 0.0, 1.0)
    assert eight == ((7, 4),)
    nine = western_electric([-0.5] * 9, 0.0, 1.0)
    assert nine == ((7, 4), (8, 4))
    assert western_electric([0.5, -0.5] * 10, 0.0, 1.0) == ()


def test_xbar_r_by_hand():
    groups = np.array([[1.0, 3.0, 2.0], [2.0, 4.0, 3.0], [1.0, 2.0, 3.0]])
    xbar, rng = xbar_r_charts(groups)
    a2, d3, d4, d2 = XBAR_R_CONSTANTS[3]
    # means 2, 3, 2 → X̿ = 7/3; ranges 2, 2, 2 → R̄ = 2
    assert xbar.centre == pytest.approx(7 / 3) and xbar.ucl == pytest.approx(7 / 3 + a2 * 2)
    assert rng.centre == 2.0 and rng.ucl == pytest.approx(d4 * 2) and rng.lcl == 0.0
    assert xbar.sigma == pytest.approx(2 / d2 / np.sqrt(3))
    with pytest.raises(ValueError, match="n in 2..10"):
        xbar_r_charts(np.ones((3, 11)))


def test_a_stable_normal_process_rarely_flags_and_a_shift_is_caught():
    rng = np.random.default_rng(3)
    x = rng.normal(0, 1, 400)
    stable = individuals_chart(x)
    assert abs(stable.sigma - 1) < 0.1 and len(stable.flagged) < 0.05 * x.size
    shifted = individuals_chart(np.concatenate([x[:200], x[200:] + 2.0]), baseline=200)
    assert {r for i, r in shifted.violations if i >= 200} >= {2, 3, 4}
    assert shifted.centre == pytest.approx(x[:200].mean())
    with pytest.raises(ValueError, match="baseline=1 not in 2..400"):
        individuals_chart(x, baseline=1)


def test_decision_risk_counts_and_a_perfect_instrument_needs_no_guard_band():
    true = np.array([-5.0, -3.0, 0.0, 3.0, 5.0, 3.9, 4.1])
    measured = np.array([-5.0, -3.0, 0.0, 3.0, 5.0, 4.1, 3.9])  # the last two cross the limit
    r = decision_risk(measured, true, -4.0, 4.0)
    assert r.false_accept.successes == 1 and r.false_reject.successes == 1
    assert r.nonconforming.successes == 3 and r.accepted.successes == 4


def test_guard_band_meets_the_target_in_closed_form():
    # Uniform truth on a fine grid across ±2 around the limit 1 (one-sided high limit), error
    # N(0, 0.5²): PFA(g) = 1/N Σ_{t>1} Φ((1 − g − t)/0.5); the band solves PFA = target.
    t = np.linspace(-1.0, 3.0, 4001)
    rng = np.random.default_rng(0)
    e = rng.normal(0, 0.5, t.size)
    e = (e - e.mean()) / e.std(ddof=1) * 0.5  # exactly the modelled bias 0, sd 0.5
    r = decision_risk(t + e, t, None, 1.0, target=0.02)
    assert r.error_sd == pytest.approx(0.5) and abs(r.error_bias) < 1e-12
    assert r.pfa_model > 0.02 and r.pfa_guarded == pytest.approx(0.02, abs=1e-6)
    outside = t[t > 1.0]
    direct = norm.cdf((1.0 - r.guard_band - outside) / 0.5).sum() / t.size
    assert direct == pytest.approx(0.02, abs=1e-6)
    assert r.pfr_guarded > r.pfr_model  # the band's cost
    assert model_rates(t, 0.0, 0.5, None, 1.0, r.guard_band * 0.9)[0] > 0.02  # and it is the smallest


def test_overall_risk():
    fa, fr = overall_risk([True, True, False, False], [True, False, True, False])
    assert fa.successes == 1 and fr.successes == 1 and fa.trials == 4
    _, fr = overall_risk([False, False], [True, True], undecidable=[True, False])
    assert fr.successes == 1  # the unit rejected on an unscored measurement is not counted
