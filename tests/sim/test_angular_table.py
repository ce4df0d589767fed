"""The angular vibration table's motion: limits, piece continuity, derivatives, ramps,
sweeps, distortion, and the reference capture's memory and noise."""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sim.devices.angular_reference import ENCODER_COUNTS, ReferenceCapture
from sim.physics.angular_demand import AngularTableLimits, Sweep, Tone
from sim.physics.angular_table import ABORT_DECAY_S, REST_SINCE_S, AngularMotion

LIM = AngularTableLimits()
PURE = (0.0, 0.0)


def scaled_to_limit(freqs, weights, phases):
    """Tones with the given frequencies, amplitude shares and phases, scaled so the
    tightest of the three sums sits exactly at its limit."""
    w = np.asarray(weights) / np.sum(weights)
    f = np.asarray(freqs)
    k = min(LIM.max_angle_rad / np.sum(w / (2 * np.pi * f)), LIM.max_rate_rad_s / np.sum(w),
            LIM.max_accel_rad_s2 / np.sum(w * 2 * np.pi * f))
    return [Tone(float(k * wi), float(fi), float(p)) for wi, fi, p in zip(w, f, phases)]


tone_sets = st.integers(1, 4).flatmap(lambda n: st.tuples(
    st.lists(st.floats(math.log(0.1), math.log(1000.0)).map(math.exp), min_size=n, max_size=n),
    st.lists(st.floats(0.05, 1.0), min_size=n, max_size=n),
    st.lists(st.floats(-math.pi, math.pi), min_size=n, max_size=n)))


def dense_times(tones, t0, t1):
    """Sample grid fine enough for every component (≥ 20 samples per period of 3 f_max)."""
    f_top = 3 * max(t.freq_hz for t in tones)
    n = int(min(2_000_000, max(20_000, (t1 - t0) * f_top * 20)))
    return np.linspace(t0, t1, n)


# ---- limits -------------------------------------------------------------------------------
@settings(max_examples=12, deadline=None)
@given(drawn=tone_sets, share=st.floats(0.3, 1.0))
def test_tones_inside_the_limits_are_run_and_the_motion_stays_inside(drawn, share):
    tones = [Tone(t.rate_amplitude_rad_s * share, t.freq_hz, t.phase_rad) for t in scaled_to_limit(*drawn)]
    m = AngularMotion(distortion=PURE)
    m.start_tones(0.0, tones)
    ramp_end = max(math.ceil(m.ramp_s * t.freq_hz - 1e-9) / t.freq_hz for t in tones)
    run = dense_times(tones, ramp_end, ramp_end + 2.0 / min(t.freq_hz for t in tones))
    ramp = dense_times(tones, 0.0, ramp_end)
    tol = 1 + 1e-9
    for t in (ramp, run):
        assert np.abs(m.rate_rad_s(t)).max() <= LIM.max_rate_rad_s * tol
        assert np.abs(m.angle_rad(t)).max() <= LIM.max_angle_rad * tol
    assert np.abs(m.accel_rad_s2(run)).max() <= LIM.max_accel_rad_s2 * tol
    # during a ramp the envelope slope A/T adds to the acceleration (documented)
    slope = sum(t.rate_amplitude_rad_s * t.freq_hz / math.ceil(m.ramp_s * t.freq_hz - 1e-9) for t in tones)
    assert np.abs(m.accel_rad_s2(ramp)).max() <= LIM.max_accel_rad_s2 * tol + slope


@settings(max_examples=30, deadline=None)
@given(drawn=tone_sets, over=st.floats(1.001, 3.0))
def test_tones_beyond_a_limit_are_refused_naming_it(drawn, over):
    tones = [Tone(t.rate_amplitude_rad_s * over, t.freq_hz, t.phase_rad) for t in scaled_to_limit(*drawn)]
    m = AngularMotion()
    with pytest.raises(ValueError, match=r"(angle|rate|acceleration) amplitude sum .* not in 0\.\.(0\.5 rad|40 rad/s|"
                                         r"1400 rad/s\^2)"):
        m.start_tones(0.0, tones)
    assert m.state(1.0) == "IDLE" and m.at_rest(0.0)


def test_limit_messages_and_counts():
    m = AngularMotion()
    with pytest.raises(ValueError, match=r"^frequency 0.05 Hz not in 0.1..1000 Hz$"):
        m.start_tones(0.0, [Tone(0.01, 0.05)])
    with pytest.raises(ValueError, match=r"^17 tones not in 1..16$"):
        m.start_tones(0.0, [Tone(0.01, 100.0 + i) for i in range(17)])
    with pytest.raises(ValueError, match=r"^angle amplitude sum 0.63662 rad not in 0..0.5 rad$"):
        m.start_tones(0.0, [Tone(1.5, 0.5), Tone(1.0, 1.0)])
    # with these figures the rate limit never binds alone (angle and acceleration cross
    # at 8.4 Hz, 26.5 rad/s), but it is checked like the others
    tight = AngularTableLimits(max_rate_rad_s=10.0)
    assert tight.violation([Tone(6.0, 8.0), Tone(6.0, 8.1)]) == "rate amplitude sum 12 rad/s not in 0..10 rad/s"
    with pytest.raises(ValueError, match=r"^sweep: acceleration amplitude sum 1884.96 rad/s\^2 not in 0..1400"):
        m.start_sweep(0.0, Sweep(1.0, 100.0, 10.0, 3.0))
    with pytest.raises(ValueError, match=r"^sweep: angle amplitude sum 4.77465 rad"):
        m.start_sweep(0.0, Sweep(0.1, 100.0, 10.0, 3.0))
    with pytest.raises(ValueError, match=r"sweep time 2000 s not in 0.1..1000 s"):
        Sweep(1.0, 10.0, 2000, 1.0)


# ---- the timeline -------------------------------------------------------------------------
@functools.cache  # read-only afterwards: queries never change the motion
def busy_motion(distortion=(0.003, 0.001)):
    """Start, change demand while running, stop mid-ramp, sweep, stop mid-sweep, start, abort."""
    m = AngularMotion(rng=np.random.default_rng(4), distortion=distortion)
    m.start_tones(0.5, [Tone(0.2, 7.0, 0.4), Tone(0.05, 0.9, -1.0)])
    m.start_tones(3.3, [Tone(0.3, 40.0, 1.0)])      # old down, new up
    m.stop(4.71)                                     # while the new one ramps up
    m.start_sweep(8.0, Sweep(2.0, 80.0, 3.0, 0.4, "LOG"))
    m.stop(10.123)                                   # in the middle of the sweep
    m.start_tones(14.0, [Tone(0.5, 3.0)])
    m.abort(15.5)
    return m


def test_consecutive_pieces_are_continuous_in_rate_and_angle():
    m = busy_motion()
    ps = m.pieces(-10.0, 30.0)
    assert len(ps) > 100 and ps[0].t_start_s == REST_SINCE_S and math.isinf(ps[-1].t_end_s)
    for p, q in zip(ps, ps[1:]):
        assert p.t_end_s == q.t_start_s
        end = np.array([p.t_end_s])
        assert p.rate_rad_s(end)[0] == pytest.approx(q.rate_rad_s(end)[0], abs=1e-10)
        assert p.angle_rad(end)[0] == pytest.approx(q.angle0_rad, abs=1e-12)
    # the compiled evaluation is the pieces' own (MotionPiece's numpy methods: the reference)
    t = np.random.default_rng(3).uniform(-1.0, 20.0, 3000)  # any order
    own = [next(p for p in ps if p.t_start_s <= x < p.t_end_s) for x in t]
    rate, angle, accel = m.motion(t)
    for got, method in ((rate, "rate_rad_s"), (angle, "angle_rad"), (accel, "accel_rad_s2")):
        ref = np.array([getattr(p, method)(np.array([x]))[0] for p, x in zip(own, t)])
        assert np.allclose(got, ref, rtol=0, atol=1e-12 * max(1.0, np.abs(ref).max())), method
    assert m.motion(t.reshape(50, 60))[1].shape == (50, 60)


def test_pieces_window_and_times_before_zero_are_rest():
    m = busy_motion()
    before = m.pieces(-5.0, -1.0)
    assert len(before) == 1 and before[0].n == 0
    assert np.all(m.rate_rad_s(np.array([-1e6, -3.0, 0.0, 0.4])) == 0.0)
    assert m.state(-2.0) == "IDLE"
    inside = m.pieces(3.0, 3.6)
    assert inside[0].t_start_s <= 3.0 < inside[0].t_end_s and inside[-1].t_start_s <= 3.6 < inside[-1].t_end_s
    with pytest.raises(ValueError, match="t0 ≤ t1"):
        m.pieces(2.0, 1.0)


@settings(max_examples=10, deadline=None)
@given(t=st.lists(st.floats(0.0, 18.0), min_size=1, max_size=50))
def test_rate_is_the_derivative_of_angle_and_accel_of_rate(t):
    m = busy_motion()
    t = np.array(t)
    h = 1e-6
    starts = np.array([p.t_start_s for p in m.pieces(-1, 20)])
    t = t[np.min(np.abs(t[:, None] - starts[None, :]), axis=1) > 2 * h]  # not across a kink in accel
    d_angle = (m.angle_rad(t + h) - m.angle_rad(t - h)) / (2 * h)
    d_rate = (m.rate_rad_s(t + h) - m.rate_rad_s(t - h)) / (2 * h)
    assert np.allclose(d_angle, m.rate_rad_s(t), rtol=0, atol=1e-6)
    assert np.allclose(d_rate, m.accel_rad_s2(t), rtol=0, atol=2e-3)


@pytest.mark.parametrize("spacing", ["LIN", "LOG"])
def test_sweep_frequency_follows_the_law_and_the_phase_its_integral(spacing):
    m = AngularMotion(distortion=PURE)
    sweep = Sweep(1.0, 200.0, 20.0, 0.5, spacing)
    m.start_sweep(2.0, sweep)
    t_on = 3.0  # ramp at 1 Hz: 1 s
    ps = [p for p in m.pieces(t_on, t_on + sweep.duration_s) if p.t_start_s >= t_on and p.t_end_s <= t_on + 20.0]
    assert len(ps) == 2000 and ps[0].t_start_s == t_on
    mid = np.array([0.5 * (p.t_start_s + p.t_end_s) - t_on for p in ps])
    assert np.allclose([p.freq_hz[0] for p in ps], sweep.freq_at(mid), rtol=1e-12)
    ends = np.array([p.t_end_s - t_on for p in ps])
    if spacing == "LIN":
        cycles = 1.0 * ends + (200.0 - 1.0) * ends ** 2 / (2 * 20.0)
    else:
        r = 200.0
        cycles = 1.0 * 20.0 / math.log(r) * (r ** (ends / 20.0) - 1.0)
    theta0 = ps[0].phase_rad[0]
    got = np.array([p.end_state()[1][0] for p in ps])
    diff = np.angle(np.exp(1j * (got - theta0 - 2 * np.pi * cycles)))
    assert np.abs(diff).max() < 2e-3  # midpoint rule per 10 ms piece
    assert np.all(np.array([p.alpha_rad_s[0] for p in ps]) == 0.5)
    assert m.state(t_on + 10) == "RUN" and m.state(t_on + 20.0 + 0.5) == "RAMP"
    assert m.state(t_on + 22.0) == "IDLE" and not m.driving


def test_ramps_whole_periods_centring_and_state():
    m = AngularMotion(distortion=PURE)
    m.set_ramp(1.0)
    m.start_tones(10.0, [Tone(0.6, 5.0, 0.9), Tone(0.2, 0.3, 2.0)])
    ps = m.pieces(10.0, 10.0)
    assert ps[0].t_start_s == 10.0 and np.allclose(ps[0].alpha_rad_s, 0.0)
    assert np.allclose(ps[0].beta_rad_s2, [0.6 / 1.0, 0.2 / (1 / 0.3)])  # 0.3 Hz: one whole period, 3.33 s
    assert [m.state(t) for t in (9.9, 10.5, 13.0, 13.4)] == ["IDLE", "RAMP", "RAMP", "RUN"]
    # the table oscillates about where it rested and comes back there after a stop
    t = np.linspace(13.4, 13.4 + 1 / 0.3, 20001)
    assert abs(np.trapezoid(m.angle_rad(t), t) / (t[-1] - t[0])) < 0.2 * 0.6 / (2 * np.pi * 5)
    m.stop(20.0)
    assert m.state(22.0) == "RAMP" and m.state(23.34) == "IDLE"
    assert abs(m.angle_rad(np.array([30.0]))[0]) < 1e-12
    # linear envelope: half amplitude half-way up
    m.start_tones(40.0, [Tone(1.0, 50.0)])
    assert 0.49 < np.abs(m.rate_rad_s(np.linspace(40.49, 40.51, 2001))).max() <= 0.51


def test_new_demand_ramps_old_down_then_new_up_and_abort_cuts_within_10_ms():
    m = AngularMotion(distortion=PURE)
    m.start_tones(0.0, [Tone(1.0, 10.0)])
    m.start_tones(5.0, [Tone(0.5, 20.0)])
    down = m.pieces(5.0, 5.999)
    assert all(np.all(p.freq_hz == 10.0) for p in down)
    up = m.pieces(6.0, 6.0)[0]
    assert up.t_start_s == 6.0 and np.all(up.freq_hz == 20.0) and up.alpha_rad_s[0] == 0.0
    assert m.rate_rad_s(np.array([6.0]))[0] == pytest.approx(0.0, abs=1e-12)
    m.abort(10.0)
    assert m.state(10.0) == "ABORT" and m.aborted
    m.stop(10.002)  # a stop after an abort does not slow the cut down
    assert np.all(m.rate_rad_s(np.linspace(10.0 + ABORT_DECAY_S, 11.0, 100)) == 0.0)
    with pytest.raises(RuntimeError, match="reset the interlock"):
        m.start_tones(10.005, [Tone(0.1, 1.0)])
    with pytest.raises(RuntimeError, match="still decaying"):
        m.reset_abort(10.005)
    m.reset_abort(10.02)
    assert m.state(10.02) == "IDLE"
    m.start_tones(11.0, [Tone(0.1, 1.0)])
    assert m.state(11.5) == "RAMP"
    with pytest.raises(ValueError, match="last command"):
        m.stop(5.0)


def test_harmonic_distortion_levels_by_fft():
    for distortion in ((0.003, 0.001), (0.01, 0.02), PURE):
        m = AngularMotion(rng=np.random.default_rng(9), distortion=distortion)
        m.start_tones(0.0, [Tone(1.0, 10.0, 0.3)])
        fs, n = 1000.0, 10_000  # 10 s, whole periods of 10, 20 and 30 Hz
        t = 2.0 + np.arange(n) / fs
        spec = np.abs(np.fft.rfft(m.rate_rad_s(t))) * 2 / n
        a1, a2, a3 = spec[100], spec[200], spec[300]
        assert a1 == pytest.approx(1.0, abs=1e-9)
        assert a2 / a1 == pytest.approx(distortion[0], abs=1e-9)
        assert a3 / a1 == pytest.approx(distortion[1], abs=1e-9)
        assert np.delete(spec, [100, 200, 300]).max() < 1e-9


# ---- reference capture (memory, noise, determinism) ---------------------------------------
def capture(poll_times, memory=10_000, seed=1):
    m = AngularMotion(distortion=PURE)
    m.start_tones(0.0, [Tone(0.5, 5.0)])
    ref = ReferenceCapture(m, np.random.default_rng(seed), memory=memory)
    ref.set_rate(2000.0)
    ref.set_count(8000)
    ref.initiate(0.25)
    rows = [ref.remove(t, 10**9) for t in poll_times]
    return m, ref, np.concatenate(rows)


@settings(max_examples=10, deadline=None)
@given(polls=st.lists(st.floats(0.25, 5.0), min_size=1, max_size=8))
def test_reference_bytes_do_not_depend_on_polling(polls):
    _, _, whole = capture([5.0])
    _, _, chunked = capture(sorted(polls) + [5.0])
    assert whole.shape == (8000, 3) and whole.tobytes() == chunked.tobytes()


def test_reference_values_noise_quantization_and_overflow():
    m, ref, rows = capture([5.0], memory=10_000)
    t = 0.25 + rows[:, 0]
    assert np.array_equal(rows[:, 0], np.arange(8000) / 2000.0)
    q = 360.0 / ENCODER_COUNTS
    err = rows[:, 1] - np.degrees(m.angle_rad(t))
    assert err.max() <= 1e-12 and err.min() >= -q - 1e-12
    noise = rows[:, 2] - np.degrees(m.rate_rad_s(t))
    assert noise.std() == pytest.approx(2e-4, rel=0.05) and abs(noise.mean()) < 2e-5
    assert not ref.overflow
    # a memory of 3000: the newest 3000 remain, flagged
    _, small, kept = capture([5.0], memory=3000)
    assert small.overflow and kept.shape == (3000, 3)
    assert kept.tobytes() == rows[-3000:].tobytes()
    _, again, _ = capture([5.0], seed=2)
    assert again is not None and not np.array_equal(capture([5.0], seed=2)[2][:, 2], rows[:, 2])
