"""Logged experiments per sensor kind in which every catalogue effect of that kind is identifiable.

``make_experiment(kind, rng)`` returns the stimulus of a realistic run as a Record with
``y = 0`` (fill it with ``Model.simulate``). Design rules, so that each effect's signature is
present and not a copy of another's or of the calibration regressors (1, input):

* the record starts at power-on (``t_on = t``) and lasts many warm-up time constants;
* inputs dwell at levels in a shuffled order (time and input are not collinear), repeated with
  different shuffles, with levels on both signs, near zero (dead zone) and near the ends of the
  range (k2, k3, asymmetry, saturation), and moves at a finite slew rate as a real table or
  tumble does (delay and bandwidth show on the moves);
* temperature follows a smooth random profile through knots (not a ramp nor an exponential,
  so it separates from drift and warm-up) on top of self-heating;
* cross-axis input, specific force and vibration change on their own schedules.

Accelerometer: a tumble in the vertical plane, input = cos θ, cross_input = sin θ (g), 30
positions (15° steps and ±0.05°, ±0.3°, ±1° around horizontal) visited three times in shuffled
orders, moves at 10 deg/s; vibration segments 0.5-3 g rms. Default 1 Hz for 2 h.
Gyro: rate-table steps to 0, ±0.02 ... ±100 deg/s at 100 deg/s², a second axis's rate as
cross_input, the specific force along the input axis (orientation) in −1..1 g, vibration
segments. Default 10 Hz for 2000 s.
MHD: a multi-tone rate (0.7-140 Hz, peak ≈ 100 deg/s) faded in from rest, a multi-tone
cross-axis rate, a few °C temperature change. Default 500 Hz for 60 s.
"""

from __future__ import annotations

import numpy as np

from bench.discovery.data import Record
from bench.discovery.effects_base import KINDS

DEFAULTS = {"accelerometer": (7200, 1.0), "gyro": (20000, 10.0), "mhd": (30000, 500.0)}


def _dwell_path(t: np.ndarray, levels: np.ndarray, slew_per_s: float) -> np.ndarray:
    """Dwell at each level for an equal share of the record, moving between them at slew_per_s
    (at most half a dwell per move)."""
    t0, dur = t[0], t[-1] - t[0]
    starts = t0 + dur * np.arange(len(levels)) / len(levels)
    kt, kv = [t0], [levels[0]]
    for i in range(1, len(levels)):
        # a short record's dwells may be shorter than a move: then move faster (half a dwell)
        ramp = min(abs(levels[i] - levels[i - 1]) / slew_per_s, 0.5 * dur / len(levels))
        kt += [starts[i], starts[i] + ramp]
        kv += [levels[i - 1], levels[i]]
    kt.append(t[-1] + 1.0)
    kv.append(levels[-1])
    knots = np.asarray(kt)
    # zero-length moves: keep knots increasing
    knots = np.maximum.accumulate(knots + np.arange(knots.size) * 1e-9 * max(dur, 1.0))
    return np.interp(t, knots, np.asarray(kv, float))


def _temperature(t: np.ndarray, rng: np.random.Generator, start_c: float, swing_c: float,
                 heating_c: float, heating_tau_s: float) -> np.ndarray:
    dur = t[-1] - t[0]
    knots_t = t[0] + dur * np.linspace(0, 1, 7)
    knots_v = start_c + swing_c * np.concatenate([[0.0], rng.uniform(-1, 1, 6)])
    chamber = np.interp(t, knots_t, knots_v)
    return chamber + heating_c * (1 - np.exp(-(t - t[0]) / heating_tau_s))


def _segments(t: np.ndarray, rng: np.random.Generator, values, count: int, slew: float) -> np.ndarray:
    levels = rng.choice(np.asarray(values, float), size=count)
    return _dwell_path(t, levels, slew)


def make_experiment(kind: str, rng: np.random.Generator, n: int | None = None,
                    rate_hz: float | None = None) -> Record:
    """A realistic logged experiment for ``kind`` (see the module docstring); y = 0.

    ``n`` samples at ``rate_hz`` (defaults per kind: accelerometer 7200 at 1 Hz, gyro 20000 at
    10 Hz, mhd 30000 at 500 Hz). Shorter records may leave slow effects undetectable."""
    if kind not in KINDS:
        raise ValueError(f"sensor kind {kind!r}; allowed: {list(KINDS)}")
    n0, r0 = DEFAULTS[kind]
    n = n0 if n is None else int(n)
    rate_hz = r0 if rate_hz is None else float(rate_hz)
    if not 200 <= n <= 10_000_000:
        raise ValueError(f"n = {n!r}; allowed: 200 .. 10000000 samples")
    if not 1e-3 <= rate_hz <= 1e6:
        raise ValueError(f"rate_hz = {rate_hz!r}; allowed: 0.001 .. 1e6 Hz")
    t = np.arange(n) / rate_hz
    return {"accelerometer": _accelerometer, "gyro": _gyro, "mhd": _mhd}[kind](t, rng)


def _accelerometer(t, rng) -> Record:
    steps = np.arange(0.0, 360.0, 15.0)
    near = np.array([90 - 1.0, 90 - 0.3, 90 - 0.05, 90 + 0.05, 90 + 0.3, 90 + 1.0])
    positions = np.concatenate([steps, near, near + 180.0])
    order = np.concatenate([rng.permutation(positions) for _ in range(3)])
    theta = np.deg2rad(_dwell_path(t, order, 10.0))
    temp = _temperature(t, rng, 23.0, 8.0, 4.0, 900.0)
    vib = _segments(t, rng, [0, 0, 0, 0.5, 1.0, 2.0, 3.0], 40, 0.5)
    return Record(t_s=t, y=np.zeros(t.size), input=np.cos(theta), cross_input=np.sin(theta), temp_c=temp,
                  t_on_s=t - t[0], vib_grms=vib)


def _gyro(t, rng) -> Record:
    mags = np.array([0.02, 0.1, 0.5, 2.0, 5.0, 10.0, 20.0, 50.0, 75.0, 100.0])
    levels = np.concatenate([[0.0], mags, -mags])
    order = np.concatenate([[0.0], rng.permutation(levels), rng.permutation(levels)])
    rate = _dwell_path(t, order, 100.0)
    cross = _segments(t, rng, [0, 0, -30, -10, 10, 30], 17, 50.0)
    accel = _segments(t, rng, [-1, -0.5, 0, 0.5, 1], 13, 0.2)
    vib = _segments(t, rng, [0, 0, 0, 0.5, 1.0, 2.0, 4.0], 23, 1.0)
    temp = _temperature(t, rng, 22.0, 8.0, 3.0, 400.0)
    return Record(t_s=t, y=np.zeros(t.size), input=rate, cross_input=cross, accel_g=accel, vib_grms=vib,
                  temp_c=temp, t_on_s=t - t[0])


def _multitone(t, rng, freqs, amps) -> np.ndarray:
    ph = rng.uniform(0, 2 * np.pi, len(freqs))
    x = sum(a * np.sin(2 * np.pi * f * t + p) for f, a, p in zip(freqs, amps, ph))
    return x * np.clip((t - t[0]) / 0.5, 0, 1)  # fade in from rest over 0.5 s


def _mhd(t, rng) -> Record:
    nyq = 0.5 / (t[1] - t[0])
    freqs = np.array([0.7, 1.9, 4.3, 11.0, 27.0, 63.0, 140.0])
    freqs = freqs[freqs < 0.4 * nyq]
    amps = 40.0 / (1 + np.arange(len(freqs))) ** 0.5
    rate = _multitone(t, rng, freqs * rng.uniform(0.97, 1.03, len(freqs)), amps)
    rate *= 100.0 / max(np.max(np.abs(rate)), 1e-12)
    cfreq = np.array([0.9, 2.7, 7.0, 19.0, 45.0])
    cfreq = cfreq[cfreq < 0.4 * nyq]
    cross = _multitone(t, rng, cfreq, np.full(len(cfreq), 10.0))
    temp = _temperature(t, rng, 25.0, 3.0, 2.0, 20.0)
    return Record(t_s=t, y=np.zeros(t.size), input=rate, cross_input=cross, temp_c=temp, t_on_s=t - t[0])
