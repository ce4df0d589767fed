"""Bias stability and noise steps on the simulated station: static records → Allan deviation
→ IEEE 952 read-offs, against the simulated unit's truth."""

from __future__ import annotations

import math

import pytest

from bench.app.station import Station, builtin_sim_config
from bench.core.procedure import execute
from bench.core.store import RunStore
from procedures.noise import AccelerometerNoise, GyroNoise
from procedures.running import alone


def run_step(tmp_path, step, serial, kind, simulation=None):
    config = builtin_sim_config()
    config.simulation = simulation or {}
    store = RunStore(tmp_path / "b.sqlite")
    with Station(config, seed=11, unit_serial=serial, unit_kind=kind) as station:
        outcome = execute(alone(step), station, store, unit_serial=serial, seed=11)
        truth = station.sim.gyro_truth() if kind == "gyro" else station.sim.truth()
    return store, outcome, truth, {m.name: m for m in outcome.measurements}


@pytest.mark.parametrize("serial", ["FOG-SIM-0005", "FOG-SIM-0007"])
def test_gyro_noise_recovers_arw_and_bias_instability(tmp_path, serial):
    store, outcome, truth, m = run_step(
        tmp_path, GyroNoise(duration_s=10800.0, frame_rate_hz=20, warmup_s=300.0), serial, "gyro")
    assert outcome.status == "passed", outcome.reason
    arw, bi = m["arw"], m["bias_instability"]
    assert arw.unit == "deg/rth" and bi.unit == "deg/h"
    assert abs(arw.value - truth["arw_deg_per_rh"]) < max(3 * arw.uncertainty, 0.02 * truth["arw_deg_per_rh"])
    # the flat minimum of a few-hour record: within its (flicker) confidence interval, 2σ
    assert abs(bi.value - truth["bias_instability_dph"]) < 2 * bi.uncertainty
    assert store.streams(outcome.run_id)["gyro_static"].n_rows == 10800 * 20


def test_accelerometer_noise_recovers_the_white_noise_density(tmp_path):
    store, outcome, truth, m = run_step(tmp_path, AccelerometerNoise(duration_s=1800.0, warmup_s=60.0),
                                        "QA-SIM-0003", "accelerometer")
    assert outcome.status == "passed", outcome.reason
    density = m["noise_density"]
    expected = truth["white_density_g_per_rthz"]  # one-sided, the model's convention
    # the DMM adds its own reading noise (~0.1 µg at this aperture): a few per cent high at most
    assert expected * 0.95 < density.value < expected * 1.12, (density.value, expected)
    assert math.isfinite(m["bias_instability"].value) and m["bias_instability"].value > 0
    assert store.streams(outcome.run_id)["noise"].n_rows == 18000
