"""The thermal steps on the simulated station, through the chamber's Modbus TCP and the
instruments' SCPI: what they measure against the simulated unit's own thermal terms, what
they store, and how a chamber fault ends them.

* A sweep of a unit whose thermal terms are linear recovers its bias and scale-factor
  temperature coefficients, attaches a compensation file that reads back, and leaves a
  compensated residual over the verification profile at the level its noise states, far
  below the uncompensated one.
* The soak waits on the unit's own sensor: every point's soak is at least the window and the
  sensor stable at its end; the points follow the set points (rising, then the falling
  verification between them).
* A limit trip, a controller alarm or a lost connection at a temperature point aborts the
  run with the reason naming the chamber, the soak's samples kept, and the station made safe
  (chamber in standby at the lab's set point, supply off, table at rest).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pytest

from bench.analysis.thermal import compensation_from_toml
from bench.app.reports.thermal_plots import thermal_sweep_section
from bench.app.station import Station, builtin_sim_config
from bench.core.procedure import execute
from bench.core.store import RunStore
from instruments.base import open_resource
from procedures.running import alone
from procedures.thermal_ramp import ThermalRamp
from procedures.thermal_sweep import COMPENSATION_FILE, ThermalSweep, verification_temperatures
from procedures.turn_on_repeatability import GyroTurnOnRepeatabilityTest
from sim.physics.accelerometer import draw_accelerometer

SERIAL = "QA-SIM-0005"
#: a short sweep: four temperatures 0…45 °C, one verification point between them
SHORT = dict(low_c=0.0, high_c=45.0, set_points=4, verify_points=2, ramp_c_per_min=3.0,
             soak_window_s=600.0, soak_poll_s=60.0, positions=12, settle_s=2.0, average_s=4.0, nplc=1.0)
#: the drawn unit with only linear thermal terms, no hysteresis or gradient, and no slow bias
#: drift in time (≈ 1e-9 g/s: 15 µg between the calibration and the verification points —
#: which no thermal model can compensate)
LINEAR = {"drift_g_per_s": 0.0, "bias_tc2_g_per_c2": 0.0, "bias_tc3_g_per_c3": 0.0, "sf_tc2_ppm_per_c2": 0.0,
          "sf_tc3_ppm_per_c3": 0.0, "bias_hysteresis_g": 0.0, "bias_gradient_g_per_c": 0.0}


def run_step(tmp_path, step, *, accelerometer: dict | None = None, kind: str = "accelerometer",
             serial: str = SERIAL, fault: str | None = None, at_progress: int = 0):
    """Run ``step`` alone on the built-in station; at its ``at_progress``-th progress report
    inject ``fault`` through the sim-control endpoint."""
    cfg = builtin_sim_config()
    if accelerometer:
        cfg = dataclasses.replace(cfg, simulation={**(cfg.simulation or {}), "accelerometer": accelerometer})
    store = RunStore(tmp_path / "bench.sqlite")
    with Station(cfg, seed=3, unit_serial=serial, unit_kind=kind) as station:
        sim: Any = station.sim
        control = open_resource(station.config.clock, timeout_ms=20000)
        calls = []

        def progress(done, total, message=""):
            calls.append(message)
            if fault is not None and len(calls) == at_progress:
                control.write(fault)

        outcome = execute(alone(step), station, store, unit_serial=serial, seed=3, progress=progress)
        control.close()
        sim.server.call(sim.world.advance, 60.0)
        safe = {"chamber_mode_auto": sim.chamber.conditioning, "set_point_c": sim.chamber.set_point_c,
                "lab_c": sim.chamber_air.params.lab_ambient_c,
                "outputs": [ch.output for ch in sim.supply.channels.values()],
                "table_moving": [bool(a.moving(sim.world.now)) for a in sim.table.axes]}
    return store, outcome, safe


def test_a_linear_unit_s_temperature_coefficients_are_recovered_and_its_file_verified(tmp_path):
    step = ThermalSweep(**SHORT)
    store, outcome, _ = run_step(tmp_path, step, accelerometer=LINEAR)
    assert outcome.status == "passed", outcome.reason
    got = {m.name: m for m in outcome.measurements}
    unit = dataclasses.replace(draw_accelerometer(SERIAL), **LINEAR)
    # the bias's slope against the unit's own sensor: the element follows the case with a
    # constant self-heating offset once soaked, so the slope is the element's b1
    assert got["bias_tc"].value == pytest.approx(unit.bias_tc_g_per_c, abs=0.5e-6)
    assert got["sf_tc"].value == pytest.approx(unit.sf_tc_ppm_per_c, abs=0.5)
    # the file the run holds reads back, for this unit, over the temperatures measured
    model = compensation_from_toml(store.attachment(outcome.run_id, COMPENSATION_FILE).decode())
    assert model.unit_serial == SERIAL and model.input_unit == "g" and model.output_unit == "mA"
    assert model["k0"].role == "bias" and model["k1"].role == "scale_factor"
    points = store.load(outcome.run_id, "thermal_points")
    assert np.array_equal(points["phase"], [0, 0, 0, 0, 1, 1])
    assert np.allclose(points["set_point_c"], [0, 15, 30, 45, *verification_temperatures(0, 45, 4, 2)])
    assert np.all(np.diff(points["temperature_c"][:4]) > 10)  # the unit's sensor followed the chamber
    assert np.all(points["soak_time_s"] >= SHORT["soak_window_s"])
    lo, hi = model.valid_range_c
    assert lo == pytest.approx(points["temperature_c"][0]) and hi == pytest.approx(points["temperature_c"][3])
    # compensated: at the noise the run states; uncompensated: the TC over ±15 °C
    assert got["bias_residual"].value < 4 * got["bias_residual"].uncertainty + 2e-6
    assert got["bias_uncompensated"].value > 5 * got["bias_residual"].value
    assert got["sf_residual"].value < 4 * got["sf_residual"].uncertainty + 2.0
    soak = store.load(outcome.run_id, "thermal_soak")
    assert soak["t_s"].size > 20 and np.all(np.diff(soak["t_s"]) > 0)
    # the report's figure: the quantities over temperature and the verification residuals
    title, png, caption = thermal_sweep_section(store, outcome.run_id, store.results(outcome.run_id), tmp_path)
    assert (tmp_path / png).stat().st_size > 10_000 and "k0: TC" in caption and "thermal_compensation.toml" in caption


def test_the_ramp_step_separates_hysteresis_from_rate_sensitivity_with_two_rates(tmp_path):
    step = ThermalRamp(soak_window_s=300.0)  # −10…60 °C at 0.7 and 1.4 °C/min
    store, outcome, _ = run_step(tmp_path, step, accelerometer={**LINEAR, "bias_hysteresis_g": 0.0})
    assert outcome.status == "passed", outcome.reason
    got = {m.name: m for m in outcome.measurements}
    assert {"hysteresis", "rate_sensitivity", "branch_offset"} <= set(got)
    # no hysteresis and no gradient in this unit: what is left is the element's lag behind
    # the case-mounted sensor, a rate term; the hysteresis is zero within its uncertainty
    assert abs(got["hysteresis"].value) < 4 * got["hysteresis"].uncertainty + 2e-6
    record = store.load(outcome.run_id, "thermal_ramp")
    assert record["t_s"].size > 20_000 and np.ptp(record["unit_c"]) > 60.0
    setpoints = store.load(outcome.run_id, "thermal_ramp_setpoints")
    assert np.allclose(setpoints["set_point_c"], [60, -10, 60, -10])
    assert np.allclose(setpoints["rate_c_per_min"], [0.7, 0.7, 1.4, 1.4])


def test_the_ramp_step_fits_the_hysteresis_switching_width(tmp_path):
    """The simulated unit's hysteresis is a play of half width w = 6.5 °C (13 °C of travel to
    switch) and ±18 µg (36 µg up minus down): the step fits the width instead of leaving a
    settling window out, and reads the full 36 µg. The width is read on the case sensor, which
    the element lags by 20 s: at up to 1.4 °C/min that widens it by up to τ·r = 0.47 °C."""
    unit = {**LINEAR, "bias_hysteresis_g": 18e-6, "hysteresis_width_c": 6.5, "element_tau_s": 20.0}
    store, outcome, _ = run_step(tmp_path, ThermalRamp(soak_window_s=300.0), accelerometer=unit)
    assert outcome.status == "passed", outcome.reason
    got = {m.name: m for m in outcome.measurements}
    assert abs(got["hysteresis"].value - 36e-6) < 3 * got["hysteresis"].uncertainty
    a = store.results(outcome.run_id)["thermal_ramp.analysis"]
    w = a["hysteresis_width_c"]
    assert 6.5 - 3 * w["std"] <= w["value"] <= 6.5 + 20.0 * 1.4 / 60.0 + 3 * w["std"]
    assert "settle_c" not in {f.name for f in dataclasses.fields(ThermalRamp.Parameters)}


def test_gyro_turn_on_repeatability_over_two_days(tmp_path):
    step = GyroTurnOnRepeatabilityTest(cycles=4, days=2, off_s=600.0, day_gap_s=20 * 3600.0, warmup_s=300.0,
                                       record_s=60.0, soak_window_s=300.0)
    store, outcome, _ = run_step(tmp_path, step, kind="gyro", serial="FOG-SIM-0005")
    assert outcome.status == "passed", outcome.reason
    got = {m.name for m in outcome.measurements}
    assert got == {"turn_on_repeatability", "turn_on_raw_sd", "day_to_day", "within_day"}
    cycles = store.load(outcome.run_id, "turn_on_cycles")
    assert np.array_equal(cycles["day"], [0, 0, 1, 1])
    gaps = np.diff(cycles["t_on_s"])
    assert gaps[1] > 20 * 3600.0 > gaps[0]  # the days apart on the bench clock
    analysis = store.results(outcome.run_id)["gyro_turn_on_repeatability.analysis"]
    assert analysis["n_cycles"] == 4 and analysis["unit"] == "deg/h"


@pytest.mark.parametrize("fault,words", [
    ('SIM:FAUL:LIM "chamber"', ("chamber", "limit tripped")),
    ('SIM:FAUL:ALAR "chamber"', ("chamber", "alarm")),
    ('SIM:FAUL:DROP "chamber",1e6', ("chamber",)),
])
def test_a_chamber_fault_at_a_point_aborts_keeps_the_samples_and_leaves_the_station_safe(
        tmp_path, fault, words):
    step = ThermalSweep(**SHORT)
    store, outcome, safe = run_step(tmp_path, step, fault=fault, at_progress=2)
    assert outcome.status == "aborted"
    for word in words:
        assert word in outcome.reason, (word, outcome.reason)
    soak = store.load(outcome.run_id, "thermal_soak")
    assert soak["t_s"].size > 0  # every poll before the fault is in the store
    info = store.get_run(outcome.run_id)
    assert info.status == "aborted" and info.last_sample_t_s is not None
    assert safe["outputs"] == [False, False, False] and safe["table_moving"] == [False, False]
    if "DROP" in fault:  # nobody could reach the controller: the teardown says so
        events = {e.kind: e.message for e in store.events(outcome.run_id)}
        assert "chamber" in events["teardown_error"]
    else:
        assert not safe["chamber_mode_auto"] and safe["set_point_c"] == pytest.approx(safe["lab_c"])
