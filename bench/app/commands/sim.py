"""``bench sim serve``: serve the simulated station's instruments until interrupted.

One JSON line per endpoint, in the station table's order (``sim.station.INSTRUMENTS``), then
the sim-control endpoint ``sim``: ``name``, ``kind``, ``transport`` (``scpi`` | ``serial`` |
``modbus``), ``resource`` (the address a driver opens) and, for an instrument, the ``driver``
key a station file names it with.  Then, in the same order, one more line per further address
of an endpoint (``"transport": "hislip"``: a SCPI instrument's HiSLIP port, same name), so a
reader that takes the first lines by name still gets the raw sockets.

One line on stderr says which simulated time runs: event-driven (the default: it moves only
when a client waits; the same seed gives the same bytes) or paced (``--pace realtime|N``: it
also follows the wall clock, N simulated seconds per wall second)."""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading

from bench.app.station import load_station
from sim.station import INSTRUMENTS, SimStationConfig, SimulatedStation


def configure(sim: argparse.ArgumentParser) -> None:
    cmds = sim.add_subparsers(dest="sim_command", metavar="SUBCOMMAND")
    cmds.required = True
    serve = cmds.add_parser("serve", help="serve the simulated instruments on TCP and print "
                            "one JSON line per instrument (name, kind, transport, driver, resource)")
    serve.add_argument("--station", default=None, help="station TOML with a [simulation] table")
    serve.add_argument("--seed", type=int, default=None,
                       help="seed of the world [the station file's, else 0]")
    serve.add_argument("--host", default="127.0.0.1",
                       help="address to listen on [127.0.0.1]; anything else warns")
    serve.add_argument("--only", default=None, metavar="NAMES",
                       help="serve only these instruments, comma-separated (e.g. dmm,supply); "
                       "the sim-control endpoint is always served [all]")
    serve.add_argument("--pace", default=None, metavar="realtime|N",
                       help="simulated time also follows the wall clock, N simulated seconds per wall "
                       "second (realtime = 1), so a client that polls sees readings arrive "
                       "[the station file's, else event-driven: time moves only when a client waits]")
    serve.set_defaults(func=serve_sim)


def parse_pace(text: str) -> float:
    """``--pace``: ``realtime`` (1) or a number N (N simulated seconds per wall second)."""
    if text.strip().lower() == "realtime":
        return 1.0
    try:
        return float(text)
    except ValueError:
        raise ValueError(f"--pace {text!r} is neither realtime nor a number (simulated seconds "
                         "per wall second)") from None


def time_banner(pace: float | None) -> str:
    """The stderr line saying which simulated time a served station runs."""
    if pace is None:
        return ("bench: simulated time is event-driven: it moves only when a client waits "
                "(FETC?, *OPC?, SIM:TIME:ADV); the same seed gives the same bytes")
    rate = "real time" if pace == 1 else f"{pace:g}x real time"
    return (f"bench: simulated time is paced at {rate}: it moves with the wall clock, so readings "
            "arrive and ramps move while clients poll; replies depend on when they are asked")


def serve_sim(args: argparse.Namespace) -> int:
    options = {}
    if args.station:
        options = dict(load_station(args.station).simulation or {})
    if args.seed is not None:
        options["seed"] = args.seed
    if args.pace is not None:
        options["pace"] = parse_pace(args.pace)
    options["host"] = args.host
    config = SimStationConfig(**options)
    config.validate()
    only = None if args.only is None else [n.strip() for n in args.only.split(",") if n.strip()]
    if only is not None and not only:
        raise ValueError(f"--only {args.only!r} names no instrument")
    station = SimulatedStation(config, only=only)
    if args.host not in ("127.0.0.1", "localhost", "::1"):
        print(f"bench: warning: listening on {args.host}: reachable from the network",
              file=sys.stderr)
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):  # before the addresses are announced
        signal.signal(sig, lambda *_: stop.set())
    station.start()
    print(time_banner(config.pace), file=sys.stderr, flush=True)
    drivers = {row.name: row.driver for row in INSTRUMENTS}
    for e in [*station.endpoints, *(other for end in station.endpoints for other in end.also.values())]:
        line = {"name": e.name, "kind": e.kind, "transport": e.transport.name, "resource": e.resource}
        if e.name in drivers:
            line["driver"] = drivers[e.name]
        print(json.dumps(line), flush=True)
    while not stop.wait(0.5):
        pass
    station.stop()
    return 0
