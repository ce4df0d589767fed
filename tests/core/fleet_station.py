"""One station of the fleet test, as its own process: writes RUNS runs to its own SQLite
store and forwards after each (one attempt, as ``bench`` does with BENCH_CENTRAL set), then
forwards what is left, retrying while the server is down.  Prints its report as JSON.

    python -m tests.core.fleet_station STORE URL STATION_ID RUNS
"""

from __future__ import annotations

import json
import sys

import numpy as np

from bench.core.store import RunStore
from bench.core.store.forward import sync


def main() -> None:
    path, url, station_id, runs = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
    rng = np.random.default_rng(abs(hash(station_id)) % 2**32)
    acknowledged = 0
    with RunStore(path, synchronous="NORMAL") as store:
        for i in range(runs):
            with store.create_run(procedure="acceptance", parameters={"i": i}, station={},
                                  unit_serial=f"{station_id}-U{i:03d}", seed=i, code_version="t",
                                  labels={"station_id": station_id, "lot": f"L{i % 3}"}) as run:
                run.add_stream("dmm", {"t_s": "s", "voltage_v": "V"})
                for k in range(4):  # 4 chunks of 2500 samples: 160 kB a run
                    t = np.arange(k * 2500, (k + 1) * 2500) * 1e-3
                    run.append("dmm", t_s=t, voltage_v=rng.standard_normal(2500))
                run.set_result("measurement.k0", {"name": "k0", "value": float(rng.normal()),
                                                  "unit": "mg", "low": -4.0, "high": 4.0,
                                                  "marginal": 0.4, "outcome": "pass",
                                                  "uncertainty": 0.1})
                run.finish("passed")
            acknowledged += len(sync(store, url, connect_timeout_s=2).stored)
        final = sync(store, url, retry_for_s=120, connect_timeout_s=2)
        print(json.dumps({"station": station_id, "after_each": acknowledged,
                          "final": final.to_dict(), "runs": store.finished_run_ids()}))


if __name__ == "__main__":
    main()
