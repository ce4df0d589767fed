"""``bench run frf`` and ``bench run fusion``: the angular vibration rig (Document B).

``frf`` measures both rate sensors' frequency response against the table reference
(stepped sine) and fits their transfer functions; ``fusion`` does that quickly, records a
multi-tone profile and compares Document B's sequential adaptive-R Kalman fusion with each
sensor alone, a fixed-R Kalman fusion and a complementary filter (``procedures/frf.py``,
``procedures/fusion.py``).  Each step's parameters are options.  The HTML report is always
attached to the run under ``analysis/angular/``; ``--report DIR`` also writes it to
``DIR/<run id>/``.
"""

from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

from bench.app.commands.common import print_outcome
from bench.app.commands.run_steps import add_parameter_options, execute_step, exit_code, load_step, step_from_args

ANALYSIS_PREFIX = "analysis/angular/"
COMMANDS = {
    "frf": ("procedures.frf", "FrfTest",
            "angular rig: frequency response of the MHD and LF rate sensors (stepped sine) and their models"),
    "fusion": ("procedures.fusion", "FusionTest",
               "angular rig: Document B's sequential Kalman fusion vs each sensor, fixed-R KF, complementary"),
}


def register_procedure(procs, common) -> None:
    for name, (_, _, help_text) in COMMANDS.items():
        p = procs.add_parser(name, help=help_text)
        common(p)
        add_parameter_options(p, load_step(name, COMMANDS)[1])
        p.add_argument("--report", metavar="DIR", default=None,
                       help="also write the HTML report into DIR/<run id>/")
        p.set_defaults(func=run_angular, step_name=name)


def attach_report(store_path, run_id: str, report_root: Path | None) -> Path | None:
    """Build the report from the run's stored results and attach it to the run."""
    import numpy as np

    from bench.app.reports.angular_report import write_angular_report
    from bench.core.store import RunStore

    with RunStore(store_path) as store, tempfile.TemporaryDirectory() as tmp:
        results = store.results(run_id)
        info = store.get_run(run_id)
        aligned = None
        if "fusion.analysis" in results:
            try:
                aligned = store.load(run_id, "fusion_aligned")
            except LookupError:
                aligned = None
        context = {"run": run_id, "unit": info.unit_serial, "procedure": info.procedure, "seed": info.seed,
                   "code version": info.code_version}
        folder = Path(report_root) / run_id if report_root is not None else Path(tmp)
        report = write_angular_report(results, folder, context,
                                      None if aligned is None else {k: np.asarray(v) for k, v in aligned.items()})
        mime = {".html": "text/html", ".png": "image/png", ".json": "application/json"}
        for f in sorted(report.parent.iterdir()):
            if f.is_file() and f.suffix in mime:
                store.attach_analysis(run_id, ANALYSIS_PREFIX + f.name, f.read_bytes(), mime[f.suffix])
    return report if report_root is not None else None


def run_angular(args) -> int:
    report_root = None if args.report is None else Path(args.report)
    if report_root is not None and report_root.exists() and not report_root.is_dir():
        raise ValueError(f"--report {args.report!r} exists and is not a folder")
    step = step_from_args(args, *load_step(args.step_name, COMMANDS))  # validated before the station opens
    outcome = execute_step(args, step)
    report = report_error = None
    if outcome.status == "passed":
        try:
            report = attach_report(args.store, outcome.run_id, report_root)
        except (ValueError, LookupError, OSError, KeyError) as exc:  # the run is stored whatever happens
            report_error = f"run {outcome.run_id} is stored, but its report failed: {exc}"
    if args.json:
        doc = outcome.to_dict()
        if outcome.status == "passed" and report_error is None:
            doc["report"] = {"attached": ANALYSIS_PREFIX, "path": None if report is None else str(report)}
        if report_error:
            doc["report_error"] = report_error
        json.dump(doc, sys.stdout, indent=2, allow_nan=False)
        print()
    else:
        print_outcome(outcome)
        if report_error:
            print(report_error, file=sys.stderr)
        elif outcome.status == "passed":
            print(f"report attached to run {outcome.run_id} as {ANALYSIS_PREFIX}")
            if report is not None:
                print(f"report: {report}")
    return exit_code(outcome) if report_error is None else 2
