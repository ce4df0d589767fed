"""The Keysight 34465A command vocabulary of the simulated multimeter.

A mixin for :class:`sim.devices.dmm.Multimeter`: one declaration per command, read top to
bottom, plus the reply formats of the real instrument (``+1.23456789E+00`` readings,
``+100`` counts, definite-length REAL,64 blocks in either byte order).  The trigger model
and reading memory it drives live in ``sim.devices.dmm``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

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
from sim.scpi import Args, ScpiError, format_block, format_number

MAX_SAMPLES = 1_000_000_000


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


class Keysight34465AVocabulary:
    """SCPI commands of the 34465A (DC volts), registered on construction by ``_register``."""

    if TYPE_CHECKING:  # what the host class provides (sim.devices.dmm.Multimeter, an ScpiDevice)
        fe: DmmFrontEnd
        converter: DmmConverter
        memory: Any  # the reading memory
        has_dig: bool
        state: str

        def command(self, pattern: str, *, set: Callable[[Args], None] | None = None,
                    query: Callable[[Args], str | bytes] | None = None,
                    max_suffix: int | tuple[int | None, ...] | None = None) -> None: ...

        def abort(self) -> None: ...

        def initiate(self) -> None: ...

        def wait_complete(self) -> None: ...

        def _wait_for_points(self, n: int) -> None: ...

        @property
        def delay_s(self) -> float: ...

        @property
        def aperture_enabled(self) -> bool: ...

        @property
        def _aper_min(self) -> float: ...

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
            self.trig_source = args.choice(0, ["IMMediate", "BUS", "EXTernal", "INTernal"])

        def set_trig_coun(args: Args) -> None:
            if args.keyword(0) == "INF":
                self.trig_count = 9.9e37
            else:
                self.trig_count = float(args.integer(0, min=1, max=1_000_000, default=1))

        def set_trig_del(args: Args) -> None:
            self.trig_delay_s = args.number(0, min=0.0, max=3600.0, default=0.0)
            self.trig_delay_auto = False

        def set_samp_sour(args: Args) -> None:
            self.samp_source = args.choice(0, ["IMMediate", "TIMer"])

        def set_samp_tim(args: Args) -> None:
            self.samp_timer_s = args.number(0, min=2e-5, max=3600.0, default=1.0)

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
            self.display = args.string(0)[:40]

        c("CONFigure[:VOLTage][:DC]", set=conf_volt, query=lambda a: self._conf_reply())
        c("CONFigure", query=lambda a: self._conf_reply())
        c("MEASure[:VOLTage][:DC]", query=meas_volt)
        c("[SENSe:]FUNCtion[:ON]", set=self._set_function, query=lambda a: '"VOLT"')
        c("[SENSe:]VOLTage[:DC]:RANGe[:UPPer]", set=set_range,
          query=lambda a: limits_query(a, fe().range_v, 0.1, 1000.0, 10.0))
        c("[SENSe:]VOLTage[:DC]:RANGe:AUTO", set=lambda a: setattr(fe(), "autorange", a.boolean(0)),
          query=lambda a: "1" if fe().autorange else "0")
        c("[SENSe:]VOLTage[:DC]:NPLCycles", set=set_nplc,
          query=lambda a: limits_query(a, fe().nplc, 0.001 if self.has_dig else 0.02, 100.0, 10.0))
        c("[SENSe:]VOLTage[:DC]:APERture", set=set_aper,
          query=lambda a: limits_query(a, self.aperture_value_s, self._aper_min, 1.0, 0.1))
        c("[SENSe:]VOLTage[:DC]:APERture:ENABled", set=self._set_aper_enabled,
          query=lambda a: "1" if self.aperture_enabled else "0")
        c("[SENSe:]VOLTage[:DC]:RESolution", set=self._set_resolution,
          query=lambda a: format_number(self._resolution()))
        c("[SENSe:]VOLTage[:DC]:ZERO:AUTO", set=set_zero,
          query=lambda a: "1" if fe().autozero == "ON" else "0")
        c("[SENSe:]VOLTage[:DC]:IMPedance:AUTO", set=_accept_boolean, query=lambda a: "0")
        c("TRIGger:SOURce", set=set_trig_sour, query=lambda a: self.trig_source[:3])
        c("TRIGger:COUNt", set=set_trig_coun,
          query=lambda a: limits_query(a, self.trig_count, 1, 1_000_000, 1, _fmt_count))
        c("TRIGger:DELay", set=set_trig_del,
          query=lambda a: limits_query(a, self.delay_s, 0.0, 3600.0, self.delay_s))
        c("TRIGger:DELay:AUTO", set=lambda a: setattr(self, "trig_delay_auto", a.boolean(0)),
          query=lambda a: "1" if self.trig_delay_auto else "0")
        c("SAMPle:SOURce", set=set_samp_sour, query=lambda a: self.samp_source[:3])
        c("SAMPle:TIMer", set=set_samp_tim,
          query=lambda a: limits_query(a, self.samp_timer_s, self.fe.reading_time_s, 3600.0, 1.0))
        c("SAMPle:COUNt", set=set_samp_coun,
          query=lambda a: limits_query(a, self.samp_count, 1, MAX_SAMPLES, 1, _fmt_count))
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
        c("DISPlay[:WINDow]:TEXT[:DATA]", set=disp_text, query=lambda a: f'"{self.display}"')
        c("DISPlay[:WINDow]:TEXT:CLEar", set=lambda a: setattr(self, "display", ""))
        c("DISPlay[:STATe]", set=_accept_boolean, query=lambda a: "1")
        c("STATus:QUEStionable[:EVENt]", query=lambda a: f"{self._ques():+d}")
        c("STATus:QUEStionable:CONDition", query=lambda a: f"{self._ques():+d}")
        c("SYSTem:BEEPer[:IMMediate]", set=lambda a: None)

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

    def _set_resolution(self, args: Args) -> None:
        if args.keyword(0) == "DEF":
            self.fe.nplc = 10.0
            return
        self._set_resolution_value(args.number(0, min=1e-9, max=1.0))

    def _set_resolution_value(self, res_v: float) -> None:
        ppm = res_v / self.fe.range_v * 1e6
        for n in allowed_nplc(self.has_dig):  # fastest NPLC that meets the resolution
            if NOISE_PPM_OF_RANGE[n] <= ppm:
                self.fe.nplc = n
                return
        self.fe.nplc = 100.0

    def _set_function(self, args: Args) -> None:
        name = args.string(0).strip().upper()
        if name not in ("VOLT", "VOLT:DC", "VOLTAGE", "VOLTAGE:DC"):
            raise ScpiError(-224, f"function {name!r} not simulated; allowed: \"VOLT:DC\"")
