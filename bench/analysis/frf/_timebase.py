"""Time alignment of sensors whose sample clocks are not the angular table's.

**Clock model.**  A sensor sample stamped ``t_y`` on its own (nominal) clock was taken at
reference (table-clock) time ``t ≈ t_y + offset_s + rate_ppm·10⁻⁶·(t_y − epoch_s)``.  A positive
``rate_ppm`` means the sensor's clock runs slow (its stamps fall increasingly behind).

:func:`estimate_time_base` fits both records by :func:`~bench.analysis.frf._stepped_sine.sine_fit` at the tone
``f`` in consecutive whole-period blocks; the phase of ``A_y/A_ref`` in block ``k`` is
``φₖ = 2πf·δ(tₖ) + arg G(f)`` with ``δ`` the clock correction above and ``G`` the sensor's
response.  A weighted straight line through the unwrapped ``φₖ`` (weights from the fits'
phase uncertainties) gives ``rate = slope/(2πf)`` and ``offset = φ(epoch)/(2πf)``, with
``epoch_s`` the weighted mean block time so that the two are uncorrelated.  Standard errors
are the line fit's, inflated by ``√χ²_red`` when the blocks scatter more than their fits say.

**What the offset is.** At one frequency a clock offset, a constant latency and the sensor's own
phase all shift ``φ`` alike: the reported ``offset_s`` is the clock offset *minus the sensor's
phase delay* ``−arg G(f)/(2πf)`` at ``f`` (a pure latency ``τ`` contributes ``−τ``), and is known
only modulo ``1/f`` (quoted in ``(−1/2f, 1/2f]``).  The procedure therefore corrects only the
rate (:func:`apply_time_base` leaves the offset out by default) and leaves latency to the FRF's
delay fit (``fit_transfer_function(..., fit_delay=True)``).

**Unwrapping.** The coarse slope is the median of the wrapped block-to-block phase steps, the
phases are unwrapped about that line, then fitted.  This holds while the drift per block is
below half a cycle, ``|rate|·f·block < 0.5`` (e.g. 100 ppm at 10 Hz: blocks up to 500 s), and
the per-block phase noise is well below π.

:func:`resample` puts one record onto another's time grid (the LF frames and the reference
onto the HF grid) — see its docstring for the error at the frequencies that matter.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.special import i0

from bench.analysis.frf._stepped_sine import check_record, sine_fit

SINC_HALF_WIDTH = 16  # taps each side of the band-limited interpolator
KAISER_BETA = 10.0  # its Kaiser window's shape: passband ripple ≈ 10⁻⁵ to f/fs = 0.4 (measured, see resample)
RESAMPLE_METHODS = ("sinc", "cubic")


@dataclass(frozen=True)
class TimeBase:
    """A sensor clock's rate error and apparent offset against the reference clock.

    A sensor clock against the reference (module docstring): ``rate_ppm`` ± ``rate_std_ppm``,
    ``offset_s`` ± ``offset_std_s`` (apparent: clock offset minus the phase delay at ``freq_hz``,
    modulo ``1/freq_hz``), at ``epoch_s``; from ``n_blocks`` blocks of ``block_s`` whose phases
    scatter ``phase_residual_rms_deg`` about the line (``chi2_reduced`` against their σ).

    Attributes
    ----------
    freq_hz : float
        The tone used, in Hz.
    rate_ppm : float
        Clock rate error, in ppm (positive: the sensor's clock runs slow).
    rate_std_ppm : float
        Its standard error, in ppm.
    offset_s : float
        Apparent offset at ``epoch_s``, in s: clock offset minus the sensor's phase delay at
        ``freq_hz``, quoted in (−1/2f, 1/2f].
    offset_std_s : float
        Its standard error, in s.
    epoch_s : float
        The weighted mean block time, in s (sensor clock), where rate and offset are
        uncorrelated.
    n_blocks : int
        Number of blocks fitted.
    block_s : float
        Block length used, in s (a whole number of periods).
    phase_residual_rms_deg : float
        RMS of the block phases about the line, in degrees.
    chi2_reduced : float
        χ² per degree of freedom of the line against the blocks' phase σ (standard errors
        are inflated by √χ²_red when > 1).
    """

    freq_hz: float
    rate_ppm: float
    rate_std_ppm: float
    offset_s: float
    offset_std_s: float
    epoch_s: float
    n_blocks: int
    block_s: float
    phase_residual_rms_deg: float
    chi2_reduced: float

    def to_dict(self) -> dict:
        return {k: (int(v) if k == "n_blocks" else float(v)) for k, v in self.__dict__.items()}


def estimate_time_base(t_ref, ref, t_y, y, freq_hz: float, block_s: float, *, harmonics: int = 3) -> TimeBase:
    """Rate error and apparent offset of a sensor's clock against the reference clock.

    The clock stamping ``t_y`` relative to the clock of ``t_ref``, from the tone at
    ``freq_hz`` (Hz) in consecutive blocks of ``block_s`` (s; rounded to a whole number of
    periods, at least one) over the records' common span; needs ≥ 3 blocks. A weighted line
    through the unwrapped block phases of ``A_y/A_ref`` gives ``rate = slope/(2πf)`` and
    ``offset = φ(epoch)/(2πf)`` (clock model, unwrapping limits and what the offset holds: module
    docstring).

    Parameters
    ----------
    t_ref : array_like, shape (N,)
        Reference sample times, in s, strictly increasing.
    ref : array_like, shape (N,)
        Reference record carrying the tone, finite.
    t_y : array_like, shape (M,)
        Sensor sample stamps on its own clock, in s, strictly increasing.
    y : array_like, shape (M,)
        Sensor record, any unit, finite.
    freq_hz : float
        The tone's frequency, in Hz; finite and > 0.
    block_s : float
        Block length, in s (finite, > 0), rounded to a whole number of periods (at least one);
        keep ``|rate|·f·block < 0.5``.
    harmonics : int, default 3
        Harmonics modelled in each block's sine fits, in [1, 20].

    Returns
    -------
    TimeBase
        Rate error (ppm) and apparent offset (s) with standard errors, the epoch (s) and the
        line's fit statistics.

    Raises
    ------
    ValueError
        If a record is invalid (see :func:`sine_fit`), ``freq_hz`` or ``block_s`` is not a
        finite value > 0, or the common span holds fewer than 3 blocks.

    Examples
    --------
    A sensor clock running 50 ppm slow, seen through a 10 Hz tone over 20 s:

    >>> import numpy as np
    >>> from bench.analysis.frf import apply_time_base, estimate_time_base
    >>> t = np.arange(20000) / 1000.0  # both records stamped at 1 kHz, each on its own clock
    >>> ref = np.sin(2 * np.pi * 10 * t)
    >>> t_true = t * (1 + 50e-6)  # when the sensor's samples were really taken
    >>> y = np.sin(2 * np.pi * 10 * t_true) + 0.001 * np.random.default_rng(0).standard_normal(t.size)
    >>> tb = estimate_time_base(t, ref, t, y, 10.0, 2.0)
    >>> round(tb.rate_ppm, 1), tb.n_blocks
    (50.0, 10)
    >>> bool(abs(tb.rate_ppm - 50.0) < 3 * tb.rate_std_ppm)
    True
    """
    t_r, v_r, dt_r = check_record(t_ref, ref, "ref")
    t_s, v_s, dt_s = check_record(t_y, y, "y")
    if not (math.isfinite(freq_hz) and freq_hz > 0):
        raise ValueError(f"freq_hz {freq_hz} must be a finite value > 0")
    if not (math.isfinite(block_s) and block_s > 0):
        raise ValueError(f"block_s {block_s} must be a finite value > 0")
    block = max(1, round(block_s * freq_hz)) / freq_hz
    start = max(t_r[0], t_s[0])
    stop = min(t_r[-1] + dt_r, t_s[-1] + dt_s)
    n_blocks = int(math.floor((stop - start) / block + 1e-9)) if stop > start else 0
    if n_blocks < 3:
        raise ValueError(f"common span {max(stop - start, 0):g} s holds {n_blocks} blocks of {block:g} s; "
                         "at least 3 are needed")
    tk, phi, var = np.empty(n_blocks), np.empty(n_blocks), np.empty(n_blocks)
    for k in range(n_blocks):
        b0 = start + k * block
        span = (b0, b0 + block)
        fits = []
        for t, v, dt in ((t_r, v_r, dt_r), (t_s, v_s, dt_s)):
            i, j = np.searchsorted(t, [span[0] - dt, span[1] + dt])  # slice first: blocks are short
            fits.append(sine_fit(t[i:j], v[i:j], freq_hz, harmonics, span_s=span, t0_s=start))
        fr, fy = fits
        tk[k] = b0 + 0.5 * block
        phi[k] = np.angle(fy.amplitude / fr.amplitude)
        var[k] = math.radians(fy.phase_std_deg) ** 2 + math.radians(fr.phase_std_deg) ** 2
    # coarse slope from the wrapped steps, unwrap about that line, then the weighted line fit
    steps = np.angle(np.exp(1j * np.diff(phi)))
    slope0 = float(np.median(steps)) / block
    psi = phi - slope0 * (tk - tk[0])
    centre = float(np.angle(np.sum(np.exp(1j * psi))))
    phi_u = centre + np.angle(np.exp(1j * (psi - centre))) + slope0 * (tk - tk[0])
    w = 1.0 / np.maximum(var, 1e-30)
    epoch = float(np.sum(w * tk) / np.sum(w))
    x = tk - epoch
    sxx = float(np.sum(w * x * x))
    slope = float(np.sum(w * x * phi_u) / sxx)
    icpt = float(np.sum(w * phi_u) / np.sum(w))
    res = phi_u - icpt - slope * x
    chi2 = float(np.sum(w * res * res) / (n_blocks - 2)) if n_blocks > 2 else 1.0
    infl = math.sqrt(max(1.0, chi2))
    two_pi_f = 2 * math.pi * freq_hz
    offset = float(np.angle(np.exp(1j * icpt))) / two_pi_f
    return TimeBase(float(freq_hz), slope / two_pi_f * 1e6, infl / math.sqrt(sxx) / two_pi_f * 1e6, offset,
                    infl / math.sqrt(float(np.sum(w))) / two_pi_f, epoch, n_blocks, float(block),
                    math.degrees(float(np.sqrt(np.mean(res * res)))), chi2)


def apply_time_base(t_y, tb: TimeBase, include_offset: bool = False, epoch_s: float | None = None) -> np.ndarray:
    """Sensor timestamps ``t_y`` (s) mapped onto the reference clock.

    ``t_y + rate_ppm·10⁻⁶·(t_y − epoch)`` (+ ``offset_s`` if ``include_offset``; by default
    the offset, which holds the sensor's own phase delay, is left to the FRF's delay fit).
    ``epoch`` is ``tb.epoch_s`` unless ``epoch_s`` names the stamp at which the sensor's clock
    is known to agree with the reference (e.g. the trigger that starts each of its traces).

    Parameters
    ----------
    t_y : array_like
        Sensor timestamps on its own clock, in s; finite.
    tb : TimeBase
        The clock's rate (and offset) from :func:`estimate_time_base`.
    include_offset : bool, default False
        Add ``tb.offset_s`` too.
    epoch_s : float, optional
        Stamp, in s, at which the two clocks agree; default ``tb.epoch_s``.

    Returns
    -------
    ndarray
        The timestamps on the reference clock, in s, shaped as ``t_y``.

    Raises
    ------
    ValueError
        If ``t_y`` or ``epoch_s`` is not finite.

    Examples
    --------
    >>> import numpy as np
    >>> from bench.analysis.frf import TimeBase, apply_time_base
    >>> tb = TimeBase(10.0, 50.0, 0.3, 0.0, 1e-6, 0.0, 10, 2.0, 0.002, 1.0)  # 50 ppm slow
    >>> apply_time_base(np.array([0.0, 10.0, 20.0]), tb).round(6).tolist()
    [0.0, 10.0005, 20.001]
    >>> apply_time_base(np.array([10.0]), tb, epoch_s=10.0).tolist()  # the clocks agree at 10 s
    [10.0]
    """
    t = np.asarray(t_y, dtype=float)
    if not np.all(np.isfinite(t)):
        raise ValueError("t_y must be finite")
    epoch = tb.epoch_s if epoch_s is None else float(epoch_s)
    if not math.isfinite(epoch):
        raise ValueError(f"epoch_s {epoch_s} must be finite")
    out = t + tb.rate_ppm * 1e-6 * (t - epoch)
    return out + tb.offset_s if include_offset else out


def _kaiser_sinc(x: np.ndarray, half_width: int, beta: float) -> np.ndarray:
    r = np.clip(x / half_width, -1.0, 1.0)
    return np.sinc(x) * i0(beta * np.sqrt(1.0 - r * r)) / i0(beta)


def resample(t_src, y_src, t_dst, method: str = "sinc", *, half_width: int = SINC_HALF_WIDTH,
             beta: float = KAISER_BETA) -> np.ndarray:
    """A band-limited record resampled at other times (windowed sinc or cubic spline).

    Values of the band-limited record ``(t_src, y_src)`` at times ``t_dst`` (s), all inside
    ``[t_src[0], t_src[-1]]`` (no extrapolation).

    ``"sinc"`` (default; needs a uniform source grid, as the LF frames and a rate-corrected
    clock are): Kaiser-windowed sinc interpolation (``half_width`` taps each side, shape
    ``beta``), weights normalised to sum 1 (a constant passes exactly).  Destination times
    within ``half_width`` intervals of either end, where the kernel would run off the record,
    take the cubic spline instead.  Largest error on a unit sine at ``f`` sampled at ``fs``
    (defaults; measured, checked in the tests): < 2·10⁻⁵ for ``f/fs ≤ 0.4`` away from the
    ends (0.1 at 0.45: the kernel's transition band), no phase bias (symmetric kernel); at the
    ends the spline's 10⁻⁵ at 0.02, 3·10⁻³ at 0.1, 0.07 at 0.25, ~1 at 0.4 (trim them).
    ``"cubic"`` (any increasing grid): not-a-knot cubic spline, error growing as ``(f/fs)⁴``:
    ≈ 10⁻⁶ at 0.02, 5·10⁻⁴ at 0.1, 0.025 at 0.25, 0.3 at 0.4 (measured) — fine for the
    reference at 10 kHz below 200 Hz, not for the 2 kHz LF frames above ~100 Hz.  Neither
    restores what the source's own sampling removed: an interval-mean frame's ``sinc(f/fs)``
    roll-off stays in the resampled series (``procedures/frf.py`` divides it out of the
    measured FRF; :func:`aperture_compensate` undoes such a droop on a series).

    Parameters
    ----------
    t_src : array_like, shape (N,)
        Source sample times, in s, strictly increasing; uniform within 1 % of the interval for
        ``"sinc"``.
    y_src : array_like, shape (N,)
        Source values, any unit, finite; N ≥ ``half_width`` + 2 for ``"sinc"``.
    t_dst : array_like
        Destination times, in s, finite, within ``[t_src[0], t_src[-1]]``.
    method : {"sinc", "cubic"}, default "sinc"
        Kaiser-windowed sinc (uniform grid) or not-a-knot cubic spline (any grid).
    half_width : int, default 16
        Taps each side of the sinc kernel, an integer in [2, 64].
    beta : float, default 10.0
        The Kaiser window's shape, in [0, 20].

    Returns
    -------
    ndarray
        Values at ``t_dst``, in the unit of ``y_src``, shaped as ``t_dst``.

    Raises
    ------
    ValueError
        If the source record is invalid (fewer than 4 samples, not finite, times not
        increasing), ``method`` is unknown, ``t_dst`` is not finite or reaches outside the
        source (no extrapolation), ``half_width`` is not an integer in [2, 64], ``beta`` is
        outside [0, 20], or for ``"sinc"`` the source grid is not uniform within 1 % or too short.

    Examples
    --------
    A 50 Hz sine sampled at 1 kHz (f/fs = 0.05), read between its samples:

    >>> import numpy as np
    >>> from bench.analysis.frf import resample
    >>> t = np.arange(200) * 1e-3
    >>> y = np.sin(2 * np.pi * 50 * t)
    >>> t_dst = np.array([0.0505, 0.1002])
    >>> bool(np.max(np.abs(resample(t, y, t_dst) - np.sin(2 * np.pi * 50 * t_dst))) < 2e-5)
    True
    >>> resample(t, y, t_dst, "cubic").shape
    (2,)
    """
    t, v, _ = check_record(t_src, y_src, "y_src")
    td = np.asarray(t_dst, dtype=float)
    if method not in RESAMPLE_METHODS:
        raise ValueError(f"method {method!r} must be one of {', '.join(RESAMPLE_METHODS)}")
    if not np.all(np.isfinite(td)):
        raise ValueError("t_dst must be finite")
    span = t[-1] - t[0]
    tol = 1e-9 * span
    if td.size and (td.min() < t[0] - tol or td.max() > t[-1] + tol):
        raise ValueError(f"t_dst [{td.min():g}, {td.max():g}] s must lie within the source's "
                         f"[{t[0]:g}, {t[-1]:g}] s (no extrapolation)")
    if method == "cubic":
        return CubicSpline(t, v)(td)
    if not (isinstance(half_width, (int, np.integer)) and 2 <= half_width <= 64):
        raise ValueError(f"half_width {half_width} must be an integer in [2, 64]")
    if not (math.isfinite(beta) and 0 <= beta <= 20):
        raise ValueError(f"beta {beta} must be in [0, 20]")
    n = t.size
    dt = span / (n - 1)
    dev = float(np.max(np.abs(t - (t[0] + dt * np.arange(n)))))
    if dev > 0.01 * dt:
        raise ValueError(f"t_src deviates {dev:g} s from a uniform grid; it must be within 1 % of the "
                         f"{dt:g} s interval for method 'sinc' (use method 'cubic')")
    if n < half_width + 2:
        raise ValueError(f"y_src has {n} samples; at least {half_width + 2} are needed for method 'sinc'")
    k = half_width
    pad = np.concatenate([2 * v[0] - v[k:0:-1], v, 2 * v[-1] - v[-2:-k - 2:-1]])
    u = (td.ravel() - t[0]) / dt
    out = np.empty(u.size)
    offs = np.arange(-k + 1, k + 1)
    for c0 in range(0, u.size, 1 << 15):  # chunks bound the (chunk × 2k) weight matrix
        uc = u[c0:c0 + (1 << 15)]
        base = np.floor(uc).astype(np.int64)
        idx = base[:, None] + offs[None, :]
        wts = _kaiser_sinc(uc[:, None] - idx, k, beta)
        out[c0:c0 + uc.size] = np.sum(wts * pad[idx + k], axis=1) / np.sum(wts, axis=1)
    edge = (u < k) | (u > n - 1 - k)  # kernel would reach past the record: the spline is better there
    if np.any(edge):
        out[edge] = CubicSpline(t, v)(td.ravel()[edge])
    return out.reshape(td.shape)


def aperture_compensate(y, aperture_s: float, interval_s: float) -> np.ndarray:
    """Undo the sinc droop of readings that are interval means (a DMM's aperture, a frame's interval).

    Undo the droop of readings that are means over ``aperture_s`` taken every
    ``interval_s`` (a DMM's aperture, a frame's interval): the mean's response
    sinc(f·T) ≈ 1 − (2πfT)²/24 is cancelled to second order by the symmetric 3-tap filter
    ``y − c·(y[n−1] − 2y[n] + y[n+1])`` with ``c = (T/Ts)²/24`` (response 1 + c(2πfTs)²).
    Residual error O((2πfT)⁴): 1·10⁻⁴ at f·T = 0.08.  The end samples are left as they are.
    Offline only: it looks one sample ahead.

    Parameters
    ----------
    y : array_like, shape (N,)
        The readings (interval means) in time order, any unit; N ≥ 3.
    aperture_s : float
        Averaging time T of each reading, in s, in (0, ``interval_s``].
    interval_s : float
        Time Ts between readings, in s.

    Returns
    -------
    ndarray, shape (N,)
        The readings with the droop undone, same unit; the first and last as given.

    Raises
    ------
    ValueError
        If ``aperture_s`` is not in (0, ``interval_s``] (or either is not finite), or ``y`` is
        not 1-D with at least 3 samples.

    Examples
    --------
    Means over whole intervals of a sine at f·T = 0.05 droop by 0.4 %; compensated, 5·10⁻⁵:

    >>> import numpy as np
    >>> from bench.analysis.frf import aperture_compensate
    >>> n, f = np.arange(200), 0.05  # f in cycles per interval
    >>> x = np.sin(2 * np.pi * f * n)
    >>> means = (np.cos(2 * np.pi * f * (n - 0.5)) - np.cos(2 * np.pi * f * (n + 0.5))) / (2 * np.pi * f)
    >>> round(float(np.max(np.abs(means - x))), 4)
    0.0041
    >>> bool(np.max(np.abs(aperture_compensate(means, 1.0, 1.0) - x)[1:-1]) < 1e-4)
    True
    """
    y = np.asarray(y, dtype=float)
    if not (math.isfinite(aperture_s) and math.isfinite(interval_s) and 0 < aperture_s <= interval_s):
        raise ValueError(f"aperture_s {aperture_s!r} must be in (0, interval_s = {interval_s!r}] s")
    if y.ndim != 1 or y.size < 3:
        raise ValueError(f"y must be 1-D with at least 3 samples (has shape {y.shape})")
    c = (aperture_s / interval_s) ** 2 / 24.0
    out = y.copy()
    out[1:-1] -= c * (y[:-2] - 2.0 * y[1:-1] + y[2:])
    return out
