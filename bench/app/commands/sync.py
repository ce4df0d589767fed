"""``bench sync``: forward this station's finished runs to the central store (PostgreSQL).

The station's SQLite store is the queue (``bench.core.store.forward``): each run goes in one
transaction under its UUID, so a sync interrupted anywhere, repeated, or run by two processes
at once stores every run once.  With ``BENCH_CENTRAL`` set, every ``bench run`` / ``bench
acceptance`` forwards what is queued when it ends
(:func:`bench.app.commands.common.forward_after_run`); a central store that cannot be reached
then leaves the runs queued for the next run or ``bench sync``.

    bench sync --central postgresql://bench@db-host/bench --retry-for 600
    bench sync --follow          # keep forwarding as runs finish (a station's service)
"""

from __future__ import annotations

import argparse
import json
import os
import time

from bench.app.commands.common import CENTRAL_ENV, open_store
from bench.core.store.forward import sync
from bench.core.store.reader import is_central_url


def configure(p: argparse.ArgumentParser) -> None:
    p.add_argument("--central", default=os.environ.get(CENTRAL_ENV),
                   help=f"central store URL, postgresql://user@host:port/db [${CENTRAL_ENV}]")
    p.add_argument("--retry-for", type=float, default=0.0, metavar="S",
                   help="keep retrying for S seconds while the server is unreachable [0: once]")
    p.add_argument("--limit", type=int, default=None, help="send at most this many runs")
    p.add_argument("--follow", action="store_true",
                   help="keep running: forward new runs as they finish, retrying while the "
                   "server is down (Ctrl-C stops)")
    p.add_argument("--interval", type=float, default=5.0, metavar="S",
                   help="with --follow: seconds between looks at the store [5]")
    p.add_argument("--status", action="store_true", help="only say what is queued")
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    p.set_defaults(func=run_sync)


def _central_url(args) -> str:
    if not args.central:
        raise ValueError(f"no central store: give --central postgresql://… or set {CENTRAL_ENV}")
    if not is_central_url(args.central):
        raise ValueError(f"--central {args.central!r} must be a postgresql:// URL")
    return str(args.central)


def run_sync(args) -> int:
    url = _central_url(args)
    if args.retry_for < 0 or args.interval <= 0:
        raise ValueError(f"--retry-for {args.retry_for} must be ≥ 0 s and --interval "
                         f"{args.interval} > 0 s")
    if args.limit is not None and args.limit < 1:
        raise ValueError(f"--limit {args.limit} must be ≥ 1")
    store = open_store(args, create=False)
    if args.status:
        queued = store.unforwarded_run_ids()
        print(json.dumps({"queued": queued}) if args.json
              else f"{len(queued)} finished run(s) never forwarded" + "".join(f"\n  {r}" for r in queued))
        return 0
    while True:
        report = sync(store, url, retry_for_s=args.retry_for, limit=args.limit)
        if args.json:
            print(json.dumps(report.to_dict()), flush=True)
        elif report.stored or report.present or not report.complete or not args.follow:
            print(_summary(report), flush=True)
        if not args.follow:
            return 0 if report.complete else 2
        time.sleep(args.interval)  # a service polling its queue: wall time is right here


def _summary(report) -> str:
    rate = report.samples / report.seconds if report.seconds > 0 else 0.0
    text = (f"{report.central}: {len(report.stored)} run(s) stored ({report.samples} samples, "
            f"{rate:,.0f} samples/s), {len(report.present)} already there, "
            f"{len(report.pending)} queued")
    if report.conflicts:
        text += f", {len(report.conflicts)} in conflict: {', '.join(report.conflicts)}"
    if report.error:
        text += f" — {report.error}"
    return text

