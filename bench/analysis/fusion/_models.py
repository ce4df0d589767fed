"""Sensor models, FRF fit and the combined state-space model of Document B's rate fusion.

Two coaxial angular-rate sensors see the same true rate ``ω`` (any rate unit, e.g. dps):

* the **HF sensor** (MHD): a high-pass ``G1(s) = k1·(s/ωh)ⁿ / D(s/ωh)`` with corner
  ``f_h`` of a few Hz, ``n = 1`` or ``2``;
* the **LF sensor** (FOG/MEMS class): a low-pass ``G2(s) = k2 / D(s/ωl)`` with corner
  ``f_l`` of tens of Hz;

with ``D(p) = 1 + p`` (first order) or ``1 + 2ζp + p²`` (second order), ``ω = 2πf``.

The true rate is modelled as a random walk driven by white noise of spectral density
``q`` (rate unit²/s): ``ω̇ = w``.  The combined continuous model, state
``x = [ω, x_hf…, x_lf…]``::

    ẋ = A x + B w,     y1 = H1 x + v1,     y2 = H2 x + v2

Each sensor is realised from the low-pass states of its own dynamics (``u`` its input):
first-order LP ``ż = ωc(u − z)``; second-order LP ``ż = v, v̇ = ωc²(u − z) − 2ζωc v``.
A low-pass sensor reads ``k·z``; a high-pass sensor reads ``k(u − z)`` (first order) or
``k(u − z − (2ζ/ωc)v)`` (second order), the complement of the same low-pass.

Discretisation: Document B's ``Φ = I + A·Ts`` with ``Q = B q Bᵀ Ts`` (``"euler"``), or the
exact zero-order-hold ``Φ = e^{A·Ts}`` with Van Loan's ``Q = ∫₀^Ts e^{Aτ} B q Bᵀ e^{Aᵀτ} dτ``
(``"zoh"``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm
from scipy.optimize import least_squares

KINDS = ("highpass", "lowpass")
DISCRETIZATIONS = ("euler", "zoh")
CORNER_STARTS = (1.0, 0.3, 3.0)  # the fit starts from the −3 dB crossing and from these multiples of it
LOG_LIMIT = 60.0  # log-parameters are clipped here inside the misfit (e⁶⁰ ≈ 10²⁶)
ORDER_GAIN_FACTOR = 2.0  # a higher order is kept only if it divides the relative RMS misfit by this


@dataclass(frozen=True)
class SensorModel:
    """One rate sensor's transfer function: a high- or low-pass of order 1 or 2.

    One sensor's transfer function: ``kind`` high/low-pass, ``order`` 1 or 2, corner
    ``corner_hz``, passband ``gain`` (output unit per rate unit), damping ``zeta`` (order 2).

    High-pass ``G(s) = k·(s/ωc)ⁿ / D(s/ωc)``, low-pass ``G(s) = k / D(s/ωc)`` with
    ``D(p) = 1 + p`` (order 1) or ``1 + 2ζp + p²`` (order 2), ``ωc = 2π·corner_hz`` (module
    docstring). Methods: ``response(freq_hz)`` (complex), ``state_space()`` ``(A, b, c, d)``.

    Parameters
    ----------
    kind : {"highpass", "lowpass"}
        High-pass (the HF sensor, e.g. an MHD) or low-pass (the LF sensor, e.g. a FOG).
    order : {1, 2}
        Order n of the filter.
    corner_hz : float
        Corner frequency, in Hz; finite and > 0.
    gain : float, default 1.0
        Passband gain k, in output unit per rate unit; finite and non-zero.
    zeta : float, default √0.5
        Damping ζ of a second-order filter (unused at order 1); finite and > 0.

    Raises
    ------
    ValueError
        If a parameter is outside what is allowed above.

    Examples
    --------
    >>> import numpy as np
    >>> from bench.analysis.fusion import SensorModel
    >>> hf = SensorModel("highpass", 1, 2.0)
    >>> g = hf.response(2.0)  # at the corner: −3 dB, a 45° lead
    >>> round(abs(g), 4), round(float(np.degrees(np.angle(g))), 1)
    (0.7071, 45.0)
    >>> [m.shape for m in SensorModel("lowpass", 2, 30.0).state_space()[:3]]
    [(2, 2), (2,), (2,)]
    """

    kind: str
    order: int
    corner_hz: float
    gain: float = 1.0
    zeta: float = math.sqrt(0.5)

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"kind {self.kind!r} must be one of {', '.join(KINDS)}")
        if self.order not in (1, 2):
            raise ValueError(f"order {self.order} must be 1 or 2")
        if not (math.isfinite(self.corner_hz) and self.corner_hz > 0):
            raise ValueError(f"corner_hz {self.corner_hz} must be a finite value > 0")
        if not (math.isfinite(self.gain) and self.gain != 0):
            raise ValueError(f"gain {self.gain} must be finite and non-zero")
        if not (math.isfinite(self.zeta) and self.zeta > 0):
            raise ValueError(f"zeta {self.zeta} must be a finite value > 0")

    def response(self, freq_hz) -> np.ndarray:
        """Complex frequency response at ``freq_hz`` (Hz)."""
        return _response(np.asarray(freq_hz, dtype=float), self.kind, self.order, self.corner_hz, self.gain, self.zeta)

    def state_space(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """``(A, b, c, d)`` with ``ẋ = A x + b u``, ``y = c x + d u`` (``u`` the true rate)."""
        wc = 2 * math.pi * self.corner_hz
        if self.order == 1:
            a, b = np.array([[-wc]]), np.array([wc])
            c_lp = np.array([1.0])
        else:
            a = np.array([[0.0, 1.0], [-wc * wc, -2 * self.zeta * wc]])
            b = np.array([0.0, wc * wc])
            c_lp = np.array([1.0, 0.0])
        if self.kind == "lowpass":
            return a, b, self.gain * c_lp, 0.0
        c_hp = -np.array([1.0]) if self.order == 1 else -np.array([1.0, 2 * self.zeta / wc])
        return a, b, self.gain * c_hp, self.gain

    def to_dict(self) -> dict:
        return {"kind": self.kind, "order": int(self.order), "corner_hz": float(self.corner_hz),
                "gain": float(self.gain), "zeta": float(self.zeta)}


def _response(f, kind, order, corner_hz, gain, zeta):
    p = 1j * f / corner_hz
    den = 1 + p if order == 1 else 1 + 2 * zeta * p + p * p
    num = 1.0 if kind == "lowpass" else p ** order
    return gain * num / den


@dataclass(frozen=True)
class TransferFit:
    """A sensor model fitted to a measured FRF, with its delay, misfit and order rule.

    Result of :func:`fit_transfer_function`: the chosen model, its relative RMS misfit
    ``residual`` (``rms(|Ĝ−G|/|G|)``, delay included), the misfit of every order tried, the
    rule used, the fitted pure delay ``delay_s`` (s; 0.0 when not fitted), when weights
    were given, ``chi2_reduced`` = ``Σ|w(Ĝ−G)|² / (2N − p)`` (≈ 1 when the model explains the
    FRF within its stated uncertainty), and a first-order pole above the band ``upper_hz``
    (``None`` when not fitted) — like the delay, part of the fit, not of ``model``.

    ``response(freq_hz)`` is the fit's complex response, delay and upper pole included.

    Attributes
    ----------
    model : SensorModel
        The chosen model (kind, order, corner in Hz, gain in output unit per rate unit).
    residual : float
        Relative RMS misfit ``rms(|Ĝ−G|/|G|)`` of the chosen order, delay included
        (dimensionless).
    residual_by_order : dict of int to float
        The relative RMS misfit of every order tried.
    rule : str
        The order rule used, in words.
    delay_s : float
        Fitted pure delay τ, in s (positive: the sensor lags); 0.0 when not fitted.
    chi2_reduced : float or None
        ``Σ|w(Ĝ−G)|² / (2N − p)`` when weights were given, else None.
    upper_hz : float or None
        Fitted first-order pole above the band, in Hz; None when not fitted.
    corner_hz : float
        Property: ``model.corner_hz``, in Hz.
    gain : float
        Property: ``model.gain``.
    order : int
        Property: ``model.order``.
    """

    model: SensorModel
    residual: float
    residual_by_order: dict
    rule: str
    delay_s: float = 0.0
    chi2_reduced: float | None = None
    upper_hz: float | None = None

    @property
    def corner_hz(self) -> float:
        return self.model.corner_hz

    @property
    def gain(self) -> float:
        return self.model.gain

    @property
    def order(self) -> int:
        return self.model.order

    def response(self, freq_hz) -> np.ndarray:
        """Complex response of the fit, delay and upper pole included: ``G(jω)·e^{−jωτ}/(1 + jf/f_u)``."""
        f = np.asarray(freq_hz, dtype=float)
        upper = 1.0 if self.upper_hz is None else 1.0 / (1 + 1j * f / self.upper_hz)
        return self.model.response(f) * np.exp(-2j * np.pi * f * self.delay_s) * upper

    def to_dict(self) -> dict:
        return {"model": self.model.to_dict(), "residual": float(self.residual),
                "residual_by_order": {str(k): float(v) for k, v in self.residual_by_order.items()}, "rule": self.rule,
                "delay_s": float(self.delay_s),
                "chi2_reduced": None if self.chi2_reduced is None else float(self.chi2_reduced),
                "upper_hz": None if self.upper_hz is None else float(self.upper_hz)}


def _phase_slope_delay(f: np.ndarray, g: np.ndarray) -> float:
    """Start value of the delay (s): minus the slope of the unwrapped phase against ω over the
    top third of the band, where a rational high/low-pass's own phase is nearly flat."""
    top = slice(max(0, f.size - max(3, f.size // 3)), None)
    w = 2 * np.pi * f[top]
    phase = np.unwrap(np.angle(g[top]))
    return float(-np.polyfit(w, phase, 1)[0])


def min_frf_points(max_order: int, fit_delay: bool = False, upper_pole: bool = False) -> int:
    """FRF points :func:`fit_transfer_function` needs: ``2·order + 1``, one more for a delay;
    an upper pole adds one at order 1 only (order 2 with a delay and an upper pole fits five
    real parameters to the twelve numbers of six points, as many spare as order 1 with a
    delay has on four)."""
    return 2 * max_order + 1 + int(bool(fit_delay)) + int(bool(upper_pole) and max_order == 1)


def fit_transfer_function(freq_hz, response_complex, kind: str = "highpass", max_order: int = 2,
                          fit_delay: bool = False, weights=None, upper_pole: bool = False) -> TransferFit:
    """Fit a high- or low-pass of order 1…``max_order`` (optionally times a pure delay) to a measured FRF.

    Each order is fitted by nonlinear least squares on the *relative* complex misfit
    ``(Ĝ(f) − G(f))/|G(f)|`` (every frequency weighs the same whatever its magnitude), or,
    with ``weights`` (``1/σ`` of each FRF point, σ the standard uncertainty of its real and
    imaginary parts, same unit as the response), on ``w·(Ĝ(f) − G(f))``; over log-gain,
    log-corner and (order 2) log-damping, started from the passband gain and the −3 dB crossing.

    ``fit_delay``: the model becomes ``G(jω)·e^{−jωτ}`` with a **signed** delay ``τ`` (s;
    positive = the sensor lags the reference: latency, an unmodelled far pole ≈ ``1/(2πf_p)``,
    or a timestamp offset, which may have either sign), started from the phase slope at the
    top of the band (:func:`_phase_slope_delay`) and from 0, keeping the better; the corner is
    started from the −3 dB crossing and from ``CORNER_STARTS`` multiples of it.

    ``upper_pole`` (high-pass only): the model is also divided by ``1 + jf/f_u``, a first-order
    pole above the band (a sensor's own bandwidth limit: left out, it would bend the gain and the
    corner to mimic its droop), started from 3× and 10× the top frequency.

    **Order rule**: start at order 1; order ``n+1`` replaces ``n`` only if
    its relative RMS misfit is below ``1/ORDER_GAIN_FACTOR`` (half) of order ``n``'s — one
    more parameter must explain at least half of the remaining misfit, not just noise.

    Parameters
    ----------
    freq_hz : array_like, shape (N,)
        FRF frequencies, in Hz; finite and > 0 (any order). N ≥ ``2·max_order + 1``, plus one
        with ``fit_delay`` and one with ``upper_pole`` at order 1.
    response_complex : array_like of complex, shape (N,)
        Measured response at each, sensor output unit per rate unit; finite and non-zero.
    kind : {"highpass", "lowpass"}, default "highpass"
        The filter family fitted.
    max_order : {1, 2}, default 2
        Highest order tried.
    fit_delay : bool, default False
        Fit a signed pure delay τ (s) too.
    weights : array_like, shape (N,), optional
        ``1/σ`` of each FRF point (σ the standard uncertainty of its real and imaginary
        parts, response unit), finite and > 0, e.g. :attr:`bench.analysis.frf.FrfResult.weights`;
        default: the relative misfit.
    upper_pole : bool, default False
        Fit a first-order pole above the band too (``kind="highpass"`` only).

    Returns
    -------
    TransferFit
        The chosen model, its misfit and every order's, the delay (s), the reduced χ² (with
        weights) and the upper pole (Hz).

    Raises
    ------
    ValueError
        If ``kind`` or ``max_order`` is not allowed, the arrays differ in length or hold too
        few points, a frequency is not finite and > 0, a response is not finite and non-zero,
        ``weights`` are not N finite values > 0, or ``upper_pole`` is asked of a low-pass.

    Examples
    --------
    A high-pass at 2 Hz with a gain of 0.9 and 1 ms of latency, measured at 12 frequencies
    with a little noise:

    >>> import numpy as np
    >>> from bench.analysis.fusion import SensorModel, fit_transfer_function
    >>> f = np.array([0.5, 1, 2, 3, 5, 8, 12, 20, 35, 60, 100, 200])
    >>> rng = np.random.default_rng(0)
    >>> g = SensorModel("highpass", 1, 2.0, 0.9).response(f) * np.exp(-2j * np.pi * f * 1e-3)
    >>> g = g + 0.002 * (rng.standard_normal(f.size) + 1j * rng.standard_normal(f.size))
    >>> fit = fit_transfer_function(f, g, "highpass", fit_delay=True)
    >>> fit.order, round(fit.corner_hz, 2), round(fit.gain, 3), round(fit.delay_s * 1e3, 2)
    (1, 2.01, 0.899, 1.0)
    """
    f = np.asarray(freq_hz, dtype=float).ravel()
    g = np.asarray(response_complex, dtype=complex).ravel()
    if kind not in KINDS:
        raise ValueError(f"kind {kind!r} must be one of {', '.join(KINDS)}")
    if max_order not in (1, 2):
        raise ValueError(f"max_order {max_order} must be 1 or 2")
    if f.size != g.size:
        raise ValueError(f"freq_hz has {f.size} values and response_complex {g.size}; they must match")
    if upper_pole and kind != "highpass":
        raise ValueError("upper_pole is for a high-pass sensor's bandwidth limit (kind 'highpass')")
    n_min = min_frf_points(max_order, fit_delay, upper_pole)
    if f.size < n_min:
        raise ValueError(f"{f.size} FRF points; at least {n_min} are needed for order {max_order}"
                         + (" with a delay" if fit_delay else "") + (" and an upper pole" if upper_pole else ""))
    if not (np.all(np.isfinite(f)) and np.all(f > 0) and np.all(np.isfinite(g)) and np.all(np.abs(g) > 0)):
        raise ValueError("freq_hz must be finite and > 0 and response_complex finite and non-zero")
    w = None
    if weights is not None:
        w = np.asarray(weights, dtype=float).ravel()
        if w.size != f.size or not (np.all(np.isfinite(w)) and np.all(w > 0)):
            raise ValueError(f"weights must be {f.size} finite values > 0 (1/σ of each FRF point)")
    order_idx = np.argsort(f)
    f, g = f[order_idx], g[order_idx]
    w = None if w is None else w[order_idx]
    mag = np.abs(g)
    scale = mag if w is None else 1.0 / w  # residual divisor: relative, or the stated σ
    # start: passband gain (sign from phase there) and the frequency where |G| crosses gain/√2
    pass_i = -1 if kind == "highpass" else 0
    delay_scale = 1.0 / (2 * np.pi * f[-1])  # τ is fitted in units of one radian at the top frequency
    taus0 = [0.0]
    if fit_delay:
        taus0 = [_phase_slope_delay(f, g), 0.0]
        g_pass = g[pass_i] * np.exp(2j * np.pi * f[pass_i] * taus0[0])  # passband sign with the delay undone
    else:
        g_pass = g[pass_i]
    k0 = float(np.real(g_pass) / abs(np.real(g_pass)) * mag[pass_i]) if np.real(g_pass) != 0 else mag[pass_i]
    level = np.abs(k0) / math.sqrt(2)
    below = mag < level
    cross = np.flatnonzero(below[:-1] != below[1:])
    fc0 = float(f[cross[0]]) if cross.size else float(np.sqrt(f[0] * f[-1]))

    fits, residuals, delays, costs, uppers = {}, {}, {}, {}, {}
    for order in range(1, max_order + 1):
        n_log = 2 + int(order == 2) + int(upper_pole)  # log gain, log corner, [log ζ], [log f_u/f_top]

        def unpack(p, order=order, n_log=n_log):
            lp = np.clip(p[:n_log], -LOG_LIMIT, LOG_LIMIT)  # a wild step from a far start must not overflow
            zeta = math.exp(lp[2]) if order == 2 else math.sqrt(0.5)
            upper = f[-1] * math.exp(lp[-1]) if upper_pole else None
            tau = float(p[-1] * delay_scale) if fit_delay else 0.0
            return SensorModel(kind, order, math.exp(lp[1]), math.copysign(math.exp(lp[0]), k0), zeta), upper, tau

        def response(p, order=order, n_log=n_log):
            model, upper, tau = unpack(p, order, n_log)
            r = _response(f, kind, order, model.corner_hz, model.gain, model.zeta if order == 2 else 1.0)
            if upper is not None:
                r = r / (1 + 1j * f / upper)
            return r * np.exp(-2j * np.pi * f * tau) if fit_delay else r

        def misfit(p, order=order, n_log=n_log):
            r = (response(p, order, n_log) - g) / scale
            return np.concatenate([r.real, r.imag])

        sols = []
        for tau0 in taus0:
            for corner_factor in CORNER_STARTS:  # a noisy −3 dB crossing can start far off: several starts
                for upper0 in ((3.0, 10.0) if upper_pole else (None,)):
                    x0 = [math.log(abs(k0)), math.log(fc0 * corner_factor)]
                    x0 += [math.log(math.sqrt(0.5))] if order == 2 else []
                    x0 += [math.log(upper0)] if upper0 is not None else []
                    x0 += [tau0 / delay_scale] if fit_delay else []
                    sols.append(least_squares(misfit, x0, method="lm"))
        best = min((sol for sol in sols if np.all(np.abs(sol.x[:n_log]) < LOG_LIMIT)),
                   key=lambda sol: sol.cost, default=min(sols, key=lambda sol: sol.cost))
        fits[order], uppers[order], delays[order] = unpack(best.x)
        costs[order] = (2 * best.cost, best.x.size)
        residuals[order] = float(np.sqrt(np.mean(np.abs(response(best.x) - g) ** 2 / mag ** 2)))
    chosen = 1
    for order in range(2, max_order + 1):
        if residuals[order] < residuals[chosen] / ORDER_GAIN_FACTOR:
            chosen = order
    rule = f"lowest order unless the next divides the relative RMS misfit by ≥ {ORDER_GAIN_FACTOR:g}"
    chi2 = None
    if w is not None:
        ss, n_par = costs[chosen]
        chi2 = float(ss / max(1, 2 * f.size - n_par))
    return TransferFit(fits[chosen], residuals[chosen], residuals, rule, delays[chosen], chi2, uppers[chosen])


@dataclass(frozen=True)
class FusionModel:
    """Document B's state-space model: the true rate as a random walk and both sensors' dynamics.

    Combined continuous model of the true rate and both sensors (see module docstring).

    ``q`` is the spectral density of the white noise driving the rate random walk (rate²/s).
    State ``x = [ω, x_hf…, x_lf…]``. Methods: ``continuous()`` ``(A, B, H1, H2)`` and
    ``discretize(ts_s, method)`` ``(Φ, Q)``, ``"euler"`` (Document B) or ``"zoh"`` (exact,
    Van Loan).

    Parameters
    ----------
    hf : SensorModel
        The HF sensor's model (a high-pass, for Document B's fusion).
    lf : SensorModel
        The LF sensor's model.
    q : float
        Spectral density of the white noise driving the rate random walk, in rate unit²/s;
        finite and > 0.

    Raises
    ------
    ValueError
        If ``q`` is not a finite value > 0.

    Examples
    --------
    >>> from bench.analysis.fusion import FusionModel, SensorModel
    >>> model = FusionModel(SensorModel("highpass", 1, 2.0), SensorModel("lowpass", 1, 30.0), q=1000.0)
    >>> phi, q = model.discretize(1e-3)
    >>> model.n_states, phi.shape, round(float(q[0, 0]), 6)  # Q = B q Bᵀ Ts
    (3, (3, 3), 1.0)
    """

    hf: SensorModel
    lf: SensorModel
    q: float

    def __post_init__(self):
        if not (math.isfinite(self.q) and self.q > 0):
            raise ValueError(f"q {self.q} must be a finite value > 0 (rate²/s)")

    @property
    def n_states(self) -> int:
        return 1 + self.hf.order + self.lf.order

    def continuous(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(A, B, H1, H2)``: ``A`` n×n, ``B`` n×1 (process noise into ``ω``), ``H1``/``H2`` 1×n."""
        n = self.n_states
        a = np.zeros((n, n))
        h = []
        i = 1
        for sensor in (self.hf, self.lf):
            sa, sb, sc, sd = sensor.state_space()
            m = sensor.order
            a[i:i + m, i:i + m] = sa
            a[i:i + m, 0] = sb
            row = np.zeros((1, n))
            row[0, 0] = sd
            row[0, i:i + m] = sc
            h.append(row)
            i += m
        b = np.zeros((n, 1))
        b[0, 0] = 1.0
        return a, b, h[0], h[1]

    def discretize(self, ts_s: float, method: str = "euler") -> tuple[np.ndarray, np.ndarray]:
        """``(Φ, Q)`` for sample interval ``ts_s``: ``"euler"`` (Document B, ``Φ = I + A·Ts``,
        ``Q = B q Bᵀ Ts``) or ``"zoh"`` (exact ``e^{A·Ts}``, Van Loan ``Q``)."""
        if not (math.isfinite(ts_s) and ts_s > 0):
            raise ValueError(f"ts_s {ts_s} must be a finite value > 0")
        if method not in DISCRETIZATIONS:
            raise ValueError(f"discretization {method!r} must be one of {', '.join(DISCRETIZATIONS)}")
        a, b, _, _ = self.continuous()
        n = a.shape[0]
        qc = self.q * (b @ b.T)
        if method == "euler":
            return np.eye(n) + a * ts_s, qc * ts_s
        # Van Loan: expm([[-A, Qc], [0, Aᵀ]]·Ts) = [[·, Φ⁻¹Q], [0, Φᵀ]]
        m = np.zeros((2 * n, 2 * n))
        m[:n, :n], m[:n, n:], m[n:, n:] = -a, qc, a.T
        e = expm(m * ts_s)
        phi = e[n:, n:].T
        q = phi @ e[:n, n:]
        return phi, 0.5 * (q + q.T)

    def to_dict(self) -> dict:
        return {"hf": self.hf.to_dict(), "lf": self.lf.to_dict(), "q": float(self.q),
                "state": ["rate"] + [f"hf_{i}" for i in range(self.hf.order)]
                + [f"lf_{i}" for i in range(self.lf.order)]}
