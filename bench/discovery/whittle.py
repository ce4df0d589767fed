"""The Whittle likelihood of a residual under white noise plus spectral components.

The periodogram I(ω_j) at the Fourier frequencies j = 1 … n/2−1 (ω in rad/sample) is, for a
stationary series, independent exponentials of mean S(ω_j); the negative log-likelihood is
Σ log S + I/S. Here S(ω) = σw² + Σ_c S_c(ω): a white level (log coordinate ``th[0] = log σw²``)
plus each component's level spectrum in per-sample units, at its own log coordinates (the next
``n_coords`` entries of ``th``, in the components' order). A component is any object with
``n_coords`` and ``spectrum(th_c, cos_w, grad)`` — the catalogue's stochastic effects
(:class:`bench.discovery.effects_noise.StochasticEffect`). ``diff``: the periodogram is of the
first differences, so every level spectrum is multiplied by |1 − e^{−iω}|² = 2 − 2cos ω.

All pure numpy/scipy.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Protocol

import numpy as np
from scipy import fft as sp_fft
from scipy import optimize


class SpectralComponent(Protocol):
    """What the likelihood needs of a component: its number of log coordinates and its level
    spectrum (per-sample units) at ``cos ω`` with, when ``grad``, the derivative in each."""

    @property
    def n_coords(self) -> int: ...

    def spectrum(self, th: np.ndarray, c: np.ndarray, grad: bool) -> tuple[np.ndarray, list[np.ndarray]]: ...


def periodogram(r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(ω in rad/sample, I(ω)) at the Fourier frequencies strictly between 0 and π, mean removed.
    (scipy's FFT: a first difference of 180 000 samples is 179 999, a prime, where numpy's took
    38 ms and scipy's Bluestein 21 ms — a random walk's fit takes ~60 of them.)"""
    n = r.size
    spec = sp_fft.rfft(r - r.mean())
    i = np.abs(spec) ** 2 / n
    w = 2 * np.pi * np.arange(i.size) / n
    keep = (w > 0) & (w < np.pi)
    return w[keep], i[keep]


def level_spectrum(components: Sequence[SpectralComponent], th: np.ndarray, c: np.ndarray,
                   grad: bool = True) -> tuple[np.ndarray, list[np.ndarray]]:
    """The level spectrum of white + ``components`` at log coordinates ``th`` and (``grad``) its
    derivative in each coordinate (``c`` = cos ω)."""
    white = np.exp(th[0])
    lev = np.full_like(c, white)
    parts = [lev.copy()] if grad else []
    j = 1
    for comp in components:
        add, comp_parts = comp.spectrum(th[j:j + comp.n_coords], c, grad)
        lev = lev + add
        parts += comp_parts
        j += comp.n_coords
    return lev, parts


def nll(th: np.ndarray, components: Sequence[SpectralComponent], c: np.ndarray, i: np.ndarray,
        diff: bool = False) -> float:
    """The Whittle NLL alone (the Hessian's and the null's scalar search's evaluations)."""
    return nll_grad(th, components, c, i, diff, grad=False)[0]


def nll_grad(th: np.ndarray, components: Sequence[SpectralComponent], c: np.ndarray, i: np.ndarray,
             diff: bool = False, grad: bool = True) -> tuple[float, np.ndarray | None]:
    """(Whittle NLL of white + ``components``, its gradient in ``th``): Σ (1/S − I/S²)·∂S/∂θ (the
    optimiser's hot loop). ``c``: cos ω at the periodogram's frequencies (computed once by the
    caller, not at every evaluation); ``diff``: ``i`` is the periodogram of the first
    differences. ``grad`` False: the gradient is not computed (None)."""
    th = np.asarray(th, float)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):  # a wild trial step: inf
        g = (2 - 2 * c) if diff else 1.0
        lev, parts = level_spectrum(tuple(components), th, c, grad)
        s = lev * g
        if not np.all(np.isfinite(s)) or np.any(s <= 0):
            return np.inf, (np.zeros_like(th) if grad else None)
        if not grad:
            return float(np.sum(np.log(s) + i / s)), None
        k = (1.0 / s - i / s ** 2) * g
        return float(np.sum(np.log(s) + i / s)), np.array([float(np.sum(k * d)) for d in parts])


def minimize(components: Sequence[SpectralComponent], starts: Sequence[np.ndarray], c: np.ndarray,
             i: np.ndarray, diff: bool) -> optimize.OptimizeResult:
    """The best of a BFGS minimisation of the NLL from each start."""
    best = None
    for th0 in starts:
        # unbounded log coordinates: plain BFGS (L-BFGS-B costs ms per iteration in its driver here)
        res = optimize.minimize(nll_grad, th0, args=(tuple(components), c, i, diff), jac=True, method="BFGS")
        if best is None or res.fun < best.fun:
            best = res
    if best is None:
        raise ValueError("no starting point given; allowed: at least one")
    return best


def inv_hessian(f: Callable[[np.ndarray], float], x: np.ndarray, h: float = 1e-3) -> np.ndarray:
    """Inverse of the central-difference Hessian of ``f`` at ``x`` (step ``h`` in every
    coordinate); infinite entries when it is singular."""
    k = x.size
    hess = np.zeros((k, k))
    for a in range(k):
        for b in range(a, k):
            ea, eb = np.eye(k)[a] * h, np.eye(k)[b] * h
            val = (f(x + ea + eb) - f(x + ea - eb) - f(x - ea + eb) + f(x - ea - eb)) / (4 * h * h)
            hess[a, b] = hess[b, a] = val
    try:
        return np.linalg.inv(hess)
    except np.linalg.LinAlgError:
        return np.full((k, k), np.inf)
