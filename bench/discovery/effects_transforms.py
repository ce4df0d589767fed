"""Catalogue effects that transform a signal: the input path (delay, bandwidth, high-pass, dead
zone) or the whole output (saturation, quantization).

Input-path convention: the record starts settled, so the first input value ``u0`` passes and the
changes ``u − u0`` go through the dynamics from rest (for the MHD sensor, which starts at rest,
``u0 = 0``). Filters are the single-pole responses sampled exactly for an input linear between
samples (pole ``a = exp(−2π·f·dt)``, :func:`first_order_lowpass`), which run from no effect
(corner → ∞ low-pass, → 0 high-pass) continuously; they need a uniform record.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter
from scipy.special import ndtr

from bench.discovery import lattice
from bench.discovery.data import Record
from bench.discovery.effects_base import (
    DRAW_SNR_FACTOR,
    MIN_SNR,
    Effect,
    HistogramEffect,
    HistogramFit,
    Param,
    guess_kind,
    noise_sd_of,
)
from bench.discovery.effects_noise import reaching


def expected_quantized(x: np.ndarray, step: float, noise_sd: float) -> np.ndarray:
    """``E[step·round((x + n)/step)]`` for Gaussian ``n`` of sd ``noise_sd`` (same unit as x).

    A reading is the quantized noisy signal, so its expectation is the quantizer smoothed by
    the noise (dither), not the quantized noiseless signal. With ``u = x/step``,
    ``τ = noise_sd/step``: for τ ≥ 0.2 the Fourier series of the sawtooth,
    ``u + Σ_k (−1)^k e^{−2π²k²τ²} sin(2πku)/(πk)``, cut where the factor falls below 1e-17
    (k ≤ 1.41/τ: at most 8 terms, harmonics by the Chebyshev recurrence); for τ < 0.2 the exact
    level sum ``⌊u⌋ + Σ_{m≥1} P(U ≥ ⌊u⌋ + m − ½) − Σ_{m≥0} P(U < ⌊u⌋ − m − ½)``
    (U ~ N(u, τ²)) over the thresholds within 9τ, which is exact rounding at τ = 0."""
    x = np.asarray(x, dtype=float)
    if step <= 0:
        return x.copy()
    u, tau = x / step, float(noise_sd) / step
    if tau == 0:
        return step * np.round(u)
    if tau >= 0.2:
        theta = 2 * math.pi * u
        c2 = 2 * np.cos(theta)
        s_prev, s_k = np.zeros_like(u), np.sin(theta)
        out = u.copy()
        for k in range(1, int(math.ceil(math.sqrt(math.log(1e17) / (2 * math.pi ** 2)) / tau)) + 1):
            out += (-1) ** k * math.exp(-2 * math.pi ** 2 * k * k * tau * tau) / (math.pi * k) * s_k
            s_prev, s_k = s_k, c2 * s_k - s_prev  # sin((k+1)θ) = 2cosθ·sin(kθ) − sin((k−1)θ)
        return step * out
    a = np.floor(u)
    f = u - a  # in [0, 1): thresholds at a + m − ½ above (m ≥ 1) and a − m − ½ below (m ≥ 0)
    out = a
    with np.errstate(over="ignore", divide="ignore"):  # tiny τ: ±inf arguments, ndtr 0 or 1
        for m in range(1, int(math.ceil(1.5 + 9 * tau)) + 1):
            out = out + ndtr((f - m + 0.5) / tau)
        for m in range(0, int(math.ceil(9 * tau - 0.5)) + 1):
            out = out - ndtr(-(f + m + 0.5) / tau)
    return step * out


def quantized_variance(x: np.ndarray, step: float, noise_sd: float, wander_sd: float = 0.0) -> np.ndarray:
    """``Var[step·round((x + n)/step)]`` per sample for Gaussian ``n`` of sd ``noise_sd``: the
    spread of a reading about its mean (:func:`expected_quantized`); :func:`quantized_moments`."""
    return quantized_moments(x, step, noise_sd, wander_sd)[0]


def quantized_moments(x: np.ndarray, step: float, noise_sd: float,
                      wander_sd: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(variance, fourth central moment) per sample of ``step·round((x + n)/step)``, n Gaussian
    of sd ``noise_sd``. With little dither they depend on where x sits on the lattice — the
    variance near 0 on a level, up to step²/4 between two — so a coarse quantizer's residual is
    heteroscedastic, and far from Gaussian (a rare flip of a whole step: kurtosis 1/p for a flip
    of probability p, against 3). ``wander_sd``: sd of a slow offset the model does not predict
    (its random processes) that moves x along the lattice; the moments at x are averaged over it
    (the phase profile's k-th harmonic damped by e^{−2π²k²w²/step²}). Exact level sums over the
    thresholds within 9σ; flat once σ or the wander reaches a step (a first harmonic below
    3e-9): ``Quantization.residual_var`` and the phase average of the fourth moment (for σ ≥ a
    step that of Gaussian noise plus an independent uniform rounding error)."""
    x = np.asarray(x, dtype=float)
    sd, w = float(noise_sd), float(wander_sd)
    if not (sd >= 0 and w >= 0 and math.isfinite(sd) and math.isfinite(w)):
        raise ValueError(f"noise_sd = {noise_sd!r}, wander_sd = {wander_sd!r}; allowed: finite values >= 0")
    if step <= 0:
        return np.full(x.shape, sd * sd), np.full(x.shape, 3 * sd ** 4)
    if sd >= step:  # the rounding error is uniform and independent of the noise (to e^{−2π²})
        return (np.full(x.shape, _phase_averaged_var(step, sd)),
                np.full(x.shape, 3 * sd ** 4 + sd * sd * step * step / 2 + step ** 4 / 80))
    if w == 0:
        v, m4 = _level_moments(x / step, sd / step)
        return step * step * v, step ** 4 * m4
    grid = (np.arange(QUANT_PHASES) + 0.5) / QUANT_PHASES
    gv, gm4 = _level_moments(grid, sd / step)
    if w >= step:
        return np.full(x.shape, _phase_averaged_var(step, sd)), np.full(x.shape, step ** 4 * float(np.mean(gm4)))
    k = np.arange(QUANT_PHASES // 2 + 1)
    damp = np.exp(-2 * math.pi ** 2 * k * k * (w / step) ** 2)
    phase = np.mod(x / step, 1.0) * QUANT_PHASES - 0.5
    knots = np.arange(-1, QUANT_PHASES + 1)

    def smoothed(g: np.ndarray) -> np.ndarray:
        prof = np.fft.irfft(np.fft.rfft(g) * damp, QUANT_PHASES)
        return np.maximum(np.interp(phase, knots, np.r_[prof[-1], prof, prof[0]]), 0.0)
    return step * step * smoothed(gv), step ** 4 * smoothed(gm4)


#: Phases of one lattice step on which :func:`quantized_moments` smooths the profile by a wander.
QUANT_PHASES = 256


def _level_moments(u: np.ndarray, tau: float) -> tuple[np.ndarray, np.ndarray]:
    """(variance, fourth central moment), in steps, of round(U), U ~ N(u, τ²): over the levels
    within 9τ + 2 of u."""
    a = np.floor(u)
    f = u - a
    if tau == 0:
        return np.zeros(f.shape), np.zeros(f.shape)
    raw = [np.zeros(f.shape) for _ in range(4)]
    reach = int(math.ceil(9 * tau)) + 2
    for d in range(-reach, reach + 1):  # level a + d takes U in [a + d − ½, a + d + ½)
        pd = ndtr((d + 0.5 - f) / tau) - ndtr((d - 0.5 - f) / tau)
        for k in range(4):
            raw[k] += d ** (k + 1) * pd
    m1, m2, m3, m4 = raw
    var = np.maximum(m2 - m1 * m1, 0.0)
    return var, np.maximum(m4 - 4 * m1 * m3 + 6 * m1 * m1 * m2 - 3 * m1 ** 4, var * var)


def _phase_averaged_var(step: float, sd: float) -> float:
    """``Var[Q(x + n) | x]`` averaged over the phase of x (``Quantization.residual_var``)."""
    if step <= 0:
        return sd * sd
    tau = sd / step
    if tau < 1e-4:
        return sd * sd + step * sd / math.sqrt(math.pi)
    k = np.arange(1, int(math.ceil(4.0 / tau)) + 2, dtype=float)
    return float(sd * sd + step * step / 12.0
                 - step * step * np.sum(np.exp(-4 * math.pi ** 2 * k * k * tau * tau) / (k * k)) / (2 * math.pi ** 2))


def clipped_variance(x: np.ndarray, limit: float, noise_sd: float) -> np.ndarray:
    """``Var[clip(x + n, −limit, limit)]`` per sample, n Gaussian of sd ``noise_sd``
    (truncated-normal moments): the noise's own variance inside the range, near 0 where the
    signal is clipped — a saturation's residual is quiet there."""
    x = np.asarray(x, dtype=float)
    sd = float(noise_sd)
    if sd <= 0:
        return np.zeros(x.shape)
    a, b = (-limit - x) / sd, (limit - x) / sd
    pa, pb = ndtr(a), ndtr(b)
    da, db = np.exp(-0.5 * a * a) / math.sqrt(2 * math.pi), np.exp(-0.5 * b * b) / math.sqrt(2 * math.pi)
    inside = pb - pa
    m1 = -limit * pa + limit * (1 - pb) + x * inside + sd * (da - db)
    m2 = (limit * limit * (pa + 1 - pb) + x * x * inside + 2 * x * sd * (da - db)
          + sd * sd * (inside + a * da - b * db))
    return np.maximum(m2 - m1 * m1, 0.0)


#: A quantizer step above this many white-noise sd makes the residual's colour follow the signal.
COARSE_STEP_SD = 2.0


def first_order_lowpass(u: np.ndarray, corner_hz: float, dt_s: float) -> np.ndarray:
    """x' = ω(u − x) from rest, ω = 2π·corner_hz, exact when u is linear between its samples (a
    table's or a tumble's motion is; the matched pole alone, y_k = a·y_{k−1} + (1 − a)·u_k, is
    exact only for an input held over each sample and puts half a sample of delay in the fit)."""
    wdt = 2 * math.pi * corner_hz * dt_s
    a = math.exp(-wdt)
    c0 = 1.0 - (-math.expm1(-wdt)) / wdt if wdt > 1e-8 else 0.5 * wdt
    c1 = (1.0 - a) - c0
    return lfilter([c0, c1], [1.0, -a], u)


def _uniform_dt(rec: Record, who: str) -> float:
    if not rec.is_uniform():
        raise ValueError(f"{who} needs a uniformly sampled record (every interval within 0.1 % of "
                         f"the median {rec.dt_s!r} s); resample first")
    return rec.dt_s


class TimeDelay(Effect):
    id = "time_delay"
    description = "latency of the sensor's input path (processing, filtering group delay, transport)"
    form = "input → input(t − delay_s), linear interpolation between samples, input[0] before the start"
    inputs = ("input",)
    main_param = "delay_s"
    signature = ("input: residual ∝ −delay·d(input)/dt, spikes at input changes; cross-correlation peak of y and "
                 "input shifted by delay")
    separating = {"lowpass_bandwidth": "sweep input frequency: a delay shifts phase linearly without attenuating, "
                                       "a low-pass attenuates"}
    stage = "input"
    competitors = ("lowpass_bandwidth",)  # a sampled single pole is a delay for slow inputs
    ranges = {
        "accelerometer": (Param("delay_s", "s", 1e-5, 1.0, log=True),),
        "gyro": (Param("delay_s", "s", 1e-5, 1.0, log=True),),
        "mhd": (Param("delay_s", "s", 1e-6, 0.1, log=True),),
    }

    def transform_input(self, p, rec, u):
        return np.interp(rec.t_s - p["delay_s"], rec.t_s, u)

    def main_grid_range(self, rec, kind):
        q = self.param("delay_s", kind)
        return max(q.low, 1e-4 * rec.dt_s), min(q.high, 20 * rec.dt_s)


class LowpassBandwidth(Effect):
    id = "lowpass_bandwidth"
    description = "finite bandwidth of the sensor or its read-out: a single-pole low-pass on the input path"
    form = ("input → u0 + LP[input − u0], LP: x' = ω(u − x) exact for an input linear between samples: "
            "y_k = a·y_{k−1} + c0·x_k + c1·x_{k−1}, a = exp(−ω·dt), c0 = 1 − (1 − a)/(ω·dt), c1 = 1 − a − c0, "
            "ω = 2π·bandwidth_hz")
    inputs = ("input",)
    needs_uniform = True
    main_param = "bandwidth_hz"
    signature = "time: exponential tails after input steps; frequency: response rolls off above bandwidth_hz"
    stage = "input"
    identity = math.inf
    increasing = False
    competitors = ("time_delay",)
    ranges = {  # QA-2000 > 300 Hz but DMM/ADC filters reach 0.01 Hz; FOG ~100-1000 Hz; MHD 8 kHz
        "accelerometer": (Param("bandwidth_hz", "Hz", 0.01, 1e3, log=True),),
        "gyro": (Param("bandwidth_hz", "Hz", 0.1, 1e3, log=True),),
        "mhd": (Param("bandwidth_hz", "Hz", 1.0, 2e4, log=True),),
    }

    def transform_input(self, p, rec, u):
        f = p["bandwidth_hz"]
        if math.isinf(f):
            return u.copy()
        return u[0] + first_order_lowpass(u - u[0], f, _uniform_dt(rec, self.id))

    def main_grid_range(self, rec, kind):
        q = self.param("bandwidth_hz", kind)
        return max(q.low, rec.rate_hz / 300), min(q.high, rec.rate_hz)


class HighpassRolloff(Effect):
    id = "highpass_rolloff"
    description = "AC coupling: a single-pole high-pass on the input path (the MHD sensor senses no DC rate)"
    form = ("input → u0 + HP[input − u0], HP = 1 − LP: the first-order low-pass at corner_hz (exact for an input "
            "linear between samples, as lowpass_bandwidth) taken from the input")
    inputs = ("input",)
    needs_uniform = True
    main_param = "corner_hz"
    signature = "time: droop after input steps (output returns to bias); frequency: loss below corner_hz, phase lead"
    stage = "input"
    kinds = ("mhd",)
    ranges = {"mhd": (Param("corner_hz", "Hz", 1e-3, 100.0, log=True),)}  # MHD preset corner 2.5 Hz

    def transform_input(self, p, rec, u):
        f = p["corner_hz"]
        if f == 0:
            return u.copy()
        d = u - u[0]
        return u[0] + d - first_order_lowpass(d, f, _uniform_dt(rec, self.id))

    def main_grid_range(self, rec, kind):
        q = self.param("corner_hz", kind)
        return max(q.low, 3.0 / rec.duration_s), min(q.high, 0.1 * rec.rate_hz)


class DeadZone(Effect):
    id = "dead_zone"
    description = "no response to inputs smaller than a threshold (half_width), offset by it beyond"
    form = "input → sign(input)·max(|input| − half_width, 0)"
    inputs = ("input",)
    main_param = "half_width"
    signature = "input: residual = −clip(input, ±half_width): a step of size half_width at zero input"
    separating = {"quantization": "apply slow ramps through zero at several levels: the dead zone sits at zero only"}
    stage = "input"
    kinds = ("accelerometer", "gyro")
    ranges = {  # QA-2000 threshold ≲ 1 µg; FOG read-out thresholds up to ~0.01-1 deg/s when faulty
        "accelerometer": (Param("half_width", "g", 1e-7, 1e-2, log=True),),
        "gyro": (Param("half_width", "deg/s", 1e-5, 1.0, log=True),),
    }

    def transform_input(self, p, rec, u):
        return np.sign(u) * np.maximum(np.abs(u) - p["half_width"], 0.0)

    def main_grid_range(self, rec, kind):
        q = self.param("half_width", kind)
        top = float(np.max(np.abs(rec.input))) if rec.logged("input") else q.high
        return q.low, max(min(q.high, 0.5 * top), q.low * 1.01)


class Saturation(Effect):
    id = "saturation"
    description = "output clipping at the sensor's or the acquisition's range (e.g. a DMM or ADC range)"
    form = "y → clip(y, −limit, +limit)"
    inputs = ()
    main_param = "limit"
    signature = "input: residual non-zero only where |y| would exceed limit; output flat at ±limit"
    stage = "output"
    identity = math.inf
    increasing = False
    # clipping's snr rises steeply below the largest excursion: 0.1 % of a 1 g peak is 200 σ of
    # an accelerometer's noise, so its threshold is resolved to 1e-12 in log(limit)
    threshold_log_tol = 1e-12
    ranges = {  # QA-2000 ±60 g but a tumble's read-out range can be ±1.2 g; FOG ±490 deg/s
        "accelerometer": (Param("limit", "g", 0.05, 100.0, log=True),),
        "gyro": (Param("limit", "deg/s", 1.0, 2000.0, log=True),),
        "mhd": (Param("limit", "deg/s", 1.0, 2000.0, log=True),),
    }

    def transform(self, p, rec, y):
        return np.clip(y, -p["limit"], p["limit"])

    def observes_noise(self, p, y):
        """Inside the limit: a clipped reading is the limit, whatever the noise."""
        return np.abs(np.asarray(y, float)) < p["limit"]

    def fit_starts(self, rec, residual, *, kind=None, rows=None, held_out=None):
        """The grid's starts after the readings' own extreme on ``rows`` (the clipped readings
        sit at the limit): the grid scores limits on the residual of a model whose scale factor
        the clip has shrunk (0.73 on a tumble clipped at 0.61 g), and a limit above that model's
        whole signal clips nothing, where a fit cannot move it (the held-out fits of such a
        clip scored 0: nothing named)."""
        starts = super().fit_starts(rec, residual, kind=kind, rows=rows, held_out=held_out)
        y = np.asarray(rec.y, float) if rows is None else np.asarray(rec.y, float)[np.asarray(rows, bool)]
        q = self.param("limit", kind or guess_kind(rec))
        top = float(np.max(np.abs(y))) if y.size else math.nan
        if not (math.isfinite(top) and q.low <= top <= q.high):
            return starts
        return [{"limit": top}, *starts]

    def residual_moments_at(self, p, rec, y, noise_sd, wander_sd=0.0):
        """Per sample at the signal y: :func:`clipped_variance` with the wander counted as noise
        (near 0 where the signal is clipped), Gaussian fourth moment."""
        v = clipped_variance(y, p["limit"], math.hypot(float(noise_sd), float(wander_sd)))
        return v, 3 * v * v

    def draw(self, rng, rec, *, kind=None, noise_sd=None, at_snr=None):
        """limit log-uniform in [0.6, 0.95] × the largest |reference output| (inside the kind's
        range): a part of the excursions clips, never most of the signal — the snr of clipping
        rises too steeply with depth for the generic snr-band rule to leave a usable interval.
        ``at_snr``: the limit where clipping has exactly that snr (the generic rule)."""
        if at_snr is not None:
            return super().draw(rng, rec, kind=kind, noise_sd=noise_sd, at_snr=at_snr)
        kind = kind or guess_kind(rec)
        q = self.params_for(kind)[0]
        top = float(np.max(np.abs(self.reference_output(rec))))
        a, b = max(q.low, 0.6 * top), min(q.high, 0.95 * top)
        sd = noise_sd if noise_sd is not None else noise_sd_of(rec, kind)
        if not a < b:
            raise ValueError(f"saturation: the record's largest |input| {top!r} leaves no limit inside "
                             f"[{q.low}, {q.high}] {q.unit} clipping 5-40 % of it")
        p = {"limit": math.exp(rng.uniform(math.log(a), math.log(b)))}
        if self.snr(p, rec, sd) < DRAW_SNR_FACTOR * MIN_SNR:
            raise ValueError(f"saturation: clipping at {p['limit']!r} is not detectable on this record")
        return p

    def main_grid_range(self, rec, kind):
        top = float(np.max(np.abs(self.reference_output(rec))))
        q = self.param("limit", kind)
        return max(q.low, 0.3 * top), max(min(q.high, top), q.low * 1.01)


#: Median distance of the readings to a quantizer's lattice (in steps) below which they sit on it.
ON_LATTICE_FRACTION = 0.05


def step_top(y: np.ndarray) -> float:
    """The largest quantizer step a fit on the readings ``y`` may reach (u): twice their full
    spread (peak to peak) — readings on two levels span one step, and a step beyond twice the
    spread leaves every reading on one level, no lattice to see."""
    y = np.asarray(y, float)
    y = y[np.isfinite(y)]
    return 2.0 * float(np.ptp(y)) if y.size else 0.0


class Quantization(HistogramEffect):
    id = "quantization"
    description = "output resolution: readings on a grid of step (ADC/DMM digits, FOG angle pulses per sample)"
    form = "y → step · round(y / step)"
    inputs = ()
    main_param = "step"
    signature = "histogram: output values on a lattice of spacing step; error bounded by step/2 (white if step ≪ noise)"
    stage = "output"
    mean_depends_on_noise = True  # a reading's mean is the dithered quantizer E[Q(x + n)]
    draw_span_main = 5.0  # steps of 3-17 noise sd: a visible lattice, not a staircase hiding the signal
    # drawn: DMM 6½ digits on a 1 V range ≈ 1 µg; FOG 0.1″ pulse at 100 Hz ≈ 3e-3 deg/s; fitted: any
    # grade up to the kind's full scale (a MEMS accelerometer's 3.33 mg LSB), the range from the record
    ranges = reaching({
        "accelerometer": (Param("step", "g", 1e-8, 1e-3, log=True),),
        "gyro": (Param("step", "deg/s", 1e-6, 0.1, log=True),),
        "mhd": (Param("step", "deg/s", 1e-5, 1.0, log=True),),
    }, levels=("step",))

    def transform(self, p, rec, y):
        s = p["step"]
        return y.copy() if s == 0 else s * np.round(y / s)

    def expected_transform(self, p, rec, y, noise_sd):
        """The mean reading E[Q(y + n)] (dithered quantizer, ``expected_quantized``)."""
        return expected_quantized(y, p["step"], noise_sd)

    def pre_transform_sd(self, p, floor_sd):
        """Noise sd before the quantizer when the residual of the model WITHOUT it has white sd
        ``floor_sd``: that residual is noise + rounding error, independent and uniform over a
        step for a signal of uniform phase, so ``floor² = σ² + step²/12``."""
        return math.sqrt(max(floor_sd ** 2 - p["step"] ** 2 / 12.0, 0.0))

    def residual_var(self, p, noise_sd):
        """Variance of a reading about its mean, ``Var[Q(x + n) | x]`` averaged over the phase of
        x: ``σ² + step²/12 − Σ_k step²·e^{−4π²k²σ²/step²}/(2π²k²)`` (0 at σ = 0, σ² + step²/12
        once σ ≳ step/2); for σ < 1e-4·step the limit ``σ² + step·σ/√π`` (a Bernoulli flip within
        a few σ of each threshold)."""
        return _phase_averaged_var(p["step"], float(noise_sd))

    def residual_moments_at(self, p, rec, y, noise_sd, wander_sd=0.0):
        """Per sample at the signal y: :func:`quantized_moments` (heteroscedastic and heavy-tailed
        with little dither)."""
        return quantized_moments(y, p["step"], noise_sd, wander_sd)

    def snr(self, p, rec, noise_sd):
        """Lattice visibility: |E exp(2πi·y/step)| = exp(−2π²σ²/step²) for Gaussian noise σ,
        estimated from n samples with sd 1/√n, so z = exp(−2π²σ²/step²)·√n."""
        s = p["step"]
        if s <= 0:
            return 0.0
        return float(math.exp(-2 * math.pi ** 2 * noise_sd ** 2 / s ** 2) * math.sqrt(rec.n))

    def main_grid_range(self, rec, kind):
        q = self.param("step", kind)
        sd = float(np.std(np.diff(rec.y))) / math.sqrt(2) or q.low
        return max(q.low, sd), min(q.high, 30 * sd)

    def fit_range(self, q: Param, rec: Record, kind: str) -> tuple[float, float]:
        """The step from the kind's finest read-out (``q.low``; the lattice scan itself starts
        at a quarter of the white sd) up to :func:`step_top` of the readings."""
        return q.low, max(step_top(rec.y), q.low)

    def fit_histogram(self, y: np.ndarray, noise_sd: float, folds: np.ndarray, kind: str) -> HistogramFit:
        """Readings on a lattice (:mod:`bench.discovery.lattice`): the step by the lattice's
        visibility, its Rayleigh-tail p-value, and the held-out visibility excess as the score;
        no lattice found: the smallest step, score 0, p = 1. The scan's range is the fit range on
        the readings (:meth:`fit_range`), within what a model may hold."""
        q = self.params_for(kind)[0]
        lo, hi = q.low, min(max(step_top(y), q.low), q.fit_high)
        fit = lattice.fit_lattice(y, noise_sd, lo, hi)
        if not np.isfinite(fit.step):
            return HistogramFit({q.name: lo}, {q.name: float("nan")}, 0.0, 1.0)
        score = lattice.heldout_score(y, noise_sd, folds, lo, hi)
        return HistogramFit({q.name: float(np.clip(fit.step, lo, hi))}, {q.name: fit.step_std},
                            score, float(fit.p_value))

