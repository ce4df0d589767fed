"""Quartz flexure (Q-Flex QA-2000 class) accelerometer with its start-up transient.

Output model (IEEE Std 1293-1998 pendulous accelerometer model, all terms in g):

    E/K1 = K0 + a_i + K2 a_i² + K3 a_i³ + δo a_p − δp a_o + Kip a_i a_p + Kio a_i a_o
    I    = K1 · (E/K1 + start-up transient + drift + thermal bias + noise)

with a_i, a_p, a_o the specific force along the input, pendulous and output axes in
standard g, K1 in A/g. Start-up terms, t_on = the instant both supply rails came
within range (Document A: exponential + linear trend + coloured noise):

    transient(t)    = warmup_amplitude_g · exp(−(t − t_on)/warmup_tau_s)
    drift(t)        = drift_g_per_s · (t − t_on)
    thermal bias(t) = b₁ΔT + b₂ΔT² + b₃ΔT³                  ΔT = T_e − ambient_c (element)
                      + h·(T_e − m)/w                         hysteresis (play memory m, width w)
                      + k_grad·(T_c − T_e)                    case–element gradient
    turn-on bias    = bias_repeatability_g · z, a new standard normal z at each power-on
    noise           = Σ Gauss-Markov terms (point samples) + white noise averaged over
                      the reading's integration time (σ = N/√(2T), one-sided density N)

and K1 → K1·(1 + 10⁻⁶(s₁ΔT + s₂ΔT² + s₃ΔT³)) (scale factor over temperature).  The unit is
two thermal nodes (``sim.physics.thermal_unit``): the case, where the AD590 sits (the
temperature the unit reports), and the sensing element (proof mass, torquer), heated by
the servo's dissipation and lagging the case by ``element_tau_s``; their ambient is the
room (``ambient_c``) or, on the station, the chamber air.  Every power-on restarts the
transient and drift at full amplitude (the warm-up history is not modelled). Outside the
supply range the unit is off and outputs 0 A.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import asdict, dataclass, fields, replace

import numpy as np

from sim.physics.noise import GaussMarkov, WhiteNoise
from sim.physics.thermal_unit import AmbientSource, ConstantAmbient, TwoNodeBody, TwoNodeParams

_KELVIN_OFFSET = 273.15


@dataclass(frozen=True)
class AccelerometerParams:
    """True parameters of one unit. Defaults: a typical QA-2000-class unit.

    Datasheet-type figures quoted from memory of the Honeywell Q-Flex QA-2000 sheet
    (verify against the current sheet before relying on them): bias < 4 mg, bias
    temperature sensitivity < 30 µg/°C, scale factor 1.20-1.46 mA/g, axis misalignment
    < 70 µrad, second-order non-linearity < 20 µg/g², noise < 7 µg rms in 0-10 Hz,
    supply ±13 to ±18 V, quiescent current < 16 mA per rail, AD590-type temperature
    sensor 1 µA/K, operating range −55 to +95 °C. Values marked "assumed" are not on
    the sheet and were chosen to give a plausible start-up record.
    """

    k0_g: float = 20e-6  # bias after calibration residual (sheet: < 4 mg raw)
    k1_ma_per_g: float = 1.33  # scale factor (sheet: 1.20-1.46 mA/g)
    k2_g_per_g2: float = 10e-6  # second-order non-linearity (sheet: < 20 µg/g²)
    k3_g_per_g3: float = 1e-6  # third-order non-linearity (assumed)
    delta_o_rad: float = 50e-6  # input-axis misalignment toward PA, sensed from a_p (sheet: < 70 µrad)
    delta_p_rad: float = 50e-6  # input-axis misalignment toward OA, sensed from −a_o
    kip_g_per_g2: float = 5e-6  # cross-coupling a_i·a_p (assumed)
    kio_g_per_g2: float = 5e-6  # cross-coupling a_i·a_o (assumed)
    warmup_amplitude_g: float = 60e-6  # start-up exponential (assumed)
    warmup_tau_s: float = 180.0  # (assumed)
    drift_g_per_s: float = 1e-9  # linear start-up drift (assumed)
    bias_tc_g_per_c: float = 5e-6  # bias temperature coefficient (sheet: < 30 µg/°C)
    ambient_c: float = 23.0  # laboratory ambient; also the reference of the thermal polynomials
    self_heating_delta_c: float = 4.0  # case rise while powered (assumed, ~0.5 W dissipated)
    thermal_tau_s: float = 600.0  # dominant thermal time constant (assumed)
    # thermal model beyond the linear bias coefficient (all assumed; 0 here, drawn per serial)
    element_tau_s: float = 20.0  # sensing element ↔ case time constant (assumed)
    element_capacity_ratio: float = 0.3  # element / case heat capacity (assumed)
    bias_tc2_g_per_c2: float = 0.0  # b₂
    bias_tc3_g_per_c3: float = 0.0  # b₃
    sf_tc_ppm_per_c: float = 0.0  # s₁: scale factor over temperature
    sf_tc2_ppm_per_c2: float = 0.0  # s₂
    sf_tc3_ppm_per_c3: float = 0.0  # s₃
    bias_hysteresis_g: float = 0.0  # h: half the up-ramp/down-ramp bias difference
    hysteresis_width_c: float = 5.0  # w: reversal that switches the hysteresis fully over
    bias_gradient_g_per_c: float = 0.0  # k_grad: bias per °C of case − element gradient
    bias_repeatability_g: float = 0.0  # 1σ turn-on to turn-on bias
    gm_sigma_g: tuple[float, ...] = (4e-6,)  # coloured noise: Gauss-Markov σ per term (assumed)
    gm_tau_s: tuple[float, ...] = (20.0,)  # and correlation times (assumed)
    # Sheet: < 7 µg rms in 0-10 Hz -> N ≤ 7e-6/√10 = 2.2e-6 g/√Hz; take 2e-6.
    white_density_g_per_rthz: float = 2e-6
    supply_min_v: float = 13.0  # per rail magnitude
    supply_max_v: float = 18.0
    quiescent_current_a: float = 0.016  # per rail (sheet maximum, used as nominal)
    temp_sensor_a_per_k: float = 1e-6  # AD590 type

    def __post_init__(self):
        bounded = {  # name: (low, high), inclusive
            "k0_g": (-10e-3, 10e-3), "k1_ma_per_g": (1.0, 1.7), "k2_g_per_g2": (-1e-3, 1e-3),
            "k3_g_per_g3": (-1e-3, 1e-3), "delta_o_rad": (-0.01, 0.01), "delta_p_rad": (-0.01, 0.01),
            "kip_g_per_g2": (-1e-3, 1e-3), "kio_g_per_g2": (-1e-3, 1e-3),
            "warmup_amplitude_g": (-10e-3, 10e-3), "warmup_tau_s": (1e-3, 1e5),
            "drift_g_per_s": (-1e-6, 1e-6), "bias_tc_g_per_c": (-1e-3, 1e-3),
            "ambient_c": (-55.0, 95.0), "self_heating_delta_c": (0.0, 30.0),
            "thermal_tau_s": (1.0, 1e5), "white_density_g_per_rthz": (0.0, 1e-3),
            "element_tau_s": (0.1, 1e4), "element_capacity_ratio": (1e-3, 10.0),
            "bias_tc2_g_per_c2": (-1e-5, 1e-5), "bias_tc3_g_per_c3": (-1e-6, 1e-6),
            "sf_tc_ppm_per_c": (-1000.0, 1000.0), "sf_tc2_ppm_per_c2": (-50.0, 50.0),
            "sf_tc3_ppm_per_c3": (-1.0, 1.0), "bias_hysteresis_g": (0.0, 1e-3),
            "hysteresis_width_c": (0.1, 50.0), "bias_gradient_g_per_c": (-1e-3, 1e-3),
            "bias_repeatability_g": (0.0, 1e-3),
            "supply_min_v": (1.0, 30.0), "supply_max_v": (1.0, 30.0),
            "quiescent_current_a": (0.0, 0.1), "temp_sensor_a_per_k": (1e-7, 1e-5),
        }
        for name, (lo, hi) in bounded.items():
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and lo <= value <= hi):
                raise ValueError(f"{name}={value!r} outside the allowed range [{lo}, {hi}]")
        if not self.supply_min_v < self.supply_max_v:
            raise ValueError(f"supply_min_v={self.supply_min_v!r} must be < supply_max_v={self.supply_max_v!r}")
        if len(self.gm_sigma_g) != len(self.gm_tau_s) or len(self.gm_sigma_g) > 4:
            raise ValueError(f"gm_sigma_g={self.gm_sigma_g!r} and gm_tau_s={self.gm_tau_s!r} "
                             "must have the same length, at most 4")
        for s in self.gm_sigma_g:
            if not 0.0 <= s <= 1e-3:
                raise ValueError(f"gm_sigma_g entry {s!r} outside the allowed range [0, 1e-3]")
        for tau in self.gm_tau_s:
            if not 1e-3 <= tau <= 1e6:
                raise ValueError(f"gm_tau_s entry {tau!r} outside the allowed range [1e-3, 1e6]")
        self.thermal_nodes()  # element_tau_s must be the fast node: checked there

    @property
    def k1_a_per_g(self) -> float:
        return self.k1_ma_per_g * 1e-3

    def thermal_nodes(self) -> TwoNodeParams:
        """The unit's case and element nodes (``sim.physics.thermal_unit``)."""
        return TwoNodeParams(self.thermal_tau_s, self.element_tau_s, self.element_capacity_ratio,
                             self.self_heating_delta_c, self.hysteresis_width_c)

    def thermal_bias_g(self, case_c: np.ndarray, element_c: np.ndarray, memory_c: np.ndarray) -> np.ndarray:
        """Bias over temperature (g): polynomial of the element, hysteresis, gradient."""
        d = element_c - self.ambient_c
        return (d * (self.bias_tc_g_per_c + d * (self.bias_tc2_g_per_c2 + d * self.bias_tc3_g_per_c3))
                + self.bias_hysteresis_g / self.hysteresis_width_c * (element_c - memory_c)
                + self.bias_gradient_g_per_c * (case_c - element_c))

    def scale_factor_ratio(self, element_c: np.ndarray) -> np.ndarray:
        """K1(T)/K1 at element temperatures (°C)."""
        d = element_c - self.ambient_c
        return 1.0 + 1e-6 * d * (self.sf_tc_ppm_per_c + d * (self.sf_tc2_ppm_per_c2 + d * self.sf_tc3_ppm_per_c3))


#: Manufacturing spread of the simulated QA-2000-class population: field -> (kind, centre, spread).
#: "normal": centre ± σ; "lognormal": median × exp(σ·z). The data-sheet limits the acceptance
#: spec uses (|K0| < 4 mg, K1 1.20–1.46 mA/g, |K2| < 20 µg/g², |δ| < 70 µrad, noise < 7 µg rms
#: in 0–10 Hz i.e. N < 2.2 µg/√Hz) sit at 2.3–2.9 σ of these, so about 6 % of units fail one.
ACCELEROMETER_SPREAD: dict[str, tuple[str, float, float]] = {
    "k0_g": ("normal", 0.0, 1.5e-3),
    "k1_ma_per_g": ("normal", 1.33, 0.045),
    "k2_g_per_g2": ("normal", 0.0, 8e-6),
    "k3_g_per_g3": ("normal", 0.0, 2e-6),        # assumed
    "delta_o_rad": ("normal", 0.0, 30e-6),
    "delta_p_rad": ("normal", 0.0, 30e-6),
    "kip_g_per_g2": ("normal", 0.0, 5e-6),       # assumed
    "kio_g_per_g2": ("normal", 0.0, 5e-6),       # assumed
    "warmup_amplitude_g": ("normal", 60e-6, 25e-6),  # assumed
    "warmup_tau_s": ("lognormal", 180.0, 0.3),   # assumed
    "drift_g_per_s": ("normal", 1e-9, 1e-9),     # assumed
    "bias_tc_g_per_c": ("normal", 0.0, 10e-6),
    "white_density_g_per_rthz": ("lognormal", 1.2e-6, 0.25),
}

#: Thermal spread (issue 14), drawn from its own stream of the serial so the draws above never
#: change. All assumed, QA-2000-class orders of magnitude: over −40…+70 °C the polynomial's
#: 2nd and 3rd order terms reach ~100 µg, the scale factor ~±200 ppm; hysteresis 2h ≈ 20 µg.
#: The scale factor's coefficients are kept small (3 ppm/°C, a unit with a compensated torquer):
#: with 1 g on the input axis the self-heating's ~5 °C shows as s₁·5 °C of warm-up drift, and the
#: room-temperature specs' warm-up limits (turn-on within 20 µg, drift ±150 µg) assume little.
ACCELEROMETER_THERMAL_SPREAD: dict[str, tuple[str, float, float]] = {
    "bias_tc2_g_per_c2": ("normal", 0.0, 0.05e-6),
    "bias_tc3_g_per_c3": ("normal", 0.0, 0.8e-9),
    "sf_tc_ppm_per_c": ("normal", 0.0, 3.0),
    "sf_tc2_ppm_per_c2": ("normal", 0.0, 0.015),
    "sf_tc3_ppm_per_c3": ("normal", 0.0, 0.0003),
    "bias_hysteresis_g": ("lognormal", 10e-6, 0.4),
    "hysteresis_width_c": ("lognormal", 6.0, 0.2),
    "bias_gradient_g_per_c": ("normal", 0.0, 4e-6),
    "bias_repeatability_g": ("lognormal", 12e-6, 0.3),
    "element_tau_s": ("lognormal", 20.0, 0.2),
}


def _draw(rng: np.random.Generator, spread: dict[str, tuple[str, float, float]]) -> dict[str, float]:
    drawn = {}
    for name, (kind, centre, width) in spread.items():  # fixed order: stable draws
        z = float(rng.standard_normal())
        drawn[name] = centre * math.exp(width * z) if kind == "lognormal" else centre + width * z
    return drawn


def draw_accelerometer(serial: str, overrides: dict | None = None) -> AccelerometerParams:
    """The unit with serial number ``serial``: drawn from :data:`ACCELEROMETER_SPREAD`.

    Seeded by the serial alone (crc32 → SeedSequence), so the same serial is the same unit on
    every station and seed, and different serials are different units. ``overrides`` (field →
    value) replace drawn values, e.g. a station file pinning one unit's parameters.
    """
    if not isinstance(serial, str) or not serial:
        raise ValueError(f"serial {serial!r} must be non-empty text")
    def stream(label: bytes) -> np.random.Generator:
        return np.random.Generator(np.random.PCG64(np.random.SeedSequence(
            [zlib.crc32(label), zlib.crc32(serial.encode("utf-8"))])))

    drawn = _draw(stream(b"accelerometer"), ACCELEROMETER_SPREAD)
    drawn.update(_draw(stream(b"accelerometer-thermal"), ACCELEROMETER_THERMAL_SPREAD))
    known = {f.name for f in fields(AccelerometerParams)}
    unknown = set(overrides or {}) - known
    if unknown:
        raise ValueError(f"accelerometer parameter(s) {sorted(unknown)} unknown; allowed: {sorted(known)}")
    return replace(AccelerometerParams(), **{**drawn, **(overrides or {})})


def indicated_acceleration_g(p: AccelerometerParams, f_iapo_g: np.ndarray) -> np.ndarray:
    """IEEE 1293 static model E/K1 in g for specific force rows (a_i, a_p, a_o) in g."""
    f = np.asarray(f_iapo_g, dtype=float)
    if f.ndim != 2 or f.shape[1] != 3:
        raise ValueError(f"f_iapo_g must have shape (n, 3), got {f.shape}")
    if f.shape[0] > 1 and f.strides[0] == 0:  # a static input broadcast over time: once
        return np.full(f.shape[0], indicated_acceleration_g(p, f[:1])[0])
    ai, ap, ao = f[:, 0], f[:, 1], f[:, 2]
    return (p.k0_g + ai + p.k2_g_per_g2 * ai**2 + p.k3_g_per_g3 * ai**3
            + p.delta_o_rad * ap - p.delta_p_rad * ao
            + p.kip_g_per_g2 * ai * ap + p.kio_g_per_g2 * ai * ao)


def _child_generators(rng: np.random.Generator, n: int) -> list[np.random.Generator]:
    """Independent child streams, so each noise term's draws never interleave with another's."""
    try:
        return rng.spawn(n)
    except (TypeError, ValueError):  # generator built without a SeedSequence: seed from its stream
        return [np.random.default_rng(int(s)) for s in rng.integers(0, 2**63, size=n)]


class QuartzAccelerometer:
    """One accelerometer: supply, thermal nodes, start-up transient and seeded noise.

    Times are simulated seconds. ``set_supply`` calls come at non-decreasing times;
    evaluations at times ≥ the last supply change. ``output_current_a`` continues the
    noise processes sequentially, so its times must also be non-decreasing across calls;
    the noise is drawn for every sample, powered or not, so the stream never depends on
    the power history. Each noise term gets its own child generator of ``rng``; the turn-on
    bias draws come from ``turn_on_rng`` (default: one more child of ``rng``), so adding them
    changed no other stream.  ``ambient``: the air around the unit (default: the still room
    at ``ambient_c``; on the station, the chamber air).
    Time inputs are promoted to 1-D arrays; every output is a 1-D array over time.
    """

    def __init__(self, params: AccelerometerParams | None, rng: np.random.Generator,
                 ambient: AmbientSource | None = None, turn_on_rng: np.random.Generator | None = None):
        if not isinstance(rng, np.random.Generator):
            raise TypeError("rng must be a numpy.random.Generator (no global RNG is used)")
        self.params = params if params is not None else AccelerometerParams()  # None: defaults
        p = self.params
        children = _child_generators(rng, len(p.gm_sigma_g) + 1)
        self._gm = [GaussMarkov(s, tau, g) for s, tau, g in zip(p.gm_sigma_g, p.gm_tau_s, children)]
        self._white = WhiteNoise(p.white_density_g_per_rthz, children[-1])
        self._turn_on_rng = turn_on_rng if turn_on_rng is not None else _child_generators(rng, 1)[0]
        self.body = TwoNodeBody(p.thermal_nodes(), ambient if ambient is not None else ConstantAmbient(p.ambient_c))
        self._powered = False
        self._t_change = 0.0  # last supply change
        self._t_on = math.nan  # last power-on time
        self._run_bias_g = 0.0  # this power-on's turn-on bias
        self._runs: list[tuple[float, float]] = []  # (t_on, turn-on bias) of every power-on
        self._supply_v = (0.0, 0.0)

    # ---- supply -------------------------------------------------------------------------
    def supply_in_range(self, v_pos: float, v_neg: float) -> bool:
        """Both rails within [supply_min_v, supply_max_v] in magnitude, v_neg negative."""
        lo, hi = self.params.supply_min_v, self.params.supply_max_v
        return lo <= v_pos <= hi and lo <= -v_neg <= hi

    def set_supply(self, t: float, v_pos: float, v_neg: float) -> None:
        """Apply rail voltages (V, v_neg < 0) at time ``t``; entering range is power-on."""
        t = float(t)
        if not (math.isfinite(t) and t >= self._t_change):
            raise ValueError(f"t={t!r} s must be finite and ≥ the last supply change at {self._t_change!r} s")
        if not (math.isfinite(v_pos) and math.isfinite(v_neg)):
            raise ValueError(f"rail voltages must be finite, got {v_pos!r}, {v_neg!r}")
        on = self.supply_in_range(v_pos, v_neg)
        self._supply_v = (float(v_pos), float(v_neg))
        if on == self._powered:
            return
        self._t_change, self._powered = t, on
        if on:
            self._t_on = t
            self._run_bias_g = self.params.bias_repeatability_g * float(self._turn_on_rng.standard_normal())
            self._runs.append((t, self._run_bias_g))
        self.body.set_power(t, on)

    @property
    def last_supply_change_s(self) -> float:
        """Time of the last power state change; evaluations must not precede it."""
        return self._t_change

    @property
    def power_on_time_s(self) -> float:
        """Time of the last power-on (NaN if never powered)."""
        return self._t_on

    def _times(self, t) -> np.ndarray:
        arr = np.atleast_1d(np.asarray(t, dtype=float))
        if arr.ndim != 1 or not np.all(np.isfinite(arr)):
            raise ValueError("times must be a finite 1-D array")
        if arr.size and arr.min() < self._t_change:
            raise ValueError(f"time {arr.min()!r} s precedes the last supply change at {self._t_change!r} s")
        return arr

    def powered(self, t) -> np.ndarray:
        """Boolean per time: both rails in range (constant after the last change)."""
        return np.full(self._times(t).shape, self._powered)

    # ---- outputs ------------------------------------------------------------------------
    def temperature_c(self, t) -> np.ndarray:
        """The case temperature in °C, where the AD590 sits (the unit's own reading)."""
        return self.body.case_c(self._times(t))

    def element_temperature_c(self, t) -> np.ndarray:
        """The sensing element's temperature in °C (what the bias and scale factor follow)."""
        return self.body.element_c(self._times(t))

    def temp_sensor_current_a(self, t) -> np.ndarray:
        """AD590-type sensor current: 1 µA/K × absolute temperature (needs only its own excitation)."""
        return self.params.temp_sensor_a_per_k * (self.temperature_c(t) + _KELVIN_OFFSET)

    def supply_current_a(self, t) -> np.ndarray:
        """Current drawn from each rail in A (magnitude, the same on + and −): the quiescent
        current while powered. The output current's share of the rails is not modelled."""
        return self.powered(t).astype(float) * self.params.quiescent_current_a

    def _thermal_state(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        nodes = self.body.nodes_c(t)
        case, element = nodes[:, 0], nodes[:, 1]
        memory = self.body.hysteresis_memory_c(t, element) if self.params.bias_hysteresis_g else element
        return case, element, memory

    def _bias_g(self, t: np.ndarray, t_on: float, run_bias_g: float, thermal: tuple) -> np.ndarray:
        p, since = self.params, t - t_on
        transient = p.warmup_amplitude_g * np.exp(-since / p.warmup_tau_s)
        return transient + p.drift_g_per_s * since + p.thermal_bias_g(*thermal) + run_bias_g

    def startup_terms_g(self, t) -> np.ndarray:
        """Deterministic bias beyond K0 (transient + drift + thermal + turn-on) in g; 0 unpowered."""
        t = self._times(t)
        if not self._powered:
            return np.zeros(t.shape)
        return self._bias_g(t, self._t_on, self._run_bias_g, self._thermal_state(t))

    def bias_truth_g(self, t) -> np.ndarray:
        """Truth for tests (never for procedures): the deterministic bias beyond K0 the unit had at
        any past powered time (that power-on's transient, drift, turn-on bias and the thermal terms)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        starts = np.array([r[0] for r in self._runs])
        k = np.searchsorted(starts, t, side="right") - 1
        if not starts.size or k.min() < 0:
            raise ValueError("bias_truth_g needs times after the first power-on")
        thermal = self._thermal_state(t)
        return self._bias_g(t, starts[k], np.array([r[1] for r in self._runs])[k], thermal)

    def scale_factor_truth(self, t) -> np.ndarray:
        """Truth for tests: K1(T)/K1 at past times (the element's temperature then)."""
        return self.params.scale_factor_ratio(self.body.element_c(np.atleast_1d(np.asarray(t, dtype=float))))

    def output_current_a(self, t, f_iapo_g, averaging_time_s: float, *, noise: bool = True) -> np.ndarray:
        """Output current in A at times ``t`` for specific force rows (a_i, a_p, a_o) in g.

        Each value is a reading averaged over ``averaging_time_s`` (sets the white-noise σ).
        ``noise=False`` gives the noise-free model without touching the noise streams.
        """
        t = self._times(t)
        self._white.sigma(averaging_time_s)  # validates the integration time
        f = np.asarray(f_iapo_g, dtype=float)
        if f.shape != (t.size, 3):
            raise ValueError(f"f_iapo_g must have shape ({t.size}, 3), got {f.shape}")
        g_units = indicated_acceleration_g(self.params, f)
        k1: float | np.ndarray = self.params.k1_a_per_g
        if self._powered:
            thermal = self._thermal_state(t)
            g_units = g_units + self._bias_g(t, self._t_on, self._run_bias_g, thermal)
            k1 = k1 * self.params.scale_factor_ratio(thermal[1])
        if noise:
            g_units = g_units + self._white.sample(t.size, averaging_time_s)
            for gm in self._gm:
                g_units = g_units + gm.sample(t)
        return np.where(self._powered, k1 * g_units, 0.0)

    def truth(self) -> dict:
        """True parameters (for estimator-recovery tests) plus the power-on time."""
        out = asdict(self.params)
        out["k1_a_per_g"] = self.params.k1_a_per_g
        out["power_on_time_s"] = self._t_on
        out["white_sigma_1s_g"] = self._white.sigma(1.0)
        nodes = self.params.thermal_nodes()
        out["run_bias_g"] = self._run_bias_g  # the last power-on's turn-on bias draw
        out["case_tau_s"] = nodes.case_tau_s
        out["element_rise_over_case_c"] = nodes.element_rise_over_case_c
        out["temperature_sensor_node"] = "case"
        return out
