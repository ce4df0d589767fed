"""Simulated Keysight 34465A digital multimeter: the trigger model, reading memory and
the 34465A SCPI vocabulary, as a view of the World.

Trigger model (as the real instrument): ``INIT`` → *wait-for-trigger*; each trigger
(``TRIG:SOUR IMM`` immediately, ``BUS`` on ``*TRG``) waits ``TRIG:DEL`` then takes
``SAMP:COUN`` readings, spaced by ``SAMP:TIM`` (``SAMP:SOUR TIM``) or back to back
(``IMM``); after ``TRIG:COUN`` triggers the meter returns to idle.  Readings go to a
FIFO reading memory (50 000 readings, 2 000 000 with the MEM option); when it overflows
the oldest readings are lost and questionable-data bit 14 is set.

Virtual time: readings appear as the world advances (this object is a World activity).
Queries that block on the real meter (``FETC?``/``READ?`` before the acquisition ends,
``*OPC?``, ``DATA:REM? n,WAIT``) let simulated time pass until they can answer.  A wait
that can never end (bus trigger pending, infinite trigger count) is answered with
``-230`` in the error queue and no response — the client times out, as with hardware.
"""

from __future__ import annotations

from collections import deque
from typing import Callable

import numpy as np

from sim.devices.dmm_model import (
    DIG_NPLC, RANGES_V, DmmConverter, DmmFrontEnd, LinePickup, noise_ppm, range_for,
    round_up_nplc,
)
from sim.scpi import Args, ScpiDevice, ScpiError, format_block, format_number
from sim.world import World

#: the source the DMM's input terminals are wired to: (start times, aperture) -> mean volts
InputSignal = Callable[[np.ndarray, float], np.ndarray]
MAX_SAMPLES = 1_000_000_000
MAX_BATCH = 500_000  # readings generated per step, bounds memory per advance


def _fmt_reading(x: float) -> str:
    return f"{x:+.8E}"


def _fmt_count(x: float) -> str:
    return f"{int(x):+d}" if x < 9.9e37 else "+9.90000000E+37"


def limits_query(args: Args, current, lo, hi, default, fmt=format_number) -> str:
    """A setting's query: the value, or with MIN|MAX|DEF the limit (as the real meter)."""
    if args.count:
        value = {"MIN": lo, "MAX": hi, "DEF": default}.get(args.raw[0].strip().upper()[:3])
        if value is None:
            raise ScpiError(-224, f"{args.raw[0]!r} not in MIN|MAX|DEF")
        return fmt(value)
    return fmt(current)


class _Memory:
    """FIFO reading memory of fixed depth, stored as numpy chunks."""

    def __init__(self, depth: int) -> None:
        self.depth = depth
        self.chunks: deque[np.ndarray] = deque()
        self.count = 0
        self.overflowed = False
        self.last = np.nan

    def clear(self) -> None:
        self.chunks.clear()
        self.count = 0
        self.overflowed = False

    def push(self, values: np.ndarray) -> None:
        if values.size == 0:
            return
        self.last = float(values[-1])
        self.chunks.append(values)
        self.count += values.size
        while self.count > self.depth:  # drop the oldest readings
            self.overflowed = True
            excess = self.count - self.depth
            head = self.chunks[0]
            if head.size <= excess:
                self.chunks.popleft()
                self.count -= head.size
            else:
                self.chunks[0] = head[excess:]
                self.count -= excess

    def peek_all(self) -> np.ndarray:
        return np.concatenate(list(self.chunks)) if self.chunks else np.empty(0)

    def remove(self, n: int) -> np.ndarray:
        n = min(n, self.count)
        out, need = [], n
        while need:
            head = self.chunks[0]
            if head.size <= need:
                out.append(self.chunks.popleft())
                need -= head.size
            else:
                out.append(head[:need])
                self.chunks[0] = head[need:]
                need = 0
        self.count -= n
        return np.concatenate(out) if out else np.empty(0)


class Multimeter(ScpiDevice):
    """34465A view of the world. ``input_signal`` is wired by the station."""

    def __init__(self, world: World, name: str, input_signal: InputSignal,
                 serial: str = "MY59001234", options: tuple[str, ...] = ("DIG", "MEM"),
                 line_pickup: LinePickup | None = None) -> None:
        super().__init__(("Keysight Technologies", "34465A", serial,
                          "A.03.01-02.40-03.01-00.52-01-02"),
                         options=",".join(options) if options else "0")
        self.world, self.name, self.input_signal = world, name, input_signal
        self.has_dig = "DIG" in options
        self.memory = _Memory(2_000_000 if "MEM" in options else 50_000)
        self.pickup = line_pickup or LinePickup()
        self.converter = DmmConverter(world.rng(f"{name}.converter"))
        self.display = ""
        self.format_real = False
        self.swapped = False
        self._defaults()
        self._register()

    # -- state ---------------------------------------------------------------------------
    def _defaults(self) -> None:
        self.fe = DmmFrontEnd(line_hz=self.pickup.nominal_hz)
        self.trig_source, self.trig_count, self.trig_delay_s = "IMMEDIATE", 1.0, 0.0
        self.trig_delay_auto = True
        self.samp_source, self.samp_count, self.samp_timer_s = "IMMEDIATE", 1, 1.0
        self.state = "IDLE"  # IDLE | WAIT_TRIGGER | ACQUIRING
        self.aperture_value_s = 0.1  # VOLT:APER value (used only while enabled)
        # the current *segment*: readings of one or more back-to-back triggers
        self._seg_t0 = 0.0           # time of the trigger that started it
        self._seg_triggers = 1.0     # triggers in it (IMM: all remaining; BUS: one)
        self._g = 0                  # next reading index within it
        self._triggers_done = 0.0

    def reset(self) -> None:
        self.abort()
        self._defaults()
        self.memory.clear()
        self.memory.last = np.nan
        self.format_real, self.swapped = False, False

    @property
    def delay_s(self) -> float:
        # Auto delay for DCV: 1.5 ms up to 1 NPLC (settling), none above (data sheet table).
        return (0.0015 if self.fe.nplc <= 1 else 0.0) if self.trig_delay_auto else self.trig_delay_s

    @property
    def interval_s(self) -> float:
        """Spacing of readings within a trigger; a timer shorter than a reading is stretched."""
        if self.samp_source == "TIMER":
            return max(self.samp_timer_s, self.fe.reading_time_s)
        return self.fe.reading_time_s

    @property
    def aperture_enabled(self) -> bool:
        return self.fe.aperture_override_s is not None

    @property
    def _aper_min(self) -> float:
        return 2e-5 if self.has_dig else 2e-4

    @property
    def _period_s(self) -> float:
        """Trigger-to-trigger time when triggers follow immediately (TRIG:SOUR IMM)."""
        return self.delay_s + (self.samp_count - 1) * self.interval_s + self.fe.aperture_s

    @property
    def _seg_total(self) -> float:
        return self._seg_triggers * self.samp_count

    def _t_start(self, g: np.ndarray) -> np.ndarray:
        """Aperture start of readings with indices ``g`` (contiguous, increasing) in the
        current segment."""
        s = self.samp_count
        j0, k0 = divmod(int(g[0]), s)
        if k0 + g.size <= s:  # the usual case: all within one trigger, no divmod needed
            return (self._seg_t0 + j0 * self._period_s + self.delay_s
                    + (k0 + np.arange(g.size)) * self.interval_s)
        j, k = np.divmod(g, s)
        return self._seg_t0 + j * self._period_s + self.delay_s + k * self.interval_s

    def _due(self, t: float) -> int:
        """Readings of the current segment whose aperture has ended by ``t``."""
        span = t - self._seg_t0
        period, s = self._period_s, self.samp_count
        eps = 1e-9 * self.interval_s
        j_full = max(0.0, np.floor((span + eps) / period))
        rem = span - j_full * period
        k = int(np.clip(np.floor((rem - self.delay_s - self.fe.aperture_s + eps)
                                 / self.interval_s) + 1, 0, s))
        return int(min(j_full * s + k, self._seg_total))

    # -- the acquisition as a world activity --------------------------------------------
    def initiate(self) -> None:
        if self.state != "IDLE":
            raise ScpiError(-213, "INIT while a measurement is in progress")
        self.memory.clear()
        self._triggers_done = 0.0
        self.state = "WAIT_TRIGGER"
        self.world.add_activity(self)
        if self.trig_source == "IMMEDIATE":
            self._fire(self.world.now, self.trig_count)

    def _fire(self, t: float, triggers: float) -> None:
        self._seg_t0, self._seg_triggers, self._g = t, triggers, 0
        self.state = "ACQUIRING"

    def trigger(self) -> None:
        if self.state == "WAIT_TRIGGER" and self.trig_source == "BUS":
            self._fire(self.world.now, 1.0)
        else:
            raise ScpiError(-211)

    def abort(self) -> None:
        self.state = "IDLE"
        self.world.remove_activity(self)

    def run_until(self, t: float) -> None:
        """Take every reading whose aperture ends by ``t``.

        Work is bounded by the memory depth whatever the span: readings the memory could
        not hold are never generated (the noise processes jump over the gap exactly), and
        the overflow is flagged as on the real meter.
        """
        try:
            self._run_until(t)
        except Exception as exc:  # a model failure must not wedge the world's clock
            self.abort()
            self.push_error(-240, f"measurement failed: {type(exc).__name__}: {exc}")

    def _run_until(self, t: float) -> None:
        while self.state == "ACQUIRING":
            due = self._due(t)
            if due - self._g > self.memory.depth:
                self._g = due - self.memory.depth
                self.memory.clear()
                self.memory.overflowed = True
            n = min(due - self._g, MAX_BATCH)
            if n > 0:
                g = np.arange(self._g, self._g + n, dtype=np.float64)
                t_start = self._t_start(g)
                ap = self.fe.aperture_s
                mean_v = self.input_signal(t_start, ap) + self.pickup.averaged(t_start, ap)
                self.memory.push(self.converter.convert(mean_v, self.fe))
                self._g += n
            if self._g >= self._seg_total:
                self._triggers_done += self._seg_triggers
                if self._triggers_done >= self.trig_count:
                    self.abort()
                else:
                    self.state = "WAIT_TRIGGER"
                return
            if n < MAX_BATCH:
                return

    def _t_end(self, g: float) -> float:
        return float(self._t_start(np.array([g]))[0]) + self.fe.aperture_s

    def completion_time(self) -> float | None:
        """Simulated time at which the acquisition ends, or None if it never does by itself."""
        if self.state == "IDLE":
            return self.world.now
        last_segment = self._triggers_done + self._seg_triggers >= self.trig_count
        if self.state != "ACQUIRING" or not last_segment or self._seg_total >= 9.9e37:
            return None
        return self._t_end(self._seg_total - 1)

    def wait_complete(self) -> None:
        t_end = self.completion_time()
        if t_end is None:
            raise ScpiError(-230, "acquisition waits for a trigger that cannot arrive")
        self.world.advance_to(max(t_end, self.world.now))

    def _wait_for_points(self, n: int) -> None:
        """Let simulated time pass until ``n`` readings are in memory."""
        while self.memory.count < n:
            missing = n - self.memory.count
            if self.state != "ACQUIRING" or self._g + missing > self._seg_total:
                raise ScpiError(-230, f"waiting for {n} readings that cannot arrive")
            self.world.advance_to(max(self.world.now, self._t_end(self._g + missing - 1)))

    # -- reply formatting ----------------------------------------------------------------
    def _readings_reply(self, values: np.ndarray, block: bool) -> bytes | str:
        if self.format_real:
            payload = values.astype("<f8" if self.swapped else ">f8").tobytes()
            return format_block(payload)
        text = ",".join(map(_fmt_reading, values.tolist()))
        return format_block(text.encode()) if block else text

    # -- SCPI vocabulary -------------------------------------------------------------------
    def _register(self) -> None:  # noqa: C901 - one declaration per command, read top to bottom
        c = self.command
        fe = lambda: self.fe  # noqa: E731 - the front end object is replaced on *RST

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
            if args.raw[0].strip().upper().startswith("INF"):
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
        c("[SENSe:]VOLTage[:DC]:IMPedance:AUTO", set=lambda a: a.boolean(0), query=lambda a: "0")
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
        c("DISPlay[:STATe]", set=lambda a: a.boolean(0), query=lambda a: "1")
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
        word = args.raw[1].strip().upper()[:3] if args.count >= 2 else "DEF"
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
        if args.raw[0].strip().upper()[:3] == "DEF":
            self.fe.nplc = 10.0
            return
        self._set_resolution_value(args.number(0, min=1e-9, max=1.0))

    def _set_resolution_value(self, res_v: float) -> None:
        from sim.devices.dmm_model import NOISE_PPM_OF_RANGE, allowed_nplc
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


__all__ = ["Multimeter", "RANGES_V", "DIG_NPLC"]
