"""Wall time of ``bench risk`` with 1 and with 2 Dask workers (a LocalCluster of processes),
the speed-up, and whether the verdicts agree unit for unit.

    .venv/bin/python benchmarks/bench_risk.py [--units 100] [--spec bench/specs/qa2000-sim.toml]

Goal (issue 17): 100 units in <= 8 min on 2 cores, >= 1.8x faster with 2 workers than 1. The
machine's load average is printed before and after: the figure means little on a busy machine.
There is no peer library that computes a test's decision risk; the reference is one worker.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def run(spec: str, units: int, workers: int, store: Path) -> tuple[float, dict]:
    t0 = time.perf_counter()
    out = subprocess.run([sys.executable, "-m", "bench.app.cli", "--store", str(store), "risk",
                          "--spec", spec, "--units", str(units), "--workers", str(workers),
                          "--seed", "1", "--json", "--no-progress"],
                         capture_output=True, text=True, cwd=ROOT)
    wall = time.perf_counter() - t0
    if out.returncode != 0:
        raise SystemExit(f"bench risk --workers {workers}: exit {out.returncode}: {out.stderr.strip()}")
    return wall, json.loads(out.stdout)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--units", type=int, default=100)
    ap.add_argument("--spec", default=str(ROOT / "bench" / "specs" / "qa2000-sim.toml"))
    ap.add_argument("--save", default=None, metavar="FILE", help="keep the 2-worker report (JSON)")
    args = ap.parse_args()
    print(f"load average before: {os.getloadavg()}, cores: {os.cpu_count()}", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        wall2, doc2 = run(args.spec, args.units, 2, Path(tmp) / "w2.sqlite")
        if args.save:
            Path(args.save).write_text(json.dumps(doc2, indent=1))
        print(f"2 workers: {wall2:7.1f} s for {args.units} units ({wall2 / args.units:.2f} s/unit)",
              flush=True)
        wall1, doc1 = run(args.spec, args.units, 1, Path(tmp) / "w1.sqlite")
        print(f"1 worker:  {wall1:7.1f} s for {args.units} units ({wall1 / args.units:.2f} s/unit)",
              flush=True)
    print(f"load average after: {os.getloadavg()}")
    verdicts1, verdicts2 = doc1["verdicts"], doc2["verdicts"]
    same = [u["measurements"] for u in doc1["units_detail"]] == [u["measurements"] for u in doc2["units_detail"]]
    print(f"speed-up 1 -> 2 workers: {wall1 / wall2:.2f}x (goal >= 1.8x); 2 workers "
          f"{'within' if wall2 <= 480 else 'OVER'} 8 min; verdicts identical: {verdicts1 == verdicts2}, "
          f"measured values identical: {same} "
          f"(yield {verdicts2.count('passed')}/{len(verdicts2)})")


if __name__ == "__main__":
    main()
