"""Units of the IEEE 952 noise terms for gyro and accelerometer records.

A record's rate unit (``unit``) fixes the unit every term comes out in.  The fit and the
slope lines work in the input unit times a power of seconds (the *input form*, e.g.
``deg/h*sqrt(s)`` for N of a °/h record); each term is then reported in the customary
unit of its sensor kind and in one alternative:

| term | gyro (dps, dph, radps) | accelerometer (g, mg, ug, mps2) | None (any) |
|---|---|---|---|
| Q | arcsec (deg) | g*s (m/s) | u*s |
| N | deg/sqrt(h) (deg/sqrt(s)) | g/sqrt(Hz) (m/s/sqrt(h)) | u*sqrt(s) = u/sqrt(Hz) |
| B | deg/h (deg/s) | g (m/s^2) | u |
| K | deg/h/sqrt(h) (deg/s/sqrt(s)) | g/sqrt(s) (m/s^2/sqrt(h)) | u/sqrt(s) |
| R | deg/h^2 (deg/s^2) | g/s (m/s^2/h) | u/s |

Conversions: 1 °/√h = 1/60 °/√s; 1 °/h/√h = 1/216 000 °/s/√s; standard gravity
g = 9.80665 m/s² (ISO 80000-3).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

STANDARD_GRAVITY_MPS2 = 9.80665

#: accepted ``unit`` values → (sensor kind, factor to °/s or g, display name)
RATE_UNITS: dict[str | None, tuple[str, float, str]] = {
    "dps": ("gyro", 1.0, "deg/s"),
    "dph": ("gyro", 1.0 / 3600.0, "deg/h"),
    "radps": ("gyro", 180.0 / math.pi, "rad/s"),
    "g": ("accelerometer", 1.0, "g"),
    "mg": ("accelerometer", 1e-3, "mg"),
    "ug": ("accelerometer", 1e-6, "ug"),
    "mps2": ("accelerometer", 1.0 / STANDARD_GRAVITY_MPS2, "m/s^2"),
    None: ("generic", 1.0, "u"),
}

_LABELS = {
    "gyro": {"Q": "angle quantization", "N": "angle random walk", "B": "bias instability",
             "K": "rate random walk", "R": "rate ramp"},
    "accelerometer": {"Q": "velocity quantization", "N": "velocity random walk", "B": "bias instability",
                      "K": "acceleration random walk", "R": "acceleration ramp"},
}
_LABELS["generic"] = {"Q": "quantization", "N": "white noise (random walk of the integral)",
                      "B": "bias instability (flicker)", "K": "random walk", "R": "ramp"}

_G = STANDARD_GRAVITY_MPS2
# per kind and term: (primary unit, factor from °/s- or g-based form, alternative unit, factor)
_REPORT = {
    "gyro": {"Q": ("arcsec", 3600.0, "deg", 1.0),
             "N": ("deg/sqrt(h)", 60.0, "deg/sqrt(s)", 1.0),
             "B": ("deg/h", 3600.0, "deg/s", 1.0),
             "K": ("deg/h/sqrt(h)", 216000.0, "deg/s/sqrt(s)", 1.0),
             "R": ("deg/h^2", 3600.0 ** 2, "deg/s^2", 1.0)},
    "accelerometer": {"Q": ("g*s", 1.0, "m/s", _G),
                      "N": ("g/sqrt(Hz)", 1.0, "m/s/sqrt(h)", _G * 60.0),
                      "B": ("g", 1.0, "m/s^2", _G),
                      "K": ("g/sqrt(s)", 1.0, "m/s^2/sqrt(h)", _G * 60.0),
                      "R": ("g/s", 1.0, "m/s^2/h", _G * 3600.0)},
}
_INPUT_FORM = {"Q": "{u}*s", "N": "{u}*sqrt(s)", "B": "{u}", "K": "{u}/sqrt(s)", "R": "{u}/s"}


@dataclass(frozen=True)
class TermUnits:
    """How one term of a record is reported: multiply the input-form value by a factor."""

    label: str
    input_unit: str     # e.g. "deg/h*sqrt(s)"
    unit: str           # customary unit
    factor: float       # input form → customary unit
    alt_unit: str
    alt_factor: float


def check_unit(unit: str | None) -> str | None:
    """``unit`` if it is one of :data:`RATE_UNITS`, else ``ValueError`` naming the choices."""
    if unit not in RATE_UNITS:
        allowed = ", ".join(repr(u) for u in RATE_UNITS)
        raise ValueError(f"unit = {unit!r} is not supported (allowed: {allowed})")
    return unit


def rate_unit_name(unit: str | None) -> str:
    return RATE_UNITS[check_unit(unit)][2]


def term_units(unit: str | None, name: str) -> TermUnits:
    """Units and conversion factors of term ``name`` (Q, N, B, K, R) for a record in ``unit``."""
    kind, to_base, display = RATE_UNITS[check_unit(unit)]
    input_unit = _INPUT_FORM[name].format(u=display)
    if kind == "generic":
        return TermUnits(_LABELS[kind][name], input_unit, input_unit, 1.0, input_unit, 1.0)
    primary, f1, alt, f2 = _REPORT[kind][name]
    return TermUnits(_LABELS[kind][name], input_unit, primary, to_base * f1, alt, to_base * f2)
