"""The ``bench`` command line.

Exit codes: 0 success (or the test passed), 1 the test failed, 2 usage, configuration or
instrument error — always with a one-line message and no traceback for user errors
(set ``BENCH_DEBUG=1`` to see tracebacks).
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys

#: subcommand modules; each has ``register(subparsers)`` and sets ``func(args) -> int``
COMMAND_MODULES = ("bench.app.commands.run", "bench.app.commands.sim", "bench.app.commands.runs",
                   "bench.app.commands.analyze", "bench.app.commands.acceptance",
                   "bench.app.commands.doctor", "bench.app.commands.discover",
                   "bench.app.commands.sync", "bench.app.commands.fleet", "bench.app.commands.risk",
                   "bench.app.commands.station")


class UsageError(Exception):
    """A user mistake: printed as one line, exit code 2."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # argparse's default exits 2 with usage; keep it one line
        self.exit(2, f"bench: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="bench", description="Inertial-sensor test bench: run procedures on a "
                     "simulated or real station, store runs, analyse them.")
    parser.add_argument("--store", default=os.environ.get("BENCH_STORE", "bench-data/bench.sqlite"),
                        help="run store (SQLite) path [bench-data/bench.sqlite]")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    for name in COMMAND_MODULES:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name != name:
                raise
            continue
        module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
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
    except (UsageError, ValueError, LookupError, OSError) as exc:
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
