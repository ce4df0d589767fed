"""Batch acceptance on the fixture: four units at once against one unit alone.

The built-in QA-2000 spec (turn-on 30 min, 24-position tumble, 1 h static record) on the
simulated station, seed 1.  Three figures per case:

* station time — the simulated (virtual-clock) time from the first to the last event of the
  run: what the procedure takes on a real station;
* compute wall time of the run (simulation + procedure + store), reports excluded;
* wall time of the HTML reports (one per unit): for the batch, from its units' end to its
  return (``run_batch`` writes them in worker processes, ``bench.app.reports.parallel``).

The single unit is run as ``bench acceptance`` runs it: the station opened, the procedure,
then its report in-process.

Usage: ``python benchmarks/bench_batch.py [--sockets N]``.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from bench.app.batch import run_batch, spec_for_sockets
from bench.app.reports.acceptance_report import write_acceptance_report
from bench.app.reports.parallel import report_workers
from bench.app.station import Station, builtin_sim_config
from bench.core.procedure import execute
from bench.core.store import RunStore
from procedures.acceptance import AcceptanceTest


def station_time_s(store: RunStore, run_id: str) -> float:
    t = [e.t_s for e in store.events(run_id)]
    return max(t) - min(t)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sockets", type=int, default=4)
    args = parser.parse_args()
    sockets = {n: f"QA-SIM-{n:04d}" for n in range(1, args.sockets + 1)}
    spec = spec_for_sockets(sockets)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        store = RunStore(folder / "bench.sqlite")
        t0 = time.perf_counter()
        with Station(builtin_sim_config(), seed=1, unit_serial=sockets[1]) as station:
            single = execute(AcceptanceTest(spec), station, store, unit_serial=sockets[1], seed=1)
        single_run_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        write_acceptance_report(store, single.run_id, folder / "r" / single.run_id)
        single_report_s = time.perf_counter() - t0
        single_station_s = station_time_s(store, single.run_id)

        ended: list[float] = []  # when the batch's units ended: the rest is reports + close

        def progress(done: float, total: float, message: str = "") -> None:
            if message == "done":
                ended.append(time.perf_counter())
        t0 = time.perf_counter()
        batch = run_batch(builtin_sim_config(), sockets, spec, store, seed=1, report_root=folder / "r",
                          labels={"station_id": "bench"}, progress=progress)
        batch_total_s = time.perf_counter() - t0
        batch_run_s = ended[-1] - t0
        batch_report_s = batch_total_s - batch_run_s
        batch_station_s = max(station_time_s(store, d["run_id"]) for d in batch.documents.values())

    n = len(sockets)
    print(f"{'':28}{'1 unit':>12}{f'{n} units':>12}{'ratio':>8}")
    for label, one, many in (("station (simulated) time, h", single_station_s / 3600, batch_station_s / 3600),
                             ("run wall time, s", single_run_s, batch_run_s),
                             ("reports (+ close) wall time, s", single_report_s, batch_report_s),
                             ("run + reports wall time, s", single_run_s + single_report_s,
                              batch_run_s + batch_report_s)):
        print(f"{label:28}{one:12.2f}{many:12.2f}{many / one:8.2f}")
    print(f"reports of the batch written by {report_workers(n) or 'this'} process(es)")
    print(f"verdicts: 1 unit {single.status}; batch "
          + ", ".join(f"{k}={d['status']}" for k, d in batch.documents.items()))
    print(f"station time per unit: {single_station_s / 3600:.2f} h alone, "
          f"{batch_station_s / 3600 / n:.2f} h in a batch of {n}")


if __name__ == "__main__":
    main()
