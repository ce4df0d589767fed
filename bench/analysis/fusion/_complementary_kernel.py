"""Compiled recursions of the complementary Kalman filter and its fixed-interval smoother
(numba), behind :mod:`bench.analysis.fusion._complementary`.

The model is ``x_k = Φ x_{k−1} + γ0 u_{k−1} + γ1 u_k + w``, ``z_k = h·x_k + v`` with a *known
input* ``u`` (the HF reading ÷ its gain), process noise covariance ``Q`` and one scalar
measurement per sample (the LF reading) whose variance ``R`` is fixed or Document B's
piecewise-adaptive bounded rule; the output is ``rate_k = u_k + h_rate·x_k``.  Sample 0 is
updated without a prediction (``x0``/``p0`` are its prior).

Conventions as in :mod:`bench.analysis.fusion._kernel`: float64 C-contiguous arrays, ``x0`` a
tuple (its length, the number of states, is a compile-time constant so the state loops
unroll), ``P`` kept exactly symmetric by computing upper triangles and mirroring them.

**Smoother** (fixed interval, offline): the modified Bryson–Frazier form of the
Rauch–Tung–Striebel smoother (Bierman, *Factorization Methods for Discrete Sequential
Estimation*, 1977, ch. X), which needs no matrix inverse:
``λ̃_{N−1} = 0``; backwards ``x^s_k = x_k + P_k λ̃_k``,
``λ̂_k = hᵀ ν_k/S_k + λ̃_k − hᵀ (K_k·λ̃_k)``, ``λ̃_{k−1} = Φᵀ λ̂_k`` — algebraically the RTS
``x^s_k = x_k + P_k Φᵀ (P⁻_{k+1})⁻¹ (x^s_{k+1} − x⁻_{k+1})`` (checked against it in the tests).
It needs every sample's posterior ``(x_k, P_k)``, gain, innovation and its variance: rather
than keep ``N·n²`` numbers (0.3 GB for 10⁶ samples of 6 states), the forward pass stores a
checkpoint ``(x, P)`` every ``every`` samples and the backward pass re-runs the filter one
block at a time from its checkpoint (with the R the forward pass used), then sweeps the block
backwards: twice the filter's work, memory ``every·n²``.
"""

from __future__ import annotations

import math

import numba
import numpy as np

STEADY_RUN = 16  # samples in a row with P unchanged (to the tolerance) before the gain is frozen


@numba.njit(cache=True)
def _predict(n, x, p, phi, kind, g0, g1, u_prev, u_now, q, xw, tw):
    """``x ← Φ x + γ0 u_prev + γ1 u_now``, ``P ← Φ P Φᵀ + Q`` in place (work arrays ``xw``, ``tw``).
    ``kind[i]`` says what row ``i`` of Φ is — 0: zero (a white-noise state), 1: the unit row
    (a random walk), 2: general — so the products skip what they need not compute."""
    for i in range(n):
        if kind[i] == 0:
            xw[i] = g0[i] * u_prev + g1[i] * u_now
        elif kind[i] == 1:
            xw[i] = x[i] + g0[i] * u_prev + g1[i] * u_now
        else:
            acc = g0[i] * u_prev + g1[i] * u_now
            for c in range(n):
                acc += phi[i, c] * x[c]
            xw[i] = acc
    for i in range(n):
        x[i] = xw[i]
    for i in range(n):  # T = Φ P
        if kind[i] == 2:
            for j in range(n):
                acc = 0.0
                for c in range(n):
                    acc += phi[i, c] * p[c, j]
                tw[i, j] = acc
        elif kind[i] == 1:
            for j in range(n):
                tw[i, j] = p[i, j]
    for i in range(n):  # P⁻ = T Φᵀ + Q, upper triangle mirrored
        for j in range(i, n):
            acc = q[i, j]
            if kind[i] != 0:
                if kind[j] == 2:
                    for c in range(n):
                        acc += tw[i, c] * phi[j, c]
                elif kind[j] == 1:
                    acc += tw[i, j]
            p[i, j] = acc
            p[j, i] = acc


@numba.njit(cache=True)
def _update(n, x, p, h, y, r_lower, r_upper, a, b, r_given, ph, gain):
    """Scalar update with reading ``y``; ``R`` = ``r_given`` if ≥ 0, else Document B's rule
    (interval from ``ν² − hPhᵀ`` against ``r_lower``/``r_upper``, ``R = clip(a_i + b_i (h x)²)``).
    Returns ``(ν, S, R, interval)``; ``gain`` holds ``K``."""
    hx = 0.0
    for i in range(n):
        hx += h[i] * x[i]
    hph = 0.0
    for i in range(n):
        acc = 0.0
        for c in range(n):
            acc += p[i, c] * h[c]
        ph[i] = acc
        hph += h[i] * acc
    nu = y - hx
    if r_given >= 0.0:
        r = r_given
        iv = -1
    else:
        idx = nu * nu - hph
        iv = 0 if idx < r_lower else (1 if idx <= r_upper else 2)
        r = a[iv] + b[iv] * hx * hx
        r = r_lower if r < r_lower else (r_upper if r > r_upper else r)
    s = hph + r
    for i in range(n):
        gain[i] = ph[i] / s
        x[i] += gain[i] * nu
    for i in range(n):  # P − K (h P), upper triangle mirrored
        for c in range(i, n):
            v = p[i, c] - gain[i] * ph[c]
            p[i, c] = v
            p[c, i] = v
    return nu, s, r, iv


@numba.njit(cache=True)
def _converged(n, p, p_last, tol):
    """Whether every element of ``P`` moved by at most ``tol·√(P_ii P_jj)`` since ``p_last``
    (then copies ``P`` into ``p_last``)."""
    ok = True
    for i in range(n):
        for j in range(i, n):
            d = p[i, j] - p_last[i, j]
            if d * d > tol * tol * abs(p[i, i] * p[j, j]):
                ok = False
            p_last[i, j] = p[i, j]
            p_last[j, i] = p[i, j]
    return ok


@numba.njit(cache=True)
def _predict_state(n, x, phi, g0, g1, u_prev, u_now, xw):
    """``x ← Φ x + γ0 u_prev + γ1 u_now`` in place (the state alone)."""
    for i in range(n):
        acc = g0[i] * u_prev + g1[i] * u_now
        for c in range(n):
            acc += phi[i, c] * x[c]
        xw[i] = acc
    for i in range(n):
        x[i] = xw[i]


@numba.njit(cache=True)
def _steady_update(n, x, h, gain, y):
    """``ν = y − h·x``, ``x ← x + K ν`` at the frozen gain; returns ``ν``."""
    hx = 0.0
    for i in range(n):
        hx += h[i] * x[i]
    nu = y - hx
    for i in range(n):
        x[i] += gain[i] * nu
    return nu


@numba.njit(cache=True)
def _input_at(i, k, u, u_near):
    """The model input at sample ``i`` as known at sample ``k`` (see :func:`complementary_forward`):
    ``u`` looks two samples ahead, so its last two samples are ``u_near``'s."""
    if i <= k - 2:
        return u[i]
    return u_near[1, i] if i == k else u_near[0, i]


@numba.njit(cache=True)
def complementary_forward(u, u_out, u_near, z, phi, kind, g0, g1, q, h, h_rate, r_lower, r_upper, a, b, adaptive,
                          x0, p0, every, steady_tol, lag):
    """The filter over the record.  ``u``/``z`` (N,) the model's input and the measurement;
    ``r_lower``/``r_upper`` the noise bounds (equal: a fixed R), ``a``/``b`` (3,) the interval
    functions, ``adaptive`` whether the rule is used (else ``R = r_lower``).

    **Output** ``rate_k = u_out_k + h_rate·x̂_k``, with ``x̂_k`` the posterior of sample
    ``k − lag`` predicted to ``k``: when ``z`` is the measurement through a filter that looks
    ``lag`` samples ahead and ``u`` is ``u_out`` through one that looks two ahead (``lag`` ≥ 2),
    the output at ``k`` still uses no reading after ``k``.  That prediction takes the model
    input ``u`` up to sample ``k − 2``, then ``u_near[0]`` at ``k − 1`` (a version of it that
    looks one sample ahead) and ``u_near[1]`` at ``k`` (one that looks none).

    **Steady state** (fixed R only; ``steady_tol`` > 0): once ``P`` has moved by less than
    ``steady_tol`` of its own scale (:func:`_converged`) for ``STEADY_RUN`` samples in a row,
    the gain is frozen and only the state is propagated (the Riccati recursion has converged:
    what remains would change the gain by < ``steady_tol``).

    Returns ``(rate, nu, s, r, interval, ck_x, ck_p, k_steady, p_final, gain_steady)``:
    ``ck_x``/``ck_p`` the state before sample ``c·every`` (for ``c = 0`` the prior of sample 0),
    ``k_steady`` the first sample at the frozen gain (``N`` if never)."""
    n_samples = u.size
    n = len(x0)
    x = np.empty(n)
    hist = np.empty((lag + 1, n))  # posteriors of the last lag + 1 samples, ring buffer
    x_out = np.empty(n)
    for i in range(n):
        x[i] = x0[i]
    p = p0.copy()
    p_last = p0.copy()
    xw, ph, gain = np.empty(n), np.empty(n), np.empty(n)
    tw = np.empty((n, n))
    rate, nus, ss, rs = np.empty(n_samples), np.empty(n_samples), np.empty(n_samples), np.empty(n_samples)
    ivs = np.empty(n_samples, dtype=np.int8)
    n_ck = (n_samples + every - 1) // every
    ck_x, ck_p = np.empty((n_ck, n)), np.empty((n_ck, n, n))
    r_fixed = -1.0 if adaptive else r_lower
    k_steady = n_samples
    run = 0
    s_steady = 0.0
    for k in range(n_samples):
        if k % every == 0:
            c = k // every
            for i in range(n):
                ck_x[c, i] = x[i]
                for j in range(n):
                    ck_p[c, i, j] = p[i, j]
        if k > 0:
            if k >= k_steady:
                _predict_state(n, x, phi, g0, g1, u[k - 1], u[k], xw)
            else:
                _predict(n, x, p, phi, kind, g0, g1, u[k - 1], u[k], q, xw, tw)
        if k >= k_steady:
            nu = _steady_update(n, x, h, gain, z[k])
            s, r, iv = s_steady, r_lower, -1
        else:
            nu, s, r, iv = _update(n, x, p, h, z[k], r_lower, r_upper, a, b, r_fixed, ph, gain)
            if steady_tol > 0 and not adaptive:
                run = run + 1 if _converged(n, p, p_last, steady_tol) else 0
                if run >= STEADY_RUN:
                    k_steady = k + 1
                    s_steady = s
        slot = k % (lag + 1)
        for i in range(n):
            hist[slot, i] = x[i]
        j0 = k - lag
        if j0 >= 0:
            src = j0 % (lag + 1)
            for i in range(n):
                x_out[i] = hist[src, i]
        else:  # before sample `lag`: the prior of sample 0
            j0 = 0
            for i in range(n):
                x_out[i] = x0[i]
        for j in range(j0 + 1, k + 1):
            _predict_state(n, x_out, phi, g0, g1, _input_at(j - 1, k, u, u_near),
                           _input_at(j, k, u, u_near), xw)
        acc = u_out[k]
        for i in range(n):
            acc += h_rate[i] * x_out[i]
        rate[k] = acc
        nus[k], ss[k], rs[k], ivs[k] = nu, s, r, iv
    return rate, nus, ss, rs, ivs, ck_x, ck_p, k_steady, p, gain


@numba.njit(cache=True)
def complementary_loglik(u, z, phi, kind, g0, g1, q, h, r, x0, p0, steady_tol):
    """``(Σ log S_k, Σ ν_k²/S_k, N)`` of the fixed-R filter's innovations: the Gaussian
    log-likelihood without storing anything (steady-state gain as in :func:`complementary_forward`)."""
    n_samples = u.size
    n = len(x0)
    x = np.empty(n)
    for i in range(n):
        x[i] = x0[i]
    p = p0.copy()
    p_last = p0.copy()
    xw, ph, gain = np.empty(n), np.empty(n), np.empty(n)
    tw = np.empty((n, n))
    dummy = np.zeros(3)
    sum_log, sum_nis = 0.0, 0.0
    run = 0
    for k in range(n_samples):
        if k > 0:
            _predict(n, x, p, phi, kind, g0, g1, u[k - 1], u[k], q, xw, tw)
        nu, s, _, _ = _update(n, x, p, h, z[k], r, r, dummy, dummy, r, ph, gain)
        if not s > 0.0:
            return math.inf, math.inf, k
        sum_log += math.log(s)
        sum_nis += nu * nu / s
        if steady_tol > 0:
            run = run + 1 if _converged(n, p, p_last, steady_tol) else 0
            if run >= STEADY_RUN:
                for kk in range(k + 1, n_samples):
                    _predict_state(n, x, phi, g0, g1, u[kk - 1], u[kk], xw)
                    nu = _steady_update(n, x, h, gain, z[kk])
                    sum_nis += nu * nu / s
                sum_log += (n_samples - k - 1) * math.log(s)
                break
    return sum_log, sum_nis, n_samples


@numba.njit(cache=True)
def complementary_smooth(u, u_out, z, phi, kind, g0, g1, q, h, h_rate, r_used, ck_x, ck_p, every, k_steady,
                         p_steady, gain_steady, s_steady):
    """Fixed-interval smoothed rate ``u_out_k + h_rate·x^s_k`` (module docstring) from the forward
    pass's checkpoints, the R it used at each sample (``r_used``) and its steady state (from ``k_steady`` on: ``P`` =
    ``p_steady``, ``K`` = ``gain_steady``, ``S`` = ``s_steady``)."""
    n_samples = u.size
    n = ck_x.shape[1]
    n_ck = ck_x.shape[0]
    rate = np.empty(n_samples)
    x, xw, ph, gain = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    p, tw = np.empty((n, n)), np.empty((n, n))
    bx, bp, bk = np.empty((every, n)), np.empty((every, n, n)), np.empty((every, n))
    bnu, bs = np.empty(every), np.empty(every)
    lam_t = np.zeros(n)  # λ̃ of the last sample of the block being swept (0 after the record)
    lam_h = np.empty(n)
    xs = np.empty(n)
    dummy = np.zeros(3)
    for c in range(n_ck - 1, -1, -1):
        k0 = c * every
        k1 = min(k0 + every, n_samples)
        for i in range(n):
            x[i] = ck_x[c, i]
            for j in range(n):
                p[i, j] = ck_p[c, i, j]
        for k in range(k0, k1):  # re-run the filter over the block, keeping what the sweep needs
            j = k - k0
            if k >= k_steady:
                if k > 0:
                    _predict_state(n, x, phi, g0, g1, u[k - 1], u[k], xw)
                bnu[j] = _steady_update(n, x, h, gain_steady, z[k])
                for i in range(n):
                    bx[j, i] = x[i]
                continue
            if k > 0:
                _predict(n, x, p, phi, kind, g0, g1, u[k - 1], u[k], q, xw, tw)
            r = r_used[k]
            nu, s, _, _ = _update(n, x, p, h, z[k], r, r, dummy, dummy, r, ph, gain)
            bnu[j], bs[j] = nu, s
            for i in range(n):
                bx[j, i] = x[i]
                bk[j, i] = gain[i]
                for m in range(n):
                    bp[j, i, m] = p[i, m]
        for k in range(k1 - 1, k0 - 1, -1):
            j = k - k0
            steady = k >= k_steady
            for i in range(n):  # x^s = x + P λ̃
                acc = bx[j, i]
                for m in range(n):
                    acc += (p_steady[i, m] if steady else bp[j, i, m]) * lam_t[m]
                xs[i] = acc
            acc = u_out[k]
            for i in range(n):
                acc += h_rate[i] * xs[i]
            rate[k] = acc
            kl = 0.0
            for i in range(n):
                kl += (gain_steady[i] if steady else bk[j, i]) * lam_t[i]
            w = bnu[j] / (s_steady if steady else bs[j]) - kl
            for i in range(n):  # λ̂ = hᵀ(ν/S − K·λ̃) + λ̃
                lam_h[i] = lam_t[i] + h[i] * w
            for i in range(n):  # λ̃ of the previous sample = Φᵀ λ̂
                acc = 0.0
                for m in range(n):
                    acc += phi[m, i] * lam_h[m]
                lam_t[i] = acc
    return rate
