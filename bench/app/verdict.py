"""The verdict of a finished run from its stored measurements: PASS, PASS (marginal), FAIL or
ABORTED — what ``bench runs show``, the operator page's history and the acceptance report say;
and the record's digest a signed report prints (:func:`record_digest`).

Plain data in, a word out: no plotting, so a reading command gets it without matplotlib."""

from __future__ import annotations

from typing import Any

from bench.core.store.digest import stored_digest


def measurements_of(results: dict[str, Any]) -> list[dict[str, Any]]:
    """A run's measurements (its ``measurement.<name>`` results), in stored order."""
    return [v for k, v in results.items() if k.startswith("measurement.")]


def verdict_of(status: str, measurements: list[dict[str, Any]]) -> str:
    """PASS / PASS (marginal) / FAIL / ABORTED for a finished run."""
    if status == "aborted":
        return "ABORTED"
    if status == "failed" or any(m["outcome"] == "fail" for m in measurements):
        return "FAIL"
    if any(m["outcome"] == "marginal" for m in measurements):
        return "PASS (marginal)"
    return "PASS"


def record_digest(store, run_id: str) -> str:
    """The digest the central store checks for the finished run (``digest.stored_digest``); a
    sentence saying why there is none for a run still running or a store that cannot say."""
    if not hasattr(store, "chunk_rows"):
        return "not computed here (read from the central store)"
    try:
        return stored_digest(store, run_id)
    except ValueError as exc:
        return f"none yet: {exc}"
