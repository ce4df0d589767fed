"""IEEE Std 952 noise terms from an Allan deviation curve: least-squares fit and slope lines.

Allan variance model (IEEE Std 952-1997 Annex C; τ in s, coefficients in the input
rate unit ``u`` times a power of seconds)::

    σ²(τ) = 3Q²/τ² + N²/τ + (2 ln2/π)·B² + K²·τ/3 + R²·τ²/2

| term | name (gyro / accelerometer)            | ADEV slope | read on its line at |
|------|----------------------------------------|-----------:|---------------------|
| Q    | angle / velocity quantization          |   −1       | τ = √3 s            |
| N    | angle / velocity random walk           |   −1/2     | τ = 1 s             |
| B    | bias instability                       |    0       | minimum: σ_min/0.664|
| K    | rate / acceleration random walk        |   +1/2     | τ = 3 s             |
| R    | rate / acceleration ramp               |   +1       | τ = √2 s            |

**Fit.**  The model is linear in ``(Q², N², B², K², R²)``; they are found by weighted
least squares with non-negative values — exact NNLS by enumerating the 31 supports
(the optimum is the unconstrained solution on its support), columns scaled to unit
norm.  The weight of a point is ``1/(σ²_model²·(2/edf + 0.02²))``: the inverse
variance of the Allan variance estimate for chi-squared statistics (``2σ⁴/edf``) plus
a 2 % allowance for the model itself.  Without the allowance the first octaves (EDF
~10⁵) dominate, and a departure from the model there (a sensor's bandwidth roll-off,
a quantizer whose error is not white) bends every term — by a factor of several in a
test with a rounded angle record; 2 % keeps that to tens of per cent while costing
little precision on records the model does describe.  The EDF needs the noise type at
each τ, taken as the type of the fitted term that dominates there (Q → white PM α = 2,
N → white FM 0, B → flicker FM −1, K → random-walk FM −2; a rate ramp is not a
power-law noise and is given −2).  Fit, noise types and EDF are iterated to a fixed
point, starting from white FM and data-based weights.  Uncertainties are the weighted
LS covariance on the support, scaled by the reduced χ² when it exceeds 1.  Octave
points overlap in the data they use and are mildly correlated, so treat them as
indicative.  A term outside the support is reported as 0 with no uncertainty.

**Slope lines** (the graphical IEEE 952 method).  The local log-log slope of the
measured curve is taken by central differences; for each slope term the point whose
local slope is nearest the term's slope — and within ±0.25 of it, i.e. nearer than to
any other term's slope — carries a line of that slope, read at the τ of the table.  B
is the curve's minimum divided by √(2 ln2/π) ≈ 0.664.  A slope is read only where its
standard deviation from the neighbours' EDF is ≤ 0.1, and B's minimum only among
points with EDF ≥ 10, so that the last, scattered octaves set neither.
Neighbouring terms lift the curve above each line, so read-offs tend high; noise in the
curve makes the minimum (B) tend low.  The fit separates the terms.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from bench.analysis.allan._stats import edf_greenhall

TERMS = ("Q", "N", "B", "K", "R")
B_FACTOR = math.sqrt(2.0 * math.log(2.0) / math.pi)  # 0.6643: σ plateau / B
SLOPE = {"Q": -1.0, "N": -0.5, "B": 0.0, "K": 0.5, "R": 1.0}
READ_TAU_S = {"Q": math.sqrt(3.0), "N": 1.0, "K": 3.0, "R": math.sqrt(2.0)}
NOISE_ALPHA = {"Q": 2, "N": 0, "B": -1, "K": -2, "R": -2}
SLOPE_TOLERANCE = 0.25
MIN_READ_EDF = 10.0  # ADEV 1σ scatter ≈ 1/√(2·edf) ≤ 22 %
MAX_SLOPE_SD = 0.1   # a read slope must be resolved well inside the ±0.25 between terms
MODEL_FLOOR = 0.02  # relative uncertainty of σ² granted to the 5-term model itself
_MAX_ITER = 8


def white_through_lowpass(tau_s: np.ndarray, lag1: float, tau0_s: float) -> np.ndarray:
    """Allan variance per N² of white rate noise through a first-order low-pass, sampled every
    ``tau0_s``: an AR(1) record of lag-1 correlation ``φ`` whose long-τ level is ``N²/τ``.

    With ``m = τ/τ0``: ``σ²(τ)/N² = (1/τ)·[1 − φ(1 − φᵐ)(3 − φᵐ) / (m(1 + φ)(1 − φ))]``
    (the window sums of ``γ_k ∝ φ^|k|``); ``1/τ`` at φ = 0, ``(1 − φ)²/((1 + φ)·τ0)`` … at m = 1.
    """
    tau = np.asarray(tau_s, dtype=float)
    if lag1 == 0.0:
        return 1.0 / tau
    phi, m = float(lag1), tau / tau0_s
    pm = phi ** m
    return (1.0 - phi * (1.0 - pm) * (3.0 - pm) / (m * (1.0 + phi) * (1.0 - phi))) / tau


def design_matrix(tau_s: np.ndarray, terms: tuple[str, ...] = TERMS, lag1: float = 0.0,
                  tau0_s: float = 1.0) -> np.ndarray:
    """Columns ``∂σ²/∂(coef²)`` of the model for each term, rows per τ.

    ``lag1`` ≠ 0: the N column is white noise through a first-order low-pass of that lag-1
    correlation at sample interval ``tau0_s`` (:func:`white_through_lowpass`).
    """
    tau = np.asarray(tau_s, dtype=float)
    cols = {"Q": 3.0 / tau ** 2, "N": white_through_lowpass(tau, lag1, tau0_s), "B": np.full_like(tau, B_FACTOR ** 2),
            "K": tau / 3.0, "R": tau ** 2 / 2.0}
    return np.column_stack([cols[t] for t in terms])


def term_adev(name: str, value: float, tau_s: np.ndarray) -> np.ndarray:
    """ADEV of one term alone (``value`` in the input unit · s^k), for slope lines.

    The square root of that term's part of the Allan variance model (module docstring),
    e.g. ``N/√τ`` for N and ``0.664·B`` for B: the straight line a plot draws for the term.

    Parameters
    ----------
    name : {"Q", "N", "B", "K", "R"}
        The IEEE 952 term.
    value : float
        Its coefficient in the input form: the record's rate unit ``u`` times s, √s, 1,
        1/√s or 1/s for Q, N, B, K, R (``NoiseCoefficient.fit_input``).
    tau_s : array_like of float
        Averaging times τ in s, > 0.

    Returns
    -------
    ndarray of float
        ADEV of the term alone at each τ, in ``u``.

    Examples
    --------
    >>> from bench.analysis.allan import term_adev
    >>> term_adev("N", 0.01, [1.0, 4.0, 100.0]).round(6).tolist()  # N/√τ
    [0.01, 0.005, 0.001]
    >>> term_adev("B", 1.0, [1.0, 100.0]).round(4).tolist()  # flat at B·√(2 ln2/π)
    [0.6643, 0.6643]
    """
    return np.sqrt(design_matrix(np.asarray(tau_s, dtype=float), (name,))[:, 0]) * value


def _supports(n_cols: int, max_size: int) -> list[tuple[int, ...]]:
    return [sup for size in range(1, min(n_cols, max_size) + 1)
            for sup in itertools.combinations(range(n_cols), size)]


def nnls_enumerated(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, tuple[int, ...]]:
    """Non-negative least squares ``min ‖a·x − b‖, x ≥ 0`` for a few columns (≤ 6).

    Every support's unconstrained solution comes from one batched solve of the normal
    equations of the unit-norm columns (the other unknowns pinned to 0); the feasible
    one with the smallest residual, computed directly, wins (ties: the smaller support).
    Returns ``x`` and its support.
    """
    n_rows, n_cols = a.shape
    norms = np.linalg.norm(a, axis=0)
    norms[norms == 0] = 1.0
    scaled = a / norms
    gram, rhs = scaled.T @ scaled, scaled.T @ b
    supports = _supports(n_cols, n_rows)
    mask = np.zeros((len(supports), n_cols), dtype=bool)
    for i, sup in enumerate(supports):
        mask[i, list(sup)] = True
    both = mask[:, :, None] & mask[:, None, :]
    systems = np.where(both, gram, np.eye(n_cols))
    with np.errstate(all="ignore"):
        try:
            xs = np.linalg.solve(systems, np.where(mask, rhs, 0.0)[:, :, None])[:, :, 0]
        except np.linalg.LinAlgError:  # a singular support: solve one by one, skipping it
            xs = np.full(mask.shape, np.nan)
            for i in range(len(supports)):
                try:
                    xs[i] = np.linalg.solve(systems[i], np.where(mask[i], rhs, 0.0))
                except np.linalg.LinAlgError:
                    pass
    feasible = np.all(np.where(mask, xs > 0.0, True), axis=1) & np.all(np.isfinite(xs), axis=1)
    best_x, best_res = np.zeros(n_cols), float(b @ b)
    best_support: tuple[int, ...] = ()
    for i in np.flatnonzero(feasible).tolist():
        res = float(np.sum((scaled @ xs[i] - b) ** 2))
        if res < best_res * (1.0 - 1e-12):
            best_x, best_support, best_res = xs[i], supports[i], res
    return best_x / norms, best_support


@dataclass(frozen=True)
class NoiseFit:
    """Least-squares noise terms (values in the input unit · s^k) and the EDF they imply.

    Returned by :func:`fit_noise_terms`.

    Attributes
    ----------
    terms : tuple of str
        Terms the fit was allowed to use, e.g. ``("Q", "N", "B", "K", "R")``.
    values : dict of str to float
        Fitted coefficient of each term in its input form (rate unit ``u`` times s, √s, 1,
        1/√s, 1/s for Q, N, B, K, R); 0 for a term outside the non-negative support.
    stds : dict of str to float or None
        Standard error of each value, same unit; None for a term outside the support.
    alpha : ndarray of int, shape (k,)
        Power-law noise exponent used for the EDF at each τ (Q → 2, N → 0, B → −1, K, R → −2).
    edf : ndarray of float, shape (k,)
        Equivalent degrees of freedom of each Allan variance (dimensionless).
    reduced_chi2 : float or None
        Weighted residual sum of squares per degree of freedom; None with no support or
        no degree of freedom left.
    iterations : int
        Fixed-point iterations of fit, noise types and EDF (0 for a constant record).
    """

    terms: tuple[str, ...]
    values: dict[str, float]
    stds: dict[str, float | None]
    alpha: np.ndarray   # noise exponent used for the EDF at each τ
    edf: np.ndarray
    reduced_chi2: float | None
    iterations: int


def _weighted_nnls(a, avar, weight):
    sw = np.sqrt(weight)
    coef2, support = nnls_enumerated(a * sw[:, None], avar * sw)
    return coef2, support


def _weights(avar: np.ndarray, edf: np.ndarray) -> np.ndarray:
    """Inverse variance of each Allan variance: chi-squared ``2σ⁴/edf`` plus the model floor."""
    return 1.0 / (avar ** 2 * (2.0 / edf + MODEL_FLOOR ** 2))


def fit_noise_terms(tau_s: np.ndarray, avar: np.ndarray, m: np.ndarray, n_phase: int,
                    terms: tuple[str, ...] = TERMS, lag1: float = 0.0) -> NoiseFit:
    """Fit the IEEE 952 model to Allan variances ``avar`` at ``tau_s`` (module docstring).

    Weighted non-negative least squares of
    ``σ²(τ) = 3Q²/τ² + N²/τ + (2 ln2/π)·B² + K²·τ/3 + R²·τ²/2`` in the squared
    coefficients, each point weighted by ``1/(σ²_model²·(2/edf + 0.02²))``, iterated with
    the noise type (and so the EDF) each τ implies.  :func:`overlapping_adev` calls it;
    call it directly to refit a curve with other ``terms``.

    Parameters
    ----------
    tau_s : ndarray of float, shape (k,)
        Averaging times τ in s.
    avar : ndarray of float, shape (k,)
        Allan variances at ``tau_s``, in ``u²`` (``u`` the record's rate unit).
    m : ndarray of int, shape (k,)
        Averaging factors τ/τ0 of the points, each in ``[1, (n_phase − 1) // 2]``.
    n_phase : int
        Phase points of the record (rate samples + 1), for the EDF.
    terms : tuple of str, default TERMS
        Terms the model may use, in Q, N, B, K, R order.
    lag1 : float, default 0.0
        Lag-1 autocorrelation of the rate samples, in (−1, 1): when ≠ 0 the N term is white
        noise through a first-order low-pass (N its long-τ level, ``N²/τ`` for τ ≫ τ0).

    Returns
    -------
    NoiseFit
        Coefficients in the input form (``u``·s, ``u``·√s, ``u``, ``u``/√s, ``u``/s), their
        standard errors, the EDF per τ and the fit quality.

    Raises
    ------
    ValueError
        If an averaging factor is outside ``[1, (n_phase − 1) // 2]`` (from :func:`edf_greenhall`).

    Examples
    --------
    An exact model curve with N = 0.01 u·√s and K = 0.002 u/√s is recovered:

    >>> import numpy as np
    >>> from bench.analysis.allan import fit_noise_terms
    >>> m = 2 ** np.arange(13)
    >>> tau = m / 100.0  # 100 Hz
    >>> fit = fit_noise_terms(tau, 0.01**2 / tau + 0.002**2 * tau / 3, m, 20_001)
    >>> {name: round(v, 4) for name, v in fit.values.items()}
    {'Q': 0.0, 'N': 0.01, 'B': 0.0, 'K': 0.002, 'R': 0.0}
    >>> fit.alpha.tolist()  # white FM (N) at short τ, random-walk FM (K) at long τ
    [0, 0, 0, 0, 0, 0, 0, 0, 0, 0, -2, -2, -2]
    """
    tau0 = float(tau_s[0] / m[0]) if len(tau_s) else 1.0
    a = design_matrix(tau_s, terms, lag1, tau0)
    if not np.any(avar > 0):  # a constant record: nothing to fit
        zero_alpha = np.zeros(len(tau_s), dtype=int)
        return NoiseFit(terms, dict.fromkeys(terms, 0.0), dict.fromkeys(terms), zero_alpha,
                        edf_greenhall(zero_alpha, m, n_phase), None, 0)
    table: dict[int, np.ndarray] = {}

    def edf_for(alpha: np.ndarray) -> np.ndarray:  # each noise type's EDF computed once per fit
        out = np.empty(alpha.size)
        for value in np.unique(alpha).tolist():
            if value not in table:
                table[value] = edf_greenhall(value, m, n_phase)
            out[alpha == value] = table[value][alpha == value]
        return out

    scale = float(np.max(avar))
    y = avar / scale
    alpha = np.zeros(len(tau_s), dtype=int)
    edf = edf_for(alpha)
    floor = 1e-12 * float(np.max(y))
    weight = _weights(np.maximum(y, floor), edf)
    coef2 = np.zeros(len(terms))
    support: tuple[int, ...] = ()
    iterations = 0
    while iterations < _MAX_ITER:
        iterations += 1
        new_coef2, support = _weighted_nnls(a, y, weight)
        model = a @ new_coef2
        contrib = a * new_coef2
        new_alpha = (np.array([NOISE_ALPHA[terms[i]] for i in np.argmax(contrib, axis=1)])
                     if support else np.zeros(len(tau_s), dtype=int))
        converged = (np.array_equal(new_alpha, alpha)
                     and np.allclose(new_coef2, coef2, rtol=1e-6, atol=1e-12 * max(float(np.max(new_coef2)), 1e-300)))
        coef2, alpha = new_coef2, new_alpha
        edf = edf_for(alpha)
        weight = _weights(np.maximum(model, floor), edf)
        if converged:
            break
    values = {t: math.sqrt(max(c, 0.0) * scale) for t, c in zip(terms, coef2)}
    stds: dict[str, float | None] = dict.fromkeys(terms)
    reduced = None
    if support:
        sub = a[:, support]
        resid = (y - a @ coef2) * np.sqrt(weight)
        dof = len(tau_s) - len(support)
        reduced = float(resid @ resid / dof) if dof > 0 else None
        try:
            cov = np.linalg.inv(sub.T @ (sub * weight[:, None]))
        except np.linalg.LinAlgError:
            cov = None
        if cov is not None:
            inflate = max(1.0, reduced or 1.0)
            model = a @ coef2
            for k, idx in enumerate(support):
                var_c2 = max(cov[k, k] * inflate,
                             _single_point_var(a[:, idx] * coef2[idx], model, edf, float(coef2[idx])))
                var_c2 *= scale ** 2
                name = terms[idx]
                if values[name] > 0 and var_c2 >= 0:
                    stds[name] = math.sqrt(var_c2) / (2.0 * values[name])  # δ√v = δv / (2√v)
    return NoiseFit(terms, values, stds, alpha, edf, reduced, iterations)


def _single_point_var(term: np.ndarray, model: np.ndarray, edf: np.ndarray, c2: float) -> float:
    """The variance of a term's coefficient ``c2`` read from the one Allan variance that tells
    it best: a floor for the least-squares variance, which treats the octave points as
    independent — they are not (overlapping estimates at neighbouring τ share most of their
    data, strongly so where a random walk dominates), so the fit knows a term little better
    than its best single point.  From point i, with the other terms known,
    ``c² = (σ²ᵢ − others) / a_ik`` and ``var(σ²ᵢ) = 2 σ⁴ᵢ / edfᵢ``: the relative variance is
    ``2 / (edfᵢ · shareᵢ²)``, ``shareᵢ`` the term's part of the model there (points where it
    makes at least half of it)."""
    share = np.divide(term, model, out=np.zeros_like(model), where=model > 0)
    usable = share >= 0.9
    if not np.any(usable):
        return 0.0
    return c2 ** 2 * float(np.min(2.0 / (edf[usable] * share[usable] ** 2)))


@dataclass(frozen=True)
class ReadOff:
    """A slope-line reading: value (input unit · s^k) and the curve point it went through.

    Returned by :func:`read_off`.

    Attributes
    ----------
    value : float
        The term's coefficient in its input form (rate unit ``u`` times s, √s, 1, 1/√s or
        1/s for Q, N, B, K, R).
    tau_s : float
        τ in s of the curve point the line went through (B: the minimum).
    adev : float
        ADEV at that point, in ``u``.
    at_edge : bool, default False
        B only: the minimum is the first or last readable point, so the reading is only an
        upper bound.
    """

    value: float
    tau_s: float
    adev: float
    at_edge: bool = False  # B only: the minimum is the first or last readable point


def read_off(tau_s: np.ndarray, adev: np.ndarray, name: str, edf: np.ndarray | None = None) -> ReadOff | None:
    """The graphical IEEE 952 reading of one term (module docstring); None if no region fits.

    With ``edf`` given, B's minimum is sought among points with ``edf ≥ MIN_READ_EDF``
    and a slope is read only where its standard deviation (from the neighbours' EDF,
    ``var ln σ̂ ≈ 1/(2·edf)``) is at most ``MAX_SLOPE_SD``, so that it tells the terms
    apart; the last, scattered octaves would otherwise produce any slope.

    The point whose local log-log slope is nearest the term's (and within ±0.25 of it)
    carries a line of that slope, read at τ = √3, 1, 3, √2 s for Q, N, K, R; B is the
    curve's minimum divided by √(2 ln2/π) ≈ 0.664.  Neighbouring terms lift the curve
    above each line, so read-offs tend high.

    Parameters
    ----------
    tau_s : array_like of float, shape (k,)
        Averaging times τ in s, increasing.
    adev : array_like of float, shape (k,)
        Allan deviation at ``tau_s`` in the rate unit ``u``; points ≤ 0 are ignored.
    name : {"Q", "N", "B", "K", "R"}
        The term to read.
    edf : array_like of float, shape (k,), optional
        Equivalent degrees of freedom per point; None treats every point as exact.

    Returns
    -------
    ReadOff or None
        The reading in the term's input form (``u``·s, ``u``·√s, ``u``, ``u``/√s, ``u``/s), or
        None when no part of the curve has the term's slope (or fewer than 3 points for a slope).

    Examples
    --------
    >>> import numpy as np
    >>> from bench.analysis.allan import read_off
    >>> tau = 2.0 ** np.arange(13) / 100.0
    >>> adev = np.sqrt(0.01**2 / tau + 0.002**2 * tau / 3)  # N = 0.01, K = 0.002
    >>> r = read_off(tau, adev, "N")
    >>> round(r.value, 4), r.tau_s
    (0.01, 0.01)
    >>> round(read_off(tau, adev, "K").value, 5)  # true 0.002, lifted a little by N
    0.00204
    >>> read_off(tau, adev, "Q") is None  # no slope −1 anywhere
    True
    """
    tau, dev = np.asarray(tau_s, dtype=float), np.asarray(adev, dtype=float)
    ok = dev > 0
    if not np.any(ok):
        return None
    tau, dev = tau[ok], dev[ok]
    edf_ok = np.full(tau.size, np.inf) if edf is None else np.asarray(edf, dtype=float)[ok]
    if name == "B":
        idx = np.flatnonzero(edf_ok >= MIN_READ_EDF)
        idx = idx if idx.size else np.arange(tau.size)
        i = int(idx[np.argmin(dev[idx])])
        return ReadOff(float(dev[i] / B_FACTOR), float(tau[i]), float(dev[i]), i in (idx[0], idx[-1]))
    if tau.size < 3:
        return None
    log_tau, var_log = np.log(tau), 0.5 / edf_ok
    slope = np.gradient(np.log(dev), log_tau)
    lo, hi = np.maximum(np.arange(tau.size) - 1, 0), np.minimum(np.arange(tau.size) + 1, tau.size - 1)
    slope_sd = np.sqrt(var_log[lo] + var_log[hi]) / (log_tau[hi] - log_tau[lo])
    gap = np.abs(slope - SLOPE[name])
    idx = np.flatnonzero((slope_sd <= MAX_SLOPE_SD) & (gap < SLOPE_TOLERANCE))
    if idx.size == 0:
        return None
    i = int(idx[np.argmin(gap[idx])])
    value = dev[i] * (READ_TAU_S[name] / tau[i]) ** SLOPE[name]
    return ReadOff(float(value), float(tau[i]), float(dev[i]))
