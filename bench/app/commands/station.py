"""``bench station serve``: the operator station — a web page to run batch acceptance.

Binds to loopback by default.  Binding to another address would put the station on the
plant network, where an operator/engineer login is needed; this version has none, so any
other address is refused with that reason.
"""

from __future__ import annotations

import ipaddress

LOOPBACK_HOSTS = ("127.0.0.1", "::1", "localhost")


def register(sub) -> None:
    station = sub.add_parser("station", help="the operator station (web page)")
    cmds = station.add_subparsers(dest="station_command", required=True)
    p = cmds.add_parser("serve", help="serve the operator page: batch acceptance with live plots")
    p.add_argument("--station", default="sim", help="'sim' or a station TOML file [sim]")
    p.add_argument("--port", type=int, default=8470, help="TCP port (0: any free one) [8470]")
    p.add_argument("--host", default="127.0.0.1", help="address to bind: loopback only "
                   "(127.0.0.1, ::1) [127.0.0.1]")
    p.add_argument("--spec", default=None, help="unit spec TOML [the built-in spec matching "
                   "the serials]")
    p.add_argument("--seed", type=int, default=None, help="seed of the simulated world")
    p.add_argument("--report", metavar="DIR", default="bench-data/reports",
                   help="reports folder, served under /reports [bench-data/reports]")
    p.add_argument("--station-id", default=None, help="this station's name in the fleet")
    p.set_defaults(func=serve)


def check_host(host: str) -> str:
    """Loopback only: ValueError naming the address otherwise."""
    try:
        loopback = host == "localhost" or ipaddress.ip_address(host).is_loopback
    except ValueError:
        loopback = False
    if not loopback:
        raise ValueError(f"--host {host!r}: only loopback addresses ({', '.join(LOOPBACK_HOSTS)}) "
                         "are served — another address needs an operator/engineer login, which "
                         "this version does not have")
    return host


def serve(args) -> int:
    import uvicorn

    from bench.app.operator.server import OperatorStation, create_app
    from bench.app.station import resolve_station

    host = check_host(args.host)
    if not 0 <= args.port <= 65535:
        raise ValueError(f"--port {args.port} not in 0..65535")
    config = resolve_station(args.station)
    labels = {"station_id": args.station_id} if args.station_id else None
    station = OperatorStation(config, args.store, args.report, seed=args.seed, spec_path=args.spec,
                              labels=labels)
    print(f"operator station on http://{host}:{args.port}/ (store {args.store}); Ctrl-C stops it",
          flush=True)
    uvicorn.run(create_app(station), host=host, port=args.port, log_level="warning")
    return 0
