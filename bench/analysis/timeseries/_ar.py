"""Autoregressive estimators for :mod:`bench.analysis.timeseries._fit`.

This module holds the AR(p) coefficient estimators — Ulrych–Clayton (forward–backward
least squares), Burg and Yule–Walker — with the helpers that compute every order
``0..pmax`` of one estimator in a single pass (``burg_path``, ``ar_path``), the
O(n·p) lag-product sums they share with the likelihood code (``lag_sums``), and the
two-sided AR interpolator of missing samples (:func:`ar_interpolate`).  Each returns
plain coefficient arrays and an innovation variance; model objects, likelihoods and
order selection live in :mod:`bench.analysis.timeseries._fit`, which re-exports every public
name here.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from bench.analysis.timeseries._acf import as_series, check_order, levinson_durbin

ArMethod = Literal["ulrych-clayton", "burg", "yule-walker"]
AR_METHODS: tuple[ArMethod, ...] = ("ulrych-clayton", "burg", "yule-walker")

def _full_lag_sums(x: np.ndarray, size: int) -> np.ndarray:
    """``full[d] = sum_{s=d}^{n-1} x[s] x[s-d]`` for ``d = 0..size-1``."""
    return np.array([x[d:] @ x[: x.size - d] for d in range(size)])


def lag_sums(x: np.ndarray, start: int, size: int, full: np.ndarray | None = None) -> np.ndarray:
    """``F[i, j] = sum_{t=start}^{n-1} x[t-i] x[t-j]`` for ``0 ≤ i, j < size ≤ start + 1``.

    One full-length dot product per lag difference (``full``, reusable across calls),
    then exact corrections at the ends: O(n·size) instead of the O(n·size²) of forming
    the lagged data matrix.
    """
    n = x.size
    full = _full_lag_sums(x, size) if full is None else full
    out = np.empty((size, size))
    for i in range(size):
        for j in range(i, size):
            d = j - i  # s = t - i runs over [start - i, n - 1 - i]; full[d] over [d, n - 1]
            head = x[d : start - i] @ x[: start - i - d]
            tail = x[n - i :] @ x[n - i - d : n - d]
            out[i, j] = out[j, i] = full[d] - head - tail
    return out


def ulrych_clayton(x: np.ndarray, p: int, _full: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """AR(p) by the Ulrych–Clayton (forward–backward least squares, modified covariance) method.

    Minimises ``sum_{t=p}^{n-1} [(x_t - Σ φ_k x_{t-k})² + (x_{t-p} - Σ φ_k x_{t-p+k})²]``
    over ``φ``: the forward and the time-reversed (backward) prediction errors share one
    coefficient vector.  Returns ``(phi, sigma2)`` with ``sigma2`` the mean of the ``2(n-p)``
    squared errors.  Stationarity is not guaranteed (unlike Burg/Yule–Walker).

    Parameters
    ----------
    x : array_like of float, shape (n,)
        The series, in any unit ``u``; finite, not constant; the sample mean is removed first.
    p : int
        AR order, a non-negative integer ≤ ``n // 10`` (10 samples per coefficient).
    _full : ndarray, optional
        Internal: precomputed lag sums of the demeaned series, shared when fitting every order.

    Returns
    -------
    phi : ndarray of float, shape (p,)
        AR coefficients φ1..φp of ``x_k = Σ φ_i x_{k−i} + e_k`` (dimensionless).
    sigma2 : float
        Innovation variance estimate, in ``u²``.

    Raises
    ------
    ValueError
        If ``x`` is not 1-D, has fewer than 2 samples, a non-finite value or is constant, or
        ``p`` is not a non-negative integer ≤ ``n // 10``.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> x = lfilter([1.0], [1.0, -0.6], np.random.default_rng(0).normal(size=5000))  # AR(1), φ = 0.6, σ² = 1
    >>> from bench.analysis.timeseries import ulrych_clayton
    >>> phi, sigma2 = ulrych_clayton(x, 1)
    >>> round(float(phi[0]), 2), round(sigma2, 2)
    (0.6, 0.99)
    """
    xd = as_series(x, 2)
    p = check_order(p, xd.size)
    if p == 0:
        return np.zeros(0), float(xd @ xd / xd.size)
    f = lag_sums(xd, p, p + 1, _full)
    c = f + f[::-1, ::-1]  # backward errors: indices mirrored, w_i x_{t-p+i}
    phi = np.linalg.solve(c[1:, 1:], c[1:, 0])
    w = np.concatenate([[1.0], -phi])
    return phi, float(w @ c @ w / (2 * (xd.size - p)))


def burg(x: np.ndarray, p: int) -> tuple[np.ndarray, float]:
    """AR(p) by Burg's method; ``sigma2`` is the mean squared forward–backward error.

    Each order's reflection coefficient ``κ_k = 2 Σ f b / (Σ f² + Σ b²)`` minimises the
    forward plus backward prediction error power, so |κ_k| ≤ 1 and the model is always
    stationary.

    Parameters
    ----------
    x : array_like of float, shape (n,)
        The series, in any unit ``u``; finite, not constant; the sample mean is removed first.
    p : int
        AR order, a non-negative integer ≤ ``n // 10`` (10 samples per coefficient).

    Returns
    -------
    phi : ndarray of float, shape (p,)
        AR coefficients φ1..φp of ``x_k = Σ φ_i x_{k−i} + e_k`` (dimensionless).
    sigma2 : float
        Innovation variance estimate, in ``u²``.

    Raises
    ------
    ValueError
        If ``x`` is not 1-D, has fewer than 2 samples, a non-finite value or is constant, or
        ``p`` is not a non-negative integer ≤ ``n // 10``.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> x = lfilter([1.0], [1.0, -0.6], np.random.default_rng(0).normal(size=5000))  # AR(1), φ = 0.6, σ² = 1
    >>> from bench.analysis.timeseries import burg
    >>> phi, sigma2 = burg(x, 2)
    >>> phi.round(2).tolist(), round(sigma2, 2)
    ([0.6, 0.0], 0.99)
    """
    phi, sigma2 = burg_path(as_series(x, 2), check_order(p, np.asarray(x).size))
    return phi[-1], float(sigma2[-1])


def burg_path(xd: np.ndarray, pmax: int) -> tuple[list[np.ndarray], np.ndarray]:
    """Burg recursion returning the AR coefficients and ``sigma2`` of every order 0..pmax."""
    f, b, old_f, step = xd.copy(), xd.copy(), np.empty_like(xd), np.empty_like(xd)
    phis, sig = [np.zeros(0)], [xd @ xd / xd.size]
    for k in range(1, pmax + 1):
        # f_{k-1}(t) and b_{k-1}(t-1), t = k..n-1, updated in place (views of shrinking
        # length): the same arithmetic as fresh arrays, without 10⁶-sample allocations
        f, b = f[1:], b[:-1]
        m = f.size
        kappa = 2 * (f @ b) / (f @ f + b @ b)
        np.copyto(old_f[:m], f)
        f -= np.multiply(b, kappa, out=step[:m])
        b -= np.multiply(old_f[:m], kappa, out=step[:m])
        phis.append(np.concatenate([phis[-1] - kappa * phis[-1][::-1], [kappa]]))
        sig.append((f @ f + b @ b) / (2 * (xd.size - k)))
    return phis, np.array(sig)


def yule_walker(x: np.ndarray, p: int) -> tuple[np.ndarray, float]:
    """AR(p) by Yule–Walker (method of moments) on the biased autocovariances.

    Solves ``Γ_p φ = γ`` (Toeplitz, biased autocovariances) by Levinson–Durbin; the biased
    estimates keep ``Γ_p`` positive definite, so the model is stationary.

    Parameters
    ----------
    x : array_like of float, shape (n,)
        The series, in any unit ``u``; finite, not constant; the sample mean is removed first.
    p : int
        AR order, a non-negative integer ≤ ``n // 10`` (10 samples per coefficient).

    Returns
    -------
    phi : ndarray of float, shape (p,)
        AR coefficients φ1..φp of ``x_k = Σ φ_i x_{k−i} + e_k`` (dimensionless).
    sigma2 : float
        Innovation variance estimate, in ``u²``.

    Raises
    ------
    ValueError
        If ``x`` is not 1-D, has fewer than 2 samples, a non-finite value or is constant, or
        ``p`` is not a non-negative integer ≤ ``n // 10``.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> x = lfilter([1.0], [1.0, -0.6], np.random.default_rng(0).normal(size=5000))  # AR(1), φ = 0.6, σ² = 1
    >>> from bench.analysis.timeseries import yule_walker
    >>> phi, sigma2 = yule_walker(x, 1)
    >>> round(float(phi[0]), 2), round(sigma2, 2)
    (0.6, 0.99)
    """
    xd = as_series(x, 2)
    p = check_order(p, xd.size)
    r = np.array([xd[k:] @ xd[: xd.size - k] for k in range(p + 1)]) / xd.size
    phi, _, sigma2 = levinson_durbin(r, p)
    return phi, float(sigma2[-1])


def ar_path(xd: np.ndarray, pmax: int, method: str) -> list[tuple[np.ndarray, float]]:
    """Coefficients and ``sigma2`` for every order 0..pmax with one estimator."""
    if method == "burg":
        phis, sig = burg_path(xd, pmax)
        return list(zip(phis, sig.tolist()))
    if method == "yule-walker":
        r = np.array([xd[k:] @ xd[: xd.size - k] for k in range(pmax + 1)]) / xd.size
        fits = [levinson_durbin(r, k) for k in range(pmax + 1)]
        return [(phi, float(sig[-1])) for phi, _, sig in fits]
    if method == "ulrych-clayton":
        full = _full_lag_sums(xd, pmax + 1)
        return [ulrych_clayton(xd, k, full) for k in range(pmax + 1)]
    raise ValueError(f"AR method {method!r} is not one of {AR_METHODS}")


def ar_interpolate(x: np.ndarray, missing: np.ndarray, phi: np.ndarray, sweeps: int = 10) -> np.ndarray:
    """Replace ``x[missing]`` by their conditional expectation given the other samples under AR(phi).

    For a zero-mean AR(p) with ``a = [1, -φ1, …, -φp]`` the two-sided interpolator is
    ``x̂_t = -Σ_{k=1..p} ρi_k (x_{t-k} + x_{t+k})`` with the inverse autocorrelations
    ``ρi_k = Σ_j a_j a_{j+k} / Σ_j a_j²`` (exact for isolated gaps away from the ends).
    Adjacent gaps are solved by repeating the update (``sweeps`` Jacobi passes).  The
    values in ``x[missing]`` on entry are the starting guess (e.g. linear interpolation).
    """
    out = np.array(x, dtype=float)
    idx = np.flatnonzero(missing)
    phi = np.asarray(phi, dtype=float)
    if idx.size == 0 or phi.size == 0:
        if idx.size:
            out[idx] = 0.0  # white noise: the best guess of a missing sample is the mean
        return out
    a = np.r_[1.0, -phi]
    p = phi.size
    rho_inv = np.array([a[: a.size - k] @ a[k:] for k in range(1, p + 1)]) / (a @ a)
    pad = np.r_[np.zeros(p), out, np.zeros(p)]  # samples beyond the ends count as the mean
    for _ in range(sweeps):
        guess = -sum(rho_inv[k - 1] * (pad[idx + p - k] + pad[idx + p + k]) for k in range(1, p + 1))
        pad[idx + p] = guess
    return pad[p:-p]
