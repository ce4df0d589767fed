"""The one ending of every command that runs something (``bench.app.commands.common.conclude``):
the table or the ``--json`` document, what followed the run, and the exit code — 0 passed,
1 failed, 2 aborted or a follow-up that failed (the run is reported first)."""

from __future__ import annotations

import json

import pytest

from bench.app.commands.common import FollowUpResult, conclude
from bench.core.procedure import RunOutcome
from bench.core.step import Limit, Measurement


def outcome(status: str) -> RunOutcome:
    m = Measurement("k1", 1.31, "mA/g", Limit(1.2, 1.46), "scale factor K1", 4e-6)
    return RunOutcome("RUN-1", status, None if status == "passed" else "why", [m], "b.sqlite")


@pytest.mark.parametrize("status,code", [("passed", 0), ("failed", 1), ("aborted", 2), ("running", 2)])
def test_exit_code_follows_the_status(status, code, capsys):
    assert conclude(outcome(status), as_json=True) == code
    doc = json.loads(capsys.readouterr().out)
    assert list(doc) == ["run_id", "status", "reason", "store", "measurements"] and doc["status"] == status


def test_follow_ups_join_the_document_and_the_table(capsys):
    extra = FollowUpResult("report", {"attached": "analysis/x/", "path": None}, ["report attached"])
    assert conclude(outcome("passed"), as_json=True, follow_ups=[extra]) == 0
    assert json.loads(capsys.readouterr().out)["report"] == {"attached": "analysis/x/", "path": None}
    assert conclude(outcome("failed"), as_json=False, follow_ups=[extra]) == 1
    out = capsys.readouterr().out.splitlines()
    assert out[0] == "run RUN-1: FAILED — why" and out[1].split()[:2] == ["k1", "1.31"]
    assert out[-2:] == ["stored in b.sqlite (bench runs show RUN-1)", "report attached"]


def test_a_failed_follow_up_is_named_and_exits_2_after_the_outcome(capsys):
    broken = FollowUpResult("analysis", error="run RUN-1 is stored, but its analysis failed: too short")
    assert conclude(outcome("passed"), as_json=True, follow_ups=[broken]) == 2
    captured = capsys.readouterr()
    doc = json.loads(captured.out)
    assert doc["status"] == "passed" and "analysis" not in doc and "too short" in doc["analysis_error"]
    assert captured.err == "bench: error: run RUN-1 is stored, but its analysis failed: too short\n"
    assert conclude(outcome("passed"), as_json=False, table=["verdict"], follow_ups=[broken]) == 2
    assert capsys.readouterr().out == "verdict\n"
