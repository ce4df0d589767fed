"""Stochastic candidates judged on the residual's spectral shape.

A stochastic effect (:class:`bench.discovery.effects_noise.StochasticEffect`) has no waveform
to fit, so it is judged on the *shape* of the residual's spectrum (equivalently its ACF / Allan
curve); which processes exist, and their spectra, are the effects' own hooks:

* fit: Whittle likelihood (:mod:`bench.discovery.whittle`) of the residual under white noise
  plus the candidate's spectral component (``spectrum``, started at ``whittle_starts``); its
  log coordinates back to the effect's parameters by ``estimate`` (the random walk re-estimates
  its q on the first differences, where the levels' end-point jump does not bias it, with a
  parametric-bootstrap bias correction and std). Other standard errors from the inverse Hessian
  of the Whittle log-likelihood (numerical, in the optimiser's log coordinates, mapped by the
  delta method).
* significance: likelihood-ratio statistic against white noise of free variance, referred to
  χ² with the number of extra parameters (the component's ``n_coords``); the null includes the
  model's own stochastic effects (``known``: every parameter free in the null and the
  alternative alike), so the test is calibrated on the current model's noise. p is floored
  at ``P_FLOOR`` (1e-300) instead of underflowing to 0.
* ranges: a fit's range comes from the residual itself (:func:`fit_bounds`: its sample
  interval, span, white level and spread, the effect's ``fit_range``), for any sensor grade; the
  Whittle fit is unbounded in its log coordinates, the parameters a model takes are clipped to
  that range, and a fit that stopped at a bound says so (``StochasticFit.edges``, ``notes``).
* held-out score (comparable with the deterministic candidates'): the Kalman one-step predictor
  of the residual under the fitted process's own states (``state_space``); out-of-sample variance
  reduction ``1 − Σ_test e_k² / Σ_test r_k²`` on the held-out blocks of both folds (the
  predictor only uses past samples; its parameters are fitted on the training fold's blocks).

All pure numpy/scipy; the residual in the sensor unit, ``dt_s`` the sample interval.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize, stats

from bench.discovery import whiten
from bench.discovery.data import Record
from bench.discovery.effects_base import Effect, Param, Params, edge_notes
from bench.discovery.effects_noise import Processes, StateBlock, StochasticEffect
from bench.discovery.significance import P_FLOOR
from bench.discovery.whittle import inv_hessian, minimize, nll, periodogram


@dataclass(frozen=True)
class StochasticFit:
    """Fitted candidate ``effect``: white σw, the effect's parameters ± std (unclipped), its
    states at those parameters (``effect.state_space``: what the held-out one-step predictor
    runs), the Whittle log-likelihood gain over the null and its χ² p-value, and the log
    coordinates ``theta`` (white, then the component's: a start for a refit)."""

    effect: StochasticEffect
    white_sd: float
    params: Params
    params_std: Params
    states: StateBlock
    lr: float
    p_value: float
    theta: tuple[float, ...] = ()
    #: the fit range of each parameter on the residual (:func:`fit_bounds`); () unknown
    bounds: tuple[Param, ...] = ()

    def params_for(self, kind: str) -> dict[str, float]:
        """The fitted parameters clipped to the fit range on the residual (``bounds``; without
        them the kind's physical range) within what ``kind``'s model may hold."""
        fit = {b.name: b for b in self.bounds}
        out = {}
        for q in self.effect.params_for(kind):
            b = fit.get(q.name)
            lo, hi = (max(b.low, q.fit_low), min(b.high, q.fit_high)) if b is not None else (q.low, q.high)
            out[q.name] = float(np.clip(self.params[q.name], lo, hi))
        return out

    @property
    def edges(self) -> tuple[str, ...]:
        """Names of the parameters fitted at (within ``EDGE_FRACTION`` of) or beyond a bound of
        their fit range: the range, not the record, stopped them."""
        return tuple(b.name for b in self.bounds if b.edge(self.params[b.name]))

    @property
    def notes(self) -> tuple[str, ...]:
        """One line per parameter at a bound, for a report: ``"gauss_markov.tau_s at its upper
        bound 3600 s"``."""
        return edge_notes(self.effect.id, self.params, self.bounds)


def fit_bounds(effect: Effect, r: np.ndarray, dt_s: float) -> tuple[Param, ...]:
    """The fit range of each of ``effect``'s parameters on the residual ``r`` (sample interval
    ``dt_s``; NaN: missing samples, set to the mean of the others): its ``fit_range`` on the
    residual as a record, within the widest a model of any kind may hold. A random process's
    range reads only the record (:class:`~bench.discovery.effects_noise.RecordLevels`), so the
    kind passed to it is immaterial."""
    r = np.asarray(r, float)
    seen = np.isfinite(r)
    y = np.where(seen, r, float(np.mean(r[seen])) if seen.any() else 0.0)
    rec = Record(t_s=dt_s * np.arange(max(y.size, 2)), y=y if y.size >= 2 else np.zeros(2))
    out = []
    for q in effect.params:
        lo, hi = effect.fit_range(q, rec, effect.kinds[0])
        lo, hi = max(lo, q.fit_low), min(hi, q.fit_high)
        unit = q.unit if "|" not in q.unit else "u"  # a level in the sensor's unit, whatever the kind
        out.append(Param(q.name, unit, lo, hi, log=q.log, linear=q.linear) if lo < hi else q)
    return tuple(out)


def _known_coords(known: Processes, dt_s: float) -> tuple[tuple[StochasticEffect, ...], np.ndarray]:
    """The model's stochastic effects as spectral components and their log coordinates.

    They are nuisance components of the likelihood ratio: every parameter free — profiled — in
    the null and the alternative alike, started at the model's values. Held at the previous
    step's estimates, their error was colour a new candidate could claim: a Gauss–Markov on a
    model holding a (bias-corrected) walk came out p < 0.05 on 9 of 40 records of the model's
    own noise, and a real one on top of the walk was missed half the time
    (tests/discovery/test_discovery_workflow.py)."""
    comps: list[StochasticEffect] = []
    th: list[float] = []
    for eff, p in known:
        comps.append(eff)
        th += eff.coords(p, dt_s)
    return tuple(comps), np.array(th, float)


def _judged_on_differences(known: Processes) -> bool:
    """A non-stationary process in the model (a walk): judge on the first differences, where it
    is white, since a finite walk's levels periodogram departs from its spectrum at low
    frequencies (end-point leakage) and that misfit would read as the candidate's colour."""
    return any(eff.nonstationary for eff, _ in known)


def _null(comps: tuple[StochasticEffect, ...], th_k: np.ndarray, c: np.ndarray, i: np.ndarray,
          diff: bool) -> optimize.OptimizeResult:
    """Fit of white noise of free level plus the known components (all parameters free); ``c``
    = cos ω at the periodogram ``i``'s frequencies."""
    v = float(np.mean(i)) / (2.0 if diff else 1.0)
    if not comps:
        res = optimize.minimize_scalar(lambda a: nll(np.array([a]), (), c, i, diff),
                                       bounds=(np.log(v) - 20, np.log(v) + 2), method="bounded")
        return optimize.OptimizeResult(x=np.array([res.x]), fun=float(res.fun))
    # the white floor nearly all of the variance, or half of it; the components as in the model
    return minimize(comps, [np.r_[np.log(v * share), th_k] for share in (0.5, 0.99)], c, i, diff)


def fit_stochastic(r: np.ndarray, dt_s: float, effect: Effect, start: np.ndarray | None = None,
                   known: Processes = (), bootstrap: bool = True) -> StochasticFit:
    """Whittle fit of ``effect``'s spectral component plus white noise to ``r``; ``start``: log
    coordinates to start from (a previous fit's ``theta``) instead of the effect's starts;
    ``known``: stochastic effects already in the model (nuisance components: every parameter
    free in both the null and the alternative of the likelihood ratio, see :func:`_known_coords`);
    ``bootstrap``: the effect's costlier bias correction (the random walk's parametric
    bootstrap; off where only the shape matters). ValueError for an effect that is not a random
    process."""
    if not isinstance(effect, StochasticEffect):
        raise ValueError(f"effect {effect.id!r} is not a stochastic effect; "
                         "allowed: a StochasticEffect of the catalogue")
    r = np.asarray(r, dtype=float)
    diff = _judged_on_differences(known)
    w, i = periodogram(np.diff(r) if diff else r)
    c = np.cos(w)  # once: every likelihood evaluation of the fits reads it
    known_comps, th_k = _known_coords(known, dt_s)
    null = _null(known_comps, th_k, c, i, diff)
    th_k = np.asarray(null.x, float)[1:]  # the known components as the null fits them
    comps = (effect, *known_comps)
    v = float(np.mean(i)) / (2.0 if diff else 1.0)
    n_c = effect.n_coords
    if start is not None:
        starts = [np.r_[np.asarray(start, float)[:1 + n_c], th_k]]
    else:
        starts = [np.r_[s, th_k] for s in effect.whittle_starts(v)]
    best = minimize(comps, starts, c, i, diff)
    th = best.x
    lr = max(0.0, 2.0 * (float(null.fun) - best.fun))
    p = max(float(stats.chi2.sf(lr, n_c)), P_FLOOR)
    cov = inv_hessian(lambda x: nll(x, comps, c, i, diff), th)
    white_sd = float(np.sqrt(np.exp(th[0])))
    own = slice(1, 1 + n_c)
    est = effect.estimate(r, th[own], cov[own, own], dt_s, alone=not known, bootstrap=bootstrap)
    # the predictor's states at the fitted values, kept inside the fit range on the residual (a
    # correlation time the record cannot bound may come out beyond it)
    bounds = fit_bounds(effect, r, dt_s)
    states = effect.state_space({q.name: float(np.clip(est.params[q.name], q.low, q.high)) for q in bounds},
                                dt_s, r.size)
    return StochasticFit(effect, white_sd, est.params, est.params_std, states, lr, p, tuple(th[:1 + n_c]), bounds)


def exact_fit(r: np.ndarray, dt_s: float, effect: Effect, params: Params, white_sd: float,
              known: Processes = ()) -> tuple[Params, float, float]:
    """Exact Gaussian maximum likelihood of ``r`` under white noise plus ``effect``'s own states
    (``state_space``: what :meth:`StochasticEffect.noise` draws — for flicker the sum of
    Gauss–Markov states, not the idealised 1/f band the Whittle fit uses) and the model's
    ``known`` processes at their values, over the white level and the effect's parameters
    (Nelder–Mead in log coordinates from ``params``/``white_sd``, the start kept inside the fit
    range on ``r``, :func:`fit_bounds`): (parameters, white sd, the negative log-likelihood there)."""
    if not isinstance(effect, StochasticEffect):
        raise ValueError(f"effect {effect.id!r} is not a stochastic effect; allowed: a StochasticEffect")
    r = np.asarray(r, dtype=float)
    bounds = fit_bounds(effect, r, dt_s)
    names = [q.name for q in bounds]
    x0 = np.r_[np.log(max(float(white_sd), 1e-300)),
               [np.log(max(float(np.clip(params[q.name], q.low, q.high)), 1e-300)) for q in bounds]]
    rate = 1.0 / float(dt_s)
    others = list(known)

    def nll_at(x: np.ndarray) -> float:
        p = {k: float(np.exp(v)) for k, v in zip(names, x[1:])}
        if not all(np.isfinite(v) and v > 0 for v in p.values()) or not np.isfinite(x[0]):
            return math.inf
        try:  # a search far out of the ranges: a flicker band of no width, or of infinite states
            return whiten.exact_nll(r, rate, float(np.exp(2 * x[0])), [(effect, p), *others])
        except (ValueError, OverflowError):
            return math.inf
    res = optimize.minimize(nll_at, x0, method="Nelder-Mead",
                            options={"xatol": 1e-4, "fatol": 1e-3, "maxiter": 200 * (1 + len(names))})
    # the start is a vertex of the simplex: res.fun is never above nll_at(x0)
    return {k: float(np.exp(v)) for k, v in zip(names, res.x[1:])}, float(np.exp(res.x[0])), float(res.fun)


def exact_white(r: np.ndarray, dt_s: float, known: Processes, white_sd: float) -> float:
    """The white level at the exact maximum likelihood of ``r`` with the ``known`` processes at
    their values (a bounded scalar search on its log, a decade either side of ``white_sd`` and
    down to a thousandth of the sd of ``r``)."""
    r = np.asarray(r, dtype=float)
    rate = 1.0 / float(dt_s)
    sd = float(np.nanstd(r)) or 1e-300
    lo = math.log(max(min(float(white_sd) / 10, sd * 1e-3), 1e-300))
    hi = math.log(max(float(white_sd) * 10, sd))

    def nll_at(lw: float) -> float:
        try:
            return whiten.exact_nll(r, rate, math.exp(2 * lw), list(known))
        except (ValueError, OverflowError):
            return math.inf
    res = optimize.minimize_scalar(nll_at, bounds=(lo, hi), method="bounded", options={"xatol": 1e-4})
    return float(math.exp(res.x))


def one_step_prediction(r: np.ndarray, fit: StochasticFit) -> np.ndarray:
    """Kalman one-step prediction of ``r`` from its past: the fitted process's states
    (:class:`~bench.discovery.effects_noise.StateBlock`, any number, diagonal or not) plus white
    noise of the fitted level."""
    return whiten.one_step_prediction(r, fit.states, fit.white_sd)


def heldout_score(r: np.ndarray, dt_s: float, effect: Effect, folds: np.ndarray,
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
        fit = fit_stochastic(train / np.sqrt(frac), dt_s, effect, start, bootstrap=False)
        rc = r - r[~te].mean()
        pred = one_step_prediction(rc, fit)
        err_c[te] = (rc - pred)[te] ** 2
        err_b[te] = rc[te] ** 2
    score = 1.0 - err_c.sum() / err_b.sum() if err_b.sum() > 0 else 0.0
    return float(score), err_c, err_b
