"""A linear angular-rate sensor whose response to the table's motion is exact in closed form.

The sensor is a cascade of high-/low-pass sections times a gain, realised as one continuous
state space from the input rate ``u`` (rad/s) to the output ``y`` (any unit)::

    ẋ = A x + B u,     y = C x + D u.

Each section is realised exactly as ``bench.analysis.fusion._models.SensorModel.state_space``
does (the analysis side's fit form), from the low-pass states of its own dynamics:
first-order ``ż = ωc(u − z)``; second-order ``ż = v, v̇ = ωc²(u − z) − 2ζωc v``; a low-pass
reads ``z``, a high-pass ``u − z`` (order 1) or ``u − z − (2ζ/ωc)v`` (order 2).  All poles
lie in the open left half-plane (corner > 0, ζ > 0), so ``A`` is invertible.

The table's motion comes as :class:`sim.physics.angular_piece.MotionPiece` pieces; within a
piece the rate is ``Σ (α + βτ) sin(wτ + φ)``.  With ``M = (jwI − A)⁻¹`` one component
``Re[c (α + βτ) e^{jwτ}]`` (``c = −j e^{jφ}``) has the particular solution
``x_p = Re[c ((α + βτ) M − β M²) B e^{jwτ}]`` (substitute ``(p + qτ)e^{jwτ}``: the τ terms
give ``q = cβ M B``, the rest ``p = cα M B − M q``), and the state is
``x(t) = e^{A(t − t_s)} (x(t_s) − x_p(t_s)) + x_p(t)``.  The mean output over a window
follows from ``∫y = C A⁻¹(Δx − B Δθ) + D Δθ`` (integrate ``ẋ = Ax + Bu``), ``Δθ`` the
table-angle increment, also in closed form: no time stepping anywhere.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numba
import numpy as np
from scipy.linalg import expm

from sim.physics.angular_piece import MotionPiece

KINDS = ("highpass", "lowpass")
#: relative mismatch tolerated between one piece's end and the next piece's start
BOUNDARY_TOL_S = 1e-9
#: eigenvector condition number above which e^{Aτ} is taken from expm instead of the modes
_MAX_MODE_COND = 1e4

#: ``pieces(t0_s, t1_s) -> list[MotionPiece]``: time-ordered, covering [t0_s, t1_s]
PiecesFn = Callable[[float, float], Sequence[MotionPiece]]
# per-piece component arrays: counts (m,), ω, α, β, φ (m, K) and the vectors M B, M² B (m, K, n)
_Components = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def check_range(name: str, value, lo: float, hi: float, *, lo_open: bool = False) -> float:
    """``value`` as a float within ``[lo, hi]`` (``(lo, hi]`` if ``lo_open``) or ValueError."""
    v = float(value)
    ok = math.isfinite(v) and (v > lo if lo_open else v >= lo) and v <= hi
    if not ok:
        raise ValueError(f"{name} = {value!r} must be in {'(' if lo_open else '['}{lo:g}, {hi:g}]")
    return v


@dataclass(frozen=True)
class Section:
    """One filter section: ``kind`` "highpass"/"lowpass", ``order`` 1 or 2, corner
    ``corner_hz`` (Hz), damping ``zeta`` (used by order 2).  Unit passband gain."""

    kind: str
    order: int
    corner_hz: float
    zeta: float = math.sqrt(0.5)

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"section kind {self.kind!r} must be one of {', '.join(KINDS)}")
        if self.order not in (1, 2):
            raise ValueError(f"section order {self.order!r} must be 1 or 2")
        check_range("corner_hz", self.corner_hz, 0.0, 1e9, lo_open=True)
        check_range("zeta", self.zeta, 0.0, 100.0, lo_open=True)

    def state_space(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """``(a, b, c, d)`` of this section alone (same realisation as ``SensorModel``)."""
        wc = 2 * math.pi * self.corner_hz
        if self.order == 1:
            a, b, c_lp = np.array([[-wc]]), np.array([wc]), np.array([1.0])
        else:
            a = np.array([[0.0, 1.0], [-wc * wc, -2 * self.zeta * wc]])
            b, c_lp = np.array([0.0, wc * wc]), np.array([1.0, 0.0])
        if self.kind == "lowpass":
            return a, b, c_lp, 0.0
        return a, b, (-np.array([1.0]) if self.order == 1 else -np.array([1.0, 2 * self.zeta / wc])), 1.0

    def response(self, freq_hz) -> np.ndarray:
        p = 1j * np.asarray(freq_hz, dtype=float) / self.corner_hz
        den = 1 + p if self.order == 1 else 1 + 2 * self.zeta * p + p * p
        return (1.0 if self.kind == "lowpass" else p ** self.order) / den


def cascade(sections: Sequence[Section], gain: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """``(A, B, C, D)`` of ``gain × sections[-1] ∘ … ∘ sections[0]`` (input to the first)."""
    a_t, b_t, c_t, d_t = np.zeros((0, 0)), np.zeros(0), np.zeros(0), 1.0
    for s in sections:
        a, b, c, d = s.state_space()
        n0, m = a_t.shape[0], a.shape[0]
        big = np.zeros((n0 + m, n0 + m))
        big[:n0, :n0], big[n0:, n0:] = a_t, a
        big[n0:, :n0] = np.outer(b, c_t)  # this section's input is the previous output
        a_t, b_t = big, np.concatenate([b_t, b * d_t])
        c_t, d_t = np.concatenate([d * c_t, c]), d * d_t
    return a_t, b_t, gain * c_t, gain * d_t


@numba.njit(cache=True)
def _chain(trans, forcing, h0):
    """h[i+1] = trans[i] @ h[i] + forcing[i]: the homogeneous state at each segment start."""
    m, n = forcing.shape
    out = np.empty((m + 1, n))
    out[0] = h0
    for i in range(m):
        for r in range(n):
            acc = forcing[i, r]
            for k in range(n):
                acc += trans[i, r, k] * out[i, k]
            out[i + 1, r] = acc
    return out


@numba.njit(cache=True)
def _forced_kernel(seg, tau, ncomp, w, alpha, beta, phase, v1, v2):
    """Particular state (P, n) and rate antiderivative (P,) at τ into pieces ``seg``:
    ``x_p = Re[rot((α+βτ)v1 − βv2)]`` with ``rot = c e^{jwτ} = sin(wτ+φ) − j cos(wτ+φ)``;
    ``∫(α+βτ) sin(wτ+φ) = −(α+βτ) cos/w + β sin/w²``."""
    n_pts, n = tau.size, v1.shape[2]
    xp = np.zeros((n_pts, n))
    anti = np.zeros(n_pts)
    for p in range(n_pts):
        s, t = seg[p], tau[p]
        for k in range(ncomp[s]):
            wk, be = w[s, k], beta[s, k]
            arg = wk * t + phase[s, k]
            sn, cs = math.sin(arg), math.cos(arg)
            amp = alpha[s, k] + be * t
            for r in range(n):
                xp[p, r] += (sn * amp * v1[s, k, r].real + cs * amp * v1[s, k, r].imag
                             - sn * be * v2[s, k, r].real - cs * be * v2[s, k, r].imag)
            anti[p] += (be * sn / wk - amp * cs) / wk
    return xp, anti


@numba.njit(cache=True)
def _modal_kernel(seg, tau, lam, vec, z):
    """``Re[V (e^{λτ_p} ⊙ z[seg_p])]`` (P, n); modes decayed below e⁻⁴⁰ are skipped (they are
    far under the rounding of the state, and their underflow would be slow)."""
    n_pts, n = tau.size, vec.shape[0]
    out = np.zeros((n_pts, n))
    for p in range(n_pts):
        s, t = seg[p], tau[p]
        for j in range(n):
            re = lam[j].real * t
            if re < -40.0:
                continue
            e = np.exp(lam[j] * t) * z[s, j]
            for r in range(n):
                out[p, r] += (vec[r, j] * e).real
    return out


class LinearRateSensor:
    """A linear rate sensor on the table: exact mean output over windows, plus noise.

    ``sections`` (input first) and ``gain`` (output unit per rad/s) form the continuous
    model; ``pieces`` is the table's motion.  Extras on the output: white noise of
    one-sided density ``noise_density`` (output unit/√Hz; a window mean of length d has
    σ = n/√(2d), drawn independently per window from ``rng``), a constant ``bias``
    (output unit), and a latency ``latency_s`` (the output at t is the response to the
    motion up to t − latency_s).

    All times are sensor times (s).  State: the sensor starts settled at ``t_origin_s``
    (default: the first request's earliest window start) — its state there is the particular
    (forced) solution of the piece covering ``t_origin_s − latency_s``: exact for a table at
    rest then, or on a dwell that has run long.
    Requests come in time order: every window start of a call must be ≥ the latest window
    start of the previous calls (ValueError otherwise); windows within one call may come
    in any order and overlap; the time between calls is propagated exactly across every
    piece in between.  ``pieces`` is called once per request with non-decreasing t0_s.
    """

    def __init__(self, sections: Sequence[Section], gain: float, pieces: PiecesFn, *,
                 noise_density: float = 0.0, bias: float = 0.0, latency_s: float = 0.0,
                 rng: np.random.Generator | None = None, t_origin_s: float | None = None) -> None:
        sections = tuple(sections)
        if not sections or not all(isinstance(s, Section) for s in sections):
            raise ValueError(f"sections {sections!r} must be 1 or more Section objects")
        if not (math.isfinite(gain) and gain != 0):
            raise ValueError(f"gain = {gain!r} must be finite and non-zero")
        self.noise_density = check_range("noise_density", noise_density, 0.0, 1e12)
        self.bias = check_range("bias", bias, -1e12, 1e12)
        self.latency_s = check_range("latency_s", latency_s, 0.0, 10.0)
        if self.noise_density > 0 and not isinstance(rng, np.random.Generator):
            raise ValueError("rng must be a numpy.random.Generator when noise_density > 0")
        if t_origin_s is not None and not math.isfinite(t_origin_s):
            raise ValueError(f"t_origin_s = {t_origin_s!r} must be finite (or None)")
        self.sections, self.gain, self.pieces, self.rng = sections, float(gain), pieces, rng
        self.a, self.b, self.c, self.d = cascade(sections, self.gain)
        self.n = self.a.shape[0]
        lam, vec = np.linalg.eig(self.a)
        if np.any(lam.real >= 0):
            raise ValueError(f"poles {lam} must lie in the left half-plane")
        # e^{Aτ} from the modes when they are well conditioned (the usual case); expm otherwise
        modal = np.linalg.cond(vec) < _MAX_MODE_COND
        self._lam, self._vec = lam, vec
        self._vinv: np.ndarray | None = np.linalg.inv(vec) if modal else None  # None: use expm
        self._c_ainv = np.linalg.solve(self.a.T, self.c)  # C A⁻¹
        self._c_ainv_b = float(self._c_ainv @ self.b)
        # motion time of the carried state (the sensor at t sees the motion at t − latency)
        self._t: float | None = None if t_origin_s is None else float(t_origin_s) - self.latency_s
        self._x: np.ndarray | None = None  # carried state; None = settled on the covering piece's forced response
        self._comp_cache: tuple[list[MotionPiece], _Components] | None = None

    # ---- the continuous model -------------------------------------------------------------
    def state_space(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """``(A, B, C, D)`` from the input rate (rad/s) to the output (latency excluded)."""
        return self.a.copy(), self.b.copy(), self.c.copy(), float(self.d)

    def response(self, freq_hz) -> np.ndarray:
        """Complex frequency response (output unit per rad/s) including the latency."""
        f = np.asarray(freq_hz, dtype=float)
        g = np.full(f.shape, self.gain, dtype=complex)
        for s in self.sections:
            g = g * s.response(f)
        return g * np.exp(-2j * math.pi * f * self.latency_s)

    # ---- exact propagation ----------------------------------------------------------------
    def _homogeneous(self, seg: np.ndarray, tau: np.ndarray, h: np.ndarray) -> np.ndarray:
        """``e^{Aτ_p} h[seg_p]`` for τ (P,) ≥ 0, h (m, n) per segment."""
        if self._vinv is not None:
            return _modal_kernel(seg, tau, self._lam, self._vec, h @ self._vinv.T)
        return np.einsum("pij,pj->pi", expm(self.a[None] * tau[:, None, None]), h[seg])

    def _transitions(self, tau: np.ndarray) -> np.ndarray:
        """``e^{Aτ}`` (m, n, n) for τ (m,)."""
        if self._vinv is not None:
            e = np.exp(np.multiply.outer(tau, self._lam))
            return np.einsum("ij,mj,jk->mik", self._vec, e, self._vinv).real
        return expm(self.a[None] * tau[:, None, None])

    def _components(self, pcs: Sequence[MotionPiece]) -> _Components:
        """Padded per-piece component arrays (m, K) and the vectors M B, M² B (m, K, n);
        the last result is reused when the same pieces come again (a dwell's calls)."""
        if self._comp_cache is not None and len(self._comp_cache[0]) == len(pcs) \
                and all(a is b for a, b in zip(self._comp_cache[0], pcs)):
            return self._comp_cache[1]
        m, k = len(pcs), max(1, max(p.n for p in pcs))
        ncomp = np.array([p.n for p in pcs], dtype=np.int64)
        w, alpha, beta, phase = np.ones((m, k)), np.zeros((m, k)), np.zeros((m, k)), np.zeros((m, k))
        for i, p in enumerate(pcs):
            w[i, :p.n], alpha[i, :p.n] = 2 * math.pi * p.freq_hz, p.alpha_rad_s
            beta[i, :p.n], phase[i, :p.n] = p.beta_rad_s2, p.phase_rad
        jw_a = 1j * w[..., None, None] * np.eye(self.n) - self.a  # (m, K, n, n)
        v1 = np.linalg.solve(jw_a, np.broadcast_to(self.b.astype(complex), (m, k, self.n))[..., None])
        v2 = np.linalg.solve(jw_a, v1)
        comp: _Components = ncomp, w, alpha, beta, phase, v1[..., 0], v2[..., 0]
        self._comp_cache = (list(pcs), comp)
        return comp

    @staticmethod
    def _forced(comp: _Components, seg: np.ndarray, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Particular state (P, n) and rate antiderivative (P,) at τ (P,) into pieces ``seg``."""
        return _forced_kernel(seg.astype(np.int64), np.ascontiguousarray(tau, dtype=float), *comp)

    def _fetch(self, t0: float, t1: float) -> list[MotionPiece]:
        pcs = [p for p in self.pieces(t0, t1) if p.t_end_s > t0]
        if not pcs or pcs[0].t_start_s > t0 or pcs[-1].t_end_s < t1:
            raise ValueError(f"pieces({t0!r}, {t1!r}) must cover [{t0!r}, {t1!r}] s")
        for p, q in zip(pcs, pcs[1:]):
            if abs(p.t_end_s - q.t_start_s) > BOUNDARY_TOL_S * max(1.0, abs(q.t_start_s)):
                raise ValueError(f"pieces must be contiguous: one ends at {p.t_end_s!r} s, "
                                 f"the next starts at {q.t_start_s!r} s")
        return pcs

    def _states(self, q: np.ndarray, keep: float, t_c: float) -> tuple[np.ndarray, np.ndarray]:
        """State (P, n) and relative table angle (P,) at motion times q (all ≥ the carried
        time ``t_c``); then carry the state to ``keep`` (one of the q)."""
        pcs = self._fetch(t_c, float(q.max()))
        starts = np.array([p.t_start_s for p in pcs])
        sigma = np.maximum(starts, t_c)  # where each segment's propagation starts
        comp = self._components(pcs)
        m = len(pcs)
        seg_all = np.arange(m)
        xp_s, anti_s = self._forced(comp, seg_all, sigma - starts)
        # each segment's end = the next's start (its own t_end may differ by rounding)
        xp_e, anti_e = self._forced(comp, seg_all[:-1], starts[1:] - starts[:-1])
        h0 = np.zeros(self.n) if self._x is None else self._x - xp_s[0]
        trans = self._transitions(sigma[1:] - sigma[:-1])
        h = _chain(trans, xp_e - xp_s[1:], h0)  # x(σ_i) − x_p(σ_i) for every segment
        theta = np.concatenate([[0.0], np.cumsum(anti_e - anti_s[:-1])])  # angle at σ_i
        seg = np.clip(np.searchsorted(starts, q, side="right") - 1, 0, m - 1)
        xp, anti = self._forced(comp, seg, q - starts[seg])
        x = self._homogeneous(seg, q - sigma[seg], h) + xp
        ang = theta[seg] + anti - anti_s[seg]
        i_keep = int(np.flatnonzero(q == keep)[0])
        self._t, self._x = float(keep), x[i_keep].copy()
        return x, ang

    # ---- the output -----------------------------------------------------------------------
    def _integrals(self, q: np.ndarray, n_win: int, shared: bool) -> np.ndarray:
        """∫y over windows whose motion-time edges are ``q``: ``[q[k], q[k+1]]`` (shared edges)
        or ``[q[k], q[n_win + k]]``."""
        a = q[:n_win]
        if self._t is None:
            self._t = float(a.min())
        t_c = self._t
        if a.min() < t_c:
            raise ValueError(f"window start {a.min() + self.latency_s!r} s precedes the latest window "
                             f"start {t_c + self.latency_s!r} s of the previous requests "
                             "(requests must come in non-decreasing time order)")
        x, ang = self._states(q, float(a.max()), t_c)
        if shared:
            dx, dth = np.diff(x, axis=0), np.diff(ang)
        else:
            dx, dth = x[n_win:] - x[:n_win], ang[n_win:] - ang[:n_win]
        return dx @ self._c_ainv + (self.d - self._c_ainv_b) * dth

    def integral_output(self, t_start_s, duration_s) -> np.ndarray:
        """Exact ``∫y`` (output unit × s) of the noiseless, bias-free output over each window
        ``[t, t + d]`` (sensor time, s; t scalar or 1-D, d scalar or the same shape).
        Advances the carried state like :meth:`mean_output`."""
        t = np.asarray(t_start_s, dtype=float)
        if t.ndim > 1:
            raise ValueError(f"t_start_s must be a scalar or 1-D, got shape {t.shape}")
        d = np.broadcast_to(np.asarray(duration_s, dtype=float), t.shape)
        t1, d1 = np.atleast_1d(t), np.atleast_1d(d)
        if t1.size == 0:
            return np.zeros(t.shape)
        if not (np.all(np.isfinite(t1)) and np.all(np.isfinite(d1)) and np.all(d1 > 0)):
            raise ValueError("t_start_s must be finite and duration_s finite and > 0 s")
        a = t1 - self.latency_s
        out = self._integrals(np.concatenate([a, a + d1]), a.size, shared=False)
        return out.reshape(t.shape) if t.ndim else out[0]

    def integral_over_edges(self, t_edges_s) -> np.ndarray:
        """Exact ``∫y`` over the n windows between n+1 strictly increasing edges (sensor
        time, s): contiguous frames, each edge evaluated once (half the work of
        :meth:`integral_output` on the same windows)."""
        e = np.asarray(t_edges_s, dtype=float)
        if e.ndim != 1 or e.size < 2 or not np.all(np.isfinite(e)) or np.any(np.diff(e) <= 0):
            raise ValueError("t_edges_s must be a finite, strictly increasing 1-D array of ≥ 2 edges")
        return self._integrals(e - self.latency_s, e.size - 1, shared=True)

    def _add_noise(self, integral: np.ndarray, d: np.ndarray) -> np.ndarray:
        out = integral / d + self.bias
        if self.noise_density > 0:
            if self.rng is None:  # the constructor refuses this pair; noise_density set later must not either
                raise ValueError(f"noise_density = {self.noise_density!r} > 0 needs rng, a numpy.random.Generator")
            out = out + self.noise_density / np.sqrt(2.0 * d) * self.rng.standard_normal(np.shape(out))
        return out

    def mean_output(self, t_start_s, duration_s) -> np.ndarray:
        """Mean output over each window ``[t, t + d]`` (sensor time, s): the exact mean of the
        continuous model's output, plus the bias and the window's white-noise mean
        (σ = noise_density/√(2d)); one normal draw per window when noise is on."""
        integral = self.integral_output(t_start_s, duration_s)
        return self._add_noise(integral, np.broadcast_to(np.asarray(duration_s, dtype=float), np.shape(integral)))

    def mean_over_edges(self, t_edges_s) -> np.ndarray:
        """:meth:`mean_output` over the contiguous windows between ``t_edges_s`` (n+1,)."""
        e = np.asarray(t_edges_s, dtype=float)
        return self._add_noise(self.integral_over_edges(e), np.diff(e))
