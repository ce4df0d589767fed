"""The simulated FOG's serial line with the real World, over a real socket, read by the driver.

docs/FOG_SERIAL.md is the contract: ASCII configuration while stopped (errors name the value
and the range), binary frames after $START in simulated time, frames lost when nobody
listens or the client stops reading, same seed → same bytes.
"""

from __future__ import annotations

import math
import time
import tomllib

import numpy as np
import pytest
import pyvisa
import serial

from bench.app.station import Station, StationError, builtin_sim_config, parse_station
from instruments.base import open_resource
from instruments.fog import GyroCommandError, GyroTimeoutError, SerialGyro
from instruments.fog_decode import FrameDecoder
from sim.physics.gyro import indicated_rate_dps
from sim.station import SimStationConfig, SimulatedStation

EARTH_RATE_DPS = math.degrees(7.2921150e-5)
READY, BOOTING, LINE_OVERFLOW = 0x01, 0x40, 0x80


class Bench:
    """A started simulated station with its supply, clock, table and the gyro's line open."""

    def __init__(self, seed: int = 11, reply_timeout_s: float = 2.0, **config) -> None:
        self.station = SimulatedStation(SimStationConfig(seed=seed, **config))
        self.station.start()
        res = self.station.resources()
        self.rm = pyvisa.ResourceManager("@py")
        opened = {n: open_resource(res[n], resource_manager=self.rm, timeout_ms=20000)
                  for n in ("supply", "sim", "turntable")}
        self.supply, self.clock, self.table = opened["supply"], opened["sim"], opened["turntable"]
        self.address = res["gyro"]
        self.port = serial.serial_for_url(self.address, baudrate=921600, timeout=reply_timeout_s)
        self.gyro = SerialGyro(self.port, name="gyro")

    def wait(self, seconds: float) -> None:
        assert self.clock.query(f"SIM:TIME:ADV {seconds!r};*OPC?").strip() == "1"

    def power(self, on: bool = True) -> None:
        if on:
            self.supply.write("APPL CH1,5,1")
        self.supply.query(f"OUTP {'ON' if on else 'OFF'},(@1);*OPC?")

    def ask(self, line: bytes) -> bytes:
        """Raw exchange: one command line, one reply line."""
        self.port.write(line + b"\r\n")
        return self.port.read_until(b"\n")

    def close(self) -> None:
        for res in (self.supply, self.clock, self.table):
            res.close()
        self.rm.close()
        self.port.close()
        self.station.stop()


@pytest.fixture
def bench():
    b = Bench()
    yield b
    b.close()


def test_identity_configuration_and_error_replies_on_the_wire(bench):
    bench.power()
    assert bench.ask(b"$ID?") == b"$ID,BENCHSIM,SFOG-2K,FOG-SIM-0001,1.0.0\r\n"
    assert bench.ask(b"$cfg?") == (b"$CFG,RATE=2000,BAUD=921600,FRAME=20,SF=10,FS=490,"
                                   b"STATE=STOPPED\r\n")
    assert bench.ask(b"$RATE 5000") == (b"$ERR,3,RATE 5000 needs 1000000 baud > BAUD 921600; "
                                        b"allowed RATE 1..4608 at this baud\r\n")
    assert bench.ask(b"$RATE 0") == b"$ERR,3,RATE 0 not in 1..10000\r\n"
    assert bench.ask(b"$RATE abc") == b"$ERR,2,RATE 'abc' is not a whole number\r\n"
    assert bench.ask(b"$BAUD 9600") == b"$ERR,3,BAUD 9600 not in 115200|230400|460800|921600\r\n"
    assert bench.ask(b"$BAUD 115200") == (b"$ERR,3,BAUD 115200 cannot carry RATE 2000 (needs "
                                          b"400000 baud); allowed BAUD 460800|921600 at this rate\r\n")
    assert bench.ask(b"$FOO").startswith(b"$ERR,1,unknown command '$FOO'; allowed ID? CFG?")
    assert bench.ask(b"$" + b"X" * 100) == b"$ERR,4,line longer than 64 bytes discarded\r\n"
    assert bench.ask(b"$RATE,500") == b"$OK,RATE,500\r\n"
    assert bench.ask(b"$BAUD 115200") == b"$OK,BAUD,115200\r\n"
    assert bench.ask(b"$CFG?").startswith(b"$CFG,RATE=500,BAUD=115200,")


def test_driver_validates_before_the_wire_and_orders_rate_and_baud(bench):
    bench.power()
    gyro, line = bench.gyro, bench.station.gyro_line
    assert gyro.identify().serial == "FOG-SIM-0001"
    for bad, fragment in [({"rate_hz": 5000}, "allowed rate_hz 1..4608"),
                          ({"rate_hz": 0}, "[1, 10000]"), ({"rate_hz": 2.5}, "rate_hz=2.5"),
                          ({"baud": 9600}, "9600"), ({"polarity": 0}, "polarity=0"),
                          ({"scale_factor_pulses_per_arcsec": -1.0}, "-1.0")]:
        with pytest.raises(ValueError, match=fragment.replace("[", r"\[").replace("]", r"\]")):
            gyro.configure(**bad)
    assert (line.rate_hz, line.baud) == (2000, 921600)  # nothing reached the unit
    gyro.configure(rate_hz=1000, baud=230400)  # rate first: 2000 Hz would not fit 230400
    assert (line.rate_hz, line.baud, bench.port.baudrate) == (1000, 230400, 230400)
    gyro.configure(rate_hz=4000, baud=921600)  # baud first
    assert (gyro.config.rate_hz, gyro.config.baud) == (4000, 921600)
    bench.port.write(b"$RATE 99999\r\n")  # the unit's own refusal reaches the caller too
    bench.port.read_until(b"\n")
    with pytest.raises(GyroCommandError, match="RATE 0 not in 1..10000"):
        gyro._command("$RATE 0", "$OK,RATE")


def test_an_unpowered_unit_is_silent():
    bench = Bench(reply_timeout_s=1.0)
    try:
        with pytest.raises(GyroTimeoutError, match=r"gyro: no reply to '\$ID\?'.*unpowered"):
            bench.gyro.identify()
        snap = bench.gyro.snapshot()
        assert snap["idn"] is None and "no reply" in snap["error"]
    finally:
        bench.close()


def test_two_khz_stream_in_simulated_time_with_continuous_sequence(bench):
    bench.power()
    gyro = bench.gyro
    gyro.start()
    first = gyro.read_frames(3000, wait=bench.wait)  # boot (BOOTING, zero counts), then READY
    second = gyro.read_frames(120_000, wait=bench.wait)  # one simulated minute at 2 kHz
    tail_s = 0.0105
    bench.wait(tail_s)
    last = gyro.stop()
    index = np.concatenate([first.index, second.index, last.index])
    assert np.array_equal(index, np.arange(index.size))
    # every frame whose interval ended before the stop (started at t = 0) arrived
    assert index.size == math.floor(bench.station.world.now * 2000) == 123_021
    assert gyro.counters.dropped == gyro.counters.corrupt == gyro.counters.resync_bytes == 0
    boot_s = bench.station.gyro_truth()["boot_time_s"]
    booting = first.t_s <= boot_s
    assert np.all(first.status[booting] & BOOTING) and np.all(first.counts[booting] == 0)
    assert np.all(second.status & READY) and not np.any(second.status & BOOTING)
    assert np.allclose(second.t_s, (second.index + 1) / 2000)
    # at rest: Earth rate along the vertical IA, plus the unit's bias, within its noise
    assert abs(second.rate_dps.mean() - EARTH_RATE_DPS * math.sin(math.radians(32.06))) < 0.003
    assert 15 < second.temperature_c.mean() < 40
    assert bench.ask(b"$CFG?").endswith(b"STATE=STOPPED\r\n")


def _until(bench: Bench, condition, tries: int = 200) -> None:
    """Wait (wall time) until the server thread has seen a connection change."""
    for _ in range(tries):
        if bench.station.server.call(condition):
            return
        time.sleep(0.01)
    raise AssertionError("the simulated line did not see the connection change")


def test_frames_without_a_listener_are_lost(bench):
    bench.power()
    bench.gyro.start()
    bench.gyro.read_frames(100, wait=bench.wait)
    line = bench.station.gyro_line
    bench.port.close()  # nobody on the line while 1 s passes
    _until(bench, lambda: line._link is None)
    bench.wait(1.0)
    port = serial.serial_for_url(bench.address, timeout=2.0)
    try:
        _until(bench, lambda: line._link is not None)
        bench.wait(0.1)
        got = FrameDecoder().feed(port.read(200 * 20))
        assert got.count.size == 200
        now_frames = math.floor(bench.station.world.now * 2000)
        assert got.index[-1] < now_frames and got.index[0] > 100 + 1900  # the gap is gone
        assert not np.any(got.status & LINE_OVERFLOW)  # nothing was buffered for nobody
        port.write(b"$STOP\r\n")
    finally:
        port.close()


def test_a_second_client_is_refused_and_the_first_keeps_the_line(bench):
    bench.power()
    other = serial.serial_for_url(bench.address, timeout=0.5)
    try:
        other.write(b"$ID?\r\n")
        with pytest.raises(serial.SerialException):
            other.read(1)  # closed at once by the unit's end
    finally:
        other.close()
    assert bench.gyro.identify().model == "SFOG-2K"


def test_a_client_that_stops_reading_costs_bounded_memory_and_sees_the_gap(bench):
    bench.power()
    line = bench.station.gyro_line
    gyro = bench.gyro
    gyro.start()
    bench.wait(300.0)  # 12 MB of frames at 2 kHz, nobody reading
    pending = bench.station.server.call(lambda: line._link.pending_bytes)
    assert pending <= line.send_buffer_bytes and line.frames_lost > 0
    delivered = line.frames_sent
    frames = gyro.read_frames(delivered + 10, wait=bench.wait)  # the backlog, then fresh ones
    assert frames.dropped == line.frames_lost
    gap = int(np.flatnonzero(np.diff(frames.index) > 1)[0]) + 1
    assert np.flatnonzero(frames.status & LINE_OVERFLOW).tolist() == [gap]
    assert frames.index[gap] == frames.index[gap - 1] + line.frames_lost + 1
    assert gap == delivered  # every frame the unit could buffer arrived, in order
    gyro.stop()


def _stream_bytes(seed: int, steps: list[float]) -> bytes:
    b = Bench(seed=seed)
    try:
        b.power()
        b.wait(2.0)
        b.port.write(b"$START\r\n")
        assert b.port.read_until(b"\n") == b"$OK,START\r\n"
        data = b""
        for step in steps:  # the same span polled in different steps
            b.wait(step)
            data += b.port.read(round(b.station.gyro_line.frames_sent * 20 - len(data)))
        return data
    finally:
        b.close()


def test_same_seed_same_bytes_however_polled():
    one = _stream_bytes(5, [1.0])
    ten = _stream_bytes(5, [0.1] * 10)
    other = _stream_bytes(6, [1.0])
    assert len(one) == 2000 * 20 and one == ten
    assert other != one


def test_whole_revolutions_at_table_rate_read_table_rate_plus_earth_rate():
    bench = Bench(seed=2, gyro_grade="navigation")
    try:
        bench.power()
        table = bench.table
        table.write(":INT:CLOS;:MODE:RATE 1;:DEM:RATE 1,30")
        table.query("*OPC?")
        bench.wait(10.0)  # boot (navigation grade: a few seconds) and reach the rate
        bench.gyro.start()
        frames = bench.gyro.read_frames(2 * 12 * 2000, wait=bench.wait)  # two revolutions
        bench.gyro.stop()
        truth = bench.station.gyro_truth()
        params = bench.station.gyro.params
        omega = 30.0 + EARTH_RATE_DPS * math.sin(math.radians(truth["latitude_deg"]))
        expected = float(indicated_rate_dps(params, omega)) + truth["run_bias_dph"] / 3600.0
        # the horizontal Earth rate seen through the misalignment averages out over whole turns
        assert frames.rate_dps.mean() == pytest.approx(expected, abs=2e-4)
        without_earth = float(indicated_rate_dps(params, 30.0)) + truth["run_bias_dph"] / 3600.0
        assert abs(frames.rate_dps.mean() - without_earth) > 1.5e-3  # Earth rate (2.2e-3) resolved
    finally:
        bench.close()


def test_power_loss_ends_the_stream_without_a_stop_reply():
    bench = Bench(reply_timeout_s=1.0)
    try:
        bench.power()
        bench.gyro.start()
        bench.gyro.read_frames(500, wait=bench.wait)
        bench.wait(0.05)
        bench.power(False)
        with pytest.raises(GyroTimeoutError, match=r"no \$OK,STOP") as err:
            bench.gyro.stop()
        assert len(err.value.frames) == 100  # the frames sent before the cut are kept
        assert not bench.gyro.streaming
    finally:
        bench.close()


@pytest.mark.parametrize("text,fragment", [
    ('[instruments.gyro]\ndriver = "fog_serial"\naddress = "/dev/ttyUSB0"\nbaudrate = 9600\n',
     "baudrate = 9600 not in 115200|230400|460800|921600"),
    ('[instruments.gyro]\ndriver = "fog_serial"\naddress = "/dev/ttyUSB0"\npolarity = 2\n',
     "polarity = 2 not in 1|-1"),
    ('[instruments.gyro]\ndriver = "fog_serial"\naddress = "/dev/ttyUSB0"\n'
     'scale_factor_pulses_per_arcsec = 0\n', "must be a number in 1e-06..1e+09"),
    ('[instruments.gyro]\ndriver = "fog_serial"\naddress = "/dev/ttyUSB0"\nparity = "E"\n',
     "option 'parity' not in"),
    ("[wiring]\ngyro_supply_channel = 2\n", "gyro_supply_channel = 2 is an accelerometer rail"),
    ("[wiring]\ngyro_current_limit_a = 7.0\n", "gyro_current_limit_a = 7.0 must be a number in 0..5"),
    ('[simulation]\ngyro_grade = "consumer"\n', "gyro_grade = 'consumer' not in navigation|tactical"),
    ("[simulation.gyro]\nwarp = 1\n", "unknown GyroParams fields ['warp']"),
    ("[simulation]\ngyro_supply_channel = 3\n", "gyro_supply_channel = 3 is an accelerometer rail"),
])
def test_station_files_validate_the_gyro(text, fragment):
    with pytest.raises(StationError, match=fragment.replace("[", r"\[").replace("]", r"\]")
                       .replace("|", r"\|").replace("(", r"\(").replace("+", r"\+")):
        parse_station(tomllib.loads(text), "rig.toml")


def test_a_serial_gyro_in_a_station_file_parses_with_its_options():
    cfg = parse_station(tomllib.loads(
        '[instruments.gyro]\ndriver = "fog_serial"\naddress = "socket://10.0.0.5:4001"\n'
        'baudrate = 460800\npolarity = -1\n[wiring]\ngyro_supply_voltage_v = 5.0\n'), "rig.toml")
    assert cfg.instruments["gyro"].options == {"baudrate": 460800, "polarity": -1}
    assert (cfg.wiring["gyro_supply_channel"], cfg.wiring["gyro_current_limit_a"]) == (1, 1.0)


def test_the_embedded_simulated_station_serves_the_gyro_with_its_driver():
    with Station(builtin_sim_config(), seed=4) as station:
        gyro = station.instruments["gyro"]
        assert isinstance(gyro, SerialGyro) and gyro.port.baudrate == 921600
        supply = station.instruments["supply"]
        supply.ch[1].apply(5.0, 1.0)
        supply.set_outputs([1], True)
        snap = station.snapshot()["instruments"]["gyro"]
        assert snap["driver"] == "fog_serial" and snap["address"].startswith("socket://")
        assert snap["idn"]["serial"] == "FOG-SIM-0001" and snap["settings"]["rate_hz"] == 2000
        gyro.start()
        frames = gyro.read_frames(4000, wait=station.clock.sleep)
        gyro.stop()
        assert np.array_equal(frames.index, np.arange(4000))
