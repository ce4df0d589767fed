"""Keysight 34465A-class digital multimeter (34465A, 34470A): DC volts and timed traces.

Written from the Keysight Truevolt Series Operating and Service Guide (SCPI reference).

Conventions
- Readings are volts (float64).  Every reading transfer (``READ?``, ``FETC?``, ``R?``)
  uses ``FORM REAL,64`` with ``FORM:BORD SWAP``: a definite-length block ``#<n><len>``
  of little-endian IEEE doubles.  The driver sets that format itself before the first
  reading transfer (and again after :meth:`reset`), so it owns the reading format.
- Overload: the meter reports an overload as ±9.9E37 (and "no reading" as 9.91E37).
  Every reading method returns such values as ``NaN``; count them with ``np.isnan``.
- The driver never sleeps: :meth:`stream_trace` takes the caller's ``wait(seconds)``
  (the bench clock) to let time pass between polls.
"""

from __future__ import annotations

import logging
from collections.abc import Generator
from dataclasses import dataclass
from typing import Any

import numpy as np

from .base import (
    InstrumentError,
    InstrumentReplyError,
    SCPIInstrument,
    UnsupportedInstrumentError,
    boolean,
    control,
    in_range,
    in_set,
    int_in_range,
    measurement,
    parse_bool,
    parse_float,
    parse_int,
    quote_string,
    unquote_string,
)
from .protocols import SafeOrder, Wait

log = logging.getLogger(__name__)

SUPPORTED_MODELS = ("34465A", "34470A")
#: Integration times in power-line cycles; the DIG option adds the three fastest.
NPLC_STANDARD = (0.02, 0.06, 0.2, 1.0, 10.0, 100.0)
NPLC_DIG = (0.001, 0.002, 0.006)
DC_VOLTAGE_RANGES_V = (0.1, 1.0, 10.0, 100.0, 1000.0)
APERTURE_RANGE_S = (200e-6, 1.0)
APERTURE_RANGE_DIG_S = (20e-6, 1.0)
AUTOZERO_MODES = ("ON", "OFF", "ONCE")
TRIGGER_SOURCES = ("IMM", "EXT", "BUS", "INT")
SAMPLE_SOURCES = ("IMM", "TIM")
MAX_TRIGGER_COUNT = 1_000_000
MAX_SAMPLE_COUNT = 1_000_000_000
MAX_DELAY_S = 3600.0
#: Fastest timed sampling of the 34465A/70A (50 kS/s with the DIG option).
MIN_SAMPLE_INTERVAL_S = 20e-6
#: Per-sample margin over the integration time (timer quantisation and A/D settling).
SAMPLE_OVERHEAD_S = 2e-6
#: Reading memory: 50 000 readings, 2 000 000 with the MEM option.
MEMORY_DEPTH = 50_000
MEMORY_DEPTH_MEM = 2_000_000
OVERLOAD_V = 9.9e37
DISPLAY_TEXT_MAX_CHARS = 40
ON_OFF = {True: "ON", False: "OFF"}



def printable_text(name: str, value: Any, max_chars: int) -> str:
    """Validator: printable ASCII of at most ``max_chars`` characters."""
    if not isinstance(value, str):
        raise ValueError(f"{name}={value!r} is not a string")
    if len(value) > max_chars or not all(" " <= c <= "~" for c in value):
        raise ValueError(
            f"{name}={value!r} must be printable ASCII of 0 to {max_chars} characters"
        )
    return value


def _parse_autozero(reply: str) -> str:
    # The query answers 1/0 (ONCE reads back as OFF once the single zero is taken).
    token = unquote_string(reply).upper()
    if token in AUTOZERO_MODES:
        return token
    return "ON" if parse_bool(token) else "OFF"


def _parse_token(reply: str) -> str:
    return unquote_string(reply).upper()


def flag_overloads(readings: np.ndarray) -> np.ndarray:
    """Replace overload (±9.9E37) and no-reading (9.91E37) markers by NaN, in place."""
    readings[np.abs(readings) >= OVERLOAD_V] = np.nan
    return readings


@dataclass(frozen=True)
class TracePlan:
    """A configured timed trace: ``n_samples`` readings every ``interval_s`` seconds."""

    n_samples: int
    interval_s: float
    integration_s: float
    trigger_delay_s: float

    @property
    def duration_s(self) -> float:
        """Time from trigger to the last sample's start."""
        return self.trigger_delay_s + (self.n_samples - 1) * self.interval_s


class Keysight34465A(SCPIInstrument):
    """Keysight 34465A/34470A digital multimeter in DC-voltage mode.

    The constructor identifies the meter (``*IDN?``, refusing other models), reads its
    options (``*OPT?``: DIG widens the NPLC/aperture choices, MEM the reading memory)
    and the line frequency (``SYST:LFR?``, needed to turn NPLC into seconds).
    """

    #: read-only queries, safe to re-send (``R?``, ``FETC?``, ``READ?``, ``MEAS?`` are not:
    #: they remove readings or trigger a measurement)
    idempotent_queries = SCPIInstrument.idempotent_queries | {"DATA:POIN?", "DATA:LAST?",
                                                              "SYST:LFR?"}
    safe_order = SafeOrder.ACQUISITION
    safe_action = "abort"

    def __init__(self, resource: Any, name: str | None = None) -> None:
        super().__init__(resource, name)
        model = self.idn.model.upper()
        if model not in SUPPORTED_MODELS:
            raise UnsupportedInstrumentError(
                f"{self.name}: model {self.idn.model!r} is not one of {SUPPORTED_MODELS}"
            )
        self.installed_options = self.options
        self._line_frequency_hz = self.line_frequency_hz
        self._binary_readings = False
        self.trace_plan: TracePlan | None = None

    # --- capabilities from the options ---------------------------------------------
    @property
    def has_dig(self) -> bool:
        return "DIG" in self.installed_options

    @property
    def memory_depth(self) -> int:
        """Readings the reading memory holds (50 000, or 2 000 000 with MEM)."""
        return MEMORY_DEPTH_MEM if "MEM" in self.installed_options else MEMORY_DEPTH

    @property
    def nplc_values(self) -> tuple[float, ...]:
        return (NPLC_DIG + NPLC_STANDARD) if self.has_dig else NPLC_STANDARD

    @property
    def aperture_range_s(self) -> tuple[float, float]:
        return APERTURE_RANGE_DIG_S if self.has_dig else APERTURE_RANGE_S

    @property
    def line_frequency_hz(self) -> float:
        """Power-line frequency the meter measured (``SYST:LFR?``), 50 or 60 Hz."""
        self._line_frequency_hz = self.query_value("SYST:LFR?", parse_float)
        return self._line_frequency_hz

    # --- settings, one declaration each ----------------------------------------------
    display_text = control(
        "DISP:TEXT?", "DISP:TEXT {value}",
        "Message shown on the front panel (printable ASCII, <= 40 characters).",
        validator=printable_text, values=DISPLAY_TEXT_MAX_CHARS,
        fmt=quote_string, parse=unquote_string,
    )
    function = measurement("FUNC?", "Active measurement function, e.g. 'VOLT'.", parse=_parse_token)
    range_v = control(
        "VOLT:DC:RANG?", "VOLT:DC:RANG {value}",
        "Fixed DC voltage range in volts (setting it turns autorange off).",
        validator=in_set, values=DC_VOLTAGE_RANGES_V,
    )
    autorange = control(
        "VOLT:DC:RANG:AUTO?", "VOLT:DC:RANG:AUTO {value}",
        "DC voltage autoranging on (True) or off (False).",
        validator=boolean, set_map=ON_OFF, parse=parse_bool,
    )
    nplc = control(
        "VOLT:DC:NPLC?", "VOLT:DC:NPLC {value}",
        "Integration time in power-line cycles: 0.02, 0.06, 0.2, 1, 10, 100 "
        "(and 0.001, 0.002, 0.006 with the DIG option).",
        validator=in_set, values=lambda dmm: dmm.nplc_values,
    )
    aperture_s = control(
        "VOLT:DC:APER?", "VOLT:DC:APER {value}",
        "Integration time in seconds, 200 us (20 us with DIG) to 1 s; overrides NPLC.",
        validator=in_range, values=lambda dmm: dmm.aperture_range_s,
    )
    aperture_enabled = measurement(
        "VOLT:DC:APER:ENAB?", "True while the aperture (not NPLC) sets the integration time.",
        parse=parse_bool,
    )
    autozero = control(
        "VOLT:DC:ZERO:AUTO?", "VOLT:DC:ZERO:AUTO {value}",
        "Autozero: ON (zero after every reading), OFF, or ONCE (one zero, then OFF).",
        validator=in_set, values=AUTOZERO_MODES, fmt=str, parse=_parse_autozero,
    )
    trigger_source = control(
        "TRIG:SOUR?", "TRIG:SOUR {value}",
        "Trigger source: IMM, EXT, BUS or INT.",
        validator=in_set, values=TRIGGER_SOURCES, fmt=str, parse=_parse_token,
    )
    trigger_count = control(
        "TRIG:COUN?", "TRIG:COUN {value}",
        "Triggers accepted before returning to idle, 1 to 1 000 000.",
        validator=int_in_range, values=(1, MAX_TRIGGER_COUNT), parse=parse_int,
    )
    trigger_delay_s = control(
        "TRIG:DEL?", "TRIG:DEL {value}",
        "Delay from trigger to first sample, 0 to 3600 s.",
        validator=in_range, values=(0.0, MAX_DELAY_S),
    )
    sample_source = control(
        "SAMP:SOUR?", "SAMP:SOUR {value}",
        "Sample pacing: IMM (after each reading's delay) or TIM (fixed sample interval).",
        validator=in_set, values=SAMPLE_SOURCES, fmt=str, parse=_parse_token,
    )
    sample_interval_s = control(
        "SAMP:TIM?", "SAMP:TIM {value}",
        "Sample interval for SAMP:SOUR TIM, 20 us to 3600 s.",
        validator=in_range, values=(MIN_SAMPLE_INTERVAL_S, MAX_DELAY_S),
    )
    sample_count = control(
        "SAMP:COUN?", "SAMP:COUN {value}",
        "Readings per trigger, 1 to 1e9 (beyond the reading memory, stream the trace).",
        validator=int_in_range, values=(1, MAX_SAMPLE_COUNT), parse=parse_int,
    )

    snapshot_settings = (
        "function", "range_v", "autorange", "nplc", "autozero",
        "trigger_source", "trigger_count", "trigger_delay_s", "sample_source",
        "sample_interval_s", "sample_count",
    )

    def snapshot_details(self) -> dict[str, Any]:
        return {"options": list(self.installed_options), "memory_depth": self.memory_depth,
                "line_frequency_hz": self._line_frequency_hz}

    # --- actions ---------------------------------------------------------------------
    def clear_display(self) -> None:
        self.configure_command("DISP:TEXT:CLE")

    def reset(self) -> None:
        super().reset()
        self._binary_readings = False  # *RST restores ASCII readings
        self.trace_plan = None

    def configure_dc_voltage(self, range_v: float | None = None, nplc: float | None = None) -> None:
        """``CONF:VOLT:DC <range>`` (``AUTO`` when ``range_v`` is None): DC volts, one
        reading per trigger, immediate trigger; then ``nplc`` if given (else the meter's
        default after CONF).  Both are validated before anything is written."""
        token = "AUTO"
        if range_v is not None:
            token = f"{in_set('range_v', range_v, DC_VOLTAGE_RANGES_V):g}"
        nplc_ = None if nplc is None else in_set("nplc", nplc, self.nplc_values)
        with self.configuring():
            self.configure_command(f"CONF:VOLT:DC {token}")
            if nplc_ is not None:
                self.nplc = nplc_
        self.trace_plan = None

    def measure_dc_voltage(self) -> float:
        """Take one reading with the present configuration (``READ?``), volts; NaN on
        overload.  Expects one reading per READ? (see :meth:`configure_dc_voltage`)."""
        self._use_binary_readings()
        readings = flag_overloads(self.query_real64("READ?"))
        if readings.size != 1:
            raise InstrumentReplyError(
                f"{self.name}: READ? returned {readings.size} readings, expected 1; "
                "call configure_dc_voltage() after a trace"
            )
        return float(readings[0])

    def configure_timed_trace(
        self,
        n_samples: int,
        interval_s: float,
        *,
        nplc: float = 1.0,
        aperture_s: float | None = None,
        range_v: float = 10.0,
        autozero: str = "OFF",
        trigger_delay_s: float = 0.0,
    ) -> TracePlan:
        """Configure one trigger of ``n_samples`` DC-volt readings every ``interval_s``.

        The integration time is ``nplc`` power-line cycles, or ``aperture_s`` seconds when
        given.  The interval must cover it (twice with autozero ON) plus
        ``SAMPLE_OVERHEAD_S``; everything is validated before anything is written.
        Start with :meth:`initiate` then :meth:`fetch_all`, or use :meth:`stream_trace`.
        """
        n = int_in_range("n_samples", n_samples, (1, MAX_SAMPLE_COUNT))
        interval = in_range("interval_s", interval_s, (MIN_SAMPLE_INTERVAL_S, MAX_DELAY_S))
        range_ = in_set("range_v", range_v, DC_VOLTAGE_RANGES_V)
        zero = in_set("autozero", autozero, AUTOZERO_MODES)
        delay = in_range("trigger_delay_s", trigger_delay_s, (0.0, MAX_DELAY_S))
        if aperture_s is None:
            nplc_ = in_set("nplc", nplc, self.nplc_values)
            integration = nplc_ / self._line_frequency_hz
            integration_text = f"nplc={nplc_:g} at {self._line_frequency_hz:g} Hz"
        else:
            integration = in_range("aperture_s", aperture_s, self.aperture_range_s)
            integration_text = f"aperture_s={integration:g}"
        min_interval = integration * (2 if zero == "ON" else 1) + SAMPLE_OVERHEAD_S
        if interval < min_interval:
            raise ValueError(
                f"interval_s={interval_s!r} is shorter than the integration time plus "
                f"overhead ({integration_text}, autozero {zero}): allowed range "
                f"[{min_interval:g}, {MAX_DELAY_S:g}] s"
            )
        self.trace_plan = None
        try:
            with self.configuring():
                self.configure_command(f"CONF:VOLT:DC {range_:g}")
                if aperture_s is None:
                    self.nplc = nplc_
                else:
                    self.aperture_s = integration
                self.autozero = zero
                self.trigger_source = "IMM"
                self.trigger_count = 1
                self.trigger_delay_s = delay
                self.sample_source = "TIM"
                self.sample_interval_s = interval
                self.sample_count = n
                self._use_binary_readings()
        except InstrumentError:
            self._binary_readings = False  # the group failed: the format is not known to be set
            raise
        self.trace_plan = TracePlan(n, interval, integration, delay)
        return self.trace_plan

    def initiate(self) -> None:
        """``INIT``: arm the trigger system; readings go to reading memory."""
        self.configure_command("INIT")

    def abort(self) -> None:
        """``ABOR``: stop an acquisition in progress (readings so far stay in memory)."""
        self.configure_command("ABOR")

    def make_safe(self) -> None:
        """Teardown: :meth:`abort` (the readings stay in memory)."""
        self.abort()

    def points_available(self) -> int:
        """``DATA:POIN?``: readings waiting in reading memory."""
        return self.query_value("DATA:POIN?", parse_int)

    def fetch_all(self) -> np.ndarray:
        """``FETC?``: every reading of the finished acquisition, volts (NaN on overload).

        The meter answers when the acquisition completes, so the VISA timeout must cover
        it; for long traces use :meth:`stream_trace`.
        """
        plan = self.trace_plan
        if plan is not None and plan.n_samples > self.memory_depth:
            raise RuntimeError(
                f"{self.name}: a {plan.n_samples}-sample trace exceeds the "
                f"{self.memory_depth}-reading memory; use stream_trace()"
            )
        self._use_binary_readings()
        return flag_overloads(self.query_real64("FETC?"))

    def read_and_remove(self, max_n: int) -> np.ndarray:
        """``R? <max_n>``: remove and return up to ``max_n`` oldest readings (may be fewer)."""
        n = int_in_range("max_n", max_n, (1, self.memory_depth))
        self._use_binary_readings()
        return flag_overloads(self.query_real64(f"R? {n}"))

    def read_available(self, max_n: int | None = None) -> np.ndarray:
        """Remove and return every reading now in memory (at most ``max_n``), volts; an
        empty array when there is none.  For polling a running trace."""
        limit = self.memory_depth if max_n is None else int_in_range(
            "max_n", max_n, (1, self.memory_depth))
        available = self.points_available()
        if available == 0:
            return np.empty(0, dtype=np.float64)
        return self.read_and_remove(min(available, limit))

    def last_reading(self) -> float:
        """``DATA:LAST?``: the most recent reading in volts (NaN on overload or none)."""
        reply = self.query("DATA:LAST?")
        value = parse_float(reply.split()[0]) if reply.split() else float("nan")
        return float("nan") if abs(value) >= OVERLOAD_V else value

    def stream_trace(
        self,
        chunk_points: int = 10_000,
        *,
        wait: Wait,
        initiate: bool = True,
        min_poll_s: float = 0.01,
        stall_timeout_s: float | None = None,
    ) -> Generator[np.ndarray, None, None]:
        """Stream the configured timed trace as float64 chunks while it is acquired.

        Yields chunks of exactly ``chunk_points`` readings (the last one may be shorter),
        in acquisition order, removed from reading memory with ``R?`` as soon as enough
        are there (polled with ``DATA:POIN?``).  Between polls it calls ``wait(seconds)``
        for the time the missing readings need (at least ``min_poll_s``).  Raises
        ``TimeoutError`` after ``stall_timeout_s`` waited without a chunk (default: 10 s
        plus five chunk durations plus the trigger delay).  If the consumer stops early
        or an error occurs, the acquisition is aborted.  ``chunk_points`` may be at most
        half the reading memory, so that a full memory reliably signals lost readings
        (``RuntimeError``).
        """
        plan = self.trace_plan
        if plan is None:
            raise RuntimeError(f"{self.name}: call configure_timed_trace() before stream_trace()")
        # Half the memory at most, so a full memory can only mean lost readings.
        chunk = int_in_range("chunk_points", chunk_points, (1, self.memory_depth // 2))
        poll = in_range("min_poll_s", min_poll_s, (1e-6, MAX_DELAY_S))
        if stall_timeout_s is None:
            stall_timeout_s = 10.0 + plan.trigger_delay_s + 5 * chunk * plan.interval_s
        stall = in_range("stall_timeout_s", stall_timeout_s, (0.0, float("inf")))
        if not callable(wait):
            raise ValueError(f"wait={wait!r} is not callable; pass the bench clock's wait")
        return self._stream(plan, chunk, wait, initiate, poll, stall)

    def _stream(
        self, plan: TracePlan, chunk: int, wait: Wait, initiate: bool, poll: float, stall: float
    ) -> Generator[np.ndarray, None, None]:
        self._use_binary_readings()
        if initiate:
            self.initiate()
        received = 0
        try:
            idle_s = 0.0
            while received < plan.n_samples:
                want = min(chunk, plan.n_samples - received)
                available = self.points_available()
                if available >= self.memory_depth:
                    raise RuntimeError(
                        f"{self.name}: reading memory full after {received} readings; "
                        "older readings may have been overwritten (poll more often)"
                    )
                if available >= want:
                    readings = self.read_and_remove(want)
                    if readings.size == 0:
                        raise InstrumentReplyError(f"{self.name}: R? {want} returned no readings")
                    received += readings.size
                    idle_s = 0.0
                    yield readings
                    continue
                if idle_s >= stall:
                    raise TimeoutError(
                        f"{self.name}: {received}/{plan.n_samples} readings after waiting "
                        f"{idle_s:g} s without a full chunk"
                    )
                dt = max((want - available) * plan.interval_s, poll)
                wait(dt)
                idle_s += dt
        finally:
            if received < plan.n_samples:
                self._abort_quietly()

    def _abort_quietly(self) -> None:
        try:
            self.abort()
        except Exception as exc:  # already unwinding: report, don't mask the cause
            log.warning("%s: abort after an interrupted stream failed: %s", self.name, exc)

    def _use_binary_readings(self) -> None:
        """Select little-endian REAL,64 reading blocks, once."""
        if not self._binary_readings:
            with self.configuring():
                self.configure_command("FORM REAL,64")
                self.configure_command("FORM:BORD SWAP")
            self._binary_readings = True
