"""Overlapping Allan deviation on 10^7 samples, octave τ: ours beside allantools.oadev.

    .venv/bin/python benchmarks/bench_allan.py [--samples 10000000] [--rate-hz 100]
        [--repeats 3] [--seed 1] [--no-memory]

The record is a gyro-like rate in °/s: white noise (N = 0.01 °/√s) plus a random walk of
rate (K = 1e-4 °/s/√s), fixed seed.  Timed, interleaved so a busy machine slows both
alike, best of ``--repeats``:

* ours, ADEV only — ``allan_core.octave_sums`` (the numbers ``oadev`` returns);
* ours, whole analysis — ``overlapping_adev``: ADEV, Greenhall EDF and chi-squared
  intervals, the IEEE 952 fit and read-offs;
* allantools ``oadev(data, rate, data_type="freq", taus="octave")``.

Wall-clock and CPU (process) times are both reported: on a shared machine the CPU time
is the steadier figure.  The goal is ours ≥ 5× faster than allantools.  The two ADEV curves are compared (largest
relative difference), and peak memory above the input is measured with ``tracemalloc``
(numpy reports its buffers to it) in a separate run of each.
"""

from __future__ import annotations

import argparse
import time
import tracemalloc

import numpy as np

import bench.analysis.allan._core as allan_core
from bench.analysis.allan import overlapping_adev

GOAL_RATIO = 5.0


def make_record(n: int, rate_hz: float, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    white = 0.01 * np.sqrt(rate_hz) * rng.standard_normal(n)
    return white + np.cumsum(1e-4 / np.sqrt(rate_hz) * rng.standard_normal(n))


def ours_adev_only(y: np.ndarray, rate_hz: float) -> np.ndarray:
    levels = allan_core.octave_levels(y.size)
    m = 2.0 ** np.arange(levels)
    return np.sqrt(allan_core.octave_sums(y, levels) / (2 * (y.size + 1 - 2 * m) * m * m))


def peak_mib(fn) -> float:
    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1] / 2**20
    finally:
        tracemalloc.stop()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=10_000_000)
    parser.add_argument("--rate-hz", type=float, default=100.0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--no-memory", action="store_true", help="skip the tracemalloc runs")
    args = parser.parse_args()
    if args.samples < 1000 or args.repeats < 1 or args.rate_hz <= 0:
        parser.error("--samples must be >= 1000, --repeats >= 1, --rate-hz > 0")
    import allantools  # noqa: PLC0415 — the peer only when the benchmark runs

    y = make_record(args.samples, args.rate_hz, args.seed)
    print(f"record: {args.samples} samples at {args.rate_hz:g} Hz ({y.nbytes / 2**20:.0f} MiB), "
          f"white + random walk of rate, seed {args.seed}; octave τ")

    def theirs():
        return allantools.oadev(y, rate=args.rate_hz, data_type="freq", taus="octave")

    names = ("ours ADEV", "ours analysis", "allantools")
    wall = dict.fromkeys(names, np.inf)
    cpu = dict.fromkeys(names, np.inf)
    for _ in range(args.repeats):
        for name, fn in zip(names, (lambda: ours_adev_only(y, args.rate_hz),
                                    lambda: overlapping_adev(y, args.rate_hz, "octave"), theirs)):
            start, start_cpu = time.perf_counter(), time.process_time()
            out = fn()
            wall[name] = min(wall[name], time.perf_counter() - start)
            cpu[name] = min(cpu[name], time.process_time() - start_cpu)
            if name == "ours ADEV":
                ours_dev = out
            elif name == "allantools":
                ref_tau, ref_dev = out[0], out[1]
    result = overlapping_adev(y, args.rate_hz, "octave")
    assert np.allclose(result.tau_s, ref_tau, rtol=1e-12)
    diff = float(np.max(np.abs(ours_dev / ref_dev - 1.0)))
    print(f"\n{len(ref_tau)} τ from {ref_tau[0]:g} s to {ref_tau[-1]:g} s; largest relative ADEV difference "
          f"ours vs allantools: {diff:.1e}")
    print(f"\nbest of {args.repeats}:      wall (s)   CPU (s)")
    for name in names:
        print(f"  {name:<14} {wall[name]:9.3f} {cpu[name]:9.3f}")
    for label, t in (("wall", wall), ("CPU", cpu)):
        ratio = t["allantools"] / t["ours ADEV"]
        print(f"ratio allantools / ours, {label:<4}: {ratio:4.1f}x ADEV (goal >= {GOAL_RATIO:g}x: "
              f"{'met' if ratio >= GOAL_RATIO else 'NOT met'}), {t['allantools'] / t['ours analysis']:4.1f}x "
              "with the whole analysis")
    c = result.coefficients
    print(f"noise terms (fit): N = {c['N'].fit:.4g} {c['N'].unit} (true 0.6), K = {c['K'].fit:.4g} {c['K'].unit} "
          f"(true 21.6)")
    if not args.no_memory:
        print("\npeak memory above the input (tracemalloc):")
        print(f"  ours ADEV      {peak_mib(lambda: ours_adev_only(y, args.rate_hz)):8.0f} MiB")
        print(f"  ours analysis  {peak_mib(lambda: overlapping_adev(y, args.rate_hz, 'octave')):8.0f} MiB")
        print(f"  allantools     {peak_mib(theirs):8.0f} MiB")


if __name__ == "__main__":
    main()
