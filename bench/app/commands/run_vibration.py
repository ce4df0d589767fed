"""``bench run vibration``: a FOG through static, random vibration, static (Document C's test).

The unit's serial names the simulated gyro (``--unit``); the run stores every frame with
its segment (see ``procedures/vibration.py``).  With ``--analyze`` the steady vibration
segment's rate goes through Document C's EMD → AR → AR-Kalman model
(:func:`bench.analysis.vibration.analyze_vibration`); the report is attached to the run
under ``analysis/vibration/`` and, with ``--report DIR``, also written to ``DIR/<run id>/``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from bench.app.commands.common import open_store, print_outcome, progress_bar, seed_of, unit_of

ANALYSIS_PREFIX = "analysis/vibration/"


def register_procedure(procs, common) -> None:
    from procedures.vibration import VibrationParameters

    d = VibrationParameters()
    p = procs.add_parser("vibration", help="gyro frames through static, random vibration, static "
                         "(Document C): noise, rms under vibration, rectified bias shift")
    common(p)
    p.add_argument("--level-grms", type=float, default=d.level_grms,
                   help=f"flat random level, g rms [{d.level_grms:g}]")
    p.add_argument("--f-lo-hz", type=float, default=d.f_lo_hz, help=f"profile start, Hz [{d.f_lo_hz:g}]")
    p.add_argument("--f-hi-hz", type=float, default=d.f_hi_hz, help=f"profile end, Hz [{d.f_hi_hz:g}]")
    p.add_argument("--duration-s", type=float, default=d.duration_s,
                   help=f"steady vibration segment, s [{d.duration_s:g}]")
    p.add_argument("--static-s", type=float, default=d.static_s,
                   help=f"each static segment, s [{d.static_s:g}]")
    p.add_argument("--rate-hz", type=int, default=d.frame_rate_hz, help=f"gyro frame rate [{d.frame_rate_hz}]")
    p.add_argument("--ramp-s", type=float, default=d.ramp_s, help=f"shaker ramp time, s [{d.ramp_s:g}]")
    p.add_argument("--warmup-s", type=float, default=d.warmup_s, help=f"gyro warm-up, s [{d.warmup_s:g}]")
    p.add_argument("--analyze", action="store_true",
                   help="model the vibration segment (EMD → AR → AR-Kalman) and attach the report")
    p.add_argument("--report", metavar="DIR", default=None,
                   help="with --analyze: also write the report into DIR/<run id>/")
    p.set_defaults(func=run_vibration)


def analyse_vibration_run(store_path, run_id: str, report_root: Path | None):
    """Document C's model of the run's steady vibration segment; the report is attached to
    the run under ``analysis/vibration/``.  Returns ``(analysis, report path or None)``."""
    import tempfile

    import numpy as np

    from bench.analysis.vibration import analyze_vibration
    from bench.app.reports.vibration_report import write_vibration_report
    from bench.core.store import RunStore

    with RunStore(store_path) as store, tempfile.TemporaryDirectory() as tmp:
        frames = store.load(run_id, "gyro_frames")
        keep = (frames["segment"] == 1) & frames["steady"].astype(bool)
        if not np.any(keep):
            raise ValueError(f"run {run_id} has no steady vibration frames to analyse")
        analysis = analyze_vibration(frames["t_s"][keep], frames["rate_dps"][keep])
        info = store.get_run(run_id)
        context = {"run": run_id, "unit": info.unit_serial, "procedure": info.procedure,
                   "seed": info.seed, "code version": info.code_version,
                   "record": "gyro_frames.rate_dps, steady vibration segment (deg/s)"}
        folder = Path(report_root) / run_id if report_root is not None else Path(tmp)
        report = write_vibration_report(analysis, folder, context)
        mime = {".html": "text/html", ".png": "image/png", ".json": "application/json"}
        for f in sorted(report.parent.iterdir()):
            if f.is_file() and f.suffix in mime:
                store.attach_analysis(run_id, ANALYSIS_PREFIX + f.name, f.read_bytes(), mime[f.suffix])
    return analysis, (report if report_root is not None else None)


def run_vibration(args) -> int:
    from bench.app.station import Station, resolve_station
    from bench.core.procedure import execute
    from procedures.steps import StepProcedure
    from procedures.vibration import VibrationParameters, VibrationTest

    if args.report is not None and not args.analyze:
        raise ValueError("--report DIR needs --analyze (the report is the vibration model's)")
    step = VibrationTest(VibrationParameters(  # validated before the station opens
        static_s=args.static_s, duration_s=args.duration_s, level_grms=args.level_grms,
        f_lo_hz=args.f_lo_hz, f_hi_hz=args.f_hi_hz, ramp_s=args.ramp_s, warmup_s=args.warmup_s,
        frame_rate_hz=args.rate_hz))
    config = resolve_station(args.station)
    unit, seed = unit_of(args, config, "gyro"), seed_of(args, config)
    store = open_store(args)
    with Station(config, seed=seed, unit_serial=unit, unit_kind="gyro") as station, \
            progress_bar(not args.no_progress and not args.json) as progress:
        outcome = execute(StepProcedure(step), station, store, unit_serial=unit, seed=seed,
                          progress=progress)
    analysis = report = analysis_error = None
    if args.analyze and outcome.status == "passed":
        try:
            analysis, report = analyse_vibration_run(store.path, outcome.run_id,
                                                     None if args.report is None else Path(args.report))
        except (ValueError, LookupError, OSError) as exc:  # the run is kept and reported first
            analysis_error = f"run {outcome.run_id} is stored, but its analysis failed: {exc}"
    if args.json:
        doc = outcome.to_dict()
        if analysis is not None:
            from bench.app.commands.analyze import analysis_document

            doc["analysis"] = analysis_document(analysis, f"run {outcome.run_id}", report)
            doc["analysis"]["attached"] = ANALYSIS_PREFIX
        if analysis_error:
            doc["analysis_error"] = analysis_error
        json.dump(doc, sys.stdout, indent=2, allow_nan=False)
        print()
    else:
        print_outcome(outcome)
        if analysis is not None:
            from bench.app.commands.analyze_vibration import summary

            print(summary(analysis, f"run {outcome.run_id} (steady vibration segment)"))
            print(f"report attached to run {outcome.run_id} as {ANALYSIS_PREFIX}")
            if report is not None:
                print(f"report: {report}")
    if analysis_error:
        print(f"bench: error: {analysis_error}", file=sys.stderr)
        return 2
    return {"passed": 0, "failed": 1}.get(outcome.status, 2)
