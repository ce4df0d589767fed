"""The shipped station files parse, and the simulated one runs with its own settings."""

from __future__ import annotations

from pathlib import Path

import pytest

from bench.app.station import OPENERS, Station, StationError, builtin_sim_config, load_station, parse_station
from bench.core.procedure import execute
from bench.core.store import RunStore
from instruments.registry import DRIVERS, MODBUS, SERIAL, TRANSPORTS, VISA
from procedures.catalogue import CATALOGUE
from procedures.running import alone
from procedures.startup import StartupAcquisition, StartupParameters
from sim import server
from sim.station import INSTRUMENTS

STATIONS = Path(__file__).resolve().parents[2] / "stations"


def test_the_real_rig_template_names_every_instrument_the_startup_procedure_needs():
    cfg = load_station(STATIONS / "lab-startup-rig.toml")
    assert not cfg.simulated and cfg.clock == "wall"
    assert set(StartupAcquisition.requires) <= set(cfg.instruments)
    assert cfg.instruments["dmm"].address.endswith("::SOCKET")
    assert cfg.wiring["positive_rail_channel"] == 2


def test_the_acceptance_rig_template_has_what_every_step_and_the_vibration_test_need():
    cfg = load_station(STATIONS / "lab-acceptance-rig.toml")
    assert not cfg.simulated
    needed = {r for step in CATALOGUE.steps.values() if set(step.kinds) & {"accelerometer", "gyro"}
              for r in step.requires}
    assert needed <= set(cfg.instruments)
    assert cfg.instruments["gyro"].driver == "fog_serial" and cfg.wiring["gyro_supply_channel"] == 1


def test_a_simulated_station_file_sets_the_world(tmp_path):
    cfg = load_station(STATIONS / "sim-custom.toml")
    assert cfg.simulated
    with Station(cfg, seed=None, unit_serial=None) as station:
        assert station.sim.config.line_hz == 60.0 and station.sim.config.seed == 42
        assert station.instruments["dmm"].line_frequency_hz == 60.0
        outcome = execute(alone(StartupAcquisition(StartupParameters(duration_s=30, off_wait_s=1))),
                          station, RunStore(tmp_path / "b.sqlite"), unit_serial="QA-SIM-0042",
                          seed=42)
        k1 = station.sim.truth()["k1_ma_per_g"]
    assert outcome.status == "passed"
    level = {m.name: m.value for m in outcome.measurements}["level_check_g"]
    # nominal 1.33 mA/g assumed by the procedure; this unit has 1.29 mA/g
    assert level == pytest.approx(k1 / 1.33 * station.sim.g_mps2 / 9.80665, rel=1e-3)


def test_site_table_is_validated_and_defaults_to_the_simulated_world(tmp_path):
    assert parse_station({"site": {"latitude_deg": 45.0, "local_g_mps2": 9.8}}).site == {
        "latitude_deg": 45.0, "height_m": 10.0, "local_g_mps2": 9.8}
    assert parse_station({"simulation": {"latitude_deg": 39.9, "height_m": 44.0}}).site == {
        "latitude_deg": 39.9, "height_m": 44.0}
    with pytest.raises(StationError, match="latitude_deg = 95 must be a number in -90..90"):
        parse_station({"site": {"latitude_deg": 95}})
    with pytest.raises(StationError, match="'altitude' not in"):
        parse_station({"site": {"altitude": 3.0}})


def test_the_embedded_station_is_the_sim_table_joined_with_the_driver_registry():
    assert set(OPENERS) == set(TRANSPORTS)  # every kind of connection a driver needs can be opened
    driven_over = {server.SCPI.name: VISA, server.SERIAL.name: SERIAL, server.MODBUS.name: MODBUS}
    for row in INSTRUMENTS:
        assert DRIVERS[row.driver].transport == driven_over[row.transport.name], row.name
    with Station(builtin_sim_config()) as station:
        assert list(station.instruments) == [row.name for row in INSTRUMENTS]
        for row in INSTRUMENTS:
            assert station.config.instruments[row.name].driver == row.driver
            assert isinstance(station.instruments[row.name], DRIVERS[row.driver].cls)


def test_driver_options_are_checked_from_the_registry():
    table = {"instruments": {"gyro": {"driver": "fog_serial", "address": "/dev/ttyUSB0", "polarity": 2}}}
    with pytest.raises(StationError, match=r"\[instruments.gyro\]: polarity = 2 not in 1\|-1"):
        parse_station(table)
    table["instruments"]["gyro"] = {"driver": "fog_serial", "address": "x", "parity": "N"}
    with pytest.raises(StationError, match=r"option 'parity' not in \['baudrate', 'polarity', "):
        parse_station(table)
    dmm = {"driver": "keysight_34465a", "address": "x", "options": ["DIG"]}  # free keys kept for the tools
    assert parse_station({"instruments": {"dmm": dmm}}).instruments["dmm"].options == {"options": ["DIG"]}
