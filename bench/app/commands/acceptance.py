"""``bench acceptance``: calibrate a unit, judge it against its spec, store one record, report.

Exit 0 pass (marginal measurements included), 1 fail, 2 error or aborted run.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from bench.app.commands.common import open_store, progress_bar, seed_of


def register(sub) -> None:
    p = sub.add_parser("acceptance", help="factory acceptance test of one unit against its spec")
    p.add_argument("--station", default="sim", help="'sim' or a station TOML file [sim]")
    p.add_argument("--unit", default=None, help="unit serial number (sim default: the spec's "
                   "serial pattern with * = 0001)")
    p.add_argument("--spec", default=None, help="unit spec TOML [the built-in spec whose "
                   "serial_pattern matches --unit]")
    p.add_argument("--seed", type=int, default=None, help="seed of the simulated world")
    p.add_argument("--report", metavar="DIR", default="bench-data/reports",
                   help="write the HTML report into DIR/<run id>/ [bench-data/reports]")
    p.add_argument("--json", action="store_true", help="print the verdict document as JSON")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=run_acceptance)


def choose_spec(spec_path: str | None, unit: str | None):
    from bench.core.spec import load_spec
    from bench.specs import builtin_specs
    from procedures.acceptance import CATALOGUE

    if spec_path is not None:
        return load_spec(spec_path, CATALOGUE)
    specs = [load_spec(p, CATALOGUE) for p in builtin_specs()]
    if unit is None:
        raise ValueError("give --spec FILE or --unit SN (built-in specs match serials: "
                         + ", ".join(f"{s.serial_pattern} → {s.model}" for s in specs) + ")")
    matching = [s for s in specs if s.applies_to(unit)]
    if not matching:
        raise ValueError(f"no built-in spec matches unit {unit!r} (patterns: "
                         + ", ".join(str(s.serial_pattern) for s in specs) + "); give --spec FILE")
    return matching[0]


def run_acceptance(args) -> int:
    from bench.app.reports.acceptance_report import acceptance_document, write_acceptance_report
    from bench.app.station import Station, resolve_station
    from bench.core.procedure import execute
    from procedures.acceptance import AcceptanceTest

    started = time.perf_counter()
    spec = choose_spec(args.spec, args.unit)
    procedure = AcceptanceTest(spec)  # every step's parameters validated before the station opens
    config = resolve_station(args.station)
    unit = args.unit
    if unit is None:
        if not config.simulated or not spec.serial_pattern:
            raise ValueError("--unit SN is required on a real station")
        unit = spec.serial_pattern.replace("*", "0001")
    if spec.serial_pattern and not spec.applies_to(unit):
        print(f"bench: warning: unit {unit!r} does not match the spec's serial pattern "
              f"{spec.serial_pattern!r}", file=sys.stderr)
    report_root = Path(args.report)
    try:  # a report folder that cannot exist is refused before the unit is touched
        report_root.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"--report {args.report!r} cannot be created: {exc.strerror}") from None
    seed = seed_of(args, config)
    store = open_store(args)
    with Station(config, seed=seed, unit_serial=unit, unit_kind=spec.kind) as station, \
            progress_bar(not args.no_progress and not args.json) as progress:
        outcome = execute(procedure, station, store, unit_serial=unit, seed=seed, progress=progress)
    folder = report_root / outcome.run_id
    report_error = None
    try:
        report = write_acceptance_report(store, outcome.run_id, folder)
        mime = {".html": "text/html", ".png": "image/png", ".json": "application/json"}
        for f in sorted(folder.iterdir()):
            if f.is_file() and f.suffix in mime:
                store.attach_analysis(outcome.run_id, f"analysis/acceptance/{f.name}",
                                      f.read_bytes(), mime[f.suffix])
    except OSError as exc:  # the verdict is stored and still printed
        report, report_error = None, f"the report could not be written: {exc}"
    doc = acceptance_document(store, outcome.run_id)
    doc.update(report=None if report is None else str(report), store=str(store.path),
               wall_time_s=round(time.perf_counter() - started, 2))
    if args.json:
        json.dump(doc, sys.stdout, indent=2, allow_nan=False, default=str)
        print()
    else:
        print_verdict(doc)
    if report_error:
        print(f"bench: error: run {outcome.run_id} is stored, but {report_error}", file=sys.stderr)
        return 2
    return {"passed": 0, "failed": 1}.get(outcome.status, 2)


def print_verdict(doc: dict) -> None:
    print(f"{doc['model']} s/n {doc['unit']}: {doc['verdict']}"
          + (f" — {doc['reason']}" if doc.get("reason") else ""))
    print(f"  {'measurement':<18} {'value':>13} {'± unc.':>9} {'unit':<8} {'low':>9} {'high':>9}  outcome")
    for m in doc["measurements"]:
        unc = "" if m.get("uncertainty") is None else f"{m['uncertainty']:.2g}"
        low = "" if m["low"] is None else f"{m['low']:g}"
        high = "" if m["high"] is None else f"{m['high']:g}"
        value = "—" if m["value"] is None else f"{m['value']:.6g}"  # None: not produced
        print(f"  {m['name']:<18} {value:>13} {unc:>9} {m['unit']:<8} {low:>9} {high:>9}  "
              f"{m['outcome'].upper()}")
    print(f"run {doc['run_id']} stored in {doc['store']} (bench runs show {doc['run_id']})")
    if doc.get("report"):
        print(f"report: {doc['report']}")
    if "wall_time_s" in doc:
        print(f"wall time: {doc['wall_time_s']:.1f} s")
