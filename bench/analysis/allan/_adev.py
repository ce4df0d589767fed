"""Overlapping Allan deviation with confidence intervals and the IEEE Std 952 noise terms.

:func:`overlapping_adev` takes a static record of a gyro or accelerometer — rate samples
(°/s, g, …) or their integral (angle, velocity) — at a uniform sample rate and returns an
:class:`AllanResult`: τ, ADEV, its confidence interval, and the noise terms Q, N, B, K, R
both fitted and read off slope lines, with units.

* ADEV: the overlapping estimator, identical to allantools' ``oadev`` with
  ``data_type="freq"`` (NIST SP 1065 eq. 11); numerics in :mod:`.allan_core`.
* τ list: ``"octave"`` (m = 1, 2, 4, … while at least two differences remain — the same
  list as allantools), ``"log"`` (``points_per_decade`` rounded log-spaced m), or any τ
  in s (rounded to whole samples, duplicates merged; allowed ``τ0 ≤ τ ≤ ⌊N/2⌋·τ0``).
* Confidence intervals: Greenhall's EDF for the noise type that the fitted model says
  dominates at each τ, chi-squared bounds at ``confidence`` (default 68.27 %, one
  sigma); :mod:`.allan_stats`.
* Noise terms: weighted NNLS fit of the Allan variance model and the slope-line
  read-off; :mod:`.allan_noise`; units per sensor kind in :mod:`.allan_units`.

Pure: arrays and numbers in, a frozen dataclass out; bad input raises ``ValueError``
naming the value and the allowed range.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from bench.analysis.allan import _core as core
from bench.analysis.allan._noise import READ_TAU_S, SLOPE, TERMS, design_matrix, fit_noise_terms, read_off
from bench.analysis.allan._stats import ONE_SIGMA, adev_interval
from bench.analysis.allan._units import check_unit, rate_unit_name, term_units

MIN_SAMPLES = 8
MAX_POINTS_PER_DECADE = 100
DataType = Literal["rate", "phase"]


def _num(x) -> float | None:
    """A finite float for JSON, else None."""
    return float(x) if x is not None and np.isfinite(x) else None


@dataclass(frozen=True)
class NoiseCoefficient:
    """One IEEE 952 term.  ``*_input`` values are in ``input_unit`` (the record's rate unit
    times a power of s); the properties give the customary ``unit``; ``alt_*`` the other.

    ``fit_input`` is 0 when the fit excluded the term (non-negativity) and None when the
    term was not in the fitted set; ``read_off_input`` is None when no part of the curve
    has the term's slope.  ``read_off_tau_s`` is the curve point the line went through,
    ``read_at_tau_s`` where the line is read (None for B, read at the minimum).
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
        return self._scaled(self.fit_input, self.factor)

    @property
    def fit_std(self) -> float | None:
        return self._scaled(self.fit_std_input, self.factor)

    @property
    def read_off(self) -> float | None:
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
    """Overlapping ADEV of one record (module docstring).  Arrays are per τ.

    ``adev`` and ``adev_ci`` (rows ``(lo, hi)``) are in the record's rate unit
    (``units["adev"]``); ``edf`` the equivalent degrees of freedom behind the interval,
    ``noise_alpha`` the power-law exponent assumed for it, ``n_terms`` the number of
    overlapping differences and ``averaging_factor`` m = τ/τ0.  ``n_samples`` counts
    rate samples (one fewer than the points of a phase record).
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

    @property
    def units(self) -> dict[str, str]:
        """Unit of every reported quantity (coefficients in their customary units)."""
        return {"tau": "s", "adev": rate_unit_name(self.unit),
                **{name: c.unit for name, c in self.coefficients.items()}}

    def model_adev(self, tau_s: np.ndarray, terms: tuple[str, ...] | None = None) -> np.ndarray:
        """ADEV of the fitted model (or of some of its terms) at ``tau_s``, in the record's unit."""
        names = tuple(self.fit_terms if terms is None else terms)
        coef = np.array([self.coefficients[n].fit_input or 0.0 for n in names])
        return np.sqrt(design_matrix(np.asarray(tau_s, dtype=float), names) @ coef ** 2)

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
                    "iterations": self.fit_iterations, "method": "weighted NNLS of the Allan variance model"},
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
    """Averaging factors m = τ·rate for ``n`` rate samples (module docstring for the lists)."""
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
                     confidence: float = ONE_SIGMA, terms: tuple[str, ...] = TERMS) -> AllanResult:
    """Overlapping Allan deviation of a uniformly sampled record, with CI and noise terms.

    ``y``: rate samples in ``unit`` (``data_type="rate"``) or their integral in ``unit``·s
    (``"phase"``: angle for a gyro, velocity for an accelerometer); ``rate_hz`` > 0 the
    sample rate; ``taus``: ``"octave"``, ``"log"`` or τ values in s; ``unit``: one of
    ``dps, dph, radps, g, mg, ug, mps2`` or None (generic); ``confidence`` in (0, 1);
    ``terms``: the IEEE 952 terms the fit may use (default all five).
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
    rate = _checked_record(y, data_type, rate_hz)
    n = rate.size
    ms = averaging_factors(n, rate_hz, taus, points_per_decade)
    n_terms = n + 1 - 2 * ms
    avar = _sums(rate, ms) / (2.0 * n_terms * ms.astype(float) ** 2)
    tau = ms / rate_hz
    adev = np.sqrt(avar)
    ordered = tuple(t for t in TERMS if t in terms)
    fit = fit_noise_terms(tau, avar, ms, n + 1, ordered)
    ci = adev_interval(adev, fit.edf, confidence)

    notes: list[str] = []
    coefficients = {}
    for name in TERMS:
        u = term_units(unit, name)
        ro = read_off(tau, adev, name, fit.edf)
        coefficients[name] = NoiseCoefficient(
            name=name, label=u.label, slope=SLOPE[name], input_unit=u.input_unit, unit=u.unit,
            alt_unit=u.alt_unit, factor=u.factor, alt_factor=u.alt_factor,
            fit_input=fit.values.get(name), fit_std_input=fit.stds.get(name),
            read_off_input=None if ro is None else ro.value,
            read_off_tau_s=None if ro is None else ro.tau_s, read_at_tau_s=READ_TAU_S.get(name))
        if name == "B" and ro is not None and ro.at_edge and tau.size > 1:
            notes.append(f"the ADEV minimum is at an end of the readable τ range ({ro.tau_s:.6g} s): the curve "
                         "has no flat bottom there, so the B read-off is only an upper bound")
    if tau.size < len(ordered) + 1:
        notes.append(f"{tau.size} τ points for {len(ordered)} noise terms: the fit is underdetermined")
    if fit.reduced_chi2 is not None and fit.reduced_chi2 > 4.0:
        notes.append(f"the noise model fits the curve poorly (reduced χ² = {fit.reduced_chi2:.3g}): "
                     "a term outside Q, N, B, K, R (e.g. a periodic or Gauss–Markov term) is present")
    if not np.any(adev > 0):
        notes.append("the record is constant: every ADEV is zero")
    return AllanResult(tau_s=tau, adev=adev, adev_ci=ci, edf=fit.edf, noise_alpha=fit.alpha,
                       n_terms=n_terms, averaging_factor=ms, confidence=float(confidence),
                       sample_rate_hz=rate_hz, n_samples=n, data_type=data_type, unit=unit,
                       coefficients=coefficients, fit_terms=ordered, fit_reduced_chi2=fit.reduced_chi2,
                       fit_iterations=fit.iterations, notes=tuple(notes))
