"""The effect catalogue (issue 7): composable physical effects with stable ids.

``CATALOGUE`` is the one registry of effects: an immutable, ordered mapping id -> Effect built
from the list of effect classes below (the issues' order, later additions appended: an
effect's place seeds the scorecard's draws; a new effect is its class and one line here).
Every effect states its physical description, parametric form (``form``), the logged inputs it
needs (``inputs``), its residual signature, the sensor kinds it applies to (``kinds``)
and per-kind physical parameter ranges (``params_for(kind)``; ``params`` is the envelope over
kinds). Conventions (units, stages, the detectability rule behind ``min_effect`` and ``draw``,
the hooks) are in ``bench.discovery.effects_base``.

Which effects apply to which kind:

* accelerometer (QA-2000 class, DC): all but ``g_sensitivity`` (a gyro effect) and
  ``highpass_rolloff`` (the accelerometer senses DC).
* gyro (tactical FOG, DC): all but ``highpass_rolloff``.
* mhd (AC-coupled angular rate sensor): all but ``g_sensitivity``, ``dead_zone``,
  ``rate_random_walk`` (no DC path for a slow walk), ``vibration_rectification`` and
  ``thermal_lag`` (its minute-long records cannot tell an element lag from ``temperature_bias``).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence

from bench.discovery.effects_base import KINDS, Effect
from bench.discovery.effects_noise import AngleQuantization, FlickerNoise, GaussMarkov, RateRandomWalk
from bench.discovery.effects_steps import BiasJump
from bench.discovery.effects_terms import (
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
from bench.discovery.effects_thermal import TemperatureRate, ThermalHysteresis, ThermalLag, ThermalTwoNode
from bench.discovery.effects_transforms import (
    DeadZone,
    HighpassRolloff,
    LowpassBandwidth,
    Quantization,
    Saturation,
    TimeDelay,
)


class Catalogue(Mapping[str, Effect]):
    """id -> Effect in the order the classes are given, immutable.

    Building it checks the entries (unique ids; every ``competitors`` and ``separating`` id names
    an entry; a pair's experiment given once) and makes the relations between entries symmetric:
    a look-alike or a separating experiment declared on either effect of a pair holds for both,
    so a new effect declares its relations to the old ones on itself alone."""

    def __init__(self, classes: Sequence[type[Effect]]):
        plain = {}
        for cls in classes:
            if not cls.id or cls.id in plain:
                raise ValueError(f"effect class {cls.__name__}: id {cls.id!r} is empty or repeated; "
                                 "allowed: a unique id per effect")
            plain[cls.id] = cls()
        self._recipes: dict[frozenset[str], str] = {}
        mates: dict[str, list[str]] = {eid: [] for eid in plain}
        for eid, eff in plain.items():
            for other in eff.competitors:
                _check_relation(plain, eid, other, "competitors")
                for a, b in ((eid, other), (other, eid)):
                    if b not in mates[a]:
                        mates[a].append(b)
            for other, recipe in eff.separating.items():
                _check_relation(plain, eid, other, "separating")
                key = frozenset({eid, other})
                if key in self._recipes:
                    raise ValueError(f"effect {eid!r}: the experiment separating it from {other!r} is given twice")
                self._recipes[key] = recipe
        self._effects: dict[str, Effect] = {
            cls.id: cls(look_alikes=[plain[m] for m in mates[cls.id]]) for cls in classes}

    def __getitem__(self, effect_id: str) -> Effect:
        return self._effects[effect_id]

    def __iter__(self) -> Iterator[str]:
        return iter(self._effects)

    def __len__(self) -> int:
        return len(self._effects)

    def effect(self, effect_id: str) -> Effect:
        """The entry, or ValueError naming the id and the known ones."""
        try:
            return self._effects[effect_id]
        except KeyError:
            raise ValueError(f"unknown effect id {effect_id!r}; allowed: {list(self._effects)}") from None

    def for_kind(self, kind: str) -> list[Effect]:
        """The entries that apply to a sensor kind, in catalogue order."""
        if kind not in KINDS:
            raise ValueError(f"unknown sensor kind {kind!r}; allowed: {list(KINDS)}")
        return [e for e in self._effects.values() if kind in e.kinds]

    def columns_used(self, kind: str) -> frozenset[str]:
        """The logged columns some effect of ``kind`` reads (besides time): a dependence on any
        other logged column is out of the catalogue."""
        return frozenset(c for e in self.for_kind(kind) for c in e.inputs if c != "t")

    def look_alikes(self, effect_id: str) -> tuple[str, ...]:
        """Ids of the effects whose signature this one resembles (declared on either side)."""
        return tuple(e.id for e in self.effect(effect_id).look_alikes)

    def separating_recipe(self, a: str, b: str) -> str | None:
        """The experiment declared to tell ``a`` from ``b`` (on either effect), or None."""
        return self._recipes.get(frozenset({a, b}))


def _check_relation(entries: Mapping[str, Effect], eid: str, other: str, where: str) -> None:
    if other == eid or other not in entries:
        raise ValueError(f"effect {eid!r}: {where} names {other!r}; allowed: another entry of the catalogue "
                         f"{sorted(set(entries) - {eid})}")


CATALOGUE = Catalogue((
    WarmupExponential, LinearDrift, TemperatureBias, TemperatureScaleFactor, K2Nonlinearity,
    K3Nonlinearity, ScaleFactorAsymmetry, Misalignment, GSensitivity, Quantization, DeadZone,
    Saturation, SinusoidalInterference, GaussMarkov, RateRandomWalk, TimeDelay, LowpassBandwidth,
    HighpassRolloff, VibrationRectification,
    # issue 15
    FlickerNoise, BiasJump, AngleQuantization, ThermalTwoNode, TemperatureRate, ThermalHysteresis,
    # the element's temperature behind the logged (case) one
    ThermalLag,
))
