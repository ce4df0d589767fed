"""Is an effect's own signature borne out by the record? (issue 15)

A name is a claim about a shape. A catch-all — a random process or a drift, which can absorb
any slow structure — is named only when its signature holds across the band where it claims
to act, not because its likelihood beats the base model's; and any effect whose shape leaves
structure where it acts (the harmonics of a square wave after a sinusoid, the curvature of a
tanh after K3) is not named either: that structure is reported as unexplained instead.

* :func:`process_evidence` — a random process, on the standardized Kalman innovations of the
  residual under the model with it (:func:`bench.discovery.whiten.innovations`), which are white
  when the process is right:

  - *band*: where the process's spectrum exceeds the white floor, the innovations' periodogram
    in log-spaced bins (at least :data:`BIN_MIN` ordinates each) against its overall level, a
    χ² over the bins — excess or deficit: a 1/f process fitted as a 1/f² walk leaves a slope;
  - *time*: segment means and mean squares, the CUSUM and single outlying innovations
    (:func:`bench.discovery.localize.time_segments`, :func:`~bench.discovery.localize.jumps`):
    a jump taken up by a walk leaves a run of one-signed innovations after it;
  - *inputs*: correlation of the innovations with each logged column passed through the same
    filter (:func:`~bench.discovery.localize.input_correlations`): a wander that follows a
    logged quantity is not random.

  The innovations are taken after refitting, under the process, the directions the model's
  calibration fitted by least squares (each named waveform, :func:`fitted_directions`:
  their whitened columns projected out — generalised least squares): beside a strong process
  those least-squares values are off, and their error follows their own columns (a K2's
  input²) — an error of the joint fit, not a departure from the process.

  The three families share ``alpha`` (Bonferroni).
* :func:`shape_evidence` — a waveform with a ``relaxed_basis``: the held-out score of those
  freer columns on the residual of the model with the effect, its p-value against the model's
  own noise (white at the floor, plus its random processes — naming the effect claims the rest
  *is* that noise; a bootstrap of the residual would keep whatever the shape leaves and call it
  typical), and a size gate (the columns' fit at least ``MIN_SNR`` against the floor). It fails
  when all three say so.

An :class:`Evidence` records which effect, whether its signature holds, and where it does not.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import stats

from bench.discovery import significance as sig
from bench.discovery import stochastic as sto
from bench.discovery.data import Record
from bench.discovery.effects_base import MIN_SNR
from bench.discovery.effects_linalg import base_regressors, orthonormal, project_out
from bench.discovery.effects_noise import StochasticEffect
from bench.discovery.localize import innovations_profile, input_correlations, jumps, time_segments
from bench.discovery.mapping import MapFn
from bench.discovery.model import Model
from bench.discovery.whiten import block_psd, innovations

#: Least periodogram ordinates in a band bin of the spectral-shape test.
BIN_MIN = 8
#: Most bins of the spectral-shape test.
MAX_BINS = 8
#: Default level of an evidence test (per named effect).
ALPHA = 0.01


@dataclass(frozen=True)
class Evidence:
    """Whether ``effect_id``'s own signature holds on the record; ``where``: what departs."""

    effect_id: str
    holds: bool
    p_value: float
    where: tuple[str, ...] = ()
    #: logged columns the innovations still follow (a random process's evidence)
    columns: tuple[str, ...] = ()

    def describe(self) -> str:
        if self.holds:
            return f"{self.effect_id}: its signature holds (p = {self.p_value:.2g})"
        return f"{self.effect_id}: its signature does not hold (p = {self.p_value:.2g}): " + "; ".join(self.where)

    def to_dict(self) -> dict:
        return {"id": self.effect_id, "holds": self.holds, "p_value": self.p_value, "where": list(self.where),
                "columns": list(self.columns)}


def band_shape(x: np.ndarray, in_band: np.ndarray) -> tuple[float, str]:
    """(p, description) of the χ² test that the periodogram of the standardized innovations
    ``x`` is flat over the Fourier frequencies ``in_band`` (mask over j = 1 … n/2 − 1), against
    its level over all of them; the bins are log-spaced with at least :data:`BIN_MIN` ordinates."""
    n = x.size
    spec = np.abs(np.fft.rfft(x - x.mean())) ** 2 / n
    ords = spec[1:(n - 1) // 2 + 1]
    level = float(np.mean(ords)) or 1.0
    j = np.flatnonzero(in_band[:ords.size])
    if j.size < BIN_MIN:
        return 1.0, ""
    n_bins = int(min(MAX_BINS, j.size // BIN_MIN))
    edges = np.unique(np.geomspace(j[0] + 1, j[-1] + 2, n_bins + 1).astype(int)) - 1
    chi2, dof, worst = 0.0, 0, (0.0, 0, 0, 1.0)
    start = 0
    for b in range(1, edges.size):
        sel = j[(j >= edges[start]) & (j < edges[b])]
        if sel.size < BIN_MIN and b < edges.size - 1:
            continue
        start = b
        if sel.size == 0:
            continue
        ratio = float(np.mean(ords[sel])) / level
        z2 = (ratio - 1.0) ** 2 * sel.size
        chi2 += z2
        dof += 1
        if z2 > worst[0]:
            worst = (z2, int(sel[0]) + 1, int(sel[-1]) + 1, ratio)
    if dof == 0:
        return 1.0, ""
    p = float(stats.chi2.sf(chi2, dof))
    return p, (f"innovations' spectrum over Fourier bins {worst[1]}–{worst[2]} at {worst[3]:.2f}× their level "
               f"(χ² {chi2:.1f} on {dof} bins)")


def fitted_directions(model: Model, rec: Record) -> np.ndarray:
    """Columns of the named waveforms the model's calibration fitted by least squares: each
    waveform effect's contribution (its prediction with it less without it); (n, 0) without
    one. Not the base's bias: under a walk a constant's whitened column is the record's first
    samples — refitting it would take out what a missing warm-up leaves in the innovations, the
    evidence against the process. (The base's input column is refitted, by
    :func:`process_evidence`: an effect linear in the input is the scale factor itself.)"""
    cols = [np.zeros((rec.n, 0))]
    full = model.predict(rec)
    for i, (e, _) in enumerate(model.entries()):
        if e.waveform and not e.stochastic:
            c = full - Model(model.base, model.effects[:i] + model.effects[i + 1:]).predict(rec)
            if np.any(c != 0):
                cols.append(c[:, None])
    return np.column_stack(cols)


def process_evidence(model: Model, rec: Record, index: int, residual: np.ndarray, *,
                     alpha: float = ALPHA) -> Evidence:
    """Does random process ``model.effects[index]`` hold on ``residual`` (= rec.y −
    model.predict(rec))? See the module docstring (band, time, inputs; Bonferroni at alpha).
    Where the model's output stage clips (``Model.noise_seen`` False) the residual holds no
    noise: those samples are missing to the Kalman filter and the tests read the others."""
    eff, p = model.entries()[index]
    if not isinstance(eff, StochasticEffect):
        raise ValueError(f"effect {eff.id!r} is not a random process; allowed: a StochasticEffect of the model")
    part = model.partly_seen(rec)
    sub = rec if part is None else rec.slice(part)
    r = np.asarray(residual, float)
    r = r - float(np.mean(r if part is None else r[part]))
    rate = rec.rate_hz
    procs = model.stochastic_effects()
    white = sig.white_floor(r if part is None else r[part], rate, procs)[0]
    if not white > 0:
        white = float(model.base.noise_sd) or float(np.std(r)) or 1.0
    if eff.nonstationary or part is not None:
        # a walk is judged at its exact-likelihood level on this residual: the Whittle estimate
        # of a finite walk's levels leans high (end-point leakage: 3.9e-4 °/s/√s for 2.2e-4 on a
        # 300-s gyro record), and the innovations then fall short of their level at the lowest
        # frequencies — a misfit of the estimate, not of the shape; so is any process beside a
        # clip (the Whittle fit reads the clipped stretches' flat residual as the process's:
        # a GM of 3.7e-6 / 58 s, 43 % clipped, came out 3.2e-6 / 17 s, exact 4.3e-6 / 68 s)
        others = [(e, q) for e, q in procs if e is not eff]
        ml, white, _ = sto.exact_fit(r if part is None else np.where(part, r, np.nan), rec.dt_s, eff, p, white,
                                     others)
        p = {k: float(np.clip(v, q.low, q.high)) for (k, v), q in zip(ml.items(), eff.params)}
        procs = [(eff, p), *others]

    def through_filter(v: np.ndarray) -> np.ndarray:
        """Innovations of a full-length ``v`` (mean removed over the seen samples), seen samples."""
        if part is None:
            return innovations(v - v.mean(), rate, white, procs)
        return innovations(v - v[part].mean(), rate, white, procs, seen=part)[part]

    x = through_filter(r)
    # the named waveforms' directions refitted under the process (GLS, by
    # projecting their whitened columns out): calibrated by least squares as if the noise were
    # white, under a strong process their values are off by colour that follows their own
    # columns (a K2's input²) — the joint model's error, not a departure from the process
    directions = fitted_directions(model, rec)
    if rec.varies("input"):
        # the scale factor too: calibrated by least squares beside a strong process its error
        # follows the input (a walk set aside for "correlation with input: +5σ" beside a coarse
        # quantizer); an effect linear in the input is a scale factor, the catalogue's others
        # are not (input², |input|, input·temp), so nothing is lost
        directions = np.column_stack([directions, rec.column("input")])
    if directions.shape[1]:
        x = project_out(x, np.column_stack([through_filter(c) for c in directions.T]))
    a = alpha / 3.0
    where: list[str] = []
    ps: list[float] = []
    # band: where its own spectrum exceeds the white floor
    w = 2 * np.pi * np.arange(1, (x.size - 1) // 2 + 1) / x.size
    own = block_psd(eff.state_space(p, rec.dt_s, rec.n), w)
    p_band, what = band_shape(x, own > white ** 2)
    ps.append(p_band)
    if p_band < a:
        where.append(what)
    # time: segments, CUSUM, single innovations (Bonferroni over the three inside)
    moments = innovations_profile(model, rec, white, procs, seen=part, residual=r)
    sd, dof = sig.white_floor(x, rate, sample_var=None if moments is None else moments[0])
    segs, cusum_p = time_segments(x, sub.t_s, sd, 16, a / 3, floor_dof=dof, sample_moments=moments)
    jmp = jumps(x, sub.t_s, sd, a / 3, floor_dof=dof, sample_moments=moments)
    ps.append(min(1.0, 3 * cusum_p))
    if segs or jmp or cusum_p < a / 3:
        where += [s.describe() for s in segs[:2]] + [j.describe() for j in jmp[:2]]
        if cusum_p < a / 3:
            where.append(f"the innovations' cumulative sum departs (CUSUM p = {cusum_p:.2g})")
        ps.append(0.0)

    def sub_filter(v: np.ndarray) -> np.ndarray:
        """:func:`through_filter` of a column of the seen samples' record."""
        if part is None:
            return through_filter(v)
        full = np.zeros(rec.n)
        full[part] = v
        return through_filter(full)
    corr = input_correlations(x, sub, a, transform=sub_filter)
    if corr:
        where += [c.describe() for c in corr]
        ps.append(0.0)
    p_all = float(min(1.0, 3 * min(ps))) if ps else 1.0
    return Evidence(eff.id, not where, p_all, tuple(f"in the innovations under {eff.id}: " + s for s in where),
                    tuple(sorted({c.column for c in corr})))


def _projection_p(q: np.ndarray, observed: float, draw: Callable[[int], np.ndarray], n_rep: int) -> float:
    """Monte-Carlo p of ``observed`` = ‖qᵀr‖² against ``draw(m)``'s columns
    (:func:`significance.sequential_p_value`: the same early stops as the bootstrap)."""
    def null_scores(m: int) -> np.ndarray:
        return np.sum(np.einsum("ik,im->km", q, draw(m)) ** 2, axis=0)
    return sig.sequential_p_value(observed, null_scores, n_rep=n_rep)


def shape_evidence(model: Model, rec: Record, index: int, residual: np.ndarray, *, alpha: float = ALPHA,
                   rng: np.random.Generator, n_rep: int = 999, fill_map: MapFn = map) -> Evidence:
    """Does waveform ``model.effects[index]`` keep its shape on ``residual`` (= rec.y −
    model.predict(rec))? The variance its ``relaxed_basis`` explains in the residual (in-sample:
    a held-out score cannot see a transient inside one block) against the same on the model's
    own noise, with a size gate (module docstring); an effect without a relaxed basis holds."""
    eff, p = model.entries()[index]
    relaxed = eff.relaxed_basis(p, rec)
    if relaxed is None:
        return Evidence(eff.id, True, 1.0)
    cols, what = relaxed
    r = np.asarray(residual, float)
    x_nuis = base_regressors(rec)
    cols = np.column_stack([project_out(c, x_nuis) for c in np.asarray(cols, float).reshape(rec.n, -1).T])
    q = orthonormal(cols)
    if q.shape[1] == 0:
        return Evidence(eff.id, True, 1.0)
    coef = q.T @ r
    observed = float(coef @ coef)
    fitted = q @ coef
    floor = float(sig.white_floor(r - fitted, rec.rate_hz, model.stochastic_effects())[0]) or float(np.std(r))
    size = math.sqrt(observed) / floor if floor > 0 else math.inf
    if size < MIN_SNR:
        return Evidence(eff.id, True, 1.0)
    # the null is the model's own noise (white at the floor measured beside the relaxed columns,
    # plus its random processes): naming an effect claims that, with it in the model, the rest
    # is that noise. A bootstrap of the residual would keep whatever the effect's shape leaves
    # (the other two bursts of three, the wander beside a drift) and call it typical.
    procs = model.stochastic_effects()
    noisy = model.with_base(noise_sd=min(floor, float(model.base.noise_sd)) if procs else floor)

    def draw(m: int) -> np.ndarray:  # the model's own noise: white + its random processes
        return noisy.simulate_noise_many(rec, rng, m, fill_map=fill_map)
    p_val = _projection_p(q, observed, draw, n_rep)
    if p_val >= alpha:
        return Evidence(eff.id, True, p_val)
    return Evidence(eff.id, False, p_val,
                    (f"{what} still explain the residual beside {eff.id} ({size:.0f}× the floor, p = {p_val:.2g})",))


#: Circular shifts of the rotation test (the shortest a twentieth of the record).
N_ROTATIONS = 199


def beyond_leftover(model: Model, rec: Record, index: int, residual: np.ndarray, *, alpha: float = ALPHA) -> Evidence:
    """Is waveform ``model.effects[index]`` significant beyond the structure the model leaves
    unexplained? Its contribution (the model's prediction with it less without it: one fixed
    column, base regressors projected out) is projected on the residual plus itself, against the
    same after circular shifts of that series by a twentieth of the record or more (a rotation
    test: the leftover keeps its whole shape — spectrum, where in time its parts are — and loses
    its alignment with the effect). A large unexplained structure (a chirp, a stepped supply)
    correlates with some catalogue regressor by chance; against white noise that is significant,
    against its own rotations it is not."""
    eff, _ = model.entries()[index]
    without = Model(model.base, model.effects[:index] + model.effects[index + 1:])
    x_nuis = base_regressors(rec)
    c = project_out(model.predict(rec) - without.predict(rec), x_nuis)
    norm = math.sqrt(float(c @ c))
    if norm == 0:
        return Evidence(eff.id, False, 1.0, (f"{eff.id} contributes nothing on this record",))
    c = c / norm
    z = project_out(np.asarray(residual, float), x_nuis) + c * norm
    observed = float(c @ z) ** 2
    n = rec.n
    shifts = np.unique(np.linspace(n // 20, n - n // 20, N_ROTATIONS).astype(int))
    null = np.array([float(c @ np.roll(z, int(k))) ** 2 for k in shifts])
    p_val = float((1 + np.sum(null >= observed)) / (1 + null.size))
    if p_val < alpha:
        return Evidence(eff.id, True, p_val)
    return Evidence(eff.id, False, p_val,
                    (f"{eff.id} is no more than the unexplained structure gives by chance (its projection is "
                     f"reached by {int(np.sum(null >= observed))} of {null.size} circular shifts of the data)",))


def evidence(model: Model, rec: Record, index: int, residual: np.ndarray, *, alpha: float = ALPHA,
             rng: np.random.Generator, n_rep: int = 999, fill_map: MapFn = map) -> Evidence:
    """The evidence for ``model.effects[index]`` as its family asks: a random process on its
    innovations, a waveform on its relaxed shape (:func:`process_evidence`, :func:`shape_evidence`;
    ``fill_map`` fills the latter's noise realisations, :meth:`.Model.simulate_noise_many`)."""
    eff = model.entries()[index][0]
    if isinstance(eff, StochasticEffect):
        return process_evidence(model, rec, index, residual, alpha=alpha)
    return shape_evidence(model, rec, index, residual, alpha=alpha, rng=rng, n_rep=n_rep, fill_map=fill_map)

