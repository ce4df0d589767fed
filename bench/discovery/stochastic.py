"""Stochastic candidates judged on the residual's spectral shape: Gauss–Markov and random walk.

A stochastic effect has no waveform to fit, so it is judged on the *shape* of the residual's
spectrum (equivalently its ACF / Allan curve):

* fit: Whittle likelihood of the periodogram I(ω_j) (Fourier frequencies j = 1 … n/2−1, ω in
  rad/sample) under S(ω) = σw² + S_c(ω) with S_c the candidate's spectrum in per-sample units:
  first-order Gauss–Markov (AR(1), x_k = φ x_{k−1} + e, var x = σ²):
  S_c = σ²(1 − φ²)/|1 − φe^{−iω}|²; random walk (x_k = x_{k−1} + e, var e = q):
  S_c = q/|1 − e^{−iω}|². The random walk's q is then re-estimated on the first differences
  (stationary: q + σw²|1 − e^{−iω}|²; the levels' periodogram overstates q through the
  end-point jump of a finite walk); the likelihood ratio stays the levels' one so the two
  shapes are compared on the same data; its bias and std come from a parametric bootstrap
  (see :func:`_random_walk_q`). Other parameter standard errors from the inverse Hessian of the Whittle
  log-likelihood (numerical, in the optimiser's log coordinates, mapped by the delta method).
* significance: likelihood-ratio statistic against white noise of free variance, referred to
  χ² with the number of extra parameters (2 for Gauss–Markov, 1 for the random walk); the null
  includes the model's own stochastic effects (``known``: every parameter free in the null and
  the alternative alike), so the test is calibrated on the current model's noise. p is floored
  at ``P_FLOOR`` (1e-300) instead of underflowing to 0.
* held-out score (comparable with the deterministic candidates'): the steady-state Kalman
  one-step predictor of the residual with the fitted parameters; out-of-sample variance
  reduction ``1 − Σ_test e_k² / Σ_test r_k²`` on the held-out blocks of both folds (the
  predictor only uses past samples; its parameters are fitted on the training fold's blocks).

All pure numpy/scipy; the residual in the sensor unit, ``dt_s`` the sample interval.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import optimize, signal, stats

KINDS = ("gauss_markov", "random_walk")


@dataclass(frozen=True)
class StochasticFit:
    """Fitted candidate: ``kind``; white σw; GM σ (unit) and τ (s) or RW q (unit² per sample);
    standard errors; Whittle log-likelihood gain over white and its χ² p-value."""

    kind: str
    white_sd: float
    sigma: float
    tau_s: float
    q: float
    sigma_std: float
    tau_std_s: float
    q_std: float
    lr: float
    p_value: float
    theta: tuple = ()


def _periodogram(r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = r.size
    spec = np.fft.rfft(r - r.mean())
    i = np.abs(spec) ** 2 / n
    w = 2 * np.pi * np.arange(i.size) / n
    keep = (w > 0) & (w < np.pi)
    return w[keep], i[keep]


#: log coordinates of each spectral component (after the white level log σw²): Gauss–Markov
#: (log σ², logit φ), random walk log q
N_PARAMS = {"gauss_markov": 2, "random_walk": 1}


def _pieces(kinds: tuple[str, ...], th: np.ndarray, c: np.ndarray,
            grad: bool = True) -> tuple[np.ndarray, list]:
    """The level spectrum of white + ``kinds`` at log coordinates ``th`` and (``grad``) its
    derivative in each coordinate (``c`` = cos ω)."""
    white = np.exp(th[0])
    lev = np.full_like(c, white)
    parts = [lev.copy()] if grad else []
    j = 1
    for kind in kinds:
        if kind == "gauss_markov":
            s2, phi = np.exp(th[j]), 1.0 / (1.0 + np.exp(-th[j + 1]))
            den = 1 - 2 * phi * c + phi ** 2
            shape = (1 - phi ** 2) / den
            lev = lev + s2 * shape
            if grad:
                d_phi = (-2 * phi * den - (1 - phi ** 2) * (2 * phi - 2 * c)) / den ** 2
                parts += [s2 * shape, s2 * d_phi * phi * (1 - phi)]
        else:
            rw = np.exp(th[j]) / (2 - 2 * c)
            lev = lev + rw
            if grad:
                parts.append(rw)
        j += N_PARAMS[kind]
    return lev, parts


def _nll(th, kinds, w, i, diff=False):
    """The Whittle NLL alone (the Hessian's and the null's scalar search's evaluations)."""
    return _nll_grad(th, kinds, w, i, diff, grad=False)[0]


def _nll_grad(th, kinds, w, i, diff=False, grad=True):
    """(Whittle NLL of white + ``kinds``, its gradient in ``th``): Σ (1/S − I/S²)·∂S/∂θ (the
    optimiser's hot loop). ``diff``: ``i`` is the periodogram of the first differences, so
    every level spectrum is multiplied by |1 − e^{−iω}|². ``grad`` False: the gradient is not
    computed (None)."""
    th = np.asarray(th, float)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):  # a wild trial step: inf
        c = np.cos(w)
        g = (2 - 2 * c) if diff else 1.0
        lev, parts = _pieces(tuple(kinds), th, c, grad)
        s = lev * g
        if not np.all(np.isfinite(s)) or np.any(s <= 0):
            return np.inf, (np.zeros_like(th) if grad else None)
        if not grad:
            return float(np.sum(np.log(s) + i / s)), None
        k = (1.0 / s - i / s ** 2) * g
        return float(np.sum(np.log(s) + i / s)), np.array([float(np.sum(k * d)) for d in parts])


def _known_coords(known: list[tuple[str, dict]], dt_s: float) -> tuple[tuple[str, ...], np.ndarray]:
    """The model's stochastic effects as spectral components and their log coordinates:
    ("gauss_markov", {sigma, tau_s}) and ("rate_random_walk", {k_per_rs}) (q = K²·dt).

    They are nuisance components of the likelihood ratio: every parameter free — profiled — in
    the null and the alternative alike, started at the model's values. Held at the previous
    step's estimates, their error was colour a new candidate could claim: a Gauss–Markov on a
    model holding a (bias-corrected) walk came out p < 0.05 on 9 of 40 records of the model's
    own noise, and a real one on top of the walk was missed half the time
    (tests/discovery/test_discovery_workflow.py)."""
    kinds, th = [], []
    for eid, p in known:
        if eid == "gauss_markov":
            phi = float(np.clip(np.exp(-dt_s / p["tau_s"]), 1e-9, 1 - 1e-12))
            kinds.append("gauss_markov")
            th += [np.log(max(p["sigma"], 1e-150) ** 2), np.log(phi / (1 - phi))]
        elif eid == "rate_random_walk":
            kinds.append("random_walk")
            th.append(np.log(max(p["k_per_rs"], 1e-150) ** 2 * dt_s))
    return tuple(kinds), np.array(th, float)


def _minimize(kinds: tuple[str, ...], starts: list[np.ndarray], w, i, diff):
    best = None
    for th0 in starts:
        # unbounded log coordinates: plain BFGS (L-BFGS-B costs ms per iteration in its driver here)
        res = optimize.minimize(_nll_grad, th0, args=(kinds, w, i, diff), jac=True, method="BFGS")
        if best is None or res.fun < best.fun:
            best = res
    return best


#: Parametric-bootstrap replicates for the random walk's q (each one Whittle fit: FFT-cheap).
N_BOOT_RW = 60
#: Smallest p-value reported (a χ² tail below it underflows to 0.0): "p < 1e-300".
P_FLOOR = 1e-300


def _diff_whittle(r: np.ndarray) -> np.ndarray:
    """Log coordinates (log σw², log q) of the Whittle fit of the first differences: spectrum
    c·(ρ + |1 − e^{−iω}|²), the level c profiled out (c = mean(I/(ρ + g))), ρ = q/σw² by a
    bounded scalar search in log ρ."""
    w, i = _periodogram(np.diff(r))
    g = 2 - 2 * np.cos(w)

    def prof(lr):
        s = np.exp(lr) + g
        c = float(np.mean(i / s))
        return float(np.sum(np.log(c * s)) + i.size), c

    res = optimize.minimize_scalar(lambda a: prof(a)[0], bounds=(-40.0, 15.0), method="bounded",
                                   options={"xatol": 1e-4})
    c = prof(res.x)[1]
    return np.array([np.log(c), np.log(c) + res.x])


def _random_walk_q(r: np.ndarray, th0: np.ndarray | None = None, n_boot: int = N_BOOT_RW) -> tuple[float, float]:
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


def white_nll(r: np.ndarray, dt_s: float, known: list[tuple[str, dict]] = ()) -> float:
    """Whittle negative log-likelihood of ``r`` under white noise of free variance plus the
    model's known stochastic effects (the null of :func:`fit_stochastic`): two residuals'
    values differ by half a likelihood-ratio statistic on the same footing as the
    stochastic candidates' (used to weigh a deterministic fit against them)."""
    r = np.asarray(r, dtype=float)
    diff = _has_walk(known)  # as in fit_stochastic
    w, i = _periodogram(np.diff(r) if diff else r)
    kinds, th_k = _known_coords(list(known), dt_s)
    return float(_null(kinds, th_k, w, i, diff).fun)


def _null(kinds: tuple[str, ...], th_k: np.ndarray, w, i, diff: bool):
    """Fit of white noise of free level plus the known components (all parameters free)."""
    v = float(np.mean(i)) / (2.0 if diff else 1.0)
    if not kinds:
        res = optimize.minimize_scalar(lambda a: _nll(np.array([a]), (), w, i, diff),
                                       bounds=(np.log(v) - 20, np.log(v) + 2), method="bounded")
        return optimize.OptimizeResult(x=np.array([res.x]), fun=float(res.fun))
    # the white floor nearly all of the variance, or half of it; the components as in the model
    return _minimize(kinds, [np.r_[np.log(v * share), th_k] for share in (0.5, 0.99)], w, i, diff)


def _has_walk(known) -> bool:
    return any(eid == "rate_random_walk" for eid, _ in known)


def fit_stochastic(r: np.ndarray, dt_s: float, kind: str, start: np.ndarray | None = None,
                   known: list[tuple[str, dict]] = (), bootstrap: bool = True) -> StochasticFit:
    """Whittle fit of ``kind`` ("gauss_markov" or "random_walk") plus white noise to ``r``;
    ``start``: log coordinates to start from (a previous fit's ``theta``) instead of the grid;
    ``known``: stochastic effects already in the model (nuisance components: every parameter
    free in both the null and the alternative of the likelihood ratio, see :func:`_known_coords`);
    ``bootstrap``: the random walk's q bias-corrected with its std by parametric bootstrap (off
    where only the shape matters)."""
    if kind not in KINDS:
        raise ValueError(f"kind = {kind!r}; allowed: {KINDS}")
    r = np.asarray(r, dtype=float)
    # a known random walk: judge on the first differences (where the walk is white), since a
    # finite walk's levels periodogram departs from q/|1 − e^{−iω}|² at low frequencies
    # (end-point leakage) and that misfit would read as the candidate's colour
    diff = _has_walk(known)
    w, i = _periodogram(np.diff(r) if diff else r)
    known_kinds, th_k = _known_coords(list(known), dt_s)
    null = _null(known_kinds, th_k, w, i, diff)
    th_k = np.asarray(null.x, float)[1:]  # the known components as the null fits them
    kinds = (kind, *known_kinds)
    v = float(np.mean(i)) / (2.0 if diff else 1.0)
    n_c = N_PARAMS[kind]
    if start is not None:
        starts = [np.r_[np.asarray(start, float)[:1 + n_c], th_k]]
    elif kind == "gauss_markov":
        starts = [np.r_[np.log(v * 0.8), np.log(v * b), np.log(phi / (1 - phi)), th_k]
                  for b in (0.1, 1.0) for phi in (0.9, 0.995)]
    else:
        starts = [np.r_[np.log(v * 0.9), np.log(v * b), th_k] for b in (1e-5, 1e-2)]
    best = _minimize(kinds, starts, w, i, diff)
    th = best.x
    lr = max(0.0, 2.0 * (float(null.fun) - best.fun))
    df = 2 if kind == "gauss_markov" else 1
    p = max(float(stats.chi2.sf(lr, df)), P_FLOOR)
    cov = _inv_hessian(lambda x: _nll(x, kinds, w, i, diff), th)
    white_sd = float(np.sqrt(np.exp(th[0])))
    if kind == "gauss_markov":
        s2, phi = np.exp(th[1]), 1.0 / (1.0 + np.exp(-th[2]))
        sigma = float(np.sqrt(s2))
        tau = float(-dt_s / np.log(phi))
        # delta method: σ = exp(th1/2); τ = −dt/ln φ with φ = logistic(th2)
        d_sigma = 0.5 * sigma
        d_tau = dt_s / np.log(phi) ** 2 * (1 - phi)  # dτ/dth2 = dt/(ln φ)² · (1/φ)·φ(1−φ)
        sd = np.sqrt(np.clip(np.diag(cov), 0, None))
        return StochasticFit(kind, white_sd, sigma, tau, 0.0, float(d_sigma * sd[1]),
                             float(abs(d_tau) * sd[2]), 0.0, lr, p, tuple(th[:1 + n_c]))
    if not known:
        q, q_std = _random_walk_q(r, th, N_BOOT_RW if bootstrap else 0)
    else:  # the differenced fit has no room for known components: keep the levels' estimate
        q = float(np.exp(th[1]))
        q_std = float(q * np.sqrt(max(cov[1, 1], 0.0)))
    return StochasticFit(kind, white_sd, 0.0, 0.0, q, 0.0, 0.0, q_std, lr, p, tuple(th[:1 + n_c]))


def _inv_hessian(f, x: np.ndarray, h: float = 1e-3) -> np.ndarray:
    k = x.size
    hess = np.zeros((k, k))
    for a in range(k):
        for b in range(a, k):
            ea, eb = np.eye(k)[a] * h, np.eye(k)[b] * h
            val = (f(x + ea + eb) - f(x + ea - eb) - f(x - ea + eb) + f(x - ea - eb)) / (4 * h * h)
            hess[a, b] = hess[b, a] = val
    try:
        return np.linalg.inv(hess)
    except np.linalg.LinAlgError:
        return np.full((k, k), np.inf)


def one_step_prediction(r: np.ndarray, fit: StochasticFit) -> np.ndarray:
    """Steady-state Kalman one-step prediction of ``r`` from its past (state x: the GM or RW
    process; measurement r = x + white)."""
    if fit.kind == "gauss_markov":
        phi = float(np.exp(-1.0 / max(fit.tau_s, 1e-12)))  # per sample, tau in samples below
        return _kalman(r, phi, fit.sigma ** 2 * (1 - phi ** 2), fit.white_sd ** 2)
    return _kalman(r, 1.0, fit.q, fit.white_sd ** 2)


def _kalman(r: np.ndarray, phi: float, q: float, rv: float) -> np.ndarray:
    # steady-state prior variance P solves P = φ²P·rv/(P+rv) + q (scalar Riccati)
    a = 1.0
    b = rv * (1 - phi ** 2) - q
    c = -q * rv
    p = (-b + np.sqrt(b * b - 4 * a * c)) / (2 * a)
    k = p / (p + rv)
    # filtered x_k|k = φ(1−K) x_{k−1|k−1} + K r_k ; prediction of r_k = φ x_{k−1|k−1}
    filt = signal.lfilter([k], [1.0, -phi * (1 - k)], r)
    pred = np.empty_like(r)
    pred[0] = 0.0
    pred[1:] = phi * filt[:-1]
    return pred


def heldout_score(r: np.ndarray, dt_s: float, kind: str, folds: np.ndarray,
                  start: np.ndarray | None = None) -> tuple[float, np.ndarray, np.ndarray]:
    """Held-out one-step prediction score and the per-sample squared errors (candidate, base).

    Parameters are fitted on the training fold only: its held-out blocks are set to zero and
    the series rescaled by 1/√(training fraction) before the Whittle fit (the gaps smear the
    spectrum a little at the block frequency; the shape at other frequencies is kept)."""
    err_c = np.zeros_like(r)
    err_b = np.zeros_like(r)
    for k in (0, 1):
        te = folds == k
        train = np.where(te, 0.0, r - r[~te].mean())
        frac = float(np.mean(~te))
        fit = fit_stochastic(train / np.sqrt(frac), dt_s, kind, start, bootstrap=False)
        fit_s = StochasticFit(fit.kind, fit.white_sd, fit.sigma, fit.tau_s / dt_s, fit.q,
                              0, 0, 0, 0, 1)
        rc = r - r[~te].mean()
        pred = one_step_prediction(rc, fit_s)
        err_c[te] = (rc - pred)[te] ** 2
        err_b[te] = rc[te] ** 2
    score = 1.0 - err_c.sum() / err_b.sum() if err_b.sum() > 0 else 0.0
    return float(score), err_c, err_b
