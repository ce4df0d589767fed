"""Discrepancy workflow (issue 7): logged records, the effect catalogue, models and their files.

``Record`` (data.py) is a logged experiment; ``CATALOGUE`` (effects.py) the physical effects a
model may lack; ``Model`` (model.py) a base model plus effects, simulated on a record's stimulus
and stored as TOML; ``make_experiment`` (experiments.py) a realistic stimulus per sensor kind.
"""

from bench.discovery.data import CSV_COLUMNS, Record
from bench.discovery.effects import CATALOGUE, KINDS, Effect, Param, effect, effects_for
from bench.discovery.experiments import make_experiment
from bench.discovery.model import BaseModel, Model, base_model, read_model, write_model

__all__ = ["CATALOGUE", "CSV_COLUMNS", "KINDS", "BaseModel", "Effect", "Model", "Param", "Record", "base_model",
           "effect", "effects_for", "make_experiment", "read_model", "write_model"]
