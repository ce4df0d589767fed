"""The one criterion of discovery: a penalised exact likelihood, its penalty derived from a
stated false-name rate.

For a model M (base + effects) on a record, the **criterion** is

    D(M) = −2 ln L(M) + Σ_{e ∈ M} pen(e)

* ``−2 ln L`` is the exact Gaussian likelihood (Kalman filter, :func:`.whiten.exact_nll`) of
  the residual ``y − predict`` — the deterministic effects' parameters by least squares
  (:func:`.calibration.calibrate`), the white level and every random process's parameters at
  their exact maximum (:func:`.stochastic.exact_fit`) — with the samples the observation
  model sets aside left out as missing (a clip's flat stretches, isolated outliers:
  :mod:`.contamination`). A histogram-judged effect (a quantizer: the readings on a lattice,
  which a Gaussian density cannot weigh) enters with the deviance its own lattice test is
  worth, ``χ²_k.isf(p)`` — the same scale.
* ``pen(e) = χ²_k.isf(α / (C · M_e))``: ``k`` the effect's free parameters, ``C`` the
  candidates an add move tries, ``M_e`` the positions its fit searched
  (:meth:`~.effects_base.Effect.search_cells`: a jump's time among the n samples, a line's
  frequency among the n/2 Fourier bins; 1 otherwise). An effect absent from the record raises
  −2 ln L by a χ²_k variable (more for a searched location: the largest of ``M_e``), so by the
  union bound over the ``C`` candidates an add move names something false with probability
  ≤ ``α`` — the **false-name rate** — on a record that holds nothing.
* An effect made of parts the search could have added one at a time (a sinusoid's lines:
  :meth:`~.effects_base.Effect.components`) is charged per part, each ``pen`` of that part
  alone: a second line costs what a line added by itself costs (``k = 3``, ``M = n/2``), so
  beside a true line a false one is named with probability ≤ ``α / C``, as any addition.

Every move of the search (:mod:`.search`) — add, drop, swap — is taken when, and only when, it
lowers D. Two models whose D differ by Δ have relative weight ``exp(−Δ/2)`` (the likelihood
ratio with each model's penalty); a look-alike whose weight is at least ``α`` of the best's
(Δ < 2 ln(1/α)) is within the criterion's noise and is reported as a tie, not forced.
"""

from __future__ import annotations

import math

from scipy.stats import chi2

from bench.discovery.data import Record
from bench.discovery.effects_base import Effect, Params

#: The default false-name rate α: the probability that discovery names an effect on a record
#: that holds none (a 5 % test, the field's default).
FALSE_NAME_RATE = 0.05

#: Smallest tail probability the penalty is computed at (scipy's χ² isf is exact down to it).
P_MIN = 1e-300


def n_free(effect: Effect, params: Params, rec: Record, kind: str) -> int:
    """The parameters a fit of ``effect`` at ``params`` moves on ``rec`` (a jump's unused
    slots are not parameters)."""
    return len(effect.free_params(params, kind, rec))


def penalty(effect: Effect, params: Params, rec: Record, kind: str, n_candidates: int,
            alpha: float = FALSE_NAME_RATE) -> float:
    """``Σ χ²_k.isf(α / (C · M_e))`` over the effect's parts (one part but for a sinusoid's
    lines) — the deviance ``effect`` must save to be named (module docstring). ValueError for
    ``alpha`` outside (0, 1) or no candidate."""
    if not 0 < alpha < 1:
        raise ValueError(f"alpha = {alpha!r}; allowed: (0, 1)")
    if n_candidates < 1:
        raise ValueError(f"n_candidates = {n_candidates!r}; allowed: ≥ 1")
    total = 0.0
    for part in effect.components(params):
        k = max(n_free(effect, part, rec, kind), 1)
        cells = max(float(effect.search_cells(part, rec)), 1.0)
        # in logs: a few jumps on a long record search n^count positions
        log_p = math.log(alpha) - math.log(n_candidates) - math.log(cells)
        total += float(chi2.isf(max(math.exp(log_p), P_MIN), k))
    return total


def equivalent_deviance(p_value: float, k: int) -> float:
    """The deviance a test's p-value is worth on ``k`` degrees of freedom, ``χ²_k.isf(p)``: how
    a histogram-judged effect's own lattice test enters the criterion."""
    return float(chi2.isf(min(max(p_value, P_MIN), 1.0), max(k, 1)))


def relative_weight(delta: float) -> float:
    """Weight of a model whose criterion is ``delta`` above the best's, relative to the best's:
    ``exp(−delta/2)``."""
    return math.exp(-0.5 * max(delta, 0.0))


def tie_band(alpha: float = FALSE_NAME_RATE) -> float:
    """Criterion difference below which two models are a tie: relative weight ≥ ``alpha``,
    Δ < 2 ln(1/α) (5.99 at α = 0.05)."""
    return 2.0 * math.log(1.0 / alpha)
