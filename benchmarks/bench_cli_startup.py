"""How long a command line pays before it does anything: imports of ``bench`` beside its peers.

    .venv/bin/python benchmarks/bench_cli_startup.py [--repeats 5] [--json]

Each case runs in a fresh interpreter under ``python -X importtime``; the figure is the sum of
the top-level imports' cumulative times (what the interpreter spent importing, start-up of
the interpreter itself excluded), the median of ``--repeats`` runs, beside the wall time of
the whole process. The peers are what a user of PyMeasure or QCoDeS pays for their first
line (``import pymeasure.instruments``, ``import qcodes``), and the interpreter's own floor.

The goal: ``bench --help`` and ``bench runs list`` ≤ 0.5 s of imports.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

GOAL_S = 0.5

#: name -> the Python code a case runs (the ``bench`` cases run the CLI's own main)
CASES = {
    "bench --help": "import sys; from bench.app.cli import main; sys.argv[1:] = ['--help']; main()",
    "bench --version": "import sys; from bench.app.cli import main; sys.argv[1:] = ['--version']; main()",
    "bench runs list": "import sys; from bench.app.cli import main; sys.exit(main(['--store', {store!r}, 'runs', "
                       "'list']))",
    "import bench.analysis.allan": "import bench.analysis.allan",
    "peer: import pymeasure.instruments": "import pymeasure.instruments",
    "peer: import qcodes": "import qcodes",
    "floor: python -c pass": "pass",
}
_LINE = re.compile(r"import time:\s+(\d+)\s+\|\s+(\d+)\s+\|(\s*)(\S+)")


def import_seconds(stderr: str) -> float:
    """Sum of the cumulative times of the top-level imports (the least indented lines)."""
    rows = [(len(m.group(3)), int(m.group(2))) for m in map(_LINE.match, stderr.splitlines()) if m]
    if not rows:
        return 0.0
    top = min(indent for indent, _ in rows)
    return sum(us for indent, us in rows if indent == top) / 1e6


def run_case(code: str) -> tuple[float, float]:
    started = time.perf_counter()
    done = subprocess.run([sys.executable, "-X", "importtime", "-c", code], capture_output=True, text=True,
                          env={**os.environ, "BENCH_STORE": ""}, check=False)
    wall = time.perf_counter() - started
    if done.returncode not in (0, 2):  # 2: `runs list` on an empty store says so and exits 2
        raise RuntimeError(f"{code!r} failed: {done.stderr.strip().splitlines()[-1:]}")
    return import_seconds(done.stderr), wall


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--json", action="store_true", help="print the figures as JSON")
    args = parser.parse_args()
    if args.repeats < 1:
        parser.error(f"--repeats {args.repeats} must be >= 1")
    store = str(Path(tempfile.mkdtemp()) / "empty.sqlite")
    results = {}
    for name, code in CASES.items():
        samples = []
        for _ in range(args.repeats):
            try:
                samples.append(run_case(code.format(store=store)))
            except RuntimeError as exc:  # a peer that is not installed: say so, go on
                print(f"{name}: skipped ({exc})", file=sys.stderr)
                break
        if samples:
            results[name] = {"imports_s": statistics.median(s[0] for s in samples),
                             "wall_s": statistics.median(s[1] for s in samples)}
        print(f"  {name}: done", file=sys.stderr)
    load = os.getloadavg()[0]
    if args.json:
        print(json.dumps({"load_1min": load, "cores": os.cpu_count(), "results": results}, indent=2))
    else:
        floor = results.get("floor: python -c pass", {}).get("wall_s", 0.0)
        print(f"median of {args.repeats}; machine: {os.cpu_count()} cores, load {load:.2f} (1 min)")
        print(f"  {'case':<38} {'imports s':>10} {'wall s':>8} {'× help':>7}")
        base = results.get("bench --help", {}).get("imports_s") or float("nan")
        for name, r in results.items():
            print(f"  {name:<38} {r['imports_s']:>10.3f} {r['wall_s']:>8.3f} {r['imports_s'] / base:>7.1f}")
        print(f"  (the interpreter alone: {floor:.3f} s wall)")
    ok = all(results[n]["imports_s"] <= GOAL_S for n in ("bench --help", "bench runs list") if n in results)
    print(f"goal: bench --help and bench runs list <= {GOAL_S} s of imports: {'met' if ok else 'NOT met'}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
