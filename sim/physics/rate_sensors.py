"""The two coaxial angular-rate sensors of Document B's rig (issue 5) on the angular table.

* **MHD sensor** (high frequency): a magnetohydrodynamic angular-rate sensor, analog
  voltage output read by a digitizing DMM.  First-order high-pass at a few Hz (Document B:
  poor at low rates; ATA application note AN-01, "Extending the Frequency Response of the
  MHD Angular Rate Sensor", http://www.atasensors.com/ATAWeb/application_note_an01_rev_a.htm:
  designed for 1 Hz – 1 kHz, sensitivity falling ≥ 20 dB/decade toward 0 Hz), times an
  upper first-order low-pass well above 1 kHz.
* **LF sensor** (low frequency): a FOG/MEMS-class rate sensor with its digital output
  filter (second-order low-pass, tens of Hz), angle random walk, bias and a processing
  latency; its frames go out on the FOG serial line (docs/FOG_SERIAL.md) through
  :class:`LfGyroUnit`.

Both are :class:`sim.physics.rate_sensor_lti.LinearRateSensor` models: exact closed-form
responses to the table's :class:`~sim.physics.angular_piece.MotionPiece` motion.  The
continuous models are of the form ``bench.analysis.fusion._models.SensorModel`` fits (one
high-pass for the MHD, one low-pass for the LF sensor) plus the extras named here (the
MHD's upper pole, noise, bias/offset, latency).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace

import numpy as np

from sim.physics.gyro import HALF_PULSE, STATUS_OVER_RANGE, STATUS_READY, check_frame_edges, quantise_pulses
from sim.physics.rate_sensor_lti import LinearRateSensor, PiecesFn, Section, check_range

__all__ = ["LF_PRESET", "MHD_PRESET", "STATUS_OVER_RANGE", "STATUS_READY", "LfGyroUnit", "LfRateParams", "MhdParams",
           "lf_sensor", "mhd_sensor"]

RAD_TO_DEG = 180.0 / math.pi


@dataclass(frozen=True)
class MhdParams:
    """MHD angular-rate sensor (output in volts).  Figures and where they come from:

    * ``highpass_corner_hz`` 2.5, ``highpass_order`` 1 — Document B (poor at low frequency)
      and ATA AN-01 (1 Hz – 1 kHz design band, ≥ 20 dB/decade roll-off toward DC); the
      exact corner is a representative assumption;
    * ``lowpass_corner_hz`` 8000 (first order) — assumed: keeps the passband flat to
      ~1 kHz (−0.07 dB, −7° at 1 kHz);
    * ``sensitivity_v_per_rad_s`` 0.1 — assumed (an analog output of a few volts at tens of rad/s);
    * ``noise_rad_s_per_rthz`` 5e-5 (input-referred, one-sided) — assumed representative
      (≈ 1.6 mrad/s rms over 1 kHz); the output density is sensitivity × this;
    * ``offset_v`` 0.003 — assumed output offset of a few mV;
    * ``latency_s`` 0 — analog output, no processing delay.
    """

    highpass_corner_hz: float = 2.5
    highpass_order: int = 1
    highpass_zeta: float = math.sqrt(0.5)  # used by order 2 only
    lowpass_corner_hz: float = 8000.0
    sensitivity_v_per_rad_s: float = 0.1
    noise_rad_s_per_rthz: float = 5e-5
    offset_v: float = 0.003
    latency_s: float = 0.0

    def __post_init__(self):
        check_range("highpass_corner_hz", self.highpass_corner_hz, 0.01, 100.0)
        if self.highpass_order not in (1, 2):
            raise ValueError(f"highpass_order = {self.highpass_order!r} must be 1 or 2")
        check_range("highpass_zeta", self.highpass_zeta, 0.05, 10.0)
        check_range("lowpass_corner_hz", self.lowpass_corner_hz, 100.0, 1e6)
        if self.lowpass_corner_hz <= 10 * self.highpass_corner_hz:
            raise ValueError(f"lowpass_corner_hz = {self.lowpass_corner_hz!r} must be > 10 × "
                             f"highpass_corner_hz = {10 * self.highpass_corner_hz!r}")
        if not (math.isfinite(self.sensitivity_v_per_rad_s) and 1e-4 <= abs(self.sensitivity_v_per_rad_s) <= 100):
            raise ValueError(f"sensitivity_v_per_rad_s = {self.sensitivity_v_per_rad_s!r} must have a "
                             "magnitude in [0.0001, 100] (either sign)")
        check_range("noise_rad_s_per_rthz", self.noise_rad_s_per_rthz, 0.0, 1.0)
        check_range("offset_v", self.offset_v, -1.0, 1.0)
        check_range("latency_s", self.latency_s, 0.0, 0.1)

    def sections(self) -> list[Section]:
        return [Section("highpass", self.highpass_order, self.highpass_corner_hz, self.highpass_zeta),
                Section("lowpass", 1, self.lowpass_corner_hz)]

    def replace(self, **changes) -> MhdParams:
        return replace(self, **changes)


@dataclass(frozen=True)
class LfRateParams:
    """Low-frequency (FOG/MEMS-class) rate sensor, output in °/s.  Figures and sources:

    * ``corner_hz`` 40, ``order`` 2, ``zeta`` 0.7 — the unit's digital output filter; assumed
      representative of tactical FOG/MEMS units (tens of Hz bandwidth);
    * ``gain`` 1 (°/s per °/s);
    * ``arw_deg_per_rh`` 0.15 °/√h and ``bias_dph`` 0.5 °/h — representative tactical-grade
      figures (assumed);  no bias instability term is modelled;
    * ``latency_s`` 0.6 ms — assumed processing + frame delay;
    * ``frame_clock_error_ppm`` +20 — assumed error of the unit's frame clock (carried for
      the station's serial line; this model does not use it);
    * ``scale_factor_pulses_per_arcsec`` 10, ``full_scale_dps`` 500 — the frame line's
      nominal figures (as the FOG presets: pulses per arc-second), assumed;
    * ``temperature_c`` 25 — the constant coil temperature reported in the frames;
    * ``supply_min_v``/``supply_max_v`` 9–36 V — the rig's own supply range (assumed);
      the unit starts powered.
    """

    corner_hz: float = 40.0
    order: int = 2
    zeta: float = 0.7
    gain: float = 1.0
    arw_deg_per_rh: float = 0.15
    bias_dph: float = 0.5
    latency_s: float = 0.6e-3
    frame_clock_error_ppm: float = 20.0
    scale_factor_pulses_per_arcsec: float = 10.0
    full_scale_dps: float = 500.0
    temperature_c: float = 25.0
    supply_min_v: float = 9.0
    supply_max_v: float = 36.0

    def __post_init__(self):
        check_range("corner_hz", self.corner_hz, 0.1, 10000.0)
        if self.order not in (1, 2):
            raise ValueError(f"order = {self.order!r} must be 1 or 2")
        check_range("zeta", self.zeta, 0.05, 10.0)
        check_range("gain", self.gain, 0.1, 10.0)
        check_range("arw_deg_per_rh", self.arw_deg_per_rh, 0.0, 100.0)
        check_range("bias_dph", self.bias_dph, -1e5, 1e5)
        check_range("latency_s", self.latency_s, 0.0, 0.1)
        check_range("frame_clock_error_ppm", self.frame_clock_error_ppm, -1000.0, 1000.0)
        check_range("scale_factor_pulses_per_arcsec", self.scale_factor_pulses_per_arcsec, 0.01, 1000.0)
        check_range("full_scale_dps", self.full_scale_dps, 1.0, 10000.0)
        check_range("temperature_c", self.temperature_c, -55.0, 125.0)
        check_range("supply_min_v", self.supply_min_v, 0.0, 100.0, lo_open=True)
        check_range("supply_max_v", self.supply_max_v, self.supply_min_v, 100.0)

    @property
    def noise_density_dps_per_rthz(self) -> float:
        """One-sided output noise density (°/s/√Hz) of the ARW: a window mean of length d has
        σ = ARW/√d (°/√s over s), i.e. n/√(2d) with n = √2·ARW."""
        return math.sqrt(2.0) * self.arw_deg_per_rh / 60.0

    def sections(self) -> list[Section]:
        return [Section("lowpass", self.order, self.corner_hz, self.zeta)]

    def replace(self, **changes) -> LfRateParams:
        return replace(self, **changes)


MHD_PRESET = MhdParams()
LF_PRESET = LfRateParams()


def mhd_sensor(pieces: PiecesFn, rng: np.random.Generator | None, params: MhdParams = MHD_PRESET, *,
               t_origin_s: float | None = None, noise: bool = True) -> LinearRateSensor:
    """The MHD sensor on the table: ``mean_output(t_start_s, aperture_s)`` in volts is what a
    digitizing DMM integrating over its aperture reads.  ``noise=False``: no random noise
    (the offset stays)."""
    if not isinstance(params, MhdParams):
        raise TypeError("params must be an MhdParams (e.g. MHD_PRESET)")
    density = params.sensitivity_v_per_rad_s * params.noise_rad_s_per_rthz if noise else 0.0
    return LinearRateSensor(params.sections(), params.sensitivity_v_per_rad_s, pieces,
                            noise_density=abs(density), bias=params.offset_v, latency_s=params.latency_s,
                            rng=rng, t_origin_s=t_origin_s)


def lf_sensor(pieces: PiecesFn, rng: np.random.Generator | None, params: LfRateParams = LF_PRESET, *,
              t_origin_s: float | None = None, noise: bool = True) -> LinearRateSensor:
    """The LF sensor on the table, output in °/s (input rad/s)."""
    if not isinstance(params, LfRateParams):
        raise TypeError("params must be an LfRateParams (e.g. LF_PRESET)")
    return LinearRateSensor(params.sections(), params.gain * RAD_TO_DEG, pieces,
                            noise_density=params.noise_density_dps_per_rthz if noise else 0.0,
                            bias=params.bias_dph / 3600.0, latency_s=params.latency_s, rng=rng,
                            t_origin_s=t_origin_s)


class LfGyroUnit:
    """The LF sensor behind the FOG frame line: the ``gyro`` of a ``FogSerialDevice``.

    ``pulses(t_edges_s, …)`` returns, per frame interval, SF × 3600 × the exact integral of
    the sensor's output (°/s, noise and bias included) over the interval, quantised with
    the fractional remainder carried (``sim.physics.gyro``'s fixed-point accumulator, so
    the counts over any span sum to the integrated angle within ±1 pulse; the carry
    survives gaps, restarts at each power-on).  The table inputs ``FogSerialDevice``
    passes (``omega_sensor_dps``, ``f_sensor_g``, ``vibration_g_rms``) are **ignored**: the
    unit reads the angular table's motion through its own ``pieces`` source.  A frame
    whose mean output exceeds ±``full_scale_dps`` is clipped and flagged OVER_RANGE.

    Power: the angular rig powers the unit from its own supply — it starts powered.
    ``set_supply(t_s, volts)`` (what fault injection calls) switches it: powered while
    ``supply_min_v ≤ volts ≤ supply_max_v``; no boot time.  A frame outputs pulses only if
    the unit was powered throughout it.  Status: READY (0x01) while powered, OVER_RANGE
    (0x08) as above, 0 unpowered.  ``temperature_c`` is the constant ``params.temperature_c``.
    """

    def __init__(self, pieces: PiecesFn, rng: np.random.Generator | None, params: LfRateParams = LF_PRESET, *,
                 t_origin_s: float | None = None, noise: bool = True) -> None:
        self.params = params
        self.sensor = lf_sensor(pieces, rng, params, t_origin_s=t_origin_s, noise=noise)
        self._switch_t = np.array([-math.inf])  # supply switch instants and states after them
        self._switch_on = np.array([True])
        self._supply_v = 0.5 * (params.supply_min_v + params.supply_max_v)
        self._acc = HALF_PULSE
        self._running = False
        self._t_edge: float | None = None
        self._last_edges, self._last_over = np.empty(0), np.empty(0, dtype=bool)

    # ---- supply ----------------------------------------------------------------------------
    def set_supply(self, t_s: float, volts: float) -> None:
        """Supply ``volts`` from ``t_s`` on (times non-decreasing, not before the last edge)."""
        earliest = max(self._switch_t[-1], -math.inf if self._t_edge is None else self._t_edge)
        if not (math.isfinite(t_s) and t_s >= earliest):
            raise ValueError(f"t_s = {t_s!r} must be finite and ≥ {earliest!r} s")
        if not math.isfinite(volts):
            raise ValueError(f"volts = {volts!r} must be finite")
        self._supply_v = float(volts)
        on = self.params.supply_min_v <= volts <= self.params.supply_max_v
        if on != self._switch_on[-1]:
            self._switch_t = np.append(self._switch_t, float(t_s))
            self._switch_on = np.append(self._switch_on, on)
            self._running = False  # a power cycle restarts the pulse accumulator

    @property
    def supply_v(self) -> float:
        return self._supply_v

    def _segment(self, t) -> np.ndarray:
        return np.searchsorted(self._switch_t, np.asarray(t, dtype=float), side="right") - 1

    def powered(self, t_s):
        """Powered at ``t_s`` (scalar → bool, array → bool array)."""
        out = self._switch_on[self._segment(t_s)]
        return bool(out) if np.ndim(out) == 0 else out

    ready = powered  # no boot time

    def temperature_c(self, t_s):
        """The reported coil temperature (°C), constant."""
        t = np.asarray(t_s, dtype=float)
        return float(self.params.temperature_c) if t.ndim == 0 else np.full(t.shape, self.params.temperature_c)

    def status(self, t_s):
        """Status bits at ``t_s``: READY while powered, OVER_RANGE in the last call's clipped frames."""
        t = np.asarray(t_s, dtype=float)
        flat = np.atleast_1d(t)
        on = np.atleast_1d(self._switch_on[self._segment(flat)])
        out = np.where(on, STATUS_READY, 0).astype(np.int64)
        if self._last_over.size:
            k = np.searchsorted(self._last_edges, flat, side="left") - 1
            inside = (k >= 0) & (k < self._last_over.size)
            over = np.zeros(flat.shape, dtype=bool)
            over[inside] = self._last_over[k[inside]]
            out |= np.where(over & on, STATUS_OVER_RANGE, 0)
        return int(out[0]) if t.ndim == 0 else out.reshape(t.shape)

    # ---- output ----------------------------------------------------------------------------
    def pulses(self, t_edges_s, omega_sensor_dps=None, f_sensor_g=None, vibration_g_rms=0.0) -> np.ndarray:
        """Pulse counts (int64, n) over the n intervals between ``t_edges_s`` (n+1, strictly
        increasing, starting at or after the previous call's last edge).  The table
        arguments are accepted for interface compatibility and ignored."""
        t, dt = check_frame_edges(t_edges_s, self._t_edge)
        n = t.size - 1
        self._t_edge = float(t[-1])
        if n == 0:
            return np.zeros(0, dtype=np.int64)
        p = self.params
        mean_dps = self.sensor.mean_over_edges(t)
        over = np.abs(mean_dps) > p.full_scale_dps
        angle_pulses = np.clip(mean_dps, -p.full_scale_dps, p.full_scale_dps) * dt
        angle_pulses *= 3600.0 * p.scale_factor_pulses_per_arcsec
        seg = self._segment(t)
        valid = (seg[:-1] == seg[1:]) & self._switch_on[seg[:-1]]  # powered throughout the frame
        counts = np.zeros(n, dtype=np.int64)
        carry_in, self._running = self._running, False
        idx = np.flatnonzero(np.diff(np.concatenate([[0], valid.astype(np.int8), [0]])))
        for a, b in zip(idx[::2], idx[1::2]):  # runs of powered frames
            start = self._acc if (carry_in and a == 0) else HALF_PULSE
            counts[a:b], self._acc = quantise_pulses(angle_pulses[a:b], start)
            self._running = b == n
        self._last_edges, self._last_over = t.copy(), over & valid
        return counts

    def truth(self) -> dict:
        """The unit's parameters (for tests and reports)."""
        return asdict(self.params)
