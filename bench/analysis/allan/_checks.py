"""Each fitted IEEE 952 term checked against the curve, by name; sample-to-sample correlation.

**Slope shown.**  Where a fitted term makes at least half of the fitted model, the curve's
own part for that term is ``σ²_curve − (model − term)``; the log-log slope of its square
root (weighted least squares, ``var ln σ̂² ≈ 2/edf`` scaled by the term's share) is the
slope the data show there, and the term whose slope (−1, −1/2, 0, +1/2, +1) is nearest
is the one they show.  A ramp R fitted where the curve rises with slope +1/2 shows K.
(Octave points share data, so the slope's standard deviation is indicative.)

**Read-off against fit.**  The slope-line read-off (:func:`read_off`) at its curve point
carries the ADEV interval there at :data:`CHECK_CONFIDENCE` (Greenhall EDF, chi-squared),
and the fitted value ``fit ± z·std`` at the same level.  The fit disagrees with the curve
when the term alone lies above the curve's interval there (other terms only add), or when
the whole model with the term at its upper bound lies below it (the term is too small to
make the curve) — each widened by half the model allowance ``MODEL_FLOOR``.

**Correlation.**  White rate noise through a first-order low-pass (a Gauss–Markov process
of short correlation time) has lag-1 autocorrelation ``ρ``; its Allan variance at τ0 is
``σ²(1 − ρ)``, below the white line ``N²/τ0`` that holds for τ ≫ the correlation time.
``ρ`` is estimated as ``1 + 2·r`` with ``r`` the lag-1 autocorrelation of the first
differences (−1/2 for white noise; slow terms hardly change it); under white noise its
standard error is ``√(2/n)`` (Bartlett, MA(1) with θ = −1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bench.analysis.allan._noise import MODEL_FLOOR, SLOPE
from bench.analysis.allan._stats import adev_interval, upper_normal_quantile

#: intervals of the fit-against-curve check: two 99 % intervals that do not meet flag an
#: honest term well under 1 % of the time
CHECK_CONFIDENCE = 0.99
#: two-sided test level of the lag-1 correlation: 1 % of white-noise records are called correlated
CORRELATION_LEVEL = 0.01
REGION_NAMES = {"Q": "slope −1 region", "N": "slope −1/2 region", "B": "flat region (minimum)",
                "K": "slope +1/2 region", "R": "slope +1 region"}
SLOPE_TEXT = {"Q": "−1", "N": "−1/2", "B": "0", "K": "+1/2", "R": "+1"}


@dataclass(frozen=True)
class TermCheck:
    """One IEEE 952 term checked against the ADEV curve (module docstring of the method).

    Values ``*_input`` are in the term's input form (``NoiseCoefficient.input_unit``);
    intervals at :data:`CHECK_CONFIDENCE`.

    Attributes
    ----------
    name : str
        Term symbol, ``"Q"``, ``"N"``, ``"B"``, ``"K"`` or ``"R"``.
    status : str
        ``"agrees"`` (fit within the read-off's reach), ``"disagrees"`` (the fit does not
        describe the curve in the term's slope region), ``"other slope"`` (where the term
        dominates, the curve shows another term's slope), ``"dropped"`` (left out of the fit
        for that reason and refitted) or ``"unchecked"`` (no slope region and no dominance).
    fit_interval_input : tuple of float or None
        ``fit ± z·std`` (lower bound ≥ 0); None when the term was not fitted.
    read_off_input : float or None
        Slope-line read-off; None when no part of the curve has the term's slope.
    read_off_interval_input : tuple of float or None
        The read-off scaled by the ADEV interval at its curve point.
    read_off_tau_s : float or None
        τ in s of that curve point.
    region_tau_s : tuple of float or None
        First and last τ in s where the term makes at least half the fitted model.
    curve_slope : float or None
        Log-log ADEV slope of the curve's part for the term in that region.
    curve_slope_sd : float or None
        Its standard deviation (octave points treated as independent: indicative).
    shows : str or None
        The term whose slope is nearest ``curve_slope``.
    message : str or None
        What is wrong, in the customary unit, naming the term; None when nothing is.
    """

    name: str
    status: str
    fit_interval_input: tuple[float, float] | None
    read_off_input: float | None
    read_off_interval_input: tuple[float, float] | None
    read_off_tau_s: float | None
    region_tau_s: tuple[float, float] | None
    curve_slope: float | None
    curve_slope_sd: float | None
    shows: str | None
    message: str | None

    def to_dict(self, factor: float = 1.0) -> dict:
        def scaled(v):
            return None if v is None else [float(x) * factor for x in v] if isinstance(v, tuple) else float(v) * factor

        return {"status": self.status, "fit_interval": scaled(self.fit_interval_input),
                "read_off": scaled(self.read_off_input), "read_off_interval": scaled(self.read_off_interval_input),
                "read_off_tau_s": self.read_off_tau_s,
                "region_tau_s": None if self.region_tau_s is None else list(self.region_tau_s),
                "curve_slope": self.curve_slope, "curve_slope_sd": self.curve_slope_sd, "shows": self.shows,
                "message": self.message, "confidence": CHECK_CONFIDENCE}


def nearest_term(slope: float) -> str:
    """The term whose ADEV slope is nearest ``slope``."""
    return min(SLOPE, key=lambda t: abs(SLOPE[t] - slope))


def shown_slope(k: int, design: np.ndarray, coef2: np.ndarray, avar: np.ndarray, tau: np.ndarray,
                edf: np.ndarray) -> tuple[tuple[float, float], float, float] | None:
    """Region (τ first, last), slope and its sd of the curve's part for fitted column ``k``;
    None when the term makes half the model nowhere (module docstring)."""
    contrib = design * coef2
    model = contrib.sum(axis=1)
    own = contrib[:, k]
    share = np.divide(own, model, out=np.zeros_like(model), where=model > 0)
    part = avar - (model - own)
    idx = np.flatnonzero((share >= 0.5) & (part > 0))
    if idx.size == 0:
        return None
    if idx.size == 1:  # one point: the slope to its neighbour inside the curve
        j = int(idx[0])
        nb = [i for i in (j - 1, j + 1) if 0 <= i < tau.size and part[i] > 0]
        if not nb:
            return None
        idx = np.sort(np.r_[idx, nb[0]])
    x, y = np.log(tau[idx]), 0.5 * np.log(part[idx])
    w = edf[idx] * 2.0 * (part[idx] / avar[idx]) ** 2  # 1/var(ln √part) = 2·edf·(part/avar)²
    xm = float(np.sum(w * x) / np.sum(w))
    sxx = float(np.sum(w * (x - xm) ** 2))
    slope = float(np.sum(w * (x - xm) * y) / sxx)
    return (float(tau[idx[0]]), float(tau[idx[-1]])), slope, math.sqrt(1.0 / sxx)


def lag1_correlation(rate: np.ndarray) -> tuple[float, float]:
    """Lag-1 autocorrelation ``ρ`` of a rate record from its differences, and its standard
    error under white noise (module docstring)."""
    d = np.diff(np.asarray(rate, dtype=float))
    den = float(d @ d)
    if d.size < 3 or den == 0:
        return 0.0, math.inf
    r = float(d[1:] @ d[:-1]) / den
    return 1.0 + 2.0 * r, math.sqrt(2.0 / d.size)


def correlation_is_significant(rho: float, se: float) -> bool:
    """True when ``|ρ|`` exceeds the two-sided normal bound at :data:`CORRELATION_LEVEL`."""
    return math.isfinite(se) and abs(rho) > upper_normal_quantile(CORRELATION_LEVEL / 2.0) * se


def compare_read_off(name: str, fit: float, fit_std: float | None, column: np.ndarray, model_adev: np.ndarray,
                     i: int, adev: np.ndarray, edf: np.ndarray, read_value: float
                     ) -> tuple[str, tuple[float, float] | None, tuple[float, float]]:
    """Status (``"agrees"``/``"disagrees"``), fit interval and read-off interval of one term
    at its read-off curve point ``i`` (module docstring); ``column`` the term's design column."""
    z = upper_normal_quantile((1.0 - CHECK_CONFIDENCE) / 2.0)
    lo_hi = adev_interval(adev[i:i + 1], edf[i:i + 1], CHECK_CONFIDENCE)[0]
    rel_lo, rel_hi = lo_hi / adev[i]
    read_iv = (read_value * rel_lo, read_value * rel_hi)
    spread = z * (fit_std or 0.0)
    fit_lo, fit_hi = max(fit - spread, 0.0), fit + spread
    alone_lo = math.sqrt(column[i]) * fit_lo
    others2 = max(model_adev[i] ** 2 - column[i] * fit ** 2, 0.0)
    model_hi = math.sqrt(others2 + column[i] * fit_hi ** 2)
    allowance = MODEL_FLOOR / 2.0  # the fit is granted 2 % in variance, 1 % in deviation
    too_big = alone_lo > lo_hi[1] * (1.0 + allowance)
    too_small = model_hi < lo_hi[0] * (1.0 - allowance)
    status = "disagrees" if too_big or too_small else "agrees"
    return status, (fit_lo, fit_hi), read_iv
