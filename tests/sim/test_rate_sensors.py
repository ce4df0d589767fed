"""Rate sensors of Document B's rig: exact closed-form responses to the table's motion pieces
(against an independent high-accuracy ODE solution), frequency response, latency, split
invariance, noise statistics, the FOG-line adapter and parameter validation."""

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from bench.analysis.fusion import SensorModel
from sim.devices import fog_frames as ff
from sim.devices.fog_serial import FogSerialDevice, GyroInputs
from sim.physics.angular_demand import Tone
from sim.physics.angular_piece import MotionPiece, at_rest
from sim.physics.angular_table import AngularMotion
from sim.physics.rate_sensor_lti import LinearRateSensor, Section
from sim.physics.rate_sensors import (
    LF_PRESET,
    MHD_PRESET,
    STATUS_OVER_RANGE,
    STATUS_READY,
    LfGyroUnit,
    LfRateParams,
    MhdParams,
    lf_sensor,
    mhd_sensor,
)
from sim.world import World


def chain(t0: float, specs) -> list[MotionPiece]:
    """Rest before t0, then pieces of (duration, freqs, alphas, betas, phases); the last is
    followed by a phase-continuous dwell to infinity."""
    pcs, t = [at_rest(t0 - 50.0, t0)], t0
    for dur, f, a, b, ph in specs:
        pcs.append(MotionPiece(t, t + dur, f, a, b, ph))
        t += dur
    amp, ph, ang = pcs[-1].end_state()
    pcs.append(MotionPiece(t, math.inf, pcs[-1].freq_hz, amp, np.zeros(amp.size), ph, ang))
    return pcs


def source(pcs):
    return lambda t0, t1: [p for p in pcs if p.t_end_s > t0 and p.t_start_s <= t1]


def ode_window_means(sensor: LinearRateSensor, pcs, t_origin: float, starts, dur):
    """Reference: DOP853 on [x, ∫y] from rest at t_origin, restarted at every piece boundary."""
    a, b, c, d = sensor.state_space()
    edges = np.unique(np.concatenate([starts, starts + dur]))
    bounds = sorted({t_origin, edges[-1], *[p.t_start_s for p in pcs if t_origin < p.t_start_s < edges[-1]]})
    z = np.zeros(a.shape[0] + 1)
    got: dict[float, float] = {}  # ∫y at each window edge
    for lo, hi in zip(bounds, bounds[1:]):
        piece = next(p for p in pcs if p.t_start_s <= lo < p.t_end_s)

        w, al, be, ph, ts = 2 * np.pi * piece.freq_hz, piece.alpha_rad_s, piece.beta_rad_s2, piece.phase_rad, \
            piece.t_start_s

        def rhs(t, zz, w=w, al=al, be=be, ph=ph, ts=ts):
            tau = t - ts
            u = float(np.dot(al + be * tau, np.sin(w * tau + ph)))
            out = np.empty(zz.size)
            out[:-1] = a @ zz[:-1] + b * u
            out[-1] = c @ zz[:-1] + d * u
            return out

        te = edges[(edges >= lo) & (edges <= hi)]
        sol = solve_ivp(rhs, (lo, hi), z, method="DOP853", rtol=1e-11, atol=1e-13, dense_output=True)
        if te.size:
            got.update(zip(te, sol.sol(te)[-1]))
        z = sol.y[:, -1]
    integral = np.array([got[t] for t in edges])
    return (np.interp(starts + dur, edges, integral) - np.interp(starts, edges, integral)) / dur


section_st = st.builds(Section, st.sampled_from(["highpass", "lowpass"]), st.sampled_from([1, 2]),
                       st.floats(1.0, 50.0), st.floats(0.3, 1.5))
component_st = st.tuples(st.floats(1.0, 30.0), st.floats(-2.0, 2.0), st.floats(-5.0, 5.0), st.floats(0, 6.3))
piece_st = st.tuples(st.floats(0.02, 0.15), st.lists(component_st, min_size=1, max_size=3))


@settings(max_examples=8, deadline=None)
@given(sections=st.lists(section_st, min_size=1, max_size=2), raw=st.lists(piece_st, min_size=1, max_size=3),
       n_win=st.integers(5, 40), dur=st.floats(1e-3, 0.05), splits=st.lists(st.floats(0, 1), max_size=3),
       seed=st.integers(0, 2**32))
def test_mean_output_is_exact_against_ode(sections, raw, n_win, dur, splits, seed):
    specs = [(d, *map(np.array, zip(*comps))) for d, comps in raw]
    pcs = chain(0.0, specs)
    rng = np.random.default_rng(seed)
    starts = np.sort(rng.uniform(-0.05, 0.4, n_win))  # windows straddle the piece boundaries
    sensor = LinearRateSensor(sections, 2.0, source(pcs), t_origin_s=-0.1)
    cuts = sorted({int(s * n_win) for s in splits} | {0, n_win})
    got = np.concatenate([sensor.mean_output(starts[i:j], dur) for i, j in zip(cuts, cuts[1:])])
    ref = ode_window_means(sensor, pcs, -0.1, starts, dur)
    scale = 2.0 * sum(np.abs(p.alpha_rad_s).sum() + np.abs(p.beta_rad_s2).sum() * 0.2 for p in pcs) + 1.0
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-8 * scale)


@pytest.mark.parametrize("sections", [
    [Section("lowpass", 2, 20.0, 1.0)],                                 # critically damped: defective A
    [Section("highpass", 1, 5.0), Section("lowpass", 1, 5.0)],          # repeated pole across sections
])
def test_defective_dynamics_stay_exact(sections):
    pcs = chain(0.0, [(0.2, np.array([3.0, 11.0]), np.array([1.0, -0.5]), np.array([2.0, 0.0]),
                       np.array([0.3, 2.0]))])
    sensor = LinearRateSensor(sections, 1.0, source(pcs), t_origin_s=-0.05)
    assert sensor._vinv is None  # no modal inverse: the expm path is the one under test
    starts = np.linspace(-0.02, 0.4, 30)
    np.testing.assert_allclose(sensor.mean_output(starts, 4e-3),
                               ode_window_means(sensor, pcs, -0.05, starts, 4e-3), atol=1e-9)


def dwell(f_hz, amp=1.0, phase=0.3, t0=0.0):
    return [at_rest(t0 - 10.0, t0), MotionPiece(t0, math.inf, [f_hz], [amp], [0.0], [phase])]


def window_mean_of_sine(g, f_hz, phase, starts, d):
    """Window means of Re[g·(−j)e^{j(wt+φ)}] = |g| sin(wt + φ + arg g)."""
    w, psi = 2 * math.pi * f_hz, phase + np.angle(g)
    return abs(g) * (np.cos(w * starts + psi) - np.cos(w * (starts + d) + psi)) / (w * d)


@settings(max_examples=15, deadline=None)
@given(kind=st.sampled_from(["highpass", "lowpass"]), order=st.sampled_from([1, 2]),
       corner=st.floats(1.0, 100.0), zeta=st.floats(0.3, 2.0), f=st.floats(0.5, 200.0),
       gain=st.floats(0.05, 20.0), settled=st.booleans())
def test_steady_state_equals_transfer_function_and_fusion_model(kind, order, corner, zeta, f, gain, settled):
    pcs = dwell(f, phase=0.3)
    # settled: start on the forced response inside the dwell; else from rest, after the transient
    sensor = LinearRateSensor([Section(kind, order, corner, zeta)], gain, source(pcs),
                              t_origin_s=1.0 if settled else -1.0)
    g = sensor.response(f)
    assert g == pytest.approx(complex(SensorModel(kind, order, corner, gain, zeta).response(f)), rel=1e-12)
    a, b, c, d = sensor.state_space()
    ma, mb, mc, md = SensorModel(kind, order, corner, gain, zeta).state_space()
    for mine, theirs in ((a, ma), (b, mb), (c, mc), (d, md)):
        np.testing.assert_allclose(mine, theirs, rtol=1e-15)
    # 40 time constants of the slowest pole: ζω for an underdamped pair, ω(ζ − √(ζ² − 1)) for an
    # overdamped one (at ζ = 2 that is 0.27ω — ω alone left a 1e-6 transient in the mean)
    slowest = 1.0 if order == 1 else (zeta - math.sqrt(zeta ** 2 - 1) if zeta > 1 else zeta)
    t_settle = 1.0 + 40.0 / (2 * math.pi * corner * slowest)
    starts = t_settle + np.linspace(0, 2.0 / f, 50)
    d = 1e-3 / f
    np.testing.assert_allclose(sensor.mean_output(starts, d), window_mean_of_sine(g, f, 0.3, starts, d),
                               atol=1e-9 * gain)


@settings(max_examples=10, deadline=None)
@given(f=st.floats(1.0, 300.0), latency=st.floats(1e-5, 5e-3))
def test_latency_is_a_delay_phase_minus_w_tau(f, latency):
    pcs = dwell(f, t0=0.5)
    secs = [Section("lowpass", 2, 40.0, 0.7)]
    lagged = LinearRateSensor(secs, 1.0, source(pcs), latency_s=latency, t_origin_s=0.0)
    plain = LinearRateSensor(secs, 1.0, source(pcs), t_origin_s=0.0)
    starts = np.linspace(0.2, 1.5, 400)
    np.testing.assert_allclose(lagged.mean_output(starts + latency, 2e-4), plain.mean_output(starts, 2e-4),
                               rtol=0, atol=1e-12)
    assert np.angle(lagged.response(f) / plain.response(f)) == pytest.approx(
        np.angle(np.exp(-2j * math.pi * f * latency)), abs=1e-12)
    late = 8.0 + np.linspace(0, 1 / f, 20)
    np.testing.assert_allclose(lagged.mean_output(late, 1e-4),
                               window_mean_of_sine(lagged.response(f), f, 0.3, late - 0.5, 1e-4), atol=1e-9)


def sweep_pieces(n=200, f0=5.0, f1=300.0, dt=0.01):
    """A phase-continuous stepped sweep with an amplitude ramp, one piece per dt."""
    pcs, t, amp, ph, ang = [at_rest(-10.0, 0.0)], 0.0, np.array([0.2]), np.array([0.0]), 0.0
    for f in np.geomspace(f0, f1, n):
        p = MotionPiece(t, t + dt, [f], amp, [0.5], ph, ang)
        pcs.append(p)
        amp, ph, ang = p.end_state()
        t += dt
    pcs.append(MotionPiece(t, math.inf, [f1], amp, [0.0], ph, ang))
    return pcs


@settings(max_examples=15, deadline=None)
@given(cuts=st.lists(st.integers(1, 3999), max_size=6, unique=True), gap_calls=st.booleans())
def test_arbitrary_splits_give_the_same_output(cuts, gap_calls):
    pcs = sweep_pieces()
    starts, dur = np.arange(4000) * 5e-4, 5e-4

    def run(bounds, noise_seed=None):
        s = mhd_sensor(source(pcs), None if noise_seed is None else np.random.default_rng(noise_seed),
                       noise=noise_seed is not None, t_origin_s=-1.0)
        return np.concatenate([s.mean_output(starts[i:j], dur) for i, j in zip(bounds, bounds[1:])])

    bounds = [0, *sorted(cuts), 4000]
    whole = run([0, 4000])
    np.testing.assert_allclose(run(bounds), whole, rtol=0, atol=1e-12)
    assert run(bounds, 5).tobytes() == run(bounds, 5).tobytes()  # same seed, same calls: same bytes
    if gap_calls:  # skipping windows (a gap between calls) leaves the later ones unchanged
        s = mhd_sensor(source(pcs), None, noise=False, t_origin_s=-1.0)
        s.mean_output(starts[:10], dur)
        np.testing.assert_allclose(s.mean_output(starts[3000:], dur), whole[3000:], rtol=0, atol=1e-12)


def test_edges_form_equals_window_form():
    pcs = sweep_pieces()
    edges = np.cumsum(np.random.default_rng(2).uniform(1e-4, 1e-3, 3000)) - 0.01
    by_edges = lf_sensor(source(pcs), None, noise=False, t_origin_s=-1.0).mean_over_edges(edges)
    by_windows = lf_sensor(source(pcs), None, noise=False, t_origin_s=-1.0).mean_output(edges[:-1], np.diff(edges))
    np.testing.assert_allclose(by_edges, by_windows, rtol=0, atol=1e-9)
    with pytest.raises(ValueError, match="strictly increasing"):
        lf_sensor(source(pcs), None, noise=False).mean_over_edges(edges[::-1])


@pytest.mark.parametrize("density,d", [(5e-6, 1e-3), (0.0035, 0.02)])
def test_white_noise_sigma_is_density_over_sqrt_2d(density, d):
    sensor = LinearRateSensor([Section("lowpass", 1, 10.0)], 1.0, source([at_rest(-1.0)]),
                              noise_density=density, bias=0.25, rng=np.random.default_rng(3))
    out = sensor.mean_output(np.arange(20000) * d, d)
    sigma = density / math.sqrt(2 * d)
    assert np.std(out) == pytest.approx(sigma, rel=0.03)  # 20000 draws: σ of the σ estimate 0.5 %
    assert np.mean(out) == pytest.approx(0.25, abs=5 * sigma / math.sqrt(out.size))


def test_presets_frequency_response():
    mhd = mhd_sensor(source([at_rest(0.0)]), None, noise=False)
    assert abs(mhd.response(100.0)) == pytest.approx(0.1, rel=1e-3)  # passband: the sensitivity
    assert abs(mhd.response(2.5)) == pytest.approx(0.1 / math.sqrt(2), rel=1e-3)  # the −3 dB corner
    assert abs(mhd.response(1000.0)) == pytest.approx(0.1, rel=0.01)
    lf = lf_sensor(source([at_rest(0.0)]), None, noise=False)
    assert abs(lf.response(0.1)) == pytest.approx(180 / math.pi, rel=1e-4)  # °/s per rad/s
    assert lf.response(40.0) == pytest.approx(180 / math.pi / (2j * 0.7) * np.exp(-2j * math.pi * 40 * 6e-4))
    assert LF_PRESET.noise_density_dps_per_rthz / math.sqrt(2) * 60 == pytest.approx(0.15)
    assert MHD_PRESET.offset_v == pytest.approx(mhd.mean_output(np.array([1.0]), 0.01)[0])


class FakeLink:
    pending_bytes = 0

    def __init__(self):
        self.data = bytearray()

    def write(self, data: bytes) -> None:
        self.data += data

    def write_frames(self, data: bytes, frame_bytes: int) -> None:
        self.data += data


def serial_line(pcs, noise=False, params=LF_PRESET, seed=0):
    world = World(seed)
    unit = LfGyroUnit(source(pcs), world.rng("lf"), params, t_origin_s=-1.0, noise=noise)
    zero = lambda edges: GyroInputs(np.zeros((edges.size - 1, 3)), np.zeros((edges.size - 1, 3)))
    dev = FogSerialDevice(world, unit, zero, serial="LF1", full_scale_dps=params.full_scale_dps,
                          scale_factor_pulses_per_arcsec=params.scale_factor_pulses_per_arcsec)
    link = FakeLink()
    dev.connect(link)
    dev.receive(link, b"$START\r\n")
    link.data.clear()  # the $OK reply
    return world, unit, dev, link


@settings(max_examples=8, deadline=None)
@given(steps=st.lists(st.floats(0.001, 0.4), min_size=1, max_size=6))
@example(steps=[0.39999999999999997])  # just short of a frame edge: that frame has not ended
def test_adapter_pulses_sum_to_the_angle_on_the_frame_line(steps):
    pcs = sweep_pieces(n=60, f0=2.0, f1=40.0, dt=0.02)
    world, unit, dev, link = serial_line(pcs)
    for s in steps:  # advances of any length: frames come in batches of any size
        world.advance(s)
    frames = np.frombuffer(bytes(link.data), ff.FRAME_DTYPE)
    # every frame whose end instant k/2000 (as the line computes it) has come by now
    due = int(np.count_nonzero(np.arange(1, int(world.now * 2000) + 3) / 2000 <= world.now))
    assert frames.size == dev.frames_sent == due
    assert np.all(frames["status"] & 0x7F == STATUS_READY)
    assert np.all(frames["temperature"] == 2500)
    fresh = lf_sensor(source(pcs), None, noise=False, t_origin_s=-1.0)
    total_dps_s = float(fresh.integral_output(np.array([0.0]), frames.size / 2000)[0]) \
        + LF_PRESET.bias_dph / 3600 * frames.size / 2000
    total_pulses = total_dps_s * 3600 * LF_PRESET.scale_factor_pulses_per_arcsec
    assert abs(int(frames["count"].astype(np.int64).sum()) - total_pulses) <= 1.0
    if world.now > 0.3:
        assert np.abs(frames["count"]).max() > 5  # the motion is visible in the counts


def test_adapter_noise_is_the_angle_random_walk_and_deterministic():
    counts = []
    for _ in range(2):
        world, unit, dev, link = serial_line([at_rest(-5.0)], noise=True, seed=4)
        world.advance(2.0)
        counts.append(bytes(link.data))
    assert counts[0] == counts[1]
    c = np.frombuffer(counts[0], ff.FRAME_DTYPE)["count"].astype(float)
    # per frame of 0.5 ms: σ = ARW·√dt (° → pulses); quantisation adds ≤ 1/12 pulse²
    sigma = LF_PRESET.arw_deg_per_rh / 60 * math.sqrt(5e-4) * 3600 * LF_PRESET.scale_factor_pulses_per_arcsec
    assert np.std(c) == pytest.approx(math.sqrt(sigma ** 2 + 1 / 12), rel=0.05)


def test_adapter_power_status_and_over_range():
    unit = LfGyroUnit(source(dwell(2.0, amp=20.0)), None, LF_PRESET.replace(full_scale_dps=100.0),
                      t_origin_s=0.0, noise=False)
    assert unit.powered(0.0) and unit.temperature_c(0.0) == 25.0
    edges = np.linspace(0.0, 1.0, 2001)
    counts = unit.pulses(edges, None, None)
    status = unit.status(edges[1:])
    clipped = (status & STATUS_OVER_RANGE) != 0
    assert clipped.any() and not clipped.all()  # 20 rad/s peaks ≈ 1146 °/s > 100 °/s
    assert np.abs(counts[clipped]).min() >= 100.0 * 5e-4 * 36000 - 1
    unit.set_supply(1.2, 0.0)
    assert unit.powered(1.1) and not unit.powered(1.3) and unit.status(1.3) == 0
    counts = unit.pulses(np.linspace(1.0, 1.5, 1001))
    assert np.all(counts[480:] == 0) and np.any(counts[:380] != 0)
    unit.set_supply(1.6, 24.0)
    assert unit.status(1.7) & STATUS_READY
    with pytest.raises(ValueError, match="precedes"):
        unit.pulses(np.array([0.5, 0.6]))


def test_requests_going_back_in_time_are_refused():
    s = lf_sensor(source([at_rest(-1.0)]), None, noise=False)
    s.mean_output(np.array([1.0, 2.0]), 0.1)
    with pytest.raises(ValueError, match="non-decreasing time order"):
        s.mean_output(np.array([1.5]), 0.1)
    with pytest.raises(ValueError, match="cover"):
        LinearRateSensor([Section("lowpass", 1, 1.0)], 1.0, lambda t0, t1: [at_rest(t0 + 1.0)]).mean_output(
            np.array([0.0]), 0.1)
    with pytest.raises(ValueError, match="contiguous"):
        LinearRateSensor([Section("lowpass", 1, 1.0)], 1.0,
                         lambda t0, t1: [at_rest(-1.0, 0.2), at_rest(0.5)]).mean_output(np.array([0.0]), 1.0)


def test_noise_switched_on_without_a_generator_is_refused_by_name():
    """``noise_density`` is a plain attribute: raising it on a sensor built without ``rng``
    must fail naming what is missing, not with an AttributeError on None."""
    s = LinearRateSensor([Section("lowpass", 1, 1.0)], 1.0, source([at_rest(-1.0)]))
    s.noise_density = 1.0
    with pytest.raises(ValueError, match="noise_density = 1.0 > 0 needs rng"):
        s.mean_output(np.array([0.0]), 0.1)


@pytest.mark.parametrize("make,match", [
    (lambda: MhdParams(highpass_corner_hz=0.0), r"highpass_corner_hz = 0.0 must be in \[0.01, 100\]"),
    (lambda: MhdParams(highpass_order=3), "highpass_order = 3 must be 1 or 2"),
    (lambda: MhdParams(lowpass_corner_hz=2e6), r"lowpass_corner_hz = 2000000.0 must be in \[100, 1e\+06\]"),
    (lambda: MhdParams(sensitivity_v_per_rad_s=0.0), r"magnitude in \[0.0001, 100\]"),
    (lambda: MhdParams(noise_rad_s_per_rthz=-1.0), r"noise_rad_s_per_rthz = -1.0 must be in \[0, 1\]"),
    (lambda: MhdParams(offset_v=math.nan), r"offset_v = nan must be in \[-1, 1\]"),
    (lambda: MhdParams(latency_s=1.0), r"latency_s = 1.0 must be in \[0, 0.1\]"),
    (lambda: LfRateParams(corner_hz=0.0), r"corner_hz = 0.0 must be in \[0.1, 10000\]"),
    (lambda: LfRateParams(zeta=0.0), r"zeta = 0.0 must be in \[0.05, 10\]"),
    (lambda: LfRateParams(arw_deg_per_rh=-0.1), r"arw_deg_per_rh = -0.1 must be in \[0, 100\]"),
    (lambda: LfRateParams(frame_clock_error_ppm=5000.0), r"frame_clock_error_ppm = 5000.0 must be in"),
    (lambda: LfRateParams(scale_factor_pulses_per_arcsec=0.0), r"scale_factor_pulses_per_arcsec = 0.0"),
    (lambda: LfRateParams(supply_max_v=5.0), r"supply_max_v = 5.0 must be in \[9, 100\]"),
    (lambda: Section("bandpass", 1, 1.0), "must be one of highpass, lowpass"),
    (lambda: Section("lowpass", 1, -1.0), r"corner_hz = -1.0 must be in \(0, 1e\+09\]"),
    (lambda: LinearRateSensor([Section("lowpass", 1, 1.0)], 1.0, source([]), noise_density=1.0),
     "rng must be a numpy.random.Generator"),
    (lambda: LinearRateSensor([Section("lowpass", 1, 1.0)], 1.0, source([]), latency_s=-1.0),
     r"latency_s = -1.0 must be in \[0, 10\]"),
])
def test_bad_parameters_raise_naming_the_range(make, match):
    with pytest.raises(ValueError, match=match):
        make()


def test_sensors_on_the_angular_table_follow_their_frequency_response():
    table = AngularMotion(distortion=(0.0, 0.0))
    table.start_tones(0.0, [Tone(0.5, 80.0)])  # rate 0.5 sin(2π·80 t) once the 1-s ramp is over
    mhd = mhd_sensor(table.pieces, None, noise=False, t_origin_s=-0.5)
    lf = lf_sensor(table.pieces, None, noise=False, t_origin_s=-0.5)
    starts = 3.0 + np.arange(200) * 1e-4
    for sensor, offset in ((mhd, MHD_PRESET.offset_v), (lf, LF_PRESET.bias_dph / 3600)):
        expected = 0.5 * window_mean_of_sine(sensor.response(80.0), 80.0, 0.0, starts, 1e-4) + offset
        np.testing.assert_allclose(sensor.mean_output(starts, 1e-4), expected, rtol=0,
                                   atol=1e-9 * abs(sensor.response(80.0)))
