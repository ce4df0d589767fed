"""Gyro rate-table calibration, IEEE Std 952 / 647 style.

Input: the mean indicated output at each table rate (averaged over whole revolutions, so
the Earth rate's horizontal part and table wobble average out), its standard error, and
the input rate along the input axis in °/s — table rate plus the Earth rate's component
(:func:`earth_rate_vertical_dps` when the IA is up).

- **Scale factor**: weighted least-squares line ``output = SF·ω + b`` (IEEE 952:
  the slope of the LS straight line through the input-output data). **Bias** in °/h is
  ``3600·b/SF_nominal`` with ``b`` the intercept of the asymmetry fit below (the line's own
  intercept carries the plan's mean of (A/2)|ω|): the indicated output at zero input as the gyro's user reads it
  (through the nominal scale factor), which is the model's B (``ω_out = B + ω(1 + ε …)``);
  the input-equivalent ``b/SF`` differs by the factor 1/(1 + ε).
- **Scale-factor error**: ``SF/SF_nominal − 1`` in ppm.
- **Nonlinearity**: ``max_k |r_k| / |SF·FS|`` in ppm, r the residuals of that line.
  Uncertainty: the standard error of the residual at the argmax, from
  ``Cov(r) = Σ − X (XᵀΣ⁻¹X)⁻¹ Xᵀ``. It ignores the choice of the argmax, so when the
  nonlinearity is not much larger than the noise the estimate is biased upward (a max of
  noisy magnitudes) and the interval is too narrow.
- **Asymmetry**: ``(SF+ − SF−)/SF_nominal`` in ppm, SF± the slopes of the positive and
  negative half-lines, both forced through one common bias, i.e. the weighted fit
  ``output = b + S·ω + D·|ω|`` with ``SF± = S ± D``. A common bias because the bias is a
  property of the gyro at rest, not of the sense of rotation: one intercept instead of two
  leaves each half-line's slope anchored by all points rather than extrapolated to zero
  rate from its own side, which roughly halves the asymmetry's variance with log-spaced
  rates. Normalised by the nominal scale factor because the model states A as a fraction
  of it (``ω(1 + ε + A/2·sign ω)``): on noiseless data without cubic nonlinearity this
  returns A exactly; IEEE 952's ratio to the measured mean scale factor differs by the
  factor 1/(1 + ε), i.e. by A·ε (0.09 ppm for A = ε = 300 ppm).
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import numpy as np

from bench.values import Estimate

#: WGS-84 Earth rotation rate in °/s (written here too: bench never imports sim).
EARTH_RATE_DPS = math.degrees(7.292115e-5)
_FULL_SCALE_MARGIN = 1.01  # ±FS table rates plus the Earth rate still count as in range
_PPM = 1e6


def _real(value) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def earth_rate_vertical_dps(latitude_deg: float) -> float:
    """Earth-rate component along local Up, Ω sin φ, in °/s.

    Add it to the table rate for an input axis pointing up (subtract it for one pointing
    down). Ω is the WGS-84 Earth rotation rate, 7.292115·10⁻⁵ rad/s (15.04 °/h).

    Parameters
    ----------
    latitude_deg : float
        Geodetic latitude φ of the table, in degrees, within [-90, 90].

    Returns
    -------
    float
        Vertical (Up) component of the Earth rate, in °/s; negative in the southern hemisphere.

    Raises
    ------
    ValueError
        If ``latitude_deg`` is not a real number in the allowed range [-90, 90].

    Examples
    --------
    >>> from bench.analysis.ratetable import earth_rate_vertical_dps
    >>> round(earth_rate_vertical_dps(90.0) * 3600, 3)  # at the pole: the whole rate, °/h
    15.041
    >>> round(earth_rate_vertical_dps(45.0) * 3600, 3)
    10.636
    >>> earth_rate_vertical_dps(0.0)
    0.0
    """
    if not (_real(latitude_deg) and -90.0 <= latitude_deg <= 90.0):
        raise ValueError(f"latitude_deg={latitude_deg!r} outside the allowed range [-90, 90]")
    return EARTH_RATE_DPS * math.sin(math.radians(latitude_deg))


def rate_plan(full_scale_dps: float, n_per_sign: int = 6, *, min_fraction: float = 0.01,
              max_fraction: float = 1.0) -> np.ndarray:
    """Default table rates of a rate-table calibration, in °/s.

    ``n_per_sign`` magnitudes log-spaced from ``min_fraction·FS`` to ``max_fraction·FS``,
    each visited + then −, smallest first. Interleaving the signs keeps a slow thermal drift
    from posing as asymmetry. A gyro that clips at exactly FS needs ``max_fraction`` < 1 so
    the Earth rate does not push it over.

    Parameters
    ----------
    full_scale_dps : float
        The gyro's full-scale rate FS, in °/s, within (0, 1e5].
    n_per_sign : int, default 6
        Number of rate magnitudes, each visited with both signs; an integer in [1, 50]. With 1
        the plan is ``±max_fraction·FS`` alone.
    min_fraction : float, default 0.01
        Smallest magnitude as a fraction of FS, in [1e-4, 1).
    max_fraction : float, default 1.0
        Largest magnitude as a fraction of FS, in (``min_fraction``, 1].

    Returns
    -------
    ndarray of float, shape (2·n_per_sign,)
        Table rates in °/s: ``[m₁, −m₁, m₂, −m₂, …]`` with increasing magnitudes mₖ, the
        last exactly ``max_fraction·FS``.

    Raises
    ------
    ValueError
        If ``full_scale_dps`` is outside (0, 1e5], ``n_per_sign`` not an integer in [1, 50],
        ``min_fraction`` outside [1e-4, 1) or ``max_fraction`` outside (``min_fraction``, 1].

    Examples
    --------
    >>> from bench.analysis.ratetable import rate_plan
    >>> rate_plan(100.0, 3).tolist()
    [1.0, -1.0, 10.0, -10.0, 100.0, -100.0]
    >>> rate_plan(500.0, 2, min_fraction=0.1, max_fraction=0.9).round(1).tolist()
    [50.0, -50.0, 450.0, -450.0]
    """
    _check_full_scale(full_scale_dps)
    if isinstance(n_per_sign, bool) or not isinstance(n_per_sign, (int, np.integer)) \
            or not 1 <= n_per_sign <= 50:
        raise ValueError(f"n_per_sign={n_per_sign!r} must be an integer in [1, 50]")
    if not (_real(min_fraction) and 1e-4 <= min_fraction < 1.0):
        raise ValueError(f"min_fraction={min_fraction!r} outside the allowed range [1e-4, 1)")
    if not (_real(max_fraction) and min_fraction < max_fraction <= 1.0):
        raise ValueError(f"max_fraction={max_fraction!r} outside the allowed range ({min_fraction}, 1]")
    top = max_fraction * full_scale_dps
    if n_per_sign == 1:
        mags = np.array([float(top)])
    else:
        mags = top * np.logspace(math.log10(min_fraction / max_fraction), 0.0, n_per_sign)
        mags[-1] = top  # exactly, not 10**0 rounded
    return np.column_stack([mags, -mags]).ravel()


def whole_revolution_duration_s(rate_dps: float, min_duration_s: float) -> float:
    """Shortest whole number (≥ 1) of revolutions at ``rate_dps`` lasting ≥ ``min_duration_s``, in s.

    Averaging the output over whole revolutions cancels the Earth rate's horizontal part and
    the table's wobble, which turn with the table.

    Parameters
    ----------
    rate_dps : float
        Table rate in °/s, finite and non-zero (either sign; its magnitude sets the period
        360/|rate| s).
    min_duration_s : float
        Shortest acceptable dwell, in s, within (0, 1e6].

    Returns
    -------
    float
        Duration of the dwell in s: n·360/|rate_dps| with n ≥ 1 the smallest whole number of
        revolutions that lasts at least ``min_duration_s``.

    Raises
    ------
    ValueError
        If ``rate_dps`` is zero or not finite, or ``min_duration_s`` is outside (0, 1e6].

    Examples
    --------
    >>> from bench.analysis.ratetable import whole_revolution_duration_s
    >>> whole_revolution_duration_s(10.0, 60.0)  # 36 s per revolution: two of them
    72.0
    >>> whole_revolution_duration_s(-100.0, 1.0)  # never less than one revolution
    3.6
    """
    if not (_real(rate_dps) and math.isfinite(rate_dps) and rate_dps != 0.0):
        raise ValueError(f"rate_dps={rate_dps!r} must be finite and non-zero")
    if not (_real(min_duration_s) and 0.0 < min_duration_s <= 1e6):
        raise ValueError(f"min_duration_s={min_duration_s!r} outside the allowed range (0, 1e6]")
    period = 360.0 / abs(rate_dps)
    n = max(1, math.ceil(min_duration_s / period))
    if n > 1 and (n - 1) * period >= min_duration_s:  # ceil overshot by a rounding error
        n -= 1
    return n * period


def _check_full_scale(full_scale_dps) -> None:
    if not (_real(full_scale_dps) and 0.0 < full_scale_dps <= 1e5):
        raise ValueError(f"full_scale_dps={full_scale_dps!r} outside the allowed range (0, 1e5]")


@dataclass(frozen=True, eq=False)
class RateTableResult:
    """Rate-table calibration of a gyro, as :func:`fit_rate_table` returns it.

    ``scale_factor`` and ``intercept`` in output units (per °/s); ppm figures of the nominal
    scale factor (``scale_factor_error_ppm``, ``asymmetry_ppm``) or of the full-scale output
    |SF·FS| (nonlinearity, residuals). ``line_covariance`` is that of (intercept,
    scale_factor). Residuals: output − LS line, per input rate. Every
    :class:`~bench.values.Estimate` carries its standard error in the same unit.

    Attributes
    ----------
    scale_factor : Estimate
        Slope SF of the weighted least-squares line ``output = SF·ω + b``, in output units
        per °/s.
    intercept : Estimate
        Intercept b of that line, in output units.
    bias_dph : Estimate
        Bias in °/h: ``3600·b/SF_nominal`` with b the intercept of the asymmetry fit
        ``output = b + S·ω + D·|ω|`` (module docstring).
    scale_factor_error_ppm : Estimate
        ``SF/SF_nominal − 1``, in ppm.
    nonlinearity_ppm : Estimate
        ``max_k |r_k| / |SF·FS|``, in ppm of the full-scale output; its std is that of the
        residual at the argmax (biased upward when near the noise, module docstring).
    nonlinearity_at_rate_dps : float
        Input rate, in °/s, of the largest residual.
    asymmetry_ppm : Estimate
        ``(SF+ − SF−)/SF_nominal``, in ppm, from half-lines sharing one bias.
    scale_factor_positive : Estimate
        Slope SF+ = S + D of the positive half-line, in output units per °/s.
    scale_factor_negative : Estimate
        Slope SF− = S − D of the negative half-line, in output units per °/s.
    input_rate_dps : ndarray, shape (m,)
        The input rates fitted, in °/s (Earth rate included).
    residuals : ndarray, shape (m,)
        Output − LS line at each input rate, in output units.
    residuals_ppm_fs : ndarray, shape (m,)
        The residuals in ppm of the full-scale output SF·FS (signed as SF·FS).
    residual_std_ppm_fs : ndarray, shape (m,)
        Standard uncertainty of each residual, from ``Cov(r) = Σ − X (XᵀΣ⁻¹X)⁻¹ Xᵀ``, in
        ppm of |SF·FS|.
    line_covariance : ndarray, shape (2, 2)
        Covariance of (intercept, scale_factor), in output units² (per °/s as they go).
    dof : int
        Degrees of freedom of the line fit, m − 2.
    full_scale_dps : float
        The full-scale rate FS used for the ppm-of-FS figures, in °/s.
    nominal_scale_factor : float
        Nominal scale factor, in output units per °/s.
    """

    scale_factor: Estimate
    intercept: Estimate
    bias_dph: Estimate
    scale_factor_error_ppm: Estimate
    nonlinearity_ppm: Estimate
    nonlinearity_at_rate_dps: float
    asymmetry_ppm: Estimate
    scale_factor_positive: Estimate
    scale_factor_negative: Estimate
    input_rate_dps: np.ndarray
    residuals: np.ndarray
    residuals_ppm_fs: np.ndarray
    residual_std_ppm_fs: np.ndarray
    line_covariance: np.ndarray
    dof: int
    full_scale_dps: float
    nominal_scale_factor: float

    def to_dict(self) -> dict:
        d = {name: getattr(self, name).to_dict() for name in (
            "scale_factor", "intercept", "bias_dph", "scale_factor_error_ppm", "nonlinearity_ppm",
            "asymmetry_ppm", "scale_factor_positive", "scale_factor_negative")}
        for name in ("input_rate_dps", "residuals", "residuals_ppm_fs", "residual_std_ppm_fs"):
            d[name] = [float(v) for v in getattr(self, name)]
        d["line_covariance"] = self.line_covariance.tolist()
        d["nonlinearity_at_rate_dps"] = float(self.nonlinearity_at_rate_dps)
        d["dof"] = int(self.dof)
        d["full_scale_dps"] = float(self.full_scale_dps)
        d["nominal_scale_factor"] = float(self.nominal_scale_factor)
        return d


def _wls(x: np.ndarray, y: np.ndarray, sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Weighted LS with absolute σ: coefficients and their covariance (XᵀΣ⁻¹X)⁻¹."""
    xw, yw = x / sigma[:, None], y / sigma
    norms = np.linalg.norm(xw, axis=0)
    u, s, vt = np.linalg.svd(xw / norms, full_matrices=False)  # unit columns: well scaled
    if s[-1] <= 1e-12 * s[0]:
        raise ValueError("input_rate_dps does not separate the fitted terms (singular design): "
                         "use at least two magnitudes of rate")
    beta = vt.T @ ((u.T @ yw) / s)
    beta = beta + vt.T @ ((u.T @ (yw - (xw / norms) @ beta)) / s)  # one refinement step
    cov = (vt.T / s**2) @ vt
    return beta / norms, cov / np.outer(norms, norms)


def _check_inputs(input_rate_dps, output, output_sigma, full_scale_dps, nominal_scale_factor):
    _check_full_scale(full_scale_dps)
    w = np.asarray(input_rate_dps, dtype=float)
    if w.ndim != 1 or w.size < 3 or not np.all(np.isfinite(w)):
        raise ValueError(f"input_rate_dps must be a finite 1-D array of ≥ 3 rates, got shape {w.shape}")
    limit = _FULL_SCALE_MARGIN * full_scale_dps
    if np.abs(w).max() > limit:
        raise ValueError(f"input_rate_dps={np.abs(w).max():.6g} beyond the allowed range "
                         f"[-{limit:.6g}, {limit:.6g}] (±1.01 full scale)")
    if not (np.any(w > 0) and np.any(w < 0)):
        raise ValueError("input_rate_dps must include positive and negative rates (asymmetry needs both)")
    y = np.asarray(output, dtype=float)
    if y.shape != w.shape or not np.all(np.isfinite(y)):
        raise ValueError(f"output must be finite with shape {w.shape}, got {y.shape}")
    sigma = np.asarray(output_sigma, dtype=float)
    if sigma.shape != w.shape or not np.all(np.isfinite(sigma)) or not np.all(sigma > 0):
        raise ValueError(f"output_sigma must be finite and > 0 with shape {w.shape}")
    if not (_real(nominal_scale_factor) and math.isfinite(nominal_scale_factor)
            and nominal_scale_factor != 0.0):
        raise ValueError(f"nominal_scale_factor={nominal_scale_factor!r} must be finite and non-zero")
    return w, y, sigma


def fit_rate_table(input_rate_dps, output, output_sigma, *, full_scale_dps: float,
                   nominal_scale_factor: float = 1.0) -> RateTableResult:
    """Scale factor, bias, nonlinearity and asymmetry from one mean output per input rate.

    ``input_rate_dps`` (m,): input rate along the IA in °/s, Earth rate included, within
    ±1.01·``full_scale_dps``; at least one positive and one negative. ``output`` (m,): mean
    indicated output in output units; ``output_sigma`` (m,): the standard error of each mean
    (> 0). ``nominal_scale_factor``: output units per °/s (1.0 when the output is already
    °/s through the nominal scale factor; the fitted SF must lie within a factor 2 of it).
    The method (IEEE Std 952 / 647) is described in the module docstring.

    Parameters
    ----------
    input_rate_dps : array_like, shape (m,)
        Input rate along the input axis at each point, in °/s: table rate plus the Earth
        rate's component (:func:`earth_rate_vertical_dps`). Finite, m ≥ 3, within
        [−1.01·FS, 1.01·FS], with at least one positive and one negative rate and at least two
        magnitudes.
    output : array_like, shape (m,)
        Mean indicated output at each rate (over whole revolutions), in output units.
    output_sigma : array_like, shape (m,)
        Standard error of each mean, in output units; finite and > 0.
    full_scale_dps : float
        The gyro's full-scale rate FS, in °/s, within (0, 1e5].
    nominal_scale_factor : float, default 1.0
        Nominal scale factor in output units per °/s, finite and non-zero; the fitted scale
        factor must lie within [0.5, 2] times it.

    Returns
    -------
    RateTableResult
        Scale factor and its error (ppm), bias (°/h), nonlinearity (ppm of FS), asymmetry
        (ppm), both half-line slopes, the residuals and the line's covariance.

    Raises
    ------
    ValueError
        If a rate lies outside ±1.01·``full_scale_dps``, the rates are fewer than 3, not finite
        or of one sign only, or cannot separate the fitted terms (a single magnitude);
        ``full_scale_dps`` is outside (0, 1e5]; ``output`` or ``output_sigma`` has the wrong
        shape, is not finite, or a sigma is ≤ 0; ``nominal_scale_factor`` is zero or not
        finite, or the fitted scale factor is outside [0.5, 2] times it.

    Examples
    --------
    A gyro with a 200 ppm scale-factor error and a 10 °/h bias, read in °/s through its
    nominal scale factor, on the plan of :func:`rate_plan` at 45° latitude:

    >>> import numpy as np
    >>> from bench.analysis.ratetable import earth_rate_vertical_dps, fit_rate_table, rate_plan
    >>> w = rate_plan(500.0, 4) + earth_rate_vertical_dps(45.0)
    >>> rng = np.random.default_rng(0)
    >>> y = 10.0 / 3600 + (1 + 200e-6) * w + 1e-4 * rng.standard_normal(w.size)
    >>> r = fit_rate_table(w, y, np.full(w.size, 1e-4), full_scale_dps=500.0)
    >>> round(r.scale_factor_error_ppm.value), round(r.bias_dph.value, 1), r.dof
    (200, 10.0, 6)
    >>> bool(abs(r.asymmetry_ppm.value) < 3 * r.asymmetry_ppm.std)  # none simulated
    True
    """
    w, y, sigma = _check_inputs(input_rate_dps, output, output_sigma, full_scale_dps, nominal_scale_factor)
    x = np.column_stack([np.ones_like(w), w])
    (b, sf), cov = _wls(x, y, sigma)
    ratio = sf / nominal_scale_factor
    if not 0.5 <= ratio <= 2.0:
        raise ValueError(f"nominal_scale_factor={nominal_scale_factor!r} is {1 / ratio:.3g} times the fitted "
                         f"scale factor {sf:.6g}: allowed ratio [0.5, 2]; pass output units per °/s")
    sf_std = math.sqrt(cov[1, 1])
    nominal_abs = abs(nominal_scale_factor)
    fs_out = abs(sf * full_scale_dps)
    resid = y - x @ np.array([b, sf])
    resid_var = sigma**2 - np.einsum("ij,jk,ik->i", x, cov, x)  # diag of Σ − X C Xᵀ
    resid_std = np.sqrt(np.clip(resid_var, 0.0, None))
    k = int(np.argmax(np.abs(resid)))
    nonlin = Estimate(float(_PPM * abs(resid[k]) / fs_out), float(_PPM * resid_std[k] / fs_out))
    (b3, s, d), cov3 = _wls(np.column_stack([np.ones_like(w), w, np.abs(w)]), y, sigma)
    # The bias is the intercept of the model with the asymmetry term: a plain line would take
    # the mean of (A/2)|ω| over the plan into its intercept (≈ 10 °/h for 50 ppm at 500 °/s).
    bias = Estimate(float(3600.0 * b3 / nominal_scale_factor), 3600.0 * math.sqrt(cov3[0, 0]) / nominal_abs)

    def half_line(sign: float) -> Estimate:
        return Estimate(float(s + sign * d), float(math.sqrt(cov3[1, 1] + cov3[2, 2] + 2 * sign * cov3[1, 2])))

    return RateTableResult(
        scale_factor=Estimate(float(sf), sf_std), intercept=Estimate(float(b), float(math.sqrt(cov[0, 0]))),
        bias_dph=bias,
        scale_factor_error_ppm=Estimate(float(_PPM * (ratio - 1.0)), _PPM * sf_std / nominal_abs),
        nonlinearity_ppm=nonlin, nonlinearity_at_rate_dps=float(w[k]),
        asymmetry_ppm=Estimate(float(_PPM * 2.0 * d / nominal_scale_factor),
                               _PPM * 2.0 * math.sqrt(cov3[2, 2]) / nominal_abs),
        scale_factor_positive=half_line(1.0), scale_factor_negative=half_line(-1.0),
        input_rate_dps=w, residuals=resid, residuals_ppm_fs=_PPM * resid / (sf * full_scale_dps),
        residual_std_ppm_fs=_PPM * resid_std / fs_out, line_covariance=cov, dof=w.size - 2,
        full_scale_dps=float(full_scale_dps), nominal_scale_factor=float(nominal_scale_factor))
