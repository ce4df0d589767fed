"""Document A's start-up model of a quartz flexure accelerometer, as one pure pipeline.

:func:`analyze_startup` takes a power-on trace (time in s, output in any unit — V, mA
or g) and returns a :class:`StartupAnalysis` holding every intermediate result; its
``model`` is a :class:`StartupModel` — trend + ARMA noise — that prints its equation
and generates new start-up traces.

Steps (Document A numbering) and the choices made where the document is silent:

2. Wavelet denoising (:mod:`bench.analysis.denoise`).
3. Trend ``c + a·exp(-t/τ) + b·t`` (:mod:`bench.analysis.trend`).  By default it is fitted
   to the *raw* trace (``trend_source="raw"``): soft thresholding shrinks every large
   wavelet coefficient of the transient by λ, which biases τ by several standard errors;
   least squares on the raw trace is unbiased and already averages the noise.
   ``trend_source="denoised"`` gives the document's literal order.
4. Standardise the detrended series (``noise_source="denoised"``: denoised − trend, the
   document's choice; ``"raw"``: raw − trend, which models the full sensor noise).
5. Outliers ``|z| > outlier_z`` are replaced by linear interpolation between their kept
   neighbours.  ARMA lags need a uniform time base: dropping samples would join
   non-adjacent samples as lag-1 pairs, while a handful of interpolated values (0.27 %
   of Gaussian data) bias the autocorrelations by O(count/N).  Count, indices and times
   are reported.
6. ACF/PACF identification, AIC/BIC order table, estimation (Ulrych–Clayton for AR by
   default; exact ML for MA/ARMA), Ljung–Box on the residuals with ``p + q`` dof removed
   (:mod:`bench.analysis.timeseries`).  A Ulrych–Clayton fit that is not stationary
   (the method does not guarantee it) is replaced by Burg's, and ``model.method`` says so.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
from scipy.signal import lfilter

from bench.analysis import timeseries as ts
from bench.analysis.denoise import DenoiseResult, wavelet_denoise
from bench.analysis.trend import Estimate, TrendFit, fit_trend

MIN_SAMPLES = 64
Source = Literal["raw", "denoised"]


def validate_trace(t_s: np.ndarray, y: np.ndarray, sampling_tolerance: float = 0.01) -> float:
    """Check a trace and return its sampling interval in s.

    Requires equal 1-D lengths ≥ 64, finite values, strictly increasing time and every
    interval within ``sampling_tolerance`` (relative) of the median interval.
    """
    t, v = np.asarray(t_s, dtype=float), np.asarray(y, dtype=float)
    if t.ndim != 1 or v.ndim != 1 or t.size != v.size:
        raise ValueError(f"time and value must be 1-D of equal length, got {t.shape} and {v.shape}")
    if t.size < MIN_SAMPLES:
        raise ValueError(f"trace has {t.size} samples; at least {MIN_SAMPLES} are required")
    for name, arr in (("time", t), ("value", v)):
        bad = np.flatnonzero(~np.isfinite(arr))
        if bad.size:
            raise ValueError(f"{name} column has {bad.size} non-finite values (first at row {bad[0]}); all must be finite")
    dt = np.diff(t)
    if np.any(dt <= 0):
        k = int(np.flatnonzero(dt <= 0)[0])
        raise ValueError(f"time is not strictly increasing at row {k + 1} ({t[k]!r} s then {t[k + 1]!r} s)")
    step = float(np.median(dt))
    worst = float(np.max(np.abs(dt / step - 1)))
    if worst > sampling_tolerance:
        raise ValueError(
            f"sampling is not uniform: an interval deviates {worst:.3%} from the median {step:.6g} s "
            f"(allowed ≤ {sampling_tolerance:.3%})"
        )
    return step


@dataclass(frozen=True)
class Outliers:
    """Samples with ``|z| > threshold_z``, replaced by interpolation (module docstring)."""

    count: int
    indices: tuple[int, ...]
    times_s: tuple[float, ...]
    threshold_z: float
    handling: str = "linear interpolation between kept neighbours"

    def to_dict(self) -> dict:
        return {"count": self.count, "indices": list(self.indices), "times_s": list(self.times_s),
                "threshold_z": self.threshold_z, "handling": self.handling}


@dataclass(frozen=True)
class StartupModel:
    """``y(t) = c + a·exp(-u/τ) [+ a2·exp(-u/τ2)] + b·u + m + s·z_k``, ``u = t - t0_s``.

    ``z_k`` is the zero-mean, unit-scale ARMA(p, q) process of :mod:`timeseries`
    (innovation variance ``sigma2``) sampled every ``sample_interval_s``; ``m`` and ``s``
    (``noise_mean``, ``noise_std``) return it to the trace's units.
    ``measurement_noise_std`` is the wavelet σ — the white noise the denoising removed.
    """

    trend: dict[str, Estimate]  # offset, exp_amplitude, exp_tau_s, linear_slope_per_s[, exp2_*]
    t0_s: float
    sample_interval_s: float
    kind: Literal["AR", "MA", "ARMA"]
    ar: tuple[float, ...]
    ma: tuple[float, ...]
    ar_std: tuple[float, ...]
    ma_std: tuple[float, ...]
    sigma2: float
    aic: float
    bic: float
    method: str
    noise_mean: float
    noise_std: float
    measurement_noise_std: float
    noise_source: Source = "denoised"

    @property
    def p(self) -> int:
        return len(self.ar)

    @property
    def q(self) -> int:
        return len(self.ma)

    def trend_at(self, t_s: np.ndarray) -> np.ndarray:
        """Trend value at absolute times ``t_s`` in s."""
        u = np.asarray(t_s, dtype=float) - self.t0_s
        tr = self.trend
        out = tr["offset"].value + tr["exp_amplitude"].value * np.exp(-u / tr["exp_tau_s"].value)
        if "exp2_tau_s" in tr:
            out = out + tr["exp2_amplitude"].value * np.exp(-u / tr["exp2_tau_s"].value)
        return out + tr["linear_slope_per_s"].value * u

    def simulate(self, t_s: np.ndarray, rng: np.random.Generator, *, measurement_noise: bool = False) -> np.ndarray:
        """A new start-up trace at times ``t_s`` (s, uniform at ``sample_interval_s`` ± 1 %).

        The ARMA noise starts in its stationary state (burn-in until the slowest pole has
        decayed by 10⁻⁸).  ``measurement_noise=True`` adds white noise of
        ``measurement_noise_std`` so the trace resembles the raw one rather than the
        denoised one (only meaningful when ``noise_source == "denoised"``).
        """
        t = np.asarray(t_s, dtype=float)
        if t.ndim != 1 or t.size < 1:
            raise ValueError(f"t_s must be a non-empty 1-D array, got shape {t.shape}")
        if t.size > 1:
            dt = np.diff(t)
            if np.any(np.abs(dt / self.sample_interval_s - 1) > 0.01):
                raise ValueError(f"t_s intervals must equal the model's {self.sample_interval_s:.6g} s within 1 % "
                                 f"(got {dt.min():.6g}..{dt.max():.6g} s)")
        poles = np.abs(np.roots(np.r_[1.0, -np.asarray(self.ar)])) if self.p else np.zeros(1)
        if np.any(poles >= 1):
            raise ValueError(f"AR part is not stationary (largest pole modulus {poles.max():.6f}, must be < 1)")
        slowest = float(poles.max())
        burn = 10 * (self.p + self.q) + 100 + (int(np.ceil(np.log(1e-8) / np.log(slowest))) if slowest > 0 else 0)
        e = rng.normal(0.0, np.sqrt(self.sigma2), t.size + burn)
        z = lfilter(np.r_[1.0, self.ma], np.r_[1.0, -np.asarray(self.ar)], e)[burn:]
        out = self.trend_at(t) + self.noise_mean + self.noise_std * z
        if measurement_noise:
            out = out + rng.normal(0.0, self.measurement_noise_std, t.size)
        return out

    def equation(self) -> str:
        """The model as plain text, with standard errors."""
        tr = self.trend

        def pm(name: str, unit: str = "") -> str:
            return f"{tr[name].value:.6g}{unit} ± {tr[name].std:.2g}{unit}"

        exps = f" + ({pm('exp_amplitude')})·exp(−u/({pm('exp_tau_s', ' s')}))"
        if "exp2_tau_s" in tr:
            exps += f" + ({pm('exp2_amplitude')})·exp(−u/({pm('exp2_tau_s', ' s')}))"
        lines = [
            f"y(t) = ({pm('offset')}){exps} + ({pm('linear_slope_per_s', '/s')})·u + n(t),",
            f"u = t − {self.t0_s:.6g} s;  n(t_k) = {self.noise_mean:.6g} + {self.noise_std:.6g}·z_k, "
            f"t_k = t0 + k·{self.sample_interval_s:.6g} s",
        ]
        terms = [f"{c:+.4f}(±{s:.1g})·z_(k−{i + 1})" for i, (c, s) in enumerate(zip(self.ar, self.ar_std))]
        terms += [f"{c:+.4f}(±{s:.1g})·ε_(k−{i + 1})" for i, (c, s) in enumerate(zip(self.ma, self.ma_std))]
        lines.append(f"z_k = {' '.join(terms + ['+ ε_k']).lstrip('+ ')},  ε_k ~ N(0, {self.sigma2:.4g})   "
                     f"[{self.kind}({self.p},{self.q}) by {self.method}]" if terms else
                     f"z_k = ε_k,  ε_k ~ N(0, {self.sigma2:.4g})   [white noise]")
        return "\n".join(lines)

    def to_dict(self) -> dict:
        """JSON-ready ``{"trend": …, "model": …}`` with the keys of issue 3."""
        trend = {k: v.to_dict() for k, v in self.trend.items()}
        trend["kind"] = "exp2" if "exp2_tau_s" in self.trend else "exp1"
        trend["t0_s"] = self.t0_s
        model = {"kind": self.kind, "p": self.p, "q": self.q, "ar": list(self.ar), "ma": list(self.ma),
                 "ar_std": list(self.ar_std), "ma_std": list(self.ma_std), "sigma2": self.sigma2,
                 "aic": self.aic, "bic": self.bic, "method": self.method, "noise_mean": self.noise_mean,
                 "noise_std": self.noise_std, "noise_source": self.noise_source,
                 "sample_interval_s": self.sample_interval_s, "measurement_noise_std": self.measurement_noise_std}
        return {"trend": trend, "model": model, "equation": self.equation()}

    @classmethod
    def from_dict(cls, d: dict) -> StartupModel:
        """Inverse of :meth:`to_dict` (so a saved model can drive a simulator)."""
        names = ("offset", "exp_amplitude", "exp_tau_s", "linear_slope_per_s", "exp2_amplitude", "exp2_tau_s")
        trend = {k: Estimate(float(d["trend"][k]["value"]), float(d["trend"][k]["std"]))
                 for k in names if k in d["trend"]}
        m = d["model"]
        return cls(trend, float(d["trend"]["t0_s"]), float(m["sample_interval_s"]), m["kind"],
                   tuple(m["ar"]), tuple(m["ma"]), tuple(m["ar_std"]), tuple(m["ma_std"]), float(m["sigma2"]),
                   float(m["aic"]), float(m["bic"]), m["method"], float(m["noise_mean"]), float(m["noise_std"]),
                   float(m["measurement_noise_std"]), m.get("noise_source", "denoised"))


@dataclass(frozen=True, eq=False)
class StartupAnalysis:
    """Everything :func:`analyze_startup` computed; arrays are read-only, indexed by sample."""

    time_s: np.ndarray
    raw: np.ndarray
    denoise: DenoiseResult
    trend: TrendFit
    standardized: np.ndarray  # z after outlier replacement — the series the ARMA model describes
    outliers: Outliers
    correlogram: ts.Correlogram
    identification: ts.Identification
    order_selection: ts.OrderSelection
    criterion: Literal["aic", "bic"]
    fit: ts.ArmaFit
    ar_estimates: dict[str, tuple[float, ...]]  # every AR estimator at the chosen p (AR models only)
    ljung_box: ts.LjungBox
    residual_correlogram: ts.Correlogram
    model: StartupModel
    settings: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        """JSON-ready summary (no sample arrays)."""
        d = self.model.to_dict()
        dn = self.denoise
        d["denoise"] = {"wavelet": dn.wavelet, "level": dn.level, "sigma": dn.sigma, "threshold": dn.threshold,
                        "thresholded_levels": list(dn.thresholded_levels)}
        d["outliers"] = self.outliers.to_dict()
        d["ljung_box_p"] = self.ljung_box.p_value
        lb = self.ljung_box
        d["ljung_box"] = {"statistic": lb.statistic, "p_value": lb.p_value, "lags": lb.lags, "dof": lb.dof}
        ident = self.identification
        d["identification"] = {"kind": ident.kind, "p": ident.p, "q": ident.q, "acf_cutoff": ident.acf_cutoff,
                               "pacf_cutoff": ident.pacf_cutoff, "reason": ident.reason}
        sel = self.order_selection
        d["order_selection"] = {"criterion": self.criterion, "method": sel.method, "best_aic": list(sel.best_aic),
                                "best_bic": list(sel.best_bic),
                                "table": [{"p": c.p, "q": c.q, "aic": c.aic, "bic": c.bic} for c in sel.candidates]}
        d["ar_estimates"] = {k: list(v) for k, v in self.ar_estimates.items()}
        d["n_samples"] = int(self.raw.size)
        d["settings"] = dict(self.settings)
        return d


def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.flags.writeable = False
    return a


def _order_limit(requested: int | None, default: int, n: int, name: str) -> int:
    """Grid limit: the default shrinks to ``n // 10``; an explicit request must fit."""
    if requested is None:
        return max(0, min(default, n // 10))
    if int(requested) != requested or not 0 <= requested <= n // 10:
        raise ValueError(f"{name} = {requested!r} is not allowed for {n} samples (allowed 0..{n // 10}, "
                         f"10 samples per parameter)")
    return int(requested)


def analyze_startup(
    t_s: np.ndarray,
    y: np.ndarray,
    *,
    noise_source: Source = "denoised",
    trend_source: Source = "raw",
    criterion: Literal["aic", "bic"] = "bic",
    ar_method: ts.ArMethod = "ulrych-clayton",
    max_ar_order: int | None = None,
    max_arma_order: int | None = None,
    identification_max_order: int = 8,
    alpha: float = 0.05,
    outlier_z: float = 3.0,
    sampling_tolerance: float = 0.01,
    wavelet: str | None = None,
    level: int | None = None,
    allow_two_exponentials: bool = True,
    ml_max_samples: int = 200_000,
) -> StartupAnalysis:
    """Run Document A's start-up modelling on a trace (see the module docstring).

    ``t_s``: sample times in s (uniform, strictly increasing); ``y``: output in any unit.
    AR grids cover p = 0..``max_ar_order`` (default 10) with ``ar_method``; MA/ARMA grids
    are conditional-least-squares fits over 0..``max_arma_order`` (default 2) in each
    order, and the chosen MA/ARMA model is refitted by exact ML (statsmodels) up to
    ``ml_max_samples`` samples (CSS beyond, where the two agree).  Raises ``ValueError`` naming the
    offending value and its allowed range on bad input.
    """
    for name, value, allowed in (("noise_source", noise_source, ("raw", "denoised")),
                                 ("trend_source", trend_source, ("raw", "denoised")),
                                 ("criterion", criterion, ("aic", "bic")), ("ar_method", ar_method, ts.AR_METHODS)):
        if value not in allowed:
            raise ValueError(f"{name} = {value!r} is not one of {allowed}")
    if not outlier_z > 0:
        raise ValueError(f"outlier_z = {outlier_z} must be > 0")
    dt = validate_trace(t_s, y, sampling_tolerance)
    t, raw = _readonly(t_s), _readonly(y)
    n = raw.size
    max_p = _order_limit(max_ar_order, 10, n, "max_ar_order")
    max_pq = _order_limit(max_arma_order, 2, n, "max_arma_order")

    dn = wavelet_denoise(raw, wavelet, level)
    trend = fit_trend(t, raw if trend_source == "raw" else dn.denoised, allow_two_exponentials=allow_two_exponentials)
    detrended = (dn.denoised if noise_source == "denoised" else raw) - trend.fitted
    mean, std = float(detrended.mean()), float(detrended.std())
    if not std > 0:
        raise ValueError("the detrended series is constant; there is no noise to model")
    z = (detrended - mean) / std
    bad = np.abs(z) > outlier_z
    kept = np.flatnonzero(~bad)
    if kept.size < n // 2:
        raise ValueError(f"{int(bad.sum())} of {n} samples exceed |z| > {outlier_z}; at most half may be outliers")
    z[bad] = np.interp(np.flatnonzero(bad), kept, z[kept])
    idx = np.flatnonzero(bad)
    outliers = Outliers(int(idx.size), tuple(idx.tolist()), tuple(t[idx].tolist()), float(outlier_z))

    corr = ts.correlogram(z, alpha=alpha)
    ident = ts.identify(corr, identification_max_order)
    if ident.kind == "AR":
        sel = ts.select_order(z, "AR", max_p, ar_method=ar_method)
    elif ident.kind == "MA":
        sel = ts.select_order(z, "MA", 0, max(max_pq, min(ident.q, n // 10)))
    else:
        sel = ts.select_order(z, "ARMA", max_pq, max_pq)
    p, q = sel.best_bic if criterion == "bic" else sel.best_aic

    ar_estimates: dict[str, tuple[float, ...]] = {}
    if q == 0:
        n_cond = max_p if sel.method != "ml" else p
        fit = ts.fit_ar(z, p, ar_method, n_condition=n_cond)
        if not fit.is_stationary:  # Ulrych–Clayton can leave the stationary region; Burg cannot
            fit = ts.fit_ar(z, p, "burg", n_condition=n_cond)
            fit = replace(fit, method=f"burg (fallback: {ar_method} fit not stationary)")
        if p:
            ar_estimates = {m: tuple(ts.fit_ar(z, p, m).ar) for m in ts.AR_METHODS}
    elif n <= ml_max_samples:
        fit = ts.fit_arma_ml(z, p, q)
    else:  # exact ML costs seconds per 10⁵ samples; CSS is asymptotically the same estimator
        fit = ts.fit_arma_css(z, p, q)
    lb_lags = ts.default_lb_lags(fit.residuals.size, p + q)
    lb = ts.ljung_box(fit.residuals, lb_lags, p + q)
    resid_corr = ts.correlogram(fit.residuals, nlags=lb_lags, alpha=alpha)

    trend_params = {name: getattr(trend, name) for name in trend.param_names}
    model = StartupModel(trend_params, trend.t0_s, dt, fit.kind, fit.ar, fit.ma, fit.ar_std, fit.ma_std,
                         fit.sigma2, fit.aic, fit.bic, fit.method, mean, std, dn.sigma, noise_source)
    settings = {"noise_source": noise_source, "trend_source": trend_source, "criterion": criterion,
                "ar_method": ar_method, "max_ar_order": max_p, "max_arma_order": max_pq, "alpha": alpha,
                "outlier_z": outlier_z, "identification_max_order": identification_max_order}
    return StartupAnalysis(t, raw, dn, trend, _readonly(z), outliers, corr, ident, sel, criterion, fit,
                           ar_estimates, lb, resid_corr, model, settings)
