"""Simulated Keysight E36312A triple-output DC power supply (E36300-series command set).

Channel 1: 0–6 V / 0–5 A; channels 2 and 3: 0–25 V / 0–1 A (E36312A data sheet).  Loads are
callables wired by the station (``attach_load``) returning the current drawn at a voltage;
when the load wants more than the current limit the channel goes into constant-current mode
and its terminal voltage collapses to ``limit × load resistance``.  Every change of an
output's terminal voltage is announced to listeners at ``world.now`` — the accelerometer
uses that to know when it was powered (t = 0 of a start-up test).

Status (SCPI ``STATus`` subsystem): the Operation and Questionable condition registers
summarise the three outputs (a bit is set while any output has the condition); their event
registers latch a condition bit when it rises (the preset transition filters: positive on,
negative off), sampled at every change of a setpoint or an output and whenever the status is
read; an enabled event sets the Status Byte's OPER (bit 7) or QUES (bit 3) summary.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from sim.devices.lifecycle import scpi_power_on
from sim.scpi import Args, ScpiDevice, ScpiError, format_int, format_number
from sim.world import World

RATINGS = {  # channel: (max volts, max amps) — E36312A
    1: (6.0, 5.0),
    2: (25.0, 1.0),
    3: (25.0, 1.0),
}


#: Operation status bits: CV 8, CC 10 (the E36100-series programming guide's "Operation Status
#: Register" table; the E36300 guide's status chapter uses the same register model — assumed the
#: same bits).  CAL (0) and WTG (5) never occur here: no calibration, no triggered setpoints.
OPER_CV, OPER_CC = 1 << 8, 1 << 10
#: Questionable status bits: OV 0, OC 1, OT 4, UNR 10 (same table).  Protection, temperature and
#: regulation faults are not simulated, so none of them is ever set.
QUES_OV, QUES_OC, QUES_OT, QUES_UNR = 1 << 0, 1 << 1, 1 << 4, 1 << 10
#: STATus:...:ENABle accepts 0..32767 (bit 15 is never used, SCPI-1999 Vol. 1 §9.2)
STATUS_ENABLE_MAX = 32767


#: output names accepted by APPL / INST:SEL (E36312A: P6V, P25V, N25V are aliases of CH1..3)
CHANNEL_NAMES = {"CH1": 1, "CH2": 2, "CH3": 3, "P6V": 1, "P25V": 2, "N25V": 3}


def channel_named(text: str) -> int:
    """Channel number of an output name (any case), else -224 naming the allowed names."""
    number = CHANNEL_NAMES.get(text.strip().upper())
    if number is None:
        raise ScpiError(-224, f"channel {text!r} not in CH1|CH2|CH3 (or P6V|P25V|N25V)")
    return number


@dataclass
class Channel:
    number: int
    v_max: float
    i_max: float
    voltage_v: float = 0.0
    current_limit_a: float = 0.0
    output: bool = False
    #: load(t_s, volts) -> amps drawn; None = open circuit
    load: Callable[[float, float], float] | None = None

    def reset(self) -> None:
        self.voltage_v, self.current_limit_a, self.output = 0.0, self.i_max, False


@dataclass
class ChannelReading:
    voltage_v: float
    current_a: float
    mode: str  # "CV", "CC" or "OFF"


class PowerSupply(ScpiDevice):
    """E36312A view of the world; ``listeners`` get ``(t_s, channel, terminal_volts)``."""

    fault_kinds: tuple[str, ...] = ("power",)

    def __init__(self, world: World, serial: str = "MY61000123") -> None:
        super().__init__(("Keysight Technologies", "E36312A", serial, "2.1.0-1.0.4-1.12"),
                         options="0")
        self.world = world
        self.channels = {n: Channel(n, v, i, current_limit_a=i) for n, (v, i) in RATINGS.items()}
        self.listeners: list[Callable[[float, int, float], None]] = []
        self._selected = 1
        # the SCPI Operation / Questionable registers: event, enable, the condition last sampled
        self.oper_event = self.oper_enable = self._oper_seen = 0
        self.ques_event = self.ques_enable = self._ques_seen = 0
        self._register()

    # -- physics ----------------------------------------------------------------------
    def attach_load(self, channel: int, load: Callable[[float, float], float]) -> None:
        self.channels[channel].load = load

    def read(self, channel: int) -> ChannelReading:
        """Terminal voltage and current now (constant-voltage or constant-current)."""
        ch = self.channels[channel]
        if not ch.output:
            return ChannelReading(0.0, 0.0, "OFF")
        if ch.load is None:
            return ChannelReading(ch.voltage_v, 0.0, "CV")
        drawn = ch.load(self.world.now, ch.voltage_v)
        if drawn <= ch.current_limit_a or drawn <= 0:
            return ChannelReading(ch.voltage_v, drawn, "CV")
        # Constant current: the load sees limit × its resistance at the set voltage.
        resistance = ch.voltage_v / drawn
        return ChannelReading(ch.current_limit_a * resistance, ch.current_limit_a, "CC")

    def _changed(self) -> None:
        for n in self.channels:
            volts = self.read(n).voltage_v
            for listener in self.listeners:
                listener(self.world.now, n, volts)
        self._sample_status()

    # -- status registers -----------------------------------------------------------------
    def operation_condition(self) -> int:
        """``STAT:OPER:COND?`` now: CV (256) while an output is on in constant voltage, CC (1024)
        while one is in constant current."""
        modes = {self.read(n).mode for n in self.channels}
        return (OPER_CV if "CV" in modes else 0) | (OPER_CC if "CC" in modes else 0)

    def questionable_condition(self) -> int:
        """``STAT:QUES:COND?`` now: 0 — no over-voltage, over-current or over-temperature
        protection is simulated and an output is always regulated (CV or CC)."""
        return 0

    def _sample_status(self) -> None:
        """Latch the condition bits that have risen since the last look into the event registers."""
        oper, ques = self.operation_condition(), self.questionable_condition()
        self.oper_event |= oper & ~self._oper_seen
        self.ques_event |= ques & ~self._ques_seen
        self._oper_seen, self._ques_seen = oper, ques

    def device_status_bits(self) -> int:
        """Status Byte QUES (bit 3) and OPER (bit 7): an enabled event is latched."""
        self._sample_status()
        return (0x08 if self.ques_event & self.ques_enable else 0) | \
               (0x80 if self.oper_event & self.oper_enable else 0)

    def clear_status(self) -> None:
        """``*CLS`` also clears the Operation and Questionable event registers (not the enables)."""
        super().clear_status()
        self.oper_event = self.ques_event = 0

    def reset(self) -> None:
        for ch in self.channels.values():
            ch.reset()
        self._selected = 1
        self._changed()

    # -- lifecycle (sim.devices.lifecycle) ------------------------------------------------
    def power_off(self) -> None:
        """Power lost: every output off (the setpoints are kept until power-on resets them)."""
        for ch in self.channels.values():
            ch.output = False
        self._changed()

    def power_on(self) -> None:
        scpi_power_on(self)
        self.oper_enable = self.ques_enable = 0  # the enables come back cleared at power-on

    # -- SCPI vocabulary --------------------------------------------------------------
    def _channels_from(self, args: Args, index: int) -> list[int]:
        if args.count > index:
            chans = args.channel_list(index)
        else:
            chans = [self._selected]
        for c in chans:
            if c not in self.channels:
                raise ScpiError(-222, f"channel {c} not in 1..{len(self.channels)}")
        return chans

    def _register(self) -> None:
        def setpoints(args: Args, attr: str, lo: float, hi_attr: str) -> None:
            # validate every channel's value before changing any (no half-applied lists)
            chans = self._channels_from(args, 1)
            values = {c: args.number(0, min=lo, max=getattr(self.channels[c], hi_attr),
                                     default=0.0 if attr == "voltage_v" else
                                     getattr(self.channels[c], hi_attr))
                      for c in chans}
            for c, v in values.items():
                setattr(self.channels[c], attr, v)
            self._changed()

        def readback(args: Args, attr: str, hi_attr: str) -> str:
            word = args.keyword(0)
            if word in ("MIN", "MAX", "DEF"):
                chans = self._channels_from(args, 1)
                return ",".join(format_number(
                    {"MIN": 0.0, "MAX": getattr(self.channels[c], hi_attr),
                     "DEF": 0.0 if attr == "voltage_v" else getattr(self.channels[c], hi_attr)
                     }[word]) for c in chans)
            return ",".join(format_number(getattr(self.channels[c], attr))
                            for c in self._channels_from(args, 0))

        set_volt = lambda a: setpoints(a, "voltage_v", 0.0, "v_max")
        get_volt = lambda a: readback(a, "voltage_v", "v_max")
        set_curr = lambda a: setpoints(a, "current_limit_a", 0.0, "i_max")
        get_curr = lambda a: readback(a, "current_limit_a", "i_max")

        def set_outp(args: Args) -> None:
            state = args.boolean(0)
            for c in self._channels_from(args, 1):
                self.channels[c].output = state
            self.world.note(f"supply output {'on' if state else 'off'}")
            self._changed()

        def get_outp(args: Args) -> str:
            return ",".join("1" if self.channels[c].output else "0"
                            for c in self._channels_from(args, 0))

        def apply(args: Args) -> None:
            args.require_count(1, 3)
            ch = self.channels[channel_named(args.raw[0])]
            if args.count > 1:
                ch.voltage_v = args.number(1, min=0.0, max=ch.v_max, default=0.0)
            if args.count > 2:
                ch.current_limit_a = args.number(2, min=0.0, max=ch.i_max, default=ch.i_max)
            self._changed()

        def apply_q(args: Args) -> str:
            ch = self.channels[channel_named(args.raw[0]) if args.count else self._selected]
            return f'"{format_number(ch.voltage_v)},{format_number(ch.current_limit_a)}"'

        def meas_volt(args: Args) -> str:
            return ",".join(format_number(self.read(c).voltage_v)
                            for c in self._channels_from(args, 0))

        def meas_curr(args: Args) -> str:
            return ",".join(format_number(self.read(c).current_a)
                            for c in self._channels_from(args, 0))

        def inst_nsel(args: Args) -> None:
            self._selected = int(args.number(0, min=1, max=3))

        def inst_sel(args: Args) -> None:
            self._selected = channel_named(args.raw[0])

        def isum_condition(args: Args) -> str:
            # operation instrument summary of output n: 1 = constant current, 2 = constant
            # voltage, 0 = off (the E364xA's published bit values; assumed the same here)
            mode = self.read(args.suffixes[0]).mode
            return str({"CC": 1, "CV": 2}.get(mode, 0))

        self.command("[SOURce:]VOLTage[:LEVel][:IMMediate][:AMPLitude]", set=set_volt, query=get_volt)
        self.command("[SOURce:]CURRent[:LEVel][:IMMediate][:AMPLitude]", set=set_curr, query=get_curr)
        self.command("OUTPut[:STATe]", set=set_outp, query=get_outp)
        self.command("APPLy", set=apply, query=apply_q)
        self.command("MEASure[:SCALar]:VOLTage[:DC]", query=meas_volt)
        self.command("MEASure[:SCALar]:CURRent[:DC]", query=meas_curr)
        self.command("INSTrument:NSELect", set=inst_nsel, query=lambda a: str(self._selected))
        self.command("INSTrument[:SELect]", set=inst_sel, query=lambda a: f"CH{self._selected}")
        self.command("STATus:OPERation:INSTrument:ISUMmary#:CONDition", query=isum_condition,
                     max_suffix=len(self.channels))

        def read_event(register: str) -> Callable[[Args], str]:
            def query(args: Args) -> str:  # reading an event register clears it
                args.require_count(0)
                self._sample_status()
                value = getattr(self, register)
                setattr(self, register, 0)
                return format_int(value)
            return query

        def enable(register: str) -> tuple[Callable[[Args], None], Callable[[Args], str]]:
            def set_(args: Args) -> None:
                args.require_count(1)
                setattr(self, register, args.integer(0, min=0, max=STATUS_ENABLE_MAX))

            def query(args: Args) -> str:
                args.require_count(0)
                return format_int(getattr(self, register))
            return set_, query

        def condition(read: Callable[[], int]) -> Callable[[Args], str]:
            def query(args: Args) -> str:
                args.require_count(0)
                self._sample_status()
                return format_int(read())
            return query

        def preset(args: Args) -> None:  # STAT:PRES: the enables cleared (E36100 guide)
            args.require_count(0)
            self.oper_enable = self.ques_enable = 0

        self.command("STATus:OPERation[:EVENt]", query=read_event("oper_event"))
        self.command("STATus:OPERation:CONDition", query=condition(self.operation_condition))
        oper_enable_set, oper_enable_query = enable("oper_enable")
        ques_enable_set, ques_enable_query = enable("ques_enable")
        self.command("STATus:OPERation:ENABle", set=oper_enable_set, query=oper_enable_query)
        self.command("STATus:QUEStionable[:EVENt]", query=read_event("ques_event"))
        self.command("STATus:QUEStionable:CONDition", query=condition(self.questionable_condition))
        self.command("STATus:QUEStionable:ENABle", set=ques_enable_set, query=ques_enable_query)
        self.command("STATus:PRESet", set=preset)
        self.command("SYSTem:REMote", set=lambda a: None)
        self.command("SYSTem:LOCal", set=lambda a: None)
