"""Unit specifications: what a sensor model must meet, as data (TOML), not code.

A spec names the sensor model, the procedures acceptance runs (in file order, each with its
parameters) and every measurement with its unit, limits and optional marginal band::

    [unit]
    model = "QA-2000-SIM"
    kind = "accelerometer"                 # accelerometer | gyro
    serial_pattern = "QA-SIM-*"            # units this spec applies to by default (fnmatch)

    [procedures.tumble]                    # run first; parameters of the procedure
    positions = 12
    planes = 2

    [[measurements]]
    name = "k0"                            # a measurement the procedure produces
    procedure = "tumble"
    unit = "mg"                            # any unit of the same dimension as produced
    low = -4.0
    high = 4.0
    marginal = 0.4                         # inside the limits but this close: "marginal"
    label = "Bias (K0)"                    # optional: its name on the operator page

    [[prompts]]                            # optional: the operator is asked before a procedure
    before = "tumble"
    text = "Remove the shipping clamp and close the fixture cover"

The procedures are steps of the step catalogue the caller passes
(``procedures.catalogue.CATALOGUE``): which sensor kinds each applies to, its parameters,
what it produces and what a given parameter table can produce.  The spec is checked against
it completely before any instrument is touched; a step's old name is refused naming the new
one.  Limits are compared in the spec's unit.  A measurement's ``label`` is the name an
operator reads (the measurement's own name when it has none); :func:`plain_unit` writes a unit
as a person reads it (``ug/g^2`` → ``µg/g²``).
"""

from __future__ import annotations

import fnmatch
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bench.core.operator import check_prompt
from bench.core.step import Catalogue
from bench.core.toml_file import read_toml

#: unit → (dimension, value of one unit in the dimension's base unit)
_ARCSEC_RAD = math.pi / 180 / 3600
UNITS: dict[str, tuple[str, float]] = {
    "g": ("acceleration", 1.0), "mg": ("acceleration", 1e-3), "ug": ("acceleration", 1e-6),
    "m/s^2": ("acceleration", 1 / 9.80665),
    "mA/g": ("accelerometer scale factor", 1.0), "A/g": ("accelerometer scale factor", 1e3),
    "g/g^2": ("second-order coefficient", 1.0), "ug/g^2": ("second-order coefficient", 1e-6),
    "g/g^3": ("third-order coefficient", 1.0), "ug/g^3": ("third-order coefficient", 1e-6),
    "rad": ("angle", 1.0), "mrad": ("angle", 1e-3), "urad": ("angle", 1e-6),
    "deg": ("angle", math.pi / 180), "arcsec": ("angle", _ARCSEC_RAD),
    "deg/h": ("angular rate", 1.0), "deg/s": ("angular rate", 3600.0),
    "ppm": ("ratio", 1.0), "%": ("ratio", 1e4),
    "s": ("time", 1.0), "min": ("time", 60.0),
    "g/rtHz": ("acceleration noise density", 1.0), "ug/rtHz": ("acceleration noise density", 1e-6),
    "deg/rth": ("angle random walk", 1.0), "deg/h/rtHz": ("angle random walk", 1 / 60),
    "deg/h/rth": ("rate random walk", 1.0),
    "pulses/arcsec": ("gyro scale factor", 1.0),
    "readings": ("count", 1.0), "frames": ("count", 1.0),
    # calibration over temperature (issue 14)
    "g/degC": ("accelerometer bias temperature coefficient", 1.0),
    "mg/degC": ("accelerometer bias temperature coefficient", 1e-3),
    "ug/degC": ("accelerometer bias temperature coefficient", 1e-6),
    "g/g^2/degC": ("K2 temperature coefficient", 1.0), "ug/g^2/degC": ("K2 temperature coefficient", 1e-6),
    "deg/h/degC": ("gyro bias temperature coefficient", 1.0),
    "ppm/degC": ("scale-factor temperature coefficient", 1.0),
    "g/(degC/min)": ("accelerometer temperature-rate sensitivity", 1.0),
    "ug/(degC/min)": ("accelerometer temperature-rate sensitivity", 1e-6),
    "deg/h/(degC/min)": ("gyro temperature-rate sensitivity", 1.0),
    "degC": ("temperature difference", 1.0),
}
KINDS = ("accelerometer", "gyro")
#: a label is one line an operator reads beside the value: at most this many characters
MAX_LABEL_CHARS = 60
#: how a unit's parts are written for a person (applied in order: ``degC`` before ``deg``)
_PLAIN_PARTS = (("rtHz", "√Hz"), ("rth", "√h"), ("^2", "²"), ("^3", "³"), ("degC", "°C"),
                ("deg", "°"))


class SpecError(ValueError):
    """A unit spec that cannot be used; the message names the file, the entry and the value."""


def convert(value: float, from_unit: str, to_unit: str) -> float:
    """``value`` in ``from_unit`` expressed in ``to_unit`` (same dimension)."""
    (dim_a, fa), (dim_b, fb) = _unit(from_unit), _unit(to_unit)
    if dim_a != dim_b:
        raise ValueError(f"cannot convert {from_unit!r} ({dim_a}) to {to_unit!r} ({dim_b})")
    return value * fa / fb


def _unit(name: str) -> tuple[str, float]:
    if name not in UNITS:
        raise ValueError(f"unit {name!r} unknown; known units: {', '.join(UNITS)}")
    return UNITS[name]


def same_dimension(unit: str) -> list[str]:
    dim = _unit(unit)[0]
    return [u for u, (d, _) in UNITS.items() if d == dim]


def plain_unit(unit: str) -> str:
    """``unit`` (a key of :data:`UNITS`) as a person reads it: ``ug/g^2`` → ``µg/g²``,
    ``ug/rtHz`` → ``µg/√Hz``, ``deg/h`` → ``°/h``, ``urad`` → ``µrad``; ValueError naming
    the known units for any other."""
    _unit(unit)
    # the micro prefix is written "u" in a spec (ug, urad): µ wherever it prefixes a base unit
    text = "/".join("µ" + part[1:] if part.startswith(("ug", "urad")) else part
                    for part in unit.split("/"))
    for written, plain in _PLAIN_PARTS:
        text = text.replace(written, plain)
    return text


@dataclass(frozen=True)
class SpecMeasurement:
    """One line of the spec: a produced measurement, its unit and its limits (in that unit)."""

    name: str
    procedure: str
    unit: str
    low: float | None = None
    high: float | None = None
    marginal: float = 0.0
    description: str = ""
    #: what an operator reads for it (the operator page); the name when the spec gives none
    label: str = ""

    def __post_init__(self) -> None:
        if not self.label:
            object.__setattr__(self, "label", self.name)  # frozen: set once, here

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "procedure": self.procedure, "unit": self.unit, "low": self.low,
                "high": self.high, "marginal": self.marginal, "description": self.description,
                "label": self.label}


@dataclass(frozen=True)
class UnitSpec:
    model: str
    kind: str
    procedures: dict[str, dict[str, Any]]  # in run order
    measurements: tuple[SpecMeasurement, ...]
    description: str = ""
    serial_pattern: str | None = None
    source: str = "<spec>"
    #: operator prompts: procedure name → what the operator is asked before it runs
    prompts: dict[str, str] = field(default_factory=dict)

    def for_procedure(self, procedure: str) -> list[SpecMeasurement]:
        return [m for m in self.measurements if m.procedure == procedure]

    def applies_to(self, serial: str) -> bool:
        return self.serial_pattern is not None and fnmatch.fnmatchcase(serial, self.serial_pattern)

    def to_dict(self) -> dict[str, Any]:
        return {"model": self.model, "kind": self.kind, "description": self.description,
                "serial_pattern": self.serial_pattern, "source": self.source,
                "procedures": self.procedures,
                "measurements": [m.to_dict() for m in self.measurements],
                **({"prompts": [{"before": k, "text": v} for k, v in self.prompts.items()]}
                   if self.prompts else {})}


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise SpecError(f"{where} = {value!r} must be a finite number")
    return float(value)


def _text(table: dict, key: str, where: str) -> str:
    value = table.get(key)
    if not isinstance(value, str) or not value.strip():
        raise SpecError(f"{where}: '{key}' = {value!r} must be non-empty text")
    return value


def _optional_text(table: dict, key: str, where: str) -> str | None:
    return None if table.get(key) is None else _text(table, key, where)


def parse_spec(data: dict, catalogue: Catalogue, source: str = "<spec>") -> UnitSpec:
    """Validate a spec table (as read from TOML) against the step catalogue."""
    unknown = set(data) - {"unit", "procedures", "measurements", "prompts"}
    if unknown:
        raise SpecError(f"{source}: unknown table(s) {sorted(unknown)}; allowed: unit, procedures, "
                        "measurements, prompts")
    unit = data.get("unit")
    if not isinstance(unit, dict):
        raise SpecError(f"{source}: missing [unit] table (model, kind)")
    extra = set(unit) - {"model", "kind", "serial_pattern", "description"}
    if extra:
        raise SpecError(f"{source}: [unit] unknown key(s) {sorted(extra)}; allowed: model, kind, "
                        "serial_pattern, description")
    model = _text(unit, "model", f"{source}: [unit]")
    kind = _text(unit, "kind", f"{source}: [unit]")
    if kind not in KINDS:
        raise SpecError(f"{source}: [unit] kind = {kind!r} not in {list(KINDS)}")
    pattern = _optional_text(unit, "serial_pattern", f"{source}: [unit]")
    judged = sorted(n for n, step in catalogue.steps.items() if step.produces)
    procedures = data.get("procedures", {})
    if not isinstance(procedures, dict) or not procedures:
        raise SpecError(f"{source}: [procedures.<name>] tables needed, one per procedure to run; "
                        f"known: {judged}")
    checked: dict[str, dict[str, Any]] = {}
    producible: dict[str, set[str]] = {}
    for name, params in procedures.items():
        where = f"{source}: [procedures.{name}]"
        if name not in catalogue:
            if name in catalogue.renamed:
                raise SpecError(f"{where}: renamed {catalogue.renamed[name]!r}; "
                                f"write [procedures.{catalogue.renamed[name]}]")
            raise SpecError(f"{where}: unknown procedure; known: {judged}")
        step = catalogue.steps[name]
        if not step.produces:  # nothing to judge: a spec naming it meant something else
            raise SpecError(f"{where}: {name!r} produces no measurement a spec can judge"
                            f"{catalogue.renamed_note(name)}; known: {judged}")
        if kind not in step.kinds:
            raise SpecError(f"{where}: applies to {list(step.kinds)}, not to a {kind}")
        if not isinstance(params, dict):
            raise SpecError(f"{where} must be a table of parameters")
        try:
            producible[name] = step.build(params).producible()
        except (TypeError, ValueError) as exc:
            raise SpecError(f"{where}: {exc}") from None
        checked[name] = dict(params)
    entries = data.get("measurements", [])
    if not isinstance(entries, list) or not entries:
        raise SpecError(f"{source}: no [[measurements]]: a spec with nothing to judge passes every unit")
    measurements, seen = [], set()
    for i, entry in enumerate(entries, start=1):
        named = entry.get("name") if isinstance(entry, dict) else None
        # the measurement by its name where it has one (a typo elsewhere in it is then found by name)
        where = f"{source}: measurement {named!r}" if isinstance(named, str) and named else \
            f"{source}: measurement #{i} (no name)"
        if not isinstance(entry, dict):
            raise SpecError(f"{where} must be a table")
        extra = set(entry) - {"name", "procedure", "unit", "low", "high", "marginal", "description",
                              "label"}
        if extra:
            raise SpecError(f"{where}: unknown key(s) {sorted(extra)}")
        name = _text(entry, "name", where)
        proc = _text(entry, "procedure", where)
        where = f"{source}: measurement {name!r}"
        if proc not in checked:
            raise SpecError(f"{where}: procedure {proc!r} is not among this spec's [procedures.*] "
                            f"({sorted(checked)}){catalogue.renamed_note(proc)}")
        produced = catalogue.steps[proc].produces
        if name not in produced:
            raise SpecError(f"{where}: {proc} produces {sorted(produced)}, not {name!r}")
        if name not in producible[proc]:
            raise SpecError(f"{where}: {proc} with these parameters cannot produce it "
                            f"(it can: {sorted(producible[proc])}) — e.g. more positions or planes")
        if name in seen:  # one record per name: two procedures cannot both judge "bias"
            raise SpecError(f"{where}: listed twice (measurement names are unique in a spec)")
        seen.add(name)
        unit_name = _text(entry, "unit", where)
        allowed = same_dimension(produced[name][0])
        if unit_name not in allowed:
            raise SpecError(f"{where}: unit {unit_name!r} not in {allowed}")
        low = None if "low" not in entry else _number(entry["low"], f"{where}: low")
        high = None if "high" not in entry else _number(entry["high"], f"{where}: high")
        if low is None and high is None:
            raise SpecError(f"{where}: needs 'low', 'high' or both")
        if low is not None and high is not None and not low < high:
            raise SpecError(f"{where}: low = {low} must be < high = {high}")
        marginal = _number(entry.get("marginal", 0.0), f"{where}: marginal")
        width = (high - low) / 2 if low is not None and high is not None else math.inf
        if not 0 <= marginal < width:
            raise SpecError(f"{where}: marginal = {marginal} not in 0..{width:g} (half the limit span)")
        description = entry.get("description", produced[name][1])
        if not isinstance(description, str):
            raise SpecError(f"{where}: description {description!r} must be text")
        measurements.append(SpecMeasurement(name, proc, unit_name, low, high, marginal, description,
                                            _label(entry, name, where)))
    return UnitSpec(model, kind, checked, tuple(measurements), unit.get("description", ""),
                    pattern, source, _prompts(data.get("prompts", []), checked, source))


def _label(entry: dict, name: str, where: str) -> str:
    """The measurement's ``label``: one line of 1..MAX_LABEL_CHARS printable characters; its
    name when the spec gives none."""
    label = entry.get("label", name)
    if (not isinstance(label, str) or not label.strip() or len(label) > MAX_LABEL_CHARS
            or not label.isprintable()):
        raise SpecError(f"{where}: label {label!r} must be text of 1..{MAX_LABEL_CHARS} printable "
                        "characters on one line (the measurement's name on the operator page)")
    return label.strip()


def _prompts(entries: Any, procedures: dict[str, Any], source: str) -> dict[str, str]:
    """``[[prompts]]`` tables (``before`` = a procedure of the spec, ``text``) checked."""
    if not isinstance(entries, list):
        raise SpecError(f"{source}: prompts must be [[prompts]] tables (before, text)")
    prompts: dict[str, str] = {}
    for i, entry in enumerate(entries, start=1):
        where = f"{source}: prompt #{i}"
        if not isinstance(entry, dict):
            raise SpecError(f"{where} must be a table (before, text)")
        extra = set(entry) - {"before", "text"}
        if extra:
            raise SpecError(f"{where}: unknown key(s) {sorted(extra)}; allowed: before, text")
        before = _text(entry, "before", where)
        if before not in procedures:
            raise SpecError(f"{where}: before = {before!r} is not among this spec's "
                            f"[procedures.*] ({list(procedures)})")
        if before in prompts:
            raise SpecError(f"{where}: a second prompt before {before!r} (one per procedure)")
        try:
            prompts[before] = check_prompt(entry.get("text"), where)
        except ValueError as exc:
            raise SpecError(str(exc)) from None
    return prompts


def load_spec(path: str | Path, catalogue: Catalogue) -> UnitSpec:
    return parse_spec(read_toml(path, "spec file", SpecError), catalogue, str(path))


__all__ = ["UNITS", "KINDS", "MAX_LABEL_CHARS", "SpecError", "SpecMeasurement", "UnitSpec",
           "convert", "same_dimension", "plain_unit", "parse_spec", "load_spec"]
