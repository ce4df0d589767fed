"""The documentation's commands, read out of its Markdown pages so tests can hold them true.

A fenced shell block (info string ``sh``) is **runnable** when the line just before its fence is
the marker ``<!-- runnable -->`` (invisible on GitHub and on the site). Runnable blocks must
work on a fresh checkout with the simulated station alone, in seconds: a test runs them, in
order, in an empty folder, as a reader would paste them. Commands that need real hardware,
a server left running or minutes of time are shown in unmarked blocks; those are still
parsed by ``bench``'s own argument parser (``bench_command_lines``), so every option they show
exists.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

#: the marker line that makes the fenced block after it runnable
RUNNABLE_MARK = "<!-- runnable -->"

_FENCE = re.compile(r"^(\s*)(`{3,})\s*([\w+-]*)")
_LINK = re.compile(r"(?<!!)\[[^\]]*\]\(([^)\s]+)\)|!\[[^\]]*\]\(([^)\s]+)\)")
_HEREDOC = re.compile(r"<<-?\s*'?\"?(\w+)'?\"?")


@dataclass(frozen=True)
class Block:
    """One fenced block of a page: its info string, text, opening line (1-based), runnable mark."""

    path: Path
    line: int
    info: str
    text: str
    runnable: bool


def fenced_blocks(path: str | os.PathLike[str]) -> list[Block]:
    """Every fenced code block of a Markdown page, in page order (indented fences included)."""
    path = Path(path)
    lines = path.read_text(encoding="utf-8").splitlines()
    blocks: list[Block] = []
    i = 0
    while i < len(lines):
        m = _FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        indent, fence, info = m.groups()
        previous = next((s.strip() for s in reversed(lines[:i]) if s.strip()), "")
        body: list[str] = []
        j = i + 1
        while j < len(lines) and not lines[j].strip().startswith(fence):
            body.append(lines[j][len(indent):] if lines[j].startswith(indent) else lines[j].lstrip())
            j += 1
        blocks.append(Block(path, i + 1, info, "\n".join(body) + "\n", previous == RUNNABLE_MARK))
        i = j + 1
    return blocks


def runnable_blocks(path: str | os.PathLike[str]) -> list[Block]:
    """The page's runnable shell blocks, in page order."""
    blocks = [b for b in fenced_blocks(path) if b.runnable]
    wrong = [b.line for b in blocks if b.info not in ("sh", "bash")]
    if wrong:
        raise ValueError(f"{path}: runnable blocks must be sh or bash, not at lines {wrong}")
    return blocks


def reader_environment() -> dict[str, str]:
    """The environment a reader has after ``. .venv/bin/activate``: this interpreter's ``bench``
    and ``python`` first on PATH, no store or central store chosen by the caller's environment."""
    env = {k: v for k, v in os.environ.items() if k not in ("BENCH_STORE", "BENCH_CENTRAL", "BENCH_DEBUG")}
    env["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), env.get("PATH", "")])
    env["NO_COLOR"] = "1"
    return env


def run_block(block: Block, cwd: str | os.PathLike[str], timeout_s: float = 120.0) -> subprocess.CompletedProcess[str]:
    """Run one shell block with bash (``-e``, ``-u``, ``pipefail``) in ``cwd``, as a reader would."""
    return subprocess.run(["bash", "-euo", "pipefail", "-c", block.text], cwd=cwd, env=reader_environment(),
                          capture_output=True, text=True, timeout=timeout_s, stdin=subprocess.DEVNULL)


def _command_lines(text: str) -> Iterator[str]:
    """Shell lines of a block, continuations joined, here-documents and comments left out."""
    heredoc_end: str | None = None
    pending = ""
    for raw in text.splitlines():
        if heredoc_end is not None:
            if raw.strip() == heredoc_end:
                heredoc_end = None
            continue
        line = pending + raw
        if line.rstrip().endswith("\\"):
            pending = line.rstrip()[:-1] + " "
            continue
        pending = ""
        m = _HEREDOC.search(line)
        if m:
            heredoc_end = m.group(1)
        yield line


def bench_command_lines(path: str | os.PathLike[str]) -> list[tuple[int, list[str]]]:
    """Every ``bench …`` command in the page's shell blocks: (the block's line, argv after
    ``bench``). A prompt (``$ ``), environment assignments and a trailing comment are removed;
    the command ends at a pipe, ``;``, ``&&`` or ``||``."""
    found: list[tuple[int, list[str]]] = []
    for block in fenced_blocks(path):
        if block.info not in ("sh", "bash"):
            continue
        for line in _command_lines(block.text):
            try:
                words = shlex.split(line.strip().removeprefix("$ "), comments=True)
            except ValueError:
                continue
            while words and re.fullmatch(r"[A-Z_][A-Z0-9_]*=.*", words[0]):
                words = words[1:]
            if not words or Path(words[0]).name != "bench":
                continue
            argv: list[str] = []
            for word in words[1:]:
                if word in ("|", ";", "&&", "||"):
                    break
                argv.append(word)
            found.append((block.line, argv))
    return found


def relative_links(path: str | os.PathLike[str]) -> list[str]:
    """The page's links and images that point into the repository (no scheme, not an anchor)."""
    text = Path(path).read_text(encoding="utf-8")
    targets = [a or b for a, b in _LINK.findall(text)]
    return [t for t in targets if not re.match(r"[a-z][a-z0-9+.-]*:", t) and not t.startswith("#")]
