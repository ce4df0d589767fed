"""The Keysight 34465A command vocabulary of the simulated multimeter.

A mixin for :class:`sim.devices.dmm.Multimeter`: one declaration per command, read top to
bottom, plus the reply formats of the real instrument (``+1.23456789E+00`` readings,
``+100`` counts, definite-length REAL,64 blocks in either byte order).  The trigger model
and reading memory it drives live in ``sim.devices.dmm``.
"""

from __future__ import annotations

from abc import ABCMeta, abstractmethod
from collections.abc import Callable
from typing import Protocol

import numpy as np

from sim.devices.dmm_model import (
    NOISE_PPM_OF_RANGE,
    DmmConverter,
    DmmFrontEnd,
    allowed_nplc,
    noise_ppm,
    range_for,
    round_up_nplc,
)
from sim.scpi import Args, ScpiDevice, ScpiError, format_block, format_number, format_string
from sim.world import World

MAX_SAMPLES = 1_000_000_000   # SAMP:COUN and TRIG:COUN of the 34465A: 1 .. 1e9
MAX_DELAY_S = 3600.0
TRIGGER_LEVEL_V = 1000.0      # TRIG:LEV within +-1000 V (manual range: +-120 % checked at INIT)
TIMER_STEP_S = 1e-6           # SAMP:TIM resolution for DC volts
DISPLAY_CHARS = 40            # DISP:TEXT is cut to what the display holds


def _fmt_reading(x: float) -> str:
    return f"{x:+.8E}"


def _fmt_count(x: float) -> str:
    return f"{int(x):+d}" if x < 9.9e37 else "+9.90000000E+37"


def _accept_boolean(args: Args) -> None:
    """A setting the simulation does not model: its ON|OFF argument checked, nothing changed."""
    args.boolean(0)


def limits_query(args: Args, current, lo, hi, default, fmt=format_number) -> str:
    """A setting's query: the value, or with MIN|MAX|DEF the limit (as the real meter)."""
    if args.count:
        value = {"MIN": lo, "MAX": hi, "DEF": default}.get(args.keyword(0) or "")
        if value is None:
            raise ScpiError(-224, f"{args.raw[0]!r} not in MIN|MAX|DEF")
        return fmt(value)
    return fmt(current)


class ReadingMemory(Protocol):
    """What the vocabulary reads of the meter's FIFO reading memory."""

    depth: int
    count: int
    overflowed: bool
    last: float

    def peek_all(self) -> np.ndarray: ...

    def remove(self, n: int) -> np.ndarray: ...


class Keysight34465AVocabulary(ScpiDevice, metaclass=ABCMeta):
    """SCPI commands of the 34465A (DC volts), registered on construction by ``_register``.

    The state they set and the trigger model they drive belong to the meter
    (``sim.devices.dmm.Multimeter``); declared here so that each command reads as one line.
    """

    world: World
    fe: DmmFrontEnd
    memory: ReadingMemory
    converter: DmmConverter
    input_signal: Callable[[np.ndarray, float], np.ndarray]
    has_dig: bool
    state: str
    trig_source: str
    trig_count: float
    trig_delay_s: float
    trig_delay_auto: bool
    trig_slope: str
    trig_level_v: float
    pretrigger_count: int
    samp_source: str
    samp_count: int
    samp_timer_s: float
    aperture_value_s: float
    format_real: bool
    swapped: bool
    display: str

    @abstractmethod
    def initiate(self) -> None:
        """INIT: the trigger model to wait-for-trigger."""

    @abstractmethod
    def abort(self) -> None:
        """ABORt: back to idle."""

    @abstractmethod
    def _wait_for_points(self, n: int) -> None:
        """Let simulated time pass until ``n`` readings are in memory."""

    @property
    @abstractmethod
    def delay_s(self) -> float:
        """Trigger delay in force (the auto delay when enabled)."""

    @property
    @abstractmethod
    def aperture_enabled(self) -> bool:
        """Integration set in seconds (VOLT:APER) rather than NPLC."""

    @property
    @abstractmethod
    def _aper_min(self) -> float:
        """Shortest aperture of the fitted options, seconds."""

    # -- reply formatting ----------------------------------------------------------------
    def _readings_reply(self, values: np.ndarray, block: bool) -> bytes | str:
        if self.format_real:
            payload = values.astype("<f8" if self.swapped else ">f8").tobytes()
            return format_block(payload)
        text = ",".join(map(_fmt_reading, values.tolist()))
        return format_block(text.encode()) if block else text

    # -- SCPI vocabulary -------------------------------------------------------------------
    def _register(self) -> None:
        c = self.command
        fe = lambda: self.fe

        def conf_volt(args: Args) -> None:
            self.abort()
            self._configure_volts(args)

        def meas_volt(args: Args) -> bytes | str:
            self.abort()
            self._configure_volts(args)
            return read_q(args)

        def set_range(args: Args) -> None:
            fe().range_v = range_for(args.number(0, min=0.0, max=1000.0, default=10.0))
            fe().autorange = False

        def set_nplc(args: Args) -> None:
            lo = 0.001 if self.has_dig else 0.02
            fe().nplc = round_up_nplc(args.number(0, min=lo, max=100.0, default=10.0),
                                      self.has_dig)
            fe().aperture_override_s = None

        def set_aper(args: Args) -> None:
            # 200 µs .. 1 s (20 µs with DIG) in 2 µs steps
            self.aperture_value_s = round(args.number(0, min=self._aper_min, max=1.0,
                                                      default=0.1) / 2e-6) * 2e-6
            fe().aperture_override_s = self.aperture_value_s

        def set_zero(args: Args) -> None:
            word = args.raw[0].strip().upper()
            if word in ("ONCE",):
                fe().autozero = "ONCE"
                self.converter.autozero_once()
            else:
                fe().autozero = "ON" if args.boolean(0) else "OFF"

        def set_trig_sour(args: Args) -> None:
            source = args.choice(0, ["IMMediate", "BUS", "EXTernal", "INTernal"])
            if source == "INTERNAL":
                self._need_dig("TRIG:SOUR INT")
            self.trig_source = source

        def set_trig_coun(args: Args) -> None:
            if args.keyword(0) == "INF":
                self.trig_count = 9.9e37
            else:
                self.trig_count = float(args.integer(0, min=1, max=MAX_SAMPLES, default=1))

        def set_trig_del(args: Args) -> None:
            self.trig_delay_s = round(args.number(0, min=0.0, max=MAX_DELAY_S, default=0.0)
                                      / TIMER_STEP_S) * TIMER_STEP_S
            self.trig_delay_auto = False

        def set_trig_lev(args: Args) -> None:
            self._need_dig("TRIG:LEV")
            self.trig_level_v = args.number(0, min=-TRIGGER_LEVEL_V, max=TRIGGER_LEVEL_V,
                                            default=0.0, units="V")

        def set_pretrigger(args: Args) -> None:
            self._need_dig("SAMP:COUN:PRET")
            self.pretrigger_count = args.integer(0, min=0, max=self.memory.depth - 1, default=0)

        def set_samp_sour(args: Args) -> None:
            self.samp_source = args.choice(0, ["IMMediate", "TIMer"])

        def set_samp_tim(args: Args) -> None:
            # MIN is the recommended minimum for the present settings; DC steps of 1 us
            value = args.number(0, min=2e-5, max=MAX_DELAY_S, default=1.0)
            if args.keyword(0) == "MIN":
                value = self.fe.reading_time_s
            self.samp_timer_s = max(2e-5, round(value / TIMER_STEP_S) * TIMER_STEP_S)

        def set_samp_coun(args: Args) -> None:
            self.samp_count = args.integer(0, min=1, max=MAX_SAMPLES, default=1)

        def init(args: Args) -> None:
            self.initiate()

        def fetch_q(args: Args) -> bytes | str:
            if self.state != "IDLE":
                self.wait_complete()
            return self._readings_reply(self.memory.peek_all(), block=False)

        def read_q(args: Args) -> bytes | str:
            self.initiate()
            return fetch_q(args)

        def r_q(args: Args) -> bytes:
            n = int(args.number(0, min=1, max=2_000_000)) if args.count else self.memory.count
            return self._as_block(self.memory.remove(n))

        def rem_q(args: Args) -> bytes | str:
            n = int(args.number(0, min=1, max=self.memory.depth))
            if args.count > 1:
                if args.choice(1, ["WAIT"]) and self.memory.count < n:
                    self._wait_for_points(n)
            if self.memory.count < n:
                raise ScpiError(-222, f"{n} readings requested, {self.memory.count} in memory")
            return self._readings_reply(self.memory.remove(n), block=False)

        def last_q(args: Args) -> str:
            v = self.memory.last
            return f"{_fmt_reading(v) if np.isfinite(v) else '+9.91000000E+37'} VDC"  # 9.91E37: none

        def form_q(args: Args) -> str:
            return "REAL,64" if self.format_real else "ASC,9"

        def set_form(args: Args) -> None:
            kind = args.choice(0, ["ASCii", "REAL"])
            if kind == "REAL":
                if args.count > 1 and int(args.number(1, min=64, max=64)) != 64:
                    raise ScpiError(-224)
                self.format_real = True
            else:
                self.format_real = False

        def set_bord(args: Args) -> None:
            self.swapped = args.choice(0, ["NORMal", "SWAPped"]) == "SWAPPED"

        def disp_text(args: Args) -> None:
            self.display = args.string(0)[:DISPLAY_CHARS]

        def set_autorange(args: Args) -> None:
            if args.count and args.raw[0].strip().upper() == "ONCE":
                # one autorange on the present input, then the range is held
                now = np.array([self.world.now])
                volts = float(np.abs(self.input_signal(now, self.fe.aperture_s))[0])
                fe().range_v = next((r for r in (0.1, 1.0, 10.0, 100.0) if volts <= 1.2 * r), 1000.0)
                fe().autorange = False
            else:
                fe().autorange = args.boolean(0)

        def bool_setting(attr: str) -> dict:
            return dict(set=lambda a: setattr(self, attr, a.boolean(0)),
                        query=lambda a: "1" if getattr(self, attr) else "0")

        c("CONFigure[:VOLTage][:DC]", set=conf_volt, query=lambda a: self._conf_reply())
        c("CONFigure", query=lambda a: self._conf_reply())
        c("MEASure[:VOLTage][:DC]", query=meas_volt)
        c("[SENSe:]FUNCtion[:ON]", set=self._set_function, query=lambda a: '"VOLT"')
        c("[SENSe:]VOLTage[:DC]:RANGe[:UPPer]", set=set_range,
          query=lambda a: limits_query(a, fe().range_v, 0.1, 1000.0, 10.0))
        c("[SENSe:]VOLTage[:DC]:RANGe:AUTO", set=set_autorange,
          query=lambda a: "1" if fe().autorange else "0")
        c("[SENSe:]VOLTage[:DC]:NPLCycles", set=set_nplc,
          query=lambda a: limits_query(a, fe().nplc, 0.001 if self.has_dig else 0.02, 100.0, 10.0))
        c("[SENSe:]VOLTage[:DC]:APERture", set=set_aper,
          query=lambda a: limits_query(a, self.aperture_value_s, self._aper_min, 1.0, 0.1))
        c("[SENSe:]VOLTage[:DC]:APERture:ENABled", set=self._set_aper_enabled,
          query=lambda a: "1" if self.aperture_enabled else "0")
        c("[SENSe:]VOLTage[:DC]:RESolution", set=self._set_resolution, query=self._resolution_query)
        c("[SENSe:]VOLTage[:DC]:ZERO:AUTO", set=set_zero,
          query=lambda a: "1" if fe().autozero == "ON" else "0")
        c("[SENSe:]VOLTage[:DC]:IMPedance:AUTO", **bool_setting("impedance_auto"))
        c("TRIGger:SOURce", set=set_trig_sour, query=lambda a: self.trig_source[:3])
        c("TRIGger:COUNt", set=set_trig_coun,
          query=lambda a: limits_query(a, self.trig_count, 1, MAX_SAMPLES, 1, _fmt_count))
        c("TRIGger:DELay", set=set_trig_del,
          query=lambda a: limits_query(a, self.delay_s, 0.0, MAX_DELAY_S, 0.0))
        c("TRIGger:DELay:AUTO", **bool_setting("trig_delay_auto"))
        c("TRIGger:SLOPe", set=lambda a: setattr(self, "trig_slope", a.choice(0, ["POSitive", "NEGative"])[:3]),
          query=lambda a: self.trig_slope)
        c("TRIGger:LEVel", set=set_trig_lev,
          query=lambda a: limits_query(a, self.trig_level_v, -TRIGGER_LEVEL_V, TRIGGER_LEVEL_V, 0.0))
        c("SAMPle:SOURce", set=set_samp_sour, query=lambda a: self.samp_source[:3])
        c("SAMPle:TIMer", set=set_samp_tim,
          query=lambda a: limits_query(a, self.samp_timer_s, self.fe.reading_time_s, MAX_DELAY_S, 1.0))
        c("SAMPle:COUNt", set=set_samp_coun,
          query=lambda a: limits_query(a, self.samp_count, 1, MAX_SAMPLES, 1, _fmt_count))
        c("SAMPle:COUNt:PRETrigger", set=set_pretrigger,
          query=lambda a: limits_query(a, self.pretrigger_count, 0, self.memory.depth - 1, 0, _fmt_count))
        c("INITiate[:IMMediate]", set=init)
        c("ABORt", set=lambda a: self.abort())
        c("FETCh", query=fetch_q)
        c("READ", query=read_q)
        c("R", query=r_q)
        c("DATA:REMove", query=rem_q)
        c("DATA:POINts", query=lambda a: f"{self.memory.count:+d}")
        c("DATA:LAST", query=last_q)
        c("FORMat[:DATA]", set=set_form, query=form_q)
        c("FORMat:BORDer", set=set_bord, query=lambda a: "SWAP" if self.swapped else "NORM")
        c("SYSTem:LFRequency", query=lambda a: f"{int(fe().line_hz)}")
        c("SYSTem:PRESet", set=lambda a: self.reset())
        c("SYSTem:LICense:CATalog", query=lambda a: ",".join(
            f'"{o}"' for o in self.options.split(",") if o != "0") or '""')
        c("SYSTem:BEEPer[:IMMediate]", set=lambda a: None)
        c("SYSTem:BEEPer:STATe", **bool_setting("beeper_on"))
        c("DISPlay[:WINDow]:TEXT[:DATA]", set=disp_text, query=lambda a: format_string(self.display))
        c("DISPlay[:WINDow]:TEXT:CLEar", set=lambda a: setattr(self, "display", ""))
        c("DISPlay[:STATe]", **bool_setting("display_on"))
        c("ROUTe:TERMinals", query=lambda a: "FRON")
        c("STATus:QUEStionable[:EVENt]", query=lambda a: f"{self._ques():+d}")
        c("STATus:QUEStionable:CONDition", query=lambda a: f"{self._ques():+d}")

    def _need_dig(self, what: str) -> None:
        if not self.has_dig:
            raise ScpiError(-241, f"{what} needs the DIG option (*OPT? {self.options})")

    def _set_aper_enabled(self, args: Args) -> None:
        self.fe.aperture_override_s = self.aperture_value_s if args.boolean(0) else None

    def _ques(self) -> int:
        return (1 << 14) if self.memory.overflowed else 0

    def _as_block(self, values: np.ndarray) -> bytes:
        out = self._readings_reply(values, block=True)
        return out if isinstance(out, bytes) else out.encode()

    def _configure_volts(self, args: Args) -> None:
        fe = self.fe
        fe.aperture_override_s = None
        if args.count >= 1 and args.raw[0].strip().upper().startswith("AUTO"):
            fe.autorange = True
        elif args.count >= 1:
            fe.range_v = range_for(args.number(0, min=0.0, max=1000.0, default=10.0))
            fe.autorange = False
        word = args.keyword(1) if args.count >= 2 else "DEF"
        if word in ("DEF", "MIN", "MAX"):
            # DEF: 10 PLC; MIN resolution value = finest (100 PLC); MAX = fastest
            fe.nplc = {"DEF": 10.0, "MIN": 100.0,
                       "MAX": 0.001 if self.has_dig else 0.02}[word]
        else:
            self._set_resolution_value(args.number(1, min=1e-9, max=1.0))
        self.trig_source, self.trig_count, self.trig_delay_auto = "IMMEDIATE", 1.0, True
        self.samp_source, self.samp_count = "IMMEDIATE", 1

    def _conf_reply(self) -> str:
        return f'"VOLT +{self.fe.range_v:.8E},+{self._resolution():.8E}"'

    def _resolution(self) -> float:
        return noise_ppm(self.fe) * 1e-6 * self.fe.range_v

    def _resolution_query(self, args: Args) -> str:
        # MIN = finest (100 PLC), MAX = coarsest (fastest NPLC), DEF = 10 PLC, on the present range
        fastest = min(allowed_nplc(self.has_dig))
        by_word = {"MIN": 100.0, "MAX": fastest, "DEF": 10.0}
        if args.count:
            word = args.keyword(0)
            if word not in by_word:
                raise ScpiError(-224, f"{args.raw[0]!r} not in MIN|MAX|DEF")
            return format_number(NOISE_PPM_OF_RANGE[by_word[word]] * 1e-6 * self.fe.range_v)
        return format_number(self._resolution())

    def _set_resolution(self, args: Args) -> None:
        word = args.keyword(0)
        if word in ("MIN", "MAX", "DEF"):
            self.fe.nplc = {"MIN": 100.0, "MAX": min(allowed_nplc(self.has_dig)), "DEF": 10.0}[word]
            self.fe.aperture_override_s = None
            return
        self._set_resolution_value(args.number(0, min=1e-9, max=1.0))

    def _set_resolution_value(self, res_v: float) -> None:
        ppm = res_v / self.fe.range_v * 1e6
        for n in allowed_nplc(self.has_dig):  # fastest NPLC that meets the resolution
            if NOISE_PPM_OF_RANGE[n] <= ppm * (1 + 1e-6):  # 3.0e-05 V on 10 V is 3 ppm, not 2.99..
                self.fe.nplc = n
                self.fe.aperture_override_s = None
                return
        self.fe.nplc = 100.0
        self.fe.aperture_override_s = None

    def _set_function(self, args: Args) -> None:
        name = args.string(0).strip().upper()
        if name not in ("VOLT", "VOLT:DC", "VOLTAGE", "VOLTAGE:DC"):
            raise ScpiError(-224, f"function {name!r} not simulated; allowed: \"VOLT:DC\"")
