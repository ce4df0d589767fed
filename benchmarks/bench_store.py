"""Throughput of the run store: append N float64 samples in two columns in chunks, load them.

    .venv/bin/python benchmarks/bench_store.py [--samples 10000000] [--chunk 10000]
        [--synchronous FULL] [--dir /tmp]

Prints append and load throughput (samples/s, MB/s) and the database file size.  The design
target is a load of 10^7 samples x 2 columns well under a second.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from bench.core.store import RunStore


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=10_000_000, help="samples per column")
    parser.add_argument("--chunk", type=int, default=10_000, help="samples per append")
    parser.add_argument("--synchronous", default="FULL", choices=("NORMAL", "FULL"))
    parser.add_argument("--dir", default=None, help="folder for the temporary database")
    args = parser.parse_args()
    if args.samples < 1 or args.chunk < 1:
        parser.error("--samples and --chunk must be >= 1")

    rng = np.random.default_rng(0)
    voltage_v = rng.standard_normal(args.chunk)
    with tempfile.TemporaryDirectory(dir=args.dir) as tmp:
        path = Path(tmp) / "bench.sqlite"
        with RunStore(path, synchronous=args.synchronous) as store:
            writer = store.create_run(procedure="benchmark", parameters=vars(args), station={},
                                      unit_serial=None, seed=0, code_version="benchmark")
            writer.add_stream("dmm", {"t_s": "s", "voltage_v": "V"})
            n_chunks = -(-args.samples // args.chunk)
            start = time.perf_counter()
            for i in range(n_chunks):
                n = min(args.chunk, args.samples - i * args.chunk)
                t_s = (i * args.chunk + np.arange(n)) * 1e-3
                writer.append("dmm", t_s=t_s, voltage_v=voltage_v[:n])
            append_s = time.perf_counter() - start
            writer.finish("completed")

            start = time.perf_counter()
            data = store.load(writer.id, "dmm")
            load_s = time.perf_counter() - start
            assert len(data["t_s"]) == args.samples
            file_mb = sum(p.stat().st_size for p in Path(tmp).iterdir()) / 1e6

    mb = args.samples * 2 * 8 / 1e6
    print(f"samples: {args.samples} x 2 float64 columns in {n_chunks} chunks of {args.chunk} "
          f"(synchronous={args.synchronous}, {os.fspath(path.parent)})")
    print(f"append: {append_s:8.3f} s  {args.samples / append_s:12.3e} samples/s  "
          f"{mb / append_s:8.1f} MB/s  {n_chunks / append_s:8.0f} commits/s")
    print(f"load:   {load_s:8.3f} s  {args.samples / load_s:12.3e} samples/s  "
          f"{mb / load_s:8.1f} MB/s")
    print(f"file:   {file_mb:8.1f} MB (database + WAL) for {mb:.1f} MB of samples")


if __name__ == "__main__":
    main()
