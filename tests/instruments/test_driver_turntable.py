"""Dual-axis turntable driver: exact wire bytes of the ACUTROL-style language, status
decoding, waiting with the caller's clock, teardown safety, and pyvisa-sim."""

from __future__ import annotations

from typing import Any, cast

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.testing import SIM_YAML_DIR, FakeResource, assert_conforms
from instruments import (
    AxisFaultError,
    AxisLimits,
    AxisStatus,
    DualAxisTurntable,
    InstrumentError,
    PositionRateTable,
    RateTableAxis,
)
from instruments.base import open_resource


def make_table(**replies: Any) -> tuple[DualAxisTurntable, FakeResource]:
    fake = FakeResource(replies=replies)
    return DualAxisTurntable(fake, name="table"), fake


def test_constructor_does_no_io() -> None:
    table, fake = make_table()
    assert fake.written == [] and sorted(table.axis) == [1, 2]


@pytest.mark.parametrize("action, commands", [
    (lambda t: t.axis[1].move_to(90), [":MODE:POS 1", ":DEM:POS 1,90"]),
    (lambda t: t.axis[2].move_to(-45.5), [":MODE:POS 2", ":DEM:POS 2,-45.5"]),
    (lambda t: t.axis[2].set_rate(-10.5), [":MODE:RATE 2", ":DEM:RATE 2,-10.5"]),
    (lambda t: t.axis[1].stop(), [":STOP 1"]),
    (lambda t: setattr(t.axis[1], "mode", "off"), [":MODE:OFF 1"]),
    (lambda t: setattr(t.axis[1], "rate_limit_dps", 100), [":LIM:RATE 1,100"]),
    (lambda t: setattr(t.axis[2], "accel_limit_dps2", 50.5), [":LIM:ACC 2,50.5"]),
    (lambda t: setattr(t.axis[1], "position_demand_deg", 180), [":DEM:POS 1,180"]),
    (lambda t: setattr(t.axis[2], "rate_demand_dps", 5), [":DEM:RATE 2,5"]),
    (lambda t: t.interlock_close(), [":INT:CLOS"]),
    (lambda t: t.interlock_open(), [":INT:OPEN"]),
    (lambda t: t.interlock_reset(), [":INT:RES"]),
])
def test_commands_write_exact_bytes_then_check_errors_once(
        action: Any, commands: list[str]) -> None:
    table, fake = make_table()
    action(table)
    assert fake.written == commands + ["SYST:ERR?"]


def test_readbacks_parse_replies() -> None:
    table, fake = make_table(**{
        ":READ:POS? 1": "+9.00000000E+01", ":READ:RATE? 2": "-1.05E+01", ":READ:ACC? 2": "+2.5E+00",
        ":MODE? 1": "POS", ":DEM:POS? 1": "+9.0E+01", ":LIM:RATE? 2": "+5.0E+02", ":INT?": "1",
        ":STAT? 1": "5"})
    ax1, ax2 = table.axis[1], table.axis[2]
    assert (ax1.position_deg, ax2.rate_dps, ax2.accel_dps2) == (90.0, -10.5, 2.5)
    assert (ax1.mode, ax1.position_demand_deg, ax2.rate_limit_dps) == ("POS", 90.0, 500.0)
    assert table.interlock_closed is True
    assert ax1.status == AxisStatus.from_bits(5)
    assert fake.written == [":READ:POS? 1", ":READ:RATE? 2", ":READ:ACC? 2", ":MODE? 1",
                            ":DEM:POS? 1", ":LIM:RATE? 2", ":INT?", ":STAT? 1"]


@given(st.integers(0, 63))
@settings(deadline=None)
def test_status_bits_decode(raw: int) -> None:
    s = AxisStatus.from_bits(raw)
    flags = [s.in_position, s.moving, s.at_rate, s.limit_reached, s.interlock_open, s.fault]
    assert sum(int(f) << k for k, f in enumerate(flags)) == raw and s.raw == raw


@pytest.mark.parametrize("action", [
    lambda t: t.axis[1].move_to(400), lambda t: t.axis[2].set_rate(501),
    lambda t: t.axis[1].set_rate(float("nan")), lambda t: setattr(t.axis[1], "mode", "JOG"),
    lambda t: setattr(t.axis[2], "rate_limit_dps", -1),
    lambda t: setattr(t.axis[1], "accel_limit_dps2", 1e4),
    lambda t: t.axis[1].move_to("90"),
])
def test_invalid_demands_raise_before_the_wire(action: Any) -> None:
    table, fake = make_table()
    with pytest.raises(ValueError):
        action(table)
    assert fake.written == []


def test_custom_limits_widen_what_the_driver_lets_through() -> None:
    fake = FakeResource()
    table = DualAxisTurntable(fake, limits={2: AxisLimits(max_rate_dps=2000.0)})
    table.axis[2].set_rate(1500)
    assert ":DEM:RATE 2,1500" in fake.written
    with pytest.raises(ValueError):
        DualAxisTurntable(FakeResource(), limits={3: AxisLimits()})


def test_instrument_error_on_move() -> None:
    table, fake = make_table()
    fake.error_queue.append('-221,"Settings conflict; interlock open"')
    with pytest.raises(InstrumentError) as info:
        table.axis[1].move_to(10)
    assert info.value.code == -221
    assert info.value.command == ":MODE:POS 1; :DEM:POS 1,10"


def scripted_status(fake: FakeResource, axis: int, sequence: list[int]) -> None:
    replies = iter(sequence)
    fake.replies[f":STAT? {axis}"] = lambda _: str(next(replies))


def test_wait_in_position_polls_with_the_callers_wait() -> None:
    table, fake = make_table()
    scripted_status(fake, 1, [2, 2, 2, 1])
    waited: list[float] = []
    status = table.axis[1].wait_in_position(waited.append, timeout_s=5.0, poll_s=0.25)
    assert status.in_position and not status.moving
    assert waited == [0.25, 0.25, 0.25]
    assert fake.written == [":STAT? 1"] * 4


def test_wait_in_position_times_out_after_the_timeout() -> None:
    table, fake = make_table(**{":STAT? 2": "2"})
    waited: list[float] = []
    with pytest.raises(TimeoutError):
        table.axis[2].wait_in_position(waited.append, timeout_s=1.0, poll_s=0.3)
    assert sum(waited) == pytest.approx(1.0)
    assert waited[-1] == pytest.approx(0.1)  # the last step is cut to the timeout


def test_wait_at_rate() -> None:
    table, fake = make_table()
    scripted_status(fake, 2, [2, 6])
    assert table.axis[2].wait_at_rate(lambda s: None, timeout_s=1.0).at_rate


@pytest.mark.parametrize("bits, what", [(32 | 2, "fault"), (16, "interlock open")])
def test_wait_raises_on_fault_or_open_interlock(bits: int, what: str) -> None:
    table, _ = make_table(**{":STAT? 1": str(bits)})
    with pytest.raises(AxisFaultError, match=what) as info:
        table.axis[1].wait_in_position(lambda s: None, timeout_s=10.0)
    assert info.value.status.raw == bits and info.value.axis == 1


def test_wait_validates_its_arguments() -> None:
    table, fake = make_table()
    with pytest.raises(ValueError):
        table.axis[1].wait_in_position(cast(Any, None), timeout_s=1.0)  # not a wait: refused
    with pytest.raises(ValueError):
        table.axis[1].wait_in_position(lambda s: None, timeout_s=-1.0)
    assert fake.written == []


def test_stop_all_reaches_every_axis_even_if_one_fails() -> None:
    table, fake = make_table()
    fake.error_queue.append('-300,"Device-specific error; drive fault"')
    failures = table.stop_all()
    assert [f.axis for f in failures] == [1]
    assert isinstance(failures[0].error, InstrumentError)
    assert fake.written == [":STOP 1", "SYST:ERR?", "SYST:ERR?", ":STOP 2", "SYST:ERR?"]


def test_stop_all_survives_an_io_failure(monkeypatch: pytest.MonkeyPatch) -> None:
    table, fake = make_table()
    original = fake.write

    def flaky_write(message: str) -> int:
        if message == ":STOP 1":
            raise OSError("connection reset")
        return original(message)

    monkeypatch.setattr(fake, "write", flaky_write)
    failures = table.stop_all()
    assert [f.axis for f in failures] == [1] and isinstance(failures[0].error, OSError)
    assert ":STOP 2" in fake.written


def test_snapshot_records_both_axes() -> None:
    replies = {f"{q} {n}": r for n in (1, 2) for q, r in (
        (":MODE?", "POS"), (":LIM:RATE?", "+1.0E+02"), (":LIM:ACC?", "+5.0E+01"),
        (":READ:POS?", "+0.0E+00"))}
    table, _ = make_table(**replies, **{"*IDN?": "Maker,Table,1,1.0"})
    snap = table.snapshot()
    assert snap["idn"]["model"] == "Table"
    assert snap["axes"][2] == {"mode": "POS", "rate_limit_dps": 100.0, "accel_limit_dps2": 50.0,
                               "position_deg": 0.0}


def test_driver_fits_the_table_protocols() -> None:
    table, fake = make_table()
    assert_conforms(table, PositionRateTable)
    assert_conforms(table.axis[1], RateTableAxis)
    assert fake.written == []


@pytest.fixture()
def sim_table() -> Any:
    resource = open_resource("TCPIP0::127.0.0.1::5027::SOCKET",
                             backend=f"{SIM_YAML_DIR / 'turntable.yaml'}@sim")
    yield DualAxisTurntable(resource)
    resource.close()


def test_pyvisa_sim_vocabulary_round_trips(sim_table: DualAxisTurntable) -> None:
    sim_table.interlock_reset()
    sim_table.interlock_close()
    assert sim_table.interlock_closed
    sim_table.axis[1].move_to(90)
    sim_table.axis[2].set_rate(-10.5)
    sim_table.axis[2].rate_limit_dps = 100
    assert (sim_table.axis[1].mode, sim_table.axis[1].position_demand_deg) == ("POS", 90.0)
    assert (sim_table.axis[2].mode, sim_table.axis[2].rate_demand_dps) == ("RATE", -10.5)
    assert sim_table.axis[2].rate_limit_dps == 100.0
    assert sim_table.axis[1].wait_in_position(lambda s: None, timeout_s=1.0).raw == 1
    assert sim_table.axis[2].wait_at_rate(lambda s: None, timeout_s=1.0).at_rate
    assert sim_table.axis[1].position_deg == 90.0
    assert sim_table.stop_all() == []


def test_pyvisa_sim_error_queue_reaches_the_driver(sim_table: DualAxisTurntable) -> None:
    sim_table.resource.write(":DEM:POS 1,720")  # beyond the controller's range
    with pytest.raises(InstrumentError) as info:
        sim_table.check_errors(":DEM:POS 1,720")
    assert info.value.code == -100
