"""The one step catalogue: every step declares what ``bench run``, the specs and the
acceptance sequence derive from it — a help line, a parameter dataclass whose every field has
help and whose defaults are valid, the instruments it needs, the sensor kinds it serves."""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import pkgutil

import pytest

import procedures
from bench.core.step import Step
from procedures.catalogue import CATALOGUE

STEPS = list(CATALOGUE.steps.values())


def test_the_catalogue_holds_every_step_of_the_procedures_package() -> None:
    defined = set()
    for module in pkgutil.iter_modules(procedures.__path__):
        for _, cls in inspect.getmembers(importlib.import_module(f"procedures.{module.name}"), inspect.isclass):
            if issubclass(cls, Step) and cls is not Step and not inspect.isabstract(cls):
                defined.add(cls)
    assert defined == set(STEPS)  # a step written and not catalogued cannot be run or specified


@pytest.mark.parametrize("step", STEPS, ids=lambda s: s.name)
def test_each_step_declares_what_is_derived_from_it(step: type[Step]) -> None:
    assert step.summary() and step.summary().endswith(".")  # `bench run --help`
    assert set(step.kinds) <= {"accelerometer", "gyro", "angular"} and step.kinds
    assert step.requires and len(set(step.requires)) == len(step.requires)
    for name, (unit, description) in step.produces.items():
        assert name.isidentifier() and unit and description
    fields = dataclasses.fields(step.Parameters)
    assert fields
    for f in fields:
        assert f.metadata.get("help"), f"{step.name}.{f.name} has no help"
    built = step.build({})  # the defaults are valid
    assert built.duration_s() > 0 and built.producible() <= set(step.produces)


def test_names_say_what_they_are() -> None:
    assert CATALOGUE.step("startup").__name__ == "StartupAcquisition"  # Document A's acquisition
    assert CATALOGUE.step("turn_on").__name__ == "TurnOnTest"  # the acceptance turn-on test
    assert CATALOGUE.step("gyro_turn_on").__name__ == "GyroTurnOnTest"
    assert not CATALOGUE.step("startup").produces  # a record, nothing a spec could judge
    with pytest.raises(LookupError, match="'gyro_startup' was renamed 'gyro_turn_on'"):
        CATALOGUE.step("gyro_startup")
