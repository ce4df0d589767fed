"""Keysight E36312A / E36313A triple-output DC power supply.

Written from the Keysight E36300 Series programming guide.  Each output is a channel
object (``supply.ch[1]`` .. ``supply.ch[3]``); commands address it with a channel list
``(@n)``.  Voltages in volts, currents in amperes.  The allowed setpoint ranges are the
rated ranges of the model named by ``*IDN?``:

=========  ==============  ==============  ==============
model      ch1             ch2             ch3
=========  ==============  ==============  ==============
E36312A    0-6 V, 0-5 A    0-25 V, 0-1 A   0-25 V, 0-1 A
E36313A    0-6 V, 0-10 A   0-25 V, 0-2 A   0-25 V, 0-2 A
=========  ==============  ==============  ==============
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from .base import (
    InstrumentChannel,
    InstrumentReplyError,
    SCPIInstrument,
    UnsupportedInstrumentError,
    boolean,
    channel_list,
    control,
    format_number,
    in_range,
    measurement,
    parse_bool,
    parse_float,
    read_settings,
)
from .protocols import SafeOrder

ON_OFF = {True: "ON", False: "OFF"}


@dataclass(frozen=True)
class ChannelRating:
    """Rated (programmable) range of one output."""

    max_voltage_v: float
    max_current_a: float


#: Rated ranges per model and channel (E36300 series data sheet).
CHANNEL_RATINGS: Mapping[str, Mapping[int, ChannelRating]] = {
    "E36312A": {1: ChannelRating(6.0, 5.0), 2: ChannelRating(25.0, 1.0),
                3: ChannelRating(25.0, 1.0)},
    "E36313A": {1: ChannelRating(6.0, 10.0), 2: ChannelRating(25.0, 2.0),
                3: ChannelRating(25.0, 2.0)},
}


class SupplyOutput(InstrumentChannel):
    """One output of the supply; settings validated against this output's rating."""

    field_name = "ch"

    def __init__(self, parent: KeysightE36312A, number: int, rating: ChannelRating) -> None:
        super().__init__(parent, number)
        self.rating = rating

    @property
    def voltage_range_v(self) -> tuple[float, float]:
        return (0.0, self.rating.max_voltage_v)

    @property
    def current_range_a(self) -> tuple[float, float]:
        return (0.0, self.rating.max_current_a)

    voltage_setpoint_v = control(
        "VOLT? (@{ch})", "VOLT {value},(@{ch})",
        "Programmed output voltage in volts, 0 to the output's rated voltage.",
        validator=in_range, values=lambda out: out.voltage_range_v,
    )
    current_limit_a = control(
        "CURR? (@{ch})", "CURR {value},(@{ch})",
        "Current limit in amperes, 0 to the output's rated current.",
        validator=in_range, values=lambda out: out.current_range_a,
    )
    output_enabled = control(
        "OUTP? (@{ch})", "OUTP {value},(@{ch})",
        "Output on (True) or off (False).",
        validator=boolean, set_map=ON_OFF, parse=parse_bool,
    )
    measured_voltage_v = measurement("MEAS:VOLT? (@{ch})", "Measured output voltage, volts.")
    measured_current_a = measurement("MEAS:CURR? (@{ch})", "Measured output current, amperes.")

    snapshot_settings = ("voltage_setpoint_v", "current_limit_a", "output_enabled")

    def apply(self, voltage_v: float, current_a: float) -> None:
        """``APPL CHn,<v>,<i>``: set voltage and current limit in one command (both
        validated first)."""
        v = in_range(self.label("voltage_v"), voltage_v, self.voltage_range_v)
        i = in_range(self.label("current_a"), current_a, self.current_range_a)
        self.configure_command(f"APPL CH{self.number},{format_number(v)},{format_number(i)}")


class KeysightE36312A(SCPIInstrument):
    """Keysight E36312A or E36313A triple-output supply (model read from ``*IDN?``).

    ``supply.ch[n]`` is output ``n``; supply-wide commands take channel lists.
    """

    #: the supply's MEAS? reads its output back (no trigger model): safe to re-send
    idempotent_queries = SCPIInstrument.idempotent_queries | {"MEAS:VOLT?", "MEAS:CURR?"}
    #: first in a teardown: what it feeds (a unit under test, a gyro's stream) stops with it
    safe_order = SafeOrder.POWER
    safe_action = "off"

    def __init__(self, resource: Any, name: str | None = None) -> None:
        super().__init__(resource, name)
        model = self.idn.model.upper()
        if model not in CHANNEL_RATINGS:
            raise UnsupportedInstrumentError(
                f"{self.name}: model {self.idn.model!r} is not one of {tuple(CHANNEL_RATINGS)}"
            )
        self.model = model
        self.ch: dict[int, SupplyOutput] = {
            n: SupplyOutput(self, n, rating) for n, rating in CHANNEL_RATINGS[model].items()
        }

    def _channels(self, channels: Iterable[int] | None) -> list[int]:
        chosen = list(self.ch) if channels is None else list(channels)
        for n in chosen:
            if n not in self.ch:
                raise ValueError(
                    f"channel {n!r} does not exist; allowed channels {sorted(self.ch)}")
        return chosen

    def set_outputs(self, channels: Iterable[int] | None, enabled: bool) -> None:
        """``OUTP ON|OFF,(@1,2,...)``: switch several outputs in one command (``None``:
        all outputs)."""
        state = ON_OFF[boolean("enabled", enabled)]
        self.configure_command(f"OUTP {state},{channel_list(self._channels(channels))}")

    def outputs_off(self) -> None:
        """Switch every output off (the safe state for teardown)."""
        self.set_outputs(None, False)

    def make_safe(self) -> None:
        """Teardown: :meth:`outputs_off`."""
        self.outputs_off()

    def snapshot_details(self) -> dict[str, Any]:
        return {"channels": {n: read_settings(out, out.snapshot_settings)
                             for n, out in self.ch.items()}}

    def measure_voltages_v(self, channels: Iterable[int] | None = None) -> tuple[float, ...]:
        """``MEAS:VOLT? (@..)``: output voltages of ``channels`` in one query, volts."""
        return self._measure_list("MEAS:VOLT?", self._channels(channels))

    def measure_currents_a(self, channels: Iterable[int] | None = None) -> tuple[float, ...]:
        """``MEAS:CURR? (@..)``: output currents of ``channels`` in one query, amperes."""
        return self._measure_list("MEAS:CURR?", self._channels(channels))

    def _measure_list(self, query: str, channels: list[int]) -> tuple[float, ...]:
        reply = self.query(f"{query} {channel_list(channels)}")
        values = tuple(parse_float(v) for v in reply.split(","))
        if len(values) != len(channels):
            raise InstrumentReplyError(
                f"{self.name}: {query} for {len(channels)} channels returned {reply!r}"
            )
        return values
