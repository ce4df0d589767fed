"""Gravity, the two-node thermal unit in a still room, and noise processes."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sim.physics.gravity import EARTH_RATE_RPS, earth_rate_enu_rps, local_gravity_mps2
from sim.physics.noise import GaussMarkov, RandomWalk, WhiteNoise
from sim.physics.thermal_unit import ConstantAmbient, TwoNodeBody, TwoNodeParams

# ---- gravity ---------------------------------------------------------------------------


def test_somigliana_reference_values():
    # WGS-84 (NIMA TR8350.2 table 3.4): equator 9.7803253359, pole 9.8321849378 m/s².
    assert local_gravity_mps2(0.0) == pytest.approx(9.7803253359, abs=1e-10)
    assert local_gravity_mps2(90.0) == pytest.approx(9.8321849378, abs=1e-9)
    assert local_gravity_mps2(-45.0) == local_gravity_mps2(45.0)
    # Independent check: the GRS80 series expansion of the normal gravity formula agrees
    # with the closed Somigliana formula to ~1e-9 relative (the ellipsoids differ slightly).
    for lat in (15.0, 30.0, 45.0, 60.0, 75.0):
        s2 = math.sin(math.radians(lat)) ** 2
        series = 9.7803253359 * (1 + 0.0052790414 * s2 + 0.0000232718 * s2**2 + 0.0000001262 * s2**3)
        assert local_gravity_mps2(lat) == pytest.approx(series, abs=2e-8)


def test_free_air_gradient():
    gradient = (local_gravity_mps2(45.0, 100.0) - local_gravity_mps2(45.0, 0.0)) / 100.0
    assert gradient == pytest.approx(-3.086e-6, rel=2e-3)  # textbook free-air gradient


@pytest.mark.parametrize("lat,h,name", [(91.0, 0.0, "latitude_deg"), (math.nan, 0.0, "latitude_deg"),
                                        (0.0, 30000.0, "height_m"), (0.0, -2000.0, "height_m")])
def test_gravity_rejects_out_of_range(lat, h, name):
    with pytest.raises(ValueError, match=name):
        local_gravity_mps2(lat, h)


@given(lat=st.floats(-90.0, 90.0))
def test_earth_rate_vector(lat):
    w = earth_rate_enu_rps(lat)
    assert w[0] == 0.0 and np.linalg.norm(w) == pytest.approx(EARTH_RATE_RPS, rel=1e-12)
    assert w[2] == pytest.approx(EARTH_RATE_RPS * math.sin(math.radians(lat)), abs=1e-18)
    assert w[1] >= 0.0


# ---- thermal -----------------------------------------------------------------------------


@settings(max_examples=50, deadline=None)
@given(gaps=st.lists(st.floats(0.0, 3000.0), min_size=1, max_size=8), delta=st.floats(0.0, 10.0),
       tau=st.floats(100.0, 2000.0))
def test_two_node_unit_is_continuous_and_bounded_through_power_switching(gaps, delta, tau):
    """The self-heating unit in a still room (the two-node model that replaced the single node;
    more in test_thermal_physics.py): both nodes between the room and their powered steady
    states, continuous at every switch."""
    p = TwoNodeParams(tau, 20.0, 0.3, delta)
    body = TwoNodeBody(p, ConstantAmbient(23.0))
    top = 23.0 + delta + p.element_rise_over_case_c
    t, on = 0.0, False
    for gap in gaps:
        grid = t + np.linspace(0.0, gap, 50)
        nodes = body.nodes_c(grid)
        assert np.all((nodes >= 23.0 - 1e-9) & (nodes <= top + 1e-9))
        t += gap
        before = body.nodes_c([t])[0]
        on = not on
        body.set_power(t, on)
        assert np.allclose(body.nodes_c([t])[0], before, atol=1e-12)  # continuity


def test_two_node_unit_history_and_errors():
    body = TwoNodeBody(TwoNodeParams(100.0, 10.0, 0.3, 5.0), ConstantAmbient(20.0), t0_s=0.0)
    body.set_power(10.0, True)
    body.set_power(1e5, False)
    assert body.case_c(1e5 - 1.0)[0] == pytest.approx(25.0, abs=1e-9)  # the history is kept
    with pytest.raises(ValueError, match="precedes"):
        body.nodes_c([-1.0])
    with pytest.raises(ValueError, match="must be finite and ≥ the last thermal change"):
        body.set_power(50.0, True)
    with pytest.raises(ValueError, match="element_tau_s"):
        TwoNodeParams(100.0, 90.0, 0.3, 5.0)


# ---- Gauss-Markov --------------------------------------------------------------------------


def reference_gauss_markov(sigma, tau, t, seed):
    """Plain-loop exact discretisation, the definition the class must reproduce."""
    w = np.random.default_rng(seed).standard_normal(t.size)
    x = np.empty(t.size)
    x[0] = sigma * w[0]
    for k in range(1, t.size):
        phi = math.exp(-(t[k] - t[k - 1]) / tau)
        x[k] = phi * x[k - 1] + sigma * math.sqrt(1 - phi * phi) * w[k]
    return x


@settings(max_examples=40, deadline=None)
@given(cuts=st.lists(st.integers(0, 400), max_size=6), dt=st.floats(1e-3, 10.0), tau=st.floats(0.1, 100.0),
       t0=st.floats(0.0, 1e5))
def test_gauss_markov_chunking_is_bit_identical_on_uniform_grids(cuts, dt, tau, t0):
    t = t0 + dt * np.arange(400)
    whole = GaussMarkov(2.0, tau, np.random.default_rng(7)).sample(t)
    chunked_gm = GaussMarkov(2.0, tau, np.random.default_rng(7))
    bounds = [0, *sorted(cuts), t.size]
    chunked = np.concatenate([chunked_gm.sample(t[a:b]) for a, b in zip(bounds[:-1], bounds[1:])])
    assert np.array_equal(whole, chunked)
    # The run uses its first step for all steps; the reference sees the grid's rounding
    # jitter (≤ eps·t/dt ≈ 2e-8 relative here), which moves values by ≲ jitter·σ.
    assert np.allclose(whole, reference_gauss_markov(2.0, tau, t, 7), rtol=0.0, atol=1e-7)


@settings(max_examples=25, deadline=None)
@given(steps=st.lists(st.floats(1e-3, 5.0), min_size=2, max_size=300), cut=st.integers(0, 300))
def test_gauss_markov_non_uniform_grid_matches_the_definition(steps, cut):
    t = np.cumsum(steps)
    ref = reference_gauss_markov(1.5, 2.0, t, 3)
    gm = GaussMarkov(1.5, 2.0, np.random.default_rng(3))
    out = np.concatenate([gm.sample(t[:cut]), gm.sample(t[cut:])])
    assert np.allclose(out, ref, rtol=1e-10, atol=1e-12)


def test_gauss_markov_stationary_statistics():
    sigma, tau, dt, n = 3.0, 10.0, 1.0, 200_000
    x = GaussMarkov(sigma, tau, np.random.default_rng(11)).sample(dt * np.arange(n))
    # Effective independent samples ≈ n·dt/(2τ) = 10 000: the variance estimate has
    # ≈ 1.4 % relative standard error, so 6 % is a > 4σ bound.
    assert x.var() == pytest.approx(sigma**2, rel=0.06)
    lag1 = np.corrcoef(x[:-1], x[1:])[0, 1]
    assert lag1 == pytest.approx(math.exp(-dt / tau), abs=0.01)
    lag10 = np.corrcoef(x[:-10], x[10:])[0, 1]
    assert lag10 == pytest.approx(math.exp(-10 * dt / tau), abs=0.05)


def test_gauss_markov_first_sample_is_stationary_and_times_checked():
    firsts = [GaussMarkov(2.0, 5.0, np.random.default_rng(s)).sample(np.array([0.0]))[0] for s in range(4000)]
    assert np.std(firsts) == pytest.approx(2.0, rel=0.06)  # 4000 draws: 1.1 % standard error
    gm = GaussMarkov(1.0, 1.0, np.random.default_rng(0))
    gm.sample(np.array([0.0, 1.0, 2.0]))
    with pytest.raises(ValueError, match="precedes"):
        gm.sample(np.array([1.5]))
    with pytest.raises(ValueError, match="non-decreasing"):
        GaussMarkov(1.0, 1.0, np.random.default_rng(0)).sample(np.array([2.0, 1.0]))
    with pytest.raises(ValueError, match="tau_s"):
        GaussMarkov(1.0, 0.0, np.random.default_rng(0))


# ---- white noise and random walk ---------------------------------------------------------


def test_white_noise_sigma_convention():
    wn = WhiteNoise(2e-6, np.random.default_rng(5))
    assert wn.sigma(0.5) == pytest.approx(2e-6)  # N/sqrt(2T), T = 0.5 s -> N
    x = wn.sample(100_000, 0.02)
    assert x.std() == pytest.approx(2e-6 / math.sqrt(0.04), rel=0.02)  # 0.22 % standard error
    with pytest.raises(ValueError, match="averaging_time_s"):
        wn.sample(3, 0.0)


def test_random_walk_variance_and_chunking():
    t = np.linspace(0.0, 100.0, 101)
    walks = np.array([RandomWalk(0.5, np.random.default_rng(s)).sample(t)[-1] for s in range(3000)])
    assert walks.var() == pytest.approx(0.25 * 100.0, rel=0.1)  # 3000 walks: 2.6 % standard error
    whole = RandomWalk(0.5, np.random.default_rng(1)).sample(t)
    rw = RandomWalk(0.5, np.random.default_rng(1))
    assert np.array_equal(whole, np.concatenate([rw.sample(t[:37]), rw.sample(t[37:])]))
    assert whole[0] == 0.0


def test_gauss_markov_gap_then_uniform_run_matches_the_exact_recursion():
    """A new acquisition (a gap, then a uniform grid) takes the lfilter path; it must equal
    the per-step exact recursion with the same draws."""
    t = np.concatenate(([0.0, 0.01, 0.02], 7.3 + 0.004 * np.arange(5000)))
    fast = GaussMarkov(2.0, 3.0, np.random.default_rng(1))
    got = np.concatenate([fast.sample(t[:3]), fast.sample(t[3:])])
    w = np.random.default_rng(1).standard_normal(t.size + 5)  # the same stream of draws
    # the first call drew 3, the second 5000: replay them in order
    w = np.concatenate((w[:3], w[3:3 + 5000]))
    ref = np.empty(t.size)
    ref[0] = 2.0 * w[0]
    for k in range(1, t.size):
        phi = np.exp(-(t[k] - t[k - 1]) / 3.0)
        ref[k] = phi * ref[k - 1] + 2.0 * np.sqrt(1 - phi**2) * w[k]
    assert np.allclose(got, ref, rtol=0, atol=1e-9)
