"""The documentation holds: the site builds strictly, the README and the tutorial's runnable
commands run as shown, every ``bench`` command the pages show parses, links resolve, and the
user-facing pages carry no development history.

Runnable blocks are marked ``<!-- runnable -->`` on the line before their fence
(``bench.testing.docs``).
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from bench.app.cli import build_parser
from bench.app.station import parse_station
from bench.testing.docs import bench_command_lines, fenced_blocks, relative_links, run_block, runnable_blocks

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
README = ROOT / "README.md"
PAGES = [README, *sorted(DOCS.rglob("*.md"))]
HISTORY = re.compile(r"\bstop \d+\b|\bthis stop\b|\bissue #?\d+\b|\bstops \d+", re.IGNORECASE)


def _name(path: Path) -> str:
    return str(path.relative_to(ROOT))


def test_the_site_builds_strictly(tmp_path):
    """`mkdocs build --strict`: a broken link, anchor or nav entry fails (make docs does the same)."""
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    done = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=110)
    assert done.returncode == 0, done.stderr[-3000:]
    cli = (tmp_path / "site" / "reference" / "cli" / "index.html").read_text(encoding="utf-8")
    assert "bench acceptance" in cli and "bench discover" in cli  # generated from the parsers


def test_the_readme_is_a_short_front_door():
    lines = README.read_text(encoding="utf-8").splitlines()
    assert len(lines) <= 250, f"README.md has {len(lines)} lines; the front door stays ≤ 250"
    text = "\n".join(lines)
    assert "## Run acceptance on a real unit" in text and "](#run-acceptance-on-a-real-unit)" in text


@pytest.mark.parametrize("page", PAGES, ids=_name)
def test_user_pages_carry_no_development_history(page):
    hits = [(n, line.strip()) for n, line in enumerate(page.read_text(encoding="utf-8").splitlines(), 1)
            if HISTORY.search(line)]
    assert not hits, f"{_name(page)}: history belongs in CHANGELOG.md: {hits}"


def test_every_api_package_has_its_reference_page():
    """docs/API.md's packages each have a page rendered from their docstrings (mkdocstrings)."""
    listed = {line.strip()[len("## `"):-1] for line in (DOCS / "API.md").read_text(encoding="utf-8").splitlines()
              if line.startswith("## `")}
    pages = {p.stem: p.read_text(encoding="utf-8") for p in (DOCS / "reference" / "api").glob("*.md")}
    assert set(pages) == listed
    assert all(f"::: {name}\n" in text for name, text in pages.items())


def test_the_readme_links_resolve():
    missing = [t for t in relative_links(README) if not (ROOT / t.split("#")[0]).exists()]
    assert not missing, f"README.md links to files that do not exist: {missing}"


@pytest.mark.parametrize("page", PAGES, ids=_name)
def test_every_bench_command_shown_parses(page):
    """Each `bench …` line in a shell block is accepted by the current CLI's parser."""
    wrong = []
    for line, argv in bench_command_lines(page):
        try:
            build_parser(argv).parse_args(argv)
        except SystemExit as exc:
            if exc.code not in (0, None):  # --help exits 0
                wrong.append((line, " ".join(argv)))
    assert not wrong, f"{_name(page)}: commands the CLI refuses (block line, command): {wrong}"


@pytest.mark.parametrize("page", [README, DOCS / "tutorial.md", DOCS / "howto" / "real-instruments.md"], ids=_name)
def test_the_station_files_shown_are_valid_stations(page):
    stations = [b for b in fenced_blocks(page) if b.info == "toml" and b.text.lstrip().startswith("[station]")]
    assert stations, f"{_name(page)} shows no station file"
    for block in stations:
        config = parse_station(tomllib.loads(block.text), f"{_name(page)}:{block.line}")
        assert not config.simulated and config.instruments


def _run_page(page: Path, folder: Path) -> None:
    blocks = runnable_blocks(page)
    assert blocks, f"{_name(page)} marks no block runnable"
    for block in blocks:
        done = run_block(block, folder)
        assert done.returncode == 0, (f"{_name(page)}, block at line {block.line} exited {done.returncode}:\n"
                                      f"{block.text}\n--- stdout\n{done.stdout[-2000:]}\n"
                                      f"--- stderr\n{done.stderr[-2000:]}")


def test_the_readme_runnable_commands_run(tmp_path):
    _run_page(README, tmp_path)
    assert list((tmp_path / "bench-data" / "reports").glob("*/acceptance_report.html"))


def test_the_tutorial_runnable_commands_run(tmp_path):
    """The tutorial's simulated path, in order, in one folder: run, own spec, stored run, Python."""
    _run_page(DOCS / "tutorial.md", tmp_path)
    assert (tmp_path / "my-unit.toml").exists() and list((tmp_path / "export-tutorial").glob("*.csv"))
