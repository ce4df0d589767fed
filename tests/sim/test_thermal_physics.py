"""The closed-form thermal physics (sim/physics/thermal_*.py) against a high-accuracy ODE
solver, and its invariants: steady states, continuity at segment edges, determinism, the
chamber's rate limits and overshoot, the two-node unit's lags and the play-operator hysteresis."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp
from scipy.linalg import expm

from sim.physics.thermal_chamber import ChamberAir, ChamberParams
from sim.physics.thermal_lti import ExpPoly, LinearBlock
from sim.physics.thermal_unit import HYSTERESIS_GRID_S, ConstantAmbient, TwoNodeBody, TwoNodeParams
from sim.world import World

SLOW = settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])


# ---- the exact linear block ------------------------------------------------------------------
@st.composite
def stable_blocks(draw):
    """Random stable 2- or 3-state blocks with distinct eigenvalues (RC networks and a loop)."""
    n = draw(st.sampled_from([2, 3]))
    taus = draw(st.lists(st.floats(5.0, 3000.0), min_size=n, max_size=n, unique=True))
    rot = np.linalg.qr(np.array(draw(st.lists(st.floats(-1, 1), min_size=n * n, max_size=n * n)))
                       .reshape(n, n) + 3 * np.eye(n))[0]
    a = rot @ np.diag([-1.0 / t for t in taus]) @ rot.T
    b = np.array(draw(st.lists(st.floats(-0.05, 0.05), min_size=n, max_size=n))).reshape(n, 1)
    return a, b


@SLOW
@given(block=stable_blocks(), x0=st.lists(st.floats(-50, 50), min_size=3, max_size=3),
       u0=st.floats(-60, 150), slope=st.floats(-0.1, 0.1), span=st.floats(10.0, 5000.0))
def test_block_response_equals_dop853(block, x0, u0, slope, span):
    a, b = block
    lb = LinearBlock(a, b)
    n = a.shape[0]
    x0 = np.array(x0[:n])
    sig = lb.respond(x0, ExpPoly.ramp(100.0, [u0], [slope]))
    ref = solve_ivp(lambda t, x: a @ x + b[:, 0] * (u0 + slope * (t - 100.0)), (100.0, 100.0 + span), x0,
                    method="DOP853", rtol=1e-12, atol=1e-12, dense_output=True)
    t = np.linspace(100.0, 100.0 + span, 37)
    # DOP853 (its dense output) agrees to ~1e-8 relative, a slow mode losing more; the matrix exponential
    # of the augmented system (scipy.linalg.expm) is the tighter reference at the end point
    assert np.allclose(sig.at(t), ref.sol(t).T, rtol=1e-6, atol=1e-6)
    aug = np.zeros((n + 2, n + 2))
    aug[:n, :n], aug[:n, n], aug[n, n + 1] = a, b[:, 0], 1.0
    z = expm(aug * span) @ np.concatenate([x0, [u0, slope]])
    assert np.allclose(sig.value(100.0 + span), z[:n], rtol=1e-10, atol=1e-10)
    assert np.allclose(sig.value(100.0), x0, atol=1e-9)  # continuity at the edge
    d = 1e-3
    numeric = (sig.at([150.0 + d]) - sig.at([150.0 - d])) / (2 * d)
    assert np.allclose(sig.rate([150.0]), numeric, rtol=1e-5, atol=1e-7)


def test_block_steady_state_and_rebasing():
    lb = TwoNodeParams().block()
    steady = lb.steady_state([30.0, 0.0])
    assert np.allclose(steady, [30.0, 30.0])  # unheated: the air's temperature
    sig = lb.respond([10.0, 5.0], ExpPoly.constant(0.0, [30.0, 0.0]))
    assert np.allclose(sig.value(1e6), steady, atol=1e-9)
    later = sig.rebased(777.0)
    t = np.array([777.0, 900.0, 5000.0])
    assert np.allclose(later.at(t), sig.at(t), atol=1e-12)


# ---- the two-node unit ----------------------------------------------------------------------
@SLOW
@given(tau=st.floats(200.0, 2000.0), frac=st.floats(0.005, 0.2), rho=st.floats(0.05, 2.0),
       rise=st.floats(0.0, 10.0), ambient=st.floats(-40.0, 60.0))
def test_two_node_steady_states_and_dominant_mode(tau, frac, rho, rise, ambient):
    p = TwoNodeParams(tau, frac * tau / (1 + rho), rho, rise)
    eig = np.sort(np.linalg.eigvals(p.block().a).real)
    assert eig[-1] == pytest.approx(-1.0 / tau, rel=1e-9)  # the slow mode is the stated τ
    body = TwoNodeBody(p, ConstantAmbient(ambient))
    assert np.allclose(body.nodes_c([0.0, 1e3]), ambient)  # starts in equilibrium, unheated
    body.set_power(10.0, True)
    case, element = body.nodes_c([10.0 + 40 * tau])[0]
    assert case == pytest.approx(ambient + rise, abs=1e-6)  # the case (sensor) rises Δ
    assert element - case == pytest.approx(p.element_rise_over_case_c, abs=1e-6)
    body.set_power(50 * tau, False)
    assert np.allclose(body.nodes_c([100 * tau]), ambient, atol=1e-6)


@SLOW
@given(knots=st.lists(st.tuples(st.floats(60.0, 3000.0), st.floats(-60.0, 120.0)), min_size=2, max_size=5),
       power=st.lists(st.booleans(), min_size=5, max_size=5))
def test_unit_in_the_chamber_matches_an_ode_solver_on_random_profiles(knots, power):
    """A random set-point profile with power switching: the whole air + unit cascade integrated
    by DOP853 from the same commands, compared at many instants (and across segment edges)."""
    world = World(3)
    params = ChamberParams()
    air = ChamberAir(world, params)
    unit = TwoNodeParams(600.0, 20.0, 0.3, 4.0)
    body = TwoNodeBody(unit, air)
    events = []  # (t, target, powered)
    powered = False
    for (dt, target), on in zip(knots, power):
        air.command(True, target, None)
        if on != powered:
            body.set_power(world.now, on)
            powered = on
        events.append((world.now, target, powered))
        world.advance(dt)
    t_end = world.now
    # reference: integrate the air loop's demand (rebuilt from the air's own segments) and the unit
    lb = unit.block()
    starts = list(air._starts) + [t_end]
    x = np.array([params.lab_ambient_c, 0.0, params.lab_ambient_c, params.lab_ambient_c])
    w, z = params.omega_rad_s, params.loop_damping
    q = unit.heating_c_per_s
    checks_t, checks_ref = [], []
    for i, t0 in enumerate(starts[:-1]):
        t1 = starts[i + 1]
        if t1 <= t0:
            continue
        past = [e for e in events if e[0] <= t0]
        on = past[-1][2] if past else False
        demand = _demand_of_segment(air, t0)

        def f(t, s, demand=demand, on=on):
            r = demand(t)
            dv = w * w * (r - s[0]) - 2 * z * w * s[1]
            dn = lb.a @ s[2:] + lb.b @ np.array([s[0], q if on else 0.0])
            return [s[1], dv, *dn]
        sol = solve_ivp(f, (t0, t1), x, method="DOP853", rtol=1e-11, atol=1e-10, dense_output=True)
        ts = np.linspace(t0, t1, 9)
        checks_t.append(ts)
        checks_ref.append(sol.sol(ts).T)
        x = sol.y[:, -1]
    t = np.concatenate(checks_t)
    ref = np.concatenate(checks_ref)
    assert np.allclose(air.air_c(t), ref[:, 0], atol=1e-5)
    assert np.allclose(body.nodes_c(t), ref[:, 2:], atol=1e-5)


def _demand_of_segment(air: ChamberAir, t0: float):
    """The demand r(t) the air followed from t0 (reconstructed from the segment's particular part)."""
    i = air._starts.index(t0)
    sig = air._signals[i]
    # the particular solution of the loop to a ramp r0 + ṙτ is T = r0 + ṙτ − 2ζṙ/ω
    slope = float(sig.c1[0])
    r0 = float(sig.c0[0]) + air.params.ramp_lag_c(slope)
    return lambda t: r0 + slope * (t - t0)


def test_thermal_state_is_deterministic_and_independent_of_how_it_is_read():
    def run(chunks: int) -> np.ndarray:
        world = World(1)
        air = ChamberAir(world)
        body = TwoNodeBody(TwoNodeParams(hysteresis_width_c=2.0), air)
        body.set_power(0.0, True)
        out = []
        for target in (70.0, -40.0, 23.0):
            air.command(True, target, 1.5)
            t = np.linspace(world.now, world.now + 3 * 3600, 601)
            for part in np.array_split(t, chunks):
                world.advance_to(part[-1])
                out.append(np.column_stack([body.nodes_c(part), body.hysteresis_memory_c(part)]))
        return np.concatenate(out)
    one, many = run(1), run(37)
    assert np.array_equal(one, many)


# ---- the chamber air ------------------------------------------------------------------------
@pytest.mark.parametrize("target", [70.0, -40.0])
def test_chamber_rate_limits_overshoot_and_settling(target):
    world = World(0)
    p = ChamberParams()
    air = ChamberAir(world, p)
    air.command(True, target, None)  # a step: the plant's rate limit sets the pace
    world.advance(5 * 3600)
    rate = p.heat_rate_c_per_min if target > p.lab_ambient_c else p.cool_rate_c_per_min
    assert air.ramp_end_s == pytest.approx(abs(target - p.lab_ambient_c) / rate * 60.0)
    t = np.arange(0.0, world.now, 5.0)
    r = air.air_rate_c_per_s(t) * 60.0
    assert np.abs(r).max() <= rate * 1.17  # the loop's overshoot on the rate, at most
    a = air.air_c(t)
    over = (a - target).max() if target > 23 else (target - a).max()
    assert 0.3 < over < 2.0  # the second-order loop overshoots where the ramp ends
    assert abs(air.air_c(world.now)[0] - target) < 1e-6  # and settles on the set point


def test_standby_relaxes_to_the_lab_and_the_state_is_continuous():
    world = World(0)
    air = ChamberAir(world)
    air.command(True, 100.0, 2.0)
    world.advance(1000.0)
    before = air.air_c(world.now)[0], air.air_rate_c_per_s(world.now)[0]
    air.command(False, 100.0, None)
    assert air.air_c(world.now)[0] == pytest.approx(before[0], abs=1e-9)
    world.advance(10 * 2700.0)
    assert air.air_c(world.now)[0] == pytest.approx(23.0, abs=0.01)
    tau = ChamberParams().standby_tau_s
    t = world.now
    assert (air.air_c(t)[0] - 23.0) == pytest.approx((air.air_c(t - tau)[0] - 23.0) * math.exp(-1.0), rel=1e-9)


def test_first_crossing_is_where_the_air_crosses():
    world = World(0)
    air = ChamberAir(world)
    air.command(True, 80.0, None)
    tc = air.first_crossing(60.0, True, world.now, 7200.0)
    assert tc is not None and air.air_c(tc)[0] == pytest.approx(60.0, abs=1e-6)
    assert air.first_crossing(200.0, True, world.now, 7200.0) is None


# ---- the unit's lag and hysteresis ---------------------------------------------------------
def test_element_lags_the_case_during_ramps_and_the_hysteresis_separates_up_from_down():
    world = World(0)
    air = ChamberAir(world)
    p = TwoNodeParams(600.0, 20.0, 0.3, 0.0, hysteresis_width_c=3.0)
    body = TwoNodeBody(p, air)
    air.command(True, 70.0, 1.0)
    world.advance(30 * 60)  # ramping up at 1 °C/min
    case, element = body.nodes_c([world.now])[0]
    assert air.air_c(world.now)[0] > case > element  # the element lags the case, the case the air
    up = body.element_c([world.now])[0] - body.hysteresis_memory_c([world.now])[0]
    world.advance(4 * 3600)
    air.command(True, -40.0, 1.0)
    world.advance(60 * 60)
    down = body.element_c([world.now])[0] - body.hysteresis_memory_c([world.now])[0]
    assert up == pytest.approx(3.0) and down == pytest.approx(-3.0)
    # the memory is sampled on the absolute grid: any time between grid points is clamped continuously
    t = world.now + 0.5 * HYSTERESIS_GRID_S
    assert abs(body.element_c([t])[0] - body.hysteresis_memory_c([t])[0]) <= 3.0 + 1e-12
