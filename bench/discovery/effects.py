"""The effect catalogue (issue 7): composable physical effects with stable ids.

``CATALOGUE`` maps id -> Effect instance, in the issue's order. Every effect states its
physical description, parametric form (``form``), the logged inputs it needs (``inputs``), its
residual signature, the sensor kinds it applies to (``kinds``) and per-kind physical parameter
ranges (``params_for(kind)``; ``params`` is the envelope over kinds). Conventions (units, stages,
the detectability rule behind ``min_effect`` and ``draw``) are in ``bench.discovery.effects_base``.

Which effects apply to which kind:

* accelerometer (QA-2000 class, DC): all but ``g_sensitivity`` (a gyro effect) and
  ``highpass_rolloff`` (the accelerometer senses DC).
* gyro (tactical FOG, DC): all but ``highpass_rolloff``.
* mhd (AC-coupled angular rate sensor): all but ``g_sensitivity``, ``dead_zone``,
  ``rate_random_walk`` (no DC path for a slow walk) and ``vibration_rectification``.
"""

from __future__ import annotations

from bench.discovery.effects_base import (
    DEFAULT_NOISE_SD,
    DRAW_SNR_FACTOR,
    DRAW_SPAN,
    KINDS,
    MIN_SNR,
    REGISTRY,
    UNIT,
    Effect,
    Param,
    guess_kind,
    noise_sd_of,
)
from bench.discovery.effects_noise import GaussMarkov, RateRandomWalk
from bench.discovery.effects_terms import (
    T_REF_C,
    GSensitivity,
    K2Nonlinearity,
    K3Nonlinearity,
    LinearDrift,
    Misalignment,
    ScaleFactorAsymmetry,
    SinusoidalInterference,
    TemperatureBias,
    TemperatureScaleFactor,
    VibrationRectification,
    WarmupExponential,
)
from bench.discovery.effects_transforms import (
    DeadZone,
    HighpassRolloff,
    LowpassBandwidth,
    Quantization,
    Saturation,
    TimeDelay,
)

_ORDER = (WarmupExponential, LinearDrift, TemperatureBias, TemperatureScaleFactor, K2Nonlinearity,
          K3Nonlinearity, ScaleFactorAsymmetry, Misalignment, GSensitivity, Quantization, DeadZone,
          Saturation, SinusoidalInterference, GaussMarkov, RateRandomWalk, TimeDelay, LowpassBandwidth,
          HighpassRolloff, VibrationRectification)

CATALOGUE: dict[str, Effect] = {cls.id: cls() for cls in _ORDER}
REGISTRY.update(CATALOGUE)


def effect(effect_id: str) -> Effect:
    """The catalogue entry, or ValueError naming the id and the known ones."""
    try:
        return CATALOGUE[effect_id]
    except KeyError:
        raise ValueError(f"unknown effect id {effect_id!r}; allowed: {list(CATALOGUE)}") from None


def effects_for(kind: str) -> list[Effect]:
    """The catalogue entries that apply to a sensor kind, in catalogue order."""
    if kind not in KINDS:
        raise ValueError(f"unknown sensor kind {kind!r}; allowed: {list(KINDS)}")
    return [e for e in CATALOGUE.values() if kind in e.kinds]


__all__ = ["CATALOGUE", "DEFAULT_NOISE_SD", "DRAW_SNR_FACTOR", "DRAW_SPAN", "KINDS", "MIN_SNR", "T_REF_C", "UNIT",
           "Effect", "Param", "effect", "effects_for", "guess_kind", "noise_sd_of"]
