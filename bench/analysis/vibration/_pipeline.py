"""Document C's random-vibration error model of a gyro channel, as one pure pipeline.

:func:`analyze_vibration` takes a uniformly sampled rate record ``y(n)`` (any unit, e.g.
°/s) and returns a :class:`VibrationAnalysis`:

1. EMD of ``y`` (:mod:`bench.analysis.emd`) and the non-random terms ``u + s`` chosen from
   it by the rule of :func:`bench.analysis.emd.nonrandom_terms` (residue = trend; too-slow
   IMFs = trend; line-dominated IMFs = periodic).
2. Every remaining (random) IMF is tested and modelled (:mod:`._ar_models`): ADF/KPSS,
   Ljung–Box and the autocorrelation criterion, ACF/PACF identification, AIC/BIC over
   AR(1..p_max), Yule–Walker estimates, residual whiteness.
3. Each random IMF is fitted twice (:mod:`._ar_kalman`): the AR one-step prediction and
   the AR-based Kalman filtered estimate (P0 = I, X0 = the first p samples, R =
   ``r_ratio`` × the AR innovation variance).  The IMF fits plus the non-random terms
   give the two fits of ``y(n)``; their errors ``y − fit`` are summarised as in
   Document C's table (mean and standard deviation, in ``y``'s unit), over the samples
   from ``max p`` on, where every IMF's filter has started.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench.analysis.emd import STOP_RULES, EmdResult, NonRandomTerms, StopRule, emd, nonrandom_terms
from bench.analysis.startup import json_safe, validate_trace
from bench.analysis.vibration._ar_kalman import KalmanFit, ar_predict, kalman_ar_fit
from bench.analysis.vibration._ar_models import ImfModel, model_imf

MIN_SAMPLES = 256


@dataclass(frozen=True)
class FitError:
    """Statistics of ``y − fit`` over the compared samples, in ``y``'s unit.

    Attributes
    ----------
    mean : float
        Mean error, in ``y``'s unit.
    std : float
        Standard deviation of the error, in ``y``'s unit (Document C's table).
    rms : float
        Root mean square error, in ``y``'s unit.
    samples : int
        Number of samples compared.
    """

    mean: float
    std: float
    rms: float
    samples: int

    @classmethod
    def of(cls, err: np.ndarray) -> FitError:
        """Statistics of the error samples ``err``."""
        return cls(float(err.mean()), float(err.std()), float(np.sqrt(np.mean(err**2))), int(err.size))

    def to_dict(self) -> dict:
        """JSON-ready ``{"mean", "std", "rms", "samples"}``."""
        return {"mean": self.mean, "std": self.std, "rms": self.rms, "samples": self.samples}


@dataclass(frozen=True, eq=False)
class VibrationAnalysis:
    """Every intermediate result of :func:`analyze_vibration`.

    Attributes
    ----------
    time_s : ndarray of float, shape (n,)
        Sample times, in s.
    y : ndarray of float, shape (n,)
        The record, in its unit (e.g. deg/s).
    rate_hz : float
        Sampling rate from the mean interval, in Hz.
    decomposition : EmdResult
        Step 1: the EMD of ``y``.
    terms : NonRandomTerms
        Step 1: every component labelled trend, periodic or random; ``terms.signal`` is ``u + s``.
    models : tuple of ImfModel
        Step 2: one per random IMF, in IMF order.
    kalman : tuple of KalmanFit
        Step 3: the AR-Kalman fit of each random IMF, same order.
    fit_ar : ndarray of float, shape (n,)
        Non-random terms + Σ AR one-step predictions, in ``y``'s unit.
    fit_ar_kalman : ndarray of float, shape (n,)
        Non-random terms + Σ Kalman filtered estimates, in ``y``'s unit.
    compared_from : int
        First sample of the error statistics (the largest AR order).
    error_ar : FitError
        Statistics of ``y − fit_ar``, in ``y``'s unit.
    error_ar_kalman : FitError
        Statistics of ``y − fit_ar_kalman``, in ``y``'s unit.
    settings : dict
        The options used.
    notes : tuple of str
        Warnings a user should read (white or non-stationary IMFs, non-AR identification, …).
    std_ratio : float
        Property: AR+Kalman error std over AR error std (Document C: ≈ 0.44); NaN if the
        AR error std is 0.
    """

    time_s: np.ndarray
    y: np.ndarray
    rate_hz: float
    decomposition: EmdResult
    terms: NonRandomTerms
    models: tuple[ImfModel, ...]  # one per random IMF, in IMF order
    kalman: tuple[KalmanFit, ...]  # same order
    fit_ar: np.ndarray  # non-random terms + Σ AR one-step predictions
    fit_ar_kalman: np.ndarray  # non-random terms + Σ Kalman filtered estimates
    compared_from: int  # first sample of the error statistics
    error_ar: FitError
    error_ar_kalman: FitError
    settings: dict
    notes: tuple[str, ...]

    @property
    def std_ratio(self) -> float:
        """AR+Kalman error std over AR error std (Document C: 0.0018 / 0.0041 ≈ 0.44)."""
        return self.error_ar_kalman.std / self.error_ar.std if self.error_ar.std > 0 else float("nan")

    def to_dict(self) -> dict:
        """JSON-ready summary (no sample arrays): EMD, components, IMF models, fit errors, notes."""
        dec = self.decomposition
        models = []
        for m, k in zip(self.models, self.kalman):
            d = m.to_dict()
            d["kalman"] = {"r": k.r, "q": k.q, "gain": k.gain.tolist(), "steady_from": k.steady_from}
            models.append(d)
        return json_safe({
            "samples": int(self.y.size), "rate_hz": self.rate_hz,
            "duration_s": float(self.time_s[-1] - self.time_s[0]),
            "imfs": dec.n_imfs,
            "emd": {"stop": dec.stop, "sifts": list(dec.sifts), "converged": list(dec.converged),
                    "reconstruction_error": float(np.max(np.abs(dec.reconstruct() - self.y)))},
            "nonrandom": [c.to_dict() for c in self.terms.nonrandom],
            "nonrandom_rule": dict(self.terms.settings),
            "components": [c.to_dict() for c in self.terms.components],
            "imf_models": models,
            "fit_error": {"ar": self.error_ar.to_dict(), "ar_kalman": self.error_ar_kalman.to_dict(),
                          "std_ratio": self.std_ratio, "compared_from_sample": self.compared_from,
                          "unit": "unit of y"},
            "settings": dict(self.settings),
            "notes": list(self.notes),
        })


def analyze_vibration(t_s: np.ndarray, y: np.ndarray, *, stop: StopRule = "sd", max_imfs: int | None = None,
                      max_sifts: int = 1000, p_max: int = 15, criterion: str = "bic", r_ratio: float = 1.0,
                      min_cycles: float = 8.0, line_alpha: float = 1e-3, line_dominance: float = 0.5,
                      lb_lags: int = 20, alpha: float = 0.05,
                      sampling_tolerance: float = 0.01) -> VibrationAnalysis:
    """Run Document C's method on a uniformly sampled record (module docstring).

    ``t_s`` in seconds, ``y`` in any unit.  ``stop``/``max_imfs``/``max_sifts``: EMD
    (:func:`bench.analysis.emd.emd`); ``min_cycles``/``line_alpha``/``line_dominance``: the
    non-random rule (:func:`bench.analysis.emd.nonrandom_terms`); ``p_max``/``criterion``/
    ``lb_lags``/``alpha``: the IMF models (:func:`model_imf`); ``r_ratio``: R / σ_a² of
    every Kalman filter (:func:`kalman_ar_fit`).

    Parameters
    ----------
    t_s : array_like of float, shape (n,)
        Sample times in s: finite, strictly increasing, uniform within ``sampling_tolerance``; n ≥ 256.
    y : array_like of float, shape (n,)
        The rate record, in any unit (e.g. deg/s); finite.
    stop : {"sd", "rilling", "s-number"}, default "sd"
        EMD sifting stop criterion.
    max_imfs : int, optional
        Largest number of IMFs; default no limit.
    max_sifts : int, default 1000
        Largest number of siftings per IMF.
    p_max : int, default 15
        Largest AR order of each IMF model.
    criterion : {"aic", "bic"}, default "bic"
        Criterion that picks each IMF's AR order.
    r_ratio : float, default 1.0
        Measurement noise variance R over the AR innovation variance σ_a², > 0.
    min_cycles : float, default 8.0
        Fewest oscillations over the record for an IMF not to count as trend.
    line_alpha : float, default 1e-3
        False-alarm probability of the spectral-line test, in (0, 1).
    line_dominance : float, default 0.5
        Least variance share of a line for its IMF to be periodic, in (0, 1].
    lb_lags : int, default 20
        Lags of each IMF's whiteness test.
    alpha : float, default 0.05
        Significance level of the IMF tests, in (0, 1).
    sampling_tolerance : float, default 0.01
        Allowed relative deviation of a sampling interval from the median.

    Returns
    -------
    VibrationAnalysis
        Decomposition, component labels, IMF models, the two fits of ``y`` and their error
        statistics (``y``'s unit).

    Raises
    ------
    ValueError
        If ``stop`` is not one of :data:`~bench.analysis.emd.STOP_RULES`, ``r_ratio`` is not > 0,
        the record fails :func:`~bench.analysis.startup.validate_trace` or has fewer than 256
        samples, or an option of :func:`~bench.analysis.emd.emd`,
        :func:`~bench.analysis.emd.nonrandom_terms` or :func:`model_imf` is out of its range.

    Examples
    --------
    A 5 Hz vibration on coloured noise, 40 s at 100 Hz:

    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from bench.analysis.vibration import analyze_vibration
    >>> rng = np.random.default_rng(0)
    >>> t = np.arange(4000) / 100.0
    >>> y = 0.5 * np.sin(2 * np.pi * 5.0 * t) + lfilter([1.0], [1.0, -0.9], rng.normal(0.0, 0.05, t.size))
    >>> a = analyze_vibration(t, y)
    >>> tone = a.terms.components[1]
    >>> tone.kind, round(tone.frequency_hz, 1)
    ('periodic', 5.0)
    >>> len(a.models) == len(a.terms.random_indices) == len(a.kalman)
    True
    >>> bool(a.error_ar_kalman.std < a.error_ar.std), round(a.std_ratio, 1)
    (True, 0.5)
    """
    if stop not in STOP_RULES:
        raise ValueError(f"stop = {stop!r} is not one of {STOP_RULES}")
    if not r_ratio > 0:
        raise ValueError(f"r_ratio = {r_ratio!r} must be > 0")
    validate_trace(t_s, y, sampling_tolerance)
    t = np.asarray(t_s, dtype=float)
    y = np.asarray(y, dtype=float)
    if y.size < MIN_SAMPLES:
        raise ValueError(f"trace has {y.size} samples; at least {MIN_SAMPLES} are required")
    rate_hz = (y.size - 1) / float(t[-1] - t[0])  # mean interval: no rounding bias of one median step
    dec = emd(y, stop=stop, max_imfs=max_imfs, max_sifts=max_sifts)
    terms = nonrandom_terms(dec.imfs, dec.residue, rate_hz, min_cycles=min_cycles, line_alpha=line_alpha,
                            line_dominance=line_dominance)
    notes: list[str] = []
    models, fits = [], []
    fit_ar = terms.signal.copy()
    fit_k = terms.signal.copy()
    for i in terms.random_indices:
        imf = dec.imfs[i - 1]
        m = model_imf(imf, i, p_max=p_max, criterion=criterion, lb_lags=lb_lags, alpha=alpha)
        k = kalman_ar_fit(imf, m.ar, m.sigma2, r_ratio=r_ratio, mean=m.mean)
        fit_ar += ar_predict(imf, m.ar, m.mean)
        fit_k += k.filtered
        models.append(m)
        fits.append(k)
        if m.imf_white.white:
            notes.append(f"IMF{i} passes the whiteness criterion; Document C models non-white IMFs only")
        if not m.stationary:
            notes.append(f"IMF{i}: ADF p = {m.adf.p_value:.3g}, KPSS p = {m.kpss.p_value:.3g} — "
                         "not judged stationary at the chosen level")
        if m.identified != "AR":
            notes.append(f"IMF{i}: ACF/PACF suggest {m.identified} ({m.identification_reason}); modelled as AR")
    if not models:
        notes.append("no random IMF: the non-random terms are the whole signal")
    start = max((m.p for m in models), default=0)
    err_ar = FitError.of(y[start:] - fit_ar[start:])
    err_k = FitError.of(y[start:] - fit_k[start:])
    settings = {"stop": stop, "max_imfs": max_imfs, "max_sifts": max_sifts, "p_max": p_max,
                "criterion": criterion, "r_ratio": r_ratio, "min_cycles": min_cycles, "line_alpha": line_alpha,
                "line_dominance": line_dominance, "lb_lags": lb_lags, "alpha": alpha,
                "kalman": "P0 = I, X0 = first p samples, Q = σ_a², R = r_ratio·σ_a²; fit = filtered x̂(n|n)",
                "ar_fit": "one-step prediction Σ φ_k y_k(n−k) from past samples"}
    return VibrationAnalysis(t, y, rate_hz, dec, terms, tuple(models), tuple(fits), fit_ar, fit_k, start,
                             err_ar, err_k, settings, tuple(notes))
