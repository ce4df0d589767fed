"""The ``bench`` command line.

Exit codes: 0 success (or the test passed), 1 the test failed, 2 usage, configuration or
instrument error — always with a one-line message and no traceback for user errors
(set ``BENCH_DEBUG=1`` to see tracebacks).

Start-up: this module imports only the standard library. The command table below names each
command's module and help line; ``bench --help`` shows the table without importing any
command, and a command line imports the one module of the command it names.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from importlib import metadata

#: command -> (module with ``configure(parser)`` that adds the options and sets ``func(args) -> int``,
#: the one-line help shown by ``bench --help``)
COMMANDS: dict[str, tuple[str, str]] = {
    "run": ("bench.app.commands.run", "run one step on a station and store the run"),
    "sim": ("bench.app.commands.sim", "the simulated station"),
    "runs": ("bench.app.commands.runs", "list, show and export stored runs"),
    "analyze": ("bench.app.commands.analyze", "analyse a trace or a stored run"),
    "acceptance": ("bench.app.commands.acceptance", "factory acceptance test of one unit against its spec"),
    "doctor": ("bench.app.commands.doctor",
               "check every instrument of a station: identity, error queue, options, round trip"),
    "discover": ("bench.app.commands.discover", "name the effect the model lacks (discrepancy workflow)"),
    "sync": ("bench.app.commands.sync", "forward finished runs to the central store (PostgreSQL)"),
    "fleet": ("bench.app.commands.fleet",
              "yield, control charts and traceability across stations (central store)"),
    "risk": ("bench.app.commands.risk",
             "yield and false accept/reject of an acceptance spec (Monte Carlo on Dask)"),
    "station": ("bench.app.commands.station", "the operator station (web page)"),
}


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # argparse's default exits 2 with usage; keep it one line
        self.exit(2, f"bench: error: {message}\n")


def version() -> str:
    """The installed package's version (``bench --version``)."""
    try:
        return metadata.version("inertial-bench")
    except metadata.PackageNotFoundError:  # run from a source tree that was never installed
        return "0+unknown"


def chosen_command(argv: list[str]) -> str | None:
    """The command a command line names: the first word that is one, past the global options."""
    words = iter(argv)
    for word in words:
        if word == "--store":
            next(words, None)
        elif word in COMMANDS:
            return word
        elif not word.startswith("-"):
            return None  # a typo: argparse says which choices there are
    return None


def build_parser(argv: list[str] | None = None) -> argparse.ArgumentParser:
    """The parser for ``argv``: every command listed, the one ``argv`` names configured.

    With ``argv`` None every command is configured (the reference documentation does this).
    """
    parser = _Parser(prog="bench", description="Inertial-sensor test bench: run procedures on a "
                     "simulated or real station, store runs, analyse them.")
    parser.add_argument("--version", action="version", version=f"bench {version()}")
    parser.add_argument("--store", default=os.environ.get("BENCH_STORE", "bench-data/bench.sqlite"),
                        help="run store (SQLite) path [bench-data/bench.sqlite]")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    chosen = chosen_command(argv) if argv is not None else None
    for name, (module_name, help_line) in COMMANDS.items():
        p = sub.add_parser(name, help=help_line, description=help_line)
        if argv is None or name == chosen:
            # Deliberately lazy: a command's module imports what it runs (numpy, the procedures,
            # the simulator), which `bench --help` and every other command must not pay for.
            importlib.import_module(module_name).configure(p)
            _accept_store_after(p)
    return parser


def _accept_store_after(parser: argparse.ArgumentParser) -> None:
    """``--store`` also after the command (``bench runs list --store URL``), as the help shows
    it before: every parser under the command takes it, leaving the global value when absent."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                _accept_store_after(sub)
    if "--store" not in parser._option_string_actions:
        parser.add_argument("--store", default=argparse.SUPPRESS,
                            help="run store (SQLite path or postgresql:// URL), as `bench --store`")


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser(argv)
    args, extra = parser.parse_known_args(argv)
    if extra and not getattr(args, "ignores_arguments", False):  # as parse_args, unless the
        parser.error(f"unrecognized arguments: {' '.join(extra)}")  # command only says "renamed"
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        print("bench: interrupted", file=sys.stderr)
        return 2
    except BrokenPipeError:  # output piped into `head` and the like: not an error of ours
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except (ValueError, LookupError, OSError) as exc:  # a user's mistake: one line
        if os.environ.get("BENCH_DEBUG"):
            raise
        print(f"bench: error: {exc}", file=sys.stderr)
        return 2
    except Exception as exc:  # instrument errors and the like: still one line
        if os.environ.get("BENCH_DEBUG"):
            raise
        print(f"bench: error: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
