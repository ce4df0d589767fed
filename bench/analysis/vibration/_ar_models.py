"""Per-IMF tests and AR models for Document C, steps 2–3.

For one IMF (any zero-mean-ish stationary series) :func:`model_imf` returns an
:class:`ImfModel` with:

* **Stationarity**: augmented Dickey–Fuller (H0 unit root; constant, ``adf_lags``
  lagged differences, p-value from MacKinnon's surface via statsmodels' ``mackinnonp``)
  and KPSS (H0 level-stationary; Newey–West long-run variance with the Hobijn et al.
  bandwidth, p-value interpolated in Kwiatkowski et al.'s table, so it is clipped to
  [0.01, 0.10]).  Both equal statsmodels' ``adfuller(…, autolag=None)`` and
  ``kpss(…, nlags="auto")`` (the tests pin this) but run in O(n log n): statsmodels
  needs seconds per IMF at 3.5·10⁵ samples (KPSS picks thousands of lags there).
  ``stationary`` = ADF rejects and KPSS does not, both at ``alpha``.
* **Whiteness** of the IMF itself: Ljung–Box p-value over ``lb_lags`` lags and the
  autocorrelation criterion (the share of ``|r_k|``, k = 1..``lb_lags``, outside
  ``±z/√N``; white when that share is at most ``alpha``).  Document C needs non-white IMFs.
* **Identification** from the ACF/PACF cut-off/tail-off table
  (:func:`bench.analysis.timeseries._fit.identify`); Document C models every IMF as AR and
  so do we — the identified class is reported.
* **Order**: AIC and BIC of Yule–Walker AR(p), p = 1..``p_max``, every order scored by
  the conditional Gaussian likelihood on the same samples (``t ≥ p_max``); the model
  uses ``criterion``'s order.
* **Estimates**: Yule–Walker (method of moments, biased autocovariances — statsmodels'
  ``yule_walker(method="mle")``), innovation variance ``sigma2``.
* **Adequacy**: the residuals ``a_n = x_n − Σ φ_k x_{n-k}`` must be white — Ljung–Box
  p-value with ``p`` degrees of freedom removed, and the autocorrelation criterion.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import fft as sp_fft
from scipy import stats
from statsmodels.tsa.adfvalues import mackinnonp

import bench.analysis.timeseries._fit as ts

KPSS_CRIT = (0.347, 0.463, 0.574, 0.739)  # Kwiatkowski et al. (1992) Table 1, level stationarity
KPSS_P = (0.10, 0.05, 0.025, 0.01)


@dataclass(frozen=True)
class StationarityTest:
    """A stationarity test's result: its statistic, p-value and the lags it used.

    The ``adf`` (augmented Dickey–Fuller, H0 unit root) and ``kpss`` (KPSS, H0
    level-stationary; p-value clipped to [0.01, 0.10]) fields of an :class:`ImfModel`.

    Attributes
    ----------
    statistic : float
        The test statistic (dimensionless).
    p_value : float
        Its p-value under the test's null hypothesis.
    lags : int
        Lagged differences (ADF) or Newey–West lags (KPSS) used.
    """

    statistic: float
    p_value: float
    lags: int


def _autocov_sums(xd: np.ndarray, maxlag: int) -> np.ndarray:
    """``sum_t xd[t] xd[t-k]`` for k = 0..maxlag, by FFT (exact up to rounding)."""
    n = xd.size
    nfft = sp_fft.next_fast_len(2 * n - 1, real=True)
    spec = sp_fft.rfft(xd, nfft)
    return sp_fft.irfft(spec.real**2 + spec.imag**2, nfft)[: maxlag + 1]


def kpss_level(x: np.ndarray) -> StationarityTest:
    """KPSS test of level stationarity, as statsmodels ``kpss(x, "c", nlags="auto")``."""
    x = np.asarray(x, dtype=float)
    n = x.size
    e = x - x.mean()
    sums = _autocov_sums(e, n - 1)
    covlags = int(np.power(n, 2.0 / 9.0))  # Hobijn et al. (1998) bandwidth selection
    k = np.arange(1, covlags + 1)
    prod = sums[1 : covlags + 1] / (n / 2.0)
    s0 = sums[0] / n + prod.sum()
    s1 = float(k @ prod)
    gamma = 1.1447 * np.power((s1 / s0) ** 2, 1.0 / 3.0)
    lags = min(int(gamma * np.power(n, 1.0 / 3.0)), n - 1)
    i = np.arange(1, lags + 1)
    s_hat = (sums[0] + 2.0 * float(sums[1 : lags + 1] @ (1.0 - i / (lags + 1.0)))) / n
    eta = float(np.sum(np.cumsum(e) ** 2)) / n**2
    stat = eta / s_hat
    return StationarityTest(float(stat), float(np.interp(stat, KPSS_CRIT, KPSS_P)), lags)


def adf_constant(x: np.ndarray, lags: int) -> StationarityTest:
    """Augmented Dickey–Fuller with a constant and ``lags`` lagged differences, as
    statsmodels ``adfuller(x, maxlag=lags, autolag=None, regression="c")``."""
    x = np.asarray(x, dtype=float)
    dx = np.diff(x)
    m = dx.size - lags  # regression rows: Δx_t for t = lags+1 .. n-1
    if m < 3 * (lags + 2):
        raise ValueError(f"{x.size} samples are too few for an ADF test with {lags} lags")
    cols = [np.ones(m), x[lags : lags + m]] + [dx[lags - j : lags - j + m] for j in range(1, lags + 1)]
    xmat = np.column_stack(cols)
    y = dx[lags:]
    scale = np.sqrt(np.einsum("ij,ij->j", xmat, xmat))
    xs = xmat / scale  # equilibrated normal equations
    gram = xs.T @ xs
    beta = np.linalg.solve(gram, xs.T @ y)
    resid = y - xs @ beta
    sigma2 = float(resid @ resid) / (m - xmat.shape[1])
    se = np.sqrt(sigma2 * np.linalg.inv(gram)[1, 1])
    stat = float(beta[1] / se)
    return StationarityTest(stat, float(mackinnonp(stat, regression="c", N=1)), lags)


@dataclass(frozen=True)
class Whiteness:
    """Ljung–Box p-value and the autocorrelation criterion over ``lags`` lags.

    The ``imf_white`` (the IMF itself) and ``residual_white`` (its AR residuals) fields of an
    :class:`ImfModel` (module docstring).

    Attributes
    ----------
    ljung_box_p : float
        Ljung–Box p-value over ``lags`` lags (model degrees of freedom removed for residuals).
    acf_outside : float
        Share of the autocorrelations ``|r_k|``, k = 1..``lags``, outside ``±z/√N``, in [0, 1].
    lags : int
        Lags tested.
    white : bool
        The autocorrelation criterion: ``acf_outside`` is at most ``alpha``.
    """

    ljung_box_p: float
    acf_outside: float  # share of |r_k| beyond z/√N
    lags: int
    white: bool


def whiteness(x: np.ndarray, lags: int, model_df: int = 0, alpha: float = 0.05) -> Whiteness:
    """Whiteness of ``x`` (residuals of a model with ``model_df`` parameters, or a raw series)."""
    n = np.asarray(x).size
    r = ts.sample_acf(x, lags)
    lb = ts.ljung_box(x, lags, model_df, _acf=r)
    band = stats.norm.ppf(1 - alpha / 2) / np.sqrt(n)
    outside = float(np.mean(np.abs(r[1:]) > band))
    return Whiteness(lb.p_value, outside, lags, outside <= alpha)


@dataclass(frozen=True, eq=False)
class ImfModel:
    """Tests, order selection and the Yule–Walker AR model of one IMF (module docstring).

    Returned by :func:`model_imf`.

    Attributes
    ----------
    index : int
        IMF number, 1 = fastest.
    n : int
        Number of samples.
    mean : float
        Sample mean of the IMF, in its unit.
    std : float
        Sample standard deviation of the IMF, in its unit.
    adf : StationarityTest
        Augmented Dickey–Fuller test (H0 unit root): ``statistic``, ``p_value``, ``lags``.
    kpss : StationarityTest
        KPSS test (H0 level-stationary); its p-value is clipped to [0.01, 0.10].
    stationary : bool
        ADF rejects and KPSS does not, both at ``alpha``.
    imf_white : Whiteness
        Whiteness of the IMF itself: Ljung–Box p-value, share of ACF lags outside ``±z/√N``, verdict.
    identified : {"AR", "MA", "ARMA"}
        Class proposed by the ACF/PACF table (the model is AR regardless).
    identification_reason : str
        Why, in words.
    orders : tuple of int
        AR orders scored, 1..p_max.
    aic : tuple of float
        AIC of each order (conditional likelihood on samples ``t ≥ p_max``).
    bic : tuple of float
        BIC of each order.
    aic_order : int
        Order with the smallest AIC.
    bic_order : int
        Order with the smallest BIC.
    criterion : {"aic", "bic"}
        Criterion whose order the model uses.
    ar : tuple of float
        φ1..φp (Yule–Walker): ``x_n = Σ φ_k x_{n-k} + a_n`` with the mean removed.
    sigma2 : float
        Innovation variance of ``a_n``, in (unit)².
    residual_white : Whiteness
        Whiteness of the AR residuals (``p`` dof removed from Ljung–Box).
    p : int
        Property: AR order.
    """

    index: int  # IMF number, 1 = fastest
    n: int
    mean: float
    std: float
    adf: StationarityTest
    kpss: StationarityTest
    stationary: bool
    imf_white: Whiteness
    identified: str  # "AR" | "MA" | "ARMA" from the ACF/PACF table
    identification_reason: str
    orders: tuple[int, ...]  # 1..p_max
    aic: tuple[float, ...]
    bic: tuple[float, ...]
    aic_order: int
    bic_order: int
    criterion: str
    ar: tuple[float, ...]  # φ1..φp: x_n = Σ φ_k x_{n-k} + a_n (mean removed)
    sigma2: float  # innovation variance of a_n, (units)²
    residual_white: Whiteness

    @property
    def p(self) -> int:
        """AR order of the model."""
        return len(self.ar)

    def to_dict(self) -> dict:
        """JSON-ready summary: model, test statistics and p-values, order table."""
        return {
            "index": self.index, "p": self.p, "ar": list(self.ar), "sigma2": self.sigma2,
            "mean": self.mean, "std": self.std,
            "white_residual_p": self.residual_white.ljung_box_p,
            "residual_acf_outside": self.residual_white.acf_outside,
            "stationary_p": self.adf.p_value, "kpss_p": self.kpss.p_value, "stationary": self.stationary,
            "adf_statistic": self.adf.statistic, "kpss_statistic": self.kpss.statistic,
            "white_p": self.imf_white.ljung_box_p, "acf_outside": self.imf_white.acf_outside,
            "white": self.imf_white.white, "identified": self.identified,
            "identification": self.identification_reason,
            "aic_order": self.aic_order, "bic_order": self.bic_order, "criterion": self.criterion,
            "orders": list(self.orders), "aic": list(self.aic), "bic": list(self.bic),
        }


def model_imf(x: np.ndarray, index: int = 1, *, p_max: int = 15, criterion: str = "bic",
              lb_lags: int = 20, alpha: float = 0.05) -> ImfModel:
    """Test and model one IMF (module docstring); ``x`` in any unit, uniformly sampled.

    ADF (``p_max`` lags) and KPSS stationarity tests, Ljung–Box and autocorrelation
    whiteness of the IMF, ACF/PACF identification, AIC/BIC of Yule–Walker AR(1..p_max) on
    common samples, the Yule–Walker model at ``criterion``'s order, and the whiteness of
    its residuals.

    Parameters
    ----------
    x : array_like of float, shape (n,)
        The IMF (or any stationary series), uniformly sampled, in any unit;
        n ≥ ``max(10·p_max, 5·lb_lags, 64)``.
    index : int, default 1
        IMF number, for labels and messages.
    p_max : int, default 15
        Largest AR order scored, an integer ≥ 1.
    criterion : {"aic", "bic"}, default "bic"
        Criterion that picks the model order.
    lb_lags : int, default 20
        Lags of the IMF's whiteness test.
    alpha : float, default 0.05
        Significance level of every test, in (0, 1).

    Returns
    -------
    ImfModel
        Tests, order table and the AR model (``ar``, ``sigma2`` in (unit)²).

    Raises
    ------
    ValueError
        If ``criterion`` is not ``"aic"`` or ``"bic"``, ``p_max`` is not an integer ≥ 1, or
        the IMF has fewer than ``max(10·p_max, 5·lb_lags, 64)`` samples.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from bench.analysis.vibration import model_imf
    >>> x = lfilter([1.0], [1.0, -0.5, 0.3], np.random.default_rng(0).normal(size=2000))  # AR(2)
    >>> m = model_imf(x, p_max=5)
    >>> m.p, m.identified, m.stationary, m.imf_white.white
    (2, 'AR', True, False)
    >>> m.residual_white.ljung_box_p > 0.05, m.residual_white.white
    (True, True)
    >>> [round(c, 1) for c in m.ar], round(m.sigma2, 1)  # true (0.5, -0.3), 1
    ([0.5, -0.3], 1.0)
    """
    x = np.asarray(x, dtype=float)
    if criterion not in ("aic", "bic"):
        raise ValueError(f"criterion = {criterion!r} must be 'aic' or 'bic'")
    if int(p_max) != p_max or p_max < 1:
        raise ValueError(f"p_max = {p_max!r} must be an integer ≥ 1")
    n = x.size
    if n < max(10 * p_max, 5 * lb_lags, 64):
        raise ValueError(f"IMF{index} has {n} samples; at least {max(10 * p_max, 5 * lb_lags, 64)} are "
                         f"needed for p_max = {p_max} and {lb_lags} test lags")
    adf = adf_constant(x, p_max)
    kp = kpss_level(x)
    stationary = adf.p_value < alpha and kp.p_value > alpha
    imf_white = whiteness(x, lb_lags, 0, alpha)
    ident = ts.identify(ts.correlogram(x, alpha=alpha), max_order=p_max)
    sel = ts.select_order(x, "AR", p_max, ar_method="yule-walker")
    cells = [c for c in sel.candidates if c.p >= 1]  # Document C: orders 1..p_max
    aic = tuple(c.aic for c in cells)
    bic = tuple(c.bic for c in cells)
    aic_order = cells[int(np.argmin(aic))].p
    bic_order = cells[int(np.argmin(bic))].p
    p = bic_order if criterion == "bic" else aic_order
    fit = ts.fit_ar(x, p, method="yule-walker")
    resid_white = whiteness(fit.residuals, ts.default_lb_lags(fit.residuals.size, p), p, alpha)
    return ImfModel(index, n, float(x.mean()), float(x.std()), adf, kp, bool(stationary), imf_white,
                    ident.kind, ident.reason, tuple(c.p for c in cells), aic, bic, aic_order, bic_order,
                    criterion, fit.ar, float(fit.sigma2), resid_white)
