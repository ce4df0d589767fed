"""Thermal soak: when is a unit's own temperature stable enough to measure?

A sweep soaks at each set point until the *unit's* temperature sensor says the unit has
settled, not for a fixed time. The criterion, over the trailing ``window_s`` of the
sensor's readings (all taken after ``start_s``, the time the new set point was commanded,
so a unit still sitting stably at the previous temperature never passes):

* **rate**: |slope| of the least-squares line through the window ≤ ``max_rate_c_per_min``;
* **spread**: max − min of the readings in the window ≤ ``band_c`` (choose it above the
  sensor's own peak-to-peak noise);
* **target** (optional): |mean − ``target_c``| ≤ ``target_tolerance_c``, so a unit stable
  at the wrong temperature (a chamber that never got there) does not pass;
* at least ``min_samples`` readings in the window.

The **soak time** is from ``start_s`` to the first time all hold (the end of that first
good window, so it is never shorter than ``window_s``).

Two entry points, both pure: :func:`soak_status` judges the series so far at its last
reading and reads only the trailing window (a procedure polling the sensor calls it after
each reading: O(window) per call); :func:`find_soak` scans a whole record for the first
time the criterion held.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bench.analysis._checks import check_int, check_real
from bench.analysis.thermal._inputs import TEMPERATURE_LIMITS_C


@dataclass(frozen=True)
class SoakCriterion:
    """When a unit counts as soaked: rate, spread and (optionally) target limits over a trailing window.

    Stability criterion (module docstring). Ranges: ``window_s`` (0, 86400];
    ``max_rate_c_per_min`` (0, 10]; ``band_c`` (0, 20]; ``min_samples`` 3 … 10⁶;
    ``target_c`` None or −100 … 200; ``target_tolerance_c`` (0, 50].

    Parameters
    ----------
    window_s : float, default 600.0
        Trailing window judged, in s, in (0, 86400].
    max_rate_c_per_min : float, default 0.05
        Largest |slope| of the window's least-squares line, in °C/min, in (0, 10].
    band_c : float, default 0.2
        Largest max − min of the readings in the window, in °C, in (0, 20]; choose it above
        the sensor's own peak-to-peak noise.
    min_samples : int, default 10
        Fewest readings in the window, 3 … 10⁶.
    target_c : float, optional
        Temperature the window's mean must be near, in °C (−100 … 200); None: no target.
    target_tolerance_c : float, default 2.0
        Largest |mean − target_c|, in °C, in (0, 50].

    Raises
    ------
    ValueError
        If a field is outside its range (the message names it).
    """

    window_s: float = 600.0
    max_rate_c_per_min: float = 0.05
    band_c: float = 0.2
    min_samples: int = 10
    target_c: float | None = None
    target_tolerance_c: float = 2.0

    def __post_init__(self) -> None:
        check_real("window_s", self.window_s, 0.0, 86400.0, low_open=True)
        check_real("max_rate_c_per_min", self.max_rate_c_per_min, 0.0, 10.0, low_open=True)
        check_real("band_c", self.band_c, 0.0, 20.0, low_open=True)
        check_int("min_samples", self.min_samples, 3, 1_000_000)
        if self.target_c is not None:
            check_real("target_c", self.target_c, *TEMPERATURE_LIMITS_C)
        check_real("target_tolerance_c", self.target_tolerance_c, 0.0, 50.0, low_open=True)


@dataclass(frozen=True)
class SoakStatus:
    """A soak criterion judged at one reading: stable or not, the window's figures and why.

    The criterion judged at ``t_s`` over the window ending there. ``reason`` says why it
    is not stable (empty when it is); the figures are None until the window is covered.

    Attributes
    ----------
    stable : bool
        Every condition of the criterion holds.
    t_s : float
        Time of the reading judged (the window's end), in s.
    rate_c_per_min : float or None
        Slope of the window's least-squares line, in °C/min.
    spread_c : float or None
        Max − min of the readings in the window, in °C.
    mean_c : float or None
        Mean of the readings in the window, in °C.
    samples : int
        Readings in the window (0 until the window is covered).
    reason : str
        Why it is not stable, conditions joined by ``"; "``; empty when stable.
    """

    stable: bool
    t_s: float
    rate_c_per_min: float | None
    spread_c: float | None
    mean_c: float | None
    samples: int
    reason: str


@dataclass(frozen=True)
class SoakResult:
    """First time a soak criterion held in a record, and the soak time from the start.

    Returned by :func:`find_soak`: ``stable_at_s`` (None: never) and ``soak_time_s`` =
    stable_at_s − start_s; ``final`` is the status at the last reading.

    Attributes
    ----------
    stable : bool
        The criterion held at some reading of the record.
    start_s : float
        When the set point was commanded, in s (the soak time counts from here).
    stable_at_s : float or None
        Time of the first reading at which the criterion held (the end of that first good
        window), in s; None when it never held.
    soak_time_s : float or None
        ``stable_at_s − start_s``, in s (never shorter than the window); None when it never held.
    criterion : SoakCriterion
        The criterion judged.
    final : SoakStatus
        The criterion judged at the record's last reading.
    """

    stable: bool
    start_s: float
    stable_at_s: float | None
    soak_time_s: float | None
    criterion: SoakCriterion
    final: SoakStatus


def _series(t_s, temp_c) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(t_s, dtype=float)
    y = np.asarray(temp_c, dtype=float)
    if t.ndim != 1 or t.shape != y.shape or t.size == 0:
        raise ValueError(f"t_s and temp_c must be 1-D of one length ≥ 1, got shapes {t.shape} and {y.shape}")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(y))):
        raise ValueError("t_s and temp_c must be finite")
    if t.size > 1 and np.any(np.diff(t) <= 0):
        i = int(np.flatnonzero(np.diff(t) <= 0)[0])
        raise ValueError(f"t_s must be strictly increasing: t_s[{i + 1}] = {float(t[i + 1])!r} "
                         f"≤ t_s[{i}] = {float(t[i])!r}")
    lo, hi = TEMPERATURE_LIMITS_C
    if np.any((y < lo) | (y > hi)):
        i = int(np.flatnonzero((y < lo) | (y > hi))[0])
        raise ValueError(f"temp_c[{i}] = {float(y[i])!r} outside the allowed range [{lo:g}, {hi:g}] °C")
    return t, y


def _judge(t: np.ndarray, y: np.ndarray, end: int, start_s: float, c: SoakCriterion) -> SoakStatus:
    """The criterion over the window ending at reading ``end`` (inclusive)."""
    t_end = float(t[end])
    if t_end - start_s < c.window_s:
        return SoakStatus(False, t_end, None, None, None, 0,
                          f"window not yet covered: {t_end - start_s:.6g} of {c.window_s:.6g} s since start")
    first = int(np.searchsorted(t, t_end - c.window_s, side="left"))
    tw, yw = t[first:end + 1], y[first:end + 1]
    n = tw.size
    if n < c.min_samples:
        return SoakStatus(False, t_end, None, None, None, n,
                          f"{n} readings in the window, {c.min_samples} needed")
    u = tw - tw.mean()
    rate = float(60.0 * (u @ (yw - yw.mean())) / (u @ u))
    spread = float(yw.max() - yw.min())
    mean = float(yw.mean())
    reasons = []
    if abs(rate) > c.max_rate_c_per_min:
        reasons.append(f"rate {rate:.4g} °C/min beyond ±{c.max_rate_c_per_min:g}")
    if spread > c.band_c:
        reasons.append(f"spread {spread:.4g} °C > band {c.band_c:g}")
    if c.target_c is not None and abs(mean - c.target_c) > c.target_tolerance_c:
        reasons.append(f"mean {mean:.4g} °C not within {c.target_tolerance_c:g} of target {c.target_c:g}")
    return SoakStatus(not reasons, t_end, rate, spread, mean, n, "; ".join(reasons))


def _start(t: np.ndarray, start_s) -> float:
    if start_s is None:
        return float(t[0])
    if not (isinstance(start_s, (int, float)) and math.isfinite(start_s) and start_s <= t[-1]):
        raise ValueError(f"start_s = {start_s!r} must be finite and not after the last reading ({t[-1]:g} s)")
    return float(start_s)


def soak_status(t_s, temp_c, criterion: SoakCriterion, *, start_s: float | None = None) -> SoakStatus:
    """Is the unit stable at its last reading?

    ``t_s`` (s, increasing) and ``temp_c`` (°C): the unit's sensor so far; ``start_s``: when
    the set point was commanded (default the first reading). Reads, and checks, only the
    trailing window and the first reading, so a procedure polling the sensor can call it after
    each reading. The window must lie wholly after ``start_s`` (module docstring).

    Parameters
    ----------
    t_s : array_like, shape (N,)
        Reading times, in s, strictly increasing; N ≥ 1.
    temp_c : array_like, shape (N,)
        The unit's sensor temperature, in °C, within −100 … 200.
    criterion : SoakCriterion
        The stability criterion.
    start_s : float, optional
        When the set point was commanded, in s, not after the last reading; default the
        first reading.

    Returns
    -------
    SoakStatus
        Whether the criterion holds at the last reading, the window's rate (°C/min), spread
        and mean (°C), and the reason when it does not.

    Raises
    ------
    ValueError
        If the arrays are not 1-D of one length ≥ 1, the window's readings (or the first) are
        not finite, not increasing or outside −100 … 200 °C, or ``start_s`` is not finite or
        after the last reading.

    Examples
    --------
    A unit settling exponentially (τ = 400 s) from 45 °C onto 25 °C, read every 10 s:

    >>> import numpy as np
    >>> from bench.analysis.thermal import SoakCriterion, soak_status
    >>> t = np.arange(0.0, 3600.0, 10.0)
    >>> temp = 25.0 + 20.0 * np.exp(-t / 400.0) + 0.01 * np.random.default_rng(0).standard_normal(t.size)
    >>> c = SoakCriterion(window_s=300.0, max_rate_c_per_min=0.05, band_c=0.2, target_c=25.0)
    >>> early = soak_status(t[:60], temp[:60], c)
    >>> early.stable, early.reason
    (False, 'rate -1.014 °C/min beyond ±0.05; spread 5.12 °C > band 0.2; mean 31.83 °C not within 2 of target 25')
    >>> late = soak_status(t, temp, c)
    >>> late.stable, late.samples, round(late.mean_c, 2)
    (True, 31, 25.0)
    """
    t = np.asarray(t_s, dtype=float)
    y = np.asarray(temp_c, dtype=float)
    if t.ndim != 1 or t.shape != y.shape or t.size == 0:
        raise ValueError(f"t_s and temp_c must be 1-D of one length ≥ 1, got shapes {t.shape} and {y.shape}")
    first = max(0, int(np.searchsorted(t, t[-1] - criterion.window_s, side="left")) - 1)
    tw, yw = _series(t[first:], y[first:])
    start = _start(np.r_[_series(t[:1], y[:1])[0], tw], start_s)
    return _judge(tw, yw, tw.size - 1, start, criterion)


def find_soak(t_s, temp_c, criterion: SoakCriterion, *, start_s: float | None = None) -> SoakResult:
    """Scan a whole temperature record for the first reading at which the soak criterion held.

    Arguments as :func:`soak_status`. Finds the first window of the unit's sensor, wholly
    after ``start_s``, in which the criterion holds (module docstring); the soak time runs
    from ``start_s`` to that window's end.

    Parameters
    ----------
    t_s : array_like, shape (N,)
        Reading times, in s, strictly increasing; N ≥ 1.
    temp_c : array_like, shape (N,)
        The unit's sensor temperature, in °C, within −100 … 200.
    criterion : SoakCriterion
        The stability criterion.
    start_s : float, optional
        When the set point was commanded, in s, not after the last reading; default the
        first reading.

    Returns
    -------
    SoakResult
        Whether and when (s) the criterion first held, the soak time from ``start_s`` (s), and
        the status at the last reading.

    Raises
    ------
    ValueError
        If the arrays are not 1-D of one length ≥ 1, a reading is not finite, the times are
        not increasing, a temperature is outside −100 … 200 °C, or ``start_s`` is not finite
        or after the last reading.

    Examples
    --------
    A unit settling exponentially (τ = 400 s) from 45 °C onto 25 °C, read every 10 s:

    >>> import numpy as np
    >>> from bench.analysis.thermal import SoakCriterion, find_soak
    >>> t = np.arange(0.0, 3600.0, 10.0)
    >>> temp = 25.0 + 20.0 * np.exp(-t / 400.0) + 0.01 * np.random.default_rng(0).standard_normal(t.size)
    >>> c = SoakCriterion(window_s=300.0, max_rate_c_per_min=0.05, band_c=0.2, target_c=25.0)
    >>> r = find_soak(t, temp, c)
    >>> r.stable, r.stable_at_s, r.soak_time_s
    (True, 1880.0, 1880.0)
    >>> find_soak(t, temp, c, start_s=600.0).soak_time_s  # the set point commanded at 600 s
    1280.0
    >>> r = find_soak(t[:150], temp[:150], c)  # the first 25 min only: not yet soaked
    >>> r.stable, r.stable_at_s, r.final.reason
    (False, None, 'rate -0.1069 °C/min beyond ±0.05; spread 0.5462 °C > band 0.2')
    """
    t, y = _series(t_s, temp_c)
    start = _start(t, start_s)
    # Rate of every trailing window at once (running sums), then the full check only where
    # the rate passes, in time order: the first pass is the answer.
    u = t - t[0]
    cs = [np.concatenate([[0.0], np.cumsum(v)]) for v in (np.ones_like(u), u, y, u * u, u * y)]
    ends = np.flatnonzero(t - start >= criterion.window_s)
    firsts = np.searchsorted(t, t[ends] - criterion.window_s, side="left")
    n, su, sy, suu, suy = (c[ends + 1] - c[firsts] for c in cs)
    with np.errstate(invalid="ignore", divide="ignore"):
        slope = (suy - su * sy / n) / (suu - su * su / n)
    candidates = ends[(n >= criterion.min_samples) & ~(np.abs(60.0 * slope) > 1.01 * criterion.max_rate_c_per_min)]
    final = _judge(t, y, t.size - 1, start, criterion)
    for end in candidates:
        status = _judge(t, y, int(end), start, criterion)
        if status.stable:
            return SoakResult(True, start, status.t_s, status.t_s - start, criterion, final)
    return SoakResult(False, start, None, None, criterion, final)
