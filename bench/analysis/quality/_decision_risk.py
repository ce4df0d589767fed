"""Decision risk of a pass/fail test: false accept and false reject against the truth, and the
guard band that holds false accept to a target (ANSI/NCSL Z540.3, §5.3 b: ≤ 2 %).

For N units with true values tᵢ and measured values mᵢ of one parameter, limits [L, H] (either
may be open):

* conforming: L ≤ tᵢ ≤ H; accepted: L ≤ mᵢ ≤ H (a value not produced is rejected);
* **PFA** (Z540.3's, unconditional) = P(accepted and nonconforming), **PFR** = P(rejected and
  conforming): counts over N with Wilson intervals (``proportion``);
* the measurement error mᵢ − tᵢ is modelled as normal, its bias b and spread s estimated from
  the units themselves; then for an acceptance interval narrowed by a guard band g on each
  open side, [L + g, H − g],

      PFA(g) = 1/N Σ_{tᵢ ∉ [L, H]} P(L + g ≤ tᵢ + b + e ≤ H − g),  e ~ N(0, s²)

  averaged over the drawn true values (no assumption about the population's shape), and
  likewise PFR(g).  The guard band is the smallest g ≥ 0 with PFA(g) ≤ target (0 when the
  limits as they are already meet it), found by bisection: PFA(g) falls as g grows.

The counts are what happened; the model gives a smooth PFA(g) where the counts of a few
hundred units are mostly zero.  Both are reported.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.stats import norm

from bench.analysis.quality._proportion import Proportion, wilson_interval

Z540_TARGET = 0.02


@dataclass(frozen=True)
class DecisionRisk:
    """One parameter's decision risk: counted and modelled false accept/reject rates and the guard band.

    One parameter's decision risk over ``n`` units (see the module docstring).

    Counted rates are :class:`Proportion` of the ``n`` units with their Wilson intervals;
    model rates are fractions of ``n`` from the normal error model. Limits, bias, spread and
    guard band are in the unit of the measured values.

    Attributes
    ----------
    n : int
        Number of units.
    low : float or None
        Lower limit L (None: open).
    high : float or None
        Upper limit H (None: open).
    nonconforming : Proportion
        Units whose true value is outside the limits.
    accepted : Proportion
        Units whose measured value is inside the limits (the test's yield).
    false_accept : Proportion
        Units accepted and nonconforming (counts): Z540.3's unconditional PFA.
    false_reject : Proportion
        Units rejected and conforming (counts): the PFR.
    error_bias : float
        Mean of measured − true over the values produced.
    error_sd : float
        Its standard deviation (ddof 1; 0 with fewer than two values).
    pfa_model : float
        PFA(0) from the error model, a fraction.
    pfr_model : float
        PFR(0) from the error model, a fraction.
    guard_band : float
        Smallest g ≥ 0 with PFA(g) ≤ ``target`` (0 when the limits already meet it).
    pfa_guarded : float
        PFA(guard_band), a fraction.
    pfr_guarded : float
        PFR(guard_band), a fraction: the cost of the guard band.
    target : float
        The PFA target, a fraction (Z540.3: 0.02).
    """

    n: int
    low: float | None
    high: float | None
    nonconforming: Proportion       # true value outside the limits
    accepted: Proportion            # measured value inside the limits (the test's yield)
    false_accept: Proportion        # accepted and nonconforming (counts)
    false_reject: Proportion        # rejected and conforming (counts)
    error_bias: float               # mean of measured − true
    error_sd: float                 # its standard deviation
    pfa_model: float                # PFA(0) from the error model
    pfr_model: float                # PFR(0) from the error model
    guard_band: float               # smallest g with PFA(g) <= target (same unit as the values)
    pfa_guarded: float              # PFA(guard_band)
    pfr_guarded: float              # PFR(guard_band): the cost of the guard band
    target: float

    def to_dict(self) -> dict[str, object]:
        return {"n": self.n, "low": self.low, "high": self.high,
                "nonconforming": self.nonconforming.to_dict(), "accepted": self.accepted.to_dict(),
                "false_accept": self.false_accept.to_dict(),
                "false_reject": self.false_reject.to_dict(),
                "error_bias": self.error_bias, "error_sd": self.error_sd,
                "pfa_model": self.pfa_model, "pfr_model": self.pfr_model,
                "guard_band": self.guard_band, "pfa_guarded": self.pfa_guarded,
                "pfr_guarded": self.pfr_guarded, "target": self.target}


def inside(x: np.ndarray, low: float | None, high: float | None) -> np.ndarray:
    """``low <= x <= high`` with open sides where None; NaN is never inside.

    Parameters
    ----------
    x : ndarray
        Values, any shape, in the limits' unit.
    low : float or None
        Lower limit (inclusive); None for no lower limit.
    high : float or None
        Upper limit (inclusive); None for no upper limit.

    Returns
    -------
    ndarray of bool
        Same shape as ``x``: True where the value is finite and within the limits.

    Examples
    --------
    >>> import numpy as np
    >>> from bench.analysis.quality import inside
    >>> x = np.array([0.5, 1.5, np.nan, -1.0])
    >>> inside(x, 0.0, 1.0).tolist()
    [True, False, False, False]
    >>> inside(x, None, 1.0).tolist()  # open below
    [True, False, False, True]
    """
    ok = np.isfinite(x)
    if low is not None:
        ok &= x >= low
    if high is not None:
        ok &= x <= high
    return ok


def _p_accept(t: np.ndarray, bias: float, sd: float, low: float | None, high: float | None) -> np.ndarray:
    """P(low <= t + bias + e <= high), e ~ N(0, sd²), for each true value t."""
    centre = t + bias
    if sd == 0:
        return inside(centre, low, high).astype(float)
    upper = np.ones_like(centre) if high is None else norm.cdf((high - centre) / sd)
    lower = np.zeros_like(centre) if low is None else norm.cdf((low - centre) / sd)
    return np.clip(upper - lower, 0.0, 1.0)


def model_rates(true: np.ndarray, bias: float, sd: float, low: float | None, high: float | None,
                guard: float) -> tuple[float, float]:
    """(PFA, PFR) of the acceptance interval narrowed by ``guard`` on each closed side."""
    lo = None if low is None else low + guard
    hi = None if high is None else high - guard
    accept = _p_accept(true, bias, sd, lo, hi)
    conforming = inside(true, low, high)
    n = true.size
    return float(accept[~conforming].sum() / n), float((1 - accept[conforming]).sum() / n)


def decision_risk(measured: npt.ArrayLike, true: npt.ArrayLike, low: float | None,
                  high: float | None, *, target: float = Z540_TARGET,
                  confidence: float = 0.95) -> DecisionRisk:
    """Decision risk of judging ``measured`` against [low, high] when ``true`` holds.

    ``measured`` and ``true`` have the same length and unit; measured may hold NaN for a
    value not produced (that unit is rejected), true must be finite. PFA and PFR are counted
    and modelled with a normal measurement error, and the guard band holding PFA to
    ``target`` is found by bisection (module docstring, ANSI/NCSL Z540.3 §5.3 b).

    Parameters
    ----------
    measured : array_like, shape (N,)
        Measured value of each unit, in the parameter's unit; NaN where none was produced.
    true : array_like, shape (N,)
        True value of each unit, same unit; finite, N ≥ 2.
    low : float or None
        Lower limit L, same unit; None for an open side.
    high : float or None
        Upper limit H, same unit; None for an open side. At least one limit, and L < H.
    target : float, default 0.02
        PFA the guard band must reach, a fraction in (0, 1) (Z540.3's 2 %).
    confidence : float, default 0.95
        Confidence level of the counts' Wilson intervals, in (0, 1).

    Returns
    -------
    DecisionRisk
        Counted and modelled PFA/PFR, the error model's bias and spread, and the guard band
        (same unit as the values) with the rates it leaves.

    Raises
    ------
    ValueError
        If the arrays are not 1-D of one length ≥ 2, ``true`` is not finite, both limits are
        None, ``low`` ≥ ``high``, ``target`` is outside (0, 1), or ``confidence`` outside
        (0, 1).

    Examples
    --------
    500 units drawn N(0, 1), measured with an error N(0, 0.2²), limits ±2; a tight 0.2 %
    target needs a guard band:

    >>> import numpy as np
    >>> from bench.analysis.quality import decision_risk
    >>> rng = np.random.default_rng(0)
    >>> true = rng.normal(0.0, 1.0, 500)
    >>> measured = true + rng.normal(0.0, 0.2, true.size)
    >>> r = decision_risk(measured, true, -2.0, 2.0, target=0.002)
    >>> r.nonconforming.successes, r.false_accept.successes, r.false_reject.successes
    (21, 3, 6)
    >>> round(r.error_sd, 2), round(r.pfa_model, 4), round(r.guard_band, 3)
    (0.19, 0.0048, 0.128)
    >>> bool(r.pfa_guarded <= 0.002 and r.pfr_guarded > r.pfr_model)
    True
    """
    m, t = np.asarray(measured, dtype=float), np.asarray(true, dtype=float)
    if m.ndim != 1 or m.shape != t.shape or m.size < 2:
        raise ValueError(f"measured and true must be 1-D of one length >= 2, got {m.shape}, {t.shape}")
    if not np.all(np.isfinite(t)):
        raise ValueError("true values must be finite")
    if low is None and high is None:
        raise ValueError("a limit needs low, high or both")
    if low is not None and high is not None and not low < high:
        raise ValueError(f"low={low} must be < high={high}")
    if not 0 < target < 1:
        raise ValueError(f"target={target!r} must be in (0, 1)")
    n = m.size
    conforming, accepted = inside(t, low, high), inside(m, low, high)
    residual = (m - t)[np.isfinite(m)]
    bias = float(residual.mean()) if residual.size else 0.0
    sd = float(residual.std(ddof=1)) if residual.size > 1 else 0.0
    pfa0, pfr0 = model_rates(t, bias, sd, low, high, 0.0)
    guard = 0.0
    if pfa0 > target:
        span = (high - low) / 2 if low is not None and high is not None else \
            max(abs(bias) + 10 * sd, float(np.ptp(t)), 1e-300)
        lo_g, hi_g = 0.0, span
        for _ in range(100):  # bisection to a relative 1e-9 of the span
            mid = (lo_g + hi_g) / 2
            if model_rates(t, bias, sd, low, high, mid)[0] > target:
                lo_g = mid
            else:
                hi_g = mid
            if hi_g - lo_g < 1e-9 * span:
                break
        guard = hi_g
    pfa_g, pfr_g = model_rates(t, bias, sd, low, high, guard)
    count = (lambda mask: wilson_interval(int(mask.sum()), n, confidence))
    return DecisionRisk(n, low, high, count(~conforming), count(accepted),
                        count(accepted & ~conforming), count(~accepted & conforming), bias, sd,
                        pfa0, pfr0, guard, pfa_g, pfr_g, target)


def overall_risk(accepted: npt.ArrayLike, conforming: npt.ArrayLike,
                 undecidable: npt.ArrayLike | None = None,
                 confidence: float = 0.95) -> tuple[Proportion, Proportion]:
    """(PFA, PFR) of the whole test over all units.

    A false accept is a unit accepted (every measurement) while some scored parameter is
    nonconforming; a false reject a unit rejected while every scored parameter conforms.
    ``undecidable`` marks units rejected on a measurement that has no true value: whether
    that rejection was false cannot be told, so they are never counted as false rejects.

    Parameters
    ----------
    accepted : array_like of bool, shape (N,)
        Per unit: the test accepted it (every measurement within its limits).
    conforming : array_like of bool, shape (N,)
        Per unit: every scored parameter's true value is within its limits.
    undecidable : array_like of bool, shape (N,), optional
        Per unit: rejected on a measurement with no true value; default none.
    confidence : float, default 0.95
        Confidence level of the Wilson intervals, in (0, 1).

    Returns
    -------
    pfa : Proportion
        Units accepted and nonconforming, of N.
    pfr : Proportion
        Units rejected, conforming and not undecidable, of N.

    Raises
    ------
    ValueError
        If the three arrays are not 1-D of one length, or ``confidence`` is outside (0, 1).

    Examples
    --------
    >>> from bench.analysis.quality import overall_risk
    >>> accepted = [True, True, False, True, False]
    >>> conforming = [True, False, True, True, False]
    >>> pfa, pfr = overall_risk(accepted, conforming)
    >>> pfa.successes, pfr.successes, pfa.trials
    (1, 1, 5)
    >>> overall_risk(accepted, conforming, undecidable=[False, False, True, False, False])[1].successes
    0
    """
    a, c = np.asarray(accepted, dtype=bool), np.asarray(conforming, dtype=bool)
    u = np.zeros(a.shape, bool) if undecidable is None else np.asarray(undecidable, dtype=bool)
    if a.shape != c.shape or a.shape != u.shape or a.ndim != 1:
        raise ValueError(f"accepted, conforming and undecidable must be 1-D of one length, got "
                         f"{a.shape}, {c.shape}, {u.shape}")
    n = a.size
    return (wilson_interval(int((a & ~c).sum()), n, confidence),
            wilson_interval(int((~a & c & ~u).sum()), n, confidence))


__all__ = ["Z540_TARGET", "DecisionRisk", "decision_risk", "inside", "model_rates", "overall_risk"]
