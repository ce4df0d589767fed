"""``bench fleet yield | spc PARAM | trace SERIAL``: the central store's views of the fleet.

    bench fleet yield --by station            # Wilson 95 % intervals per group
    bench fleet spc k0 --model QA-2000-SIM    # individuals and X̄-R charts, Western Electric rules
    bench fleet trace QA-SIM-0003             # every run of a unit, on every station

Each reads the central store (``--central`` or ``$BENCH_CENTRAL``), prints a table, or the
``--json`` document, and with ``--html FILE`` writes a page with its plots (and its PDF beside
it, the page's foot carrying the SHA-256 of the ``--json`` document).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit, urlunsplit

import numpy as np

from bench.analysis.quality import RULES, individuals_chart, wilson_interval, xbar_r_charts
from bench.app.reports.fleet_report import FleetPage, spc_page, trace_page, yield_page
from bench.core.store.central import CentralStore
from bench.core.store.fleet import measurement_names, measurement_series, unit_runs, yield_counts
from bench.core.store.reader import is_central_url


def configure(fleet: argparse.ArgumentParser) -> None:
    cmds = fleet.add_subparsers(dest="fleet_command", metavar="VIEW")
    cmds.required = True
    y = cmds.add_parser("yield", help="acceptance yield by model, spec, lot, station or day")
    y.add_argument("--by", default="model", choices=("model", "spec", "lot", "station", "day"))
    y.set_defaults(func=fleet_yield)
    s = cmds.add_parser("spc", help="control charts of one measurement over time")
    s.add_argument("param", help="measurement name (e.g. k0, bias)")
    s.add_argument("--subgroup", type=int, default=5, help="X̄-R subgroup size, 2..10 [5]")
    s.add_argument("--station", default=None, help="only this station's runs")
    s.add_argument("--baseline", type=int, default=None, metavar="N",
                   help="limits from the first N values (a period known in control) [all]")
    s.set_defaults(func=fleet_spc)
    t = cmds.add_parser("trace", help="every run of one unit serial, across stations")
    t.add_argument("serial")
    t.set_defaults(func=fleet_trace)
    for p in (y, s, t):
        p.add_argument("--central", default=os.environ.get("BENCH_CENTRAL"),
                       help="central store URL [$BENCH_CENTRAL]")
        p.add_argument("--model", default=None, help="only units of this model")
        p.add_argument("--json", action="store_true", help="print the view as JSON")
        p.add_argument("--html", metavar="FILE", default=None,
                       help="also write an HTML page with plots, and its PDF beside it")


def _central_url(args) -> str:
    url = args.central or (args.store if is_central_url(args.store) else None)
    if not url:
        raise ValueError("no central store: give --central postgresql://… or set BENCH_CENTRAL")
    if not is_central_url(url):
        raise ValueError(f"--central {url!r} must be a postgresql:// URL")
    return url


def _central(args):
    return CentralStore(_central_url(args))


def shown_url(url: str) -> str:
    """A store URL as a page may print it: no password, no query (it may carry one)."""
    parts = urlsplit(url)
    host = parts.hostname or ""
    host = f"[{host}]" if ":" in host else host  # an IPv6 address keeps its brackets
    netloc = (f"{parts.username}@" if parts.username else "") + host + (f":{parts.port}" if parts.port else "")
    return urlunsplit((parts.scheme, netloc, parts.path, "", ""))


def _context(args, **view: Any) -> dict[str, Any]:
    """What the page's header says the view was drawn from."""
    return {**view, "model": args.model or "all models", "central store": shown_url(_central_url(args))}


def _emit(args, doc: dict[str, Any], lines: list[str], page: Callable[[], FleetPage]) -> int:
    pdf = None
    if args.html:
        path = Path(args.html)
        path.parent.mkdir(parents=True, exist_ok=True)
        page().write(path)
        pdf = path.with_suffix(".pdf")
    if args.json:
        json.dump(doc, sys.stdout, indent=2, allow_nan=False, default=str)
        print()
    else:
        print("\n".join(lines))
        if args.html:
            print(f"page: {args.html} (PDF: {pdf})")
    return 0


def fleet_yield(args) -> int:
    with _central(args) as central:
        counts = yield_counts(central, args.by, model=args.model)
    rows: list[dict[str, Any]] = []
    lines = [f"{args.by:<28} {'passed':>7} {'failed':>7} {'aborted':>8} {'yield':>8}  95 % (Wilson)"]
    for c in counts:
        y = wilson_interval(c.passed, c.passed + c.failed)
        rows.append({"group": c.group, "passed": c.passed, "failed": c.failed, "aborted": c.aborted,
                     "yield": y.to_dict()})
        shown = "—" if c.passed + c.failed == 0 else f"{100 * y.p:.1f} %"
        lines.append(f"{c.group:<28} {c.passed:>7} {c.failed:>7} {c.aborted:>8} "
                     f"{shown:>8}  [{100 * y.low:.1f}, {100 * y.high:.1f}]")
    if not rows:
        lines.append("no acceptance runs in the central store yet")
    doc = {"by": args.by, "model": args.model, "groups": rows}
    return _emit(args, doc, lines, lambda: yield_page(doc, _context(args, view=f"acceptance yield by {args.by}")))


def fleet_spc(args) -> int:
    if not 2 <= args.subgroup <= 10:
        raise ValueError(f"--subgroup {args.subgroup} not in 2..10")
    with _central(args) as central:
        points = measurement_series(central, args.param, model=args.model, station=args.station)
        if not points:
            raise LookupError(f"no values of {args.param!r} in the central store; measurements "
                              f"there: {', '.join(measurement_names(central)) or 'none'}")
    if len({p.unit for p in points}) > 1:
        raise ValueError(f"{args.param!r} is stored in several units {sorted({p.unit for p in points})}; "
                         "choose one model with --model")
    if len(points) < 2:
        raise ValueError(f"{args.param!r} has {len(points)} value; a chart needs at least 2")
    values = np.array([p.value for p in points])
    if args.baseline is not None and not 2 <= args.baseline <= values.size:
        raise ValueError(f"--baseline {args.baseline} not in 2..{values.size} (the values stored)")
    chart = individuals_chart(values, args.baseline)
    k = values.size // args.subgroup
    xbar = rng = None
    if k >= 2:
        xbar, rng = xbar_r_charts(values[:k * args.subgroup].reshape(k, args.subgroup))

    def described(c) -> dict[str, Any]:
        return {"centre": c.centre, "lcl": c.lcl, "ucl": c.ucl, "sigma": c.sigma,
                "violations": [{"index": i, "rule": r, "rule_text": RULES[r]} for i, r in c.violations]}

    doc = {"param": args.param, "unit": points[0].unit, "model": args.model, "n": len(points),
           "baseline": args.baseline,
           "low": points[-1].low, "high": points[-1].high,
           "individuals": described(chart),
           "xbar": None if xbar is None else {**described(xbar), "subgroup": args.subgroup},
           "range": None if rng is None else described(rng),
           "points": [{"started_utc": p.started_utc, "value": p.value, "station_id": p.station_id,
                       "lot": p.lot, "unit_serial": p.unit_serial, "run_uuid": p.run_uuid}
                      for p in points]}
    unit = points[0].unit
    lines = [f"{args.param} [{unit}]: {len(points)} values"
             + (f" of {args.model}" if args.model else ""),
             f"individuals: centre {chart.centre:.6g}, limits {chart.lcl:.6g} .. {chart.ucl:.6g} "
             f"(σ̂ {chart.sigma:.3g} from the moving range)"]
    if xbar is not None and rng is not None:
        lines.append(f"X̄ (n = {args.subgroup}): centre {xbar.centre:.6g}, limits {xbar.lcl:.6g} .. "
                     f"{xbar.ucl:.6g}; R: centre {rng.centre:.3g}, limits {rng.lcl:.3g} .. {rng.ucl:.3g}")
    flagged = chart.violations
    lines.append(f"Western Electric: {len({i for i, _ in flagged})} point(s) flagged"
                 + ("" if flagged else " — in control"))
    for i, r in flagged:
        p = points[i]
        lines.append(f"  #{i:<4} {p.started_utc[:19]} {p.unit_serial or '-':<16} {p.station_id:<16} "
                     f"{p.value:.6g}  rule {r}: {RULES[r]}")
    context = _context(args, view=f"control charts of {args.param} [{unit}]",
                       station=args.station or "all stations",
                       baseline=f"the first {args.baseline} values" if args.baseline else "all values",
                       subgroup=args.subgroup)
    return _emit(args, doc, lines, lambda: spc_page(doc, chart, xbar, rng, context))


def fleet_trace(args) -> int:
    with _central(args) as central:
        runs = unit_runs(central, args.serial)
    if not runs:
        raise LookupError(f"no run of unit {args.serial!r} in the central store")
    lines = [f"unit {args.serial}: {len(runs)} run(s) on {len({r['station_id'] for r in runs})} station(s)",
             f"{'started (UTC)':<20} {'station':<18} {'socket':<7} {'procedure':<11} {'status':<8} "
             f"{'samples':>9}  uuid"]
    for r in runs:
        lines.append(f"{r['started_utc'][:19]:<20} {r['station_id']:<18} {r['socket'] or '-':<7} "
                     f"{r['procedure']:<11} {r['status']:<8} {r['n_samples']:>9}  {r['uuid']}")
        failed = [m["name"] for m in r["measurements"] if m["outcome"] == "fail"]
        if failed:
            lines.append(f"{'':<20} failed: {', '.join(failed)}")
    lines.append("raw samples: bench runs show|export UUID --store <central URL>")
    doc = {"serial": args.serial, "runs": runs}
    return _emit(args, doc, lines, lambda: trace_page(doc, _context(args, view=f"every run of unit {args.serial}")))
