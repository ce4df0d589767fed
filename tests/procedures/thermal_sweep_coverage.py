"""Coverage of the thermal sweep end to end: drawn units through the simulated station.

    .venv/bin/python -m tests.procedures.thermal_sweep_coverage [--units 16] [--first 100]

For serials QA-SIM-<first> … each unit is the drawn one with its thermal terms kept linear
(no 2nd/3rd order, no hysteresis, gradient or slow drift — so the truth of its temperature
coefficients is its b₁ and s₁ exactly), swept −20…+50 °C at 5 set points with a 2-point
verification through the chamber's Modbus TCP and the instruments' SCPI. Printed: the
fraction of units whose bias TC and SF TC lie within 2σ (the step's stated uncertainty) of
the truth, and the compensated bias residual over its stated noise. Not a test (≈ 10 s of
wall per unit); its figures are quoted in docs/RESULTS.md.
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
from pathlib import Path

import numpy as np

from bench.app.station import Station, builtin_sim_config
from bench.core.procedure import execute
from bench.core.store import RunStore
from procedures.running import alone
from procedures.thermal_sweep import AccelerometerSweepParameters, ThermalSweep
from sim.physics.accelerometer import draw_accelerometer

LINEAR = {"drift_g_per_s": 0.0, "bias_tc2_g_per_c2": 0.0, "bias_tc3_g_per_c3": 0.0, "sf_tc2_ppm_per_c2": 0.0,
          "sf_tc3_ppm_per_c3": 0.0, "bias_hysteresis_g": 0.0, "bias_gradient_g_per_c": 0.0}
SWEEP = AccelerometerSweepParameters(low_c=-20.0, high_c=50.0, set_points=5, verify_points=2, ramp_c_per_min=3.0,
                                     soak_window_s=600.0, soak_poll_s=60.0, positions=12, settle_s=2.0,
                                     average_s=4.0, nplc=1.0)


def _stated(uncertainty: float | None) -> float:
    if uncertainty is None:
        raise ValueError("the step stated no uncertainty")
    return uncertainty


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--units", type=int, default=16)
    ap.add_argument("--first", type=int, default=100)
    args = ap.parse_args()
    z_bias, z_sf, ratio = [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        store = RunStore(Path(tmp) / "bench.sqlite")
        for k in range(args.first, args.first + args.units):
            serial = f"QA-SIM-{k:04d}"
            cfg = builtin_sim_config()
            cfg = dataclasses.replace(cfg, simulation={**(cfg.simulation or {}), "accelerometer": LINEAR})
            with Station(cfg, seed=k, unit_serial=serial, unit_kind="accelerometer") as station:
                outcome = execute(alone(ThermalSweep(SWEEP)), station, store, unit_serial=serial, seed=k)
            got = {m.name: m for m in outcome.measurements}
            truth = draw_accelerometer(serial)
            zb = (got["bias_tc"].value - truth.bias_tc_g_per_c) / _stated(got["bias_tc"].uncertainty)
            zs = (got["sf_tc"].value - truth.sf_tc_ppm_per_c) / _stated(got["sf_tc"].uncertainty)
            r = got["bias_residual"].value / _stated(got["bias_residual"].uncertainty)
            z_bias.append(zb)
            z_sf.append(zs)
            ratio.append(r)
            print(f"{serial}: {outcome.status}; bias TC z = {zb:+.2f}, SF TC z = {zs:+.2f}, "
                  f"bias residual / noise = {r:.2f}", flush=True)
        store.close()
    zb_, zs_ = np.abs(z_bias), np.abs(z_sf)
    print(f"{args.units} units: bias TC within 2σ {np.mean(zb_ <= 2):.0%} (rms z {np.sqrt(np.mean(zb_**2)):.2f}), "
          f"SF TC within 2σ {np.mean(zs_ <= 2):.0%} (rms z {np.sqrt(np.mean(zs_**2)):.2f}); compensated bias "
          f"residual over its stated noise: median {np.median(ratio):.2f}, max {np.max(ratio):.2f}")


if __name__ == "__main__":
    main()
