"""The units over temperature: what each thermal term of the accelerometer and the FOG does to
their outputs, the separate streams (earlier draws unchanged, a turn-on bias per power-on),
and the station's chamber air as the units' ambient."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from sim.physics.accelerometer import AccelerometerParams, QuartzAccelerometer, draw_accelerometer
from sim.physics.gyro import TACTICAL, FiberOpticGyro, draw_gyro
from sim.physics.thermal_chamber import ChamberAir
from sim.station import SimulatedStation
from sim.world import World

QUIET_ACC: dict[str, Any] = dict(white_density_g_per_rthz=0.0, gm_sigma_g=(), gm_tau_s=(), warmup_amplitude_g=0.0,
                 drift_g_per_s=0.0, bias_tc_g_per_c=0.0, self_heating_delta_c=0.0)
IA_UP = np.array([[1.0, 0.0, 0.0]])


def test_earlier_draws_are_unchanged_by_the_thermal_stream():
    """Values drawn by the code before issue 14 (its own stream per serial is new)."""
    old = {"QA-SIM-0003": (0.0009054216262922597, 1.314147809273129, 6.2087108091440186e-06),
           "QA-SIM-0100": (-0.0029171075923786318, 1.43870631543293, -9.515962616095738e-06)}
    for serial, (k0, k1, tc) in old.items():
        p = draw_accelerometer(serial)
        assert (p.k0_g, p.k1_ma_per_g, p.bias_tc_g_per_c) == (k0, k1, tc)
        assert p.sf_tc_ppm_per_c != 0.0 and p.bias_hysteresis_g > 0.0  # and the unit has thermal terms
    fog = {"FOG-SIM-0002": (1.2437359183606036, 364.01314190688475, 916.0861995261542),
           "FOG-SIM-0100": (1.248735887429237, -18.066570381194303, 847.4870980181067)}
    for serial, (bias, sfe, tau) in fog.items():
        g = draw_gyro(serial)
        assert (g.bias_dph, g.scale_factor_error_ppm, g.thermal_tau_s) == (bias, sfe, tau)
        assert g.shupe_dph_per_c_per_min != 0.0


def _unit_in(air: ChamberAir, world: World, **params) -> QuartzAccelerometer:
    p = AccelerometerParams(**{**QUIET_ACC, **params})
    return QuartzAccelerometer(p, world.rng("acc"), ambient=air, turn_on_rng=world.rng("turn-on"))


def _g(unit: QuartzAccelerometer, t: float) -> float:
    """Indicated g at one instant, noiseless (output / K1), IA up."""
    return float(unit.output_current_a(np.array([t]), IA_UP, 1.0, noise=False)[0] / unit.params.k1_a_per_g)


def test_bias_and_scale_factor_follow_the_element_polynomials():
    world = World(0)
    air = ChamberAir(world)
    unit = _unit_in(air, world, bias_tc_g_per_c=5e-6, bias_tc2_g_per_c2=2e-8, bias_tc3_g_per_c3=-1e-10,
                    sf_tc_ppm_per_c=30.0, sf_tc2_ppm_per_c2=-0.1, sf_tc3_ppm_per_c3=0.002)
    unit.set_supply(0.0, 15.0, -15.0)
    air.command(True, 70.0, None)
    world.advance(6 * 3600.0)
    t = world.now
    te = unit.element_temperature_c(t)[0]
    assert te == pytest.approx(70.0, abs=1e-6)  # soaked, no self-heating
    d = te - 23.0
    bias = 5e-6 * d + 2e-8 * d**2 - 1e-10 * d**3
    ratio = 1 + 1e-6 * (30 * d - 0.1 * d**2 + 0.002 * d**3)
    e_over_k1 = 1.0 + unit.params.k0_g + unit.params.k2_g_per_g2 + unit.params.k3_g_per_g3
    assert _g(unit, t) == pytest.approx((e_over_k1 + bias) * ratio, rel=1e-12)
    assert unit.scale_factor_truth(t)[0] == pytest.approx(ratio, rel=1e-15)


def test_hysteresis_separates_up_ramps_from_down_ramps_by_twice_h():
    world = World(0)
    air = ChamberAir(world)
    unit = _unit_in(air, world, bias_hysteresis_g=10e-6, hysteresis_width_c=4.0)
    unit.set_supply(0.0, 15.0, -15.0)
    air.command(True, 70.0, 1.0)
    world.advance(25 * 60.0)                  # going up
    assert unit.bias_truth_g(world.now)[0] == pytest.approx(10e-6)
    world.advance(6 * 3600.0)                 # soaked: the memory keeps the excursion
    assert unit.bias_truth_g(world.now)[0] == pytest.approx(10e-6)
    air.command(True, -40.0, 1.0)             # going down through the same temperatures
    world.advance(60 * 60.0)
    assert unit.bias_truth_g(world.now)[0] == pytest.approx(-10e-6)
    world.advance(10 * 3600.0)
    assert unit.bias_truth_g(world.now)[0] == pytest.approx(-10e-6)


def test_gradient_sensitivity_acts_during_ramps_only():
    world = World(0)
    air = ChamberAir(world)
    unit = _unit_in(air, world, bias_gradient_g_per_c=5e-6)
    unit.set_supply(0.0, 15.0, -15.0)
    air.command(True, 60.0, 1.0)
    world.advance(20 * 60.0)
    case, element = unit.body.nodes_c([world.now])[0]
    assert case > element and unit.bias_truth_g(world.now)[0] == pytest.approx(5e-6 * (case - element))
    world.advance(8 * 3600.0)
    assert abs(unit.bias_truth_g(world.now)[0]) < 1e-12  # soaked: no gradient


def test_turn_on_bias_is_new_at_each_power_on_and_on_its_own_stream():
    def unit(seed: int) -> QuartzAccelerometer:
        world = World(seed)
        return QuartzAccelerometer(AccelerometerParams(**{**QUIET_ACC, "bias_repeatability_g": 20e-6}),
                                   world.rng("acc"), turn_on_rng=world.rng("turn-on"))
    u = unit(1)
    runs = []
    t = 0.0
    for _ in range(200):
        u.set_supply(t, 15.0, -15.0)
        runs.append(u.truth()["run_bias_g"])
        assert u.startup_terms_g(t + 1.0)[0] == pytest.approx(runs[-1])
        u.set_supply(t + 10.0, 0.0, 0.0)
        t += 20.0
    runs_arr = np.array(runs)
    assert len(set(runs)) == 200 and 15e-6 < runs_arr.std() < 25e-6
    assert u.bias_truth_g(np.array([5.0, 25.0])).tolist() == runs[:2]  # each past run keeps its own


def test_turn_on_draws_leave_the_noise_streams_alone():
    def output(repeatability_g: float) -> np.ndarray:
        world = World(3)
        p = AccelerometerParams(bias_repeatability_g=repeatability_g)
        u = QuartzAccelerometer(p, world.rng("acc"), turn_on_rng=world.rng("turn-on"))
        u.set_supply(0.0, 15.0, -15.0)
        t = np.arange(1.0, 101.0)
        return u.output_current_a(t, np.tile(IA_UP, (100, 1)), 1.0) / p.k1_a_per_g
    diff = output(20e-6) - output(0.0)
    assert np.ptp(diff) < 1e-15 and abs(diff[0]) > 0  # one constant offset: the same noise samples


def test_fog_shupe_bias_follows_the_coil_temperature_rate():
    world = World(0)
    air = ChamberAir(world)
    p = TACTICAL.replace(bias_dph=0.0, bias_repeatability_dph=0.0, arw_deg_per_rh=0.0, bias_instability_dph=0.0,
                         rrw_dph_per_rh=0.0, bias_tc_dph_per_c=0.0, warmup_amplitude_dph=0.0,
                         g_sensitivity_dph_per_g=(0.0, 0.0, 0.0), self_heating_delta_c=0.0,
                         shupe_dph_per_c_per_min=0.5, scale_factor_pulses_per_arcsec=1000.0)
    g = FiberOpticGyro(p, world.rng("fog"), ambient=air)
    g.set_supply(0.0, 12.0)
    air.command(True, 70.0, 1.0)
    world.advance(30 * 60.0)
    t0 = world.now
    edges = t0 + np.arange(0, 601) * 0.1
    counts = g.pulses(edges, np.zeros((600, 3)), np.zeros((600, 3)))
    rate_dph = counts.sum() / (3600.0 * p.scale_factor_pulses_per_arcsec) / 60.0 * 3600.0
    coil_rate = g.body.rates_c_per_s(edges)[:, 1]
    expected = 0.5 * 60.0 * float(np.mean(coil_rate))  # °/h per °C/min × °C/min
    assert expected > 0.3  # the coil warms at ~1 °C/min
    assert rate_dph == pytest.approx(expected, abs=2e-3)


def test_the_station_chamber_air_is_both_units_ambient():
    with SimulatedStation(only={"chamber"}) as station:
        station.server.call(station.chamber_air.command, True, -30.0, None)
        station.server.call(station.world.advance, 8 * 3600.0)
        truth = station.thermal_truth(station.world.now)
        for key in ("air_c", "accelerometer_case_c", "accelerometer_element_c", "gyro_case_c", "gyro_coil_c"):
            assert truth[key][0] == pytest.approx(-30.0, abs=0.05), key  # unpowered units soak to the air
        assert station.accel.temp_sensor_current_a(station.world.now)[0] == pytest.approx(
            1e-6 * (273.15 - 30.0), rel=1e-4)
        assert math.isfinite(station.gyro.temperature_c(station.world.now))
