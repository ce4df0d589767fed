"""The framework's steps (``bench.core.step``) and runner (``bench.core.procedure``), without a
station: a step's parameters and build, the catalogue's names, and a procedure run — set-up,
steps in order with events and scaled progress, judging, a teardown that always runs, the
abort path."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import pytest

from bench.core.operator import OperatorAbort
from bench.core.procedure import Procedure, execute
from bench.core.step import Catalogue, Context, Limit, Step
from bench.core.store import RunStore
from bench.testing.steps import Count, CountParameters, bare_station
from bench.values import Estimate


class Bare(Step[CountParameters]):
    name = "bare"
    requires = ()
    kinds = ("gyro",)
    Parameters = CountParameters

    def duration_s(self) -> float:
        return 0.0

    def run(self, ctx: Context) -> Mapping[str, Estimate]:
        return {}


class Recorded(Procedure):
    def __init__(self, steps: list[Step[Any]], *, teardown_fails: bool = False) -> None:
        super().__init__("recorded", steps)
        self.calls: list[str] = []
        self.teardown_fails = teardown_fails

    def setup(self, ctx: Context) -> None:
        ctx.run.add_stream("counts", {"t_s": "s", "value": "1"}, "every value")
        self.calls.append("setup")

    def teardown(self, ctx: Context) -> None:
        self.calls.append("teardown")
        if self.teardown_fails:
            raise OSError("supply unreachable")


def test_a_step_is_built_validated_and_recorded() -> None:
    step = Count.build({"n": 4})
    assert step.parameters() == {"n": 4, "fail_at": -1}
    assert Count(CountParameters(n=2)).p.n == 2
    assert Count.summary() == "Counts: produces ``n`` values, one per simulated second."
    assert Bare.summary() == ""  # its own docstring only, not the base class's
    with pytest.raises(ValueError, match=r"unknown parameter\(s\) \['m'\]; allowed: \['n', 'fail_at'\]"):
        Count.build({"m": 1})
    with pytest.raises(ValueError, match="n = 11 not in 1..10"):
        Count(n=11)
    with pytest.raises(ValueError, match="not both"):
        Count(CountParameters(), n=2)
    assert step.producible() == {"total", "last"}
    (field,) = [f for f in dataclasses.fields(CountParameters) if f.name == "n"]
    assert field.metadata["help"] == "values to produce"


def test_the_catalogue_names_steps_once_and_says_the_new_name_of_an_old_one() -> None:
    catalogue = Catalogue.of(Count, Bare, renamed={"tally": "count"})
    assert list(catalogue) == ["count", "bare"] and "count" in catalogue
    assert catalogue.build("count", {"n": 2}).parameters()["n"] == 2
    with pytest.raises(LookupError, match="'tally' was renamed 'count'"):
        catalogue.step("tally")
    with pytest.raises(LookupError, match=r"'nope' unknown; known: \['bare', 'count'\]"):
        catalogue.step("nope")
    assert "is now 'count'" in catalogue.renamed_note("tally") and catalogue.renamed_note("count") == ""
    with pytest.raises(ValueError, match="two steps named 'count'"):
        Catalogue.of(Count, Count)
    with pytest.raises(ValueError, match="no step is named 'counter'"):
        Catalogue.of(Count, renamed={"tally": "counter"})


def test_steps_run_in_order_between_setup_and_teardown_and_are_judged(tmp_path) -> None:
    store = RunStore(tmp_path / "b.sqlite")
    procedure = Recorded([Count(n=3), Count(n=2)])
    seen: list[tuple[float, float, str]] = []
    outcome = execute(procedure, bare_station(meter=object()), store, unit_serial="U1", seed=None,
                      progress=lambda done, total, message="": seen.append((done, total, message)))
    assert outcome.status == "passed" and procedure.calls == ["setup", "teardown"]
    # every produced value, in its own unit, no limits; "last" was not produced
    assert [(m.name, m.value, m.unit, m.limit, m.uncertainty) for m in outcome.measurements] == [
        ("total", 6.0, "s", Limit(), 0.5), ("total", 3.0, "s", Limit(), 0.5)]
    kinds = [(e.kind, e.message) for e in store.events(outcome.run_id)]
    assert kinds == [("step_start", "count"), ("step_end", "count")] * 2
    # each step's progress is its share of the whole (3 s then 2 s of 5), labelled by the step
    assert seen[0] == (1.0, 5.0, "count: value 1") and seen[3] == (3.0 + 1.0, 5.0, "count: value 1")
    assert seen[-1] == (5.0, 5.0, "done")
    info = store.get_run(outcome.run_id)
    assert info.parameters == {"count": {"n": 2, "fail_at": -1}}  # by step name in a sequence
    assert store.load(outcome.run_id, "counts")["value"].tolist() == [1, 2, 3, 1, 2]


def test_one_step_records_its_own_parameters_and_a_fault_aborts_keeping_the_data(tmp_path) -> None:
    store = RunStore(tmp_path / "b.sqlite")
    procedure = Recorded([Count(n=5, fail_at=3)])
    outcome = execute(procedure, bare_station(meter=object()), store, unit_serial=None, seed=1)
    assert outcome.status == "aborted" and outcome.reason == "RuntimeError: meter lost at 3"
    assert procedure.calls == ["setup", "teardown"]
    assert store.get_run(outcome.run_id).parameters == {"n": 5, "fail_at": 3}
    assert store.load(outcome.run_id, "counts")["value"].tolist() == [1, 2]
    assert any(a.name == "traceback.txt" for a in store.attachments(outcome.run_id))


def test_a_failed_teardown_aborts_a_passed_run_and_is_logged(tmp_path) -> None:
    store = RunStore(tmp_path / "b.sqlite")
    outcome = execute(Recorded([Count(n=1)], teardown_fails=True), bare_station(meter=1), store,
                      unit_serial=None, seed=None)
    assert (outcome.status, outcome.reason) == ("aborted", "teardown failed: OSError: supply unreachable")
    assert ("teardown_error", "OSError: supply unreachable") in [
        (e.kind, e.message) for e in store.events(outcome.run_id)]


def test_a_station_without_what_the_steps_need_is_refused_before_a_run(tmp_path) -> None:
    store = RunStore(tmp_path / "b.sqlite")
    with pytest.raises(ValueError, match=r"lacks \['meter'\] needed by 'recorded'"):
        execute(Recorded([Bare(), Count()]), bare_station(), store, unit_serial=None, seed=None)
    assert store.list_runs() == []
    with pytest.raises(ValueError, match="has no steps"):
        Recorded([])


class Answering:
    """An operator who answers from a list and remembers what was asked."""

    name = "Ann"

    def __init__(self, *answers: bool) -> None:
        self.answers, self.asked = list(answers), list[str]()

    def ask(self, text: str) -> bool:
        self.asked.append(text)
        return self.answers.pop(0)


class Prompted(Recorded):
    def __init__(self, steps: list[Step[Any]], prompts: dict[int, str]) -> None:
        super().__init__(steps)
        self.prompts = prompts

    def prompt_before(self, step: Step[Any]) -> str | None:
        return self.prompts.get(self.steps.index(step))


def test_a_prompt_before_a_step_is_asked_and_recorded_and_abort_leaves_the_station_safe(tmp_path) -> None:
    store = RunStore(tmp_path / "b.sqlite")
    first, second = Count(n=1), Count(n=2)
    operator = Answering(True)
    outcome = execute(Prompted([first, second], {1: "close the cover"}), bare_station(meter=object()), store,
                      unit_serial="U1", seed=None, operator=operator)
    assert outcome.status == "passed" and operator.asked == ["close the cover"]
    events = [(e.kind, e.message, e.data) for e in store.events(outcome.run_id)]
    assert events[2:5] == [("operator_prompt", "close the cover", {}),
                           ("operator_answer", "continue", {"operator": "Ann"}),
                           ("step_start", "count", {})]

    procedure = Prompted([Count(n=1), Count(n=2)], {1: "close the cover"})
    with pytest.raises(OperatorAbort):
        execute(procedure, bare_station(meter=object()), store, unit_serial="U2", seed=None,
                operator=Answering(False))
    info = store.get_run(store.list_runs()[0].id)
    assert info.status == "aborted"
    assert info.reason == "aborted by the operator at the prompt: close the cover"
    assert procedure.calls == ["setup", "teardown"]           # the teardown ran: station safe
    assert len(store.load(info.id, "counts")["value"]) == 1  # the first step's data kept

    unattended = execute(Prompted([Count(n=1)], {0: "mount the unit"}), bare_station(meter=object()), store,
                         unit_serial="U3", seed=None)  # nobody to ask: continues, says so
    answer = [e for e in store.events(unattended.run_id) if e.kind == "operator_answer"]
    assert unattended.status == "passed" and answer[0].data == {"operator": "unattended"}


def test_an_estimate_is_measured_or_a_bound_and_says_which():
    assert Estimate(1.0, 0.1).to_dict() == {"value": 1.0, "std": 0.1}  # measured: no bound key
    assert Estimate(125.0, None, bound="upper").to_dict()["bound"] == "upper"
    with pytest.raises(ValueError, match="bound = 'sideways' must be one of"):
        Estimate(1.0, None, bound="sideways")
