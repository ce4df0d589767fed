"""Steps: what a test is, what it gets, what it records, and the catalogue that names them.

A **step** (:class:`Step`) is one test that produces named values with standard
uncertainties — a tumble calibration, a rate table, a static noise record, a start-up record.
It declares what it needs and what it produces beside the code that takes it (OpenHTF
style)::

    class TumbleCalibration(Step[TumbleParameters]):
        \"\"\"Accelerometer multi-position (tumble) calibration, IEEE 1293 (the help line).\"\"\"
        name = "tumble"
        requires = ("dmm", "supply", "turntable")      # station instruments
        kinds = ("accelerometer",)                      # sensor kinds it applies to
        produces = {"k1": ("mA/g", "scale factor K1"), ...}
        Parameters = TumbleParameters                   # a dataclass: parameter(default, help), validate()
        def duration_s(self) -> float: ...              # time it takes (progress weight)
        def run(self, ctx) -> dict[str, Estimate]: ...  # streams its data; returns what it produced

It gets a :class:`Context` — the station's instruments, its clock, the open run, the wiring
and site — and records :class:`Measurement` s (a value, a unit, :class:`Limit` s and an
optional marginal band) through ``ctx.measure``.  The framework knows no instrument:
``Context.instruments`` is a plain mapping, and the procedures layer gives it types
(``procedures.typed_instruments``).

A **catalogue** (:class:`Catalogue`, filled in ``procedures.catalogue``) names every step;
``bench run <step>``, its options and the acceptance specs' procedures all come from it.
How steps are run — set-up, teardown, judging, the run record — is ``bench.core.procedure``.
"""

from __future__ import annotations

import dataclasses
import math
from abc import ABC, abstractmethod
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar, Generic, Protocol, TypeVar

from bench.core.clock import Clock
from bench.core.operator import Operator, OperatorAbort, Unattended
from bench.core.site import DEFAULT_SITE
from bench.core.store import RunWriter
from bench.values import Estimate

T = TypeVar("T")


@dataclass(frozen=True)
class Limit:
    """Inclusive limits with an optional marginal band inside them (same unit)."""

    low: float | None = None
    high: float | None = None
    marginal: float = 0.0

    def outcome(self, value: float) -> str:
        if value is None or not math.isfinite(value):
            return "fail"
        if (self.low is not None and value < self.low) or (self.high is not None and value > self.high):
            return "fail"
        if self.marginal and ((self.low is not None and value < self.low + self.marginal)
                              or (self.high is not None and value > self.high - self.marginal)):
            return "marginal"
        return "pass"


@dataclass
class Measurement:
    name: str
    value: float
    unit: str
    limit: Limit = field(default_factory=Limit)
    description: str = ""
    uncertainty: float | None = None  # standard uncertainty, same unit (None: not known)
    bound: str | None = None  # "upper"/"lower": the value only bounds the quantity (None: measured)

    @property
    def outcome(self) -> str:
        return self.limit.outcome(self.value)

    def to_dict(self) -> dict[str, Any]:
        value = self.value if math.isfinite(self.value) else None  # JSON has no NaN: null
        return {"name": self.name, "value": value, "unit": self.unit,
                "low": self.limit.low, "high": self.limit.high, "marginal": self.limit.marginal,
                "outcome": self.outcome, "description": self.description,
                "uncertainty": self.uncertainty, **({"bound": self.bound} if self.bound else {})}


class Progress(Protocol):
    def __call__(self, done: float, total: float, message: str = "") -> None: ...


def no_progress(done: float, total: float, message: str = "") -> None:
    return None


@dataclass
class Context:
    """What a step gets: the station's instruments, its clock and the open run."""

    instruments: dict[str, Any]
    clock: Clock
    run: RunWriter
    wiring: dict[str, Any]
    progress: Progress = no_progress
    measurements: list[Measurement] = field(default_factory=list)
    #: latitude_deg, height_m and optionally local_g_mps2 of the station
    site: dict[str, Any] = field(default_factory=lambda: dict(DEFAULT_SITE))
    #: who answers the run's prompts (``bench.core.operator``)
    operator: Operator = field(default_factory=Unattended)

    def ask(self, text: str) -> None:
        """Prompt the operator and wait; the prompt and the answer are events of the run.
        Abort raises :class:`OperatorAbort` (the runner's interrupt path: station safe)."""
        self.run.event(self.clock.now(), "operator_prompt", text)
        go_on = self.operator.ask(text)
        answer = "continue" if go_on else "abort"
        self.run.event(self.clock.now(), "operator_answer", answer, operator=self.operator.name)
        if not go_on:
            raise OperatorAbort(f"aborted by the operator at the prompt: {text}")

    def measure(self, name: str, value: float, unit: str, limit: Limit | None = None,
                description: str = "", uncertainty: float | None = None,
                bound: str | None = None) -> Measurement:
        u = None if uncertainty is None or not math.isfinite(uncertainty) else float(uncertainty)
        m = Measurement(name, float(value), unit, limit or Limit(), description, u, bound)
        self.measurements.append(m)
        self.run.set_result(f"measurement.{name}", m.to_dict())
        return m


def parameter(default: T, help: str, *, aliases: tuple[str, ...] = ()) -> T:
    """A step parameter: a dataclass field with its default and its help — the help of its
    ``bench run`` option (``--warmup-s``), whose type and default come from the field.
    ``aliases``: further option names a user may know it by (``rate-hz``)."""
    return field(default=default, metadata={"help": help, "aliases": aliases})


class StepParameters(Protocol):
    """A step's parameters: a dataclass whose fields are :func:`parameter` s, checked whole by
    ``validate()`` (``ValueError`` naming the value and the allowed range)."""

    __dataclass_fields__: ClassVar[dict[str, Any]]

    def validate(self) -> None: ...


P = TypeVar("P", bound=StepParameters)


@dataclass(frozen=True)
class FollowUp:
    """What follows a stored run of a step on its own, done by the application (it writes the
    report): ``analysis`` names the application's analysis of a stored run (``startup``,
    ``vibration``, ``angular``); ``on_request``: only when asked (``--analyze``), else after
    every passed run; ``summary``: what it does, in a line (the option's help)."""

    analysis: str
    on_request: bool
    summary: str


class Step(ABC, Generic[P]):
    """One test that produces named values with standard uncertainties (module docstring).

    Built from a parameter object or from keywords (a spec's table, the command line's
    options), validated at construction — before any instrument is touched — and recorded
    as a dict.  Its class docstring's first line is its one-line help (``bench run --help``).
    """

    name: ClassVar[str]
    #: station instruments it needs (a station without one is refused before a run exists)
    requires: ClassVar[tuple[str, ...]]
    #: sensor kinds it applies to (the unit a spec or ``--unit`` names)
    kinds: ClassVar[tuple[str, ...]]
    #: what ``run`` returns: measurement name → (unit, description)
    produces: ClassVar[Mapping[str, tuple[str, str]]] = {}
    Parameters: ClassVar[type[Any]]
    #: what the application does with a stored run of the step on its own, if anything
    follow_up: ClassVar[FollowUp | None] = None

    def __init__(self, params: P | None = None, **overrides: Any) -> None:
        if params is not None and overrides:
            raise ValueError("give a parameter object or keywords, not both")
        self.p: P = params if params is not None else self.Parameters(**overrides)
        self.p.validate()

    @classmethod
    def build(cls, table: Mapping[str, Any]) -> Step[Any]:
        """The step from a parameter table (a spec's ``[procedures.<name>]``): an unknown key
        is a ``ValueError`` naming it and the allowed ones; the values are validated."""
        allowed = [f.name for f in dataclasses.fields(cls.Parameters)]
        unknown = sorted(set(table) - set(allowed))
        if unknown:
            raise ValueError(f"unknown parameter(s) {unknown}; allowed: {allowed}")
        return cls(**table)

    @classmethod
    def summary(cls) -> str:
        """The first line of the step's own docstring (its ``bench run`` help)."""
        doc = cls.__dict__.get("__doc__") or ""
        return " ".join(doc.strip().split("\n\n")[0].split())

    def parameters(self) -> dict[str, Any]:
        """The validated parameters, for the run's record."""
        return dataclasses.asdict(self.p)

    def producible(self) -> set[str]:
        """What these parameters can produce (a 4-position tumble cannot separate K3 from K1);
        by default everything the step produces."""
        return set(self.produces)

    @abstractmethod
    def duration_s(self) -> float:
        """Simulated/real time the step takes (its weight in a sequence's progress)."""

    @abstractmethod
    def run(self, ctx: Context) -> Mapping[str, Estimate]:
        """Bring what it uses to its start state, take the test (streaming every sample to the
        run as it arrives, keeping its fit under the run's results) and return the produced
        values.  A value it could not produce is left out (a spec that judges it fails it)."""


@dataclass(frozen=True)
class Catalogue:
    """Every step the bench can run, by name, and the names that changed (old → new): a spec
    or a command line using an old name is told the new one."""

    steps: Mapping[str, type[Step[Any]]]
    renamed: Mapping[str, str] = field(default_factory=dict)

    @classmethod
    def of(cls, *steps: type[Step[Any]], renamed: Mapping[str, str] | None = None) -> Catalogue:
        by_name: dict[str, type[Step[Any]]] = {}
        for step in steps:
            if step.name in by_name:
                raise ValueError(f"two steps named {step.name!r}: {by_name[step.name].__name__} "
                                 f"and {step.__name__}")
            by_name[step.name] = step
        renamed = dict(renamed or {})
        for old, new in renamed.items():
            if new not in by_name:
                raise ValueError(f"renamed {old!r} → {new!r}: no step is named {new!r}")
        return cls(by_name, renamed)

    def __contains__(self, name: object) -> bool:
        return name in self.steps

    def __iter__(self) -> Iterator[str]:
        return iter(self.steps)

    def renamed_note(self, name: str) -> str:
        """``" (… is now 'new')"`` for a name that changed, else ``""``."""
        new = self.renamed.get(name)
        return f" (the step once named {name!r} is now {new!r})" if new is not None else ""

    def step(self, name: str) -> type[Step[Any]]:
        """The step class named ``name``; a ``LookupError`` naming the new name of a renamed
        step, or the known ones."""
        if name in self.steps:
            return self.steps[name]
        if name in self.renamed:
            raise LookupError(f"step {name!r} was renamed {self.renamed[name]!r}")
        raise LookupError(f"step {name!r} unknown; known: {sorted(self.steps)}")

    def build(self, name: str, table: Mapping[str, Any]) -> Step[Any]:
        """Step ``name`` built (and validated) from a parameter table."""
        return self.step(name).build(table)


__all__ = ["Limit", "Measurement", "Progress", "no_progress", "Context", "parameter", "StepParameters",
           "FollowUp", "Step", "Catalogue"]
