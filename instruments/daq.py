"""Keysight DAQ970A data-acquisition unit with a DAQM901A 20-channel multiplexer: timed scans
of DC volts over a list of channels.

Written from the Keysight DAQ970A programming guide's scanning chapter (``CONF:VOLT:DC``
with a channel list, ``ROUT:SCAN``, ``ROUT:CHAN:DEL``, ``TRIG:SOUR TIM``, ``TRIG:TIM``,
``TRIG:COUN``, ``INIT``, ``R?``, ``FORM:READ:TIME``/``CHAN``).  What the guide leaves open
and this driver assumes is listed in ``docs/vocabulary/keysight_daq970a.md``.

Conventions
- Readings are volts (float64), each with its time (s since ``INIT``, ``FORM:READ:TIME:TYPE
  REL``) and its channel: the driver sets ``FORM:READ:TIME ON`` and ``FORM:READ:CHAN ON``
  itself when it configures a scan, so it owns the reading format.
- Overload (±9.9E37) is returned as ``NaN``.
- The driver never sleeps: :meth:`stream_scan` takes the caller's ``wait(seconds)``.
- A sweep's duration is estimated from the data-sheet figures below (relay, channel delay,
  integration twice with autozero); :meth:`configure_scan` refuses an interval shorter
  than that, naming the shortest one allowed.
"""

from __future__ import annotations

import math
from collections.abc import Generator, Sequence
from typing import Any

import numpy as np

from .base import (
    InstrumentReplyError,
    SCPIInstrument,
    UnsupportedInstrumentError,
    in_range,
    in_set,
    int_in_range,
)
from .daq_types import ScanPlan, ScanReadings
from .protocols import SafeOrder, Wait

SUPPORTED_MODELS = ("DAQ970A",)
MUX_MODULES = ("DAQM901A",)
SLOT_CHANNELS = (101, 120)              # DAQM901A voltage channels in slot 1
NPLC_VALUES = (0.02, 0.06, 0.2, 1.0, 10.0, 100.0)
DC_VOLTAGE_RANGES_V = (0.1, 1.0, 10.0, 100.0, 300.0)
RELAY_CLOSE_S = 0.004                   # armature relay, data sheet (≈ 80 channels/s at best)
AUTO_DELAY_S = 0.002                    # auto channel delay, DC volts ≤ 100 V
READING_OVERHEAD_S = 0.0012             # A/D set-up and transfer per reading (with margin)
MAX_SWEEPS = 50_000_000
MAX_INTERVAL_S = 359_999.0
MAX_DELAY_S = 60.0
OVERLOAD_V = 9.9e37


def parse_scan_block(reply: str, name: str, command: str) -> ScanReadings:
    """A definite-length block of ``reading,time,channel`` triples (``R?``)."""
    if not reply.startswith("#") or len(reply) < 2 or not reply[1].isdigit() or reply[1] == "0":
        raise InstrumentReplyError(f"{name}: {command!r} answered {reply[:20]!r}, not a "
                                   "definite-length block")
    digits = int(reply[1])
    try:
        length = int(reply[2:2 + digits])
    except ValueError:
        raise InstrumentReplyError(f"{name}: {command!r}: bad block header {reply[:12]!r}") from None
    payload = reply[2 + digits:]
    if len(payload) != length:
        raise InstrumentReplyError(f"{name}: {command!r}: block of {len(payload)} bytes, "
                                   f"header says {length}")
    return parse_scan_text(payload, name, command)


def parse_scan_text(text: str, name: str, command: str) -> ScanReadings:
    """``reading,time,channel,...`` text into :class:`ScanReadings`."""
    if not text.strip():
        empty = np.empty(0)
        return ScanReadings(empty, empty.copy(), np.empty(0, dtype=np.int64))
    try:
        values = np.array(text.split(","), dtype=np.float64)
    except ValueError:
        raise InstrumentReplyError(f"{name}: {command!r}: unparsable readings {text[:40]!r}") from None
    if values.size % 3:
        raise InstrumentReplyError(f"{name}: {command!r}: {values.size} fields are not "
                                   "reading,time,channel triples")
    rows = values.reshape(-1, 3)
    volts = rows[:, 0].copy()
    volts[np.abs(volts) >= OVERLOAD_V] = np.nan
    return ScanReadings(volts, rows[:, 1].copy(), rows[:, 2].astype(np.int64))


class KeysightDAQ970A(SCPIInstrument):
    """DAQ970A with a DAQM901A in slot 1: timed scans of DC volts."""

    idempotent_queries = SCPIInstrument.idempotent_queries | frozenset(
        {"DATA:POIN?", "ROUT:SCAN:SIZE?", "SYST:CTYP?", "SYST:LFR?"})
    safe_order = SafeOrder.ACQUISITION
    safe_action = "ABOR"

    def __init__(self, resource: Any, name: str | None = None) -> None:
        super().__init__(resource, name)
        self.plan: ScanPlan | None = None

    # --- identity ---------------------------------------------------------------------
    def check_model(self) -> None:
        """The unit is a supported model with a multiplexer in slot 1, else
        ``UnsupportedInstrumentError`` naming what it found."""
        if self.idn.model not in SUPPORTED_MODELS:
            raise UnsupportedInstrumentError(f"{self.name}: model {self.idn.model!r} not in "
                                             f"{'|'.join(SUPPORTED_MODELS)}")
        module = self.module(1)
        if module not in MUX_MODULES:
            raise UnsupportedInstrumentError(f"{self.name}: slot 1 holds {module!r}, not "
                                             f"{'|'.join(MUX_MODULES)}")

    def module(self, slot: int) -> str:
        """``SYST:CTYP? <slot>00``: the module's model in ``slot`` (1..3), ``"0"`` when empty."""
        s = int_in_range("slot", slot, (1, 3))
        return self.query_value(f"SYST:CTYP? {s}00", lambda r: r.split(",")[1].strip())

    def snapshot_details(self) -> dict[str, Any]:
        return {"slot1": self.module(1)}

    @property
    def line_frequency_hz(self) -> float:
        """``SYST:LFR?``: the mains frequency the unit integrates against, Hz."""
        return self.query_value("SYST:LFR?", float)

    # --- scanning ---------------------------------------------------------------------
    @staticmethod
    def channel_time_s(nplc: float, line_hz: float = 50.0, channel_delay_s: float | None = None,
                       autozero: bool = True) -> float:
        """One channel's share of a sweep: relay, delay, integration (×2 with autozero) and
        overhead (data-sheet figures; the shortest timer interval is this × channels)."""
        delay = AUTO_DELAY_S if channel_delay_s is None else channel_delay_s
        return RELAY_CLOSE_S + delay + (2 if autozero else 1) * nplc / line_hz + READING_OVERHEAD_S

    def configure_scan(self, channels: Sequence[int], *, interval_s: float, sweeps: int,
                       nplc: float = 1.0, range_v: float = 10.0, line_hz: float = 50.0,
                       channel_delay_s: float | None = None, autozero: bool = True) -> ScanPlan:
        """Configure ``sweeps`` timer-triggered sweeps of DC volts over ``channels`` every
        ``interval_s``: ``CONF:VOLT:DC``, ``VOLT:DC:NPLC``, ``ZERO:AUTO``, the channel delay
        (auto when ``channel_delay_s`` is None), ``ROUT:SCAN``, ``TRIG:SOUR TIM``, ``TRIG:TIM``,
        ``TRIG:COUN`` and the reading format; everything validated before anything is written.
        """
        chans = tuple(sorted(int_in_range("channel", c, SLOT_CHANNELS) for c in channels))
        if not chans:
            raise ValueError("channels is empty; give 1..20 channels in 101..120")
        if len(set(chans)) != len(chans):
            raise ValueError(f"channels {list(channels)} repeat a channel")
        n = int_in_range("sweeps", sweeps, (1, MAX_SWEEPS))
        nplc_ = in_set("nplc", nplc, NPLC_VALUES)
        rng = in_set("range_v", range_v, DC_VOLTAGE_RANGES_V)
        line = in_set("line_hz", line_hz, (50.0, 60.0))
        delay = None if channel_delay_s is None else in_range("channel_delay_s", channel_delay_s,
                                                             (0.0, MAX_DELAY_S))
        per_channel = self.channel_time_s(nplc_, line, delay, autozero)
        shortest = per_channel * len(chans)
        if in_range("interval_s", interval_s, (0.0, MAX_INTERVAL_S)) < shortest:
            raise ValueError(f"interval_s={interval_s!r} is shorter than a sweep of {len(chans)} "
                             f"channels at {nplc_:g} NPLC: at least {shortest:.4f} s")
        interval = math.ceil(interval_s * 1000 - 1e-6) / 1000  # the timer's 1 ms steps, never shorter
        listed = "(@" + ",".join(map(str, chans)) + ")"
        with self.configuring():
            self.configure_command("ABOR")
            self.configure_command(f"CONF:VOLT:DC {rng:g},{listed}")
            self.configure_command(f"VOLT:DC:NPLC {nplc_:g},{listed}")
            self.configure_command(f"ZERO:AUTO {'ON' if autozero else 'OFF'},{listed}")
            if delay is None:
                self.configure_command(f"ROUT:CHAN:DEL:AUTO ON,{listed}")
            else:
                self.configure_command(f"ROUT:CHAN:DEL {delay:g},{listed}")
            self.configure_command(f"ROUT:SCAN {listed}")
            self.configure_command("TRIG:SOUR TIM")
            self.configure_command(f"TRIG:TIM {interval:.3f}")
            self.configure_command(f"TRIG:COUN {n}")
            self.configure_command("FORM:READ:TIME ON")
            self.configure_command("FORM:READ:TIME:TYPE REL")
            self.configure_command("FORM:READ:CHAN ON")
        self.plan = ScanPlan(chans, interval, n, nplc_, per_channel)
        return self.plan

    def initiate(self) -> None:
        self.configure_command("INIT")

    def abort(self) -> None:
        self.configure_command("ABOR")

    def make_safe(self) -> None:
        """``ABOR``: the scan stopped (the relays open when a scan ends)."""
        self.abort()

    def points_available(self) -> int:
        return self.query_value("DATA:POIN?", lambda r: int(float(r)))

    def read_available(self, max_n: int | None = None) -> ScanReadings:
        """``R? [max]``: the readings in memory (at most ``max_n``), removed."""
        command = "R?" if max_n is None else f"R? {int_in_range('max_n', max_n, (1, 1_000_000))}"
        return self.query_value(command, lambda r: parse_scan_block(r, self.name, command), retry=False)

    def stream_scan(self, wait: Wait, poll_s: float = 10.0,
                    timeout_s: float | None = None) -> Generator[ScanReadings, None, None]:
        """Start the configured scan and yield its readings as they arrive, every ``poll_s``,
        until every sweep is in; ``TimeoutError`` when nothing arrives for ``timeout_s``
        (default: 3 × poll + 2 sweeps + 10 s)."""
        plan = self.plan
        if plan is None:
            raise RuntimeError(f"{self.name}: configure_scan() before stream_scan()")
        poll = in_range("poll_s", poll_s, (0.01, 3600.0))
        limit = timeout_s if timeout_s is not None else 3 * poll + 2 * plan.interval_s + 10.0
        expected = plan.sweeps * len(plan.channels)
        got, quiet_s = 0, 0.0
        self.initiate()
        while got < expected:
            wait(poll)
            chunk = self.read_available()
            if len(chunk):
                got += len(chunk)
                quiet_s = 0.0
                yield chunk
            else:
                quiet_s += poll
                if quiet_s > limit:
                    raise TimeoutError(f"{self.name}: no scan readings for {quiet_s:g} s "
                                       f"({got}/{expected} received)")


__all__ = ["KeysightDAQ970A", "ScanPlan", "ScanReadings", "parse_scan_block", "parse_scan_text",
           "SLOT_CHANNELS", "NPLC_VALUES"]
