"""Where a residual departs from the model's noise floor: time, frequency, τ and each logged input.

Pure: arrays and a :class:`~bench.discovery.data.Record` in, a frozen :class:`Localization` out.
Units: the residual is in the sensor unit (g or deg/s); ``noise_sd`` is the model's white-noise
standard deviation in that unit; times in s, frequencies in Hz.

Each test is calibrated against white noise of sd ``noise_sd`` (the model's floor) with a
Bonferroni correction across the cells it scans, so on a residual at the floor every list is
empty with probability about ``1 - alpha`` per test. Only excess counts (a variance, PSD or
ADEV below the floor is not structure the model misses). ``floor_dof``: when ``noise_sd`` was
estimated from the same data (dof ν), tails use σ̂²/σ² ~ χ²_ν/ν: F instead of χ², Student
instead of normal, the Kolmogorov tail averaged over σ̂.

* time: the record cut into ``n_segments`` contiguous segments; a segment is flagged when its
  mean departs from 0 (σ/√m) or its mean square exceeds σ²; plus the CUSUM of the residual
  against the Kolmogorov bound (a slow drift shows there first); optionally single samples
  beyond the Gaussian extreme of n (``find_jumps``: a step, in Kalman innovations).
* frequency: Welch PSD (Hann, 50 % overlap) against the white floor 2σ²/fs, each bin's
  PSD/floor against χ²(ν)/ν (ν from the averaged segments); contiguous flagged bins merged:
  one or two bins → a line, more → a band.
* τ: overlapping Allan variance (octave τ) over σ²/(τ·fs) against χ²(edf)/edf, Greenhall's EDF
  for white rate noise (the null), Bonferroni over τ.
* inputs: correlation of the residual with x, x², x³ (centred) and, for ``input``, with |x| and
  dx/dt (an asymmetry is V-shaped; a time delay shows as −τ·SF·dx/dt); the standard error of r
  uses Bartlett's effective sample size n/(1 + 2Σρₓ(k)ρᵣ(k)), so slow inputs (temperature,
  time since power-on) are not over-read.

:func:`unexplained_structure` runs all families at a shared ``alpha`` on the model's own terms
(the residual, or its Kalman innovations for a model with stochastic effects). Measured false
alarms (benchmarks/bench_unexplained.py, 400 records each, n = 300 / 3000 / 30000): white
2.2 / 3.8 / 3.0 %, Gauss–Markov 1.5 / 3.0 / 3.5 %, random walk 1.5 / 3.2 / 4.8 %.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable

import numpy as np
from scipy import fft as sp_fft
from scipy import signal, special, stats
from scipy.stats import t as t_dist

from bench.analysis.allan import averaging_factors, edf_greenhall
from bench.discovery.data import Record
from bench.discovery.effects_linalg import project_out
from bench.discovery.effects_noise import StochasticEffect
from bench.discovery.findings import INPUT_COLUMNS, Band, InputCorrelation, Jump, Localization, Segment, TauRange
from bench.discovery.model import Model
from bench.discovery.significance import spread_factor, welch_dof, welch_nperseg, white_floor
from bench.discovery.whiten import innovation_var, innovations, seen_only, state_space, wander_sd


def _check(residual, rec: Record, noise_sd: float) -> np.ndarray:
    r = np.asarray(residual, dtype=float)
    if r.shape != (rec.n,):
        raise ValueError(f"residual has shape {r.shape}; allowed: ({rec.n},) like the record")
    if not np.all(np.isfinite(r)):
        raise ValueError("residual has non-finite values; allowed: finite numbers")
    if not (np.isfinite(noise_sd) and noise_sd > 0):
        raise ValueError(f"noise_sd = {noise_sd!r}; allowed: a finite number > 0")
    return r


def _ratio_sf(ratio, dof, floor_dof: float):
    """P(X ≥ ratio) for X = (χ²_dof/dof)/(χ²_ν/ν), ν = ``floor_dof``: a mean square over an
    estimated floor (F distribution); a known floor (ν = ∞) gives the χ² tail."""
    ratio = np.asarray(ratio, float)
    if np.isinf(floor_dof):
        return stats.chi2.sf(ratio * dof, dof)
    return stats.f.sf(ratio, dof, floor_dof)


def _z_sf2(z, floor_dof: float):
    """Two-sided tail of a mean over an estimated sd: Student t with ν = ``floor_dof``."""
    z = np.abs(np.asarray(z, float))
    return 2 * (stats.norm.sf(z) if np.isinf(floor_dof) else stats.t.sf(z, floor_dof))


def _floor_average(sf, x: float, floor_dof: float, n_q: int = 64) -> float:
    """E_w[sf(x·w)], w = σ̂/σ ~ √(χ²_ν/ν): a tail computed for a known sd, averaged over the
    estimated floor's spread (mid-quantile rule)."""
    if np.isinf(floor_dof):
        return float(sf(x))
    w = np.sqrt(stats.chi2.ppf((np.arange(n_q) + 0.5) / n_q, floor_dof) / floor_dof)
    return float(np.mean(sf(x * w)))


def time_segments(r: np.ndarray, t_s: np.ndarray, noise_sd: float, n_segments: int = 16,
                  alpha: float = 0.01, *, floor_dof: float = np.inf,
                  sample_moments: tuple[np.ndarray, np.ndarray, float] | None = None,
                  ) -> tuple[tuple[Segment, ...], float]:
    """Flagged segments and the CUSUM p-value (Kolmogorov limit of max|S_k|/(σ√n)).
    ``floor_dof``: dof of ``noise_sd``² when it was estimated (∞: known). ``sample_moments``:
    each sample's expected variance and fourth central moment relative to ``noise_sd``² and
    ``noise_sd``⁴ (variance mean 1; :func:`innovations_profile`) when the residual is
    heteroscedastic and heavy-tailed — a coarse quantizer's readings between two levels flip,
    on a level they barely move, and then by a whole step — and the relative variance of an
    offset common to all samples (the calibrated parameters' error, ~k/n: negligible beside
    white noise, all there is where readings sit on a level). A segment's floor is then
    ``noise_sd``² times its mean variance plus the offset's, and its mean square is referred to
    χ² with the Satterthwaite dof 2(v̄ + o)²/(Σ(μ₄ − v²)/m² + 2o²) instead of its length (187
    samples of rare whole-step flips carry the information of ~20 Gaussian ones); None: white
    Gaussian."""
    n = r.size
    n_segments = max(1, min(n_segments, n // 8))
    edges = np.linspace(0, n, n_segments + 1).astype(int)
    a = alpha / (2 * n_segments)  # Bonferroni over segments and the two tests
    m = np.diff(edges)
    mean = np.add.reduceat(r, edges[:-1]) / m
    ms = np.add.reduceat(r * r, edges[:-1]) / m
    rel, dof, mean_var = np.ones(n_segments), m.astype(float), 1.0 / m
    heavy = np.zeros(n_segments, bool)
    ms_var = 2.0 / m
    if sample_moments is not None:
        v, m4 = (np.asarray(x, float) for x in sample_moments[:2])
        off = float(sample_moments[2])
        rel_v = np.add.reduceat(v, edges[:-1]) / m
        rel = rel_v + off
        ms_var = np.add.reduceat(m4 - v * v, edges[:-1]) / m ** 2 + 2 * off * off
        dof = np.clip(2 * rel ** 2 / np.maximum(ms_var, 1e-300), 1.0, m)
        mean_var = rel_v / m + off
        heavy = np.add.reduceat(m4, edges[:-1]) > HEAVY_KURTOSIS * np.add.reduceat(v * v, edges[:-1])
    floor = noise_sd * np.sqrt(rel)  # each segment's own floor sd
    z = mean / (noise_sd * np.sqrt(mean_var))
    ratio = ms / floor ** 2
    p_mean, p_ms = _z_sf2(z, floor_dof), _ratio_sf(ratio, dof, floor_dof)
    if np.any(heavy):
        # a few whole-step flips: the χ² and normal laws are far too thin-tailed (one flip of
        # probability 0.03 would read as p = 1e-8); Chebyshev's and Cantelli's bounds hold for
        # any law with those moments
        excess = np.maximum(ms / noise_sd ** 2 - rel, 0.0)
        cantelli = ms_var / (ms_var + excess ** 2)
        chebyshev = np.minimum(1.0, 1.0 / np.maximum(z * z, 1e-300))
        p_mean = np.where(heavy, np.maximum(p_mean, chebyshev), p_mean)
        p_ms = np.where(heavy, np.maximum(p_ms, cantelli), p_ms)
    # only excess variance is structure: a quiet segment is not something the model misses
    bad = (p_mean < a) | (p_ms < a)
    out = tuple(Segment(float(t_s[edges[i]]), float(t_s[edges[i + 1] - 1]), float(mean[i]),
                        float(np.sqrt(ms[i]) / floor[i]), float(z[i])) for i in np.flatnonzero(bad))
    # a bridge: the residual's own mean is removed, max |B| has the Kolmogorov law — in the
    # time of its accumulated variance when it is heteroscedastic (each sample takes its share
    # of the mean by its variance; B(τ_k) − τ_k·B(1) is then a Brownian bridge again)
    if sample_moments is None:
        s = np.cumsum(r - r.mean()) / (noise_sd * np.sqrt(n))
    else:
        w = np.asarray(sample_moments[0], float)
        s = np.cumsum(r - w * (r.sum() / w.sum())) / (noise_sd * np.sqrt(w.sum()))
    cusum_p = _floor_average(special.kolmogorov, float(np.max(np.abs(s))), floor_dof)
    return out, cusum_p


def spectral_bands(r: np.ndarray, rate_hz: float, noise_sd: float, alpha: float = 0.01,
                   nperseg: int | None = None, *, floor_dof: float = np.inf,
                   sample_var: np.ndarray | None = None):
    """Welch PSD, the white floor and the flagged lines and bands (excess power only).
    ``sample_var``: each sample's relative variance when the series is heteroscedastic (its
    Welch dof scaled by :func:`spread_factor` over the segments)."""
    n = r.size
    nperseg = int(nperseg or welch_nperseg(n))
    f, p = signal.welch(r, fs=rate_hz, window="hann", nperseg=nperseg, detrend=False)
    floor = 2.0 * noise_sd ** 2 / rate_hz
    nu = welch_dof(n, nperseg) * spread_factor(sample_var, nperseg)
    flag = _ratio_sf(p / floor, nu, floor_dof) < alpha / max(f.size, 1)
    flag[0] = False  # DC: the calibrated bias
    bands = []
    for i, j in _runs(flag):
        pk = i + int(np.argmax(p[i:j + 1]))
        bands.append(Band("line" if j - i <= 1 else "band", float(f[i]), float(f[j]),
                          float(f[pk]), float(p[pk] / floor)))
    return tuple(bands), f, p, floor


def _runs(flag: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) index of each run of True."""
    d = np.diff(np.r_[0, flag.astype(np.int8), 0])
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1))


def allan_taus(r: np.ndarray, rate_hz: float, noise_sd: float, alpha: float = 0.01, *,
               floor_dof: float = np.inf, sample_moments: tuple[np.ndarray, np.ndarray, float] | None = None):
    """τ ranges where the ADEV exceeds the white expectation σ/√(τ·fs): one-sided test of
    AVAR/white against χ²(edf)/edf (Greenhall's EDF for white rate noise, the null), or the F
    law when σ was estimated; Bonferroni over the octave τ list. A deficit is not flagged.
    ``sample_moments``: as :func:`time_segments` (each τ's EDF scaled, below)."""
    if r.size < 16:
        return (), np.zeros(0), np.zeros(0), np.zeros(0)
    n_tau = max(1, int(np.log2(r.size // 2)) + 1)  # octave τ list length: Bonferroni over it
    ms = averaging_factors(r.size, rate_hz, "octave")
    # overlapping AVAR from the phase (cumulative sum), as bench.analysis.allan._adev computes it
    x = np.concatenate([[0.0], np.cumsum(r - r.mean())])
    avar = np.array([np.mean((x[2 * m:] - 2 * x[m:-m] + x[:-2 * m]) ** 2) for m in ms]) / (2.0 * ms ** 2)
    tau, adev = ms / rate_hz, np.sqrt(avar)
    white = noise_sd / np.sqrt(tau * rate_hz)
    edf = _white_edf(r.size, tuple(int(m) for m in ms))
    if sample_moments is not None:
        # each τ's EDF scaled by the spread over blocks of 2m and by the kurtosis of an m-sample
        # sum, 3 + (κ − 3)/m (a coarse quantizer's whole-step flips at the shortest τ)
        v, m4 = sample_moments[0], sample_moments[1]
        kappa = float(np.mean(m4)) / float(np.mean(v * v))
        edf = edf * np.array([spread_factor(v, 2 * int(m)) * 2.0 / (2.0 + max(kappa - 3.0, 0.0) / m) for m in ms])
    bad = _ratio_sf((adev / white) ** 2, edf, floor_dof) < alpha / n_tau
    out = []
    for i, j in _runs(bad):
        ratio = adev[i:j + 1] / white[i:j + 1]
        out.append(TauRange(float(tau[i]), float(tau[j]), float(np.max(ratio))))
    return tuple(out), tau, adev, white


@functools.lru_cache(maxsize=64)
def _white_edf(n: int, ms: tuple[int, ...]) -> np.ndarray:
    """Greenhall's EDF of the overlapping AVAR of n white rate samples at each factor m."""
    return edf_greenhall(0, np.array(ms), n + 1)


def jumps(r: np.ndarray, t_s: np.ndarray, noise_sd: float, alpha: float = 0.01, *,
          floor_dof: float = np.inf, max_report: int = 4,
          sample_moments: tuple[np.ndarray, np.ndarray, float] | None = None,
          nu: float = math.inf) -> tuple[Jump, ...]:
    """Single samples beyond the Gaussian extreme of n white samples (Bonferroni over n), on the
    larger of ``noise_sd`` and the series' MAD sd: in Kalman innovations a step of the output
    shows as one such sample. ``sample_moments`` (:func:`time_segments`): each sample on its own
    sd, and where its fourth moment is well above a Gaussian's (kurtosis > 4: a coarse
    quantizer's reading that flips by a whole step once in a while) its tail is Markov's bound
    μ₄/x⁴ on the fourth power instead of the Gaussian one — exact for a rare flip, so a flip
    of probability p is not a jump at p·n. ``nu``: the observation noise is Student-t with these
    degrees of freedom (finite: heavy-tailed): a sample's tail is then the t's, on the t scale
    that gives the series' MAD."""
    # the series' own overall scale (MAD), not the upper-half floor: a slightly mis-set filter
    # leaves low-frequency power in innovations, and extremes come from the whole spectrum
    mad_sd = 1.4826 * float(np.median(np.abs(r - np.median(r))))
    scale = max(noise_sd, mad_sd)
    if sample_moments is None:
        z = r / scale
        p = _z_sf2(z, floor_dof)
    else:
        v, m4 = (np.asarray(x, float) for x in sample_moments[:2])
        v = np.maximum(v + float(sample_moments[2]), 1e-9)
        z = r / (scale * np.sqrt(v))
        p = _z_sf2(z, floor_dof)
        kurt = m4 / v ** 2
        with np.errstate(divide="ignore"):
            markov = np.minimum(1.0, kurt / z ** 4)
        p = np.where(kurt > HEAVY_KURTOSIS, np.maximum(p, markov), p)
    if math.isfinite(nu):
        mad = float(np.median(np.abs(r - np.median(r))))
        scale_t = mad / float(t_dist.ppf(0.75, nu)) if mad > 0 else scale
        p = np.maximum(p, 2 * t_dist.sf(np.abs(r) / scale_t, nu))
    idx = np.flatnonzero(p * r.size < alpha)
    idx = idx[np.argsort(-np.abs(z[idx]))][:max_report]
    return tuple(Jump(float(t_s[i]), float(r[i]), float(z[i])) for i in sorted(idx))


#: Kurtosis above which :func:`jumps` takes a sample's tail from its fourth moment (Gaussian: 3).
HEAVY_KURTOSIS = 4.0


def autocorrelation(x: np.ndarray, max_lag: int) -> np.ndarray:
    """Sample autocorrelation of ``x`` at lags 0..max_lag (mean removed; zeros for a constant)."""
    x = x - x.mean()
    n = x.size
    size = sp_fft.next_fast_len(2 * n, real=True)  # ≥ 2n: linear, not circular; 2n may be prime-heavy
    spec = np.fft.rfft(x, size)
    c = np.fft.irfft(spec * np.conj(spec), size)[:max_lag + 1]
    return c / c[0] if c[0] > 0 else np.zeros(max_lag + 1)


def input_correlations(r: np.ndarray, rec: Record, alpha: float = 0.01, *,
                       transform=None) -> tuple[InputCorrelation, ...]:
    """Significant correlations of the residual with x, x², x³ (and dx/dt of ``input``).
    ``transform``: applied to each of those columns first (the whitening filter, when ``r`` are
    innovations: an effect β·v of the output shows in them as β·transform(v))."""
    n = r.size
    max_lag = min(n - 1, max(10, n // 20))
    acf_r = autocorrelation(r, max_lag)
    cands = []
    for name in INPUT_COLUMNS:
        if not rec.logged(name) and not (name == "t_on"):
            continue
        x = rec.column(name)
        if np.ptp(x) == 0:
            continue
        xs = (x - x.mean()) / np.ptp(x)
        trans = {"x": xs, "x^2": xs ** 2, "x^3": xs ** 3}
        if name == "input":
            trans["|x|"] = np.abs(x) / np.ptp(x)  # V-shaped: an asymmetry of the response
            trans["dx/dt"] = np.gradient(x, rec.t_s)
        for tname, v in trans.items():
            if np.ptp(v) == 0:
                continue
            cands.append((name, tname, v if transform is None else transform(v)))
    out = []
    a = alpha / max(len(cands), 1)
    z_crit = stats.norm.isf(a / 2)
    rc = r - r.mean()
    sr = np.sqrt(np.sum(rc ** 2))
    for name, tname, v in cands:
        vc = v - v.mean()
        sv = np.sqrt(np.sum(vc ** 2))
        if sv == 0 or sr == 0:
            continue
        rho = float(np.dot(rc, vc) / (sr * sv))
        acf_v = autocorrelation(v, max_lag)
        infl = 1.0 + 2.0 * float(np.sum(acf_v[1:] * acf_r[1:]))
        n_eff = float(np.clip(n / max(infl, 1e-9), 3.0, n))
        z = rho * np.sqrt(n_eff - 2) / np.sqrt(max(1 - rho ** 2, 1e-12))
        if abs(z) > z_crit:
            out.append(InputCorrelation(name, tname, rho, float(z), n_eff))
    return tuple(out)


def localize(rec: Record, residual, noise_sd: float, *, alpha: float = 0.01,
             n_segments: int = 16, floor_dof: float = np.inf, transform=None,
             find_jumps: bool = False,
             sample_moments: tuple[np.ndarray, np.ndarray, float] | None = None,
             nu: float = math.inf) -> Localization:
    """Localize the departure of ``residual`` (= y − model prediction) from white noise of sd
    ``noise_sd``: time segments, spectral lines/bands, Allan τ ranges, input correlations (and,
    with ``find_jumps``, single outlying samples). Each of these families is tested at
    ``alpha``. ``floor_dof``: dof of ``noise_sd``² when it was estimated from the same data
    (∞: known); ``transform``: see :func:`input_correlations`; ``sample_moments``: see
    :func:`time_segments`."""
    r = _check(residual, rec, float(noise_sd))
    if not 0 < alpha < 1:
        raise ValueError(f"alpha = {alpha!r}; allowed: (0, 1)")
    if not floor_dof > 0:
        raise ValueError(f"floor_dof = {floor_dof!r}; allowed: > 0 (inf: a known floor)")
    rate = rec.rate_hz
    segs, cusum_p = time_segments(r, rec.t_s, noise_sd, n_segments, alpha, floor_dof=floor_dof,
                                  sample_moments=sample_moments)
    v = None if sample_moments is None else sample_moments[0]
    bands, f, p, floor = spectral_bands(r, rate, noise_sd, alpha, floor_dof=floor_dof, sample_var=v)
    taus, tau, adev, white = allan_taus(r, rate, noise_sd, alpha, floor_dof=floor_dof,
                                        sample_moments=sample_moments)
    corr = input_correlations(r, rec, alpha, transform=transform)
    jmp = (jumps(r, rec.t_s, noise_sd, alpha, floor_dof=floor_dof, sample_moments=sample_moments, nu=nu)
           if find_jumps else ())
    return Localization(segs, cusum_p, bands, taus, corr, f, p, floor, tau, adev, white, alpha, jmp)


def innovations_profile(model: Model, rec: Record, white: float, procs, seen: np.ndarray | None = None,
                        residual: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, float] | None:
    """Each standardized innovation's expected variance and fourth central moment (relative:
    variance mean 1) when the model's residual is heteroscedastic (``Model.residual_profile``: a
    coarse quantizer's flips between levels, a clipping's quiet stretches), for
    :func:`time_segments`. Innovation i is the reading's own spread w (variance white²·ρᵢ, ρ
    the profile over its mean; fourth moment from the profile too) plus the states' Gaussian
    prediction error of variance cᵢ: variance white²ρᵢ + cᵢ, fourth moment μ₄(w) + 6·white²ρᵢcᵢ
    + 3cᵢ²; and the relative variance of the offset the calibration's k parameters leave
    (k/n: the bias, scale factor and each deterministic effect's parameters). Without it a
    tumble's orientations that sit between two levels read as segments 1.3× the floor under
    any process. None without an output stage or for a flat profile. ``seen``: the samples the
    innovations were taken on (``whiten.innovations``; the others missing to the filter) — the
    profile of those alone. ``residual``: the residual the innovations came from — the profile is
    then taken where the processes moved the signal (their one-step prediction from its past,
    the filter's own), averaged over that prediction's error only, not over the processes'
    whole spread: a walk that dwells near a coarse quantizer's threshold makes the readings flip
    there (gyro, steps of 6 noise sd, a walk of about a step in 300 s: 1.26× the floor over 19 s
    under every process, averaged)."""
    if not model.has_output_stage():
        return None
    if residual is not None and procs:
        # where the processes moved the signal: their one-step prediction from the residual's
        # past (the innovations' own filter), its error the wander left
        r = seen_only(residual, seen)
        e, s_pred = state_space(rec.rate_hz, rec.n, list(procs)).filter(r, white ** 2)
        path = np.where(np.isfinite(e), r - e, 0.0)
        c_pred = np.maximum(s_pred - white ** 2, 0.0)
        var, m4 = model.residual_profile(rec, math.sqrt(float(np.median(c_pred[np.isfinite(c_pred)]))), path)
    else:
        var, m4 = model.residual_profile(rec, wander_sd(rec.rate_hz, rec.n, procs))
    if seen is not None:
        var, m4 = var[seen], m4[seen]
    mean = float(np.mean(var))
    if not mean > 0 or float(np.ptp(var)) <= 1e-3 * mean:
        return None
    s = innovation_var(rec.rate_hz, rec.n, white, procs, seen=seen)
    if seen is not None:
        s = s[seen]
    c = np.maximum(s - white ** 2, 0.0)
    rho, kappa = var / mean, m4 / mean ** 2
    v = (white ** 2 * rho + c) / s
    w4 = (white ** 4 * kappa + 6 * white ** 2 * rho * c + 3 * c * c) / s ** 2
    norm = float(np.mean(v))
    k = 2 + sum(len(p) for e, p in model.entries() if not isinstance(e, StochasticEffect))
    return v / norm, w4 / norm ** 2, k / v.size


#: test families of :func:`unexplained_structure` (segments, CUSUM, spectrum, Allan, inputs,
#: jumps): each is tested at alpha / N_FAMILIES, so all together at most alpha (Bonferroni)
N_FAMILIES = 6


def unexplained_structure(rec: Record, residual: np.ndarray, model: Model, *,
                          alpha: float = 0.05, nu: float = math.inf) -> tuple[str, ...]:
    """Where ``residual`` (= rec.y − model.predict(rec), sensor unit) departs from the model's
    noise: descriptions of time segments, jumps, spectral lines/bands, Allan τ ranges and input
    correlations; empty when there is none.

    Without stochastic effects in ``model`` the residual itself is tested against white noise;
    with them (gauss_markov, rate_random_walk) its standardized Kalman innovations
    (:func:`bench.discovery.whiten.innovations`), which are white when the model is right —
    logged inputs go through the same filter before correlating (the filter's white level is
    re-estimated beside the stochastic spectrum, :func:`significance.white_floor`, rather than
    taken from ``model.base.noise_sd``, which may count a short-τ GM as white). The level is estimated
    from the tested series itself (:func:`significance.white_floor`, dof ≈ 0.35·n), and every
    test allows for that (F / Student / averaged tails instead of χ² / normal); only excess
    structure counts; the six test families share ``alpha`` (Bonferroni), so on a series that
    is white all of it is reported with probability ≤ ``alpha``. ``nu``: the observation noise's
    Student-t degrees of freedom (finite: heavy-tailed; single samples are judged on its tail)."""
    r = np.asarray(residual, dtype=float)
    _check(r, rec, 1.0)
    if not 0 < alpha < 1:
        raise ValueError(f"alpha = {alpha!r}; allowed: (0, 1)")
    if rec.n < 32:
        return ()
    r = r - r.mean()
    sto = model.stochastic_effects()
    rate = rec.rate_hz
    transform: Callable[[np.ndarray], np.ndarray] | None = None
    prefix = ""
    x = r
    white = float(np.std(r))
    # under a random process, samples where the output stage clips are missing to the filter
    # (they hold no noise: its states are carried across, whiten.innovations) and the tests read
    # the others
    part = model.partly_seen(rec) if sto else None
    tested = rec if part is None else rec.slice(part)
    if sto:
        # the white level is re-estimated beside the model's stochastic spectrum: a level that
        # counted a short-τ GM's high-frequency power as white would colour the innovations
        white = white_floor(r if part is None else r[part], rate, sto)[0]
        if not white > 0:
            white = float(model.base.noise_sd)

        def whiten(v: np.ndarray) -> np.ndarray:
            """Innovations of a column of the tested samples."""
            if part is None:
                return innovations(v - v.mean(), rate, white, sto)
            full = np.zeros(rec.n)
            full[part] = v - v.mean()
            return innovations(full, rate, white, sto, seen=part)[part]
        x = whiten(r if part is None else r[part])
        if rec.varies("input"):
            # the scale factor refitted under the process (generalised least squares): fitted by
            # least squares beside a strong process its error follows the input — not structure
            x = project_out(x, whiten(tested.column("input"))[:, None])
        transform = whiten
        prefix = "in the Kalman innovations under the model's noise: "
    moments = innovations_profile(model, rec, white or float(model.base.noise_sd) or 1.0, sto, seen=part,
                                  residual=r)
    sd, dof = white_floor(x, rate, sample_var=None if moments is None else moments[0])
    if not (np.isfinite(sd) and sd > 0):
        return ()
    loc = localize(tested, x, sd, alpha=alpha / N_FAMILIES, floor_dof=dof, transform=transform,
                   find_jumps=True, sample_moments=moments, nu=nu)
    return tuple(prefix + d for d in loc.descriptions())
