"""``bench risk``: yield and decision risk of an acceptance spec by Monte Carlo on Dask.

    bench risk --spec bench/specs/qa2000-sim.toml --units 200 --workers 2 --seed 1
    bench risk --spec ... --units 1000 --scheduler tcp://10.0.0.5:8786

Runs the real acceptance procedure on ``--units`` units drawn from the simulated population
(``bench.app.risk``), stores every run, and prints per measurement the false accept and false
reject rates (Wilson 95 % intervals) against the drawn truth and the guard band that brings
false accept to ``--target`` (ANSI/NCSL Z540.3: 2 %), then the whole test's.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

from bench.app.commands.common import forward_after_run, open_store, progress_bar
from bench.app.risk import assess, run_on_dask
from bench.core.spec import load_spec
from procedures.catalogue import CATALOGUE


def configure(p: argparse.ArgumentParser) -> None:
    p.add_argument("--spec", required=True, help="unit spec TOML (e.g. bench/specs/qa2000-sim.toml)")
    p.add_argument("--units", type=int, required=True, help="units to draw and test")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, default=None,
                       help="processes of a new local Dask cluster [the machine's cores]")
    where.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                       help="an existing Dask scheduler's address (its workers must import bench "
                       "and reach --store)")
    p.add_argument("--seed", type=int, default=0, help="root seed: unit i is SeedSequence(seed, i) [0]")
    p.add_argument("--target", type=float, default=0.02, help="false-accept target of the guard "
                   "band [0.02, Z540.3]")
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    p.add_argument("--no-progress", action="store_true")
    p.set_defaults(func=run_risk)


def run_risk(args) -> int:
    if not 2 <= args.units <= 1_000_000:
        raise ValueError(f"--units {args.units} not in 2..1000000")
    if args.workers is not None and not 1 <= args.workers <= 256:
        raise ValueError(f"--workers {args.workers} not in 1..256")
    if not 0 <= args.seed < 2**63:
        raise ValueError(f"--seed {args.seed} not in 0..2**63-1")
    if not 0 < args.target < 1:
        raise ValueError(f"--target {args.target} not in (0, 1)")
    if args.scheduler is not None and not args.scheduler.startswith(("tcp://", "tls://")):
        raise ValueError(f"--scheduler {args.scheduler!r} must be tcp://HOST:PORT")
    spec = load_spec(args.spec, CATALOGUE)  # refused before any worker starts
    store = open_store(args)  # created here, so that workers only open it
    store_path = str(Path(store.location).resolve())
    store.close()
    started = time.perf_counter()
    with progress_bar(not args.no_progress and not args.json) as progress:
        results = run_on_dask(str(Path(args.spec).resolve()), args.units, args.seed, store_path,
                              workers=args.workers or (os.cpu_count() or 1) if args.scheduler is None
                              else None, scheduler=args.scheduler,
                              on_done=lambda n, total: progress(n, total, f"unit {n}/{total}"))
    report = assess(spec, args.seed, results, args.target)
    wall_s = time.perf_counter() - started
    if args.json:
        doc = report.to_dict()
        doc.update(wall_time_s=round(wall_s, 2), store=store_path,
                   units_detail=sorted(results, key=lambda u: u["index"]))
        json.dump(doc, sys.stdout, indent=2, allow_nan=False, default=str)
        print()
    else:
        for line in risk_lines(report):
            print(line)
        print(f"runs stored in {store_path}; wall time {wall_s:.1f} s")
    forward_after_run(store_path)
    return 0


def _pct(p) -> str:
    return f"{100 * p.p:5.2f} % [{100 * p.low:.2f}, {100 * p.high:.2f}]"


def risk_lines(report) -> list[str]:
    """The risk table as printed (and pasted into docs/RESULTS.md)."""
    lines = [f"{report.model} ({report.spec}): {report.units} units, seed {report.root_seed}",
             f"yield {_pct(report.yield_)}" + (f"; {report.aborted} aborted" if report.aborted else ""),
             f"{'measurement':<20} {'nonconf.':>8} {'FA':>4} {'FR':>4} {'err sd':>10} "
             f"{'PFA model':>10} {'PFR model':>10} {'guard band':>11}  needs one?"]
    for name, r in report.per_measurement.items():
        need = "yes" if r.guard_band > 0 else "no"
        lines.append(f"{name:<20} {r.nonconforming.successes:>8} {r.false_accept.successes:>4} "
                     f"{r.false_reject.successes:>4} {r.error_sd:>10.3g} {100 * r.pfa_model:>9.3f}% "
                     f"{100 * r.pfr_model:>9.3f}% {r.guard_band:>11.4g}  {need}")
    lines.append(f"whole test: false accept {_pct(report.overall_false_accept)}, "
                 f"false reject {_pct(report.overall_false_reject)}; "
                 f"{report.rejected_unscored} unit(s) rejected on unscored measurements")
    for name, why in report.unscored.items():
        lines.append(f"  not scored: {name} — {why}")
    return lines
