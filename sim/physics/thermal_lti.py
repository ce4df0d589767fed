"""Exact responses of small linear systems to exponential-polynomial inputs.

Every thermal signal of the simulated world is, between two events, an *exponential
polynomial* of the time τ = t − t₀ since the segment's start:

    x(τ) = c₀ + c₁·τ + Re Σₖ aₖ·exp(λₖ τ)            (vectors c₀, c₁, aₖ; complex λₖ, aₖ)

A chamber's set point ramp is a first-degree polynomial; a linear node network driven by
such an input answers with another exponential polynomial, whose new exponents are the
network's eigenvalues.  :meth:`LinearBlock.respond` writes that answer down in closed form
(particular solution + modal homogeneous part), so a 20-hour chamber profile costs a few
matrix solves per event, never a time step, and a value at any instant is a short sum.

Conventions: the homogeneous part of a real system is real by construction (conjugate
eigenvalues carry conjugate amplitudes), so taking the real part of the whole sum is exact.
A forced exponent within 1e-9 (relative) of an eigenvalue of the block — resonance, which
would need a τ·exp(λτ) term — is moved by that relative amount: the error it makes is of
the order of 1e-9 of the term.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: size below which an exponential term is left out of an evaluation (°C: far below any reading)
_NEGLIGIBLE_C = 1e-12
#: relative distance below which a forced exponent counts as resonant with an eigenvalue
_RESONANCE_REL = 1e-9


@dataclass(frozen=True)
class ExpPoly:
    """``x(t) = c0 + c1·(t − t0) + Re Σₖ amp[:, k]·exp(lam[k]·(t − t0))`` for t ≥ t0.

    ``c0``, ``c1``: shape (n,); ``lam``: (m,) complex; ``amp``: (n, m) complex.
    """

    t0: float
    c0: np.ndarray
    c1: np.ndarray
    lam: np.ndarray
    amp: np.ndarray

    @staticmethod
    def constant(t0: float, value) -> ExpPoly:
        c0 = np.atleast_1d(np.asarray(value, dtype=float))
        return ExpPoly(float(t0), c0, np.zeros_like(c0), np.zeros(0, complex), np.zeros((c0.size, 0), complex))

    @staticmethod
    def ramp(t0: float, value, slope) -> ExpPoly:
        c0 = np.atleast_1d(np.asarray(value, dtype=float))
        c1 = np.atleast_1d(np.asarray(slope, dtype=float))
        return ExpPoly(float(t0), c0, c1, np.zeros(0, complex), np.zeros((c0.size, 0), complex))

    @property
    def size(self) -> int:
        return int(self.c0.size)

    def _tau(self, t) -> np.ndarray:
        return np.atleast_1d(np.asarray(t, dtype=float)) - self.t0

    def _exp_sum(self, tau: np.ndarray, weights: np.ndarray) -> np.ndarray:
        """Re Σₖ weights[:, k]·exp(λₖ τ) → (len(tau), n); each term left out where it has
        decayed below ``_NEGLIGIBLE_C`` (times in order: a prefix of them)."""
        out = np.zeros((tau.size, self.size))
        if not self.lam.size or not tau.size:
            return out
        ordered = tau.size < 2 or bool(np.all(tau[1:] >= tau[:-1]))
        for lam, w in zip(self.lam, weights.T):
            mag = float(np.abs(w).max())
            if mag < _NEGLIGIBLE_C:
                continue
            tau_dead = math.log(mag / _NEGLIGIBLE_C) / -lam.real if lam.real < 0 else math.inf
            if ordered:
                sel: slice | np.ndarray = slice(0, int(np.searchsorted(tau, tau_dead, side="right")))
            else:
                sel = tau <= tau_dead
            part = tau[sel]
            if not part.size:
                continue
            if lam.imag == 0.0:
                out[sel] += np.exp(lam.real * part)[:, None] * w.real[None, :]
            else:
                out[sel] += (np.exp(lam * part)[:, None] * w[None, :]).real
        return out

    def at(self, t) -> np.ndarray:
        """Values at times ``t`` (array (k,)) → shape (k, n)."""
        tau = self._tau(t)
        return self.c0[None, :] + tau[:, None] * self.c1[None, :] + self._exp_sum(tau, self.amp)

    def rate(self, t) -> np.ndarray:
        """Time derivatives at ``t`` → shape (k, n)."""
        tau = self._tau(t)
        return self.c1[None, :] + self._exp_sum(tau, self.amp * self.lam[None, :])

    def value(self, t: float) -> np.ndarray:
        """The state (n,) at one instant."""
        return self.at(np.array([t]))[0]

    def rebased(self, t_new: float) -> ExpPoly:
        """The same signal written from ``t_new`` on (τ measured from ``t_new``)."""
        d = float(t_new) - self.t0
        return ExpPoly(float(t_new), self.c0 + d * self.c1, self.c1.copy(), self.lam.copy(),
                       self.amp * np.exp(self.lam * d)[None, :])

    def row(self, i: int) -> ExpPoly:
        """Component ``i`` as a one-dimensional signal."""
        return ExpPoly(self.t0, self.c0[i:i + 1].copy(), self.c1[i:i + 1].copy(), self.lam.copy(),
                       self.amp[i:i + 1].copy())

    @staticmethod
    def stack(parts: list[ExpPoly]) -> ExpPoly:
        """Components of several signals with the same ``t0`` as one vector signal."""
        t0 = parts[0].t0
        if any(p.t0 != t0 for p in parts):
            raise ValueError("stacked signals must share t0 (rebase them first)")
        lam = np.concatenate([p.lam for p in parts])
        n = sum(p.size for p in parts)
        amp = np.zeros((n, lam.size), complex)
        r = k = 0
        for p in parts:
            amp[r:r + p.size, k:k + p.lam.size] = p.amp
            r, k = r + p.size, k + p.lam.size
        return ExpPoly(t0, np.concatenate([p.c0 for p in parts]), np.concatenate([p.c1 for p in parts]),
                       lam, amp)

    def pruned(self, floor: float = _NEGLIGIBLE_C) -> ExpPoly:
        """Without exponential terms too small to matter from ``t0`` on (|a| < floor)."""
        if not self.lam.size:
            return self
        keep = np.abs(self.amp).max(axis=0) >= floor
        if keep.all():
            return self
        return ExpPoly(self.t0, self.c0, self.c1, self.lam[keep], self.amp[:, keep])


class LinearBlock:
    """ẋ = A x + B u for a small, stable, diagonalisable A (distinct eigenvalues)."""

    def __init__(self, a: np.ndarray, b: np.ndarray) -> None:
        self.a = np.asarray(a, dtype=float)
        self.b = np.asarray(b, dtype=float)
        n = self.a.shape[0]
        if self.a.shape != (n, n) or self.b.shape[0] != n:
            raise ValueError(f"A {self.a.shape} and B {self.b.shape} do not fit")
        lam, vec = np.linalg.eig(self.a)
        if np.any(lam.real >= 0):
            raise ValueError(f"the block must be stable: eigenvalues {lam}")
        self.lam = lam.astype(complex)
        self.vec = vec.astype(complex)
        self.vec_inv = np.linalg.inv(self.vec)
        self.a_inv = np.linalg.inv(self.a)

    def respond(self, x0, u: ExpPoly) -> ExpPoly:
        """The state from ``u.t0`` on, starting at ``x0`` and driven by the input ``u``."""
        x0 = np.asarray(x0, dtype=float)
        bu0, bu1 = self.b @ u.c0, self.b @ u.c1
        p1 = -self.a_inv @ bu1                       # A p1 + B u1 = 0
        p0 = self.a_inv @ (p1 - bu0)                 # A p0 + B u0 = p1
        forced = np.zeros((x0.size, u.lam.size), complex)
        mus = u.lam.copy()
        for k, mu in enumerate(u.lam):
            near = np.abs(self.lam - mu) <= _RESONANCE_REL * max(abs(mu), 1e-300)
            if near.any():
                mu = mu * (1.0 + _RESONANCE_REL) + _RESONANCE_REL
                mus[k] = mu
            forced[:, k] = np.linalg.solve(mu * np.eye(x0.size) - self.a, self.b @ u.amp[:, k])
        particular0 = p0 + forced.sum(axis=1).real
        c = self.vec_inv @ (x0 - particular0)
        return ExpPoly(u.t0, p0, p1, np.concatenate([mus, self.lam]),
                       np.concatenate([forced, self.vec * c[None, :]], axis=1)).pruned()

    def steady_state(self, u_const) -> np.ndarray:
        """The equilibrium for a constant input."""
        return -self.a_inv @ (self.b @ np.atleast_1d(np.asarray(u_const, dtype=float)))


def evaluate_segments(starts: np.ndarray, signals: list[ExpPoly], t, derivative: bool = False) -> np.ndarray:
    """Values (k, n) of a piecewise signal — ``signals[i]`` from ``starts[i]`` on — at times ``t``."""
    t = np.atleast_1d(np.asarray(t, dtype=float))
    idx = np.searchsorted(starts, t, side="right") - 1
    if t.size and idx.min() < 0:
        raise ValueError(f"time {t.min()!r} s precedes the retained history (from {starts[0]!r} s)")
    n = signals[0].size
    if not t.size:
        return np.zeros((0, n))
    lo, hi = int(idx.min()), int(idx.max())
    if lo == hi:
        s = signals[lo]
        return s.rate(t) if derivative else s.at(t)
    order = np.argsort(idx, kind="stable")
    edges = np.searchsorted(idx[order], np.arange(lo, hi + 2))
    out = np.empty((t.size, n))
    for i in range(lo, hi + 1):
        a, b = edges[i - lo], edges[i - lo + 1]
        if b > a:
            sel = order[a:b]
            s = signals[i]
            out[sel] = s.rate(t[sel]) if derivative else s.at(t[sel])
    return out
