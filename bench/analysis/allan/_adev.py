"""Overlapping Allan deviation with confidence intervals and the IEEE Std 952 noise terms.

:func:`overlapping_adev` takes a static record of a gyro or accelerometer — rate samples
(°/s, g, …) or their integral (angle, velocity) — at a uniform sample rate and returns an
:class:`AllanResult`: τ, ADEV, its confidence interval, and the noise terms Q, N, B, K, R
both fitted and read off slope lines, with units.

* ADEV: the overlapping estimator, identical to allantools' ``oadev`` with
  ``data_type="freq"`` (NIST SP 1065 eq. 11); numerics in :mod:`._core`.
* τ list: ``"octave"`` (m = 1, 2, 4, … while at least two differences remain — the same
  list as allantools), ``"log"`` (``points_per_decade`` rounded log-spaced m), or any τ
  in s (rounded to whole samples, duplicates merged; allowed ``τ0 ≤ τ ≤ ⌊N/2⌋·τ0``).
* Confidence intervals: Greenhall's EDF for the noise type that the fitted model says
  dominates at each τ, chi-squared bounds at ``confidence`` (default 68.27 %, one
  sigma); :mod:`._stats`.
* Noise terms: weighted NNLS fit of the Allan variance model and the slope-line
  read-off; :mod:`._noise`; units per sensor kind in :mod:`._units`.

Pure: arrays and numbers in, a frozen dataclass out; bad input raises ``ValueError``
naming the value and the allowed range.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

import bench.analysis.allan._core as core
from bench.analysis.allan._checks import (
    CHECK_CONFIDENCE,
    REGION_NAMES,
    SLOPE_TEXT,
    TermCheck,
    compare_read_off,
    correlation_is_significant,
    lag1_correlation,
    nearest_term,
    shown_slope,
)
from bench.analysis.allan._noise import (
    READ_TAU_S,
    SLOPE,
    TERMS,
    NoiseFit,
    ReadOff,
    design_matrix,
    fit_noise_terms,
    read_off,
)
from bench.analysis.allan._robust import DEFAULT_FALSE_ALARM, OutlierScreen, screen_outliers
from bench.analysis.allan._stats import ONE_SIGMA, adev_interval, upper_normal_quantile
from bench.analysis.allan._units import check_unit, rate_unit_name, term_units

MIN_SAMPLES = 8
#: a first-order low-pass of larger lag-1 correlation is not a "short" correlation time
MAX_LAG1 = 0.95
#: an outlier fraction (plain estimate) worth a note: what 1 % false alarms per record never reach
OUTLIER_NOTE_FRACTION = 1e-3
#: the outer terms and the noise beside them: Q and R are named only where the curve's slope
#: is told apart from N's or K's at CHECK_CONFIDENCE
EDGE_TERMS = {"Q": "N", "R": "K"}
Shown = tuple[tuple[float, float], float, float]  # region (τ first, last) in s, slope, its sd
MAX_POINTS_PER_DECADE = 100
DataType = Literal["rate", "phase"]


def _num(x) -> float | None:
    """A finite float for JSON, else None."""
    return float(x) if x is not None and np.isfinite(x) else None


@dataclass(frozen=True)
class NoiseCoefficient:
    """One IEEE 952 noise term of an :class:`AllanResult`, fitted and read off, with its units.

    ``*_input`` values are in ``input_unit`` (the record's rate unit times a power of s);
    the properties give the customary ``unit``; ``alt_*`` the other.

    ``fit_input`` is 0 when the fit excluded the term (non-negativity) and None when the
    term was not in the fitted set; ``read_off_input`` is None when no part of the curve
    has the term's slope.  ``read_off_tau_s`` is the curve point the line went through,
    ``read_at_tau_s`` where the line is read (None for B, read at the minimum).

    Attributes
    ----------
    name : str
        Term symbol: ``"Q"``, ``"N"``, ``"B"``, ``"K"`` or ``"R"``.
    label : str
        Its name for the sensor kind, e.g. ``"angle random walk"`` or ``"velocity random walk"``.
    slope : float
        Log-log slope of the term's ADEV line: -1, -0.5, 0, 0.5 or 1.
    input_unit : str
        Unit of the ``*_input`` values: the record's rate unit times a power of s
        (e.g. ``"deg/s*sqrt(s)"`` for N of a deg/s record).
    unit : str
        Customary unit of the term for the sensor kind (e.g. ``"deg/sqrt(h)"``); the unit of
        :attr:`fit`, :attr:`fit_std` and :attr:`read_off`.
    alt_unit : str
        The alternative unit (e.g. ``"deg/sqrt(s)"``).
    factor : float
        Multiplier from ``input_unit`` to ``unit`` (dimensionless).
    alt_factor : float
        Multiplier from ``input_unit`` to ``alt_unit`` (dimensionless).
    fit_input : float or None
        Least-squares value in ``input_unit``; 0 when the non-negative fit excluded the term,
        None when the term was not in the fitted set.
    fit_std_input : float or None
        Standard error of ``fit_input`` in ``input_unit``; None when the term is not in the
        fit's support.
    read_off_input : float or None
        Slope-line (graphical) reading in ``input_unit``; None when no part of the curve has
        the term's slope.
    read_off_tau_s : float or None
        τ in s of the curve point the slope line went through (for B: of the minimum).
    read_at_tau_s : float or None
        τ in s at which the line is read (√3, 1, 3, √2 s for Q, N, K, R); None for B.
    fit : float or None
        Property: ``fit_input`` in ``unit``.
    fit_std : float or None
        Property: ``fit_std_input`` in ``unit``.
    read_off : float or None
        Property: ``read_off_input`` in ``unit``.

    Examples
    --------
    >>> import numpy as np
    >>> from bench.analysis.allan import overlapping_adev
    >>> y = np.random.default_rng(0).normal(0.0, 0.1, 20_000)  # deg/s at 100 Hz
    >>> n = overlapping_adev(y, 100.0, unit="dps").coefficients["N"]
    >>> n.label, n.input_unit, n.unit
    ('angle random walk', 'deg/s*sqrt(s)', 'deg/sqrt(h)')
    >>> bool(abs(n.fit - 60 * n.fit_input) < 1e-12)  # 1 deg/sqrt(s) = 60 deg/sqrt(h)
    True
    """

    name: str
    label: str
    slope: float
    input_unit: str
    unit: str
    alt_unit: str
    factor: float
    alt_factor: float
    fit_input: float | None
    fit_std_input: float | None
    read_off_input: float | None
    read_off_tau_s: float | None
    read_at_tau_s: float | None

    def _scaled(self, value: float | None, factor: float) -> float | None:
        return None if value is None else value * factor

    @property
    def fit(self) -> float | None:
        """Fitted value in the customary ``unit`` (None when the term was not fitted)."""
        return self._scaled(self.fit_input, self.factor)

    @property
    def fit_std(self) -> float | None:
        """Standard error of :attr:`fit` in ``unit`` (None when unknown)."""
        return self._scaled(self.fit_std_input, self.factor)

    @property
    def read_off(self) -> float | None:
        """Slope-line reading in ``unit`` (None when the curve has no part of that slope)."""
        return self._scaled(self.read_off_input, self.factor)

    def to_dict(self) -> dict:
        def block(factor: float, unit: str) -> dict:
            return {"value": _num(self._scaled(self.fit_input, factor)),
                    "std": _num(self._scaled(self.fit_std_input, factor)),
                    "read_off": _num(self._scaled(self.read_off_input, factor)), "unit": unit}

        return {"label": self.label, "slope": self.slope, **block(self.factor, self.unit),
                "read_off_tau_s": _num(self.read_off_tau_s), "read_at_tau_s": _num(self.read_at_tau_s),
                "alt": block(self.alt_factor, self.alt_unit), "input_form": block(1.0, self.input_unit)}


@dataclass(frozen=True, eq=False)
class AllanResult:
    """Overlapping Allan deviation of one record, its confidence interval and the noise terms.

    Returned by :func:`overlapping_adev` (module docstring for the method).  Arrays are per τ.

    ``adev`` and ``adev_ci`` (rows ``(lo, hi)``) are in the record's rate unit
    (``units["adev"]``); ``edf`` the equivalent degrees of freedom behind the interval,
    ``noise_alpha`` the power-law exponent assumed for it, ``n_terms`` the number of
    overlapping differences and ``averaging_factor`` m = τ/τ0.  ``n_samples`` counts
    rate samples (one fewer than the points of a phase record).

    Attributes
    ----------
    tau_s : ndarray of float, shape (k,)
        Averaging times τ in s, increasing.
    adev : ndarray of float, shape (k,)
        Overlapping Allan deviation at each τ, in the record's rate unit (``units["adev"]``).
    adev_ci : ndarray of float, shape (k, 2)
        Confidence interval ``(lo, hi)`` of ``adev`` at level ``confidence``, same unit.
    edf : ndarray of float, shape (k,)
        Equivalent degrees of freedom (Greenhall) behind the interval (dimensionless).
    noise_alpha : ndarray of int, shape (k,)
        Power-law exponent α of ``S_y(f) ∝ f^α`` assumed at each τ (from the dominant fitted term).
    n_terms : ndarray of int, shape (k,)
        Number of overlapping second differences, ``N + 1 − 2m``.
    averaging_factor : ndarray of int, shape (k,)
        m = τ/τ0 (samples).
    confidence : float
        Confidence level of ``adev_ci``, in (0, 1).
    sample_rate_hz : float
        Sample rate of the record, in Hz.
    n_samples : int
        Number of rate samples N.
    data_type : str
        ``"rate"`` or ``"phase"``, as given.
    unit : str or None
        Rate unit code of the record (``"dps"``, ``"g"``, …) or None (generic).
    coefficients : dict of str to NoiseCoefficient
        The five IEEE 952 terms Q, N, B, K, R, fitted and read off, with their units.
    fit_terms : tuple of str
        Terms the least-squares fit was allowed to use, in Q, N, B, K, R order.
    fit_reduced_chi2 : float or None
        Reduced χ² of the weighted fit (None when undefined, e.g. no degrees of freedom).
    fit_iterations : int
        Fixed-point iterations of fit, noise types and EDF.
    notes : tuple of str
        Warnings about the record or the fit a user should read.
    checks : dict of str to TermCheck
        Each term checked against the curve by name (:class:`TermCheck`).
    robust : bool
        Whether flagged outliers were replaced before the Allan variance.
    outliers : OutlierScreen or None
        The outlier screen of the rate samples (flagged samples, threshold); None for a
        record too short to screen.
    lag1 : float
        Lag-1 autocorrelation of the rate samples (``1 + 2·r`` of the differences).
    lag1_se : float
        Its standard error under white noise, ``√(2/n)``.
    lag1_model : float
        The lag-1 correlation the N term of the fit carries (0: plain white N).
    units : dict of str to str
        Property: unit of every reported quantity (``"tau"``, ``"adev"`` and each term).

    Examples
    --------
    >>> import numpy as np
    >>> from bench.analysis.allan import overlapping_adev
    >>> r = overlapping_adev(np.random.default_rng(1).normal(0.0, 1.0, 4096), 10.0, unit="mg")
    >>> r.tau_s.shape == r.adev.shape == r.edf.shape, r.adev_ci.shape[1]
    (True, 2)
    >>> r.units["tau"], r.units["adev"], r.units["N"]
    ('s', 'mg', 'g/sqrt(Hz)')
    """

    tau_s: np.ndarray
    adev: np.ndarray
    adev_ci: np.ndarray
    edf: np.ndarray
    noise_alpha: np.ndarray
    n_terms: np.ndarray
    averaging_factor: np.ndarray
    confidence: float
    sample_rate_hz: float
    n_samples: int
    data_type: str
    unit: str | None
    coefficients: dict[str, NoiseCoefficient]
    fit_terms: tuple[str, ...]
    fit_reduced_chi2: float | None
    fit_iterations: int
    notes: tuple[str, ...] = field(default=())
    checks: dict[str, TermCheck] = field(default_factory=dict)
    robust: bool = False
    outliers: OutlierScreen | None = None
    lag1: float = 0.0
    lag1_se: float = math.inf
    lag1_model: float = 0.0

    @property
    def units(self) -> dict[str, str]:
        """Unit of every reported quantity (coefficients in their customary units)."""
        return {"tau": "s", "adev": rate_unit_name(self.unit),
                **{name: c.unit for name, c in self.coefficients.items()}}

    def model_adev(self, tau_s: np.ndarray, terms: tuple[str, ...] | None = None) -> np.ndarray:
        """ADEV of the fitted model (or of some of its terms) at ``tau_s``, in the record's unit."""
        names = tuple(self.fit_terms if terms is None else terms)
        coef = np.array([self.coefficients[n].fit_input or 0.0 for n in names])
        return np.sqrt(design_matrix(np.asarray(tau_s, dtype=float), names, self.lag1_model,
                                     1.0 / self.sample_rate_hz) @ coef ** 2)

    def to_dict(self) -> dict:
        """JSON-safe dict (no NaN: missing values are None)."""
        return {
            "tau": [float(t) for t in self.tau_s],
            "adev": [float(a) for a in self.adev],
            "adev_ci": [[_num(lo), _num(hi)] for lo, hi in self.adev_ci],
            "edf": [_num(e) for e in self.edf],
            "noise_alpha": [int(a) for a in self.noise_alpha],
            "n_terms": [int(n) for n in self.n_terms],
            "confidence": self.confidence,
            "sample_rate_hz": self.sample_rate_hz,
            "n_samples": self.n_samples,
            "data_type": self.data_type,
            "unit": self.unit,
            "units": self.units,
            "coefficients": {name: c.to_dict() for name, c in self.coefficients.items()},
            "fit": {"terms": list(self.fit_terms), "reduced_chi2": _num(self.fit_reduced_chi2),
                    "iterations": self.fit_iterations, "method": "weighted NNLS of the Allan variance model",
                    "lag1_model": self.lag1_model},
            "checks": {name: c.to_dict(self.coefficients[name].factor) for name, c in self.checks.items()},
            "robust": self.robust,
            "outliers": None if self.outliers is None else self.outliers.to_dict(),
            "lag1": {"value": _num(self.lag1), "se": _num(self.lag1_se)},
            "notes": list(self.notes),
        }


def _checked_record(y, data_type: str, rate_hz: float) -> np.ndarray:
    """Rate samples (float64) of a valid record."""
    if data_type not in ("rate", "phase"):
        raise ValueError(f"data_type = {data_type!r} is not one of 'rate', 'phase'")
    arr = np.asarray(y, dtype=float)
    if arr.ndim != 1:
        raise ValueError(f"the record must be one-dimensional, got shape {arr.shape}")
    need = MIN_SAMPLES + (data_type == "phase")
    if arr.size < need:
        raise ValueError(f"the record has {arr.size} samples; at least {need} {data_type} samples are required")
    if not math.isfinite(float(arr.sum())):  # a finite sum: all finite; an overflowed one: look
        bad = np.flatnonzero(~np.isfinite(arr))
        if bad.size:
            raise ValueError(f"the record has {bad.size} non-finite values (first at sample index {bad[0]}); "
                             "all must be finite")
    return np.diff(arr) * rate_hz if data_type == "phase" else arr


def averaging_factors(n: int, rate_hz: float, taus, points_per_decade: int = 10) -> np.ndarray:
    """Averaging factors m = τ·rate for ``n`` rate samples.

    The τ lists (module docstring): ``"octave"`` gives m = 1, 2, 4, … while at least two
    differences remain (the allantools list); ``"log"`` gives ``points_per_decade``
    log-spaced m, rounded and deduplicated, up to ⌊(n − 1)/2⌋; explicit τ values are
    rounded to whole samples and duplicates merged.

    Parameters
    ----------
    n : int
        Number of rate samples in the record.
    rate_hz : float
        Sample rate in Hz (τ0 = 1/rate_hz s).
    taus : {"octave", "log"} or array_like of float
        The list to generate, or τ values in s, each within ``[τ0, ⌊n/2⌋·τ0]``.
    points_per_decade : int, default 10
        Points per decade of the ``"log"`` list, an integer in [1, 100].

    Returns
    -------
    ndarray of int64
        Distinct averaging factors m (samples), increasing.

    Raises
    ------
    ValueError
        If ``taus`` is an unknown string or an empty/non-1-D array, if a τ lies outside
        ``[τ0, ⌊n/2⌋·τ0]`` s, or if ``points_per_decade`` is not an integer in [1, 100].

    Examples
    --------
    >>> from bench.analysis.allan import averaging_factors
    >>> averaging_factors(1000, 10.0, "octave").tolist()
    [1, 2, 4, 8, 16, 32, 64, 128, 256]
    >>> averaging_factors(1000, 10.0, "log", points_per_decade=2).tolist()
    [1, 3, 10, 32, 100, 316]
    >>> averaging_factors(1000, 10.0, [0.1, 1.0, 1.04, 2.04]).tolist()  # τ in s, rounded to samples
    [1, 10, 20]
    """
    gen_max = (n - 1) // 2  # generated lists keep at least two differences
    if isinstance(taus, str):
        if taus == "octave":
            return 2 ** np.arange(core.octave_levels(n), dtype=np.int64)
        if taus == "log":
            ppd = points_per_decade
            if isinstance(ppd, bool) or not isinstance(ppd, (int, np.integer)) or not 1 <= ppd <= MAX_POINTS_PER_DECADE:
                raise ValueError(f"points_per_decade = {ppd!r} must be an integer in [1, {MAX_POINTS_PER_DECADE}]")
            steps = np.arange(0, math.floor(math.log10(gen_max) * ppd + 1e-9) + 1)
            return np.unique(np.rint(10.0 ** (steps / ppd)).astype(np.int64))
        raise ValueError(f"taus = {taus!r} must be 'octave', 'log' or an array of τ in s")
    tau = np.atleast_1d(np.asarray(taus, dtype=float))
    if tau.ndim != 1 or tau.size == 0:
        raise ValueError(f"taus must be a non-empty 1-D array of τ in s, got shape {tau.shape}")
    tau0, top = 1.0 / rate_hz, n // 2
    for t in tau:
        m = round(t * rate_hz) if np.isfinite(t) else -1
        if not 1 <= m <= top:
            raise ValueError(f"τ = {float(t):g} s is outside the allowed range [{tau0:.6g}, {top * tau0:.6g}] s "
                             f"(one sample interval to half the record of {n} samples at {rate_hz:g} Hz)")
    return np.unique(np.rint(tau * rate_hz).astype(np.int64))


def _sums(y: np.ndarray, ms: np.ndarray) -> np.ndarray:
    """Σ of squared second differences per m; octave engine when every m is a power of two."""
    if np.all((ms & (ms - 1)) == 0):
        levels = int(ms.max()).bit_length()
        return core.octave_sums(y, levels)[np.log2(ms).astype(int)]
    return core.cumsum_sums(y, ms)


def overlapping_adev(y, rate_hz: float, taus="octave", *, data_type: DataType = "rate",
                     points_per_decade: int = 10, unit: str | None = "dps",
                     confidence: float = ONE_SIGMA, terms: tuple[str, ...] = TERMS, robust: bool = False,
                     false_alarm: float = DEFAULT_FALSE_ALARM) -> AllanResult:
    """Overlapping Allan deviation of a uniformly sampled record, with CI and noise terms.

    ``y``: rate samples in ``unit`` (``data_type="rate"``) or their integral in ``unit``·s
    (``"phase"``: angle for a gyro, velocity for an accelerometer); ``rate_hz`` > 0 the
    sample rate; ``taus``: ``"octave"``, ``"log"`` or τ values in s; ``unit``: one of
    ``dps, dph, radps, g, mg, ug, mps2`` or None (generic); ``confidence`` in (0, 1);
    ``terms``: the IEEE 952 terms the fit may use (default all five).

    At ``τ = m·τ0`` the estimator is NIST SP 1065 eq. 11 (allantools' ``oadev``), the
    interval uses Greenhall's EDF for the noise type the fitted model says dominates, and
    the terms come from the Allan variance model
    ``σ²(τ) = 3Q²/τ² + N²/τ + (2 ln2/π)·B² + K²·τ/3 + R²·τ²/2`` (module docstring).

    Parameters
    ----------
    y : array_like of float, shape (N,) or (N + 1,)
        The record: rate samples in ``unit`` (e.g. deg/s) for ``data_type="rate"``, or their
        integral in ``unit``·s (angle, velocity) for ``"phase"``; finite, at least 8 rate samples.
    rate_hz : float
        Sample rate in Hz, finite and > 0.
    taus : {"octave", "log"} or array_like of float, default "octave"
        τ list (see :func:`averaging_factors`) or τ values in s within ``[τ0, ⌊N/2⌋·τ0]``.
    data_type : {"rate", "phase"}, default "rate"
        Whether ``y`` holds rate samples or their integral.
    points_per_decade : int, default 10
        Density of the ``"log"`` list, in [1, 100].
    unit : {"dps", "dph", "radps", "g", "mg", "ug", "mps2"} or None, default "dps"
        Rate unit of the record (deg/s, deg/h, rad/s, g, mg, µg, m/s²); it sets the
        customary unit of every term. None: a generic unit ``u``.
    confidence : float, default ONE_SIGMA
        Confidence level of the interval, in (0, 1); default 0.6827 (one sigma).
    terms : tuple of str, default TERMS
        Distinct names from ``("Q", "N", "B", "K", "R")`` the least-squares fit may use.
    robust : bool, default False
        Replace isolated outliers of the rate samples (:func:`screen_outliers`) before the
        Allan variance; the result says how many were flagged (``outliers``, ``notes``).
    false_alarm : float, default 0.01
        Probability, in (0, 1), that the outlier screen flags a clean Gaussian record at all.

    Returns
    -------
    AllanResult
        Averaging times τ in s, ADEV and its interval in the rate unit, EDF, and the five
        :class:`NoiseCoefficient` terms in their customary units (``result.units``).

    Raises
    ------
    ValueError
        If ``rate_hz`` is not a finite number > 0, ``unit`` is not one of the codes above,
        ``confidence`` or ``false_alarm`` is outside (0, 1), ``terms`` are not distinct names from
        :data:`TERMS`, ``data_type`` is not ``"rate"``/``"phase"``, the record is not 1-D,
        has fewer than 8 rate samples or a non-finite value, or a τ is out of range
        (:func:`averaging_factors`).

    Examples
    --------
    White rate noise of 0.1 deg/s at 100 Hz has an angle random walk
    N = 0.1/√100 = 0.01 deg/√s = 0.6 deg/√h, and ADEV(τ) = N/√τ:

    >>> import numpy as np
    >>> from bench.analysis.allan import overlapping_adev
    >>> y = np.random.default_rng(0).normal(0.0, 0.1, 20_000)
    >>> r = overlapping_adev(y, 100.0, unit="dps")
    >>> r.tau_s[:3].tolist()
    [0.01, 0.02, 0.04]
    >>> round(float(r.adev[0]), 3)  # the sample std at τ = τ0
    0.1
    >>> n = r.coefficients["N"]
    >>> round(n.fit, 2), n.unit
    (0.6, 'deg/sqrt(h)')
    >>> bool(abs(n.fit - 0.6) < 3 * n.fit_std)
    True
    >>> i = int(np.flatnonzero(r.averaging_factor == 128)[0])  # τ = 1.28 s
    >>> lo, hi = r.adev_ci[i]
    >>> bool(lo < r.adev[i] < hi), round(float(r.edf[i]))  # ±1σ ≈ ±1/√(2·edf) relative
    (True, 232)
    >>> r.checks["N"].status  # the fitted N against the curve's slope −1/2 region
    'agrees'

    With 8 % spikes of ±3 deg/s the plain estimate is dominated by them; ``robust=True``
    replaces them first:

    >>> rng = np.random.default_rng(3)
    >>> hit = rng.random(y.size) < 0.08
    >>> spiky = y + hit * rng.choice([-3.0, 3.0], y.size)
    >>> plain = overlapping_adev(spiky, 100.0)
    >>> robust = overlapping_adev(spiky, 100.0, robust=True)
    >>> round(plain.coefficients["N"].fit, 1), round(robust.coefficients["N"].fit, 2)
    (5.2, 0.58)
    >>> robust.notes[0][:48]
    '8.4% of samples are outliers (1675 of 20000, |y '
    """
    if isinstance(rate_hz, bool) or not isinstance(rate_hz, (int, float, np.integer, np.floating)) \
            or not math.isfinite(rate_hz) or rate_hz <= 0:
        raise ValueError(f"rate_hz = {rate_hz!r} must be a finite number > 0")
    rate_hz = float(rate_hz)
    check_unit(unit)
    if not isinstance(confidence, (int, float)) or not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence = {confidence!r} must lie in (0, 1)")
    terms = tuple(terms)
    if not terms or len(set(terms)) != len(terms) or not set(terms) <= set(TERMS):
        raise ValueError(f"terms = {terms!r} must be distinct names from {TERMS}")
    if isinstance(false_alarm, bool) or not isinstance(false_alarm, (int, float)) or not 0.0 < false_alarm < 1.0:
        raise ValueError(f"false_alarm = {false_alarm!r} must lie in (0, 1)")
    raw = _checked_record(y, data_type, rate_hz)
    screen = screen_outliers(raw, false_alarm)
    rate = screen.cleaned if robust else raw
    n = rate.size
    ms = averaging_factors(n, rate_hz, taus, points_per_decade)
    n_terms = n + 1 - 2 * ms
    avar = _sums(rate, ms) / (2.0 * n_terms * ms.astype(float) ** 2)
    tau = ms / rate_hz
    adev = np.sqrt(avar)
    ordered = tuple(t for t in TERMS if t in terms)
    notes: list[str] = []
    if robust:
        notes.append(screen.summary())
    elif screen.fraction >= OUTLIER_NOTE_FRACTION:
        notes.append(f"{screen.fraction:.1%} of samples are isolated outliers ({screen.n_flagged} of {n}, "
                     f"false-alarm probability {false_alarm:g} per record): they enter every τ; "
                     "robust=True (--robust) replaces them")
    rho, rho_se = lag1_correlation(rate)
    lag1_model = 0.0
    if correlation_is_significant(rho, rho_se):
        if 0 < rho <= MAX_LAG1 and "N" in ordered and _white_leads(tau, avar, ms, n + 1, ordered):
            lag1_model = rho
            notes.append(f"the output is correlated sample to sample (lag-1 autocorrelation {rho:.3f} ± "
                         f"{rho_se:.1g}): ADEV at τ = {1 / rate_hz:.6g} s is {1 - math.sqrt(1 - rho):.1%} below "
                         "white noise, so N is fitted as white noise through a first-order low-pass "
                         "(N is its long-τ level)")
        else:
            notes.append(f"the output is correlated sample to sample (lag-1 autocorrelation {rho:.3f} ± "
                         f"{rho_se:.1g}): the first points of the curve are not white noise alone")

    fit_set = ordered
    dropped: dict[str, Shown | bool] = {}
    z_check = upper_normal_quantile((1.0 - CHECK_CONFIDENCE) / 2.0)
    while True:
        fit = fit_noise_terms(tau, avar, ms, n + 1, fit_set, lag1_model)
        shown = _shown_slopes(fit, tau, avar, rate_hz, lag1_model)
        # a term whose region shows another allowed term's slope is dropped and the curve refitted;
        # so are Q and R where their slope cannot be told from N's or K's (the noise explains it)
        wrong = [(abs(sl - SLOPE[t]) / sd, t) for t, (_, sl, sd) in shown.items()
                 if len(fit_set) > 1 and ((nearest_term(sl) != t and nearest_term(sl) in ordered
                                           and abs(sl - SLOPE[t]) > z_check * sd)
                                          or (t in EDGE_TERMS and EDGE_TERMS[t] in fit_set
                                              and abs(sl - SLOPE[EDGE_TERMS[t]]) < z_check * sd))]
        wrong += [(0.0, t) for t in fit_set if t in EDGE_TERMS and fit.values[t] > 0 and t not in shown
                  and len(fit_set) > 1]  # a Q or R that makes the model nowhere: the curve does not show it
        if not wrong:
            break
        name = max(wrong)[1]
        dropped[name] = shown.get(name, True)
        fit_set = tuple(t for t in fit_set if t != name)
    ci = adev_interval(adev, fit.edf, confidence)
    model = np.sqrt(np.maximum(design_matrix(tau, fit_set, lag1_model, 1.0 / rate_hz)
                               @ np.array([fit.values[t] ** 2 for t in fit_set]), 0.0))

    coefficients, checks = {}, {}
    for name in TERMS:
        u = term_units(unit, name)
        ro = read_off(tau, adev, name, fit.edf)
        coefficients[name] = NoiseCoefficient(
            name=name, label=u.label, slope=SLOPE[name], input_unit=u.input_unit, unit=u.unit,
            alt_unit=u.alt_unit, factor=u.factor, alt_factor=u.alt_factor,
            fit_input=fit.values.get(name), fit_std_input=fit.stds.get(name),
            read_off_input=None if ro is None else ro.value,
            read_off_tau_s=None if ro is None else ro.tau_s, read_at_tau_s=READ_TAU_S.get(name))
        checks[name] = _check(coefficients[name], ro, shown.get(name), dropped.get(name), tau, adev, fit.edf,
                              model, lag1_model, rate_hz)
        message = checks[name].message
        if message:
            notes.append(message)
        if name == "B" and ro is not None and ro.at_edge and tau.size > 1:
            notes.append(f"the ADEV minimum is at an end of the readable τ range ({ro.tau_s:.6g} s): the curve "
                         "has no flat bottom there, so the B read-off is only an upper bound")
    if tau.size < len(fit_set) + 1:
        notes.append(f"{tau.size} τ points for {len(fit_set)} noise terms: the fit is underdetermined")
    if fit.reduced_chi2 is not None and fit.reduced_chi2 > 4.0:
        named = [n for n, c in checks.items() if c.status in ("disagrees", "other slope")]
        notes.append(f"the noise model fits the curve poorly (reduced χ² = {fit.reduced_chi2:.3g})"
                     + (f"; see the checks of {', '.join(named)}" if named else
                        ": a term outside Q, N, B, K, R (e.g. a periodic or Gauss–Markov term) is present"))
    if not np.any(adev > 0):
        notes.append("the record is constant: every ADEV is zero")
    return AllanResult(tau_s=tau, adev=adev, adev_ci=ci, edf=fit.edf, noise_alpha=fit.alpha,
                       n_terms=n_terms, averaging_factor=ms, confidence=float(confidence),
                       sample_rate_hz=rate_hz, n_samples=n, data_type=data_type, unit=unit,
                       coefficients=coefficients, fit_terms=fit_set, fit_reduced_chi2=fit.reduced_chi2,
                       fit_iterations=fit.iterations, notes=tuple(notes), checks=checks, robust=bool(robust),
                       outliers=screen, lag1=rho, lag1_se=rho_se, lag1_model=lag1_model)


def _white_leads(tau: np.ndarray, avar: np.ndarray, ms: np.ndarray, n_phase: int, terms: tuple[str, ...]) -> bool:
    """True when N makes most of the plain fit at the first τ: the lag-1 correlation is then N's."""
    if not np.any(avar > 0):
        return False
    fit = fit_noise_terms(tau, avar, ms, n_phase, terms)
    parts = design_matrix(tau[:1], terms)[0] * np.array([fit.values[t] ** 2 for t in terms])
    return bool(terms[int(np.argmax(parts))] == "N" and parts.max() > 0.5 * parts.sum())


def _shown_slopes(fit: NoiseFit, tau: np.ndarray, avar: np.ndarray, rate_hz: float,
                  lag1: float) -> dict[str, Shown]:
    """Per fitted term (value > 0): its region, the slope the curve shows there and its sd."""
    design = design_matrix(tau, fit.terms, lag1, 1.0 / rate_hz)
    coef2 = np.array([fit.values[t] ** 2 for t in fit.terms])
    out = {}
    for k, name in enumerate(fit.terms):
        if coef2[k] > 0:
            found = shown_slope(k, design, coef2, avar, tau, fit.edf)
            if found is not None:
                out[name] = found
    return out


def _check(c: NoiseCoefficient, ro: ReadOff | None, shown: Shown | None, dropped: Shown | None | bool,
           tau: np.ndarray, adev: np.ndarray, edf: np.ndarray, model: np.ndarray, lag1: float,
           rate_hz: float) -> TermCheck:
    """The check of one term (module docstring of :mod:`._checks`), with its message in ``c.unit``.

    ``dropped``: the term's region and slope when the fit left it out for them, True when it
    was left out for making the model nowhere, None when it was kept."""
    def g(v: float) -> str:
        return f"{v * c.factor:.3g}"

    z_check = upper_normal_quantile((1.0 - CHECK_CONFIDENCE) / 2.0)
    region_slope = dropped if isinstance(dropped, tuple) else shown
    status, message = "unchecked", None
    fit_iv: tuple[float, float] | None = None
    read_iv: tuple[float, float] | None = None
    if dropped is True:
        status = "dropped"
        message = (f"{c.name} ({c.label}) left out of the fit: it made the fitted model nowhere on the curve, "
                   f"which does not show its slope ({SLOPE_TEXT[c.name]}); refitted without {c.name}")
    elif isinstance(dropped, tuple):
        (t_lo, t_hi), slope, sd = dropped
        status = "dropped"
        other = nearest_term(slope) if nearest_term(slope) != c.name else EDGE_TERMS[c.name]
        message = (f"{c.name} ({c.label}) left out of the fit: where it made the model (τ {t_lo:.3g}–{t_hi:.3g} s) "
                   f"the curve has slope {slope:+.2f} ± {sd:.2f}, which is {other} ({SLOPE_TEXT[other]}) "
                   f"as much as {c.name} ({SLOPE_TEXT[c.name]}); refitted without {c.name}")
    elif shown is not None:
        (t_lo, t_hi), slope, sd = shown
        other = nearest_term(slope)
        if other != c.name and abs(slope - SLOPE[c.name]) > z_check * sd:
            status = "other slope"
            message = (f"{c.name} fitted {g(c.fit_input or 0.0)} {c.unit}, but where it makes the model "
                       f"(τ {t_lo:.3g}–{t_hi:.3g} s) the curve has slope {slope:+.2f} ± {sd:.2f}: that is "
                       f"{other} ({SLOPE_TEXT[other]}), not {c.name} ({SLOPE_TEXT[c.name]})")
    if ro is not None and not dropped:
        i = int(np.argmin(np.abs(tau - ro.tau_s)))
        column = np.zeros(tau.size)
        column[i] = design_matrix(tau[i:i + 1], (c.name,), lag1, 1.0 / rate_hz)[0, 0]
        verdict, fit_iv, read_iv = compare_read_off(c.name, c.fit_input or 0.0, c.fit_std_input, column,
                                                    model, i, adev, edf, ro.value)
        if status == "unchecked":
            status = verdict
        if verdict == "disagrees" and message is None:
            fitted = "not fitted" if not c.fit_input else f"fitted {g(c.fit_input)} {c.unit}"
            message = (f"{c.name} {fitted} but the curve's {REGION_NAMES[c.name]} reads {g(ro.value)} {c.unit} "
                       f"[{g(read_iv[0])}, {g(read_iv[1])}] ({CHECK_CONFIDENCE:.0%}, τ = {ro.tau_s:.3g} s): "
                       "the fit does not describe the curve there")
    elif c.fit_input and status == "unchecked" and shown is not None:
        status = "agrees"
    if c.fit_input is not None and fit_iv is None:
        spread = z_check * (c.fit_std_input or 0.0)
        fit_iv = (max(c.fit_input - spread, 0.0), c.fit_input + spread)
    return TermCheck(name=c.name, status=status, fit_interval_input=fit_iv,
                     read_off_input=None if ro is None else ro.value, read_off_interval_input=read_iv,
                     read_off_tau_s=None if ro is None else ro.tau_s,
                     region_tau_s=None if region_slope is None else region_slope[0],
                     curve_slope=None if region_slope is None else region_slope[1],
                     curve_slope_sd=None if region_slope is None else region_slope[2],
                     shows=None if region_slope is None else nearest_term(region_slope[1]), message=message)
