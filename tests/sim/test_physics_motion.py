"""Turntable kinematics: trapezoid planning, servo settling, modes, limits, attitude."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sim.physics.gravity import STANDARD_GRAVITY_MPS2, earth_rate_enu_rps
from sim.physics.motion import Axis, DualAxisTable, trapezoid_time_s, wrap_deg

positions = st.floats(-720.0, 720.0, allow_nan=False)
rate_limits = st.floats(1.0, 100.0)
accel_limits = st.floats(1.0, 100.0)


def make_axis(vmax=30.0, amax=20.0, **kw):
    return Axis(rate_max_dps=500.0, accel_max_dps2=500.0, rate_limit_dps=vmax, accel_limit_dps2=amax, **kw)


def check_demand_within_limits(ax, t0, t1, vmax, amax, n=20001):
    """Demand rate and acceleration within the limits, analytically and by finite differences."""
    t = np.linspace(t0, t1, n)
    pos, rate, acc = ax.demand_profile(t)
    assert np.all(np.abs(rate) <= vmax * (1 + 1e-9) + 1e-9)
    assert np.all(np.abs(acc) <= amax * (1 + 1e-12))
    dt = t[1] - t[0]
    # Finite differences (relative slack for the rounding of t itself, ~1e-16 * t / dt).
    assert np.all(np.abs(np.diff(pos)) / dt <= vmax * (1 + 1e-6))
    assert np.all(np.abs(np.diff(rate)) / dt <= amax * (1 + 1e-6))


@settings(max_examples=60, deadline=None)
@given(p0=positions, target=positions, vmax=rate_limits, amax=accel_limits)
def test_rest_to_rest_move_is_time_optimal_exact_and_within_limits(p0, target, vmax, amax):
    ax = make_axis(vmax, amax)
    ax.command_position(0.0, p0)
    t_start = 1000.0  # long after the first move settled
    assert ax.position_deg(t_start) == pytest.approx(p0, abs=1e-12)
    ax.command_position(t_start, target)
    t_end = t_start + trapezoid_time_s(target - p0, vmax, amax)
    # Time-optimality: the demand ends exactly when the closed form says.
    assert ax._plan.t_end - t_start == pytest.approx(t_end - t_start, rel=1e-9, abs=1e-9)
    pos, rate, _ = ax.demand_profile(np.array([t_end + 1e-9, t_end + 10.0]))
    assert pos[0] == target and pos[1] == target  # reaches the target exactly
    assert np.all(rate == 0.0)
    check_demand_within_limits(ax, t_start, t_end + 1.0, vmax, amax)
    # The platform itself converges to the target once the ringing has died out.
    assert ax.position_deg(t_end + 5.0) == pytest.approx(target, abs=1e-9)


@settings(max_examples=60, deadline=None)
@given(first=positions, second=positions, frac=st.floats(0.01, 0.99), vmax=rate_limits, amax=accel_limits)
def test_recommand_mid_move_is_continuous_and_ends_on_new_target(first, second, frac, vmax, amax):
    ax = make_axis(vmax, amax)
    ax.command_position(0.0, first)
    t_c = frac * ax._plan.t_end
    before = [f(np.array([t_c]))[0] for f in (ax.position_deg, ax.rate_dps, ax.accel_dps2)]
    demand_before = [x[0] for x in ax.demand_profile(np.array([t_c]))]
    ax.command_position(t_c, second)
    after = [f(np.array([t_c]))[0] for f in (ax.position_deg, ax.rate_dps, ax.accel_dps2)]
    demand_after = [x[0] for x in ax.demand_profile(np.array([t_c]))]
    # Platform position, rate and acceleration are continuous; the demand in position and rate.
    assert after == pytest.approx(before, abs=1e-9)
    assert demand_after[:2] == pytest.approx(demand_before[:2], abs=1e-9)
    check_demand_within_limits(ax, t_c, ax._plan.t_end + 1.0, vmax, amax)
    assert ax.demand_profile(np.array([ax._plan.t_end]))[0][0] == second
    # Just around the re-command the platform moves smoothly (no jump hidden between samples).
    t = t_c + np.array([-1e-6, 0.0, 1e-6])
    assert np.all(np.abs(np.diff(ax.position_deg(t[1:]))) < 1e-3)


def test_reversal_decelerates_first():
    ax = make_axis(30.0, 20.0)
    ax.command_position(0.0, 100.0)
    ax.command_position(2.0, 0.0)  # moving at +30 °/s toward 100; target behind
    _, rate, acc = ax.demand_profile(np.array([2.0, 2.5, 3.6]))
    assert acc[0] == -20.0 and rate[0] == 30.0  # braking at the acceleration limit
    assert rate[1] == pytest.approx(20.0)
    assert rate[2] < 0.0  # then reversing toward the target
    assert ax.demand_profile(np.array([100.0]))[0][0] == 0.0


def test_settling_is_finite_documented_and_in_position_tracks_the_error():
    ax = make_axis(30.0, 20.0)
    ax.command_position(0.0, 90.0)
    t_end = ax._plan.t_end
    wn, zeta = 2 * math.pi * 10.0, 0.5
    lag = 20.0 / wn**2  # constant servo lag while braking at 20 °/s²
    t = np.linspace(t_end, t_end + 1.0, 100001)
    err = ax.position_deg(t) - 90.0
    assert err[0] == pytest.approx(lag, rel=1e-6)  # ends one lag past the target
    assert err.min() < -1e-4  # then rings back through the target
    # Envelope bound: settle time = ln(env/tol)/(ζωn) + dwell, env = lag/sqrt(1-ζ²).
    expected = math.log(lag / math.sqrt(1 - zeta**2) / 1e-3) / (zeta * wn) + 0.05
    assert ax.settle_time_s == pytest.approx(expected, rel=1e-9)
    inpos = ax.in_position(t)
    t_in = t_end + ax.settle_time_s
    assert not inpos[t < t_in].any() and inpos[t >= t_in].all()
    assert np.all(np.abs(err[t >= t_in - 0.05]) < 1e-3)  # within tolerance through the dwell
    assert np.abs(err[t < t_in - 0.06]).max() > 1e-3  # and not long before it
    assert not ax.moving(t_end + 0.5) and ax.moving(t_end - 0.5)


def test_rate_mode_ramps_at_the_acceleration_limit_and_holds():
    ax = make_axis(50.0, 10.0)
    ax.command_rate(1.0, -40.0)
    _, rate, acc = ax.demand_profile(np.array([1.0, 3.0, 5.0, 6.0]))
    assert list(acc) == [-10.0, -10.0, 0.0, 0.0]
    assert rate[1] == pytest.approx(-20.0) and rate[3] == -40.0
    assert ax.mode == "RATE" and ax.moving(100.0)
    assert not ax.at_rate(5.0) and ax.at_rate(6.0)
    assert ax.rate_dps(100.0) == pytest.approx(-40.0, abs=1e-12)
    assert ax.position_deg(100.0) < -3000.0  # continuous angle, not wrapped
    with pytest.raises(ValueError, match="rate_dps"):
        ax.command_rate(101.0, 60.0)  # above the user limit


def test_off_coasts_to_rest_with_friction_from_the_actual_state():
    ax = make_axis(30.0, 20.0, friction_dps2=2.0)
    ax.command_rate(0.0, 20.0)
    p_before, v_before = ax.position_deg(10.0), ax.rate_dps(10.0)
    ax.command_off(10.0)
    assert ax.position_deg(10.0) == pytest.approx(p_before, abs=1e-12)
    assert ax.rate_dps(10.0) == pytest.approx(v_before, abs=1e-12)
    assert ax.accel_dps2(12.0) == pytest.approx(-2.0)
    t_stop = 10.0 + v_before / 2.0
    assert ax.rate_dps(t_stop + 1e-6) == 0.0 and not ax.moving(t_stop + 1.0)
    assert ax.position_deg(t_stop + 5) == pytest.approx(p_before + v_before**2 / 4.0, abs=1e-9)
    assert ax.mode == "OFF" and not ax.in_position(t_stop + 5)


def test_stop_brakes_and_holds_position():
    ax = make_axis(30.0, 20.0)
    ax.command_rate(0.0, 30.0)
    ax.stop(10.0)
    hold = ax.position_deg(10.0) + 30.0**2 / 40.0
    assert ax.mode == "POS" and ax.demand == pytest.approx(hold, abs=1e-2)
    assert ax.demand_profile(np.array([11.5]))[1][0] == 0.0
    assert ax.in_position(13.0) and ax.position_deg(20.0) == pytest.approx(ax.demand, abs=1e-9)


@settings(max_examples=30, deadline=None)
@given(rate=st.floats(1.0, 30.0), sign=st.sampled_from([-1.0, 1.0]))
def test_rate_mode_stops_exactly_at_position_limits(rate, sign):
    ax = make_axis(30.0, 20.0, lo_deg=-45.0, hi_deg=60.0)
    ax.command_rate(0.0, sign * rate)
    pos, _, _ = ax.demand_profile(np.linspace(0.0, 120.0, 120001))  # at 1 °/s: 60 s to the limit
    limit = 60.0 if sign > 0 else -45.0
    assert np.all((pos >= -45.0 - 1e-9) & (pos <= 60.0 + 1e-9))
    assert pos[-1] == pytest.approx(limit, abs=1e-9)
    assert ax.limit_reached(120.0) and not ax.limit_reached(0.0) and not ax.at_rate(120.0)
    with pytest.raises(ValueError, match="target_deg"):
        ax.command_position(121.0, 61.0)


def test_limit_change_mid_move_replans_continuously():
    ax = make_axis(30.0, 20.0)
    ax.command_position(0.0, 200.0)
    p, v = ax.position_deg(3.0), ax.rate_dps(3.0)
    ax.set_rate_limit(3.0, 10.0)
    assert ax.position_deg(3.0) == pytest.approx(p, abs=1e-12) and ax.rate_dps(3.0) == pytest.approx(v, abs=1e-12)
    rate = ax.demand_profile(np.linspace(4.0, 15.0, 1000))[1]
    assert np.all(rate <= 10.0 + 1e-9)  # braked to the new limit within (30-10)/20 = 1 s
    assert ax.demand_profile(np.array([100.0]))[0][0] == 200.0
    ax.set_accel_limit(100.0, 5.0)  # after the move: nothing to replan
    assert ax.accel_limit_dps2 == 5.0 and ax.in_position(100.0)


def test_axis_validation_errors():
    with pytest.raises(ValueError, match="rate_limit_dps"):
        Axis(rate_max_dps=100.0, rate_limit_dps=150.0)
    with pytest.raises(ValueError, match="servo_damping"):
        Axis(servo_damping=1.0)
    ax = make_axis()
    with pytest.raises(ValueError, match="accel_limit_dps2"):
        ax.set_accel_limit(0.0, 600.0)
    ax.command_position(5.0, 10.0)
    with pytest.raises(ValueError, match="last command"):
        ax.position_deg(np.array([4.0, 6.0]))
    with pytest.raises(ValueError, match="target_deg"):
        ax.command_position(6.0, math.nan)


def test_wrap_deg():
    assert wrap_deg(540.0) == 180.0 and wrap_deg(-180.0) == 180.0 and wrap_deg(-190.0) == 170.0
    assert np.allclose(wrap_deg(np.array([0.0, 359.0, 721.0])), [0.0, -1.0, 1.0])


def table_at(inner_deg, outer_deg):
    table = DualAxisTable()
    table.inner.command_position(0.0, inner_deg)
    table.outer.command_position(0.0, outer_deg)
    return table


angles = st.floats(-360.0, 360.0, allow_nan=False)


@settings(max_examples=50, deadline=None)
@given(inner=angles, outer=angles, g=st.floats(9.78, 9.84))
def test_attitude_is_a_rotation_and_specific_force_has_local_g(inner, outer, g):
    table = table_at(inner, outer)
    t = np.array([1000.0, 1001.0])
    c = table.platform_to_level(t)
    assert c.shape == (2, 3, 3)
    assert np.allclose(c @ np.swapaxes(c, 1, 2), np.eye(3), atol=1e-12)
    assert np.allclose(np.linalg.det(c), 1.0, atol=1e-12)
    f = table.specific_force_platform_g(t, g)
    assert np.allclose(np.linalg.norm(f, axis=1), g / STANDARD_GRAVITY_MPS2, rtol=1e-12)
    # The specific force, rotated to the level frame, points straight up.
    assert np.allclose(np.einsum("nij,nj->ni", c, f), [0.0, 0.0, g / STANDARD_GRAVITY_MPS2], atol=1e-12)


def test_zero_position_and_quarter_turns():
    g = 9.80
    f = DualAxisTable().specific_force_platform_g(np.array([0.0]), g)[0]
    assert np.allclose(f, [0.0, 0.0, g / STANDARD_GRAVITY_MPS2], atol=1e-15)
    f = table_at(0.0, 90.0).specific_force_platform_g(np.array([1000.0]), g)[0]
    assert np.allclose(f, [0.0, g / STANDARD_GRAVITY_MPS2, 0.0], atol=1e-12)  # +90° about East: y up
    f = table_at(90.0, 90.0).specific_force_platform_g(np.array([1000.0]), g)[0]
    assert np.allclose(f, [g / STANDARD_GRAVITY_MPS2, 0.0, 0.0], atol=1e-12)  # then x up


def test_level_platform_at_rest_senses_only_earth_rate():
    w = DualAxisTable().angular_rate_platform_dps(np.array([0.0]), 32.0)[0]
    assert np.allclose(w, np.degrees(earth_rate_enu_rps(32.0)), atol=1e-15)


@settings(max_examples=25, deadline=None)
@given(inner_rate=st.floats(-30.0, 30.0), outer_rate=st.floats(-30.0, 30.0), t=st.floats(10.0, 100.0))
def test_gimbal_rate_matches_the_attitude_derivative(inner_rate, outer_rate, t):
    table = DualAxisTable()
    table.inner.command_rate(0.0, inner_rate)
    table.outer.command_rate(0.0, outer_rate)
    h = 1e-4
    c = table.platform_to_level(np.array([t - h, t, t + h]))
    skew = c[1].T @ (c[2] - c[0]) / (2 * h)  # Cᵀ Ċ = [ω]× in platform axes, rad/s
    w_gimbal = np.degrees([skew[2, 1], skew[0, 2], skew[1, 0]])
    w_total = table.angular_rate_platform_dps(np.array([t]), 45.0)[0]
    w_earth = c[1].T @ np.degrees(earth_rate_enu_rps(45.0))
    assert np.allclose(w_total - w_earth, w_gimbal, atol=1e-6)
    assert np.linalg.norm(w_total - w_earth) == pytest.approx(math.hypot(inner_rate, outer_rate), abs=1e-6)


def test_table_axis_numbers_and_controller_views():
    table = DualAxisTable()
    assert table.axis(1) is table.inner and table.axis(2) is table.outer
    assert table.axes == (table.inner, table.outer)
    ax = table.inner
    ax.command_position(0.0, 45.0)
    ax.command_rate_mode(1.0)  # rate mode, demand 0: brakes to rest
    assert (ax.mode, ax.rate_demand_dps, ax.position_demand_deg) == ("RATE", 0.0, 45.0)
    assert ax.demand_profile(np.array([10.0]))[1][0] == 0.0
    ax.command_rate(10.0, 10.0)
    ax.command_hold(20.0)  # position mode where it comes to rest
    assert ax.mode == "POS" and ax.rate_demand_dps == 0.0
    assert ax.position_demand_deg == pytest.approx(ax.position_deg(30.0), abs=1e-9)
    assert table.outer.position_limits_deg == (None, None)
    with pytest.raises(ValueError, match="axis number"):
        table.axis(3)


def test_lowering_the_acceleration_limit_near_a_position_limit_still_stops_at_it():
    ax = make_axis(60.0, 50.0, lo_deg=-90.0, hi_deg=90.0)
    ax.command_rate(0.0, 60.0)
    t = 1.8  # p ≈ 72 °, braking point at 50 °/s² just inside 90 °; at 5 °/s² far beyond
    ax.set_accel_limit(t, 5.0)
    pos, _, acc = ax.demand_profile(np.linspace(t, t + 30.0, 30001))
    assert pos.max() == pytest.approx(90.0, abs=1e-9) and pos[-1] == pytest.approx(90.0, abs=1e-9)
    assert 5.0 < -acc.min() <= ax.accel_max_dps2  # emergency brake above the user limit
    assert ax.limit_reached(t)


command_steps = st.lists(
    st.tuples(st.floats(0.0, 5.0), st.sampled_from(["pos", "rate", "off", "stop", "vlim", "alim"]),
              st.floats(0.0, 1.0)),
    min_size=1, max_size=8)


@settings(max_examples=40, deadline=None)
@given(steps=command_steps, limited=st.booleans())
def test_any_command_sequence_keeps_motion_continuous_and_limited(steps, limited):
    ax = make_axis(40.0, 30.0, **({"lo_deg": -200.0, "hi_deg": 250.0} if limited else {}))
    t = 0.0
    for gap, cmd, u in steps:
        t += gap
        before = [ax.position_deg(t), ax.rate_dps(t)]
        if cmd == "pos":
            ax.command_position(t, -200.0 + 450.0 * u)
        elif cmd == "rate":
            ax.command_rate(t, (2 * u - 1) * ax.rate_limit_dps)
        elif cmd == "off":
            ax.command_off(t)
        elif cmd == "stop":
            ax.stop(t)
        elif cmd == "vlim":
            ax.set_rate_limit(t, 1.0 + 99.0 * u)
        else:
            ax.set_accel_limit(t, 1.0 + 99.0 * u)
        assert [ax.position_deg(t), ax.rate_dps(t)] == pytest.approx(before, abs=1e-8)
        pos, _, acc = ax.demand_profile(np.linspace(t, t + 60.0, 6001))
        bound = ax.accel_max_dps2 if limited else max(ax.accel_limit_dps2, ax.friction_dps2)
        assert np.abs(acc).max() <= bound * (1 + 1e-12)
        if limited and ax.mode != "OFF" and -200.0 <= before[0] <= 250.0:
            assert pos.min() >= -200.0 - 1e-6 and pos.max() <= 250.0 + 1e-6


def test_static_fast_path_equals_the_full_evaluation():
    """After a move has rung out, the specific force is evaluated once and repeated; it must
    equal the element-wise evaluation exactly."""
    table = DualAxisTable()
    table.outer.command_position(0.0, 37.0)
    table.inner.command_position(0.0, -20.0)
    t_rest = max(table.inner.at_rest_from_s(), table.outer.at_rest_from_s())
    assert np.isfinite(t_rest)
    t = t_rest + np.linspace(0.0, 100.0, 1001)
    fast = table.specific_force_platform_g(t, 9.8)
    slow = np.vstack([table.specific_force_platform_g(np.array([x]), 9.8) for x in t[::100]])
    assert np.allclose(fast[::100], slow, rtol=0, atol=1e-15)
    table.inner.command_rate(t[-1], 10.0)
    assert table.inner.at_rest_from_s() == np.inf
