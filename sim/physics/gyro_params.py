"""Parameters of the simulated fibre-optic gyro (FOG): the dataclass and two grade presets.

Conventions (IEEE Std 952-1997, single-axis interferometric FOG):

* Rates in °/s (``_dps``) or °/h (``_dph``); angles in degrees; times in seconds.
* Indicated rate, ω the input rate along the misaligned input axis (IA), clipped to ±FS:

      ω_out = B(t) + ω·(1 + ε + (A/2)·sign ω) + n·FS·(ω/FS)³ + noise

  so SF+ − SF− = A·SF (asymmetry) and n is the coefficient of the cubic term
  (``nonlinearity_ppm``; over a rate set spread uniformly across ±FS the worst residual
  from the least-squares line is 0.4·n ppm of FS).
* Misalignment: ω = ω₁ + θ₂·ω₂ + θ₃·ω₃ (IA tilted by θ₂ toward the second sensor axis
  and θ₃ toward the third, small angles in rad).
* Noise coefficients in the IEEE 952 Allan-variance sense (its PSDs are two-sided):
  ARW N: σ_ADEV(τ) = N/√τ; bias instability B: the flicker ADEV plateau 0.664·B, realised
  as equal-variance Gauss-Markov terms with correlation times log-spaced (at most a decade
  apart) over [flicker_tau_min_s, flicker_tau_max_s]; RRW K: σ_ADEV(τ) = K·√(τ/3).

Sources of the preset figures: El-Sheimy & Youssef, "Inertial sensors technologies for
navigation applications: state of the art and future trends", Satellite Navigation 1, 2
(2020), Table 1 (gyro drift: tactical 1-10 °/h, navigation < 0.01 °/h; random walk:
navigation < 0.002 °/√h); the tactical FOG datasheet class (bias instability ~1 °/h,
ARW 0.05-0.1 °/√h, e.g. KVH DSP-series-type units: ±490 °/s, 9-36 V). Everything marked
"assumed" is an order-of-magnitude choice, not from a sheet.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from sim.physics.thermal_unit import TwoNodeParams

_DPH_PER_DPS = 3600.0
#: Spacing of the flicker approximation: one Gauss-Markov term per decade keeps the ADEV
#: plateau within −6 %/+0 % of 0.664·B between 3·tau_min and 0.6·tau_max.
_FLICKER_TERMS_PER_DECADE = 1.0
#: Flicker ADEV plateau per unit B (IEEE 952: sqrt(2 ln 2 / π)).
FLICKER_ADEV_FACTOR = math.sqrt(2.0 * math.log(2.0) / math.pi)

_VEC_FIELDS = {  # name: (length, low, high)
    "g_sensitivity_dph_per_g": (3, -100.0, 100.0),
    "misalignment_rad": (2, -0.05, 0.05),
    "vib_rectification_dph_per_g2": (3, -100.0, 100.0),
    "vib_resonance_dps_per_grms": (3, 0.0, 10.0),
    "vib_noise_dps_per_grms": (3, 0.0, 10.0),
}

_BOUNDS = {  # name: (low, high), inclusive
    "scale_factor_pulses_per_arcsec": (0.01, 1000.0), "scale_factor_error_ppm": (-1e5, 1e5),
    "asymmetry_ppm": (-1e4, 1e4), "nonlinearity_ppm": (-1e4, 1e4), "full_scale_dps": (1.0, 5000.0),
    "bias_dph": (-1000.0, 1000.0), "bias_repeatability_dph": (0.0, 100.0),
    "arw_deg_per_rh": (0.0, 10.0), "bias_instability_dph": (0.0, 100.0),
    "flicker_tau_min_s": (0.01, 1e6), "flicker_tau_max_s": (0.1, 1e8),
    "rrw_dph_per_rh": (0.0, 100.0), "bias_tc_dph_per_c": (-10.0, 10.0),
    "warmup_amplitude_dph": (-1000.0, 1000.0), "warmup_tau_s": (1e-3, 1e5), "boot_time_s": (0.0, 600.0),
    "ambient_c": (-55.0, 95.0), "self_heating_delta_c": (0.0, 30.0), "thermal_tau_s": (1.0, 1e5),
    "supply_min_v": (0.5, 60.0), "supply_max_v": (0.5, 60.0), "supply_current_a": (0.0, 10.0),
    "temp_sensor_offset_c": (-10.0, 10.0), "operating_min_c": (-100.0, 200.0),
    "element_tau_s": (0.1, 1e4), "element_capacity_ratio": (1e-3, 10.0),
    "bias_tc2_dph_per_c2": (-1.0, 1.0), "bias_tc3_dph_per_c3": (-0.1, 0.1),
    "sf_tc_ppm_per_c": (-1000.0, 1000.0), "sf_tc2_ppm_per_c2": (-50.0, 50.0), "sf_tc3_ppm_per_c3": (-1.0, 1.0),
    "bias_hysteresis_dph": (0.0, 100.0), "hysteresis_width_c": (0.1, 50.0),
    "shupe_dph_per_c_per_min": (-100.0, 100.0),
    "operating_max_c": (-100.0, 200.0), "vib_resonance_hz": (0.1, 1e5), "vib_noise_tau_s": (1e-5, 10.0),
}


@dataclass(frozen=True)
class GyroParams:
    """True parameters of one FOG. Defaults: the tactical preset (a typical unit)."""

    # nominal output scale factor: pulses per arc-second of angle (assumed: 0.1″ pulses)
    scale_factor_pulses_per_arcsec: float = 10.0
    scale_factor_error_ppm: float = 150.0  # ε (assumed, limit ±500)
    asymmetry_ppm: float = 30.0  # A = (SF+ − SF−)/SF (assumed, limit ±100)
    nonlinearity_ppm: float = 40.0  # n, cubic coefficient (assumed, limit ±100)
    full_scale_dps: float = 490.0  # (tactical FOG class)
    bias_dph: float = 1.0  # turn-on bias (drift class 1-10 °/h, El-Sheimy 2020; limit ±3)
    bias_repeatability_dph: float = 0.3  # 1σ turn-on to turn-on, drawn per power-on (assumed)
    arw_deg_per_rh: float = 0.05  # N (tactical FOG class 0.05-0.1 °/√h)
    bias_instability_dph: float = 0.5  # IEEE 952 B (class ~1 °/h; ADEV plateau 0.33 °/h)
    flicker_tau_min_s: float = 10.0  # flicker correlation-time range (assumed)
    flicker_tau_max_s: float = 1e4
    rrw_dph_per_rh: float = 0.3  # K (assumed)
    bias_tc_dph_per_c: float = 0.02  # bias temperature coefficient vs (T_coil − ambient) (assumed)
    g_sensitivity_dph_per_g: tuple[float, float, float] = (0.3, -0.2, 0.1)  # per sensor axis (assumed)
    misalignment_rad: tuple[float, float] = (3e-4, -2e-4)  # θ₂, θ₃ (assumed, limit 1 mrad)
    warmup_amplitude_dph: float = 2.0  # start-up exponential (assumed)
    warmup_tau_s: float = 120.0  # (assumed)
    boot_time_s: float = 1.0  # power-on to valid output (assumed)
    ambient_c: float = 23.0  # laboratory ambient
    self_heating_delta_c: float = 6.0  # case rise while powered (assumed, ~3 W)
    thermal_tau_s: float = 900.0  # dominant thermal time constant (assumed)
    # thermal model (issue 14): the unit is a case node (frame temperature sensor) and the coil
    # (sensing element), sim/physics/thermal_unit.py; coefficients 0 here, drawn per serial
    element_tau_s: float = 60.0  # coil ↔ case time constant (assumed)
    element_capacity_ratio: float = 0.5  # coil / case heat capacity (assumed)
    bias_tc2_dph_per_c2: float = 0.0  # bias over (T_coil − ambient)²
    bias_tc3_dph_per_c3: float = 0.0  # and ³
    sf_tc_ppm_per_c: float = 0.0  # scale factor over temperature, 1st..3rd order
    sf_tc2_ppm_per_c2: float = 0.0
    sf_tc3_ppm_per_c3: float = 0.0
    bias_hysteresis_dph: float = 0.0  # half the up-ramp/down-ramp bias difference
    hysteresis_width_c: float = 5.0  # reversal that switches the hysteresis fully over
    shupe_dph_per_c_per_min: float = 0.0  # Shupe effect: bias per °C/min of coil temperature rate
    supply_min_v: float = 9.0  # (tactical FOG class, 9-36 V)
    supply_max_v: float = 36.0
    supply_current_a: float = 0.25  # at 12 V (assumed)
    temp_sensor_offset_c: float = 0.0  # on-board sensor reading − coil temperature
    operating_min_c: float = -40.0  # (assumed, MIL-type range)
    operating_max_c: float = 71.0
    # random vibration (Document C): rectified bias Σ kᵢ gᵢ², a structural resonance
    # aᵢ gᵢ sin(2πf t + φ), coloured Gauss-Markov rate noise of σ = |cᵢ gᵢ|; gᵢ = g rms
    # along sensor axis i (all assumed)
    vib_rectification_dph_per_g2: tuple[float, float, float] = (0.05, 0.02, 0.02)
    vib_resonance_hz: float = 450.0
    vib_resonance_dps_per_grms: tuple[float, float, float] = (0.002, 0.001, 0.001)
    vib_noise_dps_per_grms: tuple[float, float, float] = (0.003, 0.0015, 0.0015)
    vib_noise_tau_s: float = 0.002

    def __post_init__(self):
        for name, (lo, hi) in _BOUNDS.items():
            value = getattr(self, name)
            if isinstance(value, bool) or not (isinstance(value, (int, float)) and lo <= value <= hi):
                raise ValueError(f"{name}={value!r} outside the allowed range [{lo}, {hi}]")
        for name, (length, lo, hi) in _VEC_FIELDS.items():
            value = getattr(self, name)
            try:
                items = tuple(float(v) for v in value)
            except (TypeError, ValueError):
                raise ValueError(f"{name}={value!r} must be {length} numbers in [{lo}, {hi}]") from None
            if len(items) != length or not all(lo <= v <= hi for v in items):
                raise ValueError(f"{name}={value!r} must be {length} numbers in [{lo}, {hi}]")
            object.__setattr__(self, name, items)  # store as a tuple of floats (hashable)
        for low, high in (("supply_min_v", "supply_max_v"), ("operating_min_c", "operating_max_c")):
            if not getattr(self, low) < getattr(self, high):
                raise ValueError(f"{low}={getattr(self, low)!r} must be < {high}={getattr(self, high)!r}")
        ratio = self.flicker_tau_max_s / self.flicker_tau_min_s
        if not 10.0 <= ratio <= 1e6:
            raise ValueError(f"flicker_tau_max_s/flicker_tau_min_s={ratio!r} "
                             "outside the allowed range [10, 1e6]")
        self.thermal_nodes()  # element_tau_s must be the fast node: checked there

    def thermal_nodes(self) -> TwoNodeParams:
        """The unit's case and coil nodes (``sim.physics.thermal_unit``)."""
        return TwoNodeParams(self.thermal_tau_s, self.element_tau_s, self.element_capacity_ratio,
                             self.self_heating_delta_c, self.hysteresis_width_c)

    def thermal_bias_dps(self, coil_c: np.ndarray, memory_c: np.ndarray, coil_rate_c_per_s: np.ndarray) -> np.ndarray:
        """Bias over temperature (°/s): polynomial of the coil, hysteresis, Shupe (∝ dT_coil/dt)."""
        d = coil_c - self.ambient_c
        dph = (d * (self.bias_tc_dph_per_c + d * (self.bias_tc2_dph_per_c2 + d * self.bias_tc3_dph_per_c3))
               + self.bias_hysteresis_dph / self.hysteresis_width_c * (coil_c - memory_c)
               + self.shupe_dph_per_c_per_min * 60.0 * coil_rate_c_per_s)
        return dph / _DPH_PER_DPS

    def scale_factor_ratio(self, coil_c: np.ndarray) -> np.ndarray:
        """SF(T)/SF at coil temperatures (°C)."""
        d = coil_c - self.ambient_c
        return 1.0 + 1e-6 * d * (self.sf_tc_ppm_per_c + d * (self.sf_tc2_ppm_per_c2 + d * self.sf_tc3_ppm_per_c3))

    def replace(self, **changes) -> GyroParams:
        """A copy with some fields changed (validated)."""
        values = {f.name: getattr(self, f.name) for f in fields(self)}
        unknown = set(changes) - set(values)
        if unknown:
            raise ValueError(f"unknown GyroParams fields {sorted(unknown)}; allowed: {sorted(values)}")
        values.update(changes)
        return GyroParams(**values)

    @property
    def pulse_deg(self) -> float:
        """Angle of one output pulse at the nominal scale factor, degrees."""
        return 1.0 / (3600.0 * self.scale_factor_pulses_per_arcsec)

    @property
    def arw_deg_per_rs(self) -> float:
        """N in °/√s (angle increments over dt have σ = N·√dt)."""
        return self.arw_deg_per_rh / 60.0

    @property
    def rrw_dps_per_rs(self) -> float:
        """K in °/s/√s (Var[b(t) − b(s)] = K²·|t − s|)."""
        return self.rrw_dph_per_rh / _DPH_PER_DPS / 60.0


TACTICAL = GyroParams()

NAVIGATION = GyroParams(
    scale_factor_pulses_per_arcsec=20.0,  # assumed: 0.05″ pulses
    scale_factor_error_ppm=15.0, asymmetry_ppm=3.0, nonlinearity_ppm=5.0,  # assumed (limits 50/10/20)
    full_scale_dps=400.0,  # assumed
    bias_dph=0.01,  # assumed (limit ±0.05)
    bias_repeatability_dph=0.003,  # assumed
    arw_deg_per_rh=0.0012,  # navigation < 0.002 °/√h (El-Sheimy 2020)
    bias_instability_dph=0.005,  # navigation drift < 0.01 °/h (El-Sheimy 2020)
    flicker_tau_min_s=100.0, flicker_tau_max_s=1e5,  # assumed
    rrw_dph_per_rh=0.002,  # assumed
    bias_tc_dph_per_c=0.0003,  # assumed (after internal compensation)
    g_sensitivity_dph_per_g=(0.005, -0.003, 0.002), misalignment_rad=(5e-5, -3e-5),  # assumed
    warmup_amplitude_dph=0.02, warmup_tau_s=600.0, boot_time_s=5.0,  # assumed
    self_heating_delta_c=8.0, thermal_tau_s=1800.0,  # assumed
    supply_min_v=18.0, supply_max_v=32.0, supply_current_a=0.4,  # assumed (28 V avionics class)
    vib_rectification_dph_per_g2=(0.002, 0.001, 0.001), vib_resonance_hz=620.0,
    vib_resonance_dps_per_grms=(2e-4, 1e-4, 1e-4), vib_noise_dps_per_grms=(3e-4, 1.5e-4, 1.5e-4),
    vib_noise_tau_s=0.002,  # vibration terms assumed, ~10× below tactical
)

GRADES = {"tactical": TACTICAL, "navigation": NAVIGATION}


def flicker_terms(p: GyroParams) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Markov (σ in °/s, τ in s) terms whose sum approximates flicker of coefficient B.

    Equal variances s² with log-spaced correlation times of ratio r give a one-sided PSD
    ≈ s²/(f ln r); IEEE 952's flicker (two-sided B²/(2π f)) is one-sided B²/(π f), so
    s² = B² ln r / π. Empty arrays when B = 0.
    """
    if p.bias_instability_dph == 0.0:
        return np.empty(0), np.empty(0)
    decades = math.log10(p.flicker_tau_max_s / p.flicker_tau_min_s)
    k = int(math.ceil(decades * _FLICKER_TERMS_PER_DECADE - 1e-9)) + 1
    taus = np.geomspace(p.flicker_tau_min_s, p.flicker_tau_max_s, k)
    r = taus[1] / taus[0]
    b_dps = p.bias_instability_dph / _DPH_PER_DPS
    sigma = b_dps * math.sqrt(math.log(r) / math.pi)
    return np.full(k, sigma), taus


def _integral_variance(t, sigma2, tau_c):
    """Var of ∫₀ᵀ x dt for a Gauss-Markov x of variance σ² and correlation time τ_c."""
    return 2.0 * sigma2 * tau_c**2 * (t / tau_c - 1.0 + np.exp(-t / tau_c))


def adev_model_dph(p: GyroParams, tau_s) -> np.ndarray:
    """Theoretical Allan deviation (°/h) of the static output at averaging times ``tau_s``:
    white (ARW) + the flicker Gauss-Markov sum (exact) + RRW. Quantisation and the
    deterministic terms are not included."""
    tau = np.asarray(tau_s, dtype=float)
    if np.any(~np.isfinite(tau)) or np.any(tau <= 0.0):
        raise ValueError("tau_s must be finite and > 0")
    avar = p.arw_deg_per_rs**2 / tau + p.rrw_dps_per_rs**2 * tau / 3.0
    for s, tc in zip(*flicker_terms(p)):
        # AVAR = (4 V(τ) − V(2τ)) / (2τ²), V the variance of the integral over a span
        avar = avar + (4.0 * _integral_variance(tau, s * s, tc)
                       - _integral_variance(2.0 * tau, s * s, tc)) / (2.0 * tau**2)
    return np.sqrt(avar) * _DPH_PER_DPS
