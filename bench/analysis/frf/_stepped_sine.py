"""Stepped-sine frequency response of a sensor against the angular vibration table's reference.

At each frequency ``f`` of the grid the table dwells; the reference rate (table clock) and the
sensor's output (its own sample clock) are each fitted by :func:`sine_fit`, and the sensor's
frequency response is the ratio of the two complex amplitudes (:func:`frf_point`,
:func:`frf`).  The FRF feeds :func:`~bench.analysis.fusion._models.fit_transfer_function`
(with ``fit_delay=True`` and ``weights=FrfResult.weights``).

**Phasor convention** (the same as :func:`~bench.analysis.fusion._metrics.sine_phasors`)::

    y(t) ≈ c [+ d·(t − t_mid)] + Σₖ Re(Aₖ·e^{j2πkf(t − t0_s)}),   k = 1 … harmonics

so ``|A₁|`` is the tone's amplitude and ``arg A₁`` its cosine phase at ``t0_s`` (rad; a lead
is positive).  ``sine_phasors`` remains the quick multi-tone fit; :func:`sine_fit` adds the
absolute time origin (records on different clocks/grids compare), a trend term, the
whole-period window and standard errors.

**Window rule**: of the span given (default: first sample to last sample + one interval) the
fit keeps the longest whole number of periods of ``f`` from its start, ``[start,
start + ⌊span·f⌋/f)``; a sample belongs to it if its time lies in ``[start − dt/2, stop − dt/2)``
(its cell is more inside than out).  Whole periods make the constant, the trend and every
harmonic (nearly) orthogonal to the fundamental, so what is not modelled does not leak into it.
Harmonics at or above the Nyquist frequency are not modelled (they alias into the residual).

**Standard errors** (autocorrelation-aware): the white-noise covariance ``σ²(XᵀX)⁻¹`` is
rescaled by the residual's own spectrum *at the tone*: ``σ²`` is replaced by the mean
periodogram ``|Σ eₙ e^{−j2πνtₙ}|²/N`` of the residual at the ``2·NEIGHBOURS`` Fourier
frequencies ``ν = f ± m/T`` nearest ``f`` (``T`` the window; DC and the modelled harmonics'
own frequencies excluded) — the level of the noise that actually competes with the tone.
For white noise this equals ``σ²``; for correlated noise it is the local spectral density, which
is what the sine coefficients' variance depends on (``var a ≈ 2 S(f)/N``).  ``noise_factor``
reports the ratio.  With fewer than ``MIN_NEIGHBOURS`` usable frequencies (a one- or two-period
fit) the factor falls back to the AR(1) spectrum of the residual at ``f``,
``(1 − ρ²)/(1 − 2ρ cos 2πf·dt + ρ²)`` with ``ρ`` its lag-1 autocorrelation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

NEIGHBOURS = 8  # Fourier frequencies each side of f that estimate the residual's local spectrum
MIN_NEIGHBOURS = 4  # fewer usable ones → AR(1) fallback


def check_record(t_s, y, name: str = "y") -> tuple[np.ndarray, np.ndarray, float]:
    """1-D finite arrays of one length with strictly increasing times; returns ``(t, y, median dt)``."""
    t = np.asarray(t_s, dtype=float).ravel()
    v = np.asarray(y, dtype=float).ravel()
    if t.size != v.size:
        raise ValueError(f"times have {t.size} values and {name} {v.size}; they must match")
    if t.size < 4:
        raise ValueError(f"{name} has {t.size} samples; at least 4 are needed")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(v))):
        raise ValueError(f"times and {name} must be finite")
    dt = np.diff(t)
    if np.any(dt <= 0):
        raise ValueError(f"times of {name} must be strictly increasing (smallest step {dt.min():g} s must be > 0)")
    return t, v, float(np.median(dt))


def _wrap_deg(deg):
    """Wrap degrees to (−180, 180]."""
    return 180.0 - np.mod(180.0 - np.asarray(deg, dtype=float), 360.0)


def _cplx(z) -> list:
    return [float(np.real(z)), float(np.imag(z))]


@dataclass(frozen=True)
class SineFit:
    """One record's sine fit at ``freq_hz`` (see module docstring for the convention).

    ``amplitude`` ``A₁`` (y unit, complex, phase at ``t0_s``), ``cov`` the 2×2 covariance of
    ``(Re A₁, Im A₁)``, ``mag_std`` and ``phase_std_deg`` the standard uncertainties of ``|A₁|``
    and ``arg A₁``; ``harmonics`` ``A₂ … A_H`` (NaN where not modelled), ``offset`` ``c``,
    ``trend_per_s`` ``d`` (0 if not fitted), ``residual_rms`` (y unit), ``noise_factor`` the
    residual's spectrum at ``f`` over its variance (1 for white noise), ``window_s`` the
    ``[start, stop)`` fitted, ``n_periods`` periods of ``f`` in it, ``n_samples`` samples used."""

    freq_hz: float
    amplitude: complex
    cov: np.ndarray
    mag_std: float
    phase_std_deg: float
    harmonics: np.ndarray
    offset: float
    trend_per_s: float
    residual_rms: float
    noise_factor: float
    window_s: tuple
    n_periods: float
    n_samples: int
    t0_s: float

    @property
    def mag(self) -> float:
        return float(abs(self.amplitude))

    @property
    def phase_deg(self) -> float:
        return float(_wrap_deg(math.degrees(np.angle(self.amplitude))))

    @property
    def amplitude_std(self) -> float:
        """Per-component standard error ``√(tr cov / 2)`` of ``Re A₁`` and ``Im A₁`` (y unit)."""
        return float(math.sqrt(0.5 * np.trace(self.cov)))

    def to_dict(self) -> dict:
        return {"freq_hz": float(self.freq_hz), "amplitude": _cplx(self.amplitude), "mag": self.mag,
                "phase_deg": self.phase_deg, "mag_std": float(self.mag_std),
                "phase_std_deg": float(self.phase_std_deg), "amplitude_std": self.amplitude_std,
                "harmonics": [None if not np.isfinite(h) else _cplx(h) for h in self.harmonics],
                "offset": float(self.offset), "trend_per_s": float(self.trend_per_s),
                "residual_rms": float(self.residual_rms), "noise_factor": float(self.noise_factor),
                "window_s": [float(w) for w in self.window_s], "n_periods": float(self.n_periods),
                "n_samples": int(self.n_samples), "t0_s": float(self.t0_s)}


def _window(start: float, stop: float, freq_hz: float, whole_periods: bool, min_periods: float) -> tuple:
    periods = (stop - start) * freq_hz
    if periods + 1e-9 < min_periods:
        raise ValueError(f"span {stop - start:g} s holds {periods:.3g} periods of {freq_hz:g} Hz; "
                         f"at least {min_periods:g} are needed")
    if whole_periods:
        periods = math.floor(periods + 1e-9)
        stop = start + periods / freq_hz
    return start, stop, periods


def _local_noise_level(t, e, freq_hz, window_len_s, tones_hz, dt, trend) -> tuple[float, bool]:
    """Mean residual periodogram at the Fourier frequencies nearest ``freq_hz`` (y unit² per
    sample), and whether enough of them were usable."""
    nyq = 0.5 / dt
    cell = 1.0 / window_len_s
    m = np.arange(-NEIGHBOURS, NEIGHBOURS + 1)
    nu = freq_hz + cell * m
    keep = (m != 0) & (nu > (1.5 if trend else 0.5) * cell) & (nu < nyq - 0.5 * cell)
    for tone in tones_hz:
        keep &= np.abs(nu - tone) > 0.5 * cell
    if np.count_nonzero(keep) < MIN_NEIGHBOURS:
        return math.nan, False
    # DFT of the residual at f + m/T, stepping the kernel by one cell at a time (no N×2K matrix)
    tau = t - t[0]
    z = e * np.exp(-2j * np.pi * nu[0] * tau)
    step = np.exp(-2j * np.pi * cell * tau)
    power = []
    for i in range(m.size):
        if keep[i]:
            power.append(abs(z.sum()) ** 2)
        z *= step
    return float(np.mean(power)) / e.size, True


def sine_fit(t_s, y, freq_hz: float, harmonics: int = 3, *, trend: bool = False, span_s=None,
             whole_periods: bool = True, min_periods: float = 1.0, t0_s: float = 0.0) -> SineFit:
    """Linear least-squares sine fit of ``y`` at ``freq_hz`` and its harmonics (module docstring).

    ``t_s`` (s, strictly increasing, any clock the caller has aligned), ``y`` (any unit);
    ``harmonics`` ≥ 1 the number of multiples of ``f`` modelled (1 = the tone alone);
    ``trend`` adds a linear term (a drifting bias, a high-pass settling tail); ``span_s``
    ``(start, stop)`` restricts the fit (default the whole record); ``t0_s`` the time at which
    phases are quoted.  Needs ``0 < f < Nyquist`` of the samples and ``≥ min_periods`` periods."""
    t, v, dt = check_record(t_s, y)
    if not (isinstance(harmonics, (int, np.integer)) and 1 <= harmonics <= 20):
        raise ValueError(f"harmonics {harmonics} must be an integer in [1, 20]")
    nyq = 0.5 / dt
    if not (math.isfinite(freq_hz) and 0 < freq_hz < nyq):
        raise ValueError(f"freq_hz {freq_hz} must be in (0, {nyq:g}) Hz (Nyquist of the samples)")
    if not (math.isfinite(min_periods) and min_periods > 0):
        raise ValueError(f"min_periods {min_periods} must be a finite value > 0")
    if not math.isfinite(t0_s):
        raise ValueError(f"t0_s {t0_s} must be finite")
    start, stop = (t[0], t[-1] + dt) if span_s is None else (float(span_s[0]), float(span_s[1]))
    if not (math.isfinite(start) and math.isfinite(stop) and stop > start):
        raise ValueError(f"span_s ({start}, {stop}) must be finite with start < stop")
    start, stop, periods = _window(start, stop, freq_hz, whole_periods, min_periods)
    sel = (t >= start - 0.5 * dt) & (t < stop - 0.5 * dt)
    t, v = t[sel], v[sel]
    ks = [k for k in range(1, harmonics + 1) if k * freq_hz < nyq]
    n_par = 1 + int(trend) + 2 * len(ks)
    if t.size < n_par + 8:
        raise ValueError(f"{t.size} samples in the window [{start:g}, {stop:g}) s; "
                         f"at least {n_par + 8} are needed for {n_par} parameters")
    tau = t - start
    mid = 0.5 * (stop - start)
    cols = [np.ones_like(tau)] + ([(tau - mid) / (stop - start)] if trend else [])
    for k in ks:
        arg = 2 * np.pi * k * freq_hz * tau
        cols += [np.cos(arg), np.sin(arg)]
    x = np.column_stack(cols)
    # normal equations: the columns are O(1) and near-orthogonal over whole periods, so XᵀX is
    # well conditioned, and this is several times cheaper than a QR of the N×p matrix
    xtx_inv = np.linalg.inv(x.T @ x)
    coef = xtx_inv @ (x.T @ v)
    e = v - x @ coef
    white_var = float(e @ e) / (t.size - n_par)
    level, ok = _local_noise_level(t, e, freq_hz, stop - start, [0.0] + [k * freq_hz for k in ks], dt, trend)
    if ok:
        level *= t.size / (t.size - n_par)  # the fit removed n_par of N degrees of freedom
        factor = level / white_var if white_var > 0 else 1.0
    else:
        rho = float(np.clip(np.dot(e[1:], e[:-1]) / max(float(e @ e), 1e-300), -0.99, 0.99))
        factor = (1 - rho * rho) / (1 - 2 * rho * math.cos(2 * math.pi * freq_hz * dt) + rho * rho)
    cov_all = white_var * factor * xtx_inv
    i1 = 1 + int(trend)
    # (a, b) of a cos + b sin → A = a − jb; quote at t0_s: rotate by −2πkf(start − t0_s)
    amps = coef[i1::2] - 1j * coef[i1 + 1::2]
    cycles = np.array([math.fmod(k * freq_hz * (start - t0_s), 1.0) for k in ks])
    amps = amps * np.exp(-2j * np.pi * cycles)
    jac = np.array([[1.0, 0.0], [0.0, -1.0]])  # (a, b) → (Re, Im) before rotation
    c, s = math.cos(-2 * math.pi * cycles[0]), math.sin(-2 * math.pi * cycles[0])
    rot = np.array([[c, -s], [s, c]]) @ jac
    cov = rot @ cov_all[i1:i1 + 2, i1:i1 + 2] @ rot.T
    a1 = complex(amps[0])
    mag = abs(a1)
    u = np.array([a1.real, a1.imag]) / mag if mag > 0 else np.array([1.0, 0.0])
    w = np.array([-u[1], u[0]])
    mag_std = math.sqrt(max(float(u @ cov @ u), 0.0))
    phase_std = math.degrees(math.sqrt(max(float(w @ cov @ w), 0.0)) / mag) if mag > 0 else math.inf
    harm = np.full(harmonics - 1, np.nan + 0j, dtype=complex)
    harm[:len(ks) - 1] = amps[1:]
    return SineFit(float(freq_hz), a1, cov, mag_std, phase_std, harm, float(coef[0]),
                   float(coef[1] / (stop - start)) if trend else 0.0, float(np.sqrt(np.mean(e * e))),
                   float(factor), (float(start), float(stop)), float(periods), int(t.size), float(t0_s))


@dataclass(frozen=True)
class FrfPoint:
    """The sensor's response at one frequency: ``h = A_y/A_ref`` (sensor unit per reference
    unit), ``mag``, ``phase_deg`` in (−180, 180] (lead positive), their standard uncertainties
    (first order: relative variances of the two fits add; valid for SNR ≫ 1), and both fits."""

    freq_hz: float
    h: complex
    mag: float
    phase_deg: float
    mag_std: float
    phase_std_deg: float
    ref_fit: SineFit
    y_fit: SineFit

    def to_dict(self) -> dict:
        return {"freq_hz": float(self.freq_hz), "h": _cplx(self.h), "mag": float(self.mag),
                "phase_deg": float(self.phase_deg), "mag_std": float(self.mag_std),
                "phase_std_deg": float(self.phase_std_deg), "ref_fit": self.ref_fit.to_dict(),
                "y_fit": self.y_fit.to_dict()}


def frf_point(t_ref, ref, t_y, y, freq_hz: float, *, harmonics: int = 3, trend: bool = False,
              skip_s: float = 0.0, min_periods: float = 1.0) -> FrfPoint:
    """Response of ``y`` (times ``t_y``, already on the reference clock) to the reference
    ``ref`` (times ``t_ref``) at ``freq_hz``, both fitted by :func:`sine_fit` over the same
    whole-period window inside their common span (after skipping ``skip_s`` s of settling)."""
    t_r, v_r, dt_r = check_record(t_ref, ref, "ref")
    t_s, v_s, dt_s = check_record(t_y, y, "y")
    if not (math.isfinite(skip_s) and skip_s >= 0):
        raise ValueError(f"skip_s {skip_s} must be a finite value ≥ 0")
    start = max(t_r[0], t_s[0]) + skip_s
    stop = min(t_r[-1] + dt_r, t_s[-1] + dt_s)
    if not stop > start:
        raise ValueError(f"the records share no time after skip_s: common span [{start:g}, {stop:g}) s")
    kw = dict(harmonics=harmonics, trend=trend, span_s=(start, stop), min_periods=min_periods, t0_s=start)
    fr = sine_fit(t_r, v_r, freq_hz, **kw)
    fy = sine_fit(t_s, v_s, freq_hz, **kw)
    if not fr.mag > 3 * fr.amplitude_std:
        raise ValueError(f"reference amplitude {fr.mag:g} at {freq_hz:g} Hz must exceed 3× its standard error "
                         f"{fr.amplitude_std:g}: the table's tone is not above its noise")
    h = fy.amplitude / fr.amplitude
    rel_mag_var = (fy.mag_std / fy.mag) ** 2 + (fr.mag_std / fr.mag) ** 2
    phase_std = math.hypot(fy.phase_std_deg, fr.phase_std_deg)
    return FrfPoint(float(freq_hz), complex(h), float(abs(h)), float(_wrap_deg(math.degrees(np.angle(h)))),
                    float(abs(h) * math.sqrt(rel_mag_var)), float(phase_std), fr, fy)


@dataclass
class FrfResult:
    """An FRF over the dwells, in the order given: arrays ``freq_hz``, complex ``h``, ``mag``,
    ``phase_deg``, ``mag_std``, ``phase_std_deg``, and the points themselves."""

    freq_hz: np.ndarray
    h: np.ndarray
    mag: np.ndarray
    phase_deg: np.ndarray
    mag_std: np.ndarray
    phase_std_deg: np.ndarray
    points: list = field(default_factory=list)

    @property
    def h_std(self) -> np.ndarray:
        """Per-component standard uncertainty of ``Re h``/``Im h``: the mean of the magnitude and
        tangential (|h|·σφ) variances, square-rooted."""
        return component_std(self.mag, self.mag_std, self.phase_std_deg)

    @property
    def weights(self) -> np.ndarray:
        """``1/h_std``: the ``weights`` argument of :func:`fit_transfer_function`."""
        return 1.0 / self.h_std

    def to_dict(self) -> dict:
        return {"freq_hz": self.freq_hz.tolist(), "h_re": self.h.real.tolist(), "h_im": self.h.imag.tolist(),
                "mag": self.mag.tolist(), "phase_deg": self.phase_deg.tolist(), "mag_std": self.mag_std.tolist(),
                "phase_std_deg": self.phase_std_deg.tolist(), "points": [p.to_dict() for p in self.points]}


def component_std(mag, mag_std, phase_std_deg) -> np.ndarray:
    """Per-component standard uncertainty of ``Re h``/``Im h`` from a magnitude ``mag`` with
    standard uncertainty ``mag_std`` and a phase uncertainty ``phase_std_deg`` (degrees): the
    mean of the magnitude and tangential (|h|·σφ) variances, square-rooted."""
    mag, mag_std, phase_std_deg = (np.asarray(a, dtype=float) for a in (mag, mag_std, phase_std_deg))
    return np.sqrt(0.5 * (mag_std ** 2 + (mag * np.radians(phase_std_deg)) ** 2))


def frf(dwells, **kwargs) -> FrfResult:
    """:func:`frf_point` over ``dwells``, each ``(t_ref, ref, t_y, y, freq_hz)``; ``kwargs`` as
    :func:`frf_point` takes them."""
    pts = [frf_point(*d, **kwargs) for d in dwells]
    if not pts:
        raise ValueError("no dwells: at least 1 is needed")

    def arr(name):
        return np.array([getattr(p, name) for p in pts])

    return FrfResult(arr("freq_hz"), arr("h").astype(complex), arr("mag"), arr("phase_deg"), arr("mag_std"),
                     arr("phase_std_deg"), pts)
