"""Stochastic catalogue effects: coloured bias noise with no deterministic waveform.

A :class:`StochasticEffect` is a random process added to the output. It says, through its hooks,
everything the workflow needs of it, so no other module knows which processes exist:

* ``noise`` — one realisation on a record (``Model.simulate``);
* ``snr`` — detectability on the Allan variance, where it separates from white noise:
  ``z = max_T (AVAR_effect(T) / AVAR_white(T)) · sqrt((N_T − 1) / 2)`` over averaging times
  ``T = m·dt`` (m = 1, 2, 4, ... with at least 9 non-overlapping clusters N_T), i.e. the excess
  Allan variance in units of the white estimate's standard error (Allan 1966; IEEE Std 952);
* its Whittle spectral component (:mod:`bench.discovery.whittle`): ``n_coords`` log
  coordinates, ``spectrum`` (per-sample level spectrum and its derivatives), ``coords`` (the
  model's parameters in those coordinates), ``whittle_starts`` and ``estimate`` (the fitted
  coordinates back to parameters ± std);
  ``nonstationary`` (a walk: once it is in the model candidates are judged on first differences);
* ``state_space`` — its contribution to the model's noise as a block of state-space states
  (:class:`StateBlock`: the Kalman whitening of :mod:`bench.discovery.whiten`, the held-out
  one-step predictor, and the model's noise PSD);
* ``identifiable`` — whether the record can resolve the fitted parameters at all.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace

import numba
import numpy as np
from scipy import optimize

from bench.discovery.data import Record
from bench.discovery.effects_base import Effect, Param, Params
from bench.discovery.effects_linalg import base_regressors, project_out, vdot
from bench.discovery.whittle import periodogram

#: Parametric-bootstrap replicates for the random walk's q (each one Whittle fit: FFT-cheap).
N_BOOT_RW = 60

#: The widest full scale of each kind (u: saturation's top limit): no process's sd, flicker
#: level or quantizer step can exceed what the sensor reads — the most a model may hold of them.
FULL_SCALE = {"accelerometer": 100.0, "gyro": 2000.0, "mhd": 2000.0}

#: Factor between a random process's fit range and the record's own levels. Top: ten times the
#: readings' sd — a Gauss–Markov at the longest correlation time the range allows (τ = T) shows
#: about half its sd on the record (expected sample variance 1 − 2(τ/T)(1 − (τ/T)(1 − e^{−T/τ}))
#: = 0.26 of σ²), and one realisation may wander less than that. Bottom: a tenth of the white
#: noise averaged over the whole record (σw/√n) — a process whose own level over the record is
#: below that leaves no trace on it (the record's mean already wanders by σw/√n).
FIT_SPAN = 10.0

#: Flicker's Allan deviation in units of B: √(2 ln 2/π) (IEEE Std 952), the same at every τ.
FLICKER_ADEV = math.sqrt(2 * math.log(2) / math.pi)


def reaching(ranges: Mapping[str, tuple[Param, ...]], levels: Sequence[str] = ()) -> dict[str, tuple[Param, ...]]:
    """``ranges`` (kind → Params) with what a fit may return and a model hold opened beyond the
    physical envelope, for records of any sensor grade (the fit range itself comes from the
    record, :meth:`Effect.fit_range`): 0 up to the kind's :data:`FULL_SCALE` for the parameters
    named in ``levels`` (sds, flicker levels, steps), 0 to ∞ for the others (times, walk and
    angle-noise coefficients); the draws keep to ``[low, high]``."""
    return {kind: tuple(replace(q, fit_low=0.0, fit_high=FULL_SCALE[kind] if q.name in levels else math.inf)
                        for q in qs) for kind, qs in ranges.items()}


@dataclass(frozen=True)
class RecordLevels:
    """What a random process's fit range reads of a record: sample interval and span (s), number
    of samples, white-noise sd per sample from the first differences and the readings' sd (u)."""

    dt_s: float
    duration_s: float
    n: int
    white_sd: float
    spread: float

    @property
    def floor(self) -> float:
        """The smallest level of a process the record can hold a trace of (u): a tenth of the
        white noise averaged over the record (:data:`FIT_SPAN`)."""
        return self.white_sd / (FIT_SPAN * math.sqrt(self.n))

    @property
    def top(self) -> float:
        """The largest level of a process a fit on the record may reach (u): :data:`FIT_SPAN`
        times the readings' sd."""
        return FIT_SPAN * self.spread


def record_levels(rec: Record) -> RecordLevels:
    """The levels of rec a random process's fit range reads (:class:`RecordLevels`). The white sd
    is the MAD of the first differences / √2 (robust to an input's moves and to jumps), the rms
    of the differences where the MAD is 0 (readings on a coarse lattice mostly repeat), the
    readings' sd where both are 0; the smallest positive float for a constant record."""
    y = np.asarray(rec.y, float)
    d = np.diff(y)
    spread = float(np.std(y))
    white = float(1.4826 * np.median(np.abs(d - np.median(d))) / math.sqrt(2.0))
    if not white > 0:
        white = float(np.sqrt(np.mean(d * d)) / math.sqrt(2.0))
    tiny = float(np.finfo(float).tiny)
    white = white if white > 0 else max(spread, tiny)
    return RecordLevels(rec.dt_s, max(rec.duration_s, rec.dt_s), rec.n, white, max(spread, tiny))


@dataclass(frozen=True, eq=False)
class StateBlock:
    """A process as per-sample states ``x_k = F·x_{k−1} + e_k`` (cov e = ``q``) seen in the
    output as ``h·x_k``; ``p0`` the states' covariance at the first sample. Most processes are
    independent scalar states each added to the output (:meth:`diagonal`); a moving average (white
    angle noise, the difference of two successive angle errors) needs a non-diagonal ``f``."""

    f: np.ndarray
    q: np.ndarray
    h: np.ndarray
    p0: np.ndarray

    def __post_init__(self) -> None:
        f = np.atleast_2d(np.asarray(self.f, float))
        m = f.shape[0]
        arrays = {"f": f, "q": np.atleast_2d(np.asarray(self.q, float)),
                  "p0": np.atleast_2d(np.asarray(self.p0, float))}
        for name, a in arrays.items():
            if a.shape != (m, m) or not np.all(np.isfinite(a)):
                raise ValueError(f"StateBlock.{name} has shape {a.shape}; allowed: finite ({m}, {m})")
        h = np.asarray(self.h, float).reshape(-1)
        if h.shape != (m,) or not np.all(np.isfinite(h)):
            raise ValueError(f"StateBlock.h has shape {h.shape}; allowed: finite ({m},)")
        for name, a in (*arrays.items(), ("h", h)):
            object.__setattr__(self, name, a)

    @classmethod
    def diagonal(cls, phi: Sequence[float] | np.ndarray, q: Sequence[float] | np.ndarray,
                 p0: Sequence[float] | np.ndarray) -> StateBlock:
        """Independent states x_k = φ·x_{k−1} + e_k (var e = q), each added to the output."""
        return cls(np.diag(np.asarray(phi, float)), np.diag(np.asarray(q, float)), np.ones(len(phi)),
                   np.diag(np.asarray(p0, float)))

    @property
    def m(self) -> int:
        """Number of states."""
        return int(self.h.size)


def block_mean_deficit(block: StateBlock, m: int) -> float:
    """The white variance the means of ``m`` consecutive samples of ``block``'s process need
    beside it for "the same process at the means' rate plus white noise" to hold them exactly.

    Each independent first-order state x_k = φ·x_{k−1} + e_k (var e = q; σ² = q/(1 − φ²)): its
    block means have, at lags j ≥ 1, the autocovariance σ²·S²·φ^{1−m}/m² · φ^{mj} (S = Σ_{i<m} φ^i)
    — a first-order process at the means' rate (φ^m) of variance s² = σ²S²φ^{1−m}/m² — but at
    lag 0 only V₀ = σ²·(m + 2·Σ_{d<m}(m − d)φ^d)/m², less than s² (by about σ²·x/3 for a block
    x = m·dt/τ short of the correlation time). A walk (φ = 1): the first differences of its means
    have lag-1 covariance q·(m² − 1)/(6m), which a walk at the means' rate plus white noise holds
    only with that much less white. The sum over the states (their output weights squared) is
    what the means' white level must at least hold; a fit on block means whose white level is
    below it has bent its processes to stand in for the shortfall. Non-diagonal blocks (white
    angle noise's moving average) need none: their means are white."""
    if not m > 1:
        return 0.0
    f, q, h = block.f, block.q, block.h
    if np.any(f - np.diag(np.diag(f))):
        return 0.0
    out = 0.0
    d = np.arange(1, m)
    for phi, qi, hi in zip(np.diag(f), np.diag(q), h):
        if qi <= 0 or hi == 0:
            continue
        if phi >= 1.0:
            out += hi * hi * qi * (m * m - 1) / (6.0 * m)
            continue
        var = qi / (1.0 - phi * phi)
        ssum = (1.0 - phi ** m) / (1.0 - phi)
        s2 = ssum * ssum * phi ** (1 - m) / (m * m)
        v0 = (m + 2.0 * float(np.sum((m - d) * phi ** d))) / (m * m)
        out += hi * hi * var * max(s2 - v0, 0.0)
    return out


@dataclass(frozen=True)
class ComponentEstimate:
    """A fitted spectral component as the effect's parameters ± std (unclipped); the held-out
    one-step predictor runs the effect's own ``state_space`` at these parameters."""

    params: Params
    params_std: Params


@numba.njit(cache=True, nogil=True)
def _gauss_markov_add(out, dt, w, sigma, tau):
    """``out += x``: x_0 = σ·w_0 (stationary); x_k = φ_k·x_{k−1} + σ·sqrt(1 − φ_k²)·w_k,
    φ_k = exp(−dt_k/τ). φ_k and its gain are recomputed only where dt_k differs from dt_{k−1}
    (a uniform record's intervals repeat: the same numbers without an exp and a sqrt a sample)."""
    x = sigma * w[0]
    out[0] += x
    last = math.nan
    phi = gain = 0.0
    for k in range(1, w.size):
        if dt[k - 1] != last:
            last = dt[k - 1]
            phi = math.exp(-last / tau)
            gain = sigma * math.sqrt(1.0 - phi * phi)
        x = phi * x + gain * w[k]
        out[k] += x


@numba.njit(cache=True, nogil=True)
def _gauss_markov_sum(dt, w, sigma, taus):
    """Σ_j of the Gauss–Markov realisations of correlation time ``taus[j]`` driven by row j of
    ``w`` (:func:`_gauss_markov_add`), summed in row order from zero."""
    out = np.zeros(w.shape[1])
    for j in range(taus.size):
        _gauss_markov_add(out, dt, w[j], sigma, taus[j])
    return out


def _allan_z(avar_fn: Callable[[float], float], rec: Record, noise_sd: float) -> float:
    dt = rec.dt_s
    best = 0.0
    m = 1
    while rec.n // m >= 9:
        t = m * dt
        clusters = rec.n // m
        white = noise_sd ** 2 / m
        best = max(best, avar_fn(t) / white * math.sqrt((clusters - 1) / 2.0))
        m *= 2
    return best


class StochasticEffect(Effect):
    """A random process added to the output, judged on the residual's spectral shape (see the
    module docstring for its hooks). ``apply`` needs ``rng``; calibration keeps its parameters."""

    stochastic = True
    waveform = False
    #: log coordinates of its Whittle spectral component
    n_coords: int = 1
    #: its levels are not stationary (a walk): a finite record's levels periodogram departs from
    #: its spectrum at low frequencies (end-point leakage), so with it in the model candidates
    #: are judged on first differences, where it is white
    nonstationary: bool = False

    def plain_snr(self, p: Params, rec: Record, noise_sd: float) -> float:
        """A process's snr is its excess Allan variance (``snr``): look-alike processes are told
        apart by the spectral fit, not by projecting a waveform away."""
        return self.snr(p, rec, noise_sd)

    def _applied(self, p: Params, rec: Record, y: np.ndarray, rng: np.random.Generator | None) -> np.ndarray:
        if rng is None:
            raise ValueError(f"effect {self.id!r} is stochastic: apply needs rng (a numpy Generator)")
        return y + self.noise(p, rec, rng)

    def noise(self, p: Params, rec: Record, rng: np.random.Generator) -> np.ndarray:
        """One realisation of the process on rec's time stamps (sensor unit)."""
        raise NotImplementedError

    def spectrum(self, th: np.ndarray, c: np.ndarray, grad: bool) -> tuple[np.ndarray, list[np.ndarray]]:
        """Its level spectrum (per-sample units) at ``c`` = cos ω for its log coordinates ``th``
        and, when ``grad``, the derivative in each coordinate."""
        raise NotImplementedError

    def coords(self, p: Mapping[str, float], dt_s: float) -> list[float]:
        """The parameters ``p`` as its log coordinates at sample interval ``dt_s``."""
        raise NotImplementedError

    def whittle_starts(self, v: float) -> list[np.ndarray]:
        """Starting points ``[log σw², *its coordinates]`` of a fit to a periodogram of mean ``v``."""
        raise NotImplementedError

    def estimate(self, r: np.ndarray, th: np.ndarray, cov: np.ndarray, dt_s: float, *,
                 alone: bool, bootstrap: bool) -> ComponentEstimate:
        """Its fitted coordinates ``th`` (covariance ``cov``, both its own block) on residual
        ``r`` as parameters ± std. ``alone``: no other random process was fitted beside it;
        ``bootstrap``: a costlier bias correction is wanted (when the effect has one)."""
        raise NotImplementedError

    def state_space(self, p: Mapping[str, float], dt_s: float, n: int) -> StateBlock:
        """Its states for a record of ``n`` samples at interval ``dt_s`` (ValueError naming a
        parameter that no process has)."""
        raise NotImplementedError


#: A model's random processes with their parameters (``Model.stochastic_effects()``).
Processes = Sequence[tuple[StochasticEffect, Mapping[str, float]]]


class GaussMarkov(StochasticEffect):
    id = "gauss_markov"
    description = "exponentially correlated bias noise (first-order Gauss-Markov), e.g. bias instability"
    form = "x' = −x/tau_s + w, stationary sd sigma; y += x (exact discretisation for any dt)"
    inputs = ("t",)
    main_param = "sigma"
    signature = ("tau: Allan hump peaking near 1.9·tau_s; ACF e^{−lag/tau_s}; spectrum Lorentzian with corner "
                 "1/(2π·tau_s)")
    separating = {"rate_random_walk": "a record much longer than the correlation time: Gauss–Markov levels off "
                                      "in the Allan curve, a random walk keeps rising"}
    n_coords = 2  # log σ², logit φ
    # drawn: QA-2000 coloured noise µg over tens of s; FOG bias instability ~0.1-1 deg/h (3e-5-3e-4 deg/s);
    # fitted: any grade (a MEMS part's mg and tenths of deg/s), the range from the record (fit_range)
    ranges = reaching({
        "accelerometer": (Param("sigma", "g", 1e-8, 1e-3, log=True), Param("tau_s", "s", 0.1, 1e5, log=True)),
        "gyro": (Param("sigma", "deg/s", 1e-6, 0.1, log=True), Param("tau_s", "s", 0.1, 1e5, log=True)),
        "mhd": (Param("sigma", "deg/s", 1e-5, 1.0, log=True), Param("tau_s", "s", 1e-3, 1e4, log=True)),
    }, levels=("sigma",))

    def noise(self, p: Params, rec: Record, rng: np.random.Generator) -> np.ndarray:
        w = rng.standard_normal(rec.n)
        if p["sigma"] == 0:
            return np.zeros(rec.n)
        return _gauss_markov_sum(np.diff(rec.t_s), w[None, :], float(p["sigma"]), np.array([float(p["tau_s"])]))

    @staticmethod
    def avar(sigma: float, tau_s: float, t_s: float) -> float:
        """Allan variance of the process at averaging time t_s (u²)."""
        x = t_s / tau_s
        return 2 * sigma ** 2 * tau_s / t_s * (1 - (3 - 4 * math.exp(-x) + math.exp(-2 * x)) / (2 * x))

    def snr(self, p: Params, rec: Record, noise_sd: float) -> float:
        return _allan_z(lambda t: self.avar(p["sigma"], p["tau_s"], t), rec, noise_sd)

    def drawable_range(self, q: Param, rec: Record, kind: str) -> tuple[float, float]:
        if q.name == "tau_s":  # ten samples up to a thirtieth of the record: hump inside the Allan range
            lo = max(q.low, 10 * rec.dt_s)
            return lo, max(min(q.high, rec.duration_s / 30), lo * 1.01)
        return q.low, q.high

    def fit_range(self, q: Param, rec: Record, kind: str) -> tuple[float, float]:
        """From the record alone: tau_s from half a sample (φ = e^{−dt/τ} ≤ e^{−2} ≈ 0.14 below
        it: successive samples nearly independent, white at this rate) to the record's span
        (beyond it the process does not decorrelate within the record: there it is a random
        walk of K² = 2σ²/τ, the walk's to fit; ``identifiable`` asks for less than a fifth);
        sigma between the record's floor and top (:class:`RecordLevels`)."""
        lv = record_levels(rec)
        if q.name == "tau_s":
            return 0.5 * lv.dt_s, lv.duration_s
        return lv.floor, lv.top

    def identifiable(self, p: Mapping[str, float], rec: Record) -> bool:
        """A correlation time beyond a fifth of the record is not identifiable on it (a walk or a
        drift there)."""
        return p.get("tau_s", 0.0) < rec.duration_s / 5

    def fit_starts(self, rec: Record, residual: np.ndarray, *, kind: str | None = None,
                   rows: np.ndarray | None = None, held_out: np.ndarray | None = None) -> list[Params]:
        """sigma from the residual's sd after the white part (lag-1 covariance), tau_s where the
        autocorrelation falls to e^{−1} of its lag-1 value, and that tau ×/÷ 3."""
        r = project_out(np.asarray(residual, float), base_regressors(rec))
        r = r - r.mean()
        var = vdot(r, r) / r.size
        c1 = vdot(r[1:], r[:-1]) / r.size
        sigma = math.sqrt(max(c1, var * 0.05))
        lags = np.unique(np.geomspace(1, max(2, rec.n // 10), 40).astype(int))
        acf = np.array([vdot(r[k:], r[:-k]) / r.size for k in lags]) / max(c1, 1e-300)
        below = np.flatnonzero(acf < math.exp(-1))
        tau = float(lags[below[0]] * rec.dt_s) if below.size else rec.duration_s / 30
        q = self.params[1]
        return [{"sigma": sigma, "tau_s": float(np.clip(tau * f, q.low, q.high))} for f in (1.0, 3.0, 1 / 3)]

    # ---- spectral component: AR(1), x_k = φ x_{k−1} + e, var x = σ²: S = σ²(1 − φ²)/|1 − φe^{−iω}|²
    def spectrum(self, th: np.ndarray, c: np.ndarray, grad: bool) -> tuple[np.ndarray, list[np.ndarray]]:
        s2, phi = np.exp(th[0]), 1.0 / (1.0 + np.exp(-th[1]))
        den = 1 - 2 * phi * c + phi ** 2
        shape = (1 - phi ** 2) / den
        if not grad:
            return s2 * shape, []
        d_phi = (-2 * phi * den - (1 - phi ** 2) * (2 * phi - 2 * c)) / den ** 2
        return s2 * shape, [s2 * shape, s2 * d_phi * phi * (1 - phi)]

    def coords(self, p: Mapping[str, float], dt_s: float) -> list[float]:
        phi = float(np.clip(np.exp(-dt_s / p["tau_s"]), 1e-9, 1 - 1e-12))
        return [np.log(max(p["sigma"], 1e-150) ** 2), np.log(phi / (1 - phi))]

    def whittle_starts(self, v: float) -> list[np.ndarray]:
        return [np.r_[np.log(v * 0.8), np.log(v * b), np.log(phi / (1 - phi))]
                for b in (0.1, 1.0) for phi in (0.9, 0.995)]

    def estimate(self, r: np.ndarray, th: np.ndarray, cov: np.ndarray, dt_s: float, *,
                 alone: bool, bootstrap: bool) -> ComponentEstimate:
        """σ = exp(th0/2), τ = −dt/ln φ with φ = logistic(th1) (−ln φ = log1p(e^{−th1}): finite
        where φ rounds to 1); std by the delta method."""
        s2, phi = np.exp(th[0]), 1.0 / (1.0 + np.exp(-th[1]))
        sigma = float(np.sqrt(s2))
        neg_log_phi = max(float(np.log1p(np.exp(-th[1]))), 1e-300)
        tau = float(dt_s / neg_log_phi)
        d_sigma = 0.5 * sigma
        # dτ/dth1 = dt/(ln φ)² · (1/φ)·φ(1−φ) = τ·(1−φ)/(−ln φ); the ratio → 1 as φ → 1, where
        # (−ln φ)² underflows (a null replicate's fit at a correlation time of 10³⁰⁰ s divided by 0)
        d_tau = tau * (1.0 if th[1] > 30 else (1 - phi) / neg_log_phi)
        sd = np.sqrt(np.clip(np.diag(cov), 0, None))
        return ComponentEstimate({"sigma": sigma, "tau_s": tau},
                                 {"sigma": float(d_sigma * sd[0]), "tau_s": float(abs(d_tau) * sd[1])})

    def state_space(self, p: Mapping[str, float], dt_s: float, n: int) -> StateBlock:
        """One state: φ = e^{−dt/τ}, q = σ²(1 − φ²), starting stationary (variance σ²), as
        :meth:`noise` simulates it."""
        sigma, tau = float(p["sigma"]), float(p["tau_s"])
        if not (math.isfinite(sigma) and sigma >= 0 and math.isfinite(tau) and tau > 0):
            raise ValueError(f"gauss_markov sigma = {sigma!r}, tau_s = {tau!r}; allowed: sigma >= 0, tau_s > 0")
        f = math.exp(-dt_s / tau)
        return StateBlock.diagonal((f,), (sigma ** 2 * (1.0 - f * f),), (sigma ** 2,))


class RateRandomWalk(StochasticEffect):
    id = "rate_random_walk"
    description = "random walk of the bias (integrated white noise): rate random walk K in IEEE 952 terms"
    form = "x_k = x_{k−1} + k_per_rs·sqrt(dt_k)·w_k, x_0 = 0; y += x"
    inputs = ("t",)
    main_param = "k_per_rs"
    signature = "tau: Allan slope +1/2 at long tau (σ = K·sqrt(T/3)); spectrum 1/f²"
    kinds = ("accelerometer", "gyro")
    n_coords = 1  # log q, q = K²·dt the per-sample variance of the steps
    nonstationary = True
    # drawn: FOG RRW ~0.01-10 deg/h/√h (1 deg/h/√h = 4.6e-6 deg/s/√s), accelerometers µg/√s-class;
    # fitted: any grade, the range from the record (fit_range)
    ranges = reaching({
        "accelerometer": (Param("k_per_rs", "g/sqrt(s)", 1e-10, 1e-4, log=True),),
        "gyro": (Param("k_per_rs", "deg/s/sqrt(s)", 1e-8, 1e-2, log=True),),
    })

    def fit_range(self, q: Param, rec: Record, kind: str) -> tuple[float, float]:
        """From the record alone: the walks whose spread over the record, K·√T, lies between
        the record's floor and top (:class:`RecordLevels`)."""
        lv = record_levels(rec)
        root_t = math.sqrt(lv.duration_s)
        return lv.floor / root_t, lv.top / root_t

    def noise(self, p: Params, rec: Record, rng: np.random.Generator) -> np.ndarray:
        w = rng.standard_normal(rec.n)
        steps = p["k_per_rs"] * np.sqrt(np.diff(rec.t_s)) * w[1:]
        return np.concatenate([[0.0], np.cumsum(steps)])

    def snr(self, p: Params, rec: Record, noise_sd: float) -> float:
        k = p["k_per_rs"]
        return _allan_z(lambda t: k * k * t / 3.0, rec, noise_sd)

    def fit_starts(self, rec: Record, residual: np.ndarray, *, kind: str | None = None,
                   rows: np.ndarray | None = None, held_out: np.ndarray | None = None) -> list[Params]:
        """K from the growth of var(r[k+m] − r[k]) between lags n/10 and n/5 (the white part
        cancels in the difference), and ×/÷ 3."""
        r = np.asarray(residual, float)
        m1, m2 = max(1, rec.n // 10), max(2, rec.n // 5)
        v1 = float(np.var(r[m1:] - r[:-m1]))
        v2 = float(np.var(r[m2:] - r[:-m2]))
        k2 = (v2 - v1) / ((m2 - m1) * rec.dt_s)
        q = self.params[0]
        k = math.sqrt(k2) if k2 > 0 else q.low * 10
        return [{"k_per_rs": float(np.clip(k * f, q.low, q.high))} for f in (1.0, 3.0, 1 / 3)]

    # ---- spectral component: x_k = x_{k−1} + e, var e = q: S = q/|1 − e^{−iω}|² ---------------
    def spectrum(self, th: np.ndarray, c: np.ndarray, grad: bool) -> tuple[np.ndarray, list[np.ndarray]]:
        rw = np.exp(th[0]) / (2 - 2 * c)
        return rw, ([rw] if grad else [])

    def coords(self, p: Mapping[str, float], dt_s: float) -> list[float]:
        return [np.log(max(p["k_per_rs"], 1e-150) ** 2 * dt_s)]

    def whittle_starts(self, v: float) -> list[np.ndarray]:
        return [np.r_[np.log(v * 0.9), np.log(v * b)] for b in (1e-5, 1e-2)]

    def estimate(self, r: np.ndarray, th: np.ndarray, cov: np.ndarray, dt_s: float, *,
                 alone: bool, bootstrap: bool) -> ComponentEstimate:
        """Alone: q from the Whittle fit of the first differences, bias-corrected by parametric
        bootstrap when ``bootstrap`` (:func:`random_walk_q`); beside other processes the
        differenced fit has no room for them, so the levels' estimate stays. K = √(q/dt)."""
        if alone:
            q, q_std = random_walk_q(r, N_BOOT_RW if bootstrap else 0)
        else:
            q = float(np.exp(th[0]))
            with np.errstate(over="ignore", invalid="ignore"):  # a singular Hessian: infinite std
                q_std = float(q * np.sqrt(max(cov[0, 0], 0.0)))
        k = math.sqrt(q / dt_s)
        k_std = 0.5 * q_std / max(math.sqrt(q * dt_s), 1e-300)
        return ComponentEstimate({"k_per_rs": k}, {"k_per_rs": k_std})

    def state_space(self, p: Mapping[str, float], dt_s: float, n: int) -> StateBlock:
        """One state: φ = 1, q = K²·dt; its level at the first sample is not known once the bias
        is calibrated, so it starts with the variance the walk reaches over the record (K²·T) —
        the first innovations are then a little under unit variance, never over."""
        k = float(p["k_per_rs"])
        if not (math.isfinite(k) and k >= 0):
            raise ValueError(f"rate_random_walk k_per_rs = {k!r}; allowed: a finite number >= 0")
        return StateBlock.diagonal((1.0,), (k * k * dt_s,), (k * k * dt_s * n,))


#: Flicker as Gauss–Markov states: two per decade of correlation time (ratio √10: the sum's
#: spectrum ripples < 1 % about 1/f), from the band's shortest correlation time (never below a
#: quarter sample: white at the Nyquist frequency) to ten record lengths (flat below the lowest
#: Fourier frequency).
FLICKER_STATES_PER_DECADE = 2
FLICKER_TAU_MIN_SAMPLES = 0.25
FLICKER_TAU_MAX_RECORDS = 10.0


def flicker_taus(tau_min_s: float, dt_s: float, n: int) -> np.ndarray:
    """Correlation times (s) of the Gauss–Markov states whose equal-variance sum is flicker from
    ``tau_min_s`` over a record of ``n`` samples at ``dt_s`` (:data:`FLICKER_STATES_PER_DECADE`)."""
    lo = max(float(tau_min_s), FLICKER_TAU_MIN_SAMPLES * dt_s)
    hi = max(FLICKER_TAU_MAX_RECORDS * max(n, 2) * dt_s, 10 * lo)
    k = int(math.ceil(math.log10(hi / lo) * FLICKER_STATES_PER_DECADE)) + 1
    return np.geomspace(lo, hi, k)


class FlickerNoise(StochasticEffect):
    id = "flicker_noise"
    description = ("flicker (1/f) bias noise: the bias instability B of IEEE Std 952, realised as equal-variance "
                   "Gauss–Markov states with correlation times from tau_min_s to beyond the record")
    form = ("PSD S(f) = B²/(2π·f) (two-sided) below the corner 1/(2π·tau_min_s), falling as 1/f² above it: per "
            "sample (2B²/(π·ω))·atan(ω_c/ω), ω_c = dt/tau_min_s; Σ_k GM(s, τ_k), τ_k log-spaced two per decade "
            "from tau_min_s to 10·T, s² = B²·ln(τ_{k+1}/τ_k)/π; y += Σ x_k")
    inputs = ("t",)
    main_param = "b"
    signature = ("tau: a flat Allan floor 0.664·B (slope 0) above ~tau_min_s; spectrum 1/f below its corner; "
                 "innovations white")
    competitors = ("gauss_markov", "rate_random_walk")
    separating = {
        "gauss_markov": "a record much longer than the correlation time: Gauss–Markov's Allan curve falls as "
                        "1/√τ past its hump, flicker stays flat at 0.664·B",
        "rate_random_walk": "the Allan slope over the longest τ: flicker flat (0), a random walk rising (+1/2)",
    }
    n_coords = 2  # log B² (per-sample level B²/ω), log ω_c (the band's corner, rad/sample)
    # drawn: FOG bias instability 0.005-10 deg/h (1.4e-6 - 2.8e-3 deg/s), QA-2000-class µg flicker floors;
    # fitted: any grade, the range from the record (fit_range)
    ranges = reaching({
        "accelerometer": (Param("b", "g", 1e-9, 1e-3, log=True), Param("tau_min_s", "s", 1e-4, 1e5, log=True)),
        "gyro": (Param("b", "deg/s", 1e-7, 0.1, log=True), Param("tau_min_s", "s", 1e-4, 1e5, log=True)),
        "mhd": (Param("b", "deg/s", 1e-6, 1.0, log=True), Param("tau_min_s", "s", 1e-5, 1e4, log=True)),
    }, levels=("b",))

    def fit_range(self, q: Param, rec: Record, kind: str) -> tuple[float, float]:
        """From the record alone: tau_min_s from a quarter sample (white at the Nyquist
        frequency, :data:`FLICKER_TAU_MIN_SAMPLES`) to the record's span (a band starting beyond
        it is no 1/f on the record); b where flicker's flat Allan deviation, 0.664·B, lies
        between the record's floor and top (:class:`RecordLevels`; an Allan deviation is at most
        √2 times the readings' sd)."""
        lv = record_levels(rec)
        if q.name == "tau_min_s":
            return FLICKER_TAU_MIN_SAMPLES * lv.dt_s, lv.duration_s
        return lv.floor / FLICKER_ADEV, lv.top / FLICKER_ADEV

    def _terms(self, p: Mapping[str, float], dt_s: float, n: int) -> tuple[np.ndarray, float]:
        taus = flicker_taus(float(p["tau_min_s"]), dt_s, n)
        ratio = taus[1] / taus[0]
        return taus, float(p["b"]) * math.sqrt(math.log(ratio) / math.pi)

    def noise(self, p: Params, rec: Record, rng: np.random.Generator) -> np.ndarray:
        if p["b"] == 0:
            return np.zeros(rec.n)
        taus, s = self._terms(p, rec.dt_s, rec.n)
        # one state after the other from the stream: row j of the draw is state j's
        return _gauss_markov_sum(np.diff(rec.t_s), rng.standard_normal((taus.size, rec.n)), s, taus)

    @staticmethod
    def avar(b: float) -> float:
        """Allan variance of flicker (IEEE 952): (2 ln 2/π)·B², the same at every τ (u²)."""
        return 2 * math.log(2) / math.pi * b * b

    def snr(self, p: Params, rec: Record, noise_sd: float) -> float:
        """On the Allan variance of flicker at averaging times beyond its band's corner."""
        a = self.avar(float(p["b"]))
        return _allan_z(lambda t: a if t >= 2 * float(p["tau_min_s"]) else 0.0, rec, noise_sd)

    def drawable_range(self, q: Param, rec: Record, kind: str) -> tuple[float, float]:
        if q.name == "tau_min_s":  # a quarter sample to a hundredth of the record: 1/f over ≥ 2 decades
            lo = max(q.low, FLICKER_TAU_MIN_SAMPLES * rec.dt_s)
            return lo, max(min(q.high, rec.duration_s / 100), lo * 1.01)
        return q.low, q.high

    def identifiable(self, p: Mapping[str, float], rec: Record) -> bool:
        """Its band must span a decade inside the record (shortest correlation time under a
        twentieth of it): narrower, it is one Gauss–Markov."""
        return p.get("tau_min_s", 0.0) < rec.duration_s / 20

    def fit_starts(self, rec: Record, residual: np.ndarray, *, kind: str | None = None,
                   rows: np.ndarray | None = None, held_out: np.ndarray | None = None) -> list[Params]:
        """B from the residual's Allan variance at the longest τ with 9 clusters (its flat floor)."""
        r = np.asarray(residual, float) - float(np.mean(residual))
        m = max(1, rec.n // 9)
        means = r[: (rec.n // m) * m].reshape(-1, m).mean(axis=1)
        av = 0.5 * float(np.mean(np.diff(means) ** 2))
        q = self.params[0]
        b = math.sqrt(max(av, 0.0) / self.avar(1.0)) or q.low
        return [{"b": float(np.clip(b * f, q.low, q.high)), "tau_min_s": rec.dt_s} for f in (1.0, 3.0, 1 / 3)]

    # ---- spectral component: (2B²/(πω))·atan(ω_c/ω) per sample (B²/ω below the corner) ----
    def spectrum(self, th: np.ndarray, c: np.ndarray, grad: bool) -> tuple[np.ndarray, list[np.ndarray]]:
        w = np.arccos(np.clip(c, -1.0, 1.0))
        b2, wc = np.exp(th[0]), np.exp(th[1])
        level = b2 * (2.0 / (np.pi * w)) * np.arctan(wc / w)
        if not grad:
            return level, []
        return level, [level, b2 * (2.0 / np.pi) * wc / (w * w + wc * wc)]

    def coords(self, p: Mapping[str, float], dt_s: float) -> list[float]:
        return [math.log(max(float(p["b"]), 1e-150) ** 2), math.log(dt_s / float(p["tau_min_s"]))]

    def whittle_starts(self, v: float) -> list[np.ndarray]:
        return [np.r_[np.log(v * 0.9), np.log(v * b), np.log(wc)] for b in (1e-3, 3e-2) for wc in (0.05, 10.0)]

    def estimate(self, r: np.ndarray, th: np.ndarray, cov: np.ndarray, dt_s: float, *,
                 alone: bool, bootstrap: bool) -> ComponentEstimate:
        """B = exp(th0/2), tau_min = dt/exp(th1); std by the delta method."""
        with np.errstate(over="ignore", invalid="ignore"):  # a corner beyond Nyquist is unbounded
            b = float(np.exp(0.5 * th[0]))
            tau_min = float(dt_s * np.exp(-th[1]))
            sd = np.sqrt(np.clip(np.diag(cov), 0, None))
            return ComponentEstimate({"b": b, "tau_min_s": tau_min},
                                     {"b": float(0.5 * b * sd[0]), "tau_min_s": float(tau_min * sd[1])})

    def state_space(self, p: Mapping[str, float], dt_s: float, n: int) -> StateBlock:
        """The Gauss–Markov states of :meth:`noise`, each stationary at the first sample."""
        b, tau_min = float(p["b"]), float(p["tau_min_s"])
        if not (math.isfinite(b) and b >= 0 and math.isfinite(tau_min) and tau_min > 0):
            raise ValueError(f"flicker_noise b = {b!r}, tau_min_s = {tau_min!r}; allowed: b >= 0, tau_min_s > 0")
        taus, s = self._terms(p, dt_s, n)
        phi = np.exp(-dt_s / taus)
        return StateBlock.diagonal(phi, s * s * (1.0 - phi * phi), np.full(taus.size, s * s))


class AngleQuantization(StochasticEffect):
    id = "angle_quantization"
    description = ("white angle noise of a pulse-counting gyro (IEEE Std 952 Q): each reading is an angle "
                   "increment whose rounding error (variance Q²) is independent from reading to reading")
    form = "y += (e_k − e_{k−1})/dt, e white of sd q_angle (angle, deg): an MA(1) in the rate, zero at DC"
    inputs = ("t",)
    main_param = "q_angle"
    signature = ("tau: Allan slope −1 (σ = √3·Q/τ); spectrum rising as f² to the Nyquist frequency; lag-1 "
                 "autocorrelation negative")
    kinds = ("gyro",)
    separating = {"quantization": "a slow ramp of rate: reading quantization puts the readings on a lattice, "
                                  "angle quantization leaves their mean exact and anti-correlates neighbours"}
    n_coords = 1  # log c², c = Q/dt the rate noise per unit angle error
    # drawn: FOG pulses 0.05-2″ (Q = pulse/√12 ≈ 4e-6 - 2e-4 deg) up to coarse read-outs;
    # fitted: any grade, the range from the record (fit_range)
    ranges = reaching({
        "gyro": (Param("q_angle", "deg", 1e-7, 0.1, log=True),),
    })

    def fit_range(self, q: Param, rec: Record, kind: str) -> tuple[float, float]:
        """From the record alone: the angle noises whose rate sd √2·Q/dt lies between the
        record's floor and top (:class:`RecordLevels`)."""
        lv = record_levels(rec)
        return lv.floor * lv.dt_s / math.sqrt(2.0), lv.top * lv.dt_s / math.sqrt(2.0)

    def noise(self, p: Params, rec: Record, rng: np.random.Generator) -> np.ndarray:
        """Angle errors uniform on ±√3·Q (a rounding error of a dithered angle), differenced and
        divided by each sample's interval."""
        q = float(p["q_angle"])
        e = rng.uniform(-math.sqrt(3.0) * q, math.sqrt(3.0) * q, rec.n + 1)
        dt = np.diff(rec.t_s, prepend=rec.t_s[0] - rec.dt_s)
        return (e[1:] - e[:-1]) / dt

    def snr(self, p: Params, rec: Record, noise_sd: float) -> float:
        q = float(p["q_angle"])
        return _allan_z(lambda t: 3.0 * q * q / (t * t), rec, noise_sd)

    def main_draw_clip(self, rec: Record, kind: str, noise_sd: float) -> tuple[float, float]:
        """Readings stay off a visible lattice: the rate step √12·Q/dt of a pulse counter below
        π·σ·√(2/ln n), where the lattice's visibility exp(−2π²σ²/step²)·√n is one."""
        top = math.pi * noise_sd * math.sqrt(2.0 / math.log(max(rec.n, 3))) / math.sqrt(12.0) * rec.dt_s
        return 0.0, top

    def fit_starts(self, rec: Record, residual: np.ndarray, *, kind: str | None = None,
                   rows: np.ndarray | None = None, held_out: np.ndarray | None = None) -> list[Params]:
        """Q from the residual's negative lag-1 covariance: cov(1) = −Q²/dt²."""
        r = np.asarray(residual, float) - float(np.mean(residual))
        c1 = float(np.mean(r[1:] * r[:-1]))
        q = self.params[0]
        v = math.sqrt(max(-c1, 1e-3 * float(np.mean(r * r)))) * rec.dt_s
        return [{"q_angle": float(np.clip(v * f, q.low, q.high))} for f in (1.0, 3.0, 1 / 3)]

    # ---- spectral component: c²·|1 − e^{−iω}|² per sample ----------------------------------
    def spectrum(self, th: np.ndarray, c: np.ndarray, grad: bool) -> tuple[np.ndarray, list[np.ndarray]]:
        level = np.exp(th[0]) * (2.0 - 2.0 * c)
        return level, ([level] if grad else [])

    def coords(self, p: Mapping[str, float], dt_s: float) -> list[float]:
        return [math.log(max(float(p["q_angle"]) / dt_s, 1e-150) ** 2)]

    def whittle_starts(self, v: float) -> list[np.ndarray]:
        return [np.r_[np.log(v * 0.9), np.log(v * b)] for b in (1e-2, 0.1)]

    def estimate(self, r: np.ndarray, th: np.ndarray, cov: np.ndarray, dt_s: float, *,
                 alone: bool, bootstrap: bool) -> ComponentEstimate:
        """Q = dt·exp(th0/2); std by the delta method."""
        q = float(dt_s * np.exp(0.5 * th[0]))
        return ComponentEstimate({"q_angle": q},
                                 {"q_angle": float(0.5 * q * math.sqrt(max(float(cov[0, 0]), 0.0)))})

    def state_space(self, p: Mapping[str, float], dt_s: float, n: int) -> StateBlock:
        """Two states (e_k, e_{k−1}) scaled to rate: F = [[0, 0], [1, 0]], the output their
        difference — the non-diagonal block of a moving average."""
        q = float(p["q_angle"])
        if not (math.isfinite(q) and q >= 0):
            raise ValueError(f"angle_quantization q_angle = {q!r}; allowed: a finite number >= 0")
        c2 = (q / dt_s) ** 2
        return StateBlock(np.array([[0.0, 0.0], [1.0, 0.0]]), np.diag([c2, 0.0]), np.array([1.0, -1.0]),
                          np.diag([c2, c2]))


def _diff_whittle(r: np.ndarray) -> np.ndarray:
    """Log coordinates (log σw², log q) of the Whittle fit of the first differences: spectrum
    c·(ρ + |1 − e^{−iω}|²), the level c profiled out (c = mean(I/(ρ + g))), ρ = q/σw² by a
    bounded scalar search in log ρ."""
    w, i = periodogram(np.diff(r))
    g = 2 - 2 * np.cos(w)

    def prof(lr: float) -> tuple[float, float]:
        s = np.exp(lr) + g
        c = float(np.mean(i / s))
        return float(np.sum(np.log(c * s)) + i.size), c

    res = optimize.minimize_scalar(lambda a: prof(a)[0], bounds=(-40.0, 15.0), method="bounded",
                                   options={"xatol": 1e-4})
    c = prof(res.x)[1]
    return np.array([np.log(c), np.log(c) + res.x])


def random_walk_q(r: np.ndarray, n_boot: int = N_BOOT_RW) -> tuple[float, float]:
    """(q, std q) of a random walk + white from the Whittle fit of the first differences
    (stationary: q + σw²|1 − e^{−iω}|²; the levels' periodogram biases q upwards through the
    end-point jump of a finite walk), bias-corrected and with its std from a parametric
    bootstrap: ``n_boot`` walks + white of the fitted levels, refitted the same way. On short
    records the differenced fit rests on a few low frequencies where leakage from the white
    part inflates q (≈ +18 % at q/σw² ~ 1e-3, 3000 samples) and its Hessian std is ~2× too
    small; the bootstrap's median ratio corrects the first and its spread is the std."""
    th = _diff_whittle(r)
    q_hat, w2 = float(np.exp(th[1])), float(np.exp(th[0]))
    if n_boot < 2:
        return q_hat, float("nan")
    rng = np.random.default_rng(r.size)  # fixed: same data → same answer
    n = r.size
    ks = np.empty(n_boot)  # in √q (∝ K, the reported parameter): mean bias and spread there
    for b in range(n_boot):
        x = np.cumsum(rng.normal(0.0, np.sqrt(q_hat), n)) + rng.normal(0.0, np.sqrt(w2), n)
        ks[b] = np.exp(0.5 * _diff_whittle(x)[1])
    ratio = float(np.mean(ks)) / np.sqrt(q_hat)
    k = np.sqrt(q_hat) / ratio
    # std of q such that the delta method back to √q gives the bootstrap spread of √q
    return float(k * k), float(2 * k * np.std(ks, ddof=1) / ratio)
