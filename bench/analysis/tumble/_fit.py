"""Accelerometer multi-position (tumble) calibration, IEEE Std 1293 style.

Model (IEEE 1293 pendulous accelerometer, specific force a in standard g)::

    I = K1 · (K0 + a_i + K2 a_i² + K3 a_i³ + δo a_p − δp a_o + Kip a_i a_p + Kio a_i a_o)

It is linear in the coefficients ``c = (K1K0, K1, K1δo, −K1δp, K1K2, K1Kip, K1Kio, K1K3)``
of the regressors ``(1, a_i, a_p, a_o, a_i², a_i a_p, a_i a_o, a_i³)``: a weighted linear
least-squares fit gives ``c`` and its covariance, and the parameters follow as ratios to
K1 (``K0 = c0/c1`` ...), their standard errors by first-order propagation (delta method).

Positions on the dual-axis table: inner angle θi (axis 1, about platform z), outer angle
θo (axis 2, about level East). The specific force in platform axes is
``g/g0 · (sin θo sin θi, sin θo cos θi, cos θo)``; a fixture maps it to the sensor's
(IA, PA, OA) with an orthonormal ``mount`` matrix whose rows are IA, PA, OA in platform
axes. With :data:`DEFAULT_MOUNT` (IA = z, PA = x, OA = y), inner 0° tumbles IA in the
IA–OA plane (a_p = 0) and inner 90° in the IA–PA plane (a_o = 0).

Identifiability is decided from the positions alone: regressors are taken in the order
above (the model's leading terms first) and one is fitted only if its column keeps a
part of relative size ≥ ``alias_tol`` outside the span of those already kept; otherwise
its parameter is listed in ``not_identifiable`` with the reason (never excited, or the
exact alias, e.g. a_i³ = a_i at the four quadrant positions so K3 hides in K1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import stats

from bench.values import Estimate

#: Rows IA, PA, OA in platform axes: IA along platform z (up at zero), PA = x, OA = y.
DEFAULT_MOUNT = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
#: Parameter names, as the fields of ``sim.physics.accelerometer.AccelerometerParams``.
PARAM_NAMES = ("k0_g", "k1_ma_per_g", "k2_g_per_g2", "k3_g_per_g3",
               "delta_o_rad", "delta_p_rad", "kip_g_per_g2", "kio_g_per_g2")
# (parameter, regressor label, sign of the coefficient relative to K1·parameter), in the
# order terms are admitted: a later term aliased with earlier ones is the one dropped.
_TERMS = (("k0_g", "1", 1.0), ("k1_ma_per_g", "a_i", 1.0), ("delta_o_rad", "a_p", 1.0),
          ("delta_p_rad", "a_o", -1.0), ("k2_g_per_g2", "a_i^2", 1.0),
          ("kip_g_per_g2", "a_i*a_p", 1.0), ("kio_g_per_g2", "a_i*a_o", 1.0),
          ("k3_g_per_g3", "a_i^3", 1.0))
ALIAS_TOL = 1e-3  # designed aliases leave ~1e-5 with 1 mdeg position scatter; real designs ≥ 0.1


def _sincos_deg(angle_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """sin and cos of degrees, exact at multiples of 90° (so unexcited axes give exact zeros)."""
    x = np.mod(angle_deg, 360.0)
    quadrant = np.rint(x / 90.0)
    r = np.radians(x - 90.0 * quadrant)
    s, c = np.sin(r), np.cos(r)
    q = quadrant.astype(int) % 4
    sin = np.choose(q, [s, c, -s, -c])
    cos = np.choose(q, [c, -s, -c, s])
    return sin, cos


def tumble_positions(n_positions: int, planes: int = 1) -> np.ndarray:
    """Tumble plan: rows ``(inner_deg, outer_deg)``, shape ``(n_positions · planes, 2)``.

    ``n_positions`` equally spaced outer angles ``k·360/n`` (k = 0 … n−1, n ≥ 4 and
    divisible by 4, so IA up, down and both horizontals are always visited). Plane 1 has
    inner 0° — the IA–OA plane for :data:`DEFAULT_MOUNT`; ``planes=2`` adds the same
    outer angles at inner 90° — the IA–PA plane.

    Parameters
    ----------
    n_positions : int
        Outer-axis positions per plane, a multiple of 4 in [4, 360].
    planes : {1, 2}, default 1
        Tumble planes: inner 0° only, or inner 0° and 90°.

    Returns
    -------
    ndarray of float, shape (n_positions · planes, 2)
        Rows ``(inner_deg, outer_deg)``: table angles in degrees, plane by plane.

    Raises
    ------
    ValueError
        If ``n_positions`` is not an integer multiple of 4 in [4, 360], or ``planes`` is not 1 or 2.

    Examples
    --------
    >>> from bench.analysis.tumble import tumble_positions
    >>> tumble_positions(4).tolist()
    [[0.0, 0.0], [0.0, 90.0], [0.0, 180.0], [0.0, 270.0]]
    >>> tumble_positions(8, planes=2).shape
    (16, 2)
    """
    if isinstance(n_positions, bool) or not isinstance(n_positions, (int, np.integer)) \
            or not (4 <= n_positions <= 360 and n_positions % 4 == 0):
        raise ValueError(f"n_positions={n_positions!r} must be a multiple of 4 in [4, 360]")
    if planes not in (1, 2) or isinstance(planes, bool):
        raise ValueError(f"planes={planes!r} must be 1 or 2")
    outer = np.arange(n_positions) * 360.0 / n_positions  # k·360/n: quadrants exact
    inner = [0.0, 90.0][:planes]
    return np.array([(i, o) for i in inner for o in outer])


def _check_mount(mount) -> np.ndarray:
    m = np.asarray(mount, dtype=float)
    if m.shape != (3, 3) or not np.all(np.isfinite(m)) or not np.allclose(m @ m.T, np.eye(3), atol=1e-9):
        raise ValueError(f"mount={mount!r} must be a 3×3 orthonormal matrix (rows IA, PA, OA; "
                         "‖M Mᵀ − I‖ ≤ 1e-9)")
    return m


def specific_force_iapo_g(inner_deg, outer_deg, g_over_g0: float = 1.0,
                          mount=DEFAULT_MOUNT) -> np.ndarray:
    """Specific force along (IA, PA, OA) in standard g at table angles in degrees, shape (m, 3).

    ``g_over_g0`` is local gravity over standard gravity (allowed 0.95 … 1.05).

    In platform axes the specific force is ``g/g0 · (sin θo sin θi, sin θo cos θi, cos θo)``
    (θi inner, θo outer); ``mount`` maps it to the sensor's (IA, PA, OA).  Sines and cosines
    are exact at multiples of 90°, so unexcited axes give exact zeros.

    Parameters
    ----------
    inner_deg : float or array_like of float, shape (m,)
        Inner-axis angles θi (about platform z), in degrees; finite.
    outer_deg : float or array_like of float, shape (m,)
        Outer-axis angles θo (about level East), in degrees; finite, same shape as ``inner_deg``.
    g_over_g0 : float, default 1.0
        Local gravity over standard gravity (9.80665 m/s²), in [0.95, 1.05].
    mount : array_like of float, shape (3, 3), default DEFAULT_MOUNT
        Orthonormal matrix whose rows are IA, PA, OA in platform axes
        (default IA = z, PA = x, OA = y).

    Returns
    -------
    ndarray of float, shape (m, 3)
        Rows ``(a_i, a_p, a_o)``, in standard g.

    Raises
    ------
    ValueError
        If the angle arrays are not 1-D of one length or not finite, ``g_over_g0`` is outside
        [0.95, 1.05], or ``mount`` is not a 3×3 orthonormal matrix (‖M Mᵀ − I‖ ≤ 1e-9).

    Examples
    --------
    >>> from bench.analysis.tumble import specific_force_iapo_g
    >>> specific_force_iapo_g([0.0, 0.0, 90.0], [0.0, 90.0, 90.0]).tolist()  # IA up, OA up, PA up
    [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]]
    >>> specific_force_iapo_g(0.0, 180.0, g_over_g0=0.98).tolist()  # IA down, local g
    [[-0.98, 0.0, 0.0]]
    """
    inner = np.atleast_1d(np.asarray(inner_deg, dtype=float))
    outer = np.atleast_1d(np.asarray(outer_deg, dtype=float))
    if inner.ndim != 1 or inner.shape != outer.shape:
        raise ValueError(f"inner_deg and outer_deg must be 1-D of one length, got shapes "
                         f"{inner.shape} and {outer.shape}")
    if not (np.all(np.isfinite(inner)) and np.all(np.isfinite(outer))):
        raise ValueError("inner_deg and outer_deg must be finite")
    if not (isinstance(g_over_g0, (int, float)) and 0.95 <= g_over_g0 <= 1.05):
        raise ValueError(f"g_over_g0={g_over_g0!r} outside the allowed range [0.95, 1.05]")
    m = _check_mount(mount)
    si, ci = _sincos_deg(inner)
    so, co = _sincos_deg(outer)
    f_platform = np.stack([so * si, so * ci, co], axis=1) * g_over_g0
    return f_platform @ m.T


def _regressors(f: np.ndarray) -> np.ndarray:
    """Columns in ``_TERMS`` order for rows (a_i, a_p, a_o)."""
    ai, ap, ao = f[:, 0], f[:, 1], f[:, 2]
    return np.column_stack([np.ones_like(ai), ai, ap, ao, ai**2, ai * ap, ai * ao, ai**3])


def _identify(x: np.ndarray, alias_tol: float) -> tuple[list[int], dict[str, str]]:
    """Indices of ``_TERMS`` to fit, and the reason for each one left out."""
    kept: list[int] = []
    dropped: dict[str, str] = {}
    q = np.zeros((x.shape[0], 0))
    for j, (name, label, _) in enumerate(_TERMS):
        col = x[:, j]
        norm = np.linalg.norm(col)
        if norm <= alias_tol * math.sqrt(x.shape[0]):  # rms below tolerance: never excited
            dropped[name] = f"{label} is zero at every position: no position excites it"
            continue
        rest = col - q @ (q.T @ col)
        if np.linalg.norm(rest) < alias_tol * norm:
            combo, *_ = np.linalg.lstsq(x[:, kept], col, rcond=None)
            big = np.abs(combo) > 1e-6 * np.abs(combo).max()
            expr = " + ".join(f"{c:.3g}·{_TERMS[k][1]}" for c, k, b in zip(combo, kept, big) if b)
            partners = ", ".join(_TERMS[k][0] for k, b in zip(kept, big) if b)
            dropped[name] = f"{label} = {expr} at every position: not separable from {partners}"
            continue
        kept.append(j)
        q = np.column_stack([q, rest / np.linalg.norm(rest)])
    return kept, dropped


@dataclass(frozen=True, eq=False)
class TumbleResult:
    """Tumble fit. Parameters in the units their names say (g, mA/g, rad, g/g², g/g³).

    ``params`` holds the identifiable parameters (std None when the noise is unknown);
    ``covariance`` is theirs, ordered as ``param_names`` (None when unknown);
    ``coefficients`` are the fitted linear coefficients of ``terms`` in output units per
    gᵏ. Residuals are output − fit in output units, and in g (divided by fitted K1).
    ``sigma_source``: "stated" (output_sigma given), "residuals" (estimated from the
    residual scatter; use ``coverage_factor_95`` = Student t for ``dof``) or "unknown".
    ``condition_number`` is that of the weighted design with unit-norm columns.

    Attributes
    ----------
    params : dict of str to Estimate
        Identifiable parameters among ``k0_g`` (g), ``k1_ma_per_g`` (mA/g), ``k2_g_per_g2``
        (g/g²), ``k3_g_per_g3`` (g/g³), ``delta_o_rad``, ``delta_p_rad`` (rad),
        ``kip_g_per_g2``, ``kio_g_per_g2`` (g/g²), in that order.
    param_names : tuple of str
        Keys of ``params``, the order of ``covariance``.
    not_identifiable : dict of str to str
        Parameters the positions cannot determine, with the reason (never excited, or aliased).
    terms : tuple of str
        Regressors fitted (``"1"``, ``"a_i"``, ``"a_p"``, …), the order of ``coefficients``.
    coefficients : ndarray of float
        Linear coefficients of ``terms``, in output units per gᵏ.
    covariance : ndarray of float or None
        Covariance of the parameters in their units (ordered as ``param_names``); None when
        the noise is unknown.
    residuals : ndarray of float, shape (m,)
        Output − fit per position, in output units.
    residuals_g : ndarray of float, shape (m,)
        Residuals in g (divided by the fitted K1 in output units per g).
    rms : float
        RMS residual, in output units.
    rms_g : float
        RMS residual, in g.
    dof : int
        Degrees of freedom: positions − fitted parameters.
    noise_sigma : float or None
        Output noise σ used, in output units (rms of ``output_sigma``, or from the residuals);
        None when unknown.
    sigma_source : {"stated", "residuals", "unknown"}
        Where the uncertainties come from.
    chi2_per_dof : float or None
        Weighted χ²/dof with stated sigmas (None otherwise or when dof = 0).
    coverage_factor_95 : float or None
        Factor turning a standard error into a 95 % interval (normal 1.96 for stated sigmas,
        Student t for ``dof`` otherwise); None when unknown.
    condition_number : float
        Condition number of the weighted design with unit-norm columns.
    output_unit_per_ma : float
        Output units per mA, as given.
    """

    params: dict[str, Estimate]
    param_names: tuple[str, ...]
    not_identifiable: dict[str, str]
    terms: tuple[str, ...]
    coefficients: np.ndarray
    covariance: np.ndarray | None
    residuals: np.ndarray
    residuals_g: np.ndarray
    rms: float
    rms_g: float
    dof: int
    noise_sigma: float | None
    sigma_source: str
    chi2_per_dof: float | None
    coverage_factor_95: float | None
    condition_number: float
    output_unit_per_ma: float

    def predicted_output(self, f_iapo_g) -> np.ndarray:
        """Fitted model output (output units) for specific-force rows (a_i, a_p, a_o) in g."""
        f = np.asarray(f_iapo_g, dtype=float)
        if f.ndim != 2 or f.shape[1] != 3:
            raise ValueError(f"f_iapo_g must have shape (m, 3), got {f.shape}")
        cols = [k for k, (name, _, _) in enumerate(_TERMS) if name in self.params]
        return _regressors(f)[:, cols] @ self.coefficients

    def to_dict(self) -> dict:
        """JSON-ready fields (lists and floats; None where unknown)."""
        def opt(v):
            return None if v is None else float(v)
        return {
            "params": {k: v.to_dict() for k, v in self.params.items()},
            "param_names": list(self.param_names),
            "not_identifiable": dict(self.not_identifiable),
            "terms": list(self.terms),
            "coefficients": [float(c) for c in self.coefficients],
            "covariance": None if self.covariance is None else self.covariance.tolist(),
            "residuals": [float(r) for r in self.residuals],
            "residuals_g": [float(r) for r in self.residuals_g],
            "rms": float(self.rms), "rms_g": float(self.rms_g), "dof": int(self.dof),
            "noise_sigma": opt(self.noise_sigma), "sigma_source": self.sigma_source,
            "chi2_per_dof": opt(self.chi2_per_dof), "coverage_factor_95": opt(self.coverage_factor_95),
            "condition_number": float(self.condition_number),
            "output_unit_per_ma": float(self.output_unit_per_ma),
        }


def _check_inputs(f_iapo_g, output, output_sigma, output_unit_per_ma, alias_tol):
    f = np.asarray(f_iapo_g, dtype=float)
    if f.ndim != 2 or f.shape[1] != 3 or f.shape[0] < 2:
        raise ValueError(f"f_iapo_g must have shape (m, 3) with m ≥ 2, got {f.shape}")
    if not np.all(np.isfinite(f)) or np.abs(f).max() > 2.0:
        raise ValueError("f_iapo_g must be finite with every component in [-2, 2] g")
    y = np.asarray(output, dtype=float)
    if y.shape != (f.shape[0],) or not np.all(np.isfinite(y)):
        raise ValueError(f"output must be finite with shape ({f.shape[0]},), got {y.shape}")
    sigma = None
    if output_sigma is not None:
        sigma = np.asarray(output_sigma, dtype=float)
        if sigma.shape != y.shape or not np.all(np.isfinite(sigma)) or not np.all(sigma > 0):
            raise ValueError(f"output_sigma must be finite and > 0 with shape {y.shape}")
    if not (isinstance(output_unit_per_ma, (int, float)) and math.isfinite(output_unit_per_ma)
            and output_unit_per_ma != 0):
        raise ValueError(f"output_unit_per_ma={output_unit_per_ma!r} must be finite and non-zero")
    if not (isinstance(alias_tol, (int, float)) and 1e-12 <= alias_tol <= 0.1):
        raise ValueError(f"alias_tol={alias_tol!r} outside the allowed range [1e-12, 0.1]")
    return f, y, sigma


def _solve(xw: np.ndarray, yw: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Least squares on the whitened system: coefficients, (XᵀWX)⁻¹, scaled condition number."""
    norms = np.linalg.norm(xw, axis=0)
    xs = xw / norms  # unit-norm columns: the condition number then measures the design
    u, s, vt = np.linalg.svd(xs, full_matrices=False)
    beta = vt.T @ ((u.T @ yw) / s)
    beta = beta + vt.T @ ((u.T @ (yw - xs @ beta)) / s)  # one refinement step
    inv = (vt.T / s**2) @ vt
    return beta / norms, inv / np.outer(norms, norms), float(s[0] / s[-1])


def fit_tumble(f_iapo_g, output, output_sigma=None, *, output_unit_per_ma: float = 1e-3,
               alias_tol: float = ALIAS_TOL) -> TumbleResult:
    """Fit the IEEE 1293 model to one mean output per position.

    ``f_iapo_g`` (m, 3): specific force (a_i, a_p, a_o) in g per position (see
    :func:`specific_force_iapo_g`). ``output`` (m,): mean output per position in any unit
    proportional to the current, ``output_unit_per_ma`` of them per mA (default 1e-3: amperes;
    a sampling resistor R read in volts gives R·1e-3). ``output_sigma`` (m,): standard error of
    each mean in output units, or None to estimate one common σ from the residuals (needs
    dof > 0; with dof = 0 the estimates come without uncertainty).

    The model ``I = K1 · (K0 + a_i + K2 a_i² + K3 a_i³ + δo a_p − δp a_o + Kip a_i a_p + Kio a_i a_o)``
    is linear in ``c = (K1K0, K1, K1δo, −K1δp, K1K2, K1Kip, K1Kio, K1K3)``: weighted linear
    least squares gives ``c``, the parameters follow as ratios to K1 and their standard
    errors by first-order propagation.  A regressor is fitted only if the positions excite
    it apart from those already kept (``alias_tol``); the rest are listed as not identifiable.

    Parameters
    ----------
    f_iapo_g : array_like of float, shape (m, 3)
        Specific force ``(a_i, a_p, a_o)`` in g per position, each component in [−2, 2]; m ≥ 2.
    output : array_like of float, shape (m,)
        Mean output per position, in output units (proportional to the current); finite.
    output_sigma : array_like of float, shape (m,), optional
        Standard error of each mean in output units, finite and > 0; None: one common σ
        estimated from the residuals.
    output_unit_per_ma : float, default 1e-3
        Output units per mA, finite and non-zero (1e-3: output in A; a sampling resistor
        R in Ω read in volts gives R·1e-3).
    alias_tol : float, default ALIAS_TOL
        Least relative part of a regressor outside the span of the earlier ones for it to be
        fitted, in [1e-12, 0.1]; default 1e-3.

    Returns
    -------
    TumbleResult
        Identifiable parameters as :class:`~bench.values.Estimate` (g, mA/g, rad, g/g², g/g³),
        their covariance, the not identifiable ones with reasons, and the residuals.

    Raises
    ------
    ValueError
        If the shapes are wrong, a value is not finite, a specific-force component is
        outside [−2, 2] g, ``output_sigma`` is not > 0, ``output_unit_per_ma`` is zero or not
        finite, ``alias_tol`` is outside [1e-12, 0.1], the specific force is zero everywhere,
        a_i takes fewer than two distinct values, or the output does not follow a_i.

    Examples
    --------
    Two tumble planes of 8 positions; an output in A with K1 = 1.2 mA/g, K0 = 1e-4 g and
    δo = 1e-4 rad, plus 10 nA of noise:

    >>> import numpy as np
    >>> from bench.analysis.tumble import fit_tumble, specific_force_iapo_g, tumble_positions
    >>> pos = tumble_positions(8, planes=2)
    >>> f = specific_force_iapo_g(pos[:, 0], pos[:, 1])
    >>> a_i, a_p, a_o = f.T
    >>> current_a = 1.2e-3 * (1e-4 + a_i + 1e-4 * a_p) + np.random.default_rng(0).normal(0.0, 1e-8, len(f))
    >>> r = fit_tumble(f, current_a)
    >>> r.sigma_source, r.dof, r.not_identifiable
    ('residuals', 8, {})
    >>> k0, k1, d_o = r.params["k0_g"], r.params["k1_ma_per_g"], r.params["delta_o_rad"]
    >>> round(k1.value, 4), bool(abs(k0.value - 1e-4) < 3 * k0.std), bool(abs(d_o.value - 1e-4) < 3 * d_o.std)
    (1.2, True, True)

    Four positions in one plane determine only K0, K1, K2 and δp:

    >>> f4 = specific_force_iapo_g(*tumble_positions(4).T)
    >>> r4 = fit_tumble(f4, 1.2e-3 * (1e-4 + f4[:, 0]))
    >>> r4.param_names, r4.sigma_source
    (('k0_g', 'k1_ma_per_g', 'k2_g_per_g2', 'delta_p_rad'), 'unknown')
    >>> r4.not_identifiable["k3_g_per_g3"]
    'a_i^3 = 1·a_i at every position: not separable from k1_ma_per_g'
    """
    f, y, sigma = _check_inputs(f_iapo_g, output, output_sigma, output_unit_per_ma, alias_tol)
    scale = float(np.mean(np.linalg.norm(f, axis=1)))
    if scale == 0.0:
        raise ValueError("f_iapo_g is zero at every position: nothing to calibrate against")
    kept, dropped = _identify(_regressors(f / scale), alias_tol)
    if 1 not in kept:
        raise ValueError(f"a_i must take at least two distinct values over the positions: "
                         f"{dropped.get('k1_ma_per_g')}")
    x = _regressors(f)[:, kept]
    w = np.ones_like(y) if sigma is None else 1.0 / sigma
    coef, inv, cond = _solve(x * w[:, None], y * w)
    resid = y - x @ coef
    m, p = x.shape
    dof = m - p
    chi2 = coverage = noise = None
    if sigma is not None:
        cov_c, source = inv, "stated"
        noise = float(np.sqrt(np.mean(sigma**2)))
        coverage = float(stats.norm.ppf(0.975))
        if dof > 0:
            chi2 = float(np.sum((resid / sigma) ** 2) / dof)
    elif dof > 0:
        s2 = float(resid @ resid / dof)
        cov_c, source, noise = inv * s2, "residuals", math.sqrt(s2)
        coverage = float(stats.t.ppf(0.975, dof))
    else:
        cov_c, source = None, "unknown"
    c1 = coef[1]
    if not abs(c1) * np.abs(f[:, 0]).max() > 1e-9 * np.abs(y).max():  # also catches NaN
        raise ValueError(f"fitted K1 = {c1!r} output units per g: the output does not follow a_i")
    # Parameters: K1 = c1/u, every other one s·c_j/c1; J is their Jacobian w.r.t. c.
    values = np.empty(p)
    jac = np.zeros((p, p))
    for row, j in enumerate(kept):
        name, _, sign = _TERMS[j]
        if j == 1:
            values[row] = c1 / output_unit_per_ma
            jac[row, 1] = 1.0 / output_unit_per_ma
        else:
            values[row] = sign * coef[row] / c1
            jac[row, row] = sign / c1
            jac[row, 1] = -sign * coef[row] / c1**2
    cov = None if cov_c is None else jac @ cov_c @ jac.T
    names = tuple(_TERMS[j][0] for j in kept)
    std = [None] * p if cov is None else np.sqrt(np.clip(np.diag(cov), 0.0, None))
    by_name = {n: Estimate(float(v), None if s is None else float(s)) for n, v, s in zip(names, values, std)}
    order = [n for n in PARAM_NAMES if n in by_name]  # the simulator's field order
    perm = [names.index(n) for n in order]
    return TumbleResult(
        params={n: by_name[n] for n in order}, param_names=tuple(order),
        not_identifiable={n: dropped[n] for n in PARAM_NAMES if n in dropped},
        terms=tuple(_TERMS[j][1] for j in kept), coefficients=coef,
        covariance=None if cov is None else cov[np.ix_(perm, perm)],
        residuals=resid, residuals_g=resid / c1, rms=float(np.sqrt(np.mean(resid**2))),
        rms_g=float(np.sqrt(np.mean(resid**2))) / abs(c1), dof=dof, noise_sigma=noise,
        sigma_source=source, chi2_per_dof=chi2, coverage_factor_95=coverage,
        condition_number=cond, output_unit_per_ma=float(output_unit_per_ma))
