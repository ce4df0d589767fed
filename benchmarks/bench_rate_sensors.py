"""Speed and accuracy of the closed-form rate-sensor responses (sim.physics.rate_sensor_lti)
against scipy.signal.lsim on a fine grid.

    .venv/bin/python benchmarks/bench_rate_sensors.py

Cases (goals from issue 5): (a) 10⁵ contiguous 0.5-ms frames of the LF sensor over a handful
of pieces (goal ≪ 100 ms); (b) the MHD sensor over a 100-s stepped sweep of 10⁴ pieces,
10⁵ 1-ms DMM windows (goal < ~1 s).  The peer is lsim (first-order hold) at 4 points per
window followed by trapezoidal window means — approximate where ours is exact, so its
maximum deviation from ours is printed too.
"""

from __future__ import annotations

import math
import time

import numpy as np
from scipy import signal

from sim.physics.angular_demand import Sweep
from sim.physics.angular_piece import MotionPiece, at_rest
from sim.physics.angular_table import AngularMotion
from sim.physics.rate_sensors import lf_sensor, mhd_sensor


def handful() -> list[MotionPiece]:
    freqs = [3.0, 17.0]
    pcs = [at_rest(-10.0, 0.0),
           MotionPiece(0.0, 5.0, np.array(freqs), np.zeros(2), np.array([0.1, 0.02]), np.array([0.0, 1.0]))]
    for t0, t1 in ((5.0, 30.0), (30.0, 40.0), (40.0, math.inf)):
        amp, ph, ang = pcs[-1].end_state()
        beta = np.zeros(2) if t1 != 40.0 else np.array([-0.05, -0.01])
        pcs.append(MotionPiece(t0, t1, np.array(freqs), amp, beta, ph, ang))
    return pcs


def sweep(n=10_000, duration_s=100.0) -> list[MotionPiece]:
    pcs, dt, amp, ph, ang = [at_rest(-10.0, 0.0)], duration_s / n, np.array([0.5]), np.array([0.0]), 0.0
    for i, f in enumerate(np.geomspace(0.5, 1000.0, n)):
        p = MotionPiece(i * dt, (i + 1) * dt, np.array([f]), amp, np.zeros(1), ph, ang)
        pcs.append(p)
        amp, ph, ang = p.end_state()
    pcs.append(MotionPiece(duration_s, math.inf, np.array([1000.0]), amp, np.zeros(1), ph, ang))
    return pcs


def table_sweep() -> list[MotionPiece]:
    """The angular table's own 100-s LOG sweep 0.5 Hz – 1 kHz (10-ms pieces, 2nd/3rd harmonics)."""
    table = AngularMotion()
    table.start_sweep(0.0, Sweep(0.5, 1000.0, 100.0, 0.01))
    return table.pieces(-1.0, 1e9)


def source(pcs):
    starts = np.array([p.t_start_s for p in pcs])

    def fn(t0, t1):
        i = max(0, int(np.searchsorted(starts, t0, side="right")) - 1)
        j = int(np.searchsorted(starts, t1, side="right"))
        return pcs[i:j]
    return fn


def ours(make, pcs, starts, d, contiguous, repeats=3) -> tuple[float, np.ndarray]:
    """Best time of ``repeats`` fresh sensors, and the (deterministic) window means."""
    def run() -> tuple[float, np.ndarray]:
        s = make(source(pcs), None, noise=False, t_origin_s=-1.0)
        t0 = time.perf_counter()
        out = s.mean_over_edges(np.append(starts, starts[-1] + d)) if contiguous else s.mean_output(starts, d)
        return time.perf_counter() - t0, out

    return min((run() for _ in range(repeats)), key=lambda timed: timed[0])


def peer(make, pcs, starts, d, per_window=4) -> tuple[float, np.ndarray]:
    s = make(source(pcs), None, noise=False, t_origin_s=-1.0)
    a, b, c, dd = s.state_space()
    t0 = time.perf_counter()
    grid = np.arange(-1.0, starts[-1] + d + d / per_window / 2, d / per_window)
    u = np.zeros(grid.size)
    for p in pcs:
        sel = (grid >= p.t_start_s) & (grid < p.t_end_s)
        if p.n and sel.any():
            u[sel] = p.rate_rad_s(grid[sel] - s.latency_s)
    _, y, _ = signal.lsim((a, b[:, None], c[None], np.array([[dd]])), u, grid - grid[0], interp=True)
    k0 = np.rint((starts + 1.0) / (d / per_window)).astype(int)
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (y[1:] + y[:-1]))]) * (d / per_window)
    mean = (cum[k0 + per_window] - cum[k0]) / d + s.bias
    return time.perf_counter() - t0, mean


def main() -> None:
    lf_sensor(source(handful()), None, noise=False).mean_output(np.arange(10) * 1e-3, 1e-3)  # numba warm-up
    cases = [("LF, 1e5 contiguous 0.5-ms frames (mean_over_edges), 5 pieces", lf_sensor, handful(),
              np.arange(100_000) * 5e-4, 5e-4, True),
             ("MHD, 100-s sweep of 1e4 pieces, 1e5 1-ms windows (mean_output)", mhd_sensor, sweep(),
              np.arange(100_000) * 1e-3, 1e-3, False),
             ("MHD, AngularMotion's 100-s sweep (3 components/piece), 1e5 1-ms windows (mean_output)", mhd_sensor,
              table_sweep(), np.arange(100_000) * 1e-3, 1e-3, False)]
    for name, make, pcs, starts, d, contiguous in cases:
        t_ours, y_ours = ours(make, pcs, starts, d, contiguous)
        t_peer, y_peer = peer(make, pcs, starts, d)
        print(f"{name}:\n  ours (exact) {t_ours * 1e3:8.1f} ms   scipy lsim (4 pts/window) {t_peer * 1e3:8.1f} ms"
              f"   ratio {t_peer / t_ours:6.1f}×   max |lsim − exact| {np.abs(y_peer - y_ours).max():.2e}"
              f" (output span {np.ptp(y_ours):.3g})")


if __name__ == "__main__":
    main()
