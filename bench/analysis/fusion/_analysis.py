"""Every rate-fusion method side by side on one HF/LF record: tuned on its first part, judged
on the rest, and the recommended output picked by that judgement.

**Methods** (:data:`METHODS`, the one registry: CLI, report, procedure and benchmarks derive
from it) — each sensor alone, the complementary filter, Document B's sequential adaptive-R
Kalman filter as published, a conventional fixed-R Kalman filter, the complementary Kalman
filter (:mod:`bench.analysis.fusion._complementary`: cannot lag, noise by maximum likelihood)
with and without Document B's adaptive R on top, its fixed-interval smoother (offline)
with and without it, and the complementary filter and smoother on a copy of the record with
each sensor's outliers replaced (offline; see **Outliers** below).

**With a reference** (:func:`analyze_fusion` with ``ref``), the first ``tune_fraction`` of the
record *tunes* and the rest (after ``settle_s``) *judges*:

1. tones (given or detected in ``ref``); sensor models given, or fitted with their delays
   and each clock's rate error measured on the tuning part and the record aligned
   (:func:`~bench.analysis.fusion._alignment.fit_and_align`);
2. tuning on the first part only: Document B's process noise, thresholds and interval noise by
   its grid and rule (:func:`~bench.analysis.fusion._tuning.tune_fusion`); the fixed-R filter
   by the same rule among the grid's fixed-R settings; the adaptive R on top of the
   complementary Kalman filter by the same rule over its grid; the complementary filter's
   crossover by the lowest RMS error over its grid (it trades noise for noise, not for lag);
   the complementary Kalman filter's noise by maximum likelihood (the reference unused, the
   known tones fitted out first);
3. every method runs over the whole record with its tuned settings and is judged on the rest:
   RMS error, amplitude and phase error per tone with standard errors, and the *excess* — the
   method's |amplitude error| less the better single sensor's at each tone, with the standard
   error of that difference (from the method-minus-sensor series, which share their noise);
4. **recommended**: among the methods whose RMS error is no worse than the best of each sensor
   alone and the complementary filter (the baselines that need no model of the signal), the
   lowest RMS error of those whose excess is within two standard errors *of the excess* at
   every tone (the sharp test: it sees a lag of 10⁻⁴ pp — and also the 10⁻⁴ of a fitted gain)
   and within two of *the better sensor's own* amplitude error (no worse than that sensor is
   known to be; the sharp test alone is not the stricter where the method and the sensor do
   not share their noise — an outlier in one of them); if none is, of those within two
   standard errors of the sensor's own error; if none is, the lowest RMS error
   (:func:`~bench.analysis.fusion._tuning.choose`).  The judged part is where the choice is
   made, so the recommended method's figures there carry the (small) optimism of a choice
   among eleven.

**Outliers** (spikes, dropouts) stay in the record every method above sees: the sensors alone
read them, and Document B's adaptive R is meant to handle them.  Two more methods run on a
copy with each sensor's outliers replaced by its own tone fit (the reference unused;
:func:`~bench.analysis.fusion._alignment.fit_and_align`): the complementary filter and the
complementary smoother, *cleaned*.  They are judged like every other, so they are
recommended only where they do better on the judged part; where nothing was replaced they
are the methods they clean (and ties go to those).  With a reference the tone fit finds the
outliers rather than the detector used without one (step 1 below): where the motion is the
tones it restores a dropout's samples from them, which a detector without a model of the
motion cannot (it fills a dropout from its neighbours); on random motion it misses them.

**Without a reference** nothing can be judged, and a method can go wrong unseen (on random
motion a noise model fitted to motion it does not model makes the smoother lean on the wrong
sensor):

1. each sensor's spikes and dropouts are found without a model of the motion — its interpolation
   residual beyond a threshold set by a stated false-alarm rate; a dropout as a run, flat between
   two jumps, filled from its neighbours (:func:`~bench.analysis.fusion._outliers.find_spikes`) —
   and replaced in a cleaned copy;
2. the given delays are applied, then the LF record put on the HF clock: its skew and the rest of
   its delay from the sensors' cross-spectrum, each corrected where significant
   (:func:`~bench.analysis.fusion._timing.estimate_relative_timing`);
3. every method runs with settings from the data alone (Document B's defaults, the crossover at
   ``√(f_h·f_l)``, the complementary noise by maximum likelihood on the cleaned copy);
4. **recommended**: the first of :data:`PREFERENCE_WITHOUT_REF` (the smoother on the cleaned
   copy, the smoother, the complementary Kalman filter) whose filter did not diverge and which
   passes its consistency checks — read back through each sensor's model it agrees with that
   sensor within the sensor's noise, or as well as the plain complementary filter, in every
   octave the sensor reads (:func:`~bench.analysis.fusion._consistency.check_method`, bounds
   from an F quantile at a 1 % false-alarm rate); if none does, the plain complementary filter
   (on the cleaned copy where spikes were replaced).  A smoother that diverges cannot be
   recommended.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

import bench.analysis.fusion._complementary as fc
import bench.analysis.fusion._sequential as fu
from bench.analysis.fusion._alignment import MIN_TONES, PairAlignment, fit_and_align
from bench.analysis.fusion._consistency import (
    MethodCheck,
    check_method,
    difference_noise,
    sensor_noise,
    welch_segment,
)
from bench.analysis.fusion._metrics import (
    detect_tones,
    nis_check,
    tone_fit,
    tone_noise_std,
    tone_residual_var,
    without_outliers,
)
from bench.analysis.fusion._models import FusionModel, SensorModel
from bench.analysis.fusion._outliers import SPIKE_HALF_WIDTH, SpikeSearch, find_spikes
from bench.analysis.fusion._timing import RelativeTiming, align_relative, estimate_relative_timing
from bench.analysis.fusion._tuning import (
    ADAPTIVE_SETTINGS,
    FusionTuning,
    SettingsTuning,
    ToneScorer,
    choose,
    crossover_grid,
    tune_fusion,
    tune_settings,
)

DEFAULT_HF = SensorModel("highpass", 1, 2.0, 1.0)  # MHD-class: first-order high-pass at 2 Hz
DEFAULT_LF = SensorModel("lowpass", 1, 30.0, 1.0)  # FOG/MEMS-class: first-order low-pass at 30 Hz
TUNE_FRACTION = 0.4  # the first 40 % of a record with a reference tunes, the rest judges
MIN_JUDGED_PERIODS = 3  # the judged part must hold this many periods of the lowest tone


@dataclass(frozen=True)
class Method:
    """One fusion method: its key (JSON, CSV column ``rate_<key>``), label, whether its
    output at a sample uses only the readings up to it, and how it is tuned."""

    key: str
    label: str
    causal: bool
    tuning: str


METHODS = {m.key: m for m in (
    Method("hf", "HF sensor alone", True, "reading ÷ its fitted passband gain"),
    Method("lf", "LF sensor alone", True, "reading ÷ its fitted passband gain"),
    Method("complementary", "complementary filter", True,
           "both models inverted; crossover chosen on the tuning part (√(f_h·f_l) without a reference)"),
    Method("fused", "Document B: sequential adaptive-R KF", True,
           "process noise, thresholds and interval noise by Document B's grid on the tuning part"),
    Method("fixed_r_kf", "fixed-R Kalman filter", True, "process noise by the same grid, fixed R"),
    Method("complementary_kf", "complementary Kalman filter", True, "sensor noise by maximum likelihood"),
    Method("complementary_kf_adaptive", "complementary KF + Document B's adaptive R", True,
           "noise by maximum likelihood; r_upper and disturbed R chosen on the tuning part"),
    Method("complementary_smoother", "complementary smoother (offline)", False,
           "the complementary Kalman filter's fixed-interval smoother"),
    Method("complementary_smoother_adaptive", "complementary smoother + adaptive R (offline)", False,
           "the smoother of the adaptive-R complementary filter (its R replayed)"),
    # last: on a record with no outliers they equal the methods they clean, and ties go to the earlier
    Method("complementary_clean", "complementary filter, outliers replaced (offline)", False,
           "the complementary filter's crossover, on the record with each sensor's outliers replaced by its "
           "tone fit"),
    Method("complementary_smoother_clean", "complementary smoother, outliers replaced (offline)", False,
           "the complementary smoother's noise, on the record with each sensor's outliers replaced by its "
           "tone fit"),
)}
#: without a reference, the methods tried in this order: the first that passes its consistency checks
#: (:func:`~bench.analysis.fusion._consistency.check_method`) is recommended, else the complementary filter
#: (on the record with its spikes replaced, where any were)
PREFERENCE_WITHOUT_REF = ("complementary_smoother_clean", "complementary_smoother", "complementary_kf")
MIN_CHECK_SAMPLES = 1024  # the checks' Welch spectra need 16 half-overlapped segments of at least 64 samples


@dataclass(frozen=True)
class Judgement:
    """Every method judged against the reference on one stretch (see the module docstring).
    All dicts are keyed by method; per-tone arrays follow ``tones_hz``."""

    tones_hz: np.ndarray
    rms_error: dict
    amplitude_error_pct: dict
    amplitude_error_std_pct: dict
    phase_error_deg: dict
    excess_pct: dict
    excess_std_pct: dict
    excess_best: list
    feasible: dict
    #: per method: excess within two standard errors of the better sensor's own amplitude error
    feasible_sensor: dict

    def worst_excess_pct(self, method: str) -> float:
        return float(np.max(self.excess_pct[method]))

    def worst_excess_sigma(self, method: str) -> float:
        """Largest excess in its own standard errors (0/0 counts as 0)."""
        ex, sd = self.excess_pct[method], self.excess_std_pct[method]
        with np.errstate(divide="ignore", invalid="ignore"):
            z = np.where(sd > 0, ex / sd, np.where(ex > 0, np.inf, 0.0))
        return float(np.max(z))


def judge(t_s, ref, estimates: dict, tones_hz, rate_hz: float) -> Judgement:
    """Judge every estimate (dict of series on ``t_s``; it must hold ``"hf"`` and ``"lf"``, the
    sensors alone) against ``ref`` at the tones: one joint least-squares tone fit gives every
    series' phasors and residual; standard errors from the residuals' local spectrum
    (:func:`~bench.analysis.fusion._metrics.tone_noise_std`)."""
    t = np.asarray(t_s, dtype=float)
    ref = np.asarray(ref, dtype=float)
    tones = np.asarray(tones_hz, dtype=float)
    names = list(estimates)
    if "hf" not in estimates or "lf" not in estimates:
        raise ValueError(f"estimates {names} must include the sensors alone, 'hf' and 'lf'")
    e = {k: np.asarray(v, dtype=float) - ref for k, v in estimates.items()}
    rms = {k: float(np.sqrt(np.mean(v * v))) for k, v in e.items()}
    phasors, resid_all = tone_fit(t, np.column_stack([ref] + [np.asarray(estimates[k], dtype=float)
                                                              for k in names]), tones)
    resid = {k: resid_all[:, j] for j, k in enumerate(names, start=1)}
    ref_amp = np.abs(phasors[:, 0])
    amp, amp_sd, phase = {}, {}, {}
    for col, k in enumerate(names, start=1):
        ratio = phasors[:, col] / phasors[:, 0]
        amp[k] = 100 * (np.abs(ratio) - 1)
        amp_sd[k] = 100 * tone_noise_std(resid[k], rate_hz, tones) / ref_amp
        phase[k] = np.degrees(np.angle(ratio))
    singles = np.abs(np.vstack([amp["hf"], amp["lf"]]))
    best = np.argmin(singles, axis=0)
    idx = np.arange(tones.size)
    own_sd = np.vstack([amp_sd["hf"], amp_sd["lf"]])[best, idx]  # the better sensor's own standard error
    excess, excess_sd, feasible, feasible_sensor = {}, {}, {}, {}
    for k in names:
        # the method and the better sensor share their noise: the excess's standard error comes
        # from the difference series (its residual is the difference of the residuals)
        sd = np.vstack([tone_noise_std(resid[k] - resid[m], rate_hz, tones) for m in ("hf", "lf")])
        excess[k] = np.abs(amp[k]) - singles[best, idx]
        excess_sd[k] = 100 * sd[best, idx] / ref_amp
        finite = bool(np.all(np.isfinite(excess[k])))
        feasible[k] = finite and bool(np.all(excess[k] <= 2 * excess_sd[k]))
        feasible_sensor[k] = finite and bool(np.all(excess[k] <= 2 * own_sd))
    return Judgement(tones, rms, amp, amp_sd, phase, excess, excess_sd, [("hf", "lf")[b] for b in best], feasible,
                     feasible_sensor)


@dataclass(frozen=True)
class _Choice:  # what fusion_tuning.choose reads of a judged method
    rms_error: float
    excess_pct: float
    feasible: bool


BASELINES = ("hf", "lf", "complementary")  # a recommendation is never worse in RMS than the best of these


def recommend(judgement: Judgement) -> tuple[str, str]:
    """The recommended method of a judgement and the rule (module docstring, step 4): among
    the methods whose RMS error is no worse than the best of each sensor alone and the
    complementary filter, the lowest RMS error of those whose excess is within two standard
    errors of itself and of the better sensor's own amplitude error at every tone; if none is,
    of those within two standard errors of the better sensor's own amplitude error; if none is,
    the lowest RMS error."""
    names = [k for k in METHODS if k in judgement.rms_error] + [k for k in judgement.rms_error if k not in METHODS]
    rms = {k: judgement.rms_error[k] if math.isfinite(judgement.rms_error[k]) else math.inf for k in names}
    bar = min((rms[k] for k in BASELINES if k in rms), default=math.inf)
    names = [k for k in names if rms[k] <= bar]
    prefix = "among the methods no worse in RMS than the best of each sensor and the complementary filter: "
    # the sharp tier asks both: where the method and the sensor do not share their noise (an outlier
    # in one of them) the excess's standard error can exceed the sensor's own
    both = {k: judgement.feasible[k] and judgement.feasible_sensor[k] for k in judgement.feasible}
    for feasible, within in ((both, "within 2 standard errors of the excess and of the better sensor's own "
                                    "amplitude error"),
                             (judgement.feasible_sensor, "within 2 standard errors of the better sensor's own "
                                                         "amplitude error (none within 2 of both)")):
        scores = [_Choice(rms[k], judgement.worst_excess_pct(k), feasible[k]) for k in names]
        index, rule = choose(scores)
        if scores[index].feasible:
            return names[index], prefix + rule.replace("within tolerance", within)
    # none meets the amplitude rule: the lowest RMS error on the judged part (the excess of every one
    # is beyond its noise, so it no longer ranks them; ties go to the earlier method)
    best = min(range(len(names)), key=lambda i: (rms[names[i]], i))
    return names[best], prefix + ("none has its excess within 2 standard errors, of the excess or of the sensor, "
                                  "at every tone: the lowest RMS error")


@dataclass
class FusionAnalysis:
    """Every fusion method's rate on one record, its settings, the judgement and the recommendation.

    Everything :func:`analyze_fusion` found.  ``t_s`` and ``estimates`` (every method's rate,
    whole record) stay out of :meth:`to_dict`; the judged metrics (``judgement``, on samples
    ``judged_from`` onwards) go in.

    Rates are in the unit of the reference (each reading ÷ its sensor's gain).

    Attributes
    ----------
    rate_hz : float
        Sample rate, in Hz.
    t_s : ndarray, shape (n,)
        Sample times, in s (after alignment, when the record was aligned).
    model : FusionModel
        Document B's model: both sensor models and the tuned process noise q (rate²/s).
    params : FusionParams
        Document B's measurement-noise settings (sensor unit²).
    model_source : str
        Where the sensor models came from: given, fitted (aligned or not), or default.
    crossover_hz : float
        The complementary filter's crossover, in Hz.
    estimates : dict of str to ndarray
        Every method's rate over the whole record, keyed as :data:`METHODS`.
    nis : dict of str to NisStats
        χ² checks of the Kalman filters' NIS on the judged part.
    r_interval_fraction : dict of str to ndarray
        Fraction of the judged samples in each interval (0, 1, 2) of Document B's rule, per
        sensor (and for the adaptive complementary filter's LF update).
    r_range : dict of str to list of float
        ``[min, max]`` of the R used on the judged part, sensor unit².
    recommended : str
        Key of the recommended method.
    recommendation_rule : str
        The rule that picked it, in words.
    complementary_noise : ComplementaryNoise
        The complementary Kalman filter's noise (maximum likelihood).
    settings : dict of str to dict
        Each method's settings (tuned or given), JSON-ready.
    tune_samples : int
        Samples of the tuning part (0 without a reference).
    judged_from : int
        First judged sample (after tuning and ``settle_s``).
    judgement : Judgement or None
        RMS error, amplitude/phase error and excess per tone for every method; None without
        a reference.
    tuning : FusionTuning or None
        Document B's grid search; None when not tuned.
    noise_fit : NoiseFit or None
        The maximum-likelihood fit behind ``complementary_noise``.
    alignment : PairAlignment or None
        The fitted sensor models, clocks and delays; None unless fitted.
    notes : list of str
        What the analysis assumed or changed.
    timing : RelativeTiming or None
        Without a reference: the LF clock's skew and delay relative to the HF one, from the
        sensors' cross-spectrum (corrected where significant); None otherwise.
    spikes : dict of str to SpikeSearch or None
        Without a reference: the spikes found in each sensor (``"hf"``, ``"lf"``); None otherwise.
    checks : dict of str to MethodCheck or None
        Without a reference: each candidate method's consistency checks; None otherwise.
    n_samples : int
        Property: number of samples.
    recommended_rate : ndarray
        Property: the recommended method's rate.
    rms_error : dict of str to float or None
        Property: each method's RMS error on the judged part; None without a reference.
    """

    rate_hz: float
    t_s: np.ndarray
    model: FusionModel
    params: fu.FusionParams
    model_source: str
    crossover_hz: float
    estimates: dict
    nis: dict
    r_interval_fraction: dict
    r_range: dict
    recommended: str
    recommendation_rule: str
    complementary_noise: fc.ComplementaryNoise
    settings: dict
    tune_samples: int = 0
    judged_from: int = 0
    judgement: Judgement | None = None
    tuning: FusionTuning | None = None
    noise_fit: fc.NoiseFit | None = None
    alignment: PairAlignment | None = None
    notes: list = field(default_factory=list)
    timing: RelativeTiming | None = None
    spikes: dict | None = None
    checks: dict | None = None

    @property
    def n_samples(self) -> int:
        return int(self.t_s.size)

    @property
    def recommended_rate(self) -> np.ndarray:
        return self.estimates[self.recommended]

    @property
    def rms_error(self) -> dict | None:
        return None if self.judgement is None else self.judgement.rms_error

    def to_dict(self) -> dict:
        def floats(v):
            return [float(x) for x in v]

        j = self.judgement
        doc = {
            "rate_hz": float(self.rate_hz), "n_samples": self.n_samples, "model": self.model.to_dict(),
            "model_source": self.model_source, "params": self.params.to_dict(),
            "crossover_hz": float(self.crossover_hz), "complementary_noise": self.complementary_noise.to_dict(),
            "recommended": self.recommended, "recommendation_rule": self.recommendation_rule,
            "methods": {k: {"label": m.label, "causal": m.causal, "tuning": m.tuning, "settings": self.settings.get(k)}
                        for k, m in METHODS.items() if k in self.estimates},
            "tune_samples": int(self.tune_samples), "judged_from": int(self.judged_from),
            "rms_error": None, "tones_hz": None, "amplitude_error_pct": None, "amplitude_error_std_pct": None,
            "phase_error_deg": None, "excess_pct": None, "excess_std_pct": None, "excess_best": None,
            "feasible": None, "feasible_sensor": None,
            "nis": {k: v.to_dict() for k, v in self.nis.items()},
            "r_interval_fraction": {k: floats(v) for k, v in self.r_interval_fraction.items()},
            "r_range": {k: floats(v) for k, v in self.r_range.items()},
            "tuning": None if self.tuning is None else self.tuning.to_dict(),
            "noise_fit": None if self.noise_fit is None else self.noise_fit.to_dict(),
            "alignment": None if self.alignment is None else self.alignment.to_dict(),
            "notes": list(self.notes),
            "timing": None if self.timing is None else self.timing.to_dict(),
            "spikes": None if self.spikes is None else {k: v.to_dict() for k, v in self.spikes.items()},
            "checks": None if self.checks is None else {k: v.to_dict() for k, v in self.checks.items()},
        }
        if j is not None:
            doc.update({"rms_error": {k: float(v) for k, v in j.rms_error.items()}, "tones_hz": floats(j.tones_hz),
                        "excess_best": list(j.excess_best), "feasible": dict(j.feasible),
                        "feasible_sensor": dict(j.feasible_sensor)})
            for name in ("amplitude_error_pct", "amplitude_error_std_pct", "phase_error_deg", "excess_pct",
                         "excess_std_pct"):
                doc[name] = {k: floats(v) for k, v in getattr(j, name).items()}
        return doc


def excess_over_best(analysis: dict, method: str = "fused") -> tuple[np.ndarray, np.ndarray]:
    """Per tone, a method's amplitude error in excess of the better single sensor's, with its standard error.

    Per tone: ``method``'s |amplitude error| less the better single sensor's (pp) and the
    standard error of that difference, from an analysis dict (:meth:`FusionAnalysis.to_dict`;
    also a stored analysis from before the methods were many, where ``excess_pct`` was
    Document B's alone — or absent, then from each series' own standard error, an
    overestimate: the two share their noise).

    Parameters
    ----------
    analysis : dict
        An analysis as :meth:`FusionAnalysis.to_dict` writes it (or a stored older one): with
        ``excess_pct``/``excess_std_pct`` per method, or ``amplitude_error_pct`` (and
        optionally ``amplitude_error_std_pct``) per series including ``"hf"`` and ``"lf"``.
    method : str, default "fused"
        The method's key (:data:`METHODS`).

    Returns
    -------
    excess : ndarray
        Per tone, the method's |amplitude error| less the better single sensor's, in
        percentage points.
    excess_std : ndarray
        Its standard error, in percentage points.

    Examples
    --------
    >>> from bench.analysis.fusion import excess_over_best
    >>> old = {"amplitude_error_pct": {"hf": [-0.1, -40.0], "lf": [-30.0, 0.2], "fused": [0.3, -0.5]},
    ...        "amplitude_error_std_pct": {"hf": [0.1, 0.1], "lf": [0.1, 0.1], "fused": [0.1, 0.1]}}
    >>> ex, sd = excess_over_best(old)  # |0.3| − |−0.1|, |−0.5| − |0.2|
    >>> ex.round(3).tolist(), sd.round(3).tolist()
    ([0.2, 0.3], [0.141, 0.141])
    >>> new = {"excess_pct": {"fused": [0.2, 0.3]}, "excess_std_pct": {"fused": [0.05, 0.05]}}
    >>> excess_over_best(new)[1].tolist()
    [0.05, 0.05]
    """
    ex = analysis.get("excess_pct")
    if isinstance(ex, dict):
        return np.asarray(ex[method], dtype=float), np.asarray(analysis["excess_std_pct"][method], dtype=float)
    if ex is not None and method == "fused":
        return np.asarray(ex, dtype=float), np.asarray(analysis["excess_std_pct"], dtype=float)
    amp = {k: np.abs(np.asarray(v, dtype=float)) for k, v in analysis["amplitude_error_pct"].items()}
    sd = analysis.get("amplitude_error_std_pct") or {k: np.zeros_like(v) for k, v in amp.items()}
    sd = {k: np.asarray(v, dtype=float) for k, v in sd.items()}
    which = np.argmin(np.vstack([amp["hf"], amp["lf"]]), axis=0)
    idx = np.arange(which.size)
    best = np.vstack([amp["hf"], amp["lf"]])[which, idx]
    best_sd = np.vstack([sd["hf"], sd["lf"]])[which, idx]
    return amp[method] - best, np.hypot(sd[method], best_sd)


def _check_inputs(t, hf, lf, ref, rate_hz, tune_fraction, settle_s):
    t = np.asarray(t, dtype=float).ravel()
    hf, lf = fu.check_series(hf, lf)
    if t.size != hf.size:
        raise ValueError(f"t has {t.size} samples and hf {hf.size}; they must match")
    if rate_hz is None:
        rate_hz = (t.size - 1) / float(t[-1] - t[0]) if t[-1] > t[0] else math.nan
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise ValueError(f"rate_hz {rate_hz} must be a finite value > 0")
    if ref is not None:
        ref = np.asarray(ref, dtype=float).ravel()
        if ref.size != hf.size or not np.all(np.isfinite(ref)):
            raise ValueError(f"ref must have {hf.size} finite samples like hf (has {ref.size})")
    if not (math.isfinite(tune_fraction) and 0 <= tune_fraction <= 0.7):
        raise ValueError(f"tune_fraction {tune_fraction} must be in [0, 0.7]")
    if not (math.isfinite(settle_s) and settle_s >= 0):
        raise ValueError(f"settle_s {settle_s} must be a finite value ≥ 0")
    return t, hf, lf, ref, float(rate_hz)


def analyze_fusion(t, hf, lf, ref=None, rate_hz: float | None = None, *, hf_model: SensorModel | None = None,
                   lf_model: SensorModel | None = None, tones_hz=None, crossover_hz: float | None = None,
                   params: fu.FusionParams | None = None, q: float | None = None, settle_s: float = 0.0,
                   discretization: str = "euler", alpha: float = 0.05, tune_fraction: float = TUNE_FRACTION,
                   align: bool = True, hf_delay_s: float = 0.0, lf_delay_s: float = 0.0) -> FusionAnalysis:
    """Every rate-fusion method on one HF/LF record: tuned, judged against a reference and one recommended.

    Tune every method on the first part, judge on the rest and recommend one (module
    docstring).  Models: the given ones; else, with ``ref`` and ≥ 4 tones, fitted (with delays,
    the record aligned if ``align``); else :data:`DEFAULT_HF`/:data:`DEFAULT_LF`.
    ``crossover_hz``, ``params`` and ``q`` fix what they name instead of tuning it.  With
    ``tune_fraction`` 0 nothing is tuned against the reference and the whole record is judged.
    Without ``ref`` nothing can be judged: each sensor's spikes are replaced
    (:func:`find_spikes`), the LF record put on the HF clock (:func:`estimate_relative_timing`),
    every method runs with settings from the data alone, and the first of
    :data:`PREFERENCE_WITHOUT_REF` that passes its consistency checks is recommended, else the
    complementary filter (module docstring).

    Parameters
    ----------
    t : array_like, shape (n,)
        Sample times, in s (one grid for both sensors).
    hf : array_like, shape (n,)
        HF sensor readings, its output unit; finite.
    lf : array_like, shape (n,)
        LF sensor readings, its output unit; finite.
    ref : array_like, shape (n,), optional
        The table's reference rate (rate unit), finite; None: nothing is tuned or judged.
    rate_hz : float, optional
        Sample rate, in Hz, finite and > 0; default from ``t``.
    hf_model : SensorModel, optional
        The HF sensor's model; default fitted against ``ref`` (≥ 4 tones) or
        :data:`DEFAULT_HF` (high-pass, 2 Hz).
    lf_model : SensorModel, optional
        The LF sensor's model; default fitted or :data:`DEFAULT_LF` (low-pass, 30 Hz).
    tones_hz : array_like, optional
        The reference's tones, in Hz, within (0, ``rate_hz``/2); default detected in ``ref``.
    crossover_hz : float, optional
        Fix the complementary filter's crossover, in Hz, instead of tuning it.
    params : FusionParams, optional
        Fix Document B's measurement-noise settings instead of tuning them.
    q : float, optional
        Fix Document B's process noise, rate²/s, instead of tuning it.
    settle_s : float, default 0.0
        Start-up left out of the judged part after the tuning part, in s; finite and ≥ 0.
    discretization : {"euler", "zoh"}, default "euler"
        Discretisation of Document B's model.
    alpha : float, default 0.05
        Significance of the NIS χ² checks, in (0, 1).
    tune_fraction : float, default 0.4
        Fraction of the record that tunes (with ``ref``), in [0, 0.7].
    align : bool, default True
        Align the record before running the methods: with fitted models, clock rates and delays
        against ``ref``; without ``ref``, the LF clock's skew and delay relative to the HF one
        from their cross-spectrum, where significant.
    hf_delay_s, lf_delay_s : float, default 0.0
        Known delays of the sensors' readings (s, finite, within ±1 s; without ``ref``): the LF
        record is moved by their difference before the rest of its delay is estimated, and
        ``t_s`` is the HF sensor's instants less its delay.

    Returns
    -------
    FusionAnalysis
        Every method's rate, its settings, the judgement on the judged part (with ``ref``),
        the NIS checks and the recommended method with its rule.

    Raises
    ------
    ValueError
        If the series are not finite and of one length, ``rate_hz``, ``tune_fraction`` or
        ``settle_s`` is out of range, ``ref`` is not finite or not as long, the tones are empty
        or outside (0, Nyquist), or the judged part holds fewer than 3 periods of the lowest
        tone.

    Examples
    --------
    Without a reference, on the two-tone record of :func:`sequential_fusion`'s example; the
    caller, who knows the true rate here, judges the estimates himself:

    >>> import numpy as np
    >>> from bench.analysis.fusion import SensorModel, analyze_fusion
    >>> hf_model, lf_model = SensorModel("highpass", 1, 2.0), SensorModel("lowpass", 1, 30.0)
    >>> fs, f = 1000.0, np.array([0.5, 100.0])  # 1 kHz; a slow and a fast tone, 1 dps each
    >>> t = np.arange(4000) / fs
    >>> rng = np.random.default_rng(0)
    >>> def read(model, sd):  # the sensor's steady-state reading of the tones, plus white noise
    ...     g = model.response(f)
    ...     y = np.sum(np.abs(g) * np.sin(2 * np.pi * np.outer(t, f) + np.angle(g)), axis=1)
    ...     return y + sd * rng.standard_normal(t.size)
    >>> rate = np.sin(2 * np.pi * np.outer(t, f)).sum(axis=1)
    >>> hf, lf = read(hf_model, 0.02), read(lf_model, 0.01)
    >>> def rms(x):  # error against the true rate after the first second, dps
    ...     return round(float(np.sqrt(np.mean((x - rate)[1000:] ** 2))), 3)
    >>> rms(hf / hf_model.gain), rms(lf / lf_model.gain)  # each sensor alone loses one tone
    (0.687, 0.678)
    >>> a = analyze_fusion(t, hf, lf, rate_hz=fs, hf_model=hf_model, lf_model=lf_model)
    >>> a.recommended, a.judgement is None, a.model_source
    ('complementary_smoother', True, 'given')
    >>> rms(a.recommended_rate), rms(a.estimates["complementary_kf"]), rms(a.estimates["fused"])
    (0.019, 0.02, 0.057)
    >>> round(a.complementary_noise.hf_var / 0.02 ** 2, 1)  # noise by maximum likelihood
    0.9
    """
    t, hf, lf, ref, rate_hz = _check_inputs(t, hf, lf, ref, rate_hz, tune_fraction, settle_s)
    for name, v in (("hf_delay_s", hf_delay_s), ("lf_delay_s", lf_delay_s)):
        if not (math.isfinite(v) and abs(v) <= 1.0):
            raise ValueError(f"{name} {v} must be a finite value within [-1, 1] s")
    notes: list[str] = []
    tones = None
    if ref is not None:
        tones = detect_tones(ref, rate_hz) if tones_hz is None else np.asarray(tones_hz, dtype=float)
        if tones.size == 0 or np.any(tones <= 0) or np.any(tones >= rate_hz / 2):
            raise ValueError(f"tones_hz must be non-empty and within (0, {rate_hz / 2:g}) Hz")
    n_tune = int(round(tune_fraction * t.size)) if ref is not None else 0
    alignment = None
    hf_clean = lf_clean = None
    if hf_model is not None and lf_model is not None:
        source = "given"
    elif ref is not None and tones is not None and tones.size >= MIN_TONES:
        fit_part = slice(0, n_tune) if n_tune else slice(None)
        aligned, alignment = fit_and_align(t, hf, lf, ref, tones, rate_hz, fit_part)
        hf_model = hf_model or alignment.hf_fit.model
        lf_model = lf_model or alignment.lf_fit.model
        notes.extend(alignment.notes)
        if align:
            n_tune = max(0, n_tune - alignment.trimmed_start)
            t, hf, lf, ref = aligned["t_s"], aligned["hf"], aligned["lf"], aligned["ref"]
            hf_clean, lf_clean = aligned["hf_clean"], aligned["lf_clean"]
            source = "fitted to the FRF against ref, clocks and delays aligned"
        else:
            source = "fitted to the FRF against ref (not aligned)"
    else:
        hf_model, lf_model = hf_model or DEFAULT_HF, lf_model or DEFAULT_LF
        source = "default"
        notes.append(f"sensor models are defaults (HF high-pass {DEFAULT_HF.corner_hz:g} Hz, LF low-pass "
                     f"{DEFAULT_LF.corner_hz:g} Hz); pass models or a ref")
    timing = spikes = None
    if ref is not None and (hf_delay_s or lf_delay_s):
        notes.append("the given delays are not used with a reference (they are fitted with the models, or the "
                     "given models are taken as they are)")
    if ref is None:
        t, hf, lf, hf_clean, lf_clean, timing, spikes = _prepare_without_ref(
            t, hf, lf, rate_hz, hf_model, lf_model, align, hf_delay_s, lf_delay_s, notes)
    settle = int(round(settle_s * rate_hz))
    judged_from = n_tune + settle
    if ref is not None and tones is not None:
        judged_s = (t.size - judged_from) / rate_hz
        if judged_s * tones.min() < MIN_JUDGED_PERIODS:
            raise ValueError(f"the judged part ({judged_s:.3g} s after tuning {n_tune} samples and settling "
                             f"{settle_s:g} s) holds fewer than {MIN_JUDGED_PERIODS} periods of the lowest tone "
                             f"{tones.min():.3g} Hz: record longer or lower tune_fraction")
    ts = 1.0 / rate_hz
    tune = slice(0, n_tune) if n_tune else slice(None)
    settings: dict = {}

    # noise of each sensor for Document B and the fixed-R filter (outliers left out of the estimate)
    if ref is not None and tones is not None:
        clean = without_outliers(t[tune], np.column_stack([hf[tune], lf[tune]]), tones)[0]
        hf_var, lf_var = (float(v) for v in tone_residual_var(t[tune], clean, tones))
    else:  # spikes (replaced without a reference) left out of the estimate
        hf_var, lf_var = fu.white_noise_var(hf_clean), fu.white_noise_var(lf_clean)
    hf_var, lf_var = max(hf_var, 1e-30), max(lf_var, 1e-30)
    if hf_clean is None and ref is not None and tones is not None:  # not aligned: cleaned on the given clock
        hf_clean, lf_clean = without_outliers(t, np.column_stack([hf, lf]), tones)[0].T
    if hf_clean is None or lf_clean is None:  # no tones, nothing to tell an outlier by
        hf_clean, lf_clean = hf, lf
    cleaned = not (np.array_equal(hf_clean, hf) and np.array_equal(lf_clean, lf))

    scorer = None
    if n_tune and tones is not None and ref is not None:
        # the tuning part's first second (at most a quarter of it) is the filters' start-up
        scorer = ToneScorer(t[tune], ref[tune], [hf[tune] / hf_model.gain, lf[tune] / lf_model.gain], tones, rate_hz,
                            min(int(round(rate_hz)), n_tune // 4))

    # Document B and the fixed-R filter
    model, default_params = fu.tune_fusion_params(hf_model, lf_model, hf_var, lf_var, hf[tune], lf[tune], ts,
                                                  discretization=discretization)
    tuning = None
    q_fixed = model.q
    if params is None and q is None and scorer is not None and ref is not None:
        tuning = tune_fusion(t[tune], hf[tune], lf[tune], ref[tune], rate_hz, model, hf_var, lf_var, tones,
                             settle_s=scorer.keep.start / rate_hz, discretization=discretization)
        params = tuning.params(hf_var, lf_var, discretization)
        q_fixed = tuning.q_base * tuning.fixed_r().q_factor
        model = FusionModel(hf_model, lf_model, tuning.q)
    if q is not None:
        model = FusionModel(hf_model, lf_model, q)
        q_fixed = q
    params = params or default_params
    settings["fused"] = {"q": float(model.q), **params.to_dict()}
    settings["fixed_r_kf"] = {"q": float(q_fixed), "hf_r": float(params.hf_noise.nominal),
                              "lf_r": float(params.lf_noise.nominal)}

    # complementary filter
    cf_tuning: SettingsTuning | None = None
    if crossover_hz is None and scorer is not None:
        cf_model = FusionModel(hf_model, lf_model, 1.0)
        cf_tuning = tune_settings(
            scorer, crossover_grid(hf_model.corner_hz, lf_model.corner_hz, rate_hz),
            lambda crossover_hz: fu.complementary_filter(hf[tune], lf[tune], rate_hz, cf_model, crossover_hz),
            rms_only=True)
        crossover_hz = float(cf_tuning.chosen["crossover_hz"])
    elif crossover_hz is None:
        crossover_hz = math.sqrt(hf_model.corner_hz * lf_model.corner_hz)
    settings["complementary"] = {"crossover_hz": float(crossover_hz),
                                 "tuning": None if cf_tuning is None else cf_tuning.to_dict()}

    # complementary Kalman filter: noise by maximum likelihood, adaptive R on top chosen by the rule
    if ref is not None and tones is not None:  # the likelihood sees the noise, outliers left out
        noise_fit = fc.fit_complementary_noise(clean[:, 0], clean[:, 1], ts, hf_model, lf_model, tones_hz=tones,
                                               t_s=t[tune])
    else:  # spikes (replaced without a reference) left out of the likelihood
        noise_fit = fc.fit_complementary_noise(hf_clean[tune], lf_clean[tune], ts, hf_model, lf_model)
    cnoise = noise_fit.noise
    settings["complementary_kf"] = settings["complementary_smoother"] = {"noise": cnoise.to_dict()}
    ad_tuning: SettingsTuning | None = None
    adaptive = {"upper_factor": fu.UPPER_FACTOR, "inflate": fu.INFLATE}
    if scorer is not None:
        ad_tuning = tune_settings(
            scorer, list(ADAPTIVE_SETTINGS),
            lambda upper_factor, inflate: fc.complementary_kalman(
                hf[tune], lf[tune], ts, hf_model, lf_model, cnoise,
                lf_noise=fu.AdaptiveNoise.from_noise(cnoise.lf_var, 0.0, upper_factor, inflate)).rate)
        adaptive = dict(ad_tuning.chosen)
    lf_adaptive = fu.AdaptiveNoise.from_noise(cnoise.lf_var, 0.0, adaptive["upper_factor"], adaptive["inflate"])
    settings["complementary_kf_adaptive"] = settings["complementary_smoother_adaptive"] = {
        "noise": cnoise.to_dict(), "lf_noise": lf_adaptive.to_dict(),
        "tuning": None if ad_tuning is None else ad_tuning.to_dict()}

    # every method over the whole record
    seq = fu.sequential_fusion(hf, lf, ts, model, params)
    fixed = fu.fixed_r_kalman(hf, lf, ts, FusionModel(hf_model, lf_model, q_fixed), params)
    ckf = fc.complementary_kalman(hf, lf, ts, hf_model, lf_model, cnoise, smooth=True)
    ckf_ad = fc.complementary_kalman(hf, lf, ts, hf_model, lf_model, cnoise, lf_noise=lf_adaptive, smooth=True)
    estimates = {"hf": hf / hf_model.gain, "lf": lf / lf_model.gain,
                 "complementary": fu.complementary_filter(hf, lf, rate_hz, model, crossover_hz),
                 "fused": seq.rate, "fixed_r_kf": fixed.rate, "complementary_kf": ckf.rate,
                 "complementary_kf_adaptive": ckf_ad.rate, "complementary_smoother": ckf.smoothed,
                 "complementary_smoother_adaptive": ckf_ad.smoothed}
    ckf_clean = ckf
    if cleaned:
        estimates["complementary_clean"] = fu.complementary_filter(hf_clean, lf_clean, rate_hz, model, crossover_hz)
        ckf_clean = fc.complementary_kalman(hf_clean, lf_clean, ts, hf_model, lf_model, cnoise, smooth=True)
        estimates["complementary_smoother_clean"] = ckf_clean.smoothed
    else:
        estimates["complementary_clean"] = estimates["complementary"]
        estimates["complementary_smoother_clean"] = estimates["complementary_smoother"]
    settings["complementary_clean"] = {**settings["complementary"], "outliers_replaced": cleaned}
    settings["complementary_smoother_clean"] = {**settings["complementary_smoother"], "outliers_replaced": cleaned}

    keep = slice(judged_from, None)
    nis = {"fused_hf": nis_check(seq.nis[keep, 0], 1, alpha, seq.rate),
           "fused_lf": nis_check(seq.nis[keep, 1], 1, alpha, seq.rate),
           "fused": nis_check(seq.nis[keep].sum(axis=1), 2, alpha, seq.rate),
           "fixed_r_kf": nis_check(fixed.nis[keep, 0], 2, alpha, fixed.rate),
           "complementary_kf": nis_check(ckf.nis[keep], 1, alpha, ckf.rate),
           "complementary_kf_adaptive": nis_check(ckf_ad.nis[keep], 1, alpha, ckf_ad.rate)}
    if cleaned:  # the cleaned smoother's own filter
        nis["complementary_kf_clean"] = nis_check(ckf_clean.nis[keep], 1, alpha, ckf_clean.rate)
    frac = {n: np.bincount(seq.interval[keep, j], minlength=3) / seq.interval[keep, j].size
            for j, n in enumerate(("hf", "lf"))}
    frac["complementary_lf"] = np.bincount(ckf_ad.interval[keep], minlength=3) / ckf_ad.interval[keep].size
    r_range = {n: [float(seq.r[keep, j].min()), float(seq.r[keep, j].max())] for j, n in enumerate(("hf", "lf"))}
    r_range["complementary_lf"] = [float(ckf_ad.r[keep].min()), float(ckf_ad.r[keep].max())]

    judgement = checks = None
    if ref is not None and tones is not None:
        judgement = judge(t[keep], ref[keep], {k: v[keep] for k, v in estimates.items()}, tones, rate_hz)
        recommended, rule = recommend(judgement)
        rule = ("judged on samples after the tuning part: " if n_tune else "judged on the whole record: ") + rule
    else:
        checks = check_without_ref(estimates, hf_clean, lf_clean, hf_model, lf_model, rate_hz, nis, cleaned, cnoise)
        recommended, rule = recommend_without_ref(checks)
    return FusionAnalysis(rate_hz, t, model, params, source, crossover_hz, estimates, nis, frac, r_range, recommended,
                          rule, cnoise, settings, n_tune, judged_from, judgement, tuning, noise_fit, alignment, notes,
                          timing, spikes, checks)


def _prepare_without_ref(t, hf, lf, rate_hz: float, hf_model: SensorModel, lf_model: SensorModel, align: bool,
                         hf_delay_s: float, lf_delay_s: float, notes: list) -> tuple:
    """Without a reference: each sensor's spikes found and a cleaned copy made (:func:`find_spikes`),
    the LF record moved by the given delays' difference, then by its skew and the rest of its
    delay relative to the HF record (from the cleaned copies' cross-spectrum) where significant.
    Returns ``t, hf, lf, hf_clean, lf_clean, timing, spikes``."""
    if len(hf) > 4 * SPIKE_HALF_WIDTH:
        hf_clean, hf_spikes = find_spikes(hf)
        lf_clean, lf_spikes = find_spikes(lf)
    else:  # too short to interpolate a sample from its neighbours
        none = SpikeSearch(np.zeros(0, dtype=int), math.inf, 0.0, 0.0)
        hf_clean, hf_spikes, lf_clean, lf_spikes = hf, none, lf, none
        notes.append(f"spikes not searched: {len(hf)} samples (more than {4 * SPIKE_HALF_WIDTH} needed)")
    spikes = {"hf": hf_spikes, "lf": lf_spikes}
    if hf_spikes.index.size or lf_spikes.index.size:
        runs = len(hf_spikes.runs) + len(lf_spikes.runs)
        notes.append(f"spikes replaced in the cleaned copy: {hf_spikes.index.size} HF and {lf_spikes.index.size} LF "
                     f"samples (interpolation residual beyond {hf_spikes.threshold_sigma:.3g} robust σ)"
                     + (f", {runs} dropout run{'s' if runs > 1 else ''} among them (each filled from its neighbours)"
                        if runs else ""))
    t = t - hf_delay_s
    given = lf_delay_s - hf_delay_s
    if given:
        known = RelativeTiming(0.0, 0.0, given, 0.0, float(t[0]), (math.nan, math.nan), 0, 0, math.nan, False, True)
        part, lf = align_relative(t, lf, known, rate_hz)
        lf_clean = align_relative(t, lf_clean, known, rate_hz)[1]
        t, hf, hf_clean = t[part], hf[part], hf_clean[part]
    timing = None
    if align:
        timing = estimate_relative_timing(hf_clean, lf_clean, rate_hz, hf_model, lf_model, t0_s=float(t[0]))
        part, lf_new = align_relative(t, lf, timing, rate_hz)
        if timing.skew_corrected or timing.delay_corrected:
            lf_clean = align_relative(t, lf_clean, timing, rate_hz)[1]
            t, hf, hf_clean, lf = t[part], hf[part], hf_clean[part], lf_new
        skew = ("not measured" if not math.isfinite(timing.skew_ppm) else
                f"{timing.skew_ppm:+.3g} ± {timing.skew_std_ppm:.2g} ppm "
                f"({'corrected' if timing.skew_corrected else 'not significant: not corrected'})")
        if timing.n_bins == 0:
            notes.append("LF clock relative to HF not measured: no band where both sensors read the same motion")
        else:
            notes.append(f"LF clock relative to HF from their cross-spectrum ({timing.band_hz[0]:.3g}–"
                         f"{timing.band_hz[1]:.3g} Hz): skew {skew}; delay {timing.delay_s * 1e3:+.4g} ± "
                         f"{timing.delay_std_s * 1e3:.2g} ms "
                         f"({'corrected' if timing.delay_corrected else 'not significant: not corrected'})")
    if not hf_spikes.index.size:
        hf_clean = hf
    if not lf_spikes.index.size:
        lf_clean = lf
    return t, hf, lf, hf_clean, lf_clean, timing, spikes


def check_without_ref(estimates: dict, hf, lf, hf_model: SensorModel, lf_model: SensorModel, rate_hz: float,
                      nis: dict, cleaned: bool, noise: fc.ComplementaryNoise | None = None) -> dict:
    """Every candidate of :data:`PREFERENCE_WITHOUT_REF` checked on the (cleaned) record
    (:func:`~bench.analysis.fusion._consistency.check_method`), the complementary filter on the
    same record the yardstick; a Kalman method whose NIS diverged fails; a cleaned method where
    nothing was replaced is not checked (it is its uncleaned twin).  The yardstick's own check
    (against the sensors' noise alone) is reported under its key.  Each sensor's noise level is
    the lowest of its reading's PSD in the noise band and of the level the sensors' difference
    shows (:func:`~bench.analysis.fusion._consistency.difference_noise`) — upper bounds both:
    motion and model error only add — and the white noise of ``noise`` (the fitted model's own):
    a method is held to the tightest noise the data or its own model claim."""
    fallback = "complementary_clean" if cleaned else "complementary"
    if len(hf) < MIN_CHECK_SAMPLES:  # nothing to check on: nothing is trusted beyond the complementary filter
        short = MethodCheck(False, f"the record ({len(hf)} samples) is too short to check (≥ {MIN_CHECK_SAMPLES})")
        return {key: short for key in (*PREFERENCE_WITHOUT_REF, fallback) if cleaned or not key.endswith("_clean")}
    nper = welch_segment(len(hf))
    levels = [sensor_noise(hf, rate_hz, nper), sensor_noise(lf, rate_hz, nper)]
    bounds = [list(difference_noise(hf, lf, hf_model, lf_model, rate_hz))]
    if noise is not None:
        bounds.append([2 * noise.hf_var / rate_hz, 2 * noise.lf_var / rate_hz])
    levels = [replace(level, psd=float(np.nanmin([level.psd] + [b[i] for b in bounds])))
              for i, level in enumerate(levels)]
    checks: dict = {}
    for key in (*PREFERENCE_WITHOUT_REF, fallback):
        if key.endswith("_clean") and not cleaned:
            continue
        own = "complementary_kf_clean" if key.endswith("_clean") else "complementary_kf"
        stats = nis.get(own) if key.startswith(("complementary_kf", "complementary_smoother")) else None
        if stats is not None and stats.diverged:
            checks[key] = MethodCheck(False, "its filter's normalised innovations diverged")
            continue
        checks[key] = check_method(estimates[key], hf, lf, hf_model, lf_model, rate_hz, noise=tuple(levels),
                                   yardstick=None if key == fallback else estimates[fallback])
    return checks


def recommend_without_ref(checks: dict) -> tuple[str, str]:
    """The first method of :data:`PREFERENCE_WITHOUT_REF` that passed its checks, else the
    complementary filter (cleaned where spikes were replaced), and the rule in words."""
    failed: list[str] = []
    for key in PREFERENCE_WITHOUT_REF:
        check = checks.get(key)
        if check is None:
            continue
        if check.passed:
            return key, ("no reference: the first of " + ", ".join(PREFERENCE_WITHOUT_REF) + " that passes its "
                         "consistency checks (read back through each sensor's model, it agrees with that sensor "
                         "within its noise or as well as the complementary filter does)"
                         + (f"; failed: {'; '.join(failed)}" if failed else ""))
        failed.append(f"{key} ({check.reason})")
    fallback = "complementary_clean" if "complementary_clean" in checks else "complementary"
    return fallback, ("no reference and no candidate passes its consistency checks: the complementary filter"
                      + (" on the record with its spikes replaced" if fallback.endswith("_clean") else "")
                      + "; failed: " + "; ".join(failed))
