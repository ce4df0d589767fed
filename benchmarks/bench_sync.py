"""Throughput of ``bench sync`` (station SQLite → central PostgreSQL) beside a plain ``COPY``.

    .venv/bin/python benchmarks/bench_sync.py [--runs 20] [--samples 500000]

Builds a station store of RUNS runs, each with one stream of SAMPLES rows (t_s, voltage_v:
float64) appended in chunks of 10 000 as a DMM trace arrives, starts a PostgreSQL server
(``scripts/pg``, in a temporary folder) and times, in samples per second:

1. ``sync``: the whole protocol — read each run from SQLite, digest it, one transaction per
   run (record, streams, chunks by ``COPY … FORMAT BINARY``, events, results, measurements),
   acknowledge it locally;
2. plain ``COPY`` of the same chunk bytes into a bare table (no digest, no metadata, one
   transaction): the floor of moving these bytes into PostgreSQL;
3. plain ``COPY`` of the samples as rows ``(run, t_s, voltage_v)`` (binary), the naive
   layout a generic database output would use.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path

import numpy as np
import psycopg

from bench.core.store import RunStore
from bench.core.store.forward import sync

ROOT = Path(__file__).resolve().parents[1]
CHUNK = 10_000


def build(path: Path, runs: int, samples: int) -> None:
    rng = np.random.default_rng(1)
    with RunStore(path, synchronous="NORMAL") as store:
        for i in range(runs):
            with store.create_run(procedure="startup", parameters={}, station={}, unit_serial=f"U{i}",
                                  seed=i, code_version="bench") as run:
                run.add_stream("dmm", {"t_s": "s", "voltage_v": "V"})
                for a in range(0, samples, CHUNK):
                    t = np.arange(a, min(a + CHUNK, samples)) * 1e-3
                    run.append("dmm", t_s=t, voltage_v=rng.standard_normal(t.size))
                run.finish("completed")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--samples", type=int, default=500_000, help="samples per run")
    args = ap.parse_args()
    total = args.runs * args.samples
    with tempfile.TemporaryDirectory() as tmp:
        parent = Path(tmp)
        parent.chmod(0o755)  # as root the server runs as postgres and must reach its folder
        url = subprocess.run([sys.executable, str(ROOT / "scripts" / "pg"), "start", "--dir",
                              str(parent / "pg"), "--port", "54391"], capture_output=True, text=True,
                             check=True).stdout.strip()
        try:
            store_path = parent / "station.sqlite"
            build(store_path, args.runs, args.samples)
            print(f"{args.runs} runs x {args.samples} samples = {total:,} samples "
                  f"({os.path.getsize(store_path) / 1e6:.0f} MB SQLite); load {os.getloadavg()[0]:.1f}")
            with RunStore(store_path) as store:
                report = sync(store, url)
                chunks = [row for run_id in store.finished_run_ids() for row in store.chunk_rows(run_id)]
                arrays = [store.load(run_id, "dmm") for run_id in store.finished_run_ids()]
            assert report.complete and report.samples == total
            sync_rate = total / report.seconds
            with psycopg.connect(url) as conn:
                conn.execute("CREATE TABLE bare_chunks (run_uuid uuid, stream text, seq int, n_rows int, "
                             "dtypes text, data bytea)")
                conn.execute("CREATE TABLE bare_rows (run_uuid uuid, t_s float8, voltage_v float8)")
                conn.commit()
                key = uuid.uuid4()
                t0 = time.perf_counter()
                with conn.cursor() as cur, cur.copy("COPY bare_chunks FROM STDIN (FORMAT BINARY)") as copy:
                    copy.set_types(["uuid", "text", "int4", "int4", "text", "bytea"])
                    for stream, seq, n, dtypes, data in chunks:
                        copy.write_row((key, stream, seq, n, dtypes, data))
                conn.commit()
                chunk_rate = total / (time.perf_counter() - t0)
                t0 = time.perf_counter()
                with conn.cursor() as cur, cur.copy("COPY bare_rows FROM STDIN (FORMAT BINARY)") as copy:
                    copy.set_types(["uuid", "float8", "float8"])
                    for cols in arrays:
                        for t, v in zip(cols["t_s"].tolist(), cols["voltage_v"].tolist()):
                            copy.write_row((key, t, v))
                conn.commit()
                row_rate = total / (time.perf_counter() - t0)
        finally:
            subprocess.run([sys.executable, str(ROOT / "scripts" / "pg"), "stop", "--dir",
                            str(parent / "pg")], check=False)
    print(f"bench sync (whole protocol):   {sync_rate:14,.0f} samples/s")
    print(f"plain COPY of the chunk bytes: {chunk_rate:14,.0f} samples/s  (sync / COPY = "
          f"{sync_rate / chunk_rate:.2f})")
    print(f"plain COPY of sample rows:     {row_rate:14,.0f} samples/s  (sync / row COPY = "
          f"{sync_rate / row_rate:.1f}x)")


if __name__ == "__main__":
    main()
