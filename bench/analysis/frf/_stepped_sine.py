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
    """A record's least-squares sine fit at one frequency: complex amplitude, harmonics and uncertainties.

    One record's sine fit at ``freq_hz`` (see module docstring for the convention).

    ``amplitude`` ``A₁`` (y unit, complex, phase at ``t0_s``), ``cov`` the 2×2 covariance of
    ``(Re A₁, Im A₁)``, ``mag_std`` and ``phase_std_deg`` the standard uncertainties of ``|A₁|``
    and ``arg A₁``; ``harmonics`` ``A₂ … A_H`` (NaN where not modelled), ``offset`` ``c``,
    ``trend_per_s`` ``d`` (0 if not fitted), ``residual_rms`` (y unit), ``noise_factor`` the
    residual's spectrum at ``f`` over its variance (1 for white noise), ``window_s`` the
    ``[start, stop)`` fitted, ``n_periods`` periods of ``f`` in it, ``n_samples`` samples used.

    Attributes
    ----------
    freq_hz : float
        The fitted tone's frequency f, in Hz.
    amplitude : complex
        A₁, in the unit of y: ``|A₁|`` the tone's amplitude, ``arg A₁`` its cosine phase at
        ``t0_s`` (rad; a lead is positive).
    cov : ndarray, shape (2, 2)
        Covariance of ``(Re A₁, Im A₁)``, in y unit² (autocorrelation-aware, module docstring).
    mag_std : float
        Standard uncertainty of ``|A₁|``, y unit.
    phase_std_deg : float
        Standard uncertainty of ``arg A₁``, in degrees (∞ when ``|A₁|`` is 0).
    harmonics : ndarray of complex, shape (harmonics − 1,)
        A₂ … A_H, y unit, same convention; NaN where not modelled (at or above Nyquist).
    offset : float
        The constant c, y unit.
    trend_per_s : float
        The linear term d, y unit per s (0 when not fitted).
    residual_rms : float
        RMS of the fit's residual over the window, y unit.
    noise_factor : float
        The residual's spectrum at f over its variance (1 for white noise); the factor the
        white-noise covariance was scaled by.
    window_s : tuple of float
        ``(start, stop)`` of the fitted window, in s.
    n_periods : float
        Periods of f in the window (whole, unless ``whole_periods=False``).
    n_samples : int
        Samples used.
    t0_s : float
        Time at which the phases are quoted, in s.
    mag : float
        Property: ``|A₁|``, y unit.
    phase_deg : float
        Property: ``arg A₁`` in degrees, wrapped to (−180, 180].
    amplitude_std : float
        Property: per-component standard error ``√(tr cov / 2)``, y unit.
    """

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
    """Least-squares fit of a tone and its harmonics in a record, with autocorrelation-aware standard errors.

    Linear least-squares sine fit of ``y`` at ``freq_hz`` and its harmonics (module docstring).

    ``t_s`` (s, strictly increasing, any clock the caller has aligned), ``y`` (any unit);
    ``harmonics`` ≥ 1 the number of multiples of ``f`` modelled (1 = the tone alone);
    ``trend`` adds a linear term (a drifting bias, a high-pass settling tail); ``span_s``
    ``(start, stop)`` restricts the fit (default the whole record); ``t0_s`` the time at which
    phases are quoted.  Needs ``0 < f < Nyquist`` of the samples and ``≥ min_periods`` periods.
    Model ``y ≈ c [+ d·(t − t_mid)] + Σₖ Re(Aₖ·e^{j2πkf(t − t0_s)})`` over the longest whole
    number of periods of the span (window rule and standard errors in the module docstring).

    Parameters
    ----------
    t_s : array_like, shape (N,)
        Sample times in s, finite and strictly increasing; N ≥ 4.
    y : array_like, shape (N,)
        The record, any unit, finite.
    freq_hz : float
        Tone frequency f in Hz, within (0, Nyquist) of the samples (0.5/median interval).
    harmonics : int, default 3
        Number of multiples of f modelled, an integer in [1, 20] (1 = the tone alone);
        those at or above Nyquist are left out.
    trend : bool, default False
        Add a linear term d (a drifting bias, a high-pass settling tail).
    span_s : tuple of float, optional
        ``(start, stop)`` in s, start < stop, restricting the fit; default from the first
        sample to the last plus one interval.
    whole_periods : bool, default True
        Cut the span to a whole number of periods from its start.
    min_periods : float, default 1.0
        Fewest periods of f the span must hold, > 0.
    t0_s : float, default 0.0
        Time, in s, at which the phases are quoted.

    Returns
    -------
    SineFit
        Complex amplitude A₁ with its covariance, magnitude and phase uncertainties, the
        harmonics, offset, trend and the fitted window.

    Raises
    ------
    ValueError
        If the record is not 1-D finite of one length ≥ 4 with increasing times;
        ``harmonics`` is not an integer in [1, 20]; ``freq_hz`` is outside (0, Nyquist);
        ``min_periods`` is not > 0; ``t0_s`` or ``span_s`` is not finite (or start ≥ stop);
        the span holds fewer than ``min_periods`` periods, or the window fewer than 8 samples
        more than the parameters.

    Examples
    --------
    >>> import numpy as np
    >>> from bench.analysis.frf import sine_fit
    >>> t = np.arange(2000) / 1000.0  # 2 s at 1 kHz
    >>> y = 0.5 + 2.0 * np.cos(2 * np.pi * 5.0 * t + 0.3) + 0.01 * np.random.default_rng(0).standard_normal(t.size)
    >>> f = sine_fit(t, y, 5.0)
    >>> round(f.mag, 3), round(f.phase_deg, 1), round(float(np.degrees(0.3)), 1)
    (2.0, 17.2, 17.2)
    >>> round(f.offset, 3), f.n_periods, f.n_samples
    (0.5, 10.0, 2000)
    >>> bool(abs(f.mag - 2.0) < 3 * f.mag_std)
    True
    """
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
    """A sensor's response to the reference at one frequency, with its uncertainties and both fits.

    The sensor's response at one frequency: ``h = A_y/A_ref`` (sensor unit per reference
    unit), ``mag``, ``phase_deg`` in (−180, 180] (lead positive), their standard uncertainties
    (first order: relative variances of the two fits add; valid for SNR ≫ 1), and both fits.

    Attributes
    ----------
    freq_hz : float
        The dwell's frequency, in Hz.
    h : complex
        Response ``A_y/A_ref``, sensor unit per reference unit.
    mag : float
        ``|h|``, sensor unit per reference unit.
    phase_deg : float
        ``arg h`` in degrees, in (−180, 180], a lead positive.
    mag_std : float
        Standard uncertainty of ``mag``, same unit.
    phase_std_deg : float
        Standard uncertainty of ``phase_deg``, in degrees.
    ref_fit : SineFit
        The reference's sine fit.
    y_fit : SineFit
        The sensor's sine fit (same window, same ``t0_s``).
    """

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
    """Response of a sensor to the reference at one stepped-sine frequency.

    ``y`` (times ``t_y``, already on the reference clock) against the reference ``ref``
    (times ``t_ref``) at ``freq_hz``, both fitted by :func:`sine_fit` over the same
    whole-period window inside their common span (after skipping ``skip_s`` s of settling).

    Parameters
    ----------
    t_ref : array_like, shape (N,)
        Reference sample times, in s (table clock), strictly increasing.
    ref : array_like, shape (N,)
        Reference record (e.g. table rate in °/s), finite.
    t_y : array_like, shape (M,)
        Sensor sample times, in s, already on the reference clock (:func:`apply_time_base`).
    y : array_like, shape (M,)
        Sensor record, any unit, finite.
    freq_hz : float
        The dwell's frequency, in Hz (within Nyquist of both records).
    harmonics : int, default 3
        Harmonics modelled in both fits, in [1, 20].
    trend : bool, default False
        Add a linear term to both fits.
    skip_s : float, default 0.0
        Settling time skipped at the start of the common span, in s; finite and ≥ 0.
    min_periods : float, default 1.0
        Fewest periods of f the window must hold, > 0.

    Returns
    -------
    FrfPoint
        ``h`` (sensor unit per reference unit), magnitude, phase (degrees) and their standard
        uncertainties, and both fits.

    Raises
    ------
    ValueError
        If a record is invalid (see :func:`sine_fit`), ``skip_s`` is negative or not finite,
        the records share no time after ``skip_s``, or the reference's amplitude does not
        exceed 3× its standard error.

    Examples
    --------
    A sensor with a gain of 0.9 and a 10° lag at 5 Hz:

    >>> import numpy as np
    >>> from bench.analysis.frf import frf_point
    >>> rng = np.random.default_rng(0)
    >>> t = np.arange(2000) / 1000.0
    >>> ref = np.sin(2 * np.pi * 5 * t) + 0.01 * rng.standard_normal(t.size)
    >>> y = 0.9 * np.sin(2 * np.pi * 5 * t - np.radians(10)) + 0.01 * rng.standard_normal(t.size)
    >>> p = frf_point(t, ref, t, y, 5.0)
    >>> round(p.mag, 2), round(p.phase_deg, 1)
    (0.9, -10.0)
    >>> bool(abs(p.mag - 0.9) < 3 * p.mag_std and abs(p.phase_deg + 10) < 3 * p.phase_std_deg)
    True
    """
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
    """A stepped-sine frequency response over its dwells.

    An FRF over the dwells, in the order given: arrays ``freq_hz``, complex ``h``, ``mag``,
    ``phase_deg``, ``mag_std``, ``phase_std_deg``, and the points themselves.

    Attributes
    ----------
    freq_hz : ndarray, shape (K,)
        Dwell frequencies, in Hz.
    h : ndarray of complex, shape (K,)
        Response at each, sensor unit per reference unit.
    mag : ndarray, shape (K,)
        ``|h|``, same unit.
    phase_deg : ndarray, shape (K,)
        ``arg h`` in degrees, in (−180, 180], a lead positive.
    mag_std : ndarray, shape (K,)
        Standard uncertainty of ``mag``.
    phase_std_deg : ndarray, shape (K,)
        Standard uncertainty of ``phase_deg``, in degrees.
    points : list of FrfPoint
        The points themselves, with both sine fits.
    h_std : ndarray, shape (K,)
        Property: per-component standard uncertainty of ``Re h``/``Im h``
        (:func:`component_std`).
    weights : ndarray, shape (K,)
        Property: ``1/h_std``, the ``weights`` argument of
        :func:`~bench.analysis.fusion.fit_transfer_function`.
    """

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
    """Per-component standard uncertainty of ``Re h``/``Im h`` from magnitude and phase uncertainties.

    From a magnitude ``mag`` with standard uncertainty ``mag_std`` and a phase uncertainty
    ``phase_std_deg`` (degrees): the mean of the magnitude and tangential (|h|·σφ) variances,
    square-rooted, ``√((σ_|h|² + (|h|·σφ)²)/2)``.

    Parameters
    ----------
    mag : array_like
        Magnitude ``|h|``, any unit.
    mag_std : array_like
        Its standard uncertainty, same unit (broadcast with ``mag``).
    phase_std_deg : array_like
        Standard uncertainty of the phase, in degrees.

    Returns
    -------
    ndarray
        Per-component standard uncertainty, in the unit of ``mag`` (the broadcast shape).

    Examples
    --------
    >>> import numpy as np
    >>> from bench.analysis.frf import component_std
    >>> component_std([1.0, 2.0], [0.01, 0.0], [0.0, 0.0]).round(6).tolist()
    [0.007071, 0.0]
    >>> float(component_std(1.0, 0.01, np.degrees(0.01)))  # equal radial and tangential parts
    0.01
    """
    mag, mag_std, phase_std_deg = (np.asarray(a, dtype=float) for a in (mag, mag_std, phase_std_deg))
    return np.sqrt(0.5 * (mag_std ** 2 + (mag * np.radians(phase_std_deg)) ** 2))


def frf(dwells, **kwargs) -> FrfResult:
    """Stepped-sine FRF: :func:`frf_point` over ``dwells``, each ``(t_ref, ref, t_y, y, freq_hz)``.

    ``kwargs`` as :func:`frf_point` takes them. The result feeds
    :func:`~bench.analysis.fusion.fit_transfer_function` (with ``weights=FrfResult.weights``).

    Parameters
    ----------
    dwells : iterable of tuple
        One ``(t_ref, ref, t_y, y, freq_hz)`` per dwell: times in s (the sensor's on the
        reference clock), records in their units, frequency in Hz; at least one.
    **kwargs
        ``harmonics``, ``trend``, ``skip_s``, ``min_periods`` as :func:`frf_point` takes them.

    Returns
    -------
    FrfResult
        Arrays over the dwells, in the order given (Hz, sensor unit per reference unit,
        degrees), and the points.

    Raises
    ------
    ValueError
        If there are no dwells, or a dwell fails :func:`frf_point`'s checks.

    Examples
    --------
    A first-order low-pass at 20 Hz measured at four frequencies:

    >>> import numpy as np
    >>> from bench.analysis.frf import frf
    >>> rng = np.random.default_rng(0)
    >>> t = np.arange(2000) / 1000.0
    >>> def dwell(f):
    ...     g = 1 / (1 + 1j * f / 20.0)
    ...     ref = np.sin(2 * np.pi * f * t) + 0.01 * rng.standard_normal(t.size)
    ...     y = abs(g) * np.sin(2 * np.pi * f * t + np.angle(g)) + 0.01 * rng.standard_normal(t.size)
    ...     return t, ref, t, y, f
    >>> r = frf([dwell(f) for f in (2.0, 5.0, 20.0, 50.0)])
    >>> r.mag.round(2).tolist(), r.phase_deg.round(0).tolist()
    ([0.99, 0.97, 0.71, 0.37], [-6.0, -14.0, -45.0, -68.0])
    >>> truth = 1 / (1 + 1j * r.freq_hz / 20.0)
    >>> bool(np.all(np.abs(r.h - truth) < 3 * r.h_std)), r.weights.shape
    (True, (4,))
    """
    pts = [frf_point(*d, **kwargs) for d in dwells]
    if not pts:
        raise ValueError("no dwells: at least 1 is needed")

    def arr(name):
        return np.array([getattr(p, name) for p in pts])

    return FrfResult(arr("freq_hz"), arr("h").astype(complex), arr("mag"), arr("phase_deg"), arr("mag_std"),
                     arr("phase_std_deg"), pts)
