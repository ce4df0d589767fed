"""The command line starts at once: what ``bench --help`` and ``bench runs list`` import.

Not a timing (``benchmarks/bench_cli_startup.py`` measures the seconds): the property is that
the heavy libraries are not imported by a command that does not use them, checked in a fresh
interpreter's ``sys.modules``.
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from bench.app.cli import COMMANDS, build_parser, chosen_command, version

HEAVY = ("numpy", "scipy", "statsmodels", "matplotlib", "pandas", "numba", "sim", "procedures", "dask",
         "psycopg", "starlette", "pywt")


def modules_after(argv: list[str], tmp_path) -> set[str]:
    code = ("import sys, json\nfrom bench.app.cli import main\n"
            "try:\n    main(sys.argv[1:])\nexcept SystemExit:\n    pass\n"
            "print(json.dumps(sorted({m.split('.')[0] for m in sys.modules})))")
    done = subprocess.run([sys.executable, "-c", code, *argv], capture_output=True, text=True, cwd=tmp_path,
                          timeout=60)
    return set(json.loads(done.stdout.strip().splitlines()[-1]))


def test_help_and_version_import_no_command_and_no_heavy_library(tmp_path):
    for argv in (["--help"], ["--version"]):
        loaded = modules_after(argv, tmp_path)
        assert not loaded & set(HEAVY), f"bench {' '.join(argv)} imported {sorted(loaded & set(HEAVY))}"


def test_runs_list_imports_no_analysis_library(tmp_path):
    loaded = modules_after(["--store", str(tmp_path / "none.sqlite"), "runs", "list"], tmp_path)
    assert not loaded & {"scipy", "statsmodels", "matplotlib", "pandas", "numba", "sim", "procedures", "dask"}


def test_version_is_the_package_s(capsys):
    with pytest.raises(SystemExit) as stop:
        build_parser(["--version"]).parse_args(["--version"])
    assert stop.value.code == 0
    assert capsys.readouterr().out.strip() == f"bench {version()}"


def test_the_command_a_line_names_is_found_past_global_options():
    assert chosen_command(["--store", "runs", "runs", "list"]) == "runs"  # --store's value is not a command
    assert chosen_command(["--store", "x.sqlite", "acceptance", "--unit", "A"]) == "acceptance"
    assert chosen_command(["--help"]) is None
    assert chosen_command(["nosuch", "run"]) is None  # a typo is argparse's to name


def test_every_command_is_configured_by_its_module_and_listed_in_help():
    parser = build_parser()  # every command configured: each module's configure() runs
    text = parser.format_help()
    for name in COMMANDS:
        assert name in text
    sub = next(a for a in parser._actions if a.dest == "command")
    for name, p in sub.choices.items():
        assert p._actions[1:], f"bench {name} has no options: its module did not configure it"
