"""Complementary Kalman fusion of an HF and an LF rate sensor: a fusion that cannot lag.

Source: R. G. Brown and P. Y. C. Hwang, *Introduction to Random Signals and Applied Kalman
Filtering*, 4th ed. (Wiley, 2012), ch. 8, "The 'Go-Free' Concept, Complementary Filter, and
Aided Inertial Examples": when two sensors measure the same signal, a Kalman filter that
estimates the sensors' *errors* from the *difference* of the measurements never needs a model
of the signal — the signal cancels in the difference and passes to the output without
distortion, whatever its dynamics; only the errors are modelled.

**Here** the sensors are dynamic (the HF sensor a high-pass ``G1``, the LF a low-pass ``G2``,
:class:`~bench.analysis.fusion._models.SensorModel`), so "the difference" is taken through
their models.  The HF reading ``z1 = k1(ω − c_h·s_h) + o + v1`` (``s_h`` the low-pass states
of its high-pass, ``o`` its output offset, ``v1`` white noise) is solved for the rate,

    ω = (z1 − o − v1)/k1 + c_h·s_h,

and that expression drives both sensors' states as a *known input* ``u = z1/k1`` (the
"go-free" step: the true rate is replaced by the HF sensor's inverted reading and never
appears as a state):

    ṡ_h = A_h s_h + b_h ω,   ṡ_l = A_l s_l + b_l ω,   z2 = k2 c_l·s_l + v2.

The LF reading ``z2`` is the filter's only measurement; its innovation is the difference
between what the LF sensor reads and what it would read if the HF-derived rate were true —
signal-free.  State ``x = [s_h, s_l, v1, o]`` (each sensor's FRF model, the HF sample noise
and offset); the HF sample noise ``v1`` is a state (white: it is renewed each sample) because it
enters both the output and, through the input, the next states.  Output

    rate_k = u_k + c_h·s_h − (v1 + o)/k1,

so at frequencies where the LF sensor carries no information the output is the HF reading
through its inverted model, with no lag; below the HF corner the LF reading corrects the HF
path's integrator drift.  No random-walk rate model, no process-noise trade-off between lag and
noise: the only tuned quantities are the sensors' noise, estimated by maximum likelihood
(:func:`fit_complementary_noise`).

Discretisation: exact for an input that is linear between samples (first-order hold:
``x_{k+1} = Φ x_k + γ0 u_k + γ1 u_{k+1}``, from one matrix exponential); the offset is a random
walk of intensity ``offset_rw`` (HF unit²/s).  A sampled band-limited input is not linear
between samples: interpolating it linearly scales a tone at ``f`` by ``sinc²(f/fs)`` (−0.2 % at
fs/40, −3 % at fs/10), so the model's prediction of the LF reading carries that droop and the
innovation would not be free of the signal.  The model is therefore driven by the HF input
through :func:`inverse_foh_droop`, a symmetric 5-tap filter that undoes that droop to fourth
order (residual ``O((f/fs)⁶)``: 10⁻⁴ at fs/10, 2·10⁻⁶ at fs/20).  It colours the HF noise only above the
band where the LF reading sees it (its gain is 1 + O((f/fs)²)), so the noise model stays white;
it looks two samples ahead.

That corrects the hold's droop in the band, not its **images**: the linearly interpolated
input also carries copies of each tone at ``f ± k·fs`` (scaled by ``sinc²(f/fs ± k)``), which
the model's LF states low-pass and which land back on ``f`` when the LF prediction is sampled.
Where the LF sensor reads little of a tone (far above its corner) the images are a visible
part of what the model predicts it reads: for a first-order LF the prediction is 0.08 % low at
fs/10 and 1.7 % low at fs/5.  When the LF noise is low the smoother leans on the LF reading
there and the output inherits it (+0.09 % at 1.8 kHz on a 16.5 kHz pair).  The image sum is
known in closed form from the two models (:func:`hold_response`), so the LF reading is put
through a short filter with the same response (:func:`hold_correction_taps`,
``HOLD_HALF_WIDTH`` taps each side, ≈ 10⁻⁶ up to ``HOLD_BAND``·fs): what the model then
predicts and what the LF reading reads agree for any sampled band-limited rate.  That filter
looks ``HOLD_HALF_WIDTH`` samples ahead, so the causal filter's output at sample ``k`` is the
state updated with the LF readings up to ``k − HOLD_HALF_WIDTH`` predicted to ``k`` on the HF
input (the HF path still has no lag; the LF reading, which corrects the low frequencies, is
used ``HOLD_HALF_WIDTH`` samples late).

**Smoother** (:func:`complementary_kalman` with ``smooth=True``): the fixed-interval
Rauch–Tung–Striebel smoother of the same model, for post-processed references — non-causal,
it also uses the LF readings that follow each sample.

**Document B's adaptive R on top**: ``lf_noise`` may be an
:class:`~bench.analysis.fusion._sequential.AdaptiveNoise` — the LF update's R then follows Document B's
piecewise-adaptive bounded rule (the smoother replays the R the filter used).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm
from scipy.optimize import minimize
from scipy.signal import decimate

import bench.analysis.fusion._complementary_kernel as kernel
from bench.analysis.fusion._metrics import tone_residual
from bench.analysis.fusion._models import SensorModel
from bench.analysis.fusion._sequential import AdaptiveNoise, check_series, white_noise_var

#: taps (centre, ±1, ±2) of the symmetric filter undoing the first-order hold's sinc² droop to 4th order
INVERSE_DROOP_TAPS = (1 + 2 * (23 / 180 - 1 / 90), -23 / 180, 1 / 90)
HOLD_HALF_WIDTH = 6  # taps each side of the LF reading's hold correction: the causal output is this many
# samples behind the model's last update
HOLD_BAND = 0.25  # ... fitted over 0 … this fraction of the sample rate (≈ 10⁻⁶ there; unused above)
HOLD_IMAGES = 400  # images of the first-order hold summed each side (the terms fall at least as 1/k³)
CHECKPOINT_EVERY = 2048  # samples between the smoother's checkpoints (memory: this × n² floats)
STEADY_TOL = 1e-10  # the gain is frozen once P moves by less than this fraction of itself (fixed R)
ML_RATE_PER_LF_CORNER = 20.0  # the likelihood is taken at this many times the LF corner (decimated)
MIN_ML_SAMPLES = 4096  # ... on at least this many samples
ML_MAX_SAMPLES = 1 << 17  # the likelihood is taken over at most this many samples (the first)
RATIO_SPAN = 12.0  # the ML search keeps each log variance ratio within ±RATIO_SPAN of its start (e¹²≈1.6e5)


@dataclass(frozen=True)
class ComplementaryNoise:
    """The sensors' error model of the complementary Kalman filter: HF and LF noise, HF offset drift.

    White-noise variances of the HF reading (``hf_var``, HF unit²) and of the LF reading
    (``lf_var``, LF unit²), and the HF offset's random-walk intensity (``offset_rw``, HF
    unit²/s). Given to :func:`complementary_kalman`; estimated from the records by
    :func:`fit_complementary_noise`.

    Parameters
    ----------
    hf_var : float
        White-noise variance of the HF reading, HF unit²; finite and > 0.
    lf_var : float
        White-noise variance of the LF reading, LF unit²; finite and > 0.
    offset_rw : float
        Random-walk intensity of the HF output offset, HF unit²/s; finite and > 0.

    Raises
    ------
    ValueError
        If a value is not a finite value > 0.
    """

    hf_var: float
    lf_var: float
    offset_rw: float

    def __post_init__(self):
        for name in ("hf_var", "lf_var", "offset_rw"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} {v} must be a finite value > 0")

    def to_dict(self) -> dict:
        return {"hf_var": float(self.hf_var), "lf_var": float(self.lf_var), "offset_rw": float(self.offset_rw)}


@dataclass(frozen=True)
class ComplementarySystem:
    """Discrete model of the module docstring for one sample interval ``ts_s``: ``phi``,
    ``g0``/``g1`` (input vectors, ``u`` = HF reading ÷ ``k1``), the LF row ``h`` and the
    output row ``h_rate``; ``noise_in`` how a sample's HF noise enters (into the ``hf_noise``
    state and, through the input, the sensors' states); ``states`` names the states."""

    ts_s: float
    phi: np.ndarray
    g0: np.ndarray
    g1: np.ndarray
    noise_in: np.ndarray
    h: np.ndarray
    h_rate: np.ndarray
    states: tuple

    @property
    def row_kind(self) -> np.ndarray:
        """Per row of Φ: 0 zero, 1 the unit row, 2 general (the kernels skip what is known)."""
        eye = np.eye(self.phi.shape[0])
        return np.array([0 if not np.any(r) else (1 if np.array_equal(r, e) else 2) for r, e in zip(self.phi, eye)],
                        dtype=np.int8)

    def q(self, noise: ComplementaryNoise) -> np.ndarray:
        """Process-noise covariance: the HF sample noise through ``noise_in``, the offset's walk."""
        q = noise.hf_var * np.outer(self.noise_in, self.noise_in)
        q[-1, -1] += noise.offset_rw * self.ts_s
        return q


def complementary_system(hf_model: SensorModel, lf_model: SensorModel, ts_s: float) -> ComplementarySystem:
    """The discrete complementary model (module docstring) at sample interval ``ts_s``."""
    if not (math.isfinite(ts_s) and ts_s > 0):
        raise ValueError(f"ts_s {ts_s} must be a finite value > 0")
    if hf_model.kind != "highpass" or lf_model.kind != "lowpass":
        raise ValueError(f"the HF model must be a high-pass and the LF model a low-pass "
                         f"(got {hf_model.kind!r}, {lf_model.kind!r})")
    a_h, b_h, c_hp, _ = hf_model.state_space()
    a_l, b_l, c_l, _ = lf_model.state_space()
    k1 = hf_model.gain
    m1, m2 = hf_model.order, lf_model.order
    nd = m1 + m2
    c_omega = np.zeros(nd)
    c_omega[:m1] = -c_hp / k1  # ω = u_eff + c_ω·s with u_eff = (z1 − o − v1)/k1
    b = np.concatenate([b_h, b_l])
    a = np.zeros((nd, nd))
    a[:m1, :m1], a[m1:, m1:] = a_h, a_l
    a += np.outer(b, c_omega)
    # first-order hold: d/dt [s, u, u̇] = [[A, b, 0], [0, 0, 1], [0, 0, 0]] [s, u, u̇]
    aug = np.zeros((nd + 2, nd + 2))
    aug[:nd, :nd], aug[:nd, nd], aug[nd, nd + 1] = a, b, 1.0
    e = expm(aug * ts_s)
    phi_d, f_u, f_w = e[:nd, :nd], e[:nd, nd], e[:nd, nd + 1]
    gam0, gam1 = f_u - f_w / ts_s, f_w / ts_s
    n = nd + 2
    iv, io = nd, nd + 1
    phi = np.zeros((n, n))
    phi[:nd, :nd] = phi_d
    phi[:nd, iv] = -gam0 / k1  # last sample's noise, through the input
    phi[:nd, io] = -(gam0 + gam1) / k1  # the offset, through both ends of the input
    phi[io, io] = 1.0
    g0, g1 = np.zeros(n), np.zeros(n)
    g0[:nd], g1[:nd] = gam0, gam1
    noise_in = np.zeros(n)  # the new sample's noise v1_k: into the v1 state and, through γ1, the others
    noise_in[:nd], noise_in[iv] = -gam1 / k1, 1.0
    h = np.zeros(n)
    h[m1:nd] = c_l
    h_rate = np.zeros(n)
    h_rate[:nd] = c_omega
    h_rate[iv] = h_rate[io] = -1.0 / k1
    states = tuple([f"hf_{i}" for i in range(m1)] + [f"lf_{i}" for i in range(m2)] + ["hf_noise", "hf_offset"])
    return ComplementarySystem(float(ts_s), phi, g0, g1, noise_in, h, h_rate, states)


def inverse_foh_droop(y) -> np.ndarray:
    """``y`` through the symmetric 5-tap filter whose response ``c0 + 2c1 cos θ + 2c2 cos 2θ``
    (θ = 2πf/fs) is ``1/sinc²(f/fs) = 1 + θ²/12 + θ⁴/240 + …`` to fourth order: driving a
    first-order-hold model with it makes the model's response to a sampled band-limited
    input that of the continuous system.  The two samples at each end keep their value."""
    y = np.asarray(y, dtype=float)
    c0, c1, c2 = INVERSE_DROOP_TAPS
    out = y.copy()
    if y.size >= 5:
        out[2:-2] = c0 * y[2:-2] + c1 * (y[1:-3] + y[3:-1]) + c2 * (y[:-4] + y[4:])
    return out


def hold_response(hf_model: SensorModel, lf_model: SensorModel, rate_hz: float, freq_hz) -> np.ndarray:
    """What the discrete model predicts the LF sensor reads of a tone at ``freq_hz`` (Hz, in
    (0, rate_hz/2)), relative to what it does read, when the tone is sampled (band-limited) and
    drives the model as the HF input through :func:`inverse_foh_droop` (module docstring):

        D(f) = C(f) · Σ_k sinc²(f/fs + k) · [G_l(f_k) / G_l(f)] · [G_h(f) / G_h(f_k)],  f_k = f + k·fs,

    ``C`` the inverse-droop filter's response, ``G_l`` the LF model, ``G_h`` the HF model (the
    model recovers the rate from the HF input through the HF model's inverse, and each image of
    the linearly interpolated input goes through that inverse and the LF model at its own
    frequency).  ``D = 1`` would be a model exact for band-limited inputs."""
    f = np.atleast_1d(np.asarray(freq_hz, dtype=float))
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise ValueError(f"rate_hz {rate_hz} must be a finite value > 0")
    if np.any(~np.isfinite(f)) or np.any(f <= 0) or np.any(f >= rate_hz / 2):
        raise ValueError(f"freq_hz must lie in (0, {rate_hz / 2:g}) Hz")
    k = np.arange(-HOLD_IMAGES, HOLD_IMAGES + 1)[:, None]
    fk = f[None, :] + k * rate_hz
    images = np.sinc(f[None, :] / rate_hz + k) ** 2 * (lf_model.response(fk) / lf_model.response(f)[None, :]) \
        * (hf_model.response(f)[None, :] / hf_model.response(fk))
    c0, c1, c2 = INVERSE_DROOP_TAPS
    theta = 2 * np.pi * f / rate_hz
    return (c0 + 2 * c1 * np.cos(theta) + 2 * c2 * np.cos(2 * theta)) * images.sum(axis=0)


def hold_correction_taps(hf_model: SensorModel, lf_model: SensorModel, rate_hz: float) -> np.ndarray:
    """Real taps ``c_j``, ``j = −HOLD_HALF_WIDTH … HOLD_HALF_WIDTH``, of the filter
    ``y'_k = Σ_j c_j y_{k−j}`` whose response ``Σ_j c_j e^{−i2πfj/fs}`` is :func:`hold_response`
    over ``0 … HOLD_BAND``·fs (least squares on its real and imaginary parts; the error is the
    relative error of the LF prediction that is left)."""
    f = np.linspace(0.0, HOLD_BAND, 401)[1:] * rate_hz
    target = hold_response(hf_model, lf_model, rate_hz, f)
    j = np.arange(-HOLD_HALF_WIDTH, HOLD_HALF_WIDTH + 1)
    basis = np.exp(-2j * np.pi * np.outer(f / rate_hz, j))
    design = np.vstack([basis.real, basis.imag])
    return np.linalg.lstsq(design, np.concatenate([target.real, target.imag]), rcond=None)[0]


def hold_corrected(y, taps) -> np.ndarray:
    """``y`` through the filter of :func:`hold_correction_taps` (``taps`` ordered ``j = −m … m``;
    it looks ``m`` samples ahead); the ``m`` samples at each end keep their value."""
    y = np.asarray(y, dtype=float)
    taps = np.asarray(taps, dtype=float)
    m = (taps.size - 1) // 2
    out = y.copy()
    if y.size > 2 * m:
        out[m:y.size - m] = np.convolve(y, taps, mode="valid")
    return out


def near_inverse_droop(y) -> np.ndarray:
    """Two stand-ins for :func:`inverse_foh_droop` that look less far ahead, for the last samples
    before the one the causal filter outputs (rows: the 3-tap ``y − (Δ²y)/12`` centred on each
    sample, which looks one ahead; the same second difference taken one sample back, which looks
    none).  Second-order accurate: what is left is small because it only carries the state over
    two samples."""
    y = np.asarray(y, dtype=float)
    out = np.vstack([y, y])
    if y.size >= 3:
        d2 = y[:-2] - 2 * y[1:-1] + y[2:]  # second difference centred on samples 1 … N−2
        out[0, 1:-1] -= d2 / 12
        out[1, 2:] -= d2 / 12
    return out


def initial_state(hf_model: SensorModel, lf_model: SensorModel, hf: np.ndarray, lf: np.ndarray,
                  noise: ComplementaryNoise, rate_hz: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Prior of sample 0 from the start of the record only (the filter stays causal): the rate
    from the first LF reading, both sensors at rest at that rate, the offset at the HF
    readings' mean over one period of the HF corner (a high-pass passes no DC; the whole record
    without ``rate_hz``); variances as wide as that stretch's spread."""
    m1, m2 = hf_model.order, lf_model.order
    n = m1 + m2 + 2
    k1, k2 = hf_model.gain, lf_model.gain
    head = hf.size if rate_hz is None else min(hf.size, max(16, int(rate_hz / hf_model.corner_hz)))
    offset = float(np.mean(hf[:head]))
    w0 = float(lf[0]) / k2
    x0 = np.zeros(n)
    x0[0] = w0 - (float(hf[0]) - offset) / k1
    x0[m1] = w0
    x0[n - 1] = offset
    spread = float(np.var(hf[:head] / k1) + np.var(lf[:head] / k2)) + 1e-300
    p0 = np.diag(np.concatenate([np.full(m1 + m2, spread), [noise.hf_var, float(np.var(hf[:head])) + noise.hf_var]]))
    return x0, p0


@dataclass
class ComplementaryRun:
    """Output of :func:`complementary_kalman`: filtered and smoothed rate, innovations, R used.

    The filtered rate, the smoothed rate (``None`` unless asked), the LF update's normalised
    innovation ``ν²/S``, the R used and the interval of Document B's rule (``-1`` for a fixed R)
    per sample, the final covariance and the first sample at the steady-state gain.

    Attributes
    ----------
    rate : ndarray, shape (n,)
        The filtered (causal) rate, in rate units.
    smoothed : ndarray, shape (n,), or None
        The fixed-interval smoother's rate, in rate units; None unless ``smooth``.
    nis : ndarray, shape (n,)
        The LF update's normalised innovation squared ν²/S (1 degree of freedom).
    r : ndarray, shape (n,)
        The R of the LF update per sample, LF unit².
    interval : ndarray of int, shape (n,)
        The interval of Document B's rule per sample; −1 for a fixed R.
    final_p : ndarray
        The state covariance after the last sample.
    k_steady : int
        First sample at the steady-state gain (fixed R); n when never reached.
    """

    rate: np.ndarray
    smoothed: np.ndarray | None
    nis: np.ndarray
    r: np.ndarray
    interval: np.ndarray
    final_p: np.ndarray
    k_steady: int


def complementary_kalman(hf, lf, ts_s: float, hf_model: SensorModel, lf_model: SensorModel,
                         noise: ComplementaryNoise, *, lf_noise: AdaptiveNoise | None = None,
                         smooth: bool = False) -> ComplementaryRun:
    """Run the complementary Kalman filter (and with ``smooth`` its smoother) on an HF and an LF record.

    The complementary filter (and with ``smooth`` its fixed-interval smoother) on an HF
    and an LF record on one time grid; ``lf_noise`` replaces the fixed ``noise.lf_var`` by
    Document B's adaptive R (module docstring).  Compiled: 10⁶ samples in well under a second.
    The HF reading, inverted through its model, drives both sensors' states as a known input;
    the LF reading is the only measurement, so the signal cancels in the innovation and the
    output cannot lag (Brown & Hwang, ch. 8).

    Parameters
    ----------
    hf : array_like, shape (n,)
        HF sensor readings, its output unit; finite, n ≥ 2.
    lf : array_like, shape (n,)
        LF sensor readings on the same time grid, its output unit; finite.
    ts_s : float
        Sample interval, in s; finite and > 0.
    hf_model : SensorModel
        The HF sensor's model, a high-pass.
    lf_model : SensorModel
        The LF sensor's model, a low-pass.
    noise : ComplementaryNoise
        The sensors' noise (HF unit², LF unit², HF unit²/s), e.g. by maximum likelihood
        (:func:`fit_complementary_noise`).
    lf_noise : AdaptiveNoise, optional
        Document B's adaptive R for the LF update (LF unit²); default the fixed ``noise.lf_var``.
    smooth : bool, default False
        Also run the fixed-interval Rauch–Tung–Striebel smoother (offline, non-causal).

    Returns
    -------
    ComplementaryRun
        The filtered rate (and the smoothed one) in rate units, the LF update's NIS, the R and
        interval used, the final covariance and the first steady-gain sample.

    Raises
    ------
    ValueError
        If the series differ in length, hold fewer than 2 samples or a non-finite value,
        ``ts_s`` is not a finite value > 0, or the HF model is not a high-pass or the LF model
        not a low-pass.

    Examples
    --------
    >>> import numpy as np
    >>> from bench.analysis.fusion import SensorModel, complementary_kalman
    >>> hf_model, lf_model = SensorModel("highpass", 1, 2.0), SensorModel("lowpass", 1, 30.0)
    >>> fs, f = 1000.0, np.array([0.5, 100.0])  # 1 kHz; a slow and a fast tone, 1 dps each
    >>> t = np.arange(4000) / fs
    >>> rng = np.random.default_rng(0)
    >>> def read(model, sd):  # the sensor's steady-state reading of the tones, plus white noise
    ...     g = model.response(f)
    ...     y = np.sum(np.abs(g) * np.sin(2 * np.pi * np.outer(t, f) + np.angle(g)), axis=1)
    ...     return y + sd * rng.standard_normal(t.size)
    >>> rate = np.sin(2 * np.pi * np.outer(t, f)).sum(axis=1)
    >>> hf, lf = read(hf_model, 0.02), read(lf_model, 0.01)
    >>> def rms(x):  # error against the true rate after the first second, dps
    ...     return round(float(np.sqrt(np.mean((x - rate)[1000:] ** 2))), 3)
    >>> rms(hf / hf_model.gain), rms(lf / lf_model.gain)  # each sensor alone loses one tone
    (0.687, 0.678)
    >>> from bench.analysis.fusion import ComplementaryNoise
    >>> run = complementary_kalman(hf, lf, 1 / fs, hf_model, lf_model, ComplementaryNoise(4e-4, 1e-4, 1e-6),
    ...                            smooth=True)
    >>> rms(run.rate), rms(run.smoothed)
    (0.02, 0.019)
    """
    hf, lf = check_series(hf, lf)
    system = complementary_system(hf_model, lf_model, ts_s)
    x0, p0 = initial_state(hf_model, lf_model, hf, lf, noise, 1.0 / ts_s)
    u = hf / hf_model.gain
    if lf_noise is None:
        r_lo = r_hi = float(noise.lf_var)
        a = b = np.zeros(3)
    else:
        r_lo, r_hi = float(lf_noise.r_lower), float(lf_noise.r_upper)
        a, b = np.array(lf_noise.a, dtype=float), np.array(lf_noise.b, dtype=float)
    args = (system.phi, system.row_kind, system.g0, system.g1, system.q(noise), system.h)
    u_model = inverse_foh_droop(u)
    z = hold_corrected(lf, hold_correction_taps(hf_model, lf_model, 1.0 / ts_s))
    rate, nu, s, r, interval, ck_x, ck_p, k_steady, p, gain = kernel.complementary_forward(
        u_model, u, near_inverse_droop(u), z, *args, system.h_rate, r_lo, r_hi, a, b, lf_noise is not None,
        tuple(x0.tolist()), p0, CHECKPOINT_EVERY, STEADY_TOL, HOLD_HALF_WIDTH)
    smoothed = None
    if smooth:
        s_steady = float(s[k_steady]) if k_steady < s.size else 0.0
        smoothed = kernel.complementary_smooth(u_model, u, z, *args, system.h_rate, r, ck_x, ck_p,
                                               CHECKPOINT_EVERY, k_steady, p, gain, s_steady)
    return ComplementaryRun(rate, smoothed, nu * nu / s, r, interval, p, int(k_steady))


@dataclass(frozen=True)
class NoiseFit:
    """Maximum-likelihood noise of :func:`fit_complementary_noise`: the estimate, ``-2 log L``
    per sample at it, the start it came from, the number of likelihood evaluations, whether
    the optimiser met its tolerance (``at_bound``: a ratio ended at its search limit) and the
    decimation the likelihood was taken at."""

    noise: ComplementaryNoise
    neg2_loglik_per_sample: float
    n_samples: int
    start: ComplementaryNoise
    evaluations: int
    converged: bool
    at_bound: bool
    decimation: int = 1

    def to_dict(self) -> dict:
        return {"noise": self.noise.to_dict(), "neg2_loglik_per_sample": float(self.neg2_loglik_per_sample),
                "n_samples": int(self.n_samples), "start": self.start.to_dict(), "evaluations": int(self.evaluations),
                "converged": bool(self.converged), "at_bound": bool(self.at_bound),
                "decimation": int(self.decimation),
                "method": "maximum likelihood of the LF innovations (scale concentrated out, Nelder-Mead on "
                          "log(lf_var/hf_var), log(offset_rw·Ts/hf_var))"}


def likelihood_decimation(rate_hz: float, lf_model: SensorModel, n_samples: int) -> int:
    """How much :func:`fit_complementary_noise` decimates a record before its likelihood: down to
    ``ML_RATE_PER_LF_CORNER`` times the LF corner (where the sensors' noise levels decide the
    weighting), keeping at least ``MIN_ML_SAMPLES`` samples; a power of two."""
    factor = max(1, min(int(rate_hz // (ML_RATE_PER_LF_CORNER * lf_model.corner_hz)), n_samples // MIN_ML_SAMPLES))
    return 1 << (factor.bit_length() - 1)


def decimate_pair(hf: np.ndarray, lf: np.ndarray, factor: int) -> tuple[np.ndarray, np.ndarray]:
    """Both records low-passed (zero-phase FIR, the same for both: the sensors' models still
    relate them) and decimated by ``factor`` (a power of two), in stages of at most 8."""
    if factor < 1 or factor & (factor - 1):
        raise ValueError(f"factor {factor} must be a power of two ≥ 1")
    while factor > 1:
        step = min(factor, 8)
        hf, lf = (decimate(y, step, ftype="fir", zero_phase=True) for y in (hf, lf))
        factor //= step
    return hf, lf


def fit_complementary_noise(hf, lf, ts_s: float, hf_model: SensorModel, lf_model: SensorModel, *,
                            start: ComplementaryNoise | None = None, factor: int | None = None,
                            tones_hz=None, t_s=None) -> NoiseFit:
    """Estimate the sensors' noise (:class:`ComplementaryNoise`) by maximum likelihood from the records.

    Maximum-likelihood estimate of :class:`ComplementaryNoise` from the records themselves
    (no reference needed): the filter's innovations ``ν_k`` with variances ``S_k`` give
    ``−2 log L = Σ (log 2πS_k + ν_k²/S_k)``.  Scaling all three variances (and the prior) by λ
    scales every ``S_k`` by λ and leaves ``ν_k`` alone, so λ is concentrated out in closed form
    (``λ̂ = mean(ν²/S)``) and Nelder–Mead searches the two log ratios ``lf_var/hf_var`` and
    ``offset_rw·Ts/hf_var``, started from the best of a coarse grid about ``start`` (default:
    each record's second-difference white-noise variance, offset drift 10⁻³ of the HF noise
    per second).

    **Where the likelihood looks.**  The variances the filter needs are the sensors' noise
    levels at the frequencies where it blends them (up to a few times the LF corner); a white
    model fitted over the whole band would be skewed by noise that is not white up there (LF
    frames at a lower rate resampled, a converter's aperture).  So both records are first
    decimated by ``factor`` (default :func:`likelihood_decimation`: to 20× the LF corner,
    :func:`decimate_pair`), the likelihood taken over the first ``ML_MAX_SAMPLES`` decimated
    samples (2¹⁷: the variances' relative standard error is then well under 1 %), and the
    variances returned as white noise of the same density at the full rate (× ``factor``).

    **Known tones** (``tones_hz``, e.g. the table's profile): their least-squares fit (at the
    samples' instants ``t_s``, default ``k·ts_s``: a clock-corrected record's are not) is taken
    out of both records first, so that what the likelihood sees is the sensors' noise and not
    the tones through the slight mismatch of any discrete model (which it would call noise).

    Parameters
    ----------
    hf : array_like, shape (n,)
        HF sensor readings, its output unit; finite, n ≥ 2.
    lf : array_like, shape (n,)
        LF sensor readings on the same time grid, its output unit; finite.
    ts_s : float
        Sample interval, in s; finite and > 0.
    hf_model : SensorModel
        The HF sensor's model, a high-pass.
    lf_model : SensorModel
        The LF sensor's model, a low-pass.
    start : ComplementaryNoise, optional
        Where the search starts (HF unit², LF unit², HF unit²/s); default each record's
        second-difference white-noise variance and an offset drift of 10⁻³ of the HF noise per s.
    factor : int, optional
        Decimation before the likelihood, a power of two ≥ 1; default
        :func:`likelihood_decimation` (to 20× the LF corner).
    tones_hz : array_like, optional
        Frequencies of known tones in the records, in Hz, fitted out of both first; default none.
    t_s : array_like, shape (n,), optional
        The samples' instants for the tone fit, in s; default ``k·ts_s``.

    Returns
    -------
    NoiseFit
        ``noise``, the estimated :class:`ComplementaryNoise` as white noise at the full rate
        (HF unit², LF unit², HF unit²/s); ``neg2_loglik_per_sample`` (−2 log L per sample) and
        ``n_samples`` of the likelihood; ``start``; ``evaluations``; ``converged`` (the optimiser
        met its tolerance); ``at_bound`` (a ratio ended at its search limit); ``decimation``.

    Raises
    ------
    ValueError
        If the series differ in length, hold fewer than 2 samples or a non-finite value,
        ``t_s`` and ``hf`` differ in length, ``factor`` > 1 is not a power of two, or the HF model
        is not a high-pass or the LF model not a low-pass.

    Examples
    --------
    Two tones (0.5 and 100 Hz, 1 dps each) read at 1 kHz by a 2 Hz high-pass with white noise of
    0.02 and a 30 Hz low-pass with 0.01 (standard deviations):

    >>> import numpy as np
    >>> from bench.analysis.fusion import SensorModel, fit_complementary_noise
    >>> hf_model, lf_model = SensorModel("highpass", 1, 2.0), SensorModel("lowpass", 1, 30.0)
    >>> fs, f = 1000.0, np.array([0.5, 100.0])
    >>> t = np.arange(8000) / fs
    >>> rng = np.random.default_rng(0)
    >>> def read(model, sd):  # the sensor's steady-state reading of the tones, plus white noise
    ...     g = model.response(f)
    ...     y = np.sum(np.abs(g) * np.sin(2 * np.pi * np.outer(t, f) + np.angle(g)), axis=1)
    ...     return y + sd * rng.standard_normal(t.size)
    >>> hf, lf = read(hf_model, 0.02), read(lf_model, 0.01)
    >>> fit = fit_complementary_noise(hf, lf, 1 / fs, hf_model, lf_model, tones_hz=f)
    >>> round(float(np.sqrt(fit.noise.hf_var)), 3), round(float(np.sqrt(fit.noise.lf_var)), 3)
    (0.021, 0.01)
    >>> fit.converged, fit.at_bound
    (True, False)
    """
    hf, lf = check_series(hf, lf)
    if tones_hz is not None and len(tones_hz):
        t = np.arange(hf.size) * ts_s if t_s is None else np.asarray(t_s, dtype=float)
        if t.size != hf.size:
            raise ValueError(f"t_s has {t.size} samples and hf {hf.size}; they must match")
        hf, lf = tone_residual(t, np.column_stack([hf, lf]), np.asarray(tones_hz, dtype=float)).T
    if factor is None:
        factor = likelihood_decimation(1.0 / ts_s, lf_model, hf.size)
    if factor > 1:
        hf, lf = decimate_pair(hf, lf, factor)
        ts_s = ts_s * factor
    hf, lf = hf[:ML_MAX_SAMPLES], lf[:ML_MAX_SAMPLES]
    if start is None:
        k1, k2 = hf_model.gain, lf_model.gain
        hf0 = max(white_noise_var(hf), 1e-30 * k1 * k1)
        lf0 = max(white_noise_var(lf), 1e-30 * k2 * k2)
        start = ComplementaryNoise(hf0, lf0, 1e-3 * hf0)
    unit = ComplementaryNoise(1.0, start.lf_var / start.hf_var, start.offset_rw / start.hf_var)
    x0, p0_start = initial_state(hf_model, lf_model, hf, lf, start, 1.0 / ts_s)
    p0_unit = p0_start / start.hf_var
    # no hold correction here: the tones are fitted out, so its images do not matter, and near
    # the decimated rate's Nyquist frequency its response (unconstrained above HOLD_BAND) would
    # colour the LF noise whose white level is what the likelihood estimates
    u = inverse_foh_droop(hf / hf_model.gain)
    x0t = tuple(x0.tolist())
    rho0 = np.array([math.log(unit.lf_var), math.log(unit.offset_rw * ts_s)])
    lo, hi = rho0 - RATIO_SPAN, rho0 + RATIO_SPAN
    evaluations = 0

    system = complementary_system(hf_model, lf_model, ts_s)
    kind = system.row_kind

    def unit_run(rho: np.ndarray) -> tuple[float, float, int]:
        """``(Σ log S, Σ ν²/S, count)`` at HF variance 1 and the ratios ``rho``."""
        q = system.q(ComplementaryNoise(1.0, math.exp(rho[0]), math.exp(rho[1]) / ts_s))
        return kernel.complementary_loglik(u, lf, system.phi, kind, system.g0, system.g1, q, system.h,
                                           math.exp(rho[0]), x0t, p0_unit, STEADY_TOL)

    def objective(rho: np.ndarray) -> float:
        nonlocal evaluations
        evaluations += 1
        sum_log, sum_nis, count = unit_run(np.clip(rho, lo, hi))
        if not (math.isfinite(sum_log) and math.isfinite(sum_nis) and sum_nis > 0) or count == 0:
            return math.inf
        return (sum_log + count * math.log(sum_nis / count)) / count + 1.0 + math.log(2 * math.pi)

    grid = [np.array([rho0[0] + d0, rho0[1] + d1]) for d0 in (-4.0, 0.0, 4.0) for d1 in (-6.0, 0.0, 6.0)]
    best = min(grid, key=objective)
    sol = minimize(objective, best, method="Nelder-Mead",
                   options={"xatol": 0.01, "fatol": 1e-8, "maxfev": 200,
                            "initial_simplex": np.array([best, best + [1.0, 0.0], best + [0.0, 2.0]])})
    rho = np.clip(sol.x, lo, hi)
    at_bound = bool(np.any(np.isclose(rho, lo) | np.isclose(rho, hi)))
    _, sum_nis, count = unit_run(rho)  # the scale λ at the optimum
    lam = sum_nis / count
    noise = ComplementaryNoise(factor * lam, factor * lam * math.exp(rho[0]), lam * math.exp(rho[1]) / ts_s)
    return NoiseFit(noise, float(sol.fun), int(count), start, evaluations, bool(sol.success), at_bound, factor)
