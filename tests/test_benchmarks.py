"""Every benchmark script still imports (and runs nothing on import): a benchmark nobody runs
in CI must not rot unseen — the discovery scorecard once imported a module the simulator had
dropped, and could not start.

Each script is imported in a fresh interpreter started in the benchmarks folder, where running
it finds its neighbours; the tests never import a benchmark themselves. What both share is in
``bench.testing``.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


@pytest.mark.parametrize("script", sorted(p.stem for p in BENCHMARKS.glob("*.py")))
def test_a_benchmark_script_imports_without_running(script):
    # were it to run, it would print its help and exit
    code = f"import sys; sys.argv = [{script!r}, '--help']; import {script}"
    done = subprocess.run([sys.executable, "-c", code], cwd=BENCHMARKS, capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout == ""  # nothing printed: nothing ran
