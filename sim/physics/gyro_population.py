"""Manufacturing spread of the simulated FOG: ``draw_gyro(serial, grade)`` and the datasheet limits.

A serial number is a unit: ``zlib.crc32(serial)`` seeds a ``numpy.random.SeedSequence``,
and one fixed vector of standard normals z is drawn from it, the same for every grade
(so a serial's z-scores do not depend on the grade asked for). Each parameter is then
the grade's value moved by its spread. Limits are the grade's datasheet limits (the
acceptance spec uses them); spreads are set so that each limited parameter falls
outside its limit with probability ≈ 0.94 % (Gaussian limits at ±2.6σ, one-sided
log-normal limits at +2.35σ, the g-sensitivity norm at 3.37σ per component, χ²₃),
so with 12 limited quantities ≈ 10 % of units fail at least one.

Limited parameters (L = limit; tactical / navigation):

| parameter | tactical L | navigation L | spread |
|---|---|---|---|
| ``bias_dph`` | ±3 | ±0.05 | N(0, L/2.6) |
| ``scale_factor_error_ppm`` | ±500 | ±50 | N(0, L/2.6) |
| ``asymmetry_ppm`` | ±100 | ±10 | N(0, L/2.6) |
| ``nonlinearity_ppm`` (cubic coefficient n) | ±100 | ±20 | N(0, L/2.6) |
| ``arw_deg_per_rh`` | ≤ 0.1 | ≤ 0.002 | log-normal, median = preset, ln σ = ln(L/median)/2.35 |
| ``bias_instability_dph`` (IEEE 952 B) | ≤ 1.0 | ≤ 0.01 | as ARW |
| ``bias_tc_dph_per_c`` | ±0.05 | ±0.001 | N(0, L/2.6) |
| ``g_sensitivity_norm_dph_per_g`` (‖3-vector‖) | ≤ 1.0 | ≤ 0.02 | each component N(0, L/3.37) |
| ``misalignment_rad`` (each of θ₂, θ₃) | ±1e-3 | ±2e-4 | each N(0, L/2.6) |
| ``warmup_amplitude_dph`` | ±5 | ±0.05 | N(preset, (L − preset)/2.35) |
| ``boot_time_s`` | ≤ 2 | ≤ 10 | log-normal as ARW |

Not limited, spread only: RRW (log-normal, ln σ 0.3), warm-up τ (0.2), thermal τ (0.1),
self-heating rise (±10 % normal), supply current (±5 %), temperature-sensor offset
(N(0, 0.3 °C)), vibration coefficients (log-normal 0.3, 0.2 for the noise; resonance
frequency 0.03). Fixed per grade: nominal scale factor, full scale, supply range,
bias repeatability, flicker τ range, operating range, ambient.
"""

from __future__ import annotations

import math
import zlib

import numpy as np

from sim.physics.gyro_params import GRADES, GyroParams

#: z of a two-sided Gaussian limit, of a one-sided limit, and per component of a 3-D norm limit
_Z_TWO_SIDED, _Z_ONE_SIDED, _Z_NORM3 = 2.6, 2.35, 3.37

#: datasheet limits (lo, hi) per grade; vector fields: see the module docstring
LIMITS: dict[str, dict[str, tuple[float, float]]] = {
    "tactical": {
        "bias_dph": (-3.0, 3.0), "scale_factor_error_ppm": (-500.0, 500.0),
        "asymmetry_ppm": (-100.0, 100.0), "nonlinearity_ppm": (-100.0, 100.0),
        "arw_deg_per_rh": (0.0, 0.1), "bias_instability_dph": (0.0, 1.0),
        "bias_tc_dph_per_c": (-0.05, 0.05), "g_sensitivity_norm_dph_per_g": (0.0, 1.0),
        "misalignment_rad": (-1e-3, 1e-3), "warmup_amplitude_dph": (-5.0, 5.0),
        "boot_time_s": (0.0, 2.0),
    },
    "navigation": {
        "bias_dph": (-0.05, 0.05), "scale_factor_error_ppm": (-50.0, 50.0),
        "asymmetry_ppm": (-10.0, 10.0), "nonlinearity_ppm": (-20.0, 20.0),
        "arw_deg_per_rh": (0.0, 0.002), "bias_instability_dph": (0.0, 0.01),
        "bias_tc_dph_per_c": (-0.001, 0.001), "g_sensitivity_norm_dph_per_g": (0.0, 0.02),
        "misalignment_rad": (-2e-4, 2e-4), "warmup_amplitude_dph": (-0.05, 0.05),
        "boot_time_s": (0.0, 10.0),
    },
}

_N_DRAWS = 32  # fixed length of the serial's z vector (room for later parameters)


def _grade(grade: str) -> str:
    if grade not in GRADES:
        raise ValueError(f"grade={grade!r} not one of {sorted(GRADES)}")
    return grade


def serial_generator(serial: str) -> np.random.Generator:
    """The generator of a serial number: SeedSequence(crc32(serial, UTF-8))."""
    if not isinstance(serial, str) or not serial or not serial.isprintable():
        raise ValueError(f"serial={serial!r} must be a non-empty printable string")
    return np.random.default_rng(np.random.SeedSequence(zlib.crc32(serial.encode("utf-8"))))


def draw_gyro(serial: str, grade: str = "tactical") -> GyroParams:
    """The unit with serial number ``serial`` from the manufacturing spread of ``grade``."""
    nominal = GRADES[_grade(grade)]
    lim = LIMITS[grade]
    z = iter(serial_generator(serial).standard_normal(_N_DRAWS))

    def sym(name):  # zero-centred, two-sided limit at ±2.6σ
        return float(next(z) * lim[name][1] / _Z_TWO_SIDED)

    def lognormal_to_limit(name):  # median = preset, one-sided limit at +2.35σ
        median = getattr(nominal, name)
        return float(median * math.exp(next(z) * math.log(lim[name][1] / median) / _Z_ONE_SIDED))

    def lognormal(value, sigma):
        return float(value * math.exp(next(z) * sigma))

    p = nominal
    warm_lim = lim["warmup_amplitude_dph"][1]
    values = {
        "bias_dph": sym("bias_dph"),
        "scale_factor_error_ppm": sym("scale_factor_error_ppm"),
        "asymmetry_ppm": sym("asymmetry_ppm"),
        "nonlinearity_ppm": sym("nonlinearity_ppm"),
        "arw_deg_per_rh": lognormal_to_limit("arw_deg_per_rh"),
        "bias_instability_dph": lognormal_to_limit("bias_instability_dph"),
        "bias_tc_dph_per_c": sym("bias_tc_dph_per_c"),
        "g_sensitivity_dph_per_g": tuple(
            float(next(z) * lim["g_sensitivity_norm_dph_per_g"][1] / _Z_NORM3) for _ in range(3)),
        "misalignment_rad": tuple(sym("misalignment_rad") for _ in range(2)),
        "warmup_amplitude_dph": float(p.warmup_amplitude_dph
                                      + next(z) * (warm_lim - p.warmup_amplitude_dph) / _Z_ONE_SIDED),
        "boot_time_s": lognormal_to_limit("boot_time_s"),
        "rrw_dph_per_rh": lognormal(p.rrw_dph_per_rh, 0.3),
        "warmup_tau_s": lognormal(p.warmup_tau_s, 0.2),
        "thermal_tau_s": lognormal(p.thermal_tau_s, 0.1),
        "self_heating_delta_c": float(max(0.0, p.self_heating_delta_c * (1.0 + 0.1 * next(z)))),
        "supply_current_a": float(max(0.0, p.supply_current_a * (1.0 + 0.05 * next(z)))),
        "temp_sensor_offset_c": float(0.3 * next(z)),
        "vib_rectification_dph_per_g2": tuple(lognormal(v, 0.3) for v in p.vib_rectification_dph_per_g2),
        "vib_resonance_hz": lognormal(p.vib_resonance_hz, 0.03),
        "vib_resonance_dps_per_grms": tuple(lognormal(v, 0.3) for v in p.vib_resonance_dps_per_grms),
        "vib_noise_dps_per_grms": tuple(lognormal(v, 0.2) for v in p.vib_noise_dps_per_grms),
    }
    values.update(draw_thermal(serial, grade))
    return p.replace(**values)


#: Thermal spread (issue 14) per grade: field -> (kind, centre, width), drawn from the serial's own
#: thermal stream so the z vector above never changes. All assumed (tactical FOG orders: bias
#: 2nd/3rd order ~0.5 °/h over −40…+70 °C, SF ~±1500 ppm, hysteresis 2h ≈ 0.1 °/h, Shupe
#: ~0.1 °/h per °C/min); navigation ≈ 30× smaller.
THERMAL_SPREAD: dict[str, dict[str, tuple[str, float, float]]] = {
    "tactical": {
        "bias_tc2_dph_per_c2": ("normal", 0.0, 2e-4), "bias_tc3_dph_per_c3": ("normal", 0.0, 3e-6),
        "sf_tc_ppm_per_c": ("normal", 0.0, 20.0), "sf_tc2_ppm_per_c2": ("normal", 0.0, 0.1),
        "sf_tc3_ppm_per_c3": ("normal", 0.0, 0.002), "bias_hysteresis_dph": ("lognormal", 0.05, 0.4),
        "hysteresis_width_c": ("lognormal", 6.0, 0.2), "shupe_dph_per_c_per_min": ("normal", 0.0, 0.1),
        "element_tau_s": ("lognormal", 60.0, 0.2)},
    "navigation": {
        "bias_tc2_dph_per_c2": ("normal", 0.0, 6e-6), "bias_tc3_dph_per_c3": ("normal", 0.0, 1e-7),
        "sf_tc_ppm_per_c": ("normal", 0.0, 1.0), "sf_tc2_ppm_per_c2": ("normal", 0.0, 0.005),
        "sf_tc3_ppm_per_c3": ("normal", 0.0, 1e-4), "bias_hysteresis_dph": ("lognormal", 0.0015, 0.4),
        "hysteresis_width_c": ("lognormal", 6.0, 0.2), "shupe_dph_per_c_per_min": ("normal", 0.0, 0.003),
        "element_tau_s": ("lognormal", 60.0, 0.2)},
}


def thermal_generator(serial: str) -> np.random.Generator:
    """The serial's thermal stream: SeedSequence([crc32("gyro-thermal"), crc32(serial)])."""
    return np.random.default_rng(np.random.SeedSequence(
        [zlib.crc32(b"gyro-thermal"), zlib.crc32(serial.encode("utf-8"))]))


def draw_thermal(serial: str, grade: str) -> dict[str, float]:
    """The thermal coefficients of the unit ``serial`` (a separate stream of the serial)."""
    rng = thermal_generator(serial)
    out = {}
    for name, (kind, centre, width) in THERMAL_SPREAD[_grade(grade)].items():
        z = float(rng.standard_normal())
        out[name] = centre * math.exp(width * z) if kind == "lognormal" else centre + width * z
    return out


def limited_values(p: GyroParams) -> dict[str, float | tuple[float, ...]]:
    """The quantities the datasheet limits apply to (g-sensitivity as its norm)."""
    return {
        "bias_dph": p.bias_dph, "scale_factor_error_ppm": p.scale_factor_error_ppm,
        "asymmetry_ppm": p.asymmetry_ppm, "nonlinearity_ppm": p.nonlinearity_ppm,
        "arw_deg_per_rh": p.arw_deg_per_rh, "bias_instability_dph": p.bias_instability_dph,
        "bias_tc_dph_per_c": p.bias_tc_dph_per_c,
        "g_sensitivity_norm_dph_per_g": math.sqrt(sum(v * v for v in p.g_sensitivity_dph_per_g)),
        "misalignment_rad": p.misalignment_rad, "warmup_amplitude_dph": p.warmup_amplitude_dph,
        "boot_time_s": p.boot_time_s,
    }


def out_of_limits(p: GyroParams, grade: str = "tactical") -> tuple[str, ...]:
    """Names of the limited quantities of ``p`` outside the datasheet limits of ``grade``."""
    lim = LIMITS[_grade(grade)]
    bad = []
    for name, value in limited_values(p).items():
        lo, hi = lim[name]
        items = value if isinstance(value, tuple) else (value,)
        if not all(lo <= v <= hi for v in items):
            bad.append(name)
    return tuple(bad)
