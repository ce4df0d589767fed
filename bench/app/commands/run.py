"""``bench run startup``: run a procedure on a station and store the run."""

from __future__ import annotations

import importlib
import json
import pkgutil
import sys

from bench.app.commands.common import open_store, print_outcome, progress_bar, seed_of, unit_of
from bench.app.station import Station, resolve_station
from bench.core.procedure import execute


def register(sub) -> None:
    run = sub.add_parser("run", help="run a procedure on a station")
    procs = run.add_subparsers(dest="procedure", metavar="PROCEDURE")
    procs.required = True
    p = procs.add_parser("startup", help="start-up acquisition of a quartz accelerometer "
                         "(Document A, step 1)")
    _common(p)
    p.add_argument("--duration-s", type=float, default=1800.0, help="trace after power-on [1800]")
    p.add_argument("--rate-hz", type=float, default=100.0, help="output sample rate [100]")
    p.add_argument("--off-wait-s", type=float, default=600.0,
                   help="cool-down with the supply off before the cold start [600]")
    p.add_argument("--analyze", action="store_true",
                   help="fit Document A's start-up model to the run and attach the report")
    p.add_argument("--report", metavar="DIR", default=None,
                   help="with --analyze: also write the report into DIR/<run id>/")
    p.set_defaults(func=run_startup)
    # Further procedures live in their own modules, each with ``register_procedure(procs, common)``.
    for name in _procedure_modules():
        importlib.import_module(name).register_procedure(procs, _common)


def _procedure_modules() -> list[str]:
    """``bench.app.commands.run_<name>`` modules; each adds ``bench run <name>``."""
    import bench.app.commands as pkg

    return sorted(f"bench.app.commands.{m.name}" for m in pkgutil.iter_modules(pkg.__path__)
                  if m.name.startswith("run_"))


def _common(p) -> None:
    p.add_argument("--station", default="sim", help="'sim' (built-in simulated station) or a "
                   "station TOML file [sim]")
    p.add_argument("--unit", default=None, help="unit serial number")
    p.add_argument("--seed", type=int, default=None, help="seed of the simulated world")
    p.add_argument("--json", action="store_true", help="print the outcome as JSON")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def run_startup(args) -> int:
    from procedures.startup import StartupAcquisition, StartupParameters

    if args.report is not None and not args.analyze:
        raise ValueError("--report DIR needs --analyze (the report is the start-up model's)")
    params = StartupParameters(duration_s=args.duration_s, rate_hz=args.rate_hz,
                               off_wait_s=args.off_wait_s)
    procedure = StartupAcquisition(params)  # validates before any instrument is touched
    config = resolve_station(args.station)
    store = open_store(args)
    unit, seed = unit_of(args, config, "accelerometer"), seed_of(args, config)
    with Station(config, seed=seed, unit_serial=unit) as station, \
            progress_bar(not args.no_progress and not args.json) as progress:
        outcome = execute(procedure, station, store, unit_serial=unit, seed=seed,
                          progress=progress)
    analysis = report = analysis_error = None
    if args.analyze and outcome.status == "passed":
        from pathlib import Path

        from bench.app.commands.analyze import analyse_run

        try:
            _, analysis, report = analyse_run(store.path, outcome.run_id,
                                              None if args.report is None else Path(args.report))
        except (ValueError, LookupError, OSError) as exc:  # the run is kept and reported first
            analysis_error = f"run {outcome.run_id} is stored, but its analysis failed: {exc}"
    if args.json:
        doc = outcome.to_dict()
        if analysis is not None:
            from bench.app.commands.analyze import analysis_document

            doc["analysis"] = analysis_document(analysis, f"run {outcome.run_id}", report,
                                                outcome.run_id)
        if analysis_error:
            doc["analysis_error"] = analysis_error
        json.dump(doc, sys.stdout, indent=2, allow_nan=False)
        print()
    else:
        print_outcome(outcome)
        if analysis is not None:
            from bench.app.commands.analyze import print_analysis

            print_analysis(analysis, f"run {outcome.run_id}", report, outcome.run_id)
    if analysis_error:
        print(f"bench: error: {analysis_error}", file=sys.stderr)
        return 2
    return {"passed": 0, "completed": 0, "failed": 1}.get(outcome.status, 2)
