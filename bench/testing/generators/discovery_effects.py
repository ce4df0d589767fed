"""A second generator of every catalogue effect, written apart from the catalogue (issue 15).

The scorecard must not grade the discovery catalogue only on records its own ``draw`` /
``Model.simulate`` made: a shared misunderstanding would pass unseen. Here each effect is
realised by different code and a different discretisation, using the simulator's physics
(``sim/physics``) where it has the effect:

================================  ==========================================================
effect                            realised as
================================  ==========================================================
warmup_exponential                one self-heating node (``sim.physics.thermal_lti``) powered on
linear_drift                      a rate integrated sample by sample (cumulative sum)
temperature_bias                  ``np.polyval`` of the temperature rise
temperature_scale_factor          a temperature-dependent gain multiplying the whole response
k2 / k3 / misalignment (accel.)   IEEE 1293 static model ``sim.physics.accelerometer
                                  .indicated_acceleration_g`` (K2, K3, δo·a_p)
asymmetry / k3 (gyro)             ``sim.physics.gyro.indicated_rate_dps`` (asymmetry, cubic
                                  non-linearity of full scale)
g_sensitivity, vibration_rect.    the specific force / vibration column through a gain
quantization                      a reading rounded half up on a lattice with a random offset
dead_zone                         a threshold comparator on the input
saturation                        an acquisition range clipping the reading
sinusoidal_interference           a tone generated 8× faster and averaged over each sample
gauss_markov                      ``sim.physics.noise.GaussMarkov``
rate_random_walk                  ``sim.physics.noise.RandomWalk``
time_delay                        a band-limited fractional delay (FFT phase ramp)
lowpass / highpass                the first-order ODE integrated with 8 RK4 sub-steps per sample
flicker_noise                     the FOG simulator's ``KnotBias`` (Gauss–Markov terms one per
                                  decade on a knot grid, interpolated)
bias_jump                         steps at random fractional instants, the reading averaging
                                  over its interval
angle_quantization                the FOG's pulse counter (``sim.physics.gyro.quantise_pulses``)
                                  on the integrated angle: readings on the pulse lattice
thermal_two_node                  a two-node thermal network (die and case) integrated with RK4
                                  sub-steps — our own model: the simulator's thermal issue
                                  (#14) was not merged when this was written
temperature_rate                  the one-sample centred derivative of the temperature
thermal_hysteresis                a play operator on a 4× up-sampled temperature, averaged
================================  ==========================================================

The parameters are the catalogue's draws (so detectability is the same); only the realisation
differs. ``realise(kind, rec, truth, rng)`` returns the readings.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from bench.discovery.data import Record
from bench.discovery.model import Model
from sim.physics.accelerometer import AccelerometerParams, indicated_acceleration_g
from sim.physics.gyro import indicated_rate_dps, quantise_pulses
from sim.physics.gyro_noise import KnotBias
from sim.physics.gyro_params import TACTICAL
from sim.physics.noise import GaussMarkov, RandomWalk, WhiteNoise
from sim.physics.thermal_lti import ExpPoly, LinearBlock

T_REF_C = 25.0
SUBSTEPS = 8

Params = dict[str, float]


def _child(rng: np.random.Generator) -> np.random.Generator:
    return np.random.default_rng(int(rng.integers(0, 2 ** 63)))


# ---- input path ---------------------------------------------------------------------------

def _delay_fft(u: np.ndarray, delay_s: float, dt: float) -> np.ndarray:
    """Band-limited fractional delay: a linear phase ramp on the FFT of the input padded by its
    end values (a table holds its last rate)."""
    n = u.size
    pad = 2 * n
    x = np.concatenate([u, np.full(pad - n, u[-1])])
    x = np.concatenate([np.full(n // 2, u[0]), x])[: pad + n // 2]
    spec = np.fft.rfft(x - u[0])
    f = np.fft.rfftfreq(x.size, dt)
    y = np.fft.irfft(spec * np.exp(-2j * np.pi * f * delay_s), x.size) + u[0]
    return y[n // 2: n // 2 + n]


def _first_order_ode(u: np.ndarray, dt: float, corner_hz: float, highpass: bool) -> np.ndarray:
    """x' = ω(u − x) (low-pass; the high-pass output is u − x) from rest at u[0], the input
    linearly interpolated within each sample, RK4 with SUBSTEPS sub-steps."""
    w = 2 * np.pi * corner_hz
    h = dt / SUBSTEPS
    x = float(u[0])
    out = np.empty_like(u)
    out[0] = x
    for k in range(1, u.size):
        a, b = u[k - 1], u[k]
        for s in range(SUBSTEPS):
            t0 = s / SUBSTEPS
            ua, um, ub = a + (b - a) * t0, a + (b - a) * (t0 + 0.5 / SUBSTEPS), a + (b - a) * (t0 + 1 / SUBSTEPS)
            k1 = w * (ua - x)
            k2 = w * (um - (x + 0.5 * h * k1))
            k3 = w * (um - (x + 0.5 * h * k2))
            k4 = w * (ub - (x + h * k3))
            x += h * (k1 + 2 * k2 + 2 * k3 + k4) / 6
        out[k] = x
    return (u - out + u[0]) if highpass else out


def input_stage(eid: str, p: Params, u: np.ndarray, rec: Record) -> np.ndarray:
    dt = rec.dt_s
    if eid == "time_delay":
        return _delay_fft(u, p["delay_s"], dt)
    if eid == "lowpass_bandwidth":
        return _first_order_ode(u, dt, p["bandwidth_hz"], highpass=False)
    if eid == "highpass_rolloff":
        return _first_order_ode(u, dt, p["corner_hz"], highpass=True)
    if eid == "dead_zone":
        h = p["half_width"]
        return np.where(u > h, u - h, np.where(u < -h, u + h, 0.0))
    raise KeyError(eid)


# ---- static response (the simulators' own models) ---------------------------------------

def static_response(kind: str, u: np.ndarray, rec: Record, effects: dict[str, Params]) -> tuple[np.ndarray, set]:
    """The sensor's response to the (transformed) input through the simulator's static model,
    and the effect ids it realised."""
    done: set[str] = set()
    if kind == "accelerometer":
        k2 = effects.get("k2_nonlinearity", {}).get("k2_per_u", 0.0)
        k3 = effects.get("k3_nonlinearity", {}).get("k3_per_u2", 0.0)
        mis = effects.get("misalignment", {}).get("angle_rad", 0.0)
        cross = rec.cross_input if rec.cross_input is not None else np.zeros(rec.n)
        try:
            ap = AccelerometerParams(k0_g=0.0, k2_g_per_g2=k2, k3_g_per_g3=k3, delta_o_rad=mis, delta_p_rad=0.0,
                                     kip_g_per_g2=0.0, kio_g_per_g2=0.0)
        except ValueError:
            return u.copy(), done
        done |= {e for e in ("k2_nonlinearity", "k3_nonlinearity", "misalignment") if e in effects}
        f = np.column_stack([u, cross, np.zeros(rec.n)])
        return indicated_acceleration_g(ap, f), done
    if kind == "gyro":
        asym = effects.get("scale_factor_asymmetry", {}).get("asymmetry", 0.0)
        k3 = effects.get("k3_nonlinearity", {}).get("k3_per_u2", 0.0)
        fs = max(1.0, 1.05 * float(np.max(np.abs(u))))
        try:
            gp = TACTICAL.replace(full_scale_dps=fs, scale_factor_error_ppm=0.0, asymmetry_ppm=asym * 1e6,
                                  nonlinearity_ppm=k3 * fs * fs * 1e6)
        except ValueError:
            return u.copy(), done
        done |= {e for e in ("scale_factor_asymmetry", "k3_nonlinearity") if e in effects}
        return indicated_rate_dps(gp, u), done
    return u.copy(), done


# ---- additive terms ------------------------------------------------------------------------

def _warmup(p: Params, rec: Record) -> np.ndarray:
    # one self-heating node (ambient 23 °C, 4 °C rise) in the simulator's closed-form LTI
    # solver (sim/physics/thermal_lti: the responses its thermal units are made of), switched
    # on at power-on: dT/dt = (23 + 4 − T)/τ
    ambient_c, delta_c, tau_s = 23.0, 4.0, p["tau_s"]
    node = LinearBlock(np.array([[-1.0 / tau_s]]), np.array([[1.0 / tau_s]]))
    t_on = rec.column("t_on")
    start = float(rec.t_s[0] - t_on[0])  # power-on on the record's clock
    temp = node.respond([ambient_c], ExpPoly.constant(start, ambient_c + delta_c)).at(np.maximum(rec.t_s, start))[:, 0]
    return p["amplitude"] * (ambient_c + delta_c - temp) / delta_c


def _drift(p: Params, rec: Record) -> np.ndarray:
    return np.concatenate([[0.0], np.cumsum(p["slope_per_s"] * np.diff(rec.t_s))])


def _sine_averaged(p: Params, rec: Record) -> np.ndarray:
    dt = rec.dt_s
    off = (np.arange(SUBSTEPS) + 0.5) / SUBSTEPS - 0.5
    tt = (rec.t_s - rec.t_s[0])[:, None] + off[None, :] * dt
    return p["amplitude"] * np.mean(np.sin(2 * np.pi * p["freq_hz"] * tt + p["phase_rad"]), axis=1)


def _jumps_averaged(p: Params, rec: Record) -> np.ndarray:
    """Each jump at its instant; a reading averages the level over [t − dt/2, t + dt/2]."""
    out = np.zeros(rec.n)
    dt = rec.dt_s
    for k in range(1, 4):
        s = p.get(f"size_{k}", 0.0)
        if s:
            out += s * np.clip((rec.t_s + 0.5 * dt - p[f"time_{k}_s"]) / dt, 0.0, 1.0)
    return out


def _two_node(p: Params, rec: Record) -> np.ndarray:
    """A die node coupled to a case node; self-heating switched on at power-on. The network's
    two eigen time constants are the drawn ones; the bias reads a mix of the two node rises
    set so the two modes have the drawn shares. RK4, SUBSTEPS sub-steps per sample."""
    tf, ts = p["tau_fast_s"], p["tau_slow_s"]
    # modal form x = V·z, z_i' = −z_i/τ_i; a fixed, well-conditioned V (die, case) of the network
    v = np.array([[1.0, 0.6], [-0.3, 1.0]])
    m = v @ np.diag([-1 / tf, -1 / ts]) @ np.linalg.inv(v)
    amp, frac = p["amplitude"], p["fraction_slow"]
    # output c·x(t) = amp·((1 − f)e^{−t/τf} + f·e^{−t/τs}): x0 = V·[1, 1], c = [a_f, a_s]·V⁻¹
    x0 = v @ np.array([1.0, 1.0])
    c = np.array([amp * (1 - frac), amp * frac]) @ np.linalg.inv(v)
    t_on = rec.column("t_on")
    x = x0.copy()
    t_prev = 0.0
    out = np.empty(rec.n)
    for k in range(rec.n):
        span = float(t_on[k]) - t_prev
        if span > 0:
            h = span / SUBSTEPS
            for _ in range(SUBSTEPS):
                k1 = m @ x
                k2 = m @ (x + 0.5 * h * k1)
                k3 = m @ (x + 0.5 * h * k2)
                k4 = m @ (x + h * k3)
                x = x + h * (k1 + 2 * k2 + 2 * k3 + k4) / 6
            t_prev = float(t_on[k])
        out[k] = c @ x
    return out


def _hysteresis(p: Params, rec: Record) -> np.ndarray:
    temp = rec.column("temp")
    up = 4
    tt = np.linspace(rec.t_s[0], rec.t_s[-1], (rec.n - 1) * up + 1)
    fine = np.interp(tt, rec.t_s, temp)
    w = 0.5 * p["width_c"]
    play = np.empty_like(fine)
    v = fine[0]
    for k, x in enumerate(fine):
        v = min(max(v, x - w), x + w)
        play[k] = v
    rel = (play - fine) / w
    # average each reading over its own interval (the centred window of up samples)
    avg = np.convolve(rel, np.ones(up) / up, mode="same")[::up]
    return p["half_gap"] * avg[: rec.n]


def _lagged(p: Params, rec: Record) -> np.ndarray:
    """The element's temperature: the logged one through a first-order lag (RK4 sub-steps,
    :func:`_first_order_ode`), from rest at the first reading; bias and gain follow it."""
    d = _first_order_ode(rec.column("temp"), rec.dt_s, 1.0 / (2 * np.pi * p["lag_s"]), False) - T_REF_C
    out = p["coef_per_c"] * d
    if rec.logged("input"):
        out = out + p["sf_coef_per_c"] * d * rec.column("input")
    return out


ADDITIVE: dict[str, Callable[[Params, Record], np.ndarray]] = {
    "warmup_exponential": _warmup,
    "linear_drift": _drift,
    "temperature_bias": lambda p, rec: np.polyval([p["coef_per_c2"], p["coef_per_c"], 0.0],
                                                  rec.column("temp") - T_REF_C),
    "k2_nonlinearity": lambda p, rec: p["k2_per_u"] * rec.column("input") * rec.column("input"),
    "k3_nonlinearity": lambda p, rec: p["k3_per_u2"] * rec.column("input") ** 3,
    "scale_factor_asymmetry": lambda p, rec: 0.5 * p["asymmetry"] * np.abs(rec.column("input")),
    "misalignment": lambda p, rec: np.sin(p["angle_rad"]) * rec.column("cross_input"),
    "g_sensitivity": lambda p, rec: p["coef_per_g"] * rec.column("accel"),
    "vibration_rectification": lambda p, rec: p["coef_per_g2"] * np.square(rec.column("vib")),
    "sinusoidal_interference": _sine_averaged,
    "bias_jump": _jumps_averaged,
    "thermal_two_node": _two_node,
    "temperature_rate": lambda p, rec: p["coef_per_c_per_s"] * np.gradient(rec.column("temp"), rec.t_s),
    "thermal_hysteresis": _hysteresis,
    "thermal_lag": _lagged,
}


# ---- noise ---------------------------------------------------------------------------------

def _flicker(p: Params, rec: Record, rng: np.random.Generator) -> np.ndarray:
    """The FOG simulator's flicker: one Gauss–Markov term per decade from tau_min_s up to ten
    records (its own σ rule), on KnotBias's knot grid."""
    lo = max(p["tau_min_s"], rec.dt_s)
    hi = 10 * rec.duration_s
    k = int(math.ceil(math.log10(hi / lo))) + 1
    taus = np.geomspace(lo, hi, k)
    r = taus[1] / taus[0]
    sigma = p["b"] * math.sqrt(math.log(r) / math.pi)
    bias = KnotBias(np.full(k, sigma), taus, 0.0, step_s=lo / 64, rng=rng)
    return bias.values(rec.t_s - rec.t_s[0])


NOISE: dict[str, Callable[[Params, Record, np.random.Generator], np.ndarray]] = {
    "gauss_markov": lambda p, rec, rng: GaussMarkov(p["sigma"], p["tau_s"], rng).sample(rec.t_s),
    "rate_random_walk": lambda p, rec, rng: RandomWalk(p["k_per_rs"], rng).sample(rec.t_s),
    "flicker_noise": _flicker,
}


# ---- output stage --------------------------------------------------------------------------

def output_stage(eid: str, p: Params, y: np.ndarray, rec: Record, rng: np.random.Generator) -> np.ndarray:
    if eid == "saturation":
        return np.minimum(np.maximum(y, -p["limit"]), p["limit"])
    if eid == "quantization":
        s = p["step"]
        off = float(rng.uniform(0, s))
        return np.floor((y - off) / s + 0.5) * s + off
    if eid == "angle_quantization":
        # the FOG's pulse counter: angle per frame in pulses, counted with the carried remainder
        pulse = math.sqrt(12.0) * p["q_angle"]
        dt = np.diff(rec.t_s, prepend=rec.t_s[0] - rec.dt_s)
        counts, _ = quantise_pulses(y * dt / pulse, int(rng.integers(0, 1 << 23)))
        return counts * pulse / dt
    raise KeyError(eid)


OUTPUT = ("saturation", "quantization", "angle_quantization")
INPUT = ("time_delay", "lowpass_bandwidth", "highpass_rolloff", "dead_zone")


def realise(kind: str, rec: Record, truth: Model, rng: np.random.Generator) -> np.ndarray:
    """Readings of ``truth`` (base + effects, the catalogue's parameters) on rec's stimulus,
    every effect realised by this module's own code (see the module docstring)."""
    effects = {eid: dict(p) for eid, p in truth.effects}
    b = truth.base
    u = rec.input.copy() if rec.input is not None else np.zeros(rec.n)
    for eid in (e for e in effects if e in INPUT):
        u = input_stage(eid, effects[eid], u, rec)
    core, done = static_response(kind, u, rec, effects)
    y = b.bias + b.scale_factor * core
    t_scale = effects.get("temperature_scale_factor")
    if t_scale is not None:  # the gain's temperature dependence multiplies the response
        y = b.bias + b.scale_factor * core * (1.0 + t_scale["sf_coef_per_c"] * (rec.column("temp") - T_REF_C)
                                              / b.scale_factor)
        done.add("temperature_scale_factor")
    for eid, p in effects.items():
        if eid in done or eid in INPUT or eid in OUTPUT:
            continue
        if eid in ADDITIVE:
            y = y + ADDITIVE[eid](p, rec)
        elif eid in NOISE:
            y = y + NOISE[eid](p, rec, _child(rng))
        else:
            raise KeyError(f"no independent realisation of {eid!r}")
    white = WhiteNoise(b.noise_sd * math.sqrt(2.0 * rec.dt_s), _child(rng))
    y = y + white.sample(rec.n, rec.dt_s)
    for eid in (e for e in effects if e in OUTPUT):
        y = output_stage(eid, effects[eid], y, rec, _child(rng))
    return y
