"""The batch runner (``bench.core.batch``) without a station: one record per socket, the shared
actions' events in every record, a socket's fault aborting it alone, a shared fault aborting
every socket still running, the teardown once."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import pytest

from bench.core.batch import BatchProcedure, BatchStep, SocketResult, execute_batch
from bench.core.operator import OperatorAbort
from bench.core.step import Context, Limit
from bench.core.store import RunStore
from bench.testing.steps import Count, bare_station
from bench.values import Estimate


class CountBatch(BatchStep):
    """Count for every socket at once; ``broken``: sockets whose data cannot be reduced;
    ``shared_fault``: the shared station fails (raises for everyone)."""

    requires = ("meter",)

    def __init__(self, n: int, broken: tuple[int, ...] = (), shared_fault: bool = False) -> None:
        super().__init__(Count(n=n))
        self.broken, self.shared_fault = broken, shared_fault
        self.seen: list[tuple[int, ...]] = []
        self.stream = f"counts_{n}"

    def run_batch(self, shared: Context, units: Mapping[int, Context]) -> dict[int, SocketResult]:
        self.seen.append(tuple(units))
        shared.run.event(shared.clock.now(), "table_moved", "once for the batch")
        shared.clock.sleep(self.step.duration_s())
        if self.shared_fault:
            raise ConnectionError("scanner lost")
        out: dict[int, SocketResult] = {}
        for n, unit in units.items():
            unit.run.add_stream(self.stream, {"t_s": "s", "value": "1"}, "per socket")
            unit.run.append(self.stream, t_s=[shared.clock.now()], value=[n])
            out[n] = RuntimeError(f"socket {n}: channel overloaded") if n in self.broken \
                else {"total": Estimate(float(10 * n), 0.1)}
        return out


class Judged(BatchProcedure):
    def __init__(self, steps: list[BatchStep], *, high: float = 25.0) -> None:
        super().__init__("acceptance", steps)
        self.high = high
        self.calls: list[str] = []

    def setup(self, shared: Context) -> None:
        self.calls.append("setup")
        shared.run.event(shared.clock.now(), "levelled", "once")

    def teardown(self, shared: Context) -> None:
        self.calls.append("teardown")

    def judge(self, unit: Context, step: BatchStep, produced: Mapping[str, Estimate]) -> None:
        unit.measure("total", produced["total"].value, "s", Limit(None, self.high))


def run(tmp_path, procedure: BatchProcedure, sockets: dict[int, str], **kw: Any):
    store = RunStore(tmp_path / "b.sqlite")
    ended: list[tuple[int, str]] = []
    outcomes = execute_batch(procedure, bare_station(meter=object()), store, sockets=sockets, seed=1,
                             labels={"station_id": "line-3"},
                             on_socket=lambda n, status, reason: ended.append((n, status)), **kw)
    return store, outcomes, ended


def test_one_record_per_socket_with_the_shared_events_and_its_own_verdict(tmp_path) -> None:
    second = CountBatch(1)
    procedure = Judged([CountBatch(2, broken=(3,)), second])
    store, outcomes, ended = run(tmp_path, procedure, {1: "SN-1", 2: "SN-2", 3: "SN-3", 4: "SN-4"})
    assert {n: o.status for n, o in outcomes.items()} == {1: "passed", 2: "passed", 3: "aborted",
                                                          4: "failed"}
    assert "channel overloaded" in (outcomes[3].reason or "")
    assert outcomes[4].reason == "out of limits: total, total"  # one per step
    assert procedure.calls == ["setup", "teardown"]          # shared actions once
    assert second.seen == [(1, 2, 4)]            # the aborted socket skips the rest
    assert [n for n, _ in ended] == [3, 1, 2, 4]
    for n, outcome in outcomes.items():
        info = store.get_run(outcome.run_id)
        assert info.unit_serial == f"SN-{n}" and info.status == outcome.status
        assert info.labels == {"station_id": "line-3", "socket": str(n)}
        kinds = [e.kind for e in store.events(outcome.run_id)]
        assert kinds[:3] == ["levelled", "step_start", "table_moved"]
    assert [a.name for a in store.attachments(outcomes[3].run_id)] == ["traceback.txt"]


def test_a_shared_fault_aborts_every_running_socket_and_tears_down_once(tmp_path) -> None:
    procedure = Judged([CountBatch(1, shared_fault=True)])
    _, outcomes, _ = run(tmp_path, procedure, {1: "SN-1", 5: "SN-5"})
    assert {o.status for o in outcomes.values()} == {"aborted"}
    assert all("scanner lost" in (o.reason or "") for o in outcomes.values())
    assert procedure.calls == ["setup", "teardown"]


def test_a_station_without_the_scanner_is_refused_before_any_record(tmp_path) -> None:
    store = RunStore(tmp_path / "b.sqlite")
    with pytest.raises(ValueError, match="lacks \\['meter'\\]"):
        execute_batch(Judged([CountBatch(1)]), bare_station(), store, sockets={1: "SN-1"}, seed=None)
    assert store.list_runs() == []


class PromptedBatch(Judged):
    def __init__(self, steps: list[BatchStep], before: int, text: str) -> None:
        super().__init__(steps)
        self.before, self.text = before, text

    def prompt_before(self, step: BatchStep) -> str | None:
        return self.text if self.steps.index(step) == self.before else None


def test_a_prompt_mid_batch_goes_into_every_record_and_abort_ends_every_socket_safely(tmp_path) -> None:
    class Operator:
        name = "Bo"

        def __init__(self, answer: bool) -> None:
            self.answer, self.asked = answer, 0

        def ask(self, text: str) -> bool:
            self.asked += 1
            return self.answer

    going_on = Operator(True)
    store, outcomes, _ = run(tmp_path, PromptedBatch([CountBatch(1), CountBatch(2)], 1, "close the cover"),
                             {1: "SN-1", 2: "SN-2"}, operator=going_on)
    assert going_on.asked == 1  # once for the batch, not once per socket
    for outcome in outcomes.values():
        assert outcome.status == "passed"
        kinds = [(e.kind, e.message) for e in store.events(outcome.run_id)]
        assert ("operator_prompt", "close the cover") in kinds and ("operator_answer", "continue") in kinds

    procedure = PromptedBatch([CountBatch(1), CountBatch(2)], 1, "close the cover")
    with pytest.raises(OperatorAbort):
        run(tmp_path / "abort", procedure, {1: "SN-1", 2: "SN-2"}, operator=Operator(False))
    store = RunStore(tmp_path / "abort" / "b.sqlite")
    runs = store.list_runs()
    assert len(runs) == 2 and procedure.calls == ["setup", "teardown"]
    for info in runs:
        assert info.status == "aborted"
        assert info.reason == "aborted by the operator at the prompt: close the cover"
        assert len(store.load(info.id, "counts_1")["value"]) == 1  # the first step's data kept
