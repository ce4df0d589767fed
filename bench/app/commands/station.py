"""``bench station serve``: the operator station — a web page to run batch acceptance;
``bench station user``: the users who may log in to it.

Binds to loopback by default, with no login.  Another address puts the station on the plant
network: it is served only with a users file (``--users``), and then every route needs an
operator's or engineer's login (``bench.app.operator.auth``); ``--tls-cert``/``--tls-key``
serve it over HTTPS, so the credentials do not cross the network in the clear.
"""

from __future__ import annotations

import argparse
import errno
import getpass
import ipaddress
import socket
import sys

from bench.app.operator.auth import Users, add_user
from bench.app.station import resolve_station

LOOPBACK_HOSTS = ("127.0.0.1", "::1", "localhost")


def configure(station: argparse.ArgumentParser) -> None:
    cmds = station.add_subparsers(dest="station_command", required=True)
    p = cmds.add_parser("serve", help="serve the operator page: batch acceptance with live plots")
    p.add_argument("--station", default="sim", help="'sim' or a station TOML file [sim]")
    p.add_argument("--port", type=int, default=8470, help="TCP port (0: any free one) [8470]")
    p.add_argument("--host", default="127.0.0.1", help="address to bind [127.0.0.1]; any "
                   "other than loopback needs --users")
    p.add_argument("--users", metavar="FILE", default=None,
                   help="users file (`bench station user`): every route then needs a login")
    p.add_argument("--tls-cert", metavar="PEM", default=None, help="serve HTTPS with this certificate")
    p.add_argument("--tls-key", metavar="PEM", default=None, help="… and this private key")
    p.add_argument("--spec", default=None, help="unit spec TOML [the built-in spec matching "
                   "the serials]")
    p.add_argument("--seed", type=int, default=None, help="seed of the simulated world")
    p.add_argument("--report", metavar="DIR", default="bench-data/reports",
                   help="reports folder, served under /reports [bench-data/reports]")
    p.add_argument("--station-id", default=None, help="this station's name in the fleet")
    p.set_defaults(func=serve)
    u = cmds.add_parser("user", help="add a user to a users file (or change its role and password)")
    u.add_argument("file", help="users file (TOML; created if missing, mode 600)")
    u.add_argument("name", help="login name: 1..32 letters, digits or ._-")
    u.add_argument("--role", required=True, choices=("operator", "engineer"),
                   help="operator: run batches; engineer: also the station health check")
    u.add_argument("--password-stdin", action="store_true",
                   help="read the password from the first line of stdin (scripts)")
    u.set_defaults(func=add_user_command)


def check_host(host: str, users: str | None) -> str:
    """Loopback, or any address with a users file: ValueError naming the address otherwise."""
    try:
        loopback = host == "localhost" or ipaddress.ip_address(host).is_loopback
    except ValueError:
        loopback = False
    if not loopback and users is None:
        raise ValueError(f"--host {host!r}: beyond loopback ({', '.join(LOOPBACK_HOSTS)}) the "
                         "station needs a login — give --users FILE (`bench station user FILE NAME "
                         "--role operator`), and --tls-cert/--tls-key for HTTPS")
    return host


def serve(args) -> int:
    # lazy: uvicorn only for `station serve` (`station user` stays a quick prompt)
    import uvicorn  # noqa: PLC0415 — lazy, see above

    # lazy: starlette and the batch, procedures and reports behind the page: `station serve` only
    from bench.app.operator.server import OperatorStation, create_app  # noqa: PLC0415 — lazy, see above

    host = check_host(args.host, args.users)
    if not 0 <= args.port <= 65535:
        raise ValueError(f"--port {args.port} not in 0..65535")
    args.port = _bindable(host, args.port)
    if (args.tls_cert is None) != (args.tls_key is None):
        raise ValueError("--tls-cert and --tls-key go together")
    users = Users.load(args.users) if args.users is not None else None
    config = resolve_station(args.station)
    labels = {"station_id": args.station_id} if args.station_id else None
    station = OperatorStation(config, args.store, args.report, seed=args.seed, spec_path=args.spec,
                              labels=labels)
    scheme = "https" if args.tls_cert else "http"
    login = f", login: {len(users.users)} user(s) of {args.users}" if users else ""
    print(f"operator station on {scheme}://{host}:{args.port}/ (store {args.store}{login}); "
          "Ctrl-C stops it", flush=True)
    uvicorn.run(create_app(station, users), host=host, port=args.port, log_level="warning",
                ssl_certfile=args.tls_cert, ssl_keyfile=args.tls_key)
    return 0


def _bindable(host: str, port: int) -> int:
    """``port`` when it can be listened on at ``host`` now (0: a free one, chosen here so the
    address printed is the one served); ValueError, exit 2, when another program holds it."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind((host, port))
        except OSError as exc:
            if exc.errno == errno.EADDRINUSE:
                raise ValueError(f"--port {port}: {host}:{port} is in use by another program; stop it or "
                                 "give another --port (0: any free one)") from None
            raise ValueError(f"--host {host} --port {port}: cannot listen there ({exc.strerror})") from None
        return int(probe.getsockname()[1])


def add_user_command(args) -> int:
    if args.password_stdin:
        password = sys.stdin.readline().rstrip("\n")
    else:
        password = getpass.getpass(f"password for {args.name}: ")
        if getpass.getpass("again: ") != password:
            raise ValueError("the two passwords differ")
    add_user(args.file, args.name, args.role, password)
    print(f"{args.name} ({args.role}) in {args.file}")
    return 0
