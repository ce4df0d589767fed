"""Turn-on to turn-on bias repeatability (IEEE Std 952 FOG, IEEE Std 1293 accelerometer).

K power cycles, each giving the unit's bias b_i with its within-run standard uncertainty u_i
(the estimate's own noise: the record's length and the unit's noise set it). Model::

    b_i = μ + δ_day(i) + ε_i + e_i,    ε_i ~ N(0, σ_r²),  δ ~ N(0, σ_d²),  e_i ~ N(0, u_i²)

* ``raw_sd`` — the sample standard deviation of the b_i: the standards' 1σ of the turn-on
  biases, within-run noise included, with its χ² confidence interval;
* ``repeatability`` — σ_r with the within-run noise removed. The generalised Q statistic
  Q(σ²) = Σ w_i (b_i − b̄_w)², w_i = 1/(u_i² + σ²), b̄_w the w-weighted mean, is χ² with
  K − 1 degrees of freedom at the true σ_r² and falls monotonically with σ²: the estimate
  solves Q(σ²) = K − 1 (Paule–Mandel; 0 when Q(0) < K − 1) and the **Q-profile** interval
  (Viechtbauer 2007) solves Q(σ²) = χ²_{K−1} quantiles — exact coverage for normal data,
  whatever the u_i. With equal u_i it reduces to √(s² − u²);
* **day-to-day** (when each cycle carries its day): the same Q pooled within days
  (deviations from each day's weighted mean, K − D degrees of freedom, exact) gives the
  within-day σ_r; the day means, each with its within-day variance 1/Σ w_i at σ̂_r, give
  σ_d by the same Q-profile over D − 1 degrees of freedom (approximate: σ̂_r is plugged in).
  For a balanced design with equal u_i these are the ANOVA estimators, which equal REML
  when positive (the tests check against statsmodels' MixedLM).

Units: those of the biases. ``p_value_excess`` tests σ_r = 0: whether the cycles scatter
more than their within-run noise explains.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import optimize, stats

from bench.analysis._checks import as_array, check_real
from bench.values import Estimate


@dataclass(frozen=True)
class VarianceComponent:
    """A standard deviation (the square root of a variance component) with its two-sided
    confidence interval at ``confidence``; ``dof`` the degrees of freedom behind it.

    Attributes
    ----------
    sd : float
        The standard deviation, in the biases' unit.
    low : float
        Lower end of its confidence interval, same unit (0 when the data allow none).
    high : float
        Upper end of its confidence interval, same unit.
    confidence : float
        Two-sided confidence level of the interval, in [0.5, 0.999].
    dof : int
        Degrees of freedom behind the estimate.
    """

    sd: float
    low: float
    high: float
    confidence: float
    dof: int

    def to_dict(self) -> dict:
        return {"sd": self.sd, "low": self.low, "high": self.high, "confidence": self.confidence, "dof": self.dof}


@dataclass(frozen=True)
class DayToDay:
    """Split of the turn-on scatter by day: ``within_day`` (σ_r, noise removed) and
    ``day_to_day`` (σ_d), over ``n_days`` days; ``day_means`` in day order of first appearance.

    Attributes
    ----------
    n_days : int
        Number of distinct days D.
    within_day : VarianceComponent
        σ_r from the Q statistic pooled within days (K − D degrees of freedom), biases' unit.
    day_to_day : VarianceComponent
        σ_d from the day means' Q-profile (D − 1 degrees of freedom, approximate), same unit.
    day_labels : tuple of str
        The day labels, in order of first appearance.
    day_means : tuple of Estimate
        Each day's weighted mean bias with its standard error, same order and unit.
    """

    n_days: int
    within_day: VarianceComponent
    day_to_day: VarianceComponent
    day_labels: tuple[str, ...]
    day_means: tuple[Estimate, ...]

    def to_dict(self) -> dict:
        return {"n_days": self.n_days, "within_day": self.within_day.to_dict(),
                "day_to_day": self.day_to_day.to_dict(), "day_labels": list(self.day_labels),
                "day_means": [m.to_dict() for m in self.day_means]}


@dataclass(frozen=True, eq=False)
class TurnOnRepeatability:
    """Turn-on to turn-on bias repeatability, with and without the within-run noise, and its day split.

    Turn-on to turn-on repeatability of ``n_cycles`` biases (module docstring).

    Every figure is in the unit of the biases.

    Attributes
    ----------
    n_cycles : int
        Number of power cycles K.
    mean : Estimate
        Weighted mean bias (weights 1/(u_i² + σ̂_r²)) with its standard error.
    raw_sd : VarianceComponent
        Sample standard deviation of the biases, within-run noise included, with its χ²
        interval (K − 1 degrees of freedom).
    within_run_rms : float
        Root-mean-square of the within-run standard uncertainties u_i.
    repeatability : VarianceComponent
        σ_r, the within-run noise removed: Paule–Mandel estimate and Q-profile interval.
    q_statistic : float
        Generalised Q at σ² = 0, Σ w_i (b_i − b̄_w)² with w_i = 1/u_i² (χ² with K − 1
        degrees of freedom when σ_r = 0).
    p_value_excess : float
        P(χ²_{K−1} ≥ Q): the test of σ_r = 0; small when the cycles scatter more than their
        within-run noise explains.
    days : DayToDay or None
        Within-day and day-to-day split; None when no ``day`` labels were given.
    bias : ndarray, shape (K,)
        The biases b_i.
    bias_std : ndarray, shape (K,)
        Their within-run standard uncertainties u_i.
    """

    n_cycles: int
    mean: Estimate
    raw_sd: VarianceComponent
    within_run_rms: float
    repeatability: VarianceComponent
    q_statistic: float
    p_value_excess: float
    days: DayToDay | None
    bias: np.ndarray
    bias_std: np.ndarray

    def to_dict(self) -> dict:
        return {"n_cycles": self.n_cycles, "mean": self.mean.to_dict(), "raw_sd": self.raw_sd.to_dict(),
                "within_run_rms": self.within_run_rms, "repeatability": self.repeatability.to_dict(),
                "q_statistic": self.q_statistic, "p_value_excess": self.p_value_excess,
                "days": None if self.days is None else self.days.to_dict(),
                "bias": self.bias.tolist(), "bias_std": self.bias_std.tolist()}


def _q(tau2: float, y: np.ndarray, u2: np.ndarray, groups: np.ndarray, n_groups: int) -> float:
    """Generalised Q: Σ w (y − group's w-weighted mean)², w = 1/(u² + τ²)."""
    w = 1.0 / (u2 + tau2)
    means = np.bincount(groups, w * y, n_groups) / np.bincount(groups, w, n_groups)
    return float(np.sum(w * (y - means[groups]) ** 2))


def _solve_tau2(target: float, y, u2, groups, n_groups) -> float:
    """τ² ≥ 0 with Q(τ²) = target (0 when Q(0) ≤ target; Q falls monotonically in τ²)."""
    if _q(0.0, y, u2, groups, n_groups) <= target:
        return 0.0
    hi = max(float(np.var(y)), float(u2.max()), 1e-300)
    while _q(hi, y, u2, groups, n_groups) > target:
        hi *= 4.0
    return float(optimize.brentq(lambda t2: _q(t2, y, u2, groups, n_groups) - target, 0.0, hi,
                                 xtol=1e-14 * hi, rtol=1e-12))


def _q_profile(y, u2, groups, n_groups, dof: int, confidence: float) -> tuple[VarianceComponent, float]:
    alpha = 1.0 - confidence
    point = _solve_tau2(dof, y, u2, groups, n_groups)
    low = _solve_tau2(stats.chi2.ppf(1 - alpha / 2, dof), y, u2, groups, n_groups)
    high = _solve_tau2(stats.chi2.ppf(alpha / 2, dof), y, u2, groups, n_groups)
    q0 = _q(0.0, y, u2, groups, n_groups)
    return VarianceComponent(float(np.sqrt(point)), float(np.sqrt(low)), float(np.sqrt(high)),
                             confidence, dof), q0


def _day_indices(day, k: int) -> tuple[np.ndarray, tuple[str, ...]]:
    labels = [str(d) for d in day]
    if len(labels) != k:
        raise ValueError(f"day has {len(labels)} entries; one per cycle ({k}) is needed")
    order = list(dict.fromkeys(labels))
    index = {lab: i for i, lab in enumerate(order)}
    return np.array([index[lab] for lab in labels]), tuple(order)


def turn_on_repeatability(bias, bias_std, *, day: Sequence | None = None,
                          confidence: float = 0.95) -> TurnOnRepeatability:
    """Repeatability of the turn-on biases ``bias`` with their within-run uncertainties.

    ``bias`` (K ≥ 2) with within-run standard uncertainties ``bias_std`` (> 0, same unit).
    ``day``: one label per cycle (any values; equal labels = same day) to split within-day
    from day-to-day; needs ≥ 2 days and more cycles than days. ``confidence`` of the
    intervals, in [0.5, 0.999]. σ_r solves Q(σ²) = K − 1 (Paule–Mandel) with the Q-profile
    interval (Viechtbauer 2007); the model and the day split are in the module docstring.

    Parameters
    ----------
    bias : array_like, shape (K,)
        Bias b_i of each power cycle, any unit (e.g. °/h, mg); finite, K ≥ 2.
    bias_std : array_like, shape (K,)
        Within-run standard uncertainty u_i of each bias, same unit; finite and > 0.
    day : sequence, optional
        One label per cycle (compared as strings); equal labels are the same day. Needs 2 …
        K − 1 distinct days.
    confidence : float, default 0.95
        Two-sided confidence level of every interval, in [0.5, 0.999].

    Returns
    -------
    TurnOnRepeatability
        Raw scatter, repeatability σ_r (noise removed) with intervals, weighted mean, the Q
        test of σ_r = 0 and, with ``day``, the within-day/day-to-day split; in the biases' unit.

    Raises
    ------
    ValueError
        If ``bias`` has fewer than 2 finite values, ``bias_std`` is not as long or not > 0,
        ``confidence`` is outside [0.5, 0.999], ``day`` is not one label per cycle, or names
        fewer than 2 or more than K − 1 distinct days.

    Examples
    --------
    Twenty turn-ons of a gyro whose bias repeats to σ_r = 0.3 °/h, each bias known to 0.1 °/h:

    >>> import numpy as np
    >>> from bench.analysis.turn_on import turn_on_repeatability
    >>> rng = np.random.default_rng(0)
    >>> b = 5.0 + rng.normal(0.0, 0.3, 20) + rng.normal(0.0, 0.1, 20)
    >>> rep = turn_on_repeatability(b, np.full(20, 0.1))
    >>> bool(rep.repeatability.low < 0.3 < rep.repeatability.high), rep.repeatability.dof
    (True, 19)
    >>> # with equal u_i the estimate is √(s² − u²)
    >>> bool(abs(rep.repeatability.sd - np.sqrt(rep.raw_sd.sd**2 - 0.1**2)) < 1e-9)
    True
    >>> bool(rep.p_value_excess < 0.01), rep.days is None
    (True, True)
    """
    y = as_array("bias", bias, min_size=2)
    s = as_array("bias_std", bias_std, size=y.size, positive=True)
    conf = check_real("confidence", confidence, 0.5, 0.999)
    k = y.size
    u2 = s**2
    alpha = 1.0 - conf
    one = np.zeros(k, dtype=int)
    rep, q0 = _q_profile(y, u2, one, 1, k - 1, conf)
    sd = float(np.std(y, ddof=1))
    raw = VarianceComponent(sd, sd * float(np.sqrt((k - 1) / stats.chi2.ppf(1 - alpha / 2, k - 1))),
                            sd * float(np.sqrt((k - 1) / stats.chi2.ppf(alpha / 2, k - 1))), conf, k - 1)
    w = 1.0 / (u2 + rep.sd**2)
    mean = Estimate(float(w @ y / w.sum()), float(1.0 / np.sqrt(w.sum())))
    days = None
    if day is not None:
        groups, labels = _day_indices(day, k)
        d = len(labels)
        if not 2 <= d < k:
            raise ValueError(f"day names {d} distinct day(s) for {k} cycles: allowed 2 … {k - 1} "
                             "(at least two days, and a day with two cycles)")
        within, _ = _q_profile(y, u2, groups, d, k - d, conf)
        wr = 1.0 / (u2 + within.sd**2)
        sw = np.bincount(groups, wr, d)
        day_mean = np.bincount(groups, wr * y, d) / sw
        between, _ = _q_profile(day_mean, 1.0 / sw, np.zeros(d, dtype=int), 1, d - 1, conf)
        days = DayToDay(d, within, between, labels,
                        tuple(Estimate(float(m), float(np.sqrt(1.0 / v))) for m, v in zip(day_mean, sw)))
    return TurnOnRepeatability(k, mean, raw, float(np.sqrt(np.mean(u2))), rep, q0,
                               float(stats.chi2.sf(q0, k - 1)), days, y, s)
