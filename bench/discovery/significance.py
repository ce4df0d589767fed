"""Held-out block scores, an autocorrelation-keeping null, false-discovery control and gap figures.

Pure numpy/scipy; residuals in the sensor unit, rates in Hz, τ in s.

Held-out scoring (never shuffled samples): the record is cut into ``n_blocks`` (48)
contiguous blocks — short enough that a start-up transient spans several of them; fold 0 holds
out the even blocks, fold 1 the odd ones (interleaved, so both folds see the start-up and the
end of the record). The first block is cut again into spans of 2, 2, 4, 8, 16 … samples,
alternately labelled (:func:`block_folds`): a power-on transient of a few samples (a warm-up of
τ = 5 s in a 3000-s record lives in the first of 48 blocks) is then seen by both folds' training
rows at every time scale, instead of by one fold only — whose held-out blocks never see it.
A candidate is fitted on a fold's training blocks and scored on its held-out blocks; the score
is the out-of-sample variance reduction ``1 − Σ SSE_test(candidate) / Σ SSE_test(nuisance only)``
over both folds (every sample held out once). Under "no effect" it is ≤ 0 on average: an
over-fitted shape does not carry over.

Null (documented choice): a **circular moving-block bootstrap of the residual** — blocks of
``block_len`` (n/32) consecutive samples drawn with replacement from the residual wrapped on a circle.
It keeps the residual's autocorrelation up to ``block_len`` lags (coloured noise stays
coloured) while destroying alignment with time and with every logged input. Each null replicate
is scored with the candidate's *linearised* regressors (Jacobian columns of the prediction at
each fold's training fit, fixed), the amplitude refitted on the replicate's training blocks and
scored on its held-out blocks exactly like the data — cheap enough for ~10³ replicates per
candidate. Because the columns were chosen on training blocks only, the observed held-out
linear score and the null's are computed the same way. When the model already has stochastic
effects, the null replicates are simulations of the model's own noise instead (parametric
bootstrap), whose autocorrelation the model states.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import optimize, signal, stats

from bench.analysis.allan import overlapping_adev
from bench.analysis.timeseries import default_lb_lags, ljung_box
from bench.discovery.effects_noise import Processes
from bench.discovery.whiten import noise_psd

N_BLOCKS = 48
#: Smallest p-value reported: a χ² or Rayleigh tail below it underflows to 0.0 in floating point;
#: "p < 1e-300" is what such a value means.
P_FLOOR = 1e-300
#: the bootstrap keeps autocorrelation up to n / BOOT_BLOCKS lags
BOOT_BLOCKS = 32


def block_folds(n: int, n_blocks: int = N_BLOCKS) -> np.ndarray:
    """Fold label (0 or 1) of each of ``n`` samples: contiguous blocks (:func:`block_edges`),
    alternately labelled, the first cut again geometrically (module docstring)."""
    labels = np.empty(n, dtype=int)
    edges = block_edges(n, n_blocks)
    for b, (lo, hi) in enumerate(zip(edges[:-1], edges[1:])):
        labels[lo:hi] = b % 2
    # the first block in spans of 2, 2, 4, 8 … samples, alternately labelled (module docstring)
    lo, span, k = 0, 2, 0
    while lo < edges[1]:
        hi = min(lo + span, int(edges[1]))
        labels[lo:hi] = k % 2
        lo, k = hi, k + 1
        span = 2 if k == 1 else 2 * span
    return labels


def block_edges(n: int, n_blocks: int = N_BLOCKS) -> np.ndarray:
    """Edges of the ``n_blocks`` contiguous blocks of :func:`block_folds` (fewer on a short
    record: two samples a block at least) — the units of the block jackknife."""
    if n < 2 * n_blocks:
        n_blocks = max(2, n // 2)
    if n_blocks < 2:
        raise ValueError(f"n_blocks = {n_blocks}; allowed: >= 2")
    return np.linspace(0, n, n_blocks + 1).astype(int)


RCOND = 1e-8


def _unit_columns(x: np.ndarray) -> np.ndarray:
    norm = np.linalg.norm(x, axis=0)
    return x / np.where(norm > 0, norm, 1.0)


class LinearScorer:
    """Held-out variance reduction of ``[x_nuis, x_cand[k]]`` over ``x_nuis`` alone, for many
    residuals at once.

    ``x_nuis``: (n, p) nuisance columns; ``x_cand[k]``: (n, q) the candidate's columns for
    fold k (fitted on fold k's training rows); ``folds``: fold label per sample.

    Everything a score needs is a handful of inner products of the residual with fixed columns:
    with β = P·r_train (P the training rows' pseudo-inverse), the held-out error is
    ‖r_te‖² − 2βᵀ(X_teᵀ r_te) + βᵀ(X_teᵀX_te)β. So one (n, m)ᵀ·(n, B) product (m ≈ 4(p+q)
    columns: P rows on the training samples, X columns on the held-out ones) and the per-fold
    sums of r² give all B scores — no (B, n) gathers or fitted curves (the old implementation
    built those per fold and per model). Where the fit leaves under 1e-6 of ‖r_te‖² the
    expansion would lose digits to cancellation, and that replicate is scored directly."""

    def __init__(self, x_nuis: np.ndarray, x_cand: list[np.ndarray], folds: np.ndarray):
        folds = np.asarray(folds)
        n = folds.size
        self.parts = []
        blocks = []
        col = 0
        for k in (0, 1):
            te = folds == k
            tr = ~te
            x = _unit_columns(np.hstack([x_nuis, x_cand[k]]))
            xb = _unit_columns(x_nuis)
            # near-collinear columns (an effect's change and its derivative) must not turn into
            # huge opposite coefficients: singular values below 1e-8 of the largest are dropped
            fits = []
            for xm in (x, xb):
                pinv = np.linalg.pinv(xm[tr], rcond=RCOND)
                q = xm.shape[1]
                w = np.zeros((n, 2 * q))
                w[tr, :q] = pinv.T  # β = wᵀ r
                w[te, q:] = xm[te]  # X_teᵀ r
                blocks.append(w)
                fits.append((slice(col, col + q), slice(col + q, col + 2 * q), xm[te].T @ xm[te], pinv, xm))
                col += 2 * q
            self.parts.append((tr, te, fits))
        self.w = np.hstack(blocks)
        # runs of equal fold label: ‖r_te‖² as per-run dot products, without a squared copy
        cut = np.flatnonzero(np.diff(folds)) + 1
        self.runs = [(int(a), int(b), int(folds[a])) for a, b in zip(np.r_[0, cut], np.r_[cut, n])]

    def scores(self, r: np.ndarray) -> np.ndarray:
        """(B,) scores of ``r`` (n,) or (n, B)."""
        rt = r[None, :] if r.ndim == 1 else r.T  # (B, n): rows contiguous for BLAS
        if rt.strides[1] != rt.itemsize:
            rt = np.ascontiguousarray(rt)
        proj = (rt @ self.w).T  # (m, B)
        ss = np.zeros((2, rt.shape[0]))  # ‖r_te‖² of each fold
        for a, b, k in self.runs:
            ss[k] += np.einsum("bi,bi->b", rt[:, a:b], rt[:, a:b])
        sse = np.zeros((2, rt.shape[0]))  # candidate, nuisance only
        for k, (tr, te, fits) in enumerate(self.parts):
            for j, (sb, sx, gram, pinv, xm) in enumerate(fits):
                beta, xr = proj[sb], proj[sx]
                e = ss[k] - 2 * np.sum(beta * xr, axis=0) + np.sum(beta * (gram @ beta), axis=0)
                bad = np.flatnonzero(e < 1e-6 * ss[k])
                if bad.size:  # nearly all explained: the expansion's cancellation would show
                    rb = rt[bad].T
                    e[bad] = np.sum((rb[te] - xm[te] @ (pinv @ rb[tr])) ** 2, axis=0)
                sse[j] += e
        sse_c, sse_b = sse
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(sse_b > 0, 1.0 - sse_c / sse_b, 0.0)


def heldout_linear_scores(r: np.ndarray, x_nuis: np.ndarray, x_cand: list[np.ndarray],
                          folds: np.ndarray) -> np.ndarray:
    """:class:`LinearScorer` in one call: (B,) scores of ``r`` (n,) or (n, B)."""
    return LinearScorer(x_nuis, x_cand, folds).scores(r)


def block_bootstrap(r: np.ndarray, block_len: int, n_rep: int, rng: np.random.Generator) -> np.ndarray:
    """(n, n_rep) circular moving-block bootstrap replicates of ``r``.

    Sample j of a block starting at i is r[(i + j) mod n]; the record is extended by one block
    so each block is a contiguous slice (a block copy instead of per-sample modulo indexing)."""
    n = r.size
    block_len = int(np.clip(block_len, 1, n))
    n_b = -(-n // block_len)
    starts = rng.integers(0, n, size=(n_rep, n_b))
    ext = np.concatenate([r, r[:block_len]])
    windows = np.lib.stride_tricks.sliding_window_view(ext, block_len)  # (n + 1, block_len) view
    out = windows[starts].reshape(n_rep, n_b * block_len)[:, :n]
    return out.T  # (n, n_rep) view of row-contiguous replicates: LinearScorer reads rows


def default_block_len(n: int) -> int:
    """n / BOOT_BLOCKS samples: correlation up to that lag survives the bootstrap."""
    return max(1, n // BOOT_BLOCKS)


#: Sequential early stop of a clearly significant null: after at least MIN_CHUNKS chunks with no
#: exceedance, stop when the observed score lies this many null sds above the null's mean.
CLEAR_Z = 8.0


def bootstrap_p_value(r: np.ndarray, x_nuis: np.ndarray, x_cand: list[np.ndarray], folds: np.ndarray,
                      observed: float, *, n_rep: int = 999, block_len: int | None = None,
                      rng: np.random.Generator, chunk: int = 100, stop_after: int = 10,
                      draw: Callable[[int], np.ndarray] | None = None, below: float | None = None) -> float:
    """``(1 + #{null ≥ observed}) / (n_rep + 1)`` under the circular block bootstrap of ``r``.

    Sequential both ways: replicates are drawn in chunks and drawing stops once ``stop_after``
    null scores reached the observed one, p = exceedances / replicates then (Besag & Clifford
    1991: a clearly large p costs ~100 replicates); and once no replicate of the first two chunks
    came near — the observed score more than :data:`CLEAR_Z` null sds above the null's mean —
    the remaining replicates cannot change the answer (a Gaussian tail beyond 8 sd is 6e-16 per
    replicate) and p is the full run's floor ``1/(n_rep + 1)``. ``draw(m)``: an (n, m) array of
    null residuals replacing the block bootstrap (the workflow passes the model's own noise when
    the model has stochastic effects: a random walk's memory is longer than any bootstrap block);
    ``below``: only whether p < ``below`` is asked (:func:`sequential_p_value`)."""
    block_len = default_block_len(r.size) if block_len is None else block_len
    scorer = LinearScorer(x_nuis, x_cand, folds)

    def null_scores(m: int) -> np.ndarray:
        return scorer.scores(block_bootstrap(r, block_len, m, rng) if draw is None else draw(m))
    return sequential_p_value(observed, null_scores, n_rep=n_rep, chunk=chunk, stop_after=stop_after,
                              below=below)


def sequential_p_value(observed: float, draw: Callable[[int], np.ndarray], *, n_rep: int = 999,
                       chunk: int = 100, stop_after: int = 10, below: float | None = None) -> float:
    """Monte-Carlo p ``(1 + #{null ≥ observed}) / (n_rep + 1)`` of ``observed`` against the null
    statistics ``draw(m)`` returns (m of them a call), drawn in chunks of ``chunk`` and stopped
    early both ways: once ``stop_after`` null scores reached the observed one, p = exceedances /
    replicates (Besag & Clifford 1991: a clearly large p costs ~100 replicates); once no
    replicate of the first two chunks came near — the observed score more than :data:`CLEAR_Z`
    null sds above the null's mean — p is the full run's floor ``1/(n_rep + 1)`` (a Gaussian
    tail beyond 8 sd is 6e-16 per replicate: the remaining replicates cannot change the answer).
    One loop for every Monte-Carlo test of the package (the bootstrap of a candidate's held-out
    score, the projection test of a shape's relaxed basis).

    ``below``: the caller asks only whether p < ``below`` (a decision, its p reported nowhere):
    drawing also stops once ``(1 + exceedances) / (n_rep + 1) ≥ below`` — the full run's p can
    only be larger, so the answer is already known — and that bound is returned. (A
    deterministic term judged against a flicker null at 0.05/21 stopped after 100 replicates
    instead of 700.)"""
    if below is not None and not 0 < below <= 1:
        raise ValueError(f"below = {below!r}; allowed: (0, 1]")
    exceed, done = 0, 0
    nulls: list[np.ndarray] = []
    while done < n_rep:
        m = min(chunk, n_rep - done)
        null = np.asarray(draw(m), float)
        nulls.append(null)
        exceed += int(np.sum(null >= observed))
        done += m
        if exceed >= stop_after:
            return exceed / done
        if below is not None and (1.0 + exceed) / (n_rep + 1.0) >= below:
            return (1.0 + exceed) / (n_rep + 1.0)
        if exceed == 0 and done >= 2 * chunk and done < n_rep:
            every = np.concatenate(nulls)
            sd = float(np.std(every))
            if sd > 0 and (observed - float(np.mean(every))) / sd > CLEAR_Z:
                return 1.0 / (n_rep + 1.0)
    return (1.0 + exceed) / (n_rep + 1.0)


@dataclass(frozen=True)
class Gap:
    """How far a residual is from the model's noise: rms/σ (1 = at the floor), Allan distance
    (rms of log10 ADEV ratio over τ, decades), spectral distance (rms of the Welch PSD ratio in
    dB) and the Ljung–Box whiteness p-value (20 lags)."""

    rms_ratio: float
    allan_distance: float
    spectral_distance_db: float
    whiteness_p: float

    def to_dict(self) -> dict:
        return {"rms_ratio": self.rms_ratio, "allan_distance_dec": self.allan_distance,
                "spectral_distance_db": self.spectral_distance_db, "whiteness_p": self.whiteness_p}


def welch_nperseg(n: int) -> int:
    """Welch segment length for an n-sample record, the one used by every discovery spectrum:
    the power of two nearest below n/16 (≥ 64, ≤ n) — about 31 half-overlapping segments, so each
    PSD bin has ~56 degrees of freedom while 1/16 of the record still resolves slow structure."""
    n = int(n)
    if n < 1:
        raise ValueError(f"n = {n}; allowed: >= 1")
    return min(n, max(64, 2 ** int(np.log2(max(n // 16, 64)))))


def welch_dof(n: int, nperseg: int) -> float:
    """Degrees of freedom of a Welch (Hann, 50 % overlap) PSD bin: 2 per segment, less ~10 % for
    the correlation of overlapping Hann segments."""
    k = max(1, 2 * (n - nperseg) // nperseg + 1)
    return 2.0 * k * 0.9


#: effective dof of :func:`white_floor`'s variance estimate per sample: var(σ̂²/σ²) = 2/(0.35·n)
#: on white noise (measured 0.34–0.40 for n = 300…10⁵; the low end, so tests stay conservative)
FLOOR_DOF_PER_SAMPLE = 0.35


def spread_factor(v: np.ndarray | None, length: int) -> float:
    """How much of an average's information a heteroscedastic series keeps: over blocks of
    ``length`` samples with mean variances b_k, (Σb)²/(K·Σb²) — 1 for a homoscedastic series,
    1/K when one block holds all the variance. An average of per-block statistics (Welch's
    periodograms, Allan's differences) has its equivalent dof scaled by it (Satterthwaite)."""
    if v is None:
        return 1.0
    v = np.asarray(v, float)
    k = max(1, v.size // max(1, int(length)))
    b = v[:k * (v.size // k)].reshape(k, -1).mean(axis=1)
    den = k * float(np.sum(b * b))
    return float(np.sum(b)) ** 2 / den if den > 0 else 1.0


def white_floor(x: np.ndarray, rate_hz: float, stochastic_effects: Processes = (), *,
                sample_var: np.ndarray | None = None) -> tuple[float, float]:
    """(white-noise sd, dof of its variance) from the upper half of the Welch PSD of ``x``
    (median, bias-corrected): immune to slow structure and to a few spectral lines. The dof
    ν (σ̂²/σ² ~ χ²_ν/ν on white noise) lets a test allow for the floor being estimated.

    ``stochastic_effects`` ((effect, params), ``Model.stochastic_effects()``): their PSD
    is part of the model's spectrum, so the white level is the one at which the median of
    PSD/(white + theirs) over those bins is the χ² median — a short-τ Gauss–Markov puts power
    in the upper half that a plain median would count as white.

    ``sample_var``: each sample's relative variance when ``x`` is heteroscedastic (a coarse
    quantizer's readings): Welch's segments then carry unequal levels, each bin's estimate has
    fewer dof (:func:`spread_factor`) and a more skewed law whose median sits lower — the
    bias correction and the floor's dof use that."""
    x = np.asarray(x, float)
    nperseg = welch_nperseg(x.size)
    f, p = signal.welch(x, fs=rate_hz, window="hann", nperseg=nperseg, detrend="constant")
    sel = (f >= 0.5 * f[-1]) & (np.arange(f.size) < f.size - 1) if f.size > 4 else np.ones(f.size, bool)
    upper, fu = p[sel], f[sel]
    spread = spread_factor(sample_var, nperseg)
    nu = welch_dof(x.size, nperseg) * spread
    med = stats.chi2.median(nu) / nu
    dof = max(FLOOR_DOF_PER_SAMPLE * x.size * spread, 1.0)
    plain = float(np.median(upper) / med * rate_hz / 2.0)
    effects = list(stochastic_effects)
    if not effects or plain <= 0:
        return float(np.sqrt(plain)), dof
    known = noise_psd(fu, rate_hz, effects, x.size)

    def excess(log_var):  # median ratio − χ² median: decreasing in the white variance
        return float(np.median(upper / (2.0 * np.exp(log_var) / rate_hz + known))) - med

    lo, hi = np.log(plain) - 40.0, np.log(plain) + 1.0
    if excess(lo) <= 0:  # the stochastic effects alone already reach the measured level
        return float(np.sqrt(np.exp(lo))), dof
    return float(np.sqrt(np.exp(optimize.brentq(excess, lo, hi, xtol=1e-10)))), dof


def _welch(x: np.ndarray, rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
    nperseg = welch_nperseg(x.size)
    return signal.welch(x, fs=rate_hz, window="hann", nperseg=nperseg, detrend=False)


def gap_metrics(residual: np.ndarray, noise_sd: float, rate_hz: float,
                model_noise: np.ndarray | None = None, floor_rms: float | None = None) -> Gap:
    """Gap of ``residual`` (y − deterministic prediction) to the model's noise.

    ``model_noise``: one realisation of the model's own noise (white + its stochastic effects)
    on the same grid; None → white noise of sd ``noise_sd`` (expected ADEV σ/√(τ·fs), PSD
    2σ²/fs). RMS ratio uses ``floor_rms`` when given, else the model noise's rms."""
    r = np.asarray(residual, dtype=float)
    if floor_rms is None:
        floor_rms = noise_sd if model_noise is None else float(np.sqrt(np.mean(model_noise ** 2)))
    rms_ratio = float(np.sqrt(np.mean(r ** 2)) / floor_rms)
    if r.size < 32:
        return Gap(rms_ratio, float("nan"), float("nan"), float("nan"))
    a = overlapping_adev(r, rate_hz, "octave", unit=None)
    if model_noise is None:
        exp_adev = noise_sd / np.sqrt(a.tau_s * rate_hz)
    else:
        exp_adev = overlapping_adev(model_noise, rate_hz, "octave", unit=None).adev
    allan = float(np.sqrt(np.mean(np.log10(a.adev / exp_adev) ** 2)))
    f, p = _welch(r, rate_hz)
    exp_p = (np.full_like(p, 2.0 * noise_sd ** 2 / rate_hz) if model_noise is None
             else _welch(model_noise, rate_hz)[1])
    ok = (f > 0) & (p > 0) & (exp_p > 0)
    spec = float(np.sqrt(np.mean((10 * np.log10(p[ok] / exp_p[ok])) ** 2)))
    lb = ljung_box(r - r.mean(), default_lb_lags(r.size, 0))
    return Gap(rms_ratio, allan, spec, float(lb.p_value))
