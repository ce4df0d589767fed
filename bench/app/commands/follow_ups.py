"""What follows ``bench run <step>``: the application's analyses of a stored run.

A step declares its follow-up in the catalogue (``Step.follow_up``: which analysis, only on
``--analyze`` or after every passed run); the analysis itself writes HTML and plots, so it
lives here, in the application, by that name:

* ``startup``   — Document A's start-up model of the record (``bench analyze run``), JSON key
  ``analysis``, attached under ``analysis/startup/``;
* ``vibration`` — Document C's EMD → AR → AR-Kalman model of the steady vibration segment,
  ``analysis``, ``analysis/vibration/``;
* ``angular``   — the angular rig's report from the run's stored results (FRFs, fits,
  fusion), ``report``, ``analysis/angular/``.

Each returns a :class:`~bench.app.commands.common.FollowUpResult`; a failure is caught
here and becomes the result's error (the run is stored and reported first; exit 2).
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bench.app.commands.analyze import analyse_run, analysis_document, analysis_lines
from bench.app.commands.analyze_vibration import ATTACHED, analyse_vibration_run, summary
from bench.app.commands.common import FollowUpResult, attach_folder
from bench.app.verdict import record_digest
from bench.core.step import FollowUp
from bench.core.store import RunStore


@dataclass(frozen=True)
class StoredRunAnalysis:
    """One analysis of a stored run: what it is called in messages, its ``--json`` key, and
    ``run(store_path, run_id, report_root)``."""

    title: str
    key: str
    run: Callable[[Path, str, Path | None], FollowUpResult]


def _startup_model(store_path: Path, run_id: str, report_root: Path | None) -> FollowUpResult:
    _, analysis, report = analyse_run(store_path, run_id, report_root)
    label = f"run {run_id}"
    return FollowUpResult("analysis", analysis_document(analysis, label, report, run_id),
                          analysis_lines(analysis, label, report, run_id))


def _vibration_model(store_path: Path, run_id: str, report_root: Path | None) -> FollowUpResult:
    analysis, report = analyse_vibration_run(store_path, run_id, report_root)
    doc = analysis_document(analysis, f"run {run_id}", report)
    doc["attached"] = ATTACHED
    lines = [*summary(analysis, f"run {run_id} (steady vibration segment)").split("\n"),
             f"report attached to run {run_id} as {ATTACHED}"]
    return FollowUpResult("analysis", doc, lines + ([f"report: {report}"] if report is not None else []))


ANGULAR_ATTACHED = "analysis/angular/"


def attach_angular_report(store_path: Path, run_id: str, report_root: Path | None) -> Path | None:
    """The angular rig's report built from the run's stored results and attached to the run;
    also written to ``report_root/<run id>/`` when one is given (its path returned)."""
    # lazy: matplotlib only when the report is drawn (`bench run` imports this module for every step)
    from bench.app.reports.angular_report import write_angular_report  # noqa: PLC0415 — lazy, see above

    with RunStore(store_path) as store, tempfile.TemporaryDirectory() as tmp:
        results = store.results(run_id)
        info = store.get_run(run_id)
        aligned = None
        if "fusion.analysis" in results:
            try:
                aligned = store.load(run_id, "fusion_aligned")
            except LookupError:
                aligned = None
        labels = info.labels or {}
        context = {"run": run_id, "unit": info.unit_serial, "procedure": info.procedure,
                   "station": labels.get("station_id") or (info.station or {}).get("name"),
                   "operator": labels.get("operator"), "started (UTC)": info.started_utc, "seed": info.seed,
                   "run's code version": info.code_version, "digest": record_digest(store, run_id)}
        folder = Path(report_root) / run_id if report_root is not None else Path(tmp)
        report = write_angular_report(results, folder, context,
                                      None if aligned is None else {k: np.asarray(v) for k, v in aligned.items()})
        attach_folder(store, run_id, report.parent, ANGULAR_ATTACHED)
    return report if report_root is not None else None


def _angular_report(store_path: Path, run_id: str, report_root: Path | None) -> FollowUpResult:
    report = attach_angular_report(store_path, run_id, report_root)
    lines = [f"report attached to run {run_id} as {ANGULAR_ATTACHED}"]
    return FollowUpResult("report", {"attached": ANGULAR_ATTACHED, "path": None if report is None else str(report)},
                          lines + ([f"report: {report}"] if report is not None else []))


#: analysis name (``FollowUp.analysis``) → the analysis
ANALYSES: dict[str, StoredRunAnalysis] = {
    "startup": StoredRunAnalysis("start-up model", "analysis", _startup_model),
    "vibration": StoredRunAnalysis("vibration model", "analysis", _vibration_model),
    "angular": StoredRunAnalysis("angular rig report", "report", _angular_report),
}


def follow_up(declared: FollowUp, store_path: Path, run_id: str, report_root: Path | None) -> FollowUpResult:
    """Run the analysis a step declared on its stored run; a failure becomes the result's error."""
    analysis = ANALYSES[declared.analysis]
    try:
        return analysis.run(store_path, run_id, report_root)
    except (ValueError, LookupError, OSError) as exc:  # the run is stored and reported whatever happens
        return FollowUpResult(analysis.key, error=f"run {run_id} is stored, but its {analysis.key} failed: {exc}")
