"""Speed of the simulated station, side by side with its references, in one run.

    .venv/bin/python benchmarks/bench_station.py [--duration-s 1800] [--points 100000]

1. Simulated-time speed-up of the 30-minute start-up acquisition (plus its 10-minute
   cool-down) over real time: the whole procedure — levelling, level check, cool-down,
   armed traces, streaming to the SQLite store — through pyvisa-py on loopback TCP.
   Goal ≥ 1000×.
2. Simulated-DMM trace throughput through pyvisa-py: a 10^5-point REAL,64 ``FETC?`` in
   readings/s, beside the real 34465A's 50 k readings/s ceiling.  Goal ≥ 5 M/s.
3. Query round trips per second for ``*IDN?``: our TCP simulator through pyvisa-py beside
   pyvisa-sim's in-process YAML simulator (the usual way to "simulate" an instrument).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import pyvisa
from pyvisa.resources import MessageBasedResource

from bench.app.station import Station, builtin_sim_config
from bench.core.procedure import execute
from bench.core.store import RunStore
from instruments.base import SCPIInstrument
from procedures.running import alone
from procedures.startup import StartupAcquisition, StartupParameters
from sim.station import SimStationConfig, SimulatedStation

REAL_34465A_READINGS_PER_S = 50_000.0
YAML = Path(__file__).resolve().parent.parent / "sim" / "visa_yaml" / "keysight_34465a.yaml"


def speedup(duration_s: float) -> None:
    params = StartupParameters(duration_s=duration_s)
    with tempfile.TemporaryDirectory() as tmp:
        store = RunStore(Path(tmp) / "bench.sqlite")
        t_wall = time.perf_counter()
        with Station(builtin_sim_config(), seed=1, unit_serial="QA-BENCH") as station:
            t_sim0 = station.clock.now()
            outcome = execute(alone(StartupAcquisition(params)), station, store,
                              unit_serial="QA-BENCH", seed=1)
            t_sim = station.clock.now() - t_sim0
        wall = time.perf_counter() - t_wall
        n = store.streams(outcome.run_id)["output"].n_rows
        store.close()
    print(f"start-up acquisition ({duration_s:.0f} s trace, {n} readings, status {outcome.status};"
          " wall time includes starting the station)")
    print(f"  whole procedure: simulated {t_sim:8.1f} s / wall {wall:6.3f} s = "
          f"{t_sim / wall:7.0f}x   (goal >= 1000x)")
    print(f"  the trace alone: simulated {duration_s:8.1f} s / wall {wall:6.3f} s = "
          f"{duration_s / wall:7.0f}x   (the cool-down wait costs ~nothing)")


def dmm_throughput(points: int, repeats: int = 5) -> None:
    with SimulatedStation(SimStationConfig(seed=2)) as station:
        rm = pyvisa.ResourceManager("@py")
        dmm = rm.open_resource(station.resources()["dmm"], read_termination="\n",
                               write_termination="\n", timeout=60000)
        assert isinstance(dmm, MessageBasedResource)  # a TCPIP socket: read and write by message
        dmm.chunk_size = 4 << 20
        dmm.write(f"CONF:VOLT:DC 10;:VOLT:NPLC 0.001;:VOLT:ZERO:AUTO OFF;:SAMP:SOUR TIM;"
                  f":SAMP:TIM 2E-5;:SAMP:COUN {points};:FORM REAL,64;:FORM:BORD SWAP")
        driver = SCPIInstrument(dmm, name="dmm")

        def best_rate(fetch) -> float:
            best = np.inf
            for _ in range(repeats):
                t = time.perf_counter()
                data = fetch()
                best = min(best, time.perf_counter() - t)
            assert data.size == points, data.size
            return points / best

        def acquire_and_fetch() -> np.ndarray:
            dmm.write("INIT")  # FETC? lets simulated time pass: every reading is simulated here
            return driver.query_real64("FETC?")

        end_to_end = best_rate(acquire_and_fetch)
        transfer = best_rate(lambda: driver.query_real64("FETC?"))
        naive = best_rate(lambda: dmm.query_binary_values("FETC?", datatype="d",
                                                          is_big_endian=False,
                                                          container=np.ndarray))
        err = dmm.query("SYST:ERR?").strip()
        dmm.close()
        rm.close()
    real = REAL_34465A_READINGS_PER_S
    print(f"simulated DMM, {points}-point REAL,64 trace through pyvisa-py ({err}); "
          f"the real 34465A digitizes at most {real / 1e3:.0f} k readings/s")
    print(f"  INIT + FETC? (physics simulated) {end_to_end / 1e6:7.2f} M readings/s  "
          f"{end_to_end / real:7.1f}x the real meter   (goal >= 5 M/s)")
    print(f"  FETC? of the stored trace         {transfer / 1e6:7.2f} M readings/s  "
          f"{transfer / real:7.1f}x the real meter")
    print(f"  plain pyvisa query_binary_values  {naive / 1e6:7.2f} M readings/s  "
          f"(the bench driver's block read is {transfer / naive:.1f}x faster)")


def query_rate(n: int = 2000) -> None:
    def rate_of(resource) -> float:
        t = time.perf_counter()
        for _ in range(n):
            resource.query("*IDN?")
        return n / (time.perf_counter() - t)

    with SimulatedStation(SimStationConfig(seed=3)) as station:
        rm = pyvisa.ResourceManager("@py")
        ours = rm.open_resource(station.resources()["dmm"], read_termination="\n",
                                write_termination="\n")
        r_ours = rate_of(ours)
        ours.close()
        rm.close()
    rm_sim = pyvisa.ResourceManager(f"{YAML}@sim")
    peer = rm_sim.open_resource("TCPIP0::127.0.0.1::5025::SOCKET", read_termination="\n",
                                write_termination="\n")
    r_peer = rate_of(peer)
    peer.close()
    print(f"*IDN? round trips: ours (TCP + SCPI engine) {r_ours:8.0f}/s   "
          f"pyvisa-sim (in-process YAML) {r_peer:8.0f}/s   ratio {r_ours / r_peer:6.2f}x")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration-s", type=float, default=1800.0)
    parser.add_argument("--points", type=int, default=100_000)
    args = parser.parse_args()
    speedup(args.duration_s)
    dmm_throughput(args.points)
    query_rate()


if __name__ == "__main__":
    main()
