"""Tumble calibration: exact recovery, identifiability, statsmodels WLS, coverage of stated errors."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import statsmodels.api as sm
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.analysis.tumble._fit import (
    DEFAULT_MOUNT,
    PARAM_NAMES,
    fit_tumble,
    specific_force_iapo_g,
    tumble_positions,
)
from sim.physics.accelerometer import AccelerometerParams, indicated_acceleration_g


def magnitude(lo: float, hi: float):
    """Signed value with log-uniform magnitude in [lo, hi] (realistic QA-2000-class spreads)."""
    return st.tuples(st.sampled_from([-1.0, 1.0]), st.floats(math.log(lo), math.log(hi))).map(
        lambda t: t[0] * math.exp(t[1]))


unit_params = st.builds(
    AccelerometerParams,
    k0_g=magnitude(1e-5, 4e-3), k1_ma_per_g=st.floats(1.20, 1.46),
    k2_g_per_g2=magnitude(1e-6, 1e-4), k3_g_per_g3=magnitude(1e-6, 1e-4),
    delta_o_rad=magnitude(1e-6, 1e-3), delta_p_rad=magnitude(1e-6, 1e-3),
    kip_g_per_g2=magnitude(1e-6, 1e-4), kio_g_per_g2=magnitude(1e-6, 1e-4))


def plan_force(n: int, planes: int, g_over_g0: float = 1.0) -> np.ndarray:
    pos = tumble_positions(n, planes)
    return specific_force_iapo_g(pos[:, 0], pos[:, 1], g_over_g0)


def current_a(p: AccelerometerParams, f: np.ndarray) -> np.ndarray:
    return p.k1_a_per_g * indicated_acceleration_g(p, f)


def assert_rel(est: float, true: float, rtol: float = 1e-9) -> None:
    assert abs(est - true) <= rtol * abs(true), (est, true, abs(est - true) / abs(true))


@settings(max_examples=30, deadline=None, derandomize=True)
@given(unit_params, st.sampled_from([(8, 2), (12, 2), (24, 2), (16, 2)]), st.floats(0.995, 1.005))
def test_noiseless_two_planes_recover_every_parameter(p, plan, g_over_g0):
    f = plan_force(*plan, g_over_g0)
    r = fit_tumble(f, current_a(p, f))
    assert r.param_names == PARAM_NAMES and r.not_identifiable == {}
    for name in PARAM_NAMES:
        assert_rel(r.params[name].value, getattr(p, name))


@settings(max_examples=20, deadline=None, derandomize=True)
@given(unit_params, st.sampled_from([8, 12, 24]))
def test_noiseless_one_plane_recovers_the_ia_oa_terms(p, n):
    f = plan_force(n, 1)
    r = fit_tumble(f, current_a(p, f) * 1e3, output_unit_per_ma=1.0)  # output in mA
    assert set(r.not_identifiable) == {"delta_o_rad", "kip_g_per_g2"}  # a_p ≡ 0 in this plane
    for name in ("k0_g", "k1_ma_per_g", "k2_g_per_g2", "k3_g_per_g3", "delta_p_rad", "kio_g_per_g2"):
        assert_rel(r.params[name].value, getattr(p, name))


@settings(max_examples=20, deadline=None, derandomize=True)
@given(unit_params, st.sampled_from([1, 2]))
def test_four_point_recovers_the_identifiable_combinations(p, planes):
    """a_i³ = a_i at the quadrants: the fit's K1 is K1(1+K3), and every ratio to K1 shrinks by it."""
    f = plan_force(4, planes)
    r = fit_tumble(f, current_a(p, f))
    alias = 1.0 + p.k3_g_per_g3
    assert_rel(r.params["k1_ma_per_g"].value, p.k1_ma_per_g * alias)
    for name in ("k0_g", "k2_g_per_g2", "delta_p_rad") + (("delta_o_rad",) if planes == 2 else ()):
        assert_rel(r.params[name].value, getattr(p, name) / alias)


def test_identifiability_lists():
    expected = {
        (4, 1): {"k3_g_per_g3": "not separable from k1_ma_per_g", "delta_o_rad": "zero",
                 "kip_g_per_g2": "zero", "kio_g_per_g2": "zero"},
        (8, 1): {"delta_o_rad": "zero", "kip_g_per_g2": "zero"},
        (4, 2): {"k3_g_per_g3": "not separable from k1_ma_per_g", "kip_g_per_g2": "zero",
                 "kio_g_per_g2": "zero"},
        (12, 2): {}, (24, 2): {},
    }
    y_dof = {(4, 1): 0, (8, 1): 2, (4, 2): 3, (12, 2): 16, (24, 2): 40}
    p = AccelerometerParams()
    for plan, dropped in expected.items():
        f = plan_force(*plan)
        r = fit_tumble(f, current_a(p, f))
        assert set(r.not_identifiable) == set(dropped), plan
        for name, why in dropped.items():
            assert why in r.not_identifiable[name], (plan, r.not_identifiable[name])
        assert r.dof == y_dof[plan]
        assert set(r.param_names) | set(r.not_identifiable) == set(PARAM_NAMES)
    four = plan_force(4, 1)
    assert "a_i^3 = 1·a_i" in fit_tumble(four, current_a(p, four)).not_identifiable["k3_g_per_g3"]


def test_position_scatter_keeps_designed_aliases_out():
    """Read-back angles 1 mdeg off the plan still leave a_i³ aliased with a_i at 4 points."""
    pos = tumble_positions(4, 1) + np.random.default_rng(3).normal(0, 1e-3, (4, 2))
    f = specific_force_iapo_g(pos[:, 0], pos[:, 1])
    r = fit_tumble(f, current_a(AccelerometerParams(), f))
    assert "k3_g_per_g3" in r.not_identifiable and r.dof == 0


def test_plane_geometry_of_the_default_mount():
    f = plan_force(8, 2)
    ia_oa, ia_pa = f[:8], f[8:]
    assert np.all(ia_oa[:, 1] == 0.0) and np.all(ia_pa[:, 2] == 0.0)
    np.testing.assert_allclose(np.linalg.norm(f, axis=1), 1.0, rtol=1e-15)
    np.testing.assert_array_equal(f[0], [1.0, 0.0, 0.0])  # level: IA up
    np.testing.assert_array_equal(f[4], [-1.0, 0.0, 0.0])  # outer 180°: IA down
    np.testing.assert_array_equal(f[2], [0.0, 0.0, 1.0])  # outer 90°, inner 0: +g along OA
    np.testing.assert_array_equal(f[10], [0.0, 1.0, 0.0])  # outer 90°, inner 90: +g along PA
    mount = DEFAULT_MOUNT[[1, 0, 2]] * [1, 1, -1]  # IA along x, PA along z, OA along −y
    g = specific_force_iapo_g([90.0], [90.0], mount=mount)
    np.testing.assert_allclose(g, [[1.0, 0.0, 0.0]], atol=1e-15)


def statsmodels_fit(f, y, sigma):
    ai, ap, ao = f.T
    x = np.column_stack([np.ones_like(ai), ai, ap, ao, ai**2, ai * ap, ai * ao, ai**3])
    return sm.WLS(y, x, weights=1.0 / sigma**2).fit(cov_type="fixed scale", cov_kwds={"scale": 1.0})


def test_weighted_fit_matches_statsmodels():
    rng = np.random.default_rng(11)
    p = AccelerometerParams(k0_g=1e-3, k2_g_per_g2=3e-4, k3_g_per_g3=2e-4, delta_o_rad=-2e-4,
                            delta_p_rad=1e-4, kip_g_per_g2=1e-4, kio_g_per_g2=-1e-4)
    f = plan_force(12, 2)
    sigma = p.k1_a_per_g * 1e-5 * rng.uniform(0.5, 3.0, len(f))  # unequal σ: weights matter
    y = current_a(p, f) + rng.normal(0, sigma)
    ours = fit_tumble(f, y, sigma)
    ref = statsmodels_fit(f, y, sigma)
    np.testing.assert_allclose(ours.coefficients, ref.params, rtol=1e-9, atol=1e-18)
    cov_c = ref.cov_params()
    c = ref.params
    # Delta method by hand on statsmodels' covariance: K1 = c1/u, K0 = c0/c1, δp = −c3/c1 ...
    jac = np.zeros((8, 8))
    jac[0, 0], jac[0, 1] = 1 / c[1], -c[0] / c[1] ** 2
    jac[1, 1] = 1 / 1e-3
    for row, j, sign in ((2, 4, 1), (3, 7, 1), (4, 2, 1), (5, 3, -1), (6, 5, 1), (7, 6, 1)):
        jac[row, j], jac[row, 1] = sign / c[1], -sign * c[j] / c[1] ** 2
    ref_std = np.sqrt(np.diag(jac @ cov_c @ jac.T))
    np.testing.assert_allclose([ours.params[n].std for n in PARAM_NAMES], ref_std, rtol=1e-7)
    np.testing.assert_allclose(np.sqrt(np.diag(ours.covariance)), ref_std, rtol=1e-7)
    assert ours.sigma_source == "stated" and ours.chi2_per_dof == pytest.approx(ref.ssr / ref.df_resid)
    # Unweighted with σ from the residuals: statsmodels OLS standard errors of the coefficients.
    ols = sm.OLS(y, statsmodels_fit(f, y, sigma).model.exog).fit()
    r = fit_tumble(f, y)
    assert r.sigma_source == "residuals" and r.noise_sigma == pytest.approx(math.sqrt(ols.scale), rel=1e-9)
    assert r.params["k1_ma_per_g"].std == pytest.approx(ols.bse[1] / 1e-3, rel=1e-7)
    assert r.coverage_factor_95 == pytest.approx(2.1199, abs=1e-4)  # Student t, 16 dof


def coverage(p: AccelerometerParams, f: np.ndarray, sigma_g: float, draws: int, seed: int,
             stated: bool) -> dict[str, float]:
    rng = np.random.default_rng(seed)
    clean = current_a(p, f)
    sigma = np.full(len(f), sigma_g * p.k1_a_per_g)
    inside = dict.fromkeys(PARAM_NAMES, 0)
    for _ in range(draws):
        r = fit_tumble(f, clean + rng.normal(0, sigma), sigma if stated else None)
        k95 = r.coverage_factor_95
        assert k95 is not None, "σ stated or residual degrees of freedom left: the intervals exist"
        for name, est in r.params.items():
            assert est.std is not None
            inside[name] += abs(est.value - getattr(p, name)) <= k95 * est.std
    return {name: k / draws for name, k in inside.items() if name in r.params}


@settings(max_examples=4, deadline=None, derandomize=True)
@given(unit_params, st.sampled_from([1e-6, 1e-5, 1e-4]), st.integers(0, 2**32 - 1))
def test_truth_within_1_96_stated_errors_in_95_percent(p, sigma_g, seed):
    """Known σ: coverage of ±1.96 σ over 1000 seeded noise draws lies in 92-98 % for every
    parameter (binomial sd 0.7 %: a 3 % miss is a real bias, not chance)."""
    cov = coverage(p, plan_force(12, 2), sigma_g, 1000, seed, stated=True)
    assert len(cov) == 8
    for name, c in cov.items():
        assert 0.92 <= c <= 0.98, (name, c)


def test_residual_sigma_with_student_t_covers():
    p = AccelerometerParams()
    cov = coverage(p, plan_force(8, 1), 2e-5, 1000, 5, stated=False)  # dof 2: t = 4.30
    for name, c in cov.items():
        assert 0.92 <= c <= 0.98, (name, c)


def test_zero_dof_without_sigma_has_unknown_uncertainty():
    f = plan_force(4, 1)
    r = fit_tumble(f, current_a(AccelerometerParams(), f) + np.array([1e-7, 0, 0, 0]))
    assert r.dof == 0 and r.sigma_source == "unknown" and r.covariance is None
    assert all(e.std is None for e in r.params.values())
    d = json.loads(json.dumps(r.to_dict(), allow_nan=False))
    assert d["params"]["k0_g"]["std"] is None and d["noise_sigma"] is None
    with_sigma = fit_tumble(f, current_a(AccelerometerParams(), f), np.full(4, 1e-8))
    assert with_sigma.params["k0_g"].std > 0 and with_sigma.chi2_per_dof is None


def test_to_dict_is_json_and_prediction_reproduces_the_fit():
    f = plan_force(8, 2)
    y = current_a(AccelerometerParams(), f) + np.random.default_rng(1).normal(0, 1e-9, len(f))
    r = fit_tumble(f, y)
    d = json.loads(json.dumps(r.to_dict(), allow_nan=False))
    assert d["param_names"] == list(PARAM_NAMES) and len(d["residuals"]) == 16
    np.testing.assert_allclose(r.predicted_output(f) + r.residuals, y, rtol=1e-12)


@pytest.mark.parametrize("call, words", [
    (lambda: tumble_positions(6), "n_positions=6"),
    (lambda: tumble_positions(2), "[4, 360]"),
    (lambda: tumble_positions(8, planes=3), "planes=3"),
    (lambda: specific_force_iapo_g([0.0], [0.0], g_over_g0=2.0), "g_over_g0=2.0"),
    (lambda: specific_force_iapo_g([0.0], [0.0, 1.0]), "one length"),
    (lambda: specific_force_iapo_g([0.0], [0.0], mount=np.eye(3) * 2), "orthonormal"),
    (lambda: fit_tumble(np.zeros((4, 2)), np.zeros(4)), "shape (m, 3)"),
    (lambda: fit_tumble(plan_force(4, 1), np.zeros(3)), "output must be finite"),
    (lambda: fit_tumble(plan_force(4, 1), np.ones(4), np.zeros(4)), "output_sigma"),
    (lambda: fit_tumble(plan_force(4, 1), np.ones(4), output_unit_per_ma=0.0), "output_unit_per_ma=0.0"),
    (lambda: fit_tumble(np.tile([1.0, 0, 0], (4, 1)), np.ones(4)), "a_i must take"),
    (lambda: fit_tumble(plan_force(4, 1), np.ones(4)), "fitted K1"),
    (lambda: fit_tumble(plan_force(4, 1) * 3, np.ones(4)), "[-2, 2] g"),
])
def test_bad_input_raises_value_error_naming_it(call, words):
    with pytest.raises(ValueError) as err:
        call()
    assert words in str(err.value)
