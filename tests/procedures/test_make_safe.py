"""``procedures.common.make_safe``: every instrument of the station brought to rest by its own
``make_safe``, power first, every one tried even when some fail, one error naming them all."""

from __future__ import annotations

from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import cast

import numpy as np
import pytest
import serial

from bench.app.station import Station, builtin_sim_config
from bench.core.procedure import Context
from instruments.fog import SerialGyro
from instruments.protocols import SafeOrder
from procedures.common import make_safe


@dataclass
class Fake:
    """An instrument that records when it was made safe, and may fail to be."""

    safe_order: SafeOrder
    safe_action: str
    calls: list[str] = field(default_factory=list)
    name: str = ""
    error: Exception | None = None

    def make_safe(self) -> None:
        self.calls.append(self.name)
        if self.error is not None:
            raise self.error


def context(**instruments: Fake) -> Context:
    return cast(Context, SimpleNamespace(instruments=instruments))


def station_of_fakes(calls: list[str], failing: dict[str, Exception]) -> dict[str, Fake]:
    kinds = {"dmm": (SafeOrder.ACQUISITION, "abort"), "turntable": (SafeOrder.MOTION, "stop"),
             "supply": (SafeOrder.POWER, "off"), "gyro": (SafeOrder.ACQUISITION, "stop"),
             "shaker": (SafeOrder.MOTION, "stop"), "dmm_temp": (SafeOrder.ACQUISITION, "abort")}
    return {name: Fake(order, action, calls, name, failing.get(name)) for name, (order, action) in kinds.items()}


def test_power_first_then_acquisitions_then_motion_each_in_station_order() -> None:
    calls: list[str] = []
    make_safe(context(**station_of_fakes(calls, {})))
    assert calls == ["supply", "dmm", "gyro", "dmm_temp", "turntable", "shaker"]


def test_every_instrument_is_tried_and_one_error_names_every_failure() -> None:
    calls: list[str] = []
    failing = {"supply": TimeoutError("supply: no reply to 'OUTP OFF'"),
               "turntable": RuntimeError("axis 2: -221"), "shaker": OSError("connection reset")}
    with pytest.raises(RuntimeError) as info:
        make_safe(context(**station_of_fakes(calls, failing)))
    assert calls == ["supply", "dmm", "gyro", "dmm_temp", "turntable", "shaker"]
    assert str(info.value) == ("supply off: supply: no reply to 'OUTP OFF'; turntable stop: axis 2: -221; "
                               "shaker stop: connection reset")


def test_an_empty_station_has_nothing_to_make_safe() -> None:
    make_safe(context())


def test_the_simulated_station_is_left_at_rest_with_both_gyro_streams_ended() -> None:
    """On the real wire: the station's gyro streams from the supply (silenced by it going off
    first), the rig's LF gyro from its own supply (stopped by command), a table turns, the
    meters acquire, the shaker runs — one make_safe leaves everything at rest, no error."""
    with Station(builtin_sim_config(), seed=3) as station:
        inst, sim = station.instruments, station.sim
        assert sim is not None
        supply = inst["supply"]
        supply.ch[1].apply(5.0, 1.0)
        supply.set_outputs([1], True)
        station.clock.sleep(10.0)  # both units booted
        gyro, lf = inst["gyro"], inst["lf_gyro"]
        for line in (gyro, lf):
            line.configure(rate_hz=500)
            line.start()
            line.read_frames(100, wait=station.clock.sleep)
        inst["turntable"].interlock_close()
        inst["turntable"].axis[1].set_rate(10.0)
        inst["dmm"].configure_timed_trace(1000, 0.01, nplc=0.2)
        inst["dmm"].initiate()
        inst["shaker"].set_random_profile(grms=1.0)
        ctx = cast(Context, SimpleNamespace(instruments=inst))
        make_safe(ctx)
        assert not gyro.streaming and not lf.streaming
        station.clock.sleep(120.0)  # anything coasting comes to rest
        now = sim.world.now
        assert sim.gyro_line.state == "OFF" and sim.angular.lf_line.state == "STOPPED"
        assert not any(ch.output for ch in sim.supply.channels.values())
        assert sim.dmm.state == "IDLE"
        assert [float(a.rate_dps(now)) for a in sim.table.axes] == [0.0, 0.0]
        assert float(sim.shaker.envelope_grms(np.array([now]))[0]) == 0.0
        assert sim.angular.controller.motion.at_rest(now)


def test_a_gyro_not_streaming_is_left_alone(sim_station) -> None:
    port = serial.serial_for_url(sim_station.resources()["lf_gyro"], baudrate=921600, timeout=2.0)
    try:
        gyro = SerialGyro(port, name="lf_gyro")
        gyro.make_safe()  # nothing started by this driver: nothing sent
        port.write(b"$ID?\r\n")
        assert port.readline().startswith(b"$ID,")  # the first reply: no $OK,STOP before it
    finally:
        port.close()
