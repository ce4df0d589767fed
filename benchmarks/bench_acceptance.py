"""Wall time of the factory acceptance sequence on the simulated station, and its speed-up
over the real-time sequence it stands for.

    .venv/bin/python benchmarks/bench_acceptance.py [--units 3]

For each shipped spec (QA-2000 accelerometer: start-up, tumble, noise; tactical FOG: rate
table, noise) runs ``bench acceptance`` end to end — station start, every step through the
wire, the run store, the HTML report — for a few serials, and prints the wall time per unit,
the simulated time it covered (what the same sequence takes on a real station) and the
ratio. Goal: < 60 s wall per unit on 2 cores. There is no peer library that runs a station
sequence, so the reference is the real-time duration of the same sequence.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SERIALS = {"QA-SIM": "QA-SIM-{:04d}", "FOG-SIM": "FOG-SIM-{:04d}"}


def run(unit: str, tmp: Path) -> tuple[float, float, str]:
    t0 = time.perf_counter()
    out = subprocess.run([sys.executable, "-m", "bench.app.cli", "--store", str(tmp / "b.sqlite"),
                          "acceptance", "--unit", unit, "--seed", "1", "--json", "--no-progress",
                          "--report", str(tmp / "reports")], capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if out.returncode not in (0, 1):
        raise SystemExit(f"{unit}: exit {out.returncode}: {out.stderr.strip()}")
    doc = json.loads(out.stdout)
    show = subprocess.run([sys.executable, "-m", "bench.app.cli", "--store", str(tmp / "b.sqlite"),
                           "runs", "show", doc["run_id"], "--json"], capture_output=True, text=True)
    events = json.loads(show.stdout)["events"]
    times = [e[0] for e in events]  # (t_s, kind, message, data) rows
    simulated = max(times) - min(times)
    return wall, simulated, doc["verdict"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--units", type=int, default=3, help="serials per spec [3]")
    args = ap.parse_args()
    print(f"{'unit':<14} {'verdict':<16} {'wall (s)':>9} {'simulated (h)':>14} {'speed-up':>9}")
    worst = 0.0
    with tempfile.TemporaryDirectory() as tmp:
        for pattern in SERIALS.values():
            for i in range(1, args.units + 1):
                unit = pattern.format(i)
                wall, sim_s, verdict = run(unit, Path(tmp))
                worst = max(worst, wall)
                print(f"{unit:<14} {verdict:<16} {wall:>9.1f} {sim_s / 3600:>14.2f} {sim_s / wall:>8.0f}x",
                      flush=True)
    print(f"slowest unit: {worst:.1f} s wall (goal < 60 s): {'met' if worst < 60 else 'NOT met'}")


if __name__ == "__main__":
    main()
