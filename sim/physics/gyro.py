"""Interferometric fibre-optic gyro (FOG) with angle-increment pulse output (IEEE Std 952).

Per output interval [t₀, t₁] the unit integrates its indicated rate (°/s)

    ω_out = B(t) + ω·(1 + ε + (A/2)·sign ω) + n·FS·(ω/FS)³ + vibration + white noise

with ω the interval-mean input rate along the misaligned input axis (clipped to ±FS,
which sets OVER_RANGE) and B(t) = turn-on bias (+ a repeatability draw per power-on)
+ warm-up a·exp(−(t − t_on)/τ) + temperature (a polynomial of the coil's T − ambient to 3rd
order, hysteresis, Shupe ∝ dT_coil/dt: ``GyroParams.thermal_bias_dps``) + g-sensitivity·f
+ flicker (Gauss-Markov sum) + rate random walk; the scale factor is multiplied by
``GyroParams.scale_factor_ratio`` of the coil temperature.  The unit is two thermal nodes
(``sim.physics.thermal_unit``): the case, where the frame's temperature sensor sits, and the
coil, heated by the unit's dissipation; their ambient is the room or the chamber air.
Parameters, conventions and sources: ``sim/physics/gyro_params.py``; manufacturing spread and limits:
``sim/physics/gyro_population.py``.

How each term enters the interval's angle (degrees):
* warm-up: its exact integral over the interval; temperature terms: Simpson's rule on the
  interval's edges and midpoint (exact to ~dt⁴/τ⁴ of the term: τ ≥ tens of seconds);
* flicker + RRW: the knot-grid process (``gyro_noise.KnotBias``) at the interval midpoint;
* ARW: white rate noise of density N integrated exactly, an increment of σ = N·√dt;
* vibration (g rms per sensor axis): rectified bias Σ kᵢgᵢ², the resonance's exact mean
  over the interval, and a Gauss-Markov rate noise of σ = ‖cᵢgᵢ‖ at the midpoint.

Quantisation with carry: pulses = angle·3600·SF (nominal SF) accumulated in 2⁻²⁴-pulse
fixed point (exact integer sums, so any split of the intervals gives the same counts);
each interval outputs the change of the rounded accumulator, so the sum of pulses over
any span equals the integrated angle within ±1 pulse. The accumulator restarts at each
boot. An interval outputs pulses only if the unit was ready (powered and booted)
throughout it; otherwise 0 — its noise is still drawn, so the random streams never
depend on the power history.

Determinism: every stochastic term has its own child generator of the given ``rng``.
On uniform interval grids (the frame line's) a split call [0..k], [k..n] gives pulses
identical to one call, noise included; on non-uniform grids the vibration noise's
per-step coefficients agree to rounding only (~1e-15), so a count may differ by one
where the accumulator sits on a pulse boundary.

Status bits (aligned with docs/FOG_SERIAL.md where they overlap): 0x01 READY, 0x04
TEMPERATURE (coil outside the operating range), 0x08 OVER_RANGE (|ω| > FS in the interval
of the last ``pulses`` call containing t), 0x20 WARMING_UP (ready and t − t_on < 3 τ_warm-up),
0x40 BOOTING (powered, not yet ready). SUPPLY (0x02) and BIT_FAIL (0x10) are not produced.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from sim.physics.gyro_noise import KNOT_STEPS_PER_TAU, KnotBias
from sim.physics.gyro_params import (
    FLICKER_ADEV_FACTOR,
    GRADES,
    NAVIGATION,
    TACTICAL,
    GyroParams,
    adev_model_dph,
    flicker_terms,
)
from sim.physics.gyro_population import LIMITS, draw_gyro, out_of_limits
from sim.physics.noise import GaussMarkov
from sim.physics.thermal_unit import AmbientSource, ConstantAmbient, TwoNodeBody

__all__ = ["GRADES", "LIMITS", "NAVIGATION", "TACTICAL", "FiberOpticGyro", "GyroParams", "adev_model_dph",
           "draw_gyro", "flicker_terms", "indicated_rate_dps", "out_of_limits"]

STATUS_READY, STATUS_TEMPERATURE, STATUS_OVER_RANGE = 0x01, 0x04, 0x08
STATUS_WARMING_UP, STATUS_BOOTING = 0x20, 0x40
WARMUP_STATUS_TAUS = 3.0

_FRAC_BITS = 24  # fixed-point fraction of a pulse in the carry accumulator
HALF_PULSE = 1 << (_FRAC_BITS - 1)
_FRAC_MASK = (1 << _FRAC_BITS) - 1
_MAX_SPAN_PULSES = float(2**61 >> _FRAC_BITS)  # |accumulator| bound of one cumulative sum


def indicated_rate_dps(p: GyroParams, omega_ia_dps) -> np.ndarray:
    """Static rate response (°/s) to input rates along the input axis: scale-factor error,
    asymmetry and cubic non-linearity, input clipped to ±FS. Bias not included."""
    fs = p.full_scale_dps
    w = np.clip(np.asarray(omega_ia_dps, dtype=float), -fs, fs)
    half_asym = 0.5e-6 * p.asymmetry_ppm
    x = w / fs
    return w * (1.0 + 1e-6 * p.scale_factor_error_ppm + half_asym * np.sign(w)) \
        + (1e-6 * p.nonlinearity_ppm * fs) * (x * x * x)  # x*x*x: much faster than ** 3


def _child_generators(rng: np.random.Generator, n: int) -> list[np.random.Generator]:
    """Independent child streams (as in accelerometer.py), one per stochastic term."""
    try:
        return rng.spawn(n)
    except (TypeError, ValueError):  # generator built without a SeedSequence: seed from its stream
        return [np.random.default_rng(int(s)) for s in rng.integers(0, 2**63, size=n)]


@dataclass(frozen=True)
class _Segment:
    """A span of constant supply state starting at ``t_start``."""

    t_start: float
    on: bool
    t_on: float  # power-on instant (NaN when off)
    t_ready: float  # t_on + boot time (inf when off)
    run_bias_dps: float  # turn-on bias of this run (bias + repeatability draw)


class FiberOpticGyro:
    """One FOG: supply and boot, self-heating, bias terms, noise and pulse quantisation.

    Times are simulated seconds. ``set_supply`` calls come at non-decreasing times, not
    before the last interval edge already processed; ``pulses`` calls come in time order,
    each starting at (contiguous) or after (a gap) the previous call's last edge.
    Queries (``powered``, ``ready``, ``status``, temperatures) accept times from the
    start of the last ``pulses`` call on; scalars give scalars, arrays give arrays.
    ``ambient``: the air around the unit (default: the still room at ``ambient_c``).
    """

    def __init__(self, params: GyroParams, rng: np.random.Generator, ambient: AmbientSource | None = None) -> None:
        if not isinstance(params, GyroParams):
            raise TypeError("params must be a GyroParams (e.g. draw_gyro(serial) or TACTICAL)")
        if not isinstance(rng, np.random.Generator):
            raise TypeError("rng must be a numpy.random.Generator (no global RNG is used)")
        self.params = p = params
        arw_rng, slow_rng, vib_rng, phase_rng, rep_rng = _child_generators(rng, 5)
        self._arw_rng, self._rep_rng = arw_rng, rep_rng
        self._flicker = flicker_terms(p)
        self._slow = KnotBias(*self._flicker, p.rrw_dps_per_rs, p.flicker_tau_min_s / KNOT_STEPS_PER_TAU,
                              slow_rng)
        self._vib_noise = GaussMarkov(1.0, p.vib_noise_tau_s, vib_rng)
        self._vib_phase = float(phase_rng.uniform(0.0, 2.0 * math.pi))
        self._ia = np.array([1.0, *p.misalignment_rad])
        self._g_sens_dps = np.array(p.g_sensitivity_dph_per_g) / 3600.0
        self.body = TwoNodeBody(p.thermal_nodes(), ambient if ambient is not None else ConstantAmbient(p.ambient_c))
        self._segments = [_Segment(-math.inf, False, math.nan, math.inf, 0.0)]
        self._supply_v = 0.0
        self._t_edge: float | None = None  # last interval edge processed
        self._acc = HALF_PULSE  # carry accumulator (fixed point), valid while _running
        self._running = False
        self._last_edges = np.empty(0)
        self._last_over = np.empty(0, dtype=bool)

    # ---- supply -------------------------------------------------------------------------
    def supply_in_range(self, volts: float) -> bool:
        return self.params.supply_min_v <= volts <= self.params.supply_max_v

    def set_supply(self, t_s: float, volts: float) -> None:
        """Apply ``volts`` at ``t_s``; entering the supply range is a power-on (restarts
        boot, warm-up and draws this run's turn-on bias), leaving it a power-off."""
        t = float(t_s)
        earliest = max(self._segments[-1].t_start, -math.inf if self._t_edge is None else self._t_edge)
        if not (math.isfinite(t) and t >= earliest):
            raise ValueError(f"t_s={t_s!r} must be finite and ≥ {earliest!r} s "
                             "(the last supply change or the last processed interval edge)")
        if not math.isfinite(volts):
            raise ValueError(f"volts={volts!r} must be finite")
        self._supply_v = float(volts)
        on = self.supply_in_range(volts)
        if on == self._segments[-1].on:
            return
        self.body.set_power(t, on)
        p = self.params
        run_bias = (p.bias_dph + p.bias_repeatability_dph * float(self._rep_rng.standard_normal())) / 3600.0 \
            if on else 0.0
        self._segments.append(_Segment(t, on, t if on else math.nan, t + p.boot_time_s if on else math.inf,
                                       run_bias))
        self._running = False

    @property
    def supply_v(self) -> float:
        return self._supply_v

    # ---- state queries ------------------------------------------------------------------
    def _seg_index(self, t: np.ndarray) -> np.ndarray:
        starts = np.array([s.t_start for s in self._segments])
        if t.size and not np.all(np.isfinite(t)):
            raise ValueError("times must be finite")
        idx = np.searchsorted(starts, t, side="right") - 1
        if t.size and idx.min() < 0:
            raise ValueError(f"time {t.min()!r} s precedes the retained history (from {starts[0]!r} s)")
        return idx

    def _per_segment(self, t_s, fn, dtype=float):
        """Evaluate ``fn(segment, times)`` per segment; scalar in, scalar out."""
        t = np.asarray(t_s, dtype=float)
        flat = np.atleast_1d(t).ravel()
        idx = self._seg_index(flat)
        lo, hi = (int(idx.min()), int(idx.max())) if idx.size else (0, 0)
        if lo == hi:  # the usual case: one supply state over all the times
            out = np.asarray(fn(self._segments[lo], flat), dtype=dtype)
        else:
            out = np.empty(flat.shape, dtype=dtype)
            for i in range(lo, hi + 1):
                sel = idx == i
                out[sel] = fn(self._segments[i], flat[sel])
        return out.reshape(t.shape)[()] if t.ndim else out[0].item()

    def powered(self, t_s):
        """Supply within range at ``t_s``."""
        return self._per_segment(t_s, lambda s, t: np.full(t.shape, s.on), bool)

    def ready(self, t_s):
        """Powered and booted at ``t_s`` (output valid)."""
        return self._per_segment(t_s, lambda s, t: s.on & (t >= s.t_ready), bool)

    def _node(self, t_s, column: int, offset: float = 0.0):
        t = np.asarray(t_s, dtype=float)
        out = self.body.nodes_c(t.ravel())[:, column].reshape(t.shape) + offset
        return out[()] if t.ndim == 0 else out

    def body_temperature_c(self, t_s):
        """Coil (sensing element) temperature in °C — the one the bias and scale factor follow."""
        return self._node(t_s, 1)

    def case_temperature_c(self, t_s):
        """Case temperature in °C, where the frame's temperature sensor sits."""
        return self._node(t_s, 0)

    def temperature_c(self, t_s):
        """The on-board temperature sensor's reading in °C (case + sensor offset)."""
        return self._node(t_s, 0, self.params.temp_sensor_offset_c)

    def supply_current_a(self, t_s):
        """Current drawn from the supply in A (constant while powered)."""
        current = self.params.supply_current_a
        return self._per_segment(t_s, lambda s, t: np.full(t.shape, current if s.on else 0.0))

    def status(self, t_s):
        """Status bit field at ``t_s`` (module docstring); 0 when unpowered."""
        p = self.params

        def bits(s: _Segment, t: np.ndarray) -> np.ndarray:
            if not s.on:
                return np.zeros(t.shape, dtype=np.int64)
            ready = t >= s.t_ready
            temp = self.body.element_c(t)
            out = np.where(ready, STATUS_READY, STATUS_BOOTING).astype(np.int64)
            out |= np.where(ready & (t - s.t_on < WARMUP_STATUS_TAUS * p.warmup_tau_s), STATUS_WARMING_UP, 0)
            out |= np.where((temp < p.operating_min_c) | (temp > p.operating_max_c), STATUS_TEMPERATURE, 0)
            if self._last_over.size:
                k = np.searchsorted(self._last_edges, t, side="left") - 1
                inside = (k >= 0) & (k < self._last_over.size)
                over = np.zeros(t.shape, dtype=bool)
                over[inside] = self._last_over[k[inside]]
                out |= np.where(over & ready, STATUS_OVER_RANGE, 0)
            return out

        return self._per_segment(t_s, bits, np.int64)

    # ---- output -------------------------------------------------------------------------
    def _vibration(self, v, n: int):
        """(rectified bias °/s, resonance amplitude °/s, noise σ °/s), each a scalar or
        per interval (n,), or None without vibration."""
        p = self.params
        g = np.asarray(v, dtype=float)
        if g.ndim == 0 or g.shape == (n,):  # along the input axis
            if not np.all(np.isfinite(g)) or np.any(g < 0):
                raise ValueError("vibration_g_rms must be finite and ≥ 0")
            if not np.any(g):
                return None
            return (p.vib_rectification_dph_per_g2[0] / 3600.0 * g * g,
                    p.vib_resonance_dps_per_grms[0] * g, p.vib_noise_dps_per_grms[0] * g)
        if g.shape != (n, 3):
            raise ValueError(f"vibration_g_rms must be a scalar, shape ({n},) or ({n}, 3), got {g.shape}")
        if not np.all(np.isfinite(g)) or np.any(g < 0):
            raise ValueError("vibration_g_rms must be finite and ≥ 0")
        if not np.any(g):
            return None
        g2 = g * g
        return (g2 @ (np.array(p.vib_rectification_dph_per_g2) / 3600.0),
                np.sqrt(g2 @ np.square(p.vib_resonance_dps_per_grms)),
                np.sqrt(g2 @ np.square(p.vib_noise_dps_per_grms)))

    def pulses(self, t_edges_s: np.ndarray, omega_sensor_dps: np.ndarray, f_sensor_g: np.ndarray,
               vibration_g_rms: float | np.ndarray = 0.0) -> np.ndarray:
        """Pulse counts (int64, n) over the n intervals between ``t_edges_s`` (n+1, increasing).

        ``omega_sensor_dps`` (n, 3): mean inertial rate per interval in sensor axes (IA,
        second, third); ``f_sensor_g`` (n, 3): specific force in g; ``vibration_g_rms``:
        random-vibration level, a scalar or (n,) along the IA, or (n, 3) per sensor axis.
        """
        t, dt = check_frame_edges(t_edges_s, self._t_edge)
        n = t.size - 1
        omega = np.asarray(omega_sensor_dps, dtype=float)
        f = np.asarray(f_sensor_g, dtype=float)
        for name, arr in (("omega_sensor_dps", omega), ("f_sensor_g", f)):
            if arr.shape != (n, 3):
                raise ValueError(f"{name} must have shape ({n}, 3), got {arr.shape}")
        vib = self._vibration(vibration_g_rms, n)
        contiguous = self._t_edge is None or t[0] == self._t_edge
        if n == 0:
            self._t_edge = float(t[0])
            return np.zeros(0, dtype=np.int64)
        p = self.params
        mid = t[:-1] + 0.5 * dt
        # noise for every interval, powered or not (streams independent of the power history)
        noise_dps = self._slow.values(mid, contiguous)
        vib_unit = self._vib_noise.sample(mid)
        arw_deg = self._arw_rng.standard_normal(n)
        arw_deg *= p.arw_deg_per_rs * np.sqrt(dt)

        omega_ia = omega @ self._ia
        over = np.abs(omega_ia) > p.full_scale_dps
        counts = np.zeros(n, dtype=np.int64)
        valid = np.zeros(n, dtype=bool)
        carry_in = self._running
        self._running = False
        for seg, a, b in self._ready_runs(t):
            valid[a:b] = True
            rate = indicated_rate_dps(p, omega_ia[a:b])
            thermal_bias, sf_ratio = self._thermal_terms(t[a:b + 1], mid[a:b])
            if sf_ratio is not None:
                rate *= sf_ratio
            rate += seg.run_bias_dps
            rate += noise_dps[a:b]
            rate += self._deterministic_bias_dps(seg, t[a:b + 1], dt[a:b])
            rate += thermal_bias
            rate += f[a:b] @ self._g_sens_dps
            if vib is not None:
                rect, amp, sigma = (x if np.ndim(x) == 0 else x[a:b] for x in vib)
                half = math.pi * p.vib_resonance_hz * dt[a:b]  # half the phase advance
                phase = 2.0 * math.pi * p.vib_resonance_hz * mid[a:b] + self._vib_phase
                rate += rect + amp * np.sin(phase) * (np.sin(half) / half) + sigma * vib_unit[a:b]
            rate *= dt[a:b]
            rate += arw_deg[a:b]
            rate *= 3600.0 * p.scale_factor_pulses_per_arcsec  # now the angle in pulses
            start = self._acc if (carry_in and a == 0) else HALF_PULSE
            counts[a:b], self._acc = quantise_pulses(rate, start)
            self._running = b == n
        self._t_edge = float(t[-1])
        self._last_edges, self._last_over = t.copy(), over & valid
        self._prune(t[0])
        return counts

    def _ready_runs(self, t: np.ndarray):
        """(segment, a, b): intervals a..b-1 lie inside one powered segment after its boot.

        Segment indices of the edges are non-decreasing, so each segment's intervals are
        one contiguous range, and its ready ones a contiguous tail of it (minus an interval
        cut by the next change)."""
        starts = np.array([s.t_start for s in self._segments])
        lo_seg = max(0, int(np.searchsorted(starts, t[0], side="right")) - 1)
        hi_seg = int(np.searchsorted(starts, t[-1], side="right")) - 1
        for i in range(lo_seg, hi_seg + 1):
            seg = self._segments[i]
            if not seg.on:
                continue
            a = int(np.searchsorted(t, max(seg.t_start, seg.t_ready), side="left"))  # first edge ≥ ready
            if i + 1 < len(self._segments):  # the last edge ≤ the next change ends the run
                b = int(np.searchsorted(t, self._segments[i + 1].t_start, side="right")) - 1
            else:
                b = t.size - 1
            if b > a:
                yield seg, a, b

    def _deterministic_bias_dps(self, seg: _Segment, edges: np.ndarray, dt: np.ndarray) -> np.ndarray:
        """Interval means of the warm-up bias (exact integrals), °/s."""
        p = self.params
        out = np.zeros(dt.size)
        if p.warmup_amplitude_dph:
            e = np.exp(-(edges - seg.t_on) / p.warmup_tau_s)
            out += (p.warmup_amplitude_dph / 3600.0 * p.warmup_tau_s) * (e[:-1] - e[1:]) / dt
        return out

    def _thermal_terms(self, edges: np.ndarray, mids: np.ndarray) -> tuple[np.ndarray | float, np.ndarray | None]:
        """Interval means of the thermal bias (°/s, Simpson on edges and midpoints) and the
        scale-factor ratio at the midpoints (None when the unit has no SF temperature terms)."""
        p = self.params
        has_bias = bool(p.bias_tc_dph_per_c or p.bias_tc2_dph_per_c2 or p.bias_tc3_dph_per_c3
                        or p.bias_hysteresis_dph or p.shupe_dph_per_c_per_min)
        has_sf = bool(p.sf_tc_ppm_per_c or p.sf_tc2_ppm_per_c2 or p.sf_tc3_ppm_per_c3)
        if not (has_bias or has_sf):
            return 0.0, None
        n = mids.size
        t = np.empty(2 * n + 1)
        t[0::2], t[1::2] = edges, mids
        coil = self.body.element_c(t)
        bias: np.ndarray | float = 0.0
        if has_bias:
            memory = self.body.hysteresis_memory_c(t, coil) if p.bias_hysteresis_dph else coil
            rate = self.body.rates_c_per_s(t)[:, 1] if p.shupe_dph_per_c_per_min else np.zeros(t.size)
            b = p.thermal_bias_dps(coil, memory, rate)
            bias = (b[0:-1:2] + 4.0 * b[1::2] + b[2::2]) / 6.0
        return bias, (p.scale_factor_ratio(coil[1::2]) if has_sf else None)

    def _prune(self, t_first: float) -> None:
        """Forget supply segments that ended before the last call's first edge."""
        starts = [s.t_start for s in self._segments]
        keep = max(0, int(np.searchsorted(starts, t_first, side="right")) - 1)
        del self._segments[:keep]

    # ---- truth --------------------------------------------------------------------------
    def truth(self) -> dict:
        """True parameters of the unit (for recovery tests) and of the current run."""
        p, seg = self.params, self._segments[-1]
        out = asdict(p)
        sig, tau = self._flicker
        out.update({
            "run_bias_dph": seg.run_bias_dps * 3600.0 if seg.on else math.nan,
            "power_on_time_s": seg.t_on, "ready_time_s": seg.t_ready if seg.on else math.nan,
            "pulse_deg": p.pulse_deg, "arw_deg_per_rs": p.arw_deg_per_rs,
            "rrw_dps_per_rs": p.rrw_dps_per_rs,
            "bias_instability_adev_floor_dph": FLICKER_ADEV_FACTOR * p.bias_instability_dph,
            "flicker_sigma_dph": (sig * 3600.0).tolist(), "flicker_tau_s": tau.tolist(),
            "slow_knot_step_s": self._slow.step_s, "vib_resonance_phase_rad": self._vib_phase,
        })
        return out


def check_frame_edges(t_edges_s, last_edge_s: float | None) -> tuple[np.ndarray, np.ndarray]:
    """Frame interval edges (n+1 → n intervals) as an array with their widths: finite, 1-D,
    at least one edge, strictly increasing, not before ``last_edge_s`` (the previous call's
    last edge; None on the first call).  ValueError naming the fault otherwise."""
    t = np.asarray(t_edges_s, dtype=float)
    if t.ndim != 1 or t.size < 1 or not np.all(np.isfinite(t)):
        raise ValueError("t_edges_s must be a finite 1-D array of at least one edge")
    dt = np.diff(t)
    if dt.size and dt.min() <= 0.0:
        raise ValueError("t_edges_s must be strictly increasing")
    if last_edge_s is not None and t[0] < last_edge_s:
        raise ValueError(f"t_edges_s[0]={t[0]!r} s precedes the previous call's last edge {last_edge_s!r} s")
    return t, dt


def quantise_pulses(angle_pulses: np.ndarray, start: int) -> tuple[np.ndarray, int]:
    """Counts = changes of the rounded fixed-point accumulator; returns (counts, end state)."""
    fixed = np.rint(angle_pulses * float(1 << _FRAC_BITS)).astype(np.int64)
    n = fixed.size
    peak = float(np.abs(angle_pulses).max()) if n else 0.0
    chunk = n if peak * n < _MAX_SPAN_PULSES else max(1, int(_MAX_SPAN_PULSES // max(peak, 1.0)))
    counts = np.empty(n, dtype=np.int64)
    acc = start
    for a in range(0, n, chunk):  # one pass unless the span could overflow int64
        cum = np.cumsum(fixed[a:a + chunk])
        cum += acc
        whole = cum >> _FRAC_BITS  # floor division: arithmetic shift
        counts[a:a + chunk] = np.diff(whole, prepend=acc >> _FRAC_BITS)
        acc = int(cum[-1] & _FRAC_MASK)  # keep only the sub-pulse remainder
    return counts, acc
