"""Turn-on time and warm-up drift of a sensor from its start-up record (pure).

* **settled value** — mean of the output over the last ``settled_window_s`` of the record;
* **turn-on time** — time after power-on from which the output averaged over the preceding
  ``smooth_s`` (a causal moving average, as a meter averaging that long would show it; it
  lags an exponential by about ``smooth_s``/2) stays within ± ``band`` of the settled value
  (the first average's time, ``smooth_s``, when it never leaves the band);
* **warm-up drift** — change of the fitted start-up trend (Document A's exponential(s) +
  linear term, :func:`bench.analysis.startup._trend.fit_trend`) from ``smooth_s`` after power-on to the
  end of the record, with its standard error by the delta method.

Times in s from power-on (t = 0), output in any unit (band and drift in that unit).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bench.analysis.startup import TrendFit, fit_trend

_TREND_POINTS = 4000  # the trend is fitted to block means: the warm-up is slow, the noise is not


@dataclass(frozen=True, eq=False)
class TurnOnResult:
    """Turn-on time, settled value and warm-up drift of one start-up record.

    As :func:`turn_on_metrics` returns it (definitions in the module docstring). Times in s
    from power-on; every other figure in the unit of the record's output.

    Attributes
    ----------
    turn_on_time_s : float
        Time after power-on, in s, from which the causal ``smooth_s`` moving average stays
        within ± ``band`` of the settled value (the time of the first average when it never
        leaves the band: then an upper bound, ``resolved`` False).
    settled_value : float
        Mean output over the last ``settled_window_s`` of the record, output unit.
    band : float
        The band used, output unit.
    smooth_s : float
        The moving average's length used, in s.
    warmup_drift : float
        Change of the fitted start-up trend from ``smooth_s`` after power-on to the end of
        the record, output unit.
    warmup_drift_std : float or None
        Its standard error by the delta method, output unit; None when the trend's
        covariance is not usable.
    trend : TrendFit
        The start-up trend (exponential(s) + linear term) fitted to block means of the record
        (:func:`bench.analysis.startup.fit_trend`).
    smoothed_t_s : ndarray, shape (N − n + 1,)
        Times of the moving averages (the end of each window), in s.
    smoothed : ndarray, shape (N − n + 1,)
        The causal moving average of the output, output unit.
    resolved : bool
        False when the average never leaves the band: the output settled before the first full
        average could tell, so ``turn_on_time_s`` (the first average's time, ``smooth_s`` after
        the first sample) is an upper bound, not a measured time.
    """

    turn_on_time_s: float
    settled_value: float
    band: float
    smooth_s: float
    warmup_drift: float
    warmup_drift_std: float | None
    trend: TrendFit
    smoothed_t_s: np.ndarray
    smoothed: np.ndarray
    resolved: bool = True

    def to_dict(self) -> dict:
        return {"turn_on_time_s": self.turn_on_time_s, "resolved": self.resolved,
                "settled_value": self.settled_value,
                "band": self.band, "smooth_s": self.smooth_s, "warmup_drift": self.warmup_drift,
                "warmup_drift_std": self.warmup_drift_std, "trend": self.trend.to_dict()}


def _moving_average(y: np.ndarray, n: int) -> np.ndarray:
    c = np.concatenate([[0.0], np.cumsum(y)])
    return (c[n:] - c[:-n]) / n


def turn_on_metrics(t_s, y, *, band: float, smooth_s: float = 10.0,
                    settled_window_s: float = 300.0) -> TurnOnResult:
    """Turn-on time and warm-up drift of a sensor from its start-up record.

    The **settled value** is the mean output over the last ``settled_window_s``; the
    **turn-on time** the time after power-on from which the output averaged over the
    preceding ``smooth_s`` (a causal moving average, which lags an exponential by about
    ``smooth_s``/2) stays within ± ``band`` of it; the **warm-up drift** the change of the
    fitted start-up trend from ``smooth_s`` after power-on to the end of the record, with its
    delta-method standard error (module docstring).

    Parameters
    ----------
    t_s : array_like, shape (N,)
        Sample times in s from power-on (t = 0), finite and strictly increasing; N ≥ 64.
    y : array_like, shape (N,)
        The sensor's output, any unit, finite.
    band : float
        Half-width of the settling band, in the output's unit; > 0.
    smooth_s : float, default 10.0
        Length of the causal moving average, in s, from the sample interval to a quarter of
        the record.
    settled_window_s : float, default 300.0
        Trailing window the settled value is the mean of, in s, from ``smooth_s`` to half the
        record.

    Returns
    -------
    TurnOnResult
        Turn-on time (s), settled value, warm-up drift and its standard error (output unit),
        the fitted trend and the moving average.

    Raises
    ------
    ValueError
        If ``t_s`` and ``y`` are not 1-D of one length ≥ 64, not finite or not increasing;
        ``band`` is not > 0; ``smooth_s`` is outside [sample interval, record/4] or
        ``settled_window_s`` outside [``smooth_s``, record/2].

    Examples
    --------
    An exponential warm-up of 100 ppm with τ = 120 s and 1 ppm of noise, band ± 10 ppm: the
    exponential itself enters the band at τ·ln 10 = 276 s, its 10-s average a few s later.

    >>> import numpy as np
    >>> from bench.analysis.turn_on import turn_on_metrics
    >>> t = np.arange(0.0, 1200.0, 1.0)
    >>> y = 1.0 + 100e-6 * np.exp(-t / 120.0) + 1e-6 * np.random.default_rng(0).standard_normal(t.size)
    >>> r = turn_on_metrics(t, y, band=10e-6, smooth_s=10.0)
    >>> r.turn_on_time_s, round(r.settled_value, 5)
    (280.0, 1.0)
    >>> truth = 100e-6 * (np.exp(-1199 / 120) - np.exp(-10 / 120))
    >>> bool(abs(r.warmup_drift - truth) < 3 * r.warmup_drift_std)
    True
    """
    t = np.asarray(t_s, dtype=float)
    y = np.asarray(y, dtype=float)
    if t.ndim != 1 or t.shape != y.shape or t.size < 64:
        raise ValueError(f"t_s and y must be 1-D of one length ≥ 64, got shapes {t.shape}, {y.shape}")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(y))):
        raise ValueError("t_s and y must be finite")
    dt = np.diff(t)
    if np.any(dt <= 0):
        raise ValueError("t_s must be strictly increasing")
    step = float(np.median(dt))
    span = float(t[-1] - t[0])
    if not (isinstance(band, (int, float)) and math.isfinite(band) and band > 0):
        raise ValueError(f"band = {band!r} must be a positive number (output units)")
    if not step <= smooth_s <= span / 4:
        raise ValueError(f"smooth_s = {smooth_s!r} not in {step:g}..{span / 4:g} s "
                         "(sample interval..a quarter of the record)")
    if not smooth_s <= settled_window_s <= span / 2:
        raise ValueError(f"settled_window_s = {settled_window_s!r} not in {smooth_s:g}..{span / 2:g} s")
    settled = float(np.mean(y[t >= t[-1] - settled_window_s]))
    n = max(1, int(round(smooth_s / step)))
    smooth = _moving_average(y, n)
    ts = t[n - 1:]  # a moving average is known at the end of its window
    outside = np.flatnonzero(np.abs(smooth - settled) > band)
    # never outside: within the band from the first average there is (smooth_s after power-on)
    turn_on = float(ts[0]) if outside.size == 0 else float(ts[outside[-1]] + step)
    # Trend on block means: the same fit as the start-up analysis, at a fraction of the cost.
    k = max(1, y.size // _TREND_POINTS)
    m = y.size // k
    tb = t[: m * k].reshape(m, k).mean(axis=1)
    yb = y[: m * k].reshape(m, k).mean(axis=1)
    trend = fit_trend(tb, yb)
    t1, t2 = max(float(t[0]), smooth_s), float(t[-1])
    drift = float(trend.evaluate(np.array([t2]))[0] - trend.evaluate(np.array([t1]))[0])
    drift_std = _drift_std(trend, t1, t2)
    return TurnOnResult(turn_on, settled, float(band), float(smooth_s), drift, drift_std, trend,
                        ts, smooth, resolved=bool(outside.size))


def _drift_std(trend: TrendFit, t1: float, t2: float) -> float | None:
    """Delta-method standard error of trend(t2) − trend(t1) (numerical gradient)."""
    names = trend.param_names
    values = np.array([getattr(trend, n).value for n in names])
    cov = np.asarray(trend.covariance, dtype=float)
    if cov.shape != (len(names), len(names)) or not np.all(np.isfinite(cov)):
        return None

    def drift(theta: np.ndarray) -> float:
        p = dict(zip(names, theta))
        u1, u2 = t1 - trend.t0_s, t2 - trend.t0_s
        out = p["exp_amplitude"] * (math.exp(-u2 / p["exp_tau_s"]) - math.exp(-u1 / p["exp_tau_s"]))
        if "exp2_amplitude" in p:
            out += p["exp2_amplitude"] * (math.exp(-u2 / p["exp2_tau_s"]) - math.exp(-u1 / p["exp2_tau_s"]))
        return out + p["linear_slope_per_s"] * (u2 - u1)

    grad = np.empty(len(names))
    for i, v in enumerate(values):
        h = 1e-6 * max(abs(v), 1e-12)
        up, dn = values.copy(), values.copy()
        up[i] += h
        dn[i] -= h
        grad[i] = (drift(up) - drift(dn)) / (2 * h)
    var = float(grad @ cov @ grad)
    return math.sqrt(var) if var >= 0 and math.isfinite(var) else None
