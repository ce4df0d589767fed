"""FOG model throughput: intervals per second of ``FiberOpticGyro.pulses`` at 2 kHz frames.

    .venv/bin/python benchmarks/bench_gyro.py [--intervals 4000000] [--batch 65536] [--repeats 3]

Ours: a tactical unit (every term on: ARW, 4 flicker terms, RRW, warm-up, thermal,
g-sensitivity, misalignment) fed in batches of ``--batch`` intervals (65536 = the
frame line's batch), without and with random vibration (6 g rms along the IA).
Goal: ≥ 2 M intervals/s.

Peer: there is no library FOG simulator to compare with; the design choice worth timing
is the slow-noise knot grid (``gyro_noise.KnotBias``). The peer figure is the same slow
terms drawn per interval with the project's own sequential processes
(``sim.physics.noise.GaussMarkov`` per flicker term + ``RandomWalk``), on the same times.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from sim.physics.gyro import TACTICAL, FiberOpticGyro, flicker_terms
from sim.physics.gyro_noise import KNOT_STEPS_PER_TAU, KnotBias
from sim.physics.noise import GaussMarkov, RandomWalk

FRAME_S = 5e-4
GOAL_PER_S = 2e6


def time_model(total: int, batch: int, vib: float, repeats: int) -> float:
    best = float("inf")
    omega = np.tile([5.0, 0.1, -0.2], (batch, 1))
    force = np.tile([0.0, 0.0, 1.0], (batch, 1))
    for r in range(repeats):
        gyro = FiberOpticGyro(TACTICAL, np.random.default_rng(r))
        gyro.set_supply(0.0, 12.0)
        t0 = time.perf_counter()
        for k in range(0, total, batch):
            edges = np.arange(k, k + batch + 1) * FRAME_S
            gyro.pulses(edges, omega, force, vib)
        best = min(best, time.perf_counter() - t0)
    return total / best


def time_slow_terms(total: int, batch: int, repeats: int) -> tuple[float, float]:
    sig, tau = flicker_terms(TACTICAL)
    q = TACTICAL.rrw_dps_per_rs
    ours = peer = float("inf")
    for r in range(repeats):
        knots = KnotBias(sig, tau, q, TACTICAL.flicker_tau_min_s / KNOT_STEPS_PER_TAU, np.random.default_rng(r))
        gms = [GaussMarkov(s, t, g) for s, t, g in zip(sig, tau, np.random.default_rng(r).spawn(len(sig)))]
        walk = RandomWalk(q, np.random.default_rng(r + 100))
        mids = [(np.arange(k, k + batch) + 0.5) * FRAME_S for k in range(0, total, batch)]
        t0 = time.perf_counter()
        for m in mids:
            knots.values(m)
        ours = min(ours, time.perf_counter() - t0)
        t0 = time.perf_counter()
        for m in mids:
            acc = walk.sample(m)
            for gm in gms:
                acc += gm.sample(m)
        peer = min(peer, time.perf_counter() - t0)
    return total / ours, total / peer


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--intervals", type=int, default=4_000_000)
    ap.add_argument("--batch", type=int, default=65536)
    ap.add_argument("--repeats", type=int, default=3)
    a = ap.parse_args()
    total = (a.intervals // a.batch) * a.batch
    quiet = time_model(total, a.batch, 0.0, a.repeats)
    shaken = time_model(total, a.batch, 6.0, a.repeats)
    print(f"FiberOpticGyro.pulses, {total} intervals in batches of {a.batch}:")
    print(f"  static:               {quiet / 1e6:6.2f} M intervals/s  (goal ≥ {GOAL_PER_S / 1e6:.0f} M/s)")
    print(f"  6 g rms vibration:    {shaken / 1e6:6.2f} M intervals/s")
    ours, peer = time_slow_terms(total, a.batch, a.repeats)
    print("slow noise (4 flicker Gauss-Markov terms + RRW) on the same times:")
    print(f"  ours (knot grid):     {ours / 1e6:6.2f} M intervals/s")
    print(f"  peer (per interval, sim.physics.noise): {peer / 1e6:6.2f} M intervals/s")
    print(f"  ratio ours/peer:      {ours / peer:6.1f}x")


if __name__ == "__main__":
    main()
