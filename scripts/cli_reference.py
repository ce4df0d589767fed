"""The CLI reference page (reference/cli.md), written from ``bench``'s own argparse parsers.

    .venv/bin/python scripts/cli_reference.py          # print the page

It is also an MkDocs hook (``hooks:`` in mkdocs.yml): every ``mkdocs build`` generates the page
from the parsers of the installed code, so it cannot go stale and is never committed. Each
command and sub-command gets the ``--help`` text a user sees, at a fixed width of 96 columns.
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Iterator
from typing import Any

from bench.app.cli import build_parser

PAGE = "reference/cli.md"
WIDTH = 96  # the help text's width, fixed so the page does not depend on the terminal

INTRO = """\
# CLI reference

<!-- generated at build time by scripts/cli_reference.py from bench's argparse parsers -->

Every command and sub-command of `bench`, with the help text `bench … --help` prints. Options
given before the command (`--store`) apply to every command. Exit codes: 0 success or the test
passed, 1 the test failed (a measurement outside its limits), 2 usage, configuration or
instrument error, or an aborted run — always with one line on stderr (`BENCH_DEBUG=1` shows the
traceback).
"""


def _subcommands(parser: argparse.ArgumentParser) -> Iterator[tuple[str, argparse.ArgumentParser]]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            yield from action.choices.items()


def _walk(parser: argparse.ArgumentParser, depth: int) -> Iterator[tuple[int, argparse.ArgumentParser]]:
    yield depth, parser
    for _name, sub in _subcommands(parser):
        yield from _walk(sub, depth + 1)


def _help(parser: argparse.ArgumentParser) -> str:
    previous = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = str(WIDTH + 2)  # argparse's formatter reads the width from here
    try:
        return parser.format_help().rstrip()
    finally:
        if previous is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = previous


def page() -> str:
    """The whole page: one section per command, nested as the commands are."""
    lines = [INTRO]
    for depth, parser in _walk(build_parser(None), 0):
        level = "#" * min(depth + 2, 4)
        lines += [f"{level} `{parser.prog}`", "", "```text", _help(parser), "```", ""]
    return "\n".join(lines)


def on_files(files: Any, config: Any) -> Any:
    """MkDocs hook: add the generated page to the site's files."""
    from mkdocs.structure.files import File  # noqa: PLC0415 — only MkDocs runs this hook

    files.append(File.generated(config, PAGE, content=page()))
    return files


if __name__ == "__main__":
    print(page())
