"""``bench doctor``: is every configured instrument there, healthy and as expected?

The check itself (identity, error queue, options, one round trip; OK, FAIL or OFF per
instrument) is :func:`bench.app.health.diagnose`; this command prints its table or JSON.

Exit codes: 0 every instrument OK (or OFF), 1 at least one FAIL, 2 the station cannot
be opened at all (a bad station file, an embedded simulation that does not start, no
instruments configured).
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import asdict

from bench.app.health import Health, diagnose
from bench.app.station import resolve_station


def configure(p: argparse.ArgumentParser) -> None:
    p.add_argument("--station", default="sim", help="'sim' (built-in simulated station) or a "
                   "station TOML file [sim]")
    p.add_argument("--json", action="store_true", help="print the results as JSON")
    p.set_defaults(func=run_doctor)


def run_doctor(args) -> int:
    config = resolve_station(args.station)  # StationError (ValueError) → exit 2 in the CLI
    results = diagnose(config)
    healthy = all(r.status != "FAIL" for r in results)
    if args.json:
        json.dump({"station": config.name, "healthy": healthy,
                   "instruments": [asdict(r) for r in results]}, sys.stdout, indent=2)
        print()
    else:
        print_table(config.name, results)
    return 0 if healthy else 1


def print_table(station: str, results: list[Health]) -> None:
    print(f"station {station}: {len(results)} instrument(s)")
    wn = max([len("instrument")] + [len(r.name) for r in results])
    wd = max([len("driver")] + [len(r.driver) for r in results])
    print(f"{'instrument':<{wn}} {'driver':<{wd}} {'address':<34} {'identity':<48} "
          f"{'errors':>6} {'rtt ms':>7}  status")
    for r in results:
        rtt = "-" if r.round_trip_ms is None else f"{r.round_trip_ms:.1f}"
        errors = "-" if r.status == "FAIL" and not r.identity else str(len(r.errors))
        status = r.status + (f" ({r.reason})" if r.reason else "")
        print(f"{r.name:<{wn}} {r.driver:<{wd}} {r.address[:34]:<34} {r.identity[:48] or '-':<48} "
              f"{errors:>6} {rtt:>7}  {status}")
    bad = sum(r.status == "FAIL" for r in results)
    print("all healthy" if not bad else f"{bad} unhealthy")
