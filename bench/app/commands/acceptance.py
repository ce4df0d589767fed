"""``bench acceptance``: calibrate a unit, judge it against its spec, store one record, report.

Exit 0 pass (marginal measurements included), 1 fail, 2 error or aborted run.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from bench.app import session
from bench.app.batch import parse_sockets, run_batch, spec_for_sockets
from bench.app.commands.common import (
    FollowUpResult,
    attach_folder,
    conclude,
    forward_after_run,
    label_options,
    labels_of,
    open_store,
    operator_of,
    operator_options,
    progress_bar,
    seed_of,
)
from bench.app.reports.acceptance_report import acceptance_document, write_acceptance_report
from bench.app.wording import bound_text
from procedures.acceptance import AcceptanceTest


def configure(p: argparse.ArgumentParser) -> None:
    p.add_argument("--station", default="sim", help="'sim' or a station TOML file [sim]")
    p.add_argument("--unit", default=None, help="unit serial number (sim default: the spec's "
                   "serial pattern with * = 0001)")
    p.add_argument("--spec", default=None, help="unit spec TOML [the built-in spec whose "
                   "serial_pattern matches --unit]")
    p.add_argument("--seed", type=int, default=None, help="seed of the simulated world")
    p.add_argument("--report", metavar="DIR", default="bench-data/reports",
                   help="write the HTML report into DIR/<run id>/ [bench-data/reports]")
    p.add_argument("--sockets", default=None, metavar="N=SN,...",
                   help="a batch on the fixture: socket=serial pairs (sockets 1..8), e.g. "
                   "'1=QA-SIM-0001,2=QA-SIM-0002'; one run and one report per unit")
    p.add_argument("--json", action="store_true", help="print the verdict document as JSON")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    label_options(p)
    operator_options(p)
    p.set_defaults(func=run_acceptance)


def run_acceptance(args) -> int:
    if args.sockets is not None:
        return run_batch_acceptance(args)
    started = time.perf_counter()
    spec = session.choose_spec(args.spec, args.unit)
    AcceptanceTest(spec)  # every step's parameters validated before the station opens
    config = session.station_config(args.station)
    unit = session.acceptance_unit(spec, config, args.unit)
    if spec.serial_pattern and not spec.applies_to(unit):
        print(f"bench: warning: unit {unit!r} does not match the spec's serial pattern "
              f"{spec.serial_pattern!r}", file=sys.stderr)
    report_root = Path(args.report)
    try:  # a report folder that cannot exist is refused before the unit is touched
        report_root.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"--report {args.report!r} cannot be created: {exc.strerror}") from None
    seed = seed_of(args, config)  # --seed named in the error, before the unit is touched
    labels = labels_of(args, config)  # so is --operator
    store = open_store(args)
    with progress_bar(not args.no_progress and not args.json) as progress:
        outcome = session.run_acceptance(unit, spec=spec, station=config, seed=seed, store=store,
                                         labels=labels, operator=operator_of(args), progress=progress)
    folder = report_root / outcome.run_id
    report = None
    written = FollowUpResult("report")
    try:
        report = write_acceptance_report(store, outcome.run_id, folder)
        attach_folder(store, outcome.run_id, folder, "analysis/acceptance/")
    except OSError as exc:  # the verdict is stored and still printed
        written.error = f"run {outcome.run_id} is stored, but the report could not be written: {exc}"
    doc = acceptance_document(store, outcome.run_id)
    doc.update(report=None if report is None else str(report), store=str(store.path),
               wall_time_s=round(time.perf_counter() - started, 2))
    return conclude(outcome, as_json=args.json, document=doc, table=verdict_lines(doc),
                    follow_ups=[written])


def run_batch_acceptance(args) -> int:
    """``--sockets``: the batch on the fixture, each unit's verdict, exit 0 all passed, 1 one
    failed, 2 one aborted."""
    if args.unit is not None or args.socket is not None:
        raise ValueError("--sockets names every unit and its socket: give no --unit / --socket")
    sockets = parse_sockets(args.sockets)
    spec = spec_for_sockets(sockets, args.spec)
    for n, serial in sockets.items():
        if spec.serial_pattern and not spec.applies_to(serial):
            print(f"bench: warning: socket {n}: unit {serial!r} does not match the spec's serial "
                  f"pattern {spec.serial_pattern!r}", file=sys.stderr)
    config = session.station_config(args.station)
    report_root = Path(args.report)
    try:
        report_root.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"--report {args.report!r} cannot be created: {exc.strerror}") from None
    seed = seed_of(args, config)
    store = open_store(args)
    with progress_bar(not args.no_progress and not args.json) as progress:
        result = run_batch(config, sockets, spec, store, seed=seed, report_root=report_root,
                           labels=labels_of(args, config), progress=progress,
                           operator=operator_of(args))
    if args.json:
        json.dump({"sockets": {str(n): d for n, d in result.documents.items()},
                   "wall_time_s": round(result.wall_time_s, 2)},
                  sys.stdout, indent=2, allow_nan=False, default=str)
        print()
    else:
        for n, doc in result.documents.items():
            print(f"socket {n}:")
            for line in verdict_lines(doc):
                print("  " + line)
        print(f"batch of {len(sockets)}: " + ", ".join(
            f"{n}={d['verdict']}" for n, d in result.documents.items())
            + f"; wall time {result.wall_time_s:.1f} s")
    for doc in result.documents.values():
        if doc.get("report_error"):
            print(f"bench: error: {doc['report_error']}", file=sys.stderr)
    forward_after_run(str(store.path))
    return result.exit_code


def verdict_lines(doc: dict) -> list[str]:
    """The verdict and the measurement table of an acceptance document, as printed."""
    lines = [f"{doc['model']} s/n {doc['unit']}: {doc['verdict']}"
             + (f" — {doc['reason']}" if doc.get("reason") else ""),
             f"  {'measurement':<18} {'value':>13} {'± unc.':>9} {'unit':<8} {'low':>9} {'high':>9}  outcome"]
    for m in doc["measurements"]:
        unc = "" if m.get("uncertainty") is None else f"{m['uncertainty']:.2g}"
        low = "" if m["low"] is None else f"{m['low']:g}"
        high = "" if m["high"] is None else f"{m['high']:g}"
        value = "—" if m["value"] is None else f"{bound_text(m)}{m['value']:.6g}"  # None: not produced
        lines.append(f"  {m['name']:<18} {value:>13} {unc:>9} {m['unit']:<8} {low:>9} {high:>9}  "
                     f"{m['outcome'].upper()}")
    lines.append(f"run {doc['run_id']} stored in {doc['store']} (bench runs show {doc['run_id']})")
    if doc.get("report"):
        lines.append(f"report: {doc['report']}")
    if "wall_time_s" in doc:
        lines.append(f"wall time: {doc['wall_time_s']:.1f} s")
    return lines
