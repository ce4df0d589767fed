"""Start-up trend: exponential settling plus linear drift (Document A, step 3).

Model, with ``u = t - t0`` seconds since the first sample::

    exp1:  y(u) = c + a·exp(-u/τ) + b·u
    exp2:  y(u) = c + a1·exp(-u/τ1) + a2·exp(-u/τ2) + b·u      (τ1 < τ2)

fitted by nonlinear least squares (``scipy.optimize.least_squares``, analytic Jacobian).

Starting values: a variable-projection scan — for each τ on a log grid from one sample
interval to three record lengths, ``c, a, b`` are linear and solved exactly; the τ with
the smallest residual starts the fit.  Unlike a log-linear fit of the early samples,
this needs no guess of where the transient ends or of the sign of ``a``, and copes
with noise larger than the transient's tail.  The scan runs on block means (≤ 4096
points) so it stays cheap at 10⁶ samples.

Standard errors: the residual noise of a start-up trace is coloured, so the white-noise
``s²(JᵀJ)⁻¹`` would be too small.  The residual is modelled as AR(p) (Burg, order by
BIC, p ≤ 10) and the sandwich ``(JᵀJ)⁻¹ JᵀΣJ (JᵀJ)⁻¹`` is evaluated exactly for that AR
covariance Σ, using ``JᵀΣJ = σ² GᵀG`` where ``G`` is J filtered by the inverse AR
filter run backwards in time.

Two exponentials are kept only when the data demand it: the BIC of the trend plus its
AR noise (innovation variance, all parameters counted) must fall by more than 10
("very strong" evidence) and both amplitudes must exceed three standard errors.  On
long traces (> 65 536 samples) the two-exponential fit is first done on the block means
and polished on every sample only when the block-mean likelihood ratio reaches half of
what acceptance needs (:func:`_exp2_promising`); otherwise ``bic_exp2`` is None.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy.optimize import least_squares
from scipy.signal import lfilter

import bench.analysis.timeseries._fit as ts
from bench.values import Estimate

MIN_SAMPLES = 32
BIC_MARGIN = 10.0
MAX_NOISE_ORDER = 10
_SCAN_POINTS = 4096
_FIT_POINTS = 16384


@dataclass(frozen=True, eq=False)
class TrendFit:
    """Fitted start-up trend.  Units: those of ``y``; time constants in s; slope per s.

    ``exp_*`` is the faster exponential (τ1) and ``exp2_*`` the slower one when
    ``kind == "exp2"``.  ``covariance`` is ordered as ``param_names``.

    The model, with ``u = t − t0_s``, is ``y(u) = c + a·exp(−u/τ) [+ a2·exp(−u/τ2)] + b·u``.

    Attributes
    ----------
    kind : {"exp1", "exp2"}
        One exponential, or two when the data demand it (BIC and 3σ amplitudes).
    offset : Estimate
        ``c``, in the unit of ``y``.
    exp_amplitude : Estimate
        ``a`` of the faster exponential, in the unit of ``y``.
    exp_tau_s : Estimate
        Its time constant τ (τ1), in s.
    linear_slope_per_s : Estimate
        Drift ``b``, in the unit of ``y`` per s.
    exp2_amplitude : Estimate or None
        ``a2`` of the slower exponential (unit of ``y``); None unless ``kind == "exp2"``.
    exp2_tau_s : Estimate or None
        Its time constant τ2 in s; None unless ``kind == "exp2"``.
    t0_s : float
        Time of the first sample, in s (the origin of ``u``).
    param_names : tuple of str
        Names of the fitted parameters, the order of ``covariance``.
    covariance : ndarray of float, shape (k, k)
        Sandwich covariance of the parameters under the AR model of the residual, in their units.
    noise_ar : tuple of float
        AR coefficients φ (Burg, BIC order ≤ 10) of the residual behind the standard errors.
    noise_sigma2 : float
        Innovation variance of that AR model, in (unit of ``y``)².
    bic_exp1 : float
        BIC of the one-exponential trend plus its AR noise.
    bic_exp2 : float or None
        BIC of the two-exponential fit; None when it was not attempted or failed.
    fitted : ndarray of float, shape (N,)
        Trend at the sample times (read-only), in the unit of ``y``.
    residual : ndarray of float, shape (N,)
        ``y − fitted`` (read-only).

    Raises
    ------
    ValueError
        On construction, if ``exp2_amplitude`` and ``exp2_tau_s`` are not both set for
        ``kind == "exp2"`` and both None otherwise.
    """

    kind: Literal["exp1", "exp2"]
    offset: Estimate
    exp_amplitude: Estimate
    exp_tau_s: Estimate
    linear_slope_per_s: Estimate
    exp2_amplitude: Estimate | None
    exp2_tau_s: Estimate | None
    t0_s: float
    param_names: tuple[str, ...]
    covariance: np.ndarray
    noise_ar: tuple[float, ...]  # AR model of the residual behind the standard errors
    noise_sigma2: float
    bic_exp1: float
    bic_exp2: float | None  # None when the two-exponential fit was not attempted or failed
    fitted: np.ndarray
    residual: np.ndarray

    def __post_init__(self) -> None:
        exp2 = self.kind == "exp2"
        if (self.exp2_amplitude is not None) != exp2 or (self.exp2_tau_s is not None) != exp2:
            raise ValueError(f"kind = {self.kind!r} needs exp2_amplitude and exp2_tau_s "
                             f"{'both set' if exp2 else 'both None'}")

    def evaluate(self, t_s: np.ndarray) -> np.ndarray:
        """Trend value at absolute times ``t_s`` (same time base as the fitted trace)."""
        u = np.asarray(t_s, dtype=float) - self.t0_s
        out = self.offset.value + self.exp_amplitude.value * np.exp(-u / self.exp_tau_s.value)
        if self.exp2_amplitude is not None and self.exp2_tau_s is not None:  # kind == "exp2"
            out = out + self.exp2_amplitude.value * np.exp(-u / self.exp2_tau_s.value)
        return out + self.linear_slope_per_s.value * u

    def to_dict(self) -> dict:
        """JSON-ready parameters (``{"value", "std"}`` each), ``kind``, ``t0_s``, noise AR and BICs."""
        d: dict[str, object] = {"kind": self.kind, "t0_s": float(self.t0_s)}
        for name in ("offset", "exp_amplitude", "exp_tau_s", "linear_slope_per_s", "exp2_amplitude", "exp2_tau_s"):
            est = getattr(self, name)
            if est is not None:
                d[name] = est.to_dict()
        d["noise_ar"] = list(self.noise_ar)
        d["bic_exp1"] = float(self.bic_exp1)
        d["bic_exp2"] = None if self.bic_exp2 is None else float(self.bic_exp2)
        return d


def _model(theta: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Model value and Jacobian; ``theta = [c, a1, τ1, (a2, τ2,) b]``."""
    n_exp = (theta.size - 2) // 2
    cols = [np.ones_like(u)]
    value = theta[0] + theta[-1] * u
    for i in range(n_exp):
        a, tau = theta[1 + 2 * i], theta[2 + 2 * i]
        e = np.exp(-u / tau)
        value = value + a * e
        cols += [e, a * u / tau**2 * e]
    cols.append(u)
    return value, np.column_stack(cols)


def _value(theta: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Model value only (the Jacobian costs several more passes over ``u``)."""
    value = theta[0] + theta[-1] * u
    for i in range((theta.size - 2) // 2):
        value += theta[1 + 2 * i] * np.exp(-u / theta[2 + 2 * i])
    return value


def _block_means(u: np.ndarray, y: np.ndarray, points: int) -> tuple[np.ndarray, np.ndarray]:
    """Average consecutive blocks so at most ~``points`` remain (the tail block is dropped)."""
    if u.size <= points:
        return u, y
    block = -(-u.size // points)
    m = u.size // block * block
    return u[:m].reshape(-1, block).mean(1), y[:m].reshape(-1, block).mean(1)


def _scan(u: np.ndarray, y: np.ndarray, taus: np.ndarray, fixed: tuple[float, ...] = ()) -> np.ndarray:
    """Variable projection: best τ on the grid with every linear coefficient solved exactly."""
    u, y = _block_means(u, y, _SCAN_POINTS)
    base = [np.ones_like(u), u] + [np.exp(-u / t) for t in fixed]
    best_sse, best = np.inf, None
    for tau in taus:
        a = np.column_stack(base + [np.exp(-u / tau)])
        coef, *_ = np.linalg.lstsq(a, y, rcond=None)
        with np.errstate(over="ignore"):  # an overflowing residual is refused below, by name
            sse = float(np.sum((a @ coef - y) ** 2))
        if sse < best_sse:
            best_sse, best = sse, (coef, tau)
    if best is None:
        raise ValueError(f"no time constant of the scan gives a finite residual: values up to "
                         f"{float(np.max(np.abs(y))):.3g} overflow the sum of squares; rescale the trace")
    coef, tau = best
    c, b, amps = coef[0], coef[1], coef[2:]
    pairs = sorted(zip(list(fixed) + [tau], amps), key=lambda pair: pair[0])
    return np.array([c, *[v for t, a in pairs for v in (a, t)], b])


def _noise_model(resid: np.ndarray) -> tuple[np.ndarray, float]:
    """AR model (Burg, BIC order) of a trend residual; a noiseless fit gets a vanishing σ²."""
    if not np.any(resid - resid.mean()):
        return np.zeros(0), float(np.finfo(float).tiny)
    return ts.burg_bic(resid, min(MAX_NOISE_ORDER, resid.size // 10))


_TAUS = slice(2, -1, 2)  # positions of the time constants in theta


def _solve(u: np.ndarray, y: np.ndarray, z0: np.ndarray, log_bounds: tuple[float, float]) -> np.ndarray:
    """Least squares in ``z`` = theta with ln τ in place of τ (positive by construction,
    better scaled): MINPACK Levenberg–Marquardt, or bounded TRF if τ runs off."""

    def theta(z: np.ndarray) -> np.ndarray:
        th = z.copy()
        th[_TAUS] = np.exp(np.clip(z[_TAUS], -700.0, 700.0))  # a trial step may run τ off; no overflow
        return th

    def resid(z: np.ndarray) -> np.ndarray:
        return _value(theta(z), u) - y

    def jac(z: np.ndarray) -> np.ndarray:
        th = theta(z)
        j = _model(th, u)[1]
        j[:, _TAUS] *= th[_TAUS]  # d/d ln τ = τ d/dτ
        return j

    sol = least_squares(resid, z0, jac=jac, x_scale="jac", method="lm")
    if np.any((sol.x[_TAUS] < log_bounds[0]) | (sol.x[_TAUS] > log_bounds[1])):  # no transient: bounded rerun
        lo, hi = np.full(z0.size, -np.inf), np.full(z0.size, np.inf)
        lo[_TAUS], hi[_TAUS] = log_bounds
        z0 = z0.copy()
        z0[_TAUS] = np.clip(z0[_TAUS], log_bounds[0] + 1e-9, log_bounds[1] - 1e-9)
        sol = least_squares(resid, z0, jac=jac, x_scale="jac", method="trf", bounds=(lo, hi))
    return sol.x


def _fit_blocks(u: np.ndarray, y: np.ndarray, start: np.ndarray,
                tau_bounds: tuple[float, float]) -> tuple[np.ndarray, float, int]:
    """First stage of :func:`_fit` for long traces: NLS on ≤ 16384 block means.

    Returns ``(z, sse, n_blocks)``: parameters with ln τ, the block-mean residual sum of
    squares and the number of block means.
    """
    log_bounds = (float(np.log(tau_bounds[0])), float(np.log(tau_bounds[1])))
    z = start.copy()
    z[_TAUS] = np.log(np.clip(start[_TAUS], *tau_bounds))
    ub, yb = _block_means(u, y, _FIT_POINTS)
    z = _solve(ub, yb, z, log_bounds)
    theta = z.copy()
    theta[_TAUS] = np.exp(z[_TAUS])
    return z, float(np.sum((_value(theta, ub) - yb) ** 2)), ub.size


# theta, covariance, noise AR coefficients, innovation variance, BIC, fitted values
_Fit = tuple[np.ndarray, np.ndarray, np.ndarray, float, float, np.ndarray]


def _fit(u: np.ndarray, y: np.ndarray, start: np.ndarray, tau_bounds: tuple[float, float],
         z_blocks: np.ndarray | None = None) -> _Fit:
    """NLS from ``start``; returns (theta, cov, phi, sigma2, bic, fitted).

    Long traces are first fitted on ≤ 16384 block means (or ``z_blocks``, that stage's
    result from :func:`_fit_blocks`), then polished on every sample (a few iterations
    from there).  Covariances are evaluated in τ.
    """
    log_bounds = (float(np.log(tau_bounds[0])), float(np.log(tau_bounds[1])))
    z = start.copy()
    z[_TAUS] = np.log(np.clip(start[_TAUS], *tau_bounds))
    if z_blocks is not None:
        z = z_blocks
    elif u.size > 4 * _FIT_POINTS:
        z = _fit_blocks(u, y, start, tau_bounds)[0]
    z = _solve(u, y, z, log_bounds)
    theta = z.copy()
    theta[_TAUS] = np.exp(z[_TAUS])
    fitted, jac = _model(theta, u)
    resid = y - fitted
    phi, sigma2 = _noise_model(resid)
    g = lfilter([1.0], np.r_[1.0, -phi], jac[::-1], axis=0)[::-1]  # L⁻ᵀJ, see module docstring
    scale = 1.0 / np.maximum(np.linalg.norm(jac, axis=0), np.finfo(float).tiny)  # columns differ by ~10¹⁵
    h_inv = scale[:, None] * np.linalg.pinv((jac * scale).T @ (jac * scale)) * scale[None, :]
    cov = h_inv @ (sigma2 * g.T @ g) @ h_inv
    k = theta.size + phi.size + 1
    bic = float(y.size * np.log(sigma2) + k * np.log(y.size))
    return theta, cov, phi, sigma2, bic, fitted


def _exp2_promising(blocks1: tuple[np.ndarray, float, int], blocks2: tuple[np.ndarray, float, int], n: int) -> bool:
    """Could two exponentials pass the full-length BIC test?  Judged on block means.

    Each block mean averages ≥ 61 samples, many noise correlation times, so block means
    carry nearly white noise and the Gaussian likelihood ratio ``nb·ln(SSE1/SSE2)`` of
    the two block fits estimates the full-length one (the trend lives at frequencies the
    blocks keep).  Acceptance needs a full-length ratio above ``BIC_MARGIN + 2 ln n``
    (~38 at 10⁶ samples); the full fit is skipped only when the block ratio is below
    half of that.  Correlated block noise (slow drift) inflates the block ratio, which
    errs towards fitting.
    """
    (_, sse1, nb), (_, sse2, _) = blocks1, blocks2
    if not sse2 > 0:
        return True
    return nb * np.log(sse1 / sse2) > 0.5 * (BIC_MARGIN + 2 * np.log(n))


def fit_trend(t_s: np.ndarray, y: np.ndarray, *, allow_two_exponentials: bool = True) -> TrendFit:
    """Fit the start-up trend to a trace; see the module docstring.

    ``t_s``: strictly increasing times in s (uniform sampling assumed for the noise
    model); ``y``: the trace in its own units.  Needs at least 32 samples.

    ``y(u) = c + a·exp(−u/τ) + b·u`` (``u = t − t0``) by nonlinear least squares from a
    variable-projection scan of τ; standard errors by the sandwich formula under an AR
    model of the residual.  A second exponential is kept only when the BIC falls by more
    than 10 and both amplitudes exceed three standard errors.

    Parameters
    ----------
    t_s : array_like of float, shape (N,)
        Sample times in s, finite and strictly increasing (uniform sampling assumed by the
        noise model).
    y : array_like of float, shape (N,)
        The trace in its own unit (V, mA, g, …), finite; N ≥ 32.
    allow_two_exponentials : bool, default True
        Try ``c + a1·exp(−u/τ1) + a2·exp(−u/τ2) + b·u`` as well; False fits one exponential only.

    Returns
    -------
    TrendFit
        Parameters as :class:`~bench.values.Estimate` (unit of ``y``, τ in s, slope per s),
        their covariance, the fitted trend and the residual.

    Raises
    ------
    ValueError
        If ``t_s`` and ``y`` are not 1-D of equal length, have fewer than 32 samples or a
        non-finite value, ``t_s`` is not strictly increasing, or the values overflow the
        sum of squares (rescale the trace).

    Examples
    --------
    >>> import numpy as np
    >>> from bench.analysis.startup import fit_trend
    >>> t = np.arange(2000) * 0.1  # s
    >>> y = 1.0 + 0.05 * np.exp(-t / 20.0) + 1e-4 * t + np.random.default_rng(0).normal(0.0, 0.002, t.size)
    >>> f = fit_trend(t, y)
    >>> f.kind, f.param_names
    ('exp1', ('offset', 'exp_amplitude', 'exp_tau_s', 'linear_slope_per_s'))
    >>> bool(abs(f.exp_tau_s.value - 20.0) < 3 * f.exp_tau_s.std), round(f.exp_tau_s.value)
    (True, 20)
    >>> round(f.exp_amplitude.value, 3), round(f.linear_slope_per_s.value * 1e4, 1)
    (0.05, 1.0)
    >>> round(float(np.std(f.residual)), 4)  # the white noise is what is left
    0.002
    """
    t = np.asarray(t_s, dtype=float)
    y = np.asarray(y, dtype=float)
    if t.shape != y.shape or t.ndim != 1:
        raise ValueError(f"t_s and y must be 1-D of equal length, got shapes {t.shape} and {y.shape}")
    if t.size < MIN_SAMPLES:
        raise ValueError(f"trace has {t.size} samples; the trend fit needs at least {MIN_SAMPLES}")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(y))):
        raise ValueError("t_s and y must be finite")
    if np.any(np.diff(t) <= 0):
        raise ValueError("t_s must be strictly increasing")
    u = t - t[0]
    dt, span = float(np.median(np.diff(u))), float(u[-1])
    bounds = (dt / 10, 1e3 * span)
    taus = np.geomspace(dt, 3 * span, 60)

    long = u.size > 4 * _FIT_POINTS
    start1 = _scan(u, y, taus)
    blocks1 = _fit_blocks(u, y, start1, bounds) if long else None
    fit1 = _fit(u, y, start1, bounds, None if blocks1 is None else blocks1[0])
    best, bic2 = fit1, None
    kind: Literal["exp1", "exp2"] = "exp1"
    fit2: _Fit | None
    if allow_two_exponentials:
        try:
            start2 = _scan(u, y, taus[np.abs(np.log(taus / fit1[0][2])) > np.log(2)], fixed=(fit1[0][2],))
            blocks2 = _fit_blocks(u, y, start2, bounds) if long else None
            if blocks1 is not None and blocks2 is not None and not _exp2_promising(blocks1, blocks2, u.size):
                fit2 = None  # screened out on the block means (module docstring)
            else:
                fit2 = _fit(u, y, start2, bounds, None if blocks2 is None else blocks2[0])
        except (np.linalg.LinAlgError, ValueError):  # degenerate scan/fit: one exponential it is
            fit2 = None
        if fit2 is not None:
            bic2 = float(fit2[4])
            var2 = np.diag(fit2[1])
            # a negative variance means an ill-conditioned fit: treat it as insignificant
            std2 = np.sqrt(np.where(var2 >= 0, var2, np.inf))
            amps_significant = np.all(np.abs(fit2[0][[1, 3]]) > 3 * std2[[1, 3]])
            if fit1[4] - fit2[4] > BIC_MARGIN and amps_significant:
                best, kind = fit2, "exp2"
    theta, cov, phi, sigma2, _, fitted = best
    if kind == "exp2" and theta[2] > theta[4]:  # report the faster exponential first
        order = [0, 3, 4, 1, 2, 5]
        theta, cov = theta[order], cov[np.ix_(order, order)]
    std = np.sqrt(np.clip(np.diag(cov), 0, None))
    est = [Estimate(float(v), float(s)) for v, s in zip(theta, std)]
    names = ("offset", "exp_amplitude", "exp_tau_s") + (("exp2_amplitude", "exp2_tau_s") if kind == "exp2" else ())
    fitted.flags.writeable = False
    resid = y - fitted
    resid.flags.writeable = False
    return TrendFit(
        kind, est[0], est[1], est[2], est[-1],
        est[3] if kind == "exp2" else None, est[4] if kind == "exp2" else None,
        float(t[0]), names + ("linear_slope_per_s",), cov, tuple(phi.tolist()), float(sigma2),
        float(fit1[4]), bic2, fitted, resid,
    )
