"""Speed of the thermal simulation: 20 hours of chamber profile, both units powered.

    .venv/bin/python benchmarks/bench_thermal.py [--hours 20] [--skip-wire] [--calibration]

The profile is a thermal calibration's: seven set points −40 … +70 °C, a 2 °C/min ramp to
each, a soak, then back to the lab (≈ 20 h of chamber time, which a real chamber also takes).

1. The physics alone: the chamber air, the accelerometer's and the FOG's two-node models with
   hysteresis, polynomials and self-heating, read every 5 min of simulated time (1 s of
   accelerometer readings at 100 readings/s, 1 s of FOG frames at 1 kHz, both sensors'
   temperatures); then the thermal cascade alone (air loop + two units, 6 states) evaluated
   at the same instants, beside scipy's DOP853 integrating it — the stepping the closed form
   replaces.
2. Through the wire: the built-in simulated station, the chamber driven over Modbus TCP
   (``WatlowF4TChamber``), the units powered from the supply (SCPI), every 10 min the
   accelerometer's temperature read by ``dmm_temp`` and the chamber's status, every hour
   2 s of gyro frames.
3. ``--calibration``: the thermal acceptance of each unit (``bench acceptance --spec
   bench/specs/qa2000-thermal.toml`` and ``fog-tactical-thermal.toml``, in-process: sweep,
   compensation file and verification, ramps, turn-on repeatability), its wall time beside
   the chamber time it simulates — the time a real chamber takes for the same profile.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

from bench.app.station import Station, builtin_sim_config
from bench.core.procedure import execute
from bench.core.spec import load_spec
from bench.core.store import RunStore
from procedures.acceptance import AcceptanceTest
from procedures.catalogue import CATALOGUE
from sim.physics.accelerometer import QuartzAccelerometer, draw_accelerometer
from sim.physics.gyro import FiberOpticGyro, draw_gyro
from sim.physics.thermal_chamber import ChamberAir
from sim.physics.thermal_unit import TwoNodeBody
from sim.world import World

SET_POINTS_C = (-40.0, -20.0, 0.0, 23.0, 40.0, 55.0, 70.0)
RAMP_C_PER_MIN = 2.0
RTOL = 1e-9


def profile(hours: float) -> list[tuple[float, float]]:
    """(set point, hold s) so that the ramps and soaks fill ``hours``."""
    ramps_min = sum(abs(b - a) for a, b in zip((23.0, *SET_POINTS_C), (*SET_POINTS_C, 23.0))) / RAMP_C_PER_MIN
    soak_s = max(600.0, (hours * 3600.0 - ramps_min * 60.0) / (len(SET_POINTS_C) + 1))
    out, last = [], 23.0
    for sp in (*SET_POINTS_C, 23.0):
        out.append((sp, abs(sp - last) / RAMP_C_PER_MIN * 60.0 + soak_s))
        last = sp
    return out


def physics(hours: float) -> None:
    world = World(1)
    air = ChamberAir(world)
    acc = QuartzAccelerometer(draw_accelerometer("QA-SIM-0005"), world.rng("acc"), ambient=air)
    fog = FiberOpticGyro(draw_gyro("FOG-SIM-0005"), world.rng("fog"), ambient=air)
    acc.set_supply(0.0, 15.0, -15.0)
    fog.set_supply(0.0, 12.0)
    steps = profile(hours)
    t_read = np.arange(0.0, sum(h for _, h in steps), 300.0)
    readings = frames = 0
    f_acc = np.tile([1.0, 0.0, 0.0], (100, 1))
    t0 = time.perf_counter()
    k = 0
    for sp, hold in steps:
        air.command(True, sp, RAMP_C_PER_MIN)
        end = world.now + hold
        while k < t_read.size and t_read[k] < end:
            world.advance_to(max(world.now, t_read[k]))
            ts = world.now + np.arange(100) * 0.01
            acc.output_current_a(ts, f_acc, 0.01)
            acc.temperature_c(ts[:1])
            edges = world.now + np.arange(1001) * 1e-3
            fog.pulses(edges, np.zeros((1000, 3)), np.tile([1.0, 0.0, 0.0], (1000, 1)))
            fog.temperature_c(edges[-1])
            readings += 100
            frames += 1000
            k += 1
        world.advance_to(end)
    wall = time.perf_counter() - t0
    sim_s = world.now
    print(f"physics: {sim_s / 3600:.1f} h simulated ({len(steps)} set points, {k} reads: {readings} "
          f"accelerometer readings, {frames} FOG frames) in {wall:.3f} s wall = {sim_s / wall:,.0f}x real time")

    # the peer: DOP853 on the same cascade (air loop + the two units' nodes) to the same instants
    pa, pg, pc = acc.params.thermal_nodes(), fog.params.thermal_nodes(), air.params
    ba, bg = pa.block(), pg.block()
    w, z = pc.omega_rad_s, pc.loop_damping
    qa, qg = pa.heating_c_per_s, pg.heating_c_per_s
    x = np.array([23.0, 0.0, *acc.body.nodes_c([0.0])[0], *fog.body.nodes_c([0.0])[0]])
    t1 = time.perf_counter()
    t_start, last, worst = 0.0, 23.0, 0.0
    for sp, hold in steps:
        duration = abs(sp - last) / RAMP_C_PER_MIN * 60.0
        slope = np.sign(sp - last) * RAMP_C_PER_MIN / 60.0

        def demand(t, ts=t_start, r0=last, s=slope, d=duration, target=sp):
            return r0 + s * min(t - ts, d) if d > 0 else target

        def f(t, y, demand=demand):
            dv = w * w * (demand(t) - y[0]) - 2 * z * w * y[1]
            return [y[1], dv, *(ba.a @ y[2:4] + ba.b @ [y[0], qa]), *(bg.a @ y[4:6] + bg.b @ [y[0], qg])]
        seg_t = t_read[(t_read >= t_start) & (t_read < t_start + hold)]
        bounds = [t_start, t_start + duration, t_start + hold] if duration > 0 else [t_start, t_start + hold]
        for a, b in zip(bounds[:-1], bounds[1:]):
            pick = seg_t[(seg_t >= a) & (seg_t < b)]
            sol = solve_ivp(f, (a, b), x, method="DOP853", rtol=RTOL, atol=RTOL, t_eval=np.append(pick, b))
            if pick.size:
                worst = max(worst, float(np.abs(sol.y[3, :-1] - acc.body.element_c(pick)).max()))
            x = sol.y[:, -1]
        t_start += hold
        last = sp
    peer = time.perf_counter() - t1

    # ours, the same thermal cascade alone (air + both units' nodes) at the same instants
    t2 = time.perf_counter()
    world2 = World(1)
    air2 = ChamberAir(world2)
    bodies = [TwoNodeBody(pa, air2), TwoNodeBody(pg, air2)]
    for body in bodies:
        body.set_power(0.0, True)
    k = 0
    for sp, hold in steps:
        air2.command(True, sp, RAMP_C_PER_MIN)
        end = world2.now + hold
        while k < t_read.size and t_read[k] < end:
            world2.advance_to(max(world2.now, t_read[k]))
            for body in bodies:
                body.nodes_c([world2.now])
            k += 1
        world2.advance_to(end)
    ours = time.perf_counter() - t2
    print(f"  the thermal cascade alone (air loop + 2 units × 2 nodes, {t_read.size} instants): ours "
          f"{ours * 1e3:.1f} ms, scipy DOP853 (rtol {RTOL:g}) {peer * 1e3:.0f} ms = {peer / ours:.0f}x; "
          f"DOP853 differs from the closed form by up to {worst:.1e} °C (the closed form agrees with the "
          f"matrix exponential to 1e-10, tests/sim/test_thermal_physics.py)")


def wire(hours: float) -> None:
    steps = profile(hours)
    t0 = time.perf_counter()
    with Station(builtin_sim_config(), seed=1, unit_serial="QA-SIM-0005") as st:
        start = time.perf_counter()
        clock, chamber = st.clock, st.instruments["chamber"]
        supply, dmm_t, gyro = st.instruments["supply"], st.instruments["dmm_temp"], st.instruments["gyro"]
        for ch in (2, 3):
            supply.ch[ch].apply(15.0, 0.1)
        supply.ch[1].apply(5.0, 1.0)
        supply.set_outputs([1, 2, 3], True)
        chamber.set_ramp(RAMP_C_PER_MIN)
        chamber.run()
        reads = frames = 0
        t_sim0 = clock.now()
        for sp, hold in steps:
            chamber.set_set_point(sp)
            end = clock.now() + hold
            while clock.now() < end:
                clock.sleep(min(600.0, end - clock.now()))
                dmm_t.measure_dc_voltage()
                chamber.check()
                reads += 1
                if reads % 6 == 0:
                    gyro.start()
                    frames += len(gyro.read_frames(2000, wait=clock.sleep))
                    gyro.stop()
        chamber.make_safe()
        supply.outputs_off()
        sim_s = clock.now() - t_sim0
        wall = time.perf_counter() - start
    total = time.perf_counter() - t0
    print(f"through the wire: {sim_s / 3600:.1f} h of chamber profile, {reads} temperature reads + chamber "
          f"status over Modbus TCP, {frames} gyro frames: {wall:.2f} s wall ({total:.2f} s with the station's "
          f"start) = {sim_s / wall:,.0f}x real time (a real chamber takes the {sim_s / 3600:.1f} h)")


def calibration() -> None:
    root = Path(__file__).resolve().parents[1] / "bench" / "specs"
    with tempfile.TemporaryDirectory() as tmp:
        store = RunStore(Path(tmp) / "bench.sqlite")
        runs = (("qa2000-thermal.toml", "QA-SIM-0005"), ("fog-tactical-thermal.toml", "FOG-SIM-0005"))
        for spec_file, serial in runs:
            spec = load_spec(root / spec_file, CATALOGUE)
            t0 = time.perf_counter()
            with Station(builtin_sim_config(), seed=1, unit_serial=serial, unit_kind=spec.kind) as st:
                start = time.perf_counter()
                outcome = execute(AcceptanceTest(spec), st, store, unit_serial=serial, seed=1)
                wall = time.perf_counter() - start
                sim_s = st.clock.now()
            total = time.perf_counter() - t0
            temps = store.load(outcome.run_id, "thermal_points")["set_point_c"].size
            print(f"thermal acceptance {spec_file} ({serial}): {outcome.status}, {temps} temperatures, "
                  f"{sim_s / 3600:.1f} h of chamber time in {wall:.1f} s wall ({total:.1f} s with the station's "
                  f"start) = {sim_s / wall:,.0f}x real time (a real chamber: the {sim_s / 3600:.1f} h)")
        store.close()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, default=20.0)
    ap.add_argument("--skip-wire", action="store_true")
    ap.add_argument("--calibration", action="store_true", help="also the thermal acceptance of both units")
    args = ap.parse_args()
    physics(args.hours)
    if not args.skip_wire:
        wire(args.hours)
    if args.calibration:
        calibration()


if __name__ == "__main__":
    main()
