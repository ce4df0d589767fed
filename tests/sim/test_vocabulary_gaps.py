"""The commands clients written from the instruments' manuals sent and the simulators did not
answer, each pinned by the bytes on the wire: the DAQ970A's MEAS?, CONF?, FUNC?, DATA:LAST?,
Monitor and ROUT:SCAN? (a definite-length block), the E36312A's Operation and Questionable
status registers, and the Watlow F4T's part number (one character per register), loop power,
alarms 3-6 and real-time clock.

Expected replies are built here, independently of the simulators' encoders (a block header
counted by hand, a register word from ``ord``), so one bug cannot hide on both sides."""

from __future__ import annotations

import datetime
import re
import socket
import struct

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pymodbus.client import ModbusTcpClient

from sim.station import SimStationConfig, SimulatedStation

FIXTURE = {"1": "QA-SIM-0001", "2": "QA-SIM-0002", "3": "QA-SIM-0003", "4": "QA-SIM-0004"}
READING = rb"[+-]\d\.\d{8}E[+-]\d{2}"  # an NR3 reading as the DAQ970A sends it
PART_NUMBER = "F4T1L0AA1A11AA1"


def ask(device, *messages: str) -> bytes | None:
    """Send each message to a device directly; the last one's reply."""
    reply = None
    for message in messages:
        reply = device.process(message.encode())
    return reply


def block(payload: bytes) -> bytes:
    """An IEEE 488.2 definite-length block, counted by hand: #, digits of the length, length."""
    length = str(len(payload)).encode()
    return b"#" + str(len(length)).encode() + length + payload


# ---- DAQ970A ---------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def daq_station(station_factory):
    station = station_factory(seed=5, fixture=FIXTURE)
    supply = station.supply
    assert ask(supply, "APPL CH2,15,0.1;APPL CH3,15,0.1;OUTP ON,(@2,3)") is None
    station.world.advance(600.0)  # the units powered and warm: their channels read volts
    return station


@pytest.fixture
def daq(daq_station):
    device = daq_station.fixture.daq
    ask(device, "ABOR", "*RST", "*CLS")
    return device


def test_rout_scan_query_answers_the_34970a_definite_length_block(daq):
    assert ask(daq, "ROUT:SCAN?") == b"#13(@)\n"
    assert ask(daq, "ROUT:SCAN (@103,101:102)") is None
    assert ask(daq, "ROUT:SCAN?") == b"#214(@101,102,103)\n"
    assert ask(daq, "ROUTE:SCAN?;:ROUT:SCAN:SIZE?") == b"#214(@101,102,103);+3\n"


@settings(max_examples=40, deadline=None)
@given(st.sets(st.integers(101, 120), min_size=1, max_size=20), st.randoms(use_true_random=False))
def test_any_scan_list_comes_back_sorted_in_a_block(daq_station, channels, rnd):
    daq = daq_station.fixture.daq
    sent = sorted(channels)
    rnd.shuffle(sent)
    assert ask(daq, "ROUT:SCAN (@" + ",".join(map(str, sent)) + ")") is None
    expected = block(("(@" + ",".join(str(c) for c in sorted(channels)) + ")").encode())
    assert ask(daq, "ROUT:SCAN?") == expected + b"\n"
    assert daq.pop_error() == '+0,"No error"'


def test_conf_query_gives_each_channels_function_range_and_resolution(daq):
    assert ask(daq, "CONF:VOLT:DC 1,(@101)", "CONF:VOLT:DC 10,(@102)", "VOLT:NPLC 10,(@102)") is None
    # resolution = rms noise of the NPLC on the range: 0.3 ppm at 1 PLC, 0.1 ppm at 10 PLC
    assert ask(daq, "CONF? (@101,102)") == (b'"VOLT +1.00000000E+00,+3.00000000E-07",'
                                             b'"VOLT +1.00000000E+01,+1.00000000E-06"\n')
    assert ask(daq, "CONF?") is None  # the channel list is required
    assert daq.pop_error() == '-109,"Missing parameter"'


def test_func_query_answers_volt_for_every_listed_channel(daq):
    assert ask(daq, "FUNC? (@101:103)") == b'"VOLT","VOLT","VOLT"\n'
    assert ask(daq, "SENS:FUNC? (@120)") == b'"VOLT"\n'
    assert ask(daq, "SENSE:FUNCTION? (@105,104)") == b'"VOLT","VOLT"\n'


def test_meas_configures_overwrites_the_scan_list_triggers_and_returns_the_readings(daq_station, daq):
    assert ask(daq, "ROUT:SCAN (@105:110)", "VOLT:NPLC 10,(@101)") is None
    reply = ask(daq, "MEAS:VOLT:DC? 10,(@102,101)")
    assert reply is not None and re.fullmatch(READING + b"," + READING + b"\n", reply)
    assert ask(daq, "ROUT:SCAN?") == b"#210(@101,102)\n"          # the scan list overwritten
    assert ask(daq, "CONF? (@101)") == b'"VOLT +1.00000000E+01,+3.00000000E-06"\n'  # 1 PLC again
    first, second = reply.strip().split(b",")
    assert ask(daq, "DATA:LAST? (@101)") == first + b"\n"          # channel 101 scanned first
    assert ask(daq, "DATA:LAST? (@102)") == second + b"\n"
    truth = daq_station.fixture_truth()  # level, IA up: ≈ (K0 + 1 g)·K1·R, R = 5 kΩ at each socket
    for socket_, reading in ((1, first), (2, second)):
        assert float(reading) == pytest.approx(truth[socket_]["k1_ma_per_g"] * 1e-3 * 5000.0, rel=5e-3)
    assert ask(daq, "MEAS? (@103)") is not None                       # [:VOLT][:DC] are optional
    assert daq.pop_error() == '+0,"No error"'


def test_meas_honours_the_reading_format(daq):
    assert ask(daq, "FORM:READ:CHAN ON") is None
    reply = ask(daq, "MEAS? (@104)")
    assert reply is not None and re.fullmatch(READING + rb",104\n", reply)


@settings(max_examples=15, deadline=None)
@given(sweeps=st.integers(1, 6), wanted=st.integers(1, 9), channel=st.sampled_from([101, 102, 103]))
def test_data_last_returns_the_channels_most_recent_readings_oldest_first(daq_station, sweeps, wanted, channel):
    daq = daq_station.fixture.daq
    ask(daq, "ABOR", "*RST", "*CLS")
    fetched = ask(daq, "CONF:VOLT:DC (@101:103)", "FORM:READ:CHAN ON;TIME ON", f"TRIG:COUN {sweeps}",
                  "INIT", "FETC?")
    assert fetched is not None
    fields = fetched.strip().split(b",")
    mine = [b",".join(fields[i:i + 3]) for i in range(0, len(fields), 3) if fields[i + 2] == str(channel).encode()]
    assert len(mine) == sweeps
    reply = ask(daq, f"DATA:LAST? {wanted},(@{channel})")
    if wanted <= sweeps:
        assert reply == b",".join(mine[-wanted:]) + b"\n"
        assert daq.pop_error() == '+0,"No error"'
    else:  # the guide: more readings than are stored is an error
        assert reply is None
        assert daq.pop_error().startswith("-222,")


def test_data_last_keeps_its_readings_through_r_and_forgets_them_at_init(daq):
    ask(daq, "CONF:VOLT:DC (@101:102)", "TRIG:SOUR BUS", "INIT", "*TRG")
    assert ask(daq, "*OPC?") == b"1\n"
    last = ask(daq, "DATA:LAST? (@102)")
    assert last is not None and re.fullmatch(READING + b"\n", last)
    assert ask(daq, "R?") is not None and ask(daq, "DATA:POIN?") == b"+0\n"   # memory emptied ...
    assert ask(daq, "DATA:LAST? (@102)") == last                              # ... DATA:LAST? kept
    assert ask(daq, "INIT") is None                                           # a new scan
    assert ask(daq, "DATA:LAST? (@102)") is None
    assert daq.pop_error().startswith("-222,")
    assert ask(daq, "DATA:LAST? (@101,102)") is None                         # one channel only
    assert daq.pop_error().startswith("-222,")
    assert ask(daq, "DATA:LAST?") is None
    assert daq.pop_error() == '-109,"Missing parameter"'


def test_monitor_channel_state_and_data(daq):
    assert ask(daq, "ROUT:MON?") == b"#13(@)\n"
    assert ask(daq, "ROUT:MON:STAT?") == b"0\n"
    assert ask(daq, "ROUT:MON:DATA?") == b"+9.91000000E+37\n"       # Monitor off: not a number
    assert ask(daq, "ROUT:MON (@103)") is None
    assert ask(daq, "ROUT:MON?") == b"#16(@103)\n"
    assert ask(daq, "ROUT:MON:DATA?") == b"+9.91000000E+37\n"       # still off
    assert ask(daq, "ROUT:MON:STAT ON;STAT?") == b"1\n"
    reading = ask(daq, "ROUT:MON:DATA?")
    assert reading is not None and re.fullmatch(READING + b"\n", reading)
    scanned = ask(daq, "MEAS? (@103)")
    assert scanned is not None and abs(float(reading) - float(scanned)) < 1e-3   # the same unit's output
    assert ask(daq, "ROUT:MON:CHAN (@120)", "ROUT:MONITOR:CHANNEL?") == b"#16(@120)\n"
    assert ask(daq, "ROUT:MON (@101:102)") is None
    assert daq.pop_error().startswith("-222,")
    assert ask(daq, "*RST", "ROUT:MON?;:ROUT:MON:STAT?") == b"#13(@);0\n"


def test_a_running_scan_has_priority_the_monitor_shows_its_latest_reading(daq):
    ask(daq, "CONF:VOLT:DC (@101:102)", "TRIG:SOUR BUS", "TRIG:COUN 2", "ROUT:MON (@102)",
        "ROUT:MON:STAT ON", "INIT")
    assert ask(daq, "ROUT:MON:DATA?") == b"+9.91000000E+37\n"       # scanning, no reading yet
    ask(daq, "*TRG")
    daq.world.advance(1.0)                                            # one sweep taken, one to come
    assert ask(daq, "ROUT:MON:DATA?") == ask(daq, "DATA:LAST? (@102)")
    ask(daq, "ABOR")                                                  # idle: the Monitor measures
    reading = ask(daq, "ROUT:MON:DATA?")
    assert reading is not None and reading != b"+9.91000000E+37\n"


def test_monitoring_draws_nothing_from_the_scan_channels_streams():
    def scan(monitor: bool) -> bytes | None:
        daq = SimulatedStation(SimStationConfig(seed=9, fixture=FIXTURE)).fixture.daq
        if monitor:
            ask(daq, "ROUT:MON (@101)", "ROUT:MON:STAT ON", "ROUT:MON:DATA?", "ROUT:MON:DATA?")
        return ask(daq, "CONF:VOLT:DC (@101:102)", "TRIG:COUN 3", "READ?")

    assert scan(monitor=True) == scan(monitor=False)


# ---- E36312A status registers ------------------------------------------------------------------
CV, CC = 256, 1024  # Operation Status: bit 8 CV, bit 10 CC (E36100-series guide's table)


@pytest.fixture(scope="module")
def supply_station(station_factory):
    return station_factory(seed=2)


@pytest.fixture
def supply(supply_station):
    device = supply_station.supply
    ask(device, "*RST", "*CLS", "STAT:PRES")
    return device


def test_operation_condition_reports_cv_and_cc_over_the_outputs(supply):
    assert ask(supply, "STAT:OPER:COND?") == b"+0\n"                      # every output off
    assert ask(supply, "APPL CH2,15,0.1;OUTP ON,(@2)") is None
    assert ask(supply, "STAT:OPER:COND?") == b"+256\n"                    # CH2 in CV
    assert ask(supply, "CURR 0.005,(@2)") is None                          # below the unit's 16 mA draw
    assert ask(supply, "STATUS:OPERATION:CONDITION?") == b"+1024\n"       # CH2 in CC
    assert ask(supply, "APPL CH1,5,1;OUTP ON,(@1)") is None                # CH1 open circuit: CV
    assert ask(supply, "STAT:OPER:COND?") == b"+1280\n"
    assert ask(supply, "STAT:QUES:COND?") == b"+0\n"                      # no protection simulated


def test_event_registers_latch_rising_bits_and_clear_when_read(supply):
    assert ask(supply, "STAT:OPER?") == b"+0\n"
    ask(supply, "APPL CH2,15,0.1;OUTP ON,(@2)")
    assert ask(supply, "STAT:OPER:EVEN?") == b"+256\n"
    assert ask(supply, "STAT:OPER?") == b"+0\n"                           # the read cleared it
    ask(supply, "CURR 0.005,(@2)", "CURR 0.1,(@2)")                        # CC for a moment, CV again
    assert ask(supply, "STAT:OPER:COND?") == b"+256\n"
    assert ask(supply, "STAT:OPER?") == b"+1280\n"                        # both rose since the read
    assert ask(supply, "STAT:QUES?;:STAT:QUES:EVEN?") == b"+0;+0\n"


def test_enabled_events_set_the_status_byte_summaries_until_cls(supply):
    assert ask(supply, "STAT:OPER:ENAB 1024;ENAB?") == b"+1024\n"
    assert ask(supply, "STAT:QUES:ENAB 19;:STAT:QUES:ENAB?") == b"+19\n"
    ask(supply, "APPL CH2,15,0.1;OUTP ON,(@2)")
    assert ask(supply, "*STB?") == b"+0\n"                                # CV is not enabled
    ask(supply, "CURR 0.005,(@2)")
    assert ask(supply, "*STB?") == b"+128\n"                              # OPER summary (bit 7)
    assert ask(supply, "*CLS") is None
    assert ask(supply, "*STB?") == b"+0\n"                                # the event register cleared
    assert ask(supply, "STAT:OPER:ENAB?") == b"+1024\n"                   # ... its enable kept
    assert ask(supply, "STAT:PRES") is None
    assert ask(supply, "STAT:OPER:ENAB?;:STAT:QUES:ENAB?") == b"+0;+0\n"
    assert ask(supply, "STAT:OPER:ENAB 32768") is None
    assert supply.pop_error().startswith("-222,")


@settings(max_examples=30, deadline=None)
@given(st.lists(st.tuples(st.integers(1, 3), st.booleans(), st.sampled_from([0.005, 0.5])), min_size=1, max_size=8))
def test_the_operation_register_agrees_with_each_outputs_summary_and_latches_every_rise(supply_station, steps):
    supply = supply_station.supply
    ask(supply, "*RST", "*CLS", "APPL CH1,5,1;APPL CH2,15,0.1;APPL CH3,15,0.1")
    assert ask(supply, "STAT:OPER?") is not None  # start from an empty event register
    previous, latched = 0, 0
    commands = [c for channel, on, limit in steps
                for c in (f"CURR {limit},(@{channel})", f"OUTP {'ON' if on else 'OFF'},(@{channel})")]
    for command in commands:  # every command is a moment the condition is seen
        ask(supply, command)
        modes = [int(ask(supply, f"STAT:OPER:INST:ISUM{n}:COND?") or b"-1") for n in (1, 2, 3)]
        expected = (CV if 2 in modes else 0) | (CC if 1 in modes else 0)  # per output: 2 CV, 1 CC
        assert ask(supply, "STAT:OPER:COND?") == f"+{expected}\n".encode()
        latched |= expected & ~previous
        previous = expected
    assert ask(supply, "STAT:OPER?") == f"+{latched}\n".encode()
    assert ask(supply, "STAT:QUES:COND?;:STAT:QUES?") == b"+0;+0\n"


# ---- Watlow F4T registers ----------------------------------------------------------------------
@pytest.fixture(scope="module")
def chamber_sim():
    with SimulatedStation(only={"chamber"}) as station:
        yield station


@pytest.fixture(scope="module")
def modbus(chamber_sim):
    host, port = chamber_sim.resources()["chamber"][len("modbus://"):].rsplit(":", 1)
    client = ModbusTcpClient(host, port=int(port), timeout=2.0, retries=0)
    assert client.connect()
    yield client
    client.close()


def f32(words: list[int]) -> float:
    """The F4T's float: low word first, each word big-endian."""
    return float(struct.unpack(">f", struct.pack(">HH", words[1], words[0]))[0])


def f32_words(value: float) -> list[int]:
    high, low = struct.unpack(">HH", struct.pack(">f", value))
    return [low, high]


def read(client: ModbusTcpClient, address: int, count: int = 1) -> list[int]:
    reply = client.read_holding_registers(address, count=count)
    assert not reply.isError(), (address, reply)
    return list(reply.registers)


def refused(reply) -> int:
    assert reply.isError()
    return int(reply.exception_code)


def advance(sim: SimulatedStation, seconds: float) -> None:
    sim.server.call(sim.world.advance, seconds)


def test_part_number_is_one_character_per_register_on_the_wire(chamber_sim):
    """Raw Modbus TCP: read holding registers 16..30 (function 03) and the exact reply bytes."""
    host, port = chamber_sim.resources()["chamber"][len("modbus://"):].rsplit(":", 1)
    request = struct.pack(">HHHBBHH", 0x0701, 0, 6, 1, 3, 16, 15)
    body = bytes([3, 30]) + b"".join(b"\x00" + ch.encode("ascii") for ch in PART_NUMBER)
    with socket.create_connection((host, int(port)), timeout=2.0) as s:
        s.sendall(request)
        reply = b""
        while len(reply) < 7 + len(body):
            chunk = s.recv(4096)
            assert chunk
            reply += chunk
    assert reply == struct.pack(">HHHB", 0x0701, 0, 1 + len(body), 1) + body


def test_a_client_that_chrs_each_register_reads_the_part_number(modbus):
    words = read(modbus, 16, 15)
    assert all(w < 256 for w in words)                       # chr() on each never fails (Python 2's)
    part = "".join(chr(w) for w in words if w != 0)          # ESPEC's read_holding_string
    assert part == PART_NUMBER
    assert part[6] == "A" and part[11] == "1"                # ESPEC: six alarms, no profiles; one loop


@pytest.mark.parametrize("n", [3, 4, 5, 6])
def test_alarms_3_to_6_have_alarm_1s_registers_at_the_f4t_defaults(modbus, n):
    base = 1330 + 100 * (n - 1)
    assert read(modbus, base) == [62]                         # type Off
    assert read(modbus, base + 2) == [13]                     # sides Both
    assert f32(read(modbus, base + 4, 2)) == pytest.approx(148.9, abs=1e-4)
    assert f32(read(modbus, base + 6, 2)) == 0.0
    assert f32(read(modbus, base + 8, 2)) == pytest.approx(0.6, abs=1e-6)
    assert read(modbus, base + 12) == [60]                    # non-latching
    assert read(modbus, base + 26) == [61]                    # state None
    assert [read(modbus, 1356 + 100 * i)[0] in (88, 61, 12) for i in range(6)] == [True] * 6  # ESPEC: inactive


@settings(max_examples=20, deadline=None)
@given(n=st.integers(3, 6), high_c=st.floats(-50.0, 100.0, width=32))
def test_a_process_alarm_3_to_6_watches_the_air_and_unlatched_clears_itself(modbus, n, high_c):
    base = 1330 + 100 * (n - 1)
    assert not modbus.write_registers(base + 4, f32_words(high_c)).isError()
    assert not modbus.write_registers(base + 6, f32_words(-60.0)).isError()
    assert not modbus.write_register(base, 76).isError()      # Process
    air_c = f32(read(modbus, 2820, 2))
    expected = 7 if air_c > high_c else 61                     # Alarm High, or None
    assert read(modbus, base + 26) == [expected]
    assert not modbus.write_registers(base + 4, f32_words(148.9)).isError()
    assert read(modbus, base + 26) == [61]                     # non-latching: gone with its cause
    assert not modbus.write_register(base, 62).isError()
    assert refused(modbus.write_register(base + 2, 37)) == 3   # sides other than Both: not simulated


def test_loop_power_is_read_only_and_follows_the_loop(chamber_sim, modbus):
    assert read(modbus, 2808, 2) == [0, 0]                     # standby: 0.0 %
    assert refused(modbus.write_registers(2808, f32_words(10.0))) == 2
    assert read(modbus, 2784, 2) == [0, 0]                     # manual power 0.0 %
    assert not modbus.write_registers(2784, f32_words(-40.0)).isError()
    assert read(modbus, 2784, 2) == [0x0000, 0xC220]           # -40.0 = 0xC2200000
    assert refused(modbus.write_registers(2784, f32_words(150.0))) == 3
    assert not modbus.write_registers(2782, f32_words(180.0)).isError()
    assert not modbus.write_register(2730, 10).isError()       # Auto
    advance(chamber_sim, 20 * 60.0)
    assert read(modbus, 2808, 2) == [0x0000, 0x42C8]           # 100.0 %: heating at the plant's rate
    advance(chamber_sim, 3 * 3600.0)
    # holding 180 °C: the loss to the 23 °C lab, (180 − 23)/2700 s, over the 4 °C/min heating rate
    assert f32(read(modbus, 2808, 2)) == pytest.approx(100.0 * (157.0 / 2700.0) / (4.0 / 60.0), rel=1e-4)
    assert not modbus.write_register(2730, 62).isError()
    assert read(modbus, 2808, 2) == [0, 0]
    assert not modbus.write_registers(2782, f32_words(23.0)).isError()


def clock_of(words: list[int]) -> datetime.datetime:
    """ESPEC's get_datetime: 12 registers from 14664, the even ones hour, minute, second, month,
    day, year."""
    return datetime.datetime(hour=words[0], minute=words[2], second=words[4], month=words[6],
                             day=words[8], year=words[10])


def test_the_clock_reads_in_one_block_and_runs_with_the_world(chamber_sim, modbus):
    # ESPEC's set_datetime: one register each, hour, minute, second, month, day, year
    for address, value in zip(range(14664, 14676, 2), (0, 0, 0, 1, 1, 2025)):
        assert not modbus.write_registers(address, [value]).isError()
    words = read(modbus, 14664, 12)
    assert words == [0, 0, 0, 0, 0, 0, 1, 0, 1, 0, 2025, 0]     # the odd registers read 0
    advance(chamber_sim, 3661.0)
    assert clock_of(read(modbus, 14664, 12)) == datetime.datetime(2025, 1, 1, 1, 1, 1)
    assert refused(modbus.write_register(14665, 7)) == 2        # between the fields: read-only
    assert refused(modbus.write_register(14664, 24)) == 3       # hour 24
    assert refused(modbus.write_register(14672, 32)) == 3       # day 32
    assert not modbus.write_register(14670, 2).isError()        # February ...
    assert refused(modbus.write_register(14672, 29)) == 3       # ... of 2025 has no 29th


@settings(max_examples=25, deadline=None)
@given(st.datetimes(min_value=datetime.datetime(2000, 1, 1), max_value=datetime.datetime(2099, 12, 31, 23, 59, 59)))
def test_a_written_date_reads_back(modbus, when):
    when = when.replace(microsecond=0)
    # year and month before the day, so that any valid day is inside its month when written
    for address, value in ((14674, when.year), (14670, when.month), (14672, when.day),
                           (14664, when.hour), (14666, when.minute), (14668, when.second)):
        assert not modbus.write_registers(address, [value]).isError(), (address, value)
    assert clock_of(read(modbus, 14664, 12)) == when
