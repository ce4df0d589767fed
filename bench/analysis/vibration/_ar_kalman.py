"""AR-based Kalman fit of one IMF (Document C, step 4).

State-space form of a zero-mean AR(p) ``x_n = Σ φ_k x_{n-k} + a_n`` (companion form)::

    X_n = Φ X_{n-1} + G a_n,    X_n = [x_n, x_{n-1}, …, x_{n-p+1}]ᵀ,  G = e₁
    z_n = H X_n + v_n,          H = e₁ᵀ

with ``Φ`` the companion matrix (first row ``φ``, ones on the sub-diagonal),
``Q = σ_a² G Gᵀ`` from the AR innovation variance, and ``R`` the variance of the
measurement noise ``v`` (see below).  Document C starts the filter with ``P0 = I`` and
``X0`` = the first ``p`` samples: the state at sample ``p − 1`` is
``[z_{p-1}, …, z_0]`` and filtering starts at sample ``p``.

Two fits of the IMF are compared, both from sample ``p`` on:

* **AR fit** — the one-step prediction from past samples, ``ẑ_n = Σ φ_k z_{n-k}``; its
  error is the AR residual ``a_n``.
* **AR + Kalman fit** — the filtered estimate ``x̂_{n|n}`` (first state component).
  It uses the sample ``z_n`` itself: ``z_n − x̂_{n|n} = (1 − K₁)(z_n − x̂_{n|n-1})``, so its
  error is the innovation scaled by ``1 − K₁`` (``K₁`` the gain's first component).  It is
  the minimum-variance estimate of the AR process under measurement noise of variance R,
  a smoother description of the data — not a better predictor.

**R**: Document C does not give it.  By default ``R = r_ratio · σ_a²`` with
``r_ratio = 1`` — the measurement is trusted as much as the model's one-step
prediction; on data like Document C's this gives an error std of about 0.4–0.5 of the
AR fit's, their published 0.44.  ``R → 0`` makes the fit reproduce the data (error 0),
``R → ∞`` turns it into the AR prediction.  A measured sensor noise variance can be
passed instead (``measurement_var``).

**Speed**: the gain does not depend on the data.  The filter runs the exact
time-varying recursion until the gain settles (``max |K_n − K_{n-1}| ≤ gain_tol·max |K_n|``,
at most ``max_transient`` samples), then the steady-state filter as one IIR filter:
the innovations of the steady filter are ``e = [a(B)/c(B)] z`` with ``a`` the AR
polynomial and ``c`` the characteristic polynomial of ``Φ(I − K H)``, started from the
exact filter state by matching the first ``p`` samples of the free response.  With
``steady_state=False`` the exact recursion runs over every sample (slow; for tests).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.signal import lfilter


def companion(ar: np.ndarray) -> np.ndarray:
    """Companion matrix of ``x_n = Σ φ_k x_{n-k}``: first row ``φ``, ones below the diagonal."""
    ar = np.asarray(ar, dtype=float)
    p = ar.size
    phi = np.zeros((p, p))
    phi[0] = ar
    phi[np.arange(1, p), np.arange(p - 1)] = 1.0
    return phi


def ar_predict(z: np.ndarray, ar: npt.ArrayLike, mean: float = 0.0) -> np.ndarray:
    """One-step AR prediction ``mean + Σ φ_k (z_{n-k} − mean)``; samples ``n < p`` are returned as ``z``."""
    z = np.asarray(z, dtype=float)
    ar = np.asarray(ar, dtype=float)
    p = ar.size
    out = lfilter(np.r_[0.0, ar], [1.0], z - mean) + mean
    out[:p] = z[:p]
    return out


@dataclass(frozen=True, eq=False)
class KalmanFit:
    """Filtered estimate of one IMF and how the filter ran.

    Returned by :func:`kalman_ar_fit`.

    Attributes
    ----------
    filtered : ndarray of float, shape (n,)
        ``x̂_{n|n}`` + mean, in the unit of the series; samples ``n < p`` are the initial
        state (the data).
    gain : ndarray of float, shape (p,)
        Kalman gain K (filtered form) at the last exact step: the steady-state gain once it
        has settled (dimensionless).
    steady_from : int
        First sample filtered with the frozen gain (``n`` if never).
    q : float
        Process noise variance σ_a², in (unit)².
    r : float
        Measurement noise variance R used, in (unit)².
    p : int
        AR order.
    """

    filtered: np.ndarray  # x̂_{n|n} + mean; samples n < p are the initial state (the data)
    gain: np.ndarray  # steady-state gain K (filtered form), length p
    steady_from: int  # first sample filtered with the frozen gain (= n if never)
    q: float  # σ_a², process noise variance
    r: float  # measurement noise variance used
    p: int


def kalman_ar_fit(z: np.ndarray, ar: npt.ArrayLike, sigma2: float, *, r: float | None = None,
                  r_ratio: float = 1.0, mean: float | None = None, p0: float = 1.0, gain_tol: float = 1e-13,
                  max_transient: int = 200_000, steady_state: bool = True) -> KalmanFit:
    """Kalman-filter ``z`` with the AR(p) model ``ar``, ``sigma2`` (module docstring).

    ``r`` (the measurement noise variance, units²) defaults to ``r_ratio · sigma2``;
    ``mean`` (default: the sample mean) is removed first and added back; ``P0 = p0·I``.

    Companion-form state space ``X_n = Φ X_{n-1} + G a_n``, ``z_n = H X_n + v_n`` with
    ``Q = σ_a² G Gᵀ`` and ``R = r``; the filter starts at sample ``p`` from
    ``X0 = [z_{p-1}, …, z_0]``.  Its error ``z_n − x̂_{n|n}`` is the innovation scaled by
    ``1 − K₁``: a smoother description of the data, not a better predictor.  Once the gain
    settles the steady-state filter runs as one IIR filter.

    Parameters
    ----------
    z : array_like of float, shape (n,)
        The IMF (or any series), uniformly sampled, in any unit; n > p.
    ar : array_like of float, shape (p,)
        AR coefficients φ1..φp of ``x_n = Σ φ_k x_{n-k} + a_n``, p ≥ 1.
    sigma2 : float
        Innovation variance σ_a² of ``a_n``, in (unit)², > 0.
    r : float, optional
        Measurement noise variance R in (unit)², > 0; default ``r_ratio · sigma2``.
    r_ratio : float, default 1.0
        ``R / σ_a²`` when ``r`` is not given.
    mean : float, optional
        Level removed before filtering and added back, in the unit of ``z``; default the
        sample mean.
    p0 : float, default 1.0
        Initial state covariance ``P0 = p0·I``, in (unit)².
    gain_tol : float, default 1e-13
        The gain counts as settled when ``max |K_n − K_{n-1}| ≤ gain_tol·max |K_n|``.
    max_transient : int, default 200000
        Largest number of samples run with the exact time-varying recursion.
    steady_state : bool, default True
        Switch to the steady-state filter once the gain settles; False runs the exact
        recursion over every sample (slow; for tests).

    Returns
    -------
    KalmanFit
        The filtered estimate in the unit of ``z``, the gain, where it froze, Q and R.

    Raises
    ------
    ValueError
        If the AR order is < 1 or not below the number of samples, ``sigma2`` is not > 0,
        or R (given or ``r_ratio · sigma2``) is not > 0.

    Examples
    --------
    An AR(1) series (φ = 0.6, σ_a² = 1): the filtered estimate's error is ``1 − K₁`` of the
    innovation, about half the AR prediction error:

    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from bench.analysis.vibration import kalman_ar_fit
    >>> z = lfilter([1.0], [1.0, -0.6], np.random.default_rng(0).normal(size=2000))
    >>> k = kalman_ar_fit(z, [0.6], 1.0)
    >>> k.p, k.r, round(float(k.gain[0]), 3), k.steady_from
    (1, 1.0, 0.545, 14)
    >>> round(float(np.std(z[1:] - k.filtered[1:])), 2)  # ≈ (1 − K₁)·σ_a
    0.47
    """
    z = np.asarray(z, dtype=float)
    ar = np.asarray(ar, dtype=float)
    p, n = ar.size, z.size
    if p < 1 or n <= p:
        raise ValueError(f"need an AR order ≥ 1 and more samples than it, got p = {p}, n = {n}")
    if not sigma2 > 0:
        raise ValueError(f"sigma2 = {sigma2!r} must be > 0")
    r = r_ratio * sigma2 if r is None else r
    if not r > 0:
        raise ValueError(f"the measurement noise variance R = {r!r} must be > 0")
    mu = float(z.mean()) if mean is None else float(mean)
    x = z - mu
    phi = companion(ar)
    q = float(sigma2)
    state = x[p - 1 :: -1][:p].copy()  # X0 = the first p samples, newest first
    cov = p0 * np.eye(p)
    out = np.empty(n)
    out[:p] = x[:p]
    gain = np.zeros(p)
    k = p
    limit = n if not steady_state else min(n, p + max_transient)
    while k < limit:
        pred = phi @ state
        cov = phi @ cov @ phi.T
        cov[0, 0] += q
        new_gain = cov[:, 0] / (cov[0, 0] + r)
        state = pred + new_gain * (x[k] - pred[0])
        cov = cov - np.outer(new_gain, cov[0])
        cov = 0.5 * (cov + cov.T)  # keep it symmetric against rounding
        out[k] = state[0]
        k += 1
        settled = np.max(np.abs(new_gain - gain)) <= gain_tol * np.max(np.abs(new_gain))
        gain = new_gain
        if steady_state and settled:
            break
    if k < n:
        out[k:] = _steady_filter(x[k:], phi, ar, gain, phi @ state)
    out += mu
    out[:p] = z[:p]  # the initial state is the data itself, exactly
    return KalmanFit(out, gain, k, q, float(r), p)


def _steady_filter(x: np.ndarray, phi: np.ndarray, ar: np.ndarray, gain: np.ndarray,
                   pred0: np.ndarray) -> np.ndarray:
    """Filtered first component ``x − (1 − K₁) e`` with ``e = [a(B)/c(B)] x`` from predicted state ``pred0``."""
    p = ar.size
    a_poly = np.r_[1.0, -ar]
    closed = phi - np.outer(phi @ gain, np.eye(p)[0])  # Φ(I − K H)
    c_poly = np.real(np.poly(closed))
    # initial conditions: the free response of lfilter must equal the filter's own,
    # e_j = −H A^j s0 (A = closed loop), over p samples (then for ever: same recursion)
    free = np.empty(p)
    s = pred0.copy()
    for j in range(p):
        free[j] = -s[0]
        s = closed @ s
    basis = np.column_stack([lfilter(a_poly, c_poly, np.zeros(p), zi=np.eye(p)[i])[0] for i in range(p)])
    zi = np.linalg.solve(basis, free)
    e, _ = lfilter(a_poly, c_poly, x, zi=zi)
    return x - (1.0 - gain[0]) * e
