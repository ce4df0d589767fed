"""Simulated Keysight DAQ970A data-acquisition unit with a DAQM901A 20-channel multiplexer in
slot 1: the scan, its timing on the virtual clock and the reading memory, as a view of the
World.  Its command vocabulary is in ``docs/vocabulary/keysight_daq970a.md``.

Scan model (as the DAQ970A programming guide describes it):

* ``CONF:VOLT:DC [range[,resolution]],(@list)`` configures the channels for DC volts and makes
  them the scan list; ``ROUT:SCAN (@list)`` sets the scan list alone (channels scanned in
  ascending order, as the real instrument does);
* ``INIT`` arms the scan; each trigger (``TRIG:SOUR IMM`` at once and back to back,
  ``TIM`` every ``TRIG:TIM`` s, ``BUS`` on ``*TRG``) runs one *sweep* through the scan list;
  after ``TRIG:COUN`` sweeps the unit is idle.  A timer interval shorter than a sweep is
  stretched to the sweep (the next sweep starts when the previous one ends).
* In a sweep each channel's relay closes (``RELAY_CLOSE_S``), the channel delay passes
  (``ROUT:CHAN:DEL``; auto: ``AUTO_DELAY_S``), then the internal DMM integrates over the
  channel's aperture (``NPLC / f_line``, twice with autozero on) plus ``READING_OVERHEAD_S``.
* **Settling**: the fixture's input filter (time constant ``settling_tau_s``) still carries
  the previous channel's voltage when the relay closes; a reading is the mean over its
  aperture of ``v + (v_prev − v)·exp(−t/τ)``: with the auto delay the residue is negligible,
  with ``ROUT:CHAN:DEL 0`` and a short aperture the previous channel shows through.

Time: readings appear as the world advances (this object is a World activity), a whole sweep
at a time.  ``FETC?``, ``READ?``, ``*OPC?`` and ``DATA:REM? n`` wait (simulated time passes)
until they can answer; one that can never complete (bus trigger pending, ``TRIG:COUN INF``)
queues ``-230`` and sends nothing, as the real unit leaves the client to time out.

Each channel reads its own input signal (wired by the station) through its own noise
generator (``world.rng("<name>:ch<n>")``), so a channel's bytes do not depend on the others
or on how the advance was split.

Besides the scan: ``MEAS?`` (``CONF`` then ``READ?``), ``DATA:LAST?`` (each channel's last
1000 scan readings, kept apart from the reading memory so ``R?`` does not empty them) and the
Monitor mode (``ROUT:MON``, ``ROUT:MON:STAT``, ``ROUT:MON:DATA?``: one reading of the monitored
channel, idle, through its own noise stream ``world.rng("<name>:monitor")``, so monitoring
never shifts a channel's scan bytes).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Mapping

import numpy as np

from sim.devices.dmm_model import (
    DmmConverter,
    DmmFrontEnd,
    ForcedInput,
    LinePickup,
    noise_ppm,
    round_up_nplc,
)
from sim.devices.lifecycle import scpi_power_on
from sim.scpi import Args, ScpiDevice, ScpiError, format_block, format_int, format_number
from sim.world import World

#: a channel's input: (aperture start times, aperture) -> mean volts over each aperture
InputSignal = Callable[[np.ndarray, float], np.ndarray]

SLOT_CHANNELS = range(101, 121)   # DAQM901A: 20 two-wire voltage channels in slot 1
RELAY_CLOSE_S = 0.004             # armature relay close and bounce (assumed; ~80 ch/s at best)
AUTO_DELAY_S = 0.002              # auto channel delay for DC volts ≤ 100 V (assumed)
READING_OVERHEAD_S = 0.001        # A/D set-up and data handling per reading (assumed)
MEMORY_DEPTH = 1_000_000          # readings with time and channel (assumed)
MAX_SWEEPS = 50_000_000           # TRIG:COUN 1..5e7 | INF
MAX_TIMER_S = 359_999.0           # TRIG:TIM 0..359999 s (99:59:59)
MAX_DELAY_S = 60.0                # ROUT:CHAN:DEL 0..60 s
LAST_READINGS = 1000              # DATA:LAST? <num_rdgs> 1..1000 (DAQ970A guide, p. 109)
SWEEP_BATCH = 20_000              # sweeps generated per step, bounds memory per advance
INFINITE = 9.9e37
OVERLOAD = 9.9e37
NOT_A_NUMBER = 9.91e37            # ROUT:MON:DATA? with the Monitor mode off or no reading (guide p. 211)


READING_FORMAT = "%+.8E"         # a reading as the DAQ970A sends it: +1.23456789E+00


def channel_list_block(channels: list[int]) -> bytes:
    """A channel list as ``ROUT:SCAN?`` and ``ROUT:MON?`` answer it: a definite-length block,
    ``#214(@101,102,103)``, empty ``#13(@)`` (34970A user's guide, ROUTe:SCAN? and ROUTe:MONitor?;
    the DAQ970A keeps the 34970A's scan commands, programming guide pp. 214-215)."""
    return format_block(("(@" + ",".join(map(str, channels)) + ")").encode("ascii"))


class _ScanMemory:
    """FIFO of (reading, seconds since INIT, channel), oldest lost on overflow."""

    def __init__(self, depth: int) -> None:
        self.depth = depth
        self.chunks: deque[np.ndarray] = deque()  # (n, 3) float64 arrays
        self.count = 0
        self.overflowed = False

    def clear(self) -> None:
        self.chunks.clear()
        self.count = 0
        self.overflowed = False

    def push(self, rows: np.ndarray) -> None:
        if rows.shape[0] == 0:
            return
        self.chunks.append(rows)
        self.count += rows.shape[0]
        while self.count > self.depth:
            self.overflowed = True
            excess = self.count - self.depth
            head = self.chunks[0]
            if head.shape[0] <= excess:
                self.chunks.popleft()
                self.count -= head.shape[0]
            else:
                self.chunks[0] = head[excess:]
                self.count -= excess

    def peek_all(self) -> np.ndarray:
        return np.concatenate(list(self.chunks)) if self.chunks else np.empty((0, 3))

    def remove(self, n: int) -> np.ndarray:
        n = min(n, self.count)
        out, need = [], n
        while need:
            head = self.chunks[0]
            if head.shape[0] <= need:
                out.append(self.chunks.popleft())
                need -= head.shape[0]
            else:
                out.append(head[:need])
                self.chunks[0] = head[need:]
                need = 0
        self.count -= n
        return np.concatenate(out) if out else np.empty((0, 3))


class _Channel:
    """One multiplexer channel's measurement settings."""

    def __init__(self, line_hz: float) -> None:
        self.fe = DmmFrontEnd(range_v=10.0, autorange=True, nplc=1.0, autozero="ON", line_hz=line_hz)
        self.delay_s = AUTO_DELAY_S
        self.delay_auto = True

    @property
    def busy_s(self) -> float:
        """Time the channel takes in a sweep: relay, delay, reading."""
        return RELAY_CLOSE_S + self.delay_s + self.fe.reading_time_s + READING_OVERHEAD_S


class ScanningDaq(ScpiDevice):
    """DAQ970A view of the world; ``inputs`` maps a slot-1 channel (101..120) to what its
    terminals are wired to (an unwired channel reads 0 V: an open input shorted by the filter)."""

    fault_kinds: tuple[str, ...] = ("power", "overload")

    def __init__(self, world: World, name: str, inputs: Mapping[int, InputSignal], *,
                 serial: str = "MY60001234", line_pickup: LinePickup | None = None,
                 settling_tau_s: float = 1e-4, ideal: bool = False) -> None:
        super().__init__(("Keysight Technologies", "DAQ970A", serial, "A.03.01-01.00-03.01"),
                         options="0")
        unknown = sorted(set(inputs) - set(SLOT_CHANNELS))
        if unknown:
            raise ValueError(f"channels {unknown} not on the DAQM901A (101..120)")
        if not 0 < settling_tau_s <= 1.0:
            raise ValueError(f"settling_tau_s {settling_tau_s!r} not in (0, 1] s")
        self.world, self.name = world, name
        self.inputs = dict(inputs)
        self.settling_tau_s = float(settling_tau_s)
        self.pickup = line_pickup or LinePickup()
        self.converters = {ch: DmmConverter(world.rng(f"{name}:ch{ch}"),
                                            noise_scale=0.0 if ideal else 1.0)
                           for ch in SLOT_CHANNELS}
        # the Monitor's readings come from a stream of their own: monitoring shifts no scan byte
        self.monitor_converter = DmmConverter(world.rng(f"{name}:monitor"), noise_scale=0.0 if ideal else 1.0)
        self.memory = _ScanMemory(MEMORY_DEPTH)
        self.forced = ForcedInput()  # the overload fault's windows
        self._defaults()
        self._register()

    # -- state ---------------------------------------------------------------------------
    def _defaults(self) -> None:
        self.channels = {ch: _Channel(self.pickup.nominal_hz) for ch in SLOT_CHANNELS}
        self.scan_list: list[int] = []
        self.closed: set[int] = set()
        self.trig_source, self.trig_timer_s, self.trig_count = "IMMEDIATE", 1.0, 1.0
        self.format_time, self.format_channel, self.time_type = False, False, "REL"
        self.state = "IDLE"            # IDLE | WAIT_TRIGGER | SCANNING
        self._t0 = 0.0                 # INIT instant: reading times are relative to it
        self._sweep_starts: list[float] = []  # BUS: the sweeps triggered, not yet taken
        self._next_sweep = 0           # index of the next sweep to take
        self._prev_v = 0.0             # input of the channel scanned last (settling residue)
        self.last_readings: dict[int, np.ndarray] = {}  # DATA:LAST?: per channel, (n, 3) rows
        self.monitor_channel: int | None = None
        self.monitor_on = False

    def reset(self) -> None:
        self.abort()
        self._defaults()
        self.memory.clear()

    # -- lifecycle (sim.devices.lifecycle) ------------------------------------------------
    def power_off(self) -> None:
        self.abort()
        self.memory.clear()
        self.last_readings.clear()

    def power_on(self) -> None:
        scpi_power_on(self)

    @property
    def overloaded(self) -> bool:
        return self.forced.active

    def overload(self, volts: float) -> None:
        """Every channel's input forced to ``volts`` from now (beyond range: ±9.9E37)."""
        self.forced.force(self.world.now, volts)

    def end_overload(self) -> None:
        self.forced.release(self.world.now)

    # -- the scan's timing ---------------------------------------------------------------
    @property
    def sweep_s(self) -> float:
        return sum(self.channels[ch].busy_s for ch in self.scan_list)

    @property
    def period_s(self) -> float:
        """Sweep start to sweep start."""
        if self.trig_source == "TIMER":
            return max(self.trig_timer_s, self.sweep_s)
        return self.sweep_s

    def _sweep_start_times(self, first: int, n: int) -> np.ndarray:
        """When sweeps ``first`` … ``first + n − 1`` start (their triggers have come)."""
        if self.trig_source in ("IMMEDIATE", "TIMER"):
            return self._t0 + np.arange(first, first + n, dtype=np.float64) * self.period_s
        return np.array(self._sweep_starts[first:first + n], dtype=np.float64)

    def _sweep_start(self, k: int) -> float | None:
        """When sweep ``k`` starts, or None while its trigger has not come."""
        if self.trig_source not in ("IMMEDIATE", "TIMER") and k >= len(self._sweep_starts):
            return None
        return float(self._sweep_start_times(k, 1)[0])

    def completion_time(self) -> float | None:
        """When the last sweep ends, None if that cannot be known (a trigger still to come)."""
        if self.state == "IDLE":
            return self.world.now
        if self.trig_count >= INFINITE:
            return None
        start = self._sweep_start(int(self.trig_count) - 1)
        return None if start is None else start + self.sweep_s

    def initiate(self) -> None:
        if self.state != "IDLE":
            raise ScpiError(-213, "INIT while a scan is in progress")
        if not self.scan_list:
            raise ScpiError(-221, "INIT with an empty scan list (ROUT:SCAN or CONF first)")
        self.memory.clear()
        self.last_readings.clear()  # a new scan: DATA:LAST? has nothing of the previous one
        self._t0 = self.world.now
        self._sweep_starts, self._next_sweep, self._prev_v = [], 0, 0.0
        self.closed.clear()
        self.state = "WAIT_TRIGGER" if self.trig_source in ("BUS", "EXTERNAL") else "SCANNING"
        self.world.add_activity(self)

    def trigger(self) -> None:
        """``*TRG``: one sweep now, when armed for bus triggers."""
        if self.state == "IDLE" or self.trig_source != "BUS":
            raise ScpiError(-211, "*TRG while not waiting for a bus trigger")
        if self._sweep_starts and self._sweep_starts[-1] + self.sweep_s > self.world.now:
            raise ScpiError(-211, "*TRG during a sweep")
        self._sweep_starts.append(self.world.now)
        self.state = "SCANNING"

    def abort(self) -> None:
        self.state = "IDLE"
        self.world.remove_activity(self)

    def run_until(self, t: float) -> None:
        try:
            self._run_until(t)
        except Exception as exc:  # a model failure must not wedge the world's clock
            self.abort()
            # the instrument's own failure, whichever session's message let time run: every session
            self.instrument_error(-240, f"measurement failed: {type(exc).__name__}: {exc}")

    def _due_sweeps(self, t: float) -> int:
        """Sweeps ending by ``t`` in all (taken or not)."""
        total = INFINITE if self.trig_count >= INFINITE else int(self.trig_count)
        if self.trig_source in ("IMMEDIATE", "TIMER"):
            if t < self._t0 + self.sweep_s:
                return 0
            return int(min(total, math.floor((t - self._t0 - self.sweep_s) / self.period_s + 1e-9) + 1))
        return sum(1 for s in self._sweep_starts if s + self.sweep_s <= t)

    def _run_until(self, t: float) -> None:
        while self.state != "IDLE":
            due = self._due_sweeps(t)
            n = due - self._next_sweep
            if n <= 0:
                break
            per_sweep = len(self.scan_list)
            if n * per_sweep > self.memory.depth:  # readings memory could not hold: never taken
                skip = n - self.memory.depth // per_sweep
                self._next_sweep += skip
                self.memory.overflowed = True
                n -= skip
            n = min(n, SWEEP_BATCH)
            self._take_sweeps(self._next_sweep, n)
            self._next_sweep += n
            if self.trig_count < INFINITE and self._next_sweep >= int(self.trig_count):
                self.abort()
            elif self.trig_source == "BUS" and self._next_sweep >= len(self._sweep_starts):
                self.state = "WAIT_TRIGGER"

    def _take_sweeps(self, first: int, n: int) -> None:
        starts = self._sweep_start_times(first, n)
        out = np.empty((n, len(self.scan_list), 3))
        offset, tau = 0.0, self.settling_tau_s
        inputs: list[np.ndarray] = []
        for ch in self.scan_list:  # what each channel's terminals carry at its aperture
            c = self.channels[ch]
            inputs.append(self._input(ch, starts + offset + RELAY_CLOSE_S + c.delay_s, c.fe.aperture_s))
            offset += c.busy_s
        offset = 0.0
        for j, ch in enumerate(self.scan_list):
            c = self.channels[ch]
            t_ap = starts + offset + RELAY_CLOSE_S + c.delay_s
            ap, v = c.fe.aperture_s, inputs[j]
            if j > 0:
                prev = inputs[j - 1]
            else:  # the last channel of the sweep before (the first after INIT: 0 V, relays open)
                prev = np.concatenate(([self._prev_v], inputs[-1][:-1]))
            # the fixture filter still holds the previous channel's level when the relay
            # closes: mean over the aperture of (v_prev − v)·exp(−t/τ), t from the closing
            gain = math.exp(-c.delay_s / tau) * (tau / ap) * -math.expm1(-ap / tau)
            mean = v + (prev - v) * gain + self.pickup.averaged(t_ap, ap)
            out[:, j, 0] = self.converters[ch].convert(mean, c.fe)
            out[:, j, 1] = t_ap - self._t0
            out[:, j, 2] = ch
            offset += c.busy_s
        self._prev_v = float(inputs[-1][-1])
        self.memory.push(out.reshape(-1, 3))
        for j, ch in enumerate(self.scan_list):
            held = self.last_readings.get(ch)
            recent = out[-LAST_READINGS:, j, :].copy()  # a copy: the batch's array is not kept alive
            self.last_readings[ch] = recent if held is None else np.concatenate((held, recent))[-LAST_READINGS:]

    def _input(self, ch: int, t_start: np.ndarray, aperture_s: float) -> np.ndarray:
        source = self.inputs.get(ch)
        volts = np.zeros_like(t_start) if source is None else source(t_start, aperture_s)
        return self.forced.apply(t_start, volts)

    def wait_complete(self) -> None:
        t_end = self.completion_time()
        if t_end is None:
            raise ScpiError(-230, "scan waits for a trigger that cannot arrive or never ends")
        self.world.advance_to(max(t_end, self.world.now))

    def _wait_for_points(self, n: int) -> None:
        while self.memory.count < n:
            if self.state == "IDLE":
                raise ScpiError(-230, f"waiting for {n} readings that cannot arrive")
            start = self._sweep_start(self._next_sweep)
            if start is None:
                raise ScpiError(-230, f"waiting for {n} readings: a bus trigger is pending")
            self.world.advance_to(max(self.world.now, start + self.sweep_s))

    def monitor_reading(self) -> float:
        """``ROUT:MON:DATA?``: the monitored channel's reading now — 9.91E37 with the Monitor mode
        off or no channel chosen (DAQ970A guide, p. 211).  A scan has priority over the Monitor
        (guide, p. 212): while one runs, the channel's latest scan reading (9.91E37 before it has
        one); idle, one reading over the aperture that has just ended (no time passes)."""
        ch = self.monitor_channel
        if not self.monitor_on or ch is None:
            return NOT_A_NUMBER
        if self.state != "IDLE":
            held = self.last_readings.get(ch)
            return NOT_A_NUMBER if held is None else float(held[-1, 0])
        fe = self.channels[ch].fe
        ap = fe.aperture_s
        t_start = np.array([max(self.world.now - ap, 0.0)])
        mean = self._input(ch, t_start, ap) + self.pickup.averaged(t_start, ap)
        return float(self.monitor_converter.convert(mean, fe)[0])

    # -- replies -------------------------------------------------------------------------
    def _format(self, rows: np.ndarray) -> str:
        """Readings as text: each ``value[,time][,channel]`` (``FORM:READ:TIME``/``CHAN``)."""
        if rows.shape[0] == 0:
            return ""
        columns, fields = [0], [READING_FORMAT]
        if self.format_time:
            columns.append(1)
            fields.append("%.6f")
        if self.format_channel:
            columns.append(2)
            fields.append("%d")
        row = ",".join(fields)  # one %-format over the whole reply: ~3x the speed of a loop
        return ",".join([row] * rows.shape[0]) % tuple(rows[:, columns].ravel().tolist())

    # -- SCPI vocabulary -----------------------------------------------------------------
    def _channels(self, args: Args, i: int) -> list[int]:
        return args.channel_list(i, min=SLOT_CHANNELS.start, max=SLOT_CHANNELS.stop - 1)

    def _last_channels(self, args: Args) -> tuple[list[int], int]:
        """The channel list that ends a command's parameters, and how many come before it."""
        if not args.count:
            raise ScpiError(-109, "a channel list (@...) is required")
        return self._channels(args, args.count - 1), args.count - 1

    def _register(self) -> None:
        c = self.command

        def idle() -> None:
            if self.state != "IDLE":
                raise ScpiError(-221, "settings conflict: a scan is in progress (ABOR first)")

        def conf_volt(args: Args) -> None:
            idle()
            chans, n = self._last_channels(args)
            rng, auto = 10.0, True
            if n >= 1 and args.raw[0].strip().upper() not in ("AUTO", "DEF", "DEFAULT"):
                rng, auto = args.number(0, min=0.1, max=300.0, default=10.0), False
            for ch in chans:
                fe = self.channels[ch].fe
                fe.autorange, fe.nplc, fe.autozero, fe.aperture_override_s = auto, 1.0, "ON", None
                fe.range_v = next(r for r in (0.1, 1.0, 10.0, 100.0, 300.0) if rng <= r * (1 + 1e-9))
            self.scan_list = sorted(set(chans))

        def per_channel_query(get: Callable[[_Channel], str]) -> Callable[[Args], str]:
            def query(args: Args) -> str:
                chans, _ = self._last_channels(args)
                return ",".join(get(self.channels[ch]) for ch in chans)
            return query

        def set_nplc(args: Args) -> None:
            idle()
            chans, n = self._last_channels(args)
            if n != 1:
                raise ScpiError(-109, "VOLT:NPLC <n>,(@list)")
            value = round_up_nplc(args.number(0, min=0.02, max=100.0, default=1.0), False)
            for ch in chans:
                self.channels[ch].fe.nplc = value

        def set_range(args: Args) -> None:
            idle()
            chans, n = self._last_channels(args)
            if n != 1:
                raise ScpiError(-109, "VOLT:RANG <volts>,(@list)")
            volts = args.number(0, min=0.0, max=300.0, default=10.0)
            for ch in chans:
                fe = self.channels[ch].fe
                fe.range_v = next(r for r in (0.1, 1.0, 10.0, 100.0, 300.0) if volts <= r * (1 + 1e-9))
                fe.autorange = False

        def set_autorange(args: Args) -> None:
            idle()
            chans, _ = self._last_channels(args)
            on = args.boolean(0)
            for ch in chans:
                self.channels[ch].fe.autorange = on

        def set_zero(args: Args) -> None:
            idle()
            chans, _ = self._last_channels(args)
            on = args.boolean(0)
            for ch in chans:
                self.channels[ch].fe.autozero = "ON" if on else "OFF"

        def set_scan(args: Args) -> None:
            idle()
            if args.count and args.raw[0].replace(" ", "") == "(@)":
                self.scan_list = []
                return
            self.scan_list = sorted(set(self._channels(args, 0)))

        def scan_q(args: Args) -> bytes:
            args.require_count(0)
            return channel_list_block(self.scan_list)

        def conf_q(args: Args) -> str:
            # CONF? (@list): one quoted "VOLT <range>,<resolution>" per channel, the form the
            # 34465A answers CONF? in; the resolution is the rms noise of the channel's NPLC
            chans, _ = self._last_channels(args)
            return ",".join(f'"VOLT {format_number(c.fe.range_v)},'
                            f'{format_number(noise_ppm(c.fe) * 1e-6 * c.fe.range_v)}"'
                            for c in (self.channels[ch] for ch in chans))

        def meas_q(args: Args) -> str:
            # the guide: MEAS? configures the channels, makes them the scan list, then READ?
            conf_volt(args)
            return read_q(args)

        def last_q(args: Args) -> str:
            chans, n = self._last_channels(args)
            if len(chans) != 1:
                raise ScpiError(-222, f"DATA:LAST? takes a single channel, got {len(chans)}")
            if n > 1:
                raise ScpiError(-108, "DATA:LAST? [<num_rdgs>,](@<channel>)")
            count = args.integer(0, min=1, max=LAST_READINGS, default=1) if n else 1
            held = self.last_readings.get(chans[0], np.empty((0, 3)))
            if held.shape[0] < count:  # the guide: more than are stored, or none, is an error
                raise ScpiError(-222, f"{count} readings of channel {chans[0]} requested, "
                                      f"{held.shape[0]} stored")
            return self._format(held[-count:])

        def set_monitor(args: Args) -> None:
            args.require_count(1)
            chans = self._channels(args, 0)
            if len(chans) != 1:
                raise ScpiError(-222, f"ROUT:MON takes a single channel, got {len(chans)}")
            self.monitor_channel = chans[0]

        def monitor_q(args: Args) -> bytes:
            args.require_count(0)
            return channel_list_block([] if self.monitor_channel is None else [self.monitor_channel])

        def set_delay(args: Args) -> None:
            idle()
            chans, n = self._last_channels(args)
            if n != 1:
                raise ScpiError(-109, "ROUT:CHAN:DEL <seconds>,(@list)")
            value = args.number(0, min=0.0, max=MAX_DELAY_S, default=0.0, units="S")
            for ch in chans:
                self.channels[ch].delay_s = round(value / 1e-6) * 1e-6
                self.channels[ch].delay_auto = False

        def set_delay_auto(args: Args) -> None:
            idle()
            chans, _ = self._last_channels(args)
            on = args.boolean(0)
            for ch in chans:
                self.channels[ch].delay_auto = on
                if on:
                    self.channels[ch].delay_s = AUTO_DELAY_S

        def set_close(args: Args) -> None:
            idle()
            chans = self._channels(args, 0)
            self.closed = {chans[-1]}  # a multiplexer closes one channel to the DMM at a time

        def set_open(args: Args) -> None:
            idle()
            self.closed -= set(self._channels(args, 0))

        def close_q(args: Args) -> str:
            return ",".join("1" if ch in self.closed else "0" for ch in self._channels(args, 0))

        def set_trig_sour(args: Args) -> None:
            idle()
            self.trig_source = args.choice(0, ["IMMediate", "TIMer", "BUS", "EXTernal"])

        def set_trig_tim(args: Args) -> None:
            idle()
            self.trig_timer_s = round(args.number(0, min=0.0, max=MAX_TIMER_S, default=1.0,
                                                  units="S") / 1e-3) * 1e-3

        def set_trig_coun(args: Args) -> None:
            idle()
            if args.keyword(0) == "INF":
                self.trig_count = INFINITE
            else:
                self.trig_count = float(args.integer(0, min=1, max=MAX_SWEEPS, default=1))

        def count_q(args: Args) -> str:
            return "+9.90000000E+37" if self.trig_count >= INFINITE else format_int(int(self.trig_count))

        def fetch_q(args: Args) -> str:
            if self.state != "IDLE":
                self.wait_complete()
            return self._format(self.memory.peek_all())

        def read_q(args: Args) -> str:
            self.initiate()
            return fetch_q(args)

        def r_q(args: Args) -> bytes:
            n = int(args.number(0, min=1, max=MEMORY_DEPTH)) if args.count else self.memory.count
            return format_block(self._format(self.memory.remove(n)).encode())

        def rem_q(args: Args) -> str:
            n = args.integer(0, min=1, max=MEMORY_DEPTH, default=1)
            if args.count > 1 and args.choice(1, ["WAIT"]):
                self._wait_for_points(n)
            if self.memory.count < n:
                raise ScpiError(-222, f"{n} readings requested, {self.memory.count} in memory")
            return self._format(self.memory.remove(n))

        def set_time_type(args: Args) -> None:
            if args.choice(0, ["ABSolute", "RELative"]) == "ABSOLUTE":
                raise ScpiError(-221, "FORM:READ:TIME:TYPE ABS: the simulated unit has no "
                                      "calendar; allowed: REL")
            self.time_type = "REL"

        def ctype_q(args: Args) -> str:
            slot = args.integer(0, min=100, max=300, default=100)
            if slot not in (100, 200, 300):
                raise ScpiError(-222, f"slot {slot} not in 100|200|300")
            return ("Keysight Technologies,DAQM901A,0,1.0" if slot == 100
                    else "Keysight Technologies,0,0,0")

        c("CONFigure[:VOLTage][:DC]", set=conf_volt)
        c("[SENSe:]VOLTage[:DC]:NPLCycles", set=set_nplc,
          query=per_channel_query(lambda ch: format_number(ch.fe.nplc)))
        c("[SENSe:]VOLTage[:DC]:RANGe", set=set_range,
          query=per_channel_query(lambda ch: format_number(ch.fe.range_v)))
        c("[SENSe:]VOLTage[:DC]:RANGe:AUTO", set=set_autorange,
          query=per_channel_query(lambda ch: "1" if ch.fe.autorange else "0"))
        c("[SENSe:]ZERO:AUTO", set=set_zero,
          query=per_channel_query(lambda ch: "1" if ch.fe.autozero == "ON" else "0"))
        c("ROUTe:SCAN", set=set_scan, query=scan_q)
        c("CONFigure", query=conf_q)
        c("MEASure[:VOLTage][:DC]", query=meas_q)
        c("[SENSe:]FUNCtion", query=per_channel_query(lambda ch: '"VOLT"'))
        c("DATA:LAST", query=last_q)
        c("ROUTe:MONitor[:CHANnel]", set=set_monitor, query=monitor_q)
        c("ROUTe:MONitor:STATe", set=lambda a: setattr(self, "monitor_on", a.boolean(0)),
          query=lambda a: "1" if self.monitor_on else "0")
        c("ROUTe:MONitor:DATA", query=lambda a: format_number(self.monitor_reading()))
        c("ROUTe:SCAN:SIZE", query=lambda a: format_int(len(self.scan_list)))
        c("ROUTe:CHANnel:DELay", set=set_delay,
          query=per_channel_query(lambda ch: format_number(ch.delay_s)))
        c("ROUTe:CHANnel:DELay:AUTO", set=set_delay_auto,
          query=per_channel_query(lambda ch: "1" if ch.delay_auto else "0"))
        c("ROUTe:CLOSe", set=set_close, query=close_q)
        c("ROUTe:OPEN", set=set_open)
        c("ROUTe:DONE", query=lambda a: "1" if self.state == "IDLE" else "0")
        c("TRIGger:SOURce", set=set_trig_sour, query=lambda a: self.trig_source[:3]
          if self.trig_source != "IMMEDIATE" else "IMM")
        c("TRIGger:TIMer", set=set_trig_tim, query=lambda a: format_number(self.trig_timer_s))
        c("TRIGger:COUNt", set=set_trig_coun, query=count_q)
        c("INITiate[:IMMediate]", set=lambda a: self.initiate())
        c("ABORt", set=lambda a: self.abort())
        c("FETCh", query=fetch_q)
        c("READ", query=read_q)
        c("R", query=r_q)
        c("DATA:POINts", query=lambda a: format_int(self.memory.count))
        c("DATA:REMove", query=rem_q)
        c("FORMat:READing:TIME", set=lambda a: setattr(self, "format_time", a.boolean(0)),
          query=lambda a: "1" if self.format_time else "0")
        c("FORMat:READing:TIME:TYPE", set=set_time_type, query=lambda a: self.time_type)
        c("FORMat:READing:CHANnel", set=lambda a: setattr(self, "format_channel", a.boolean(0)),
          query=lambda a: "1" if self.format_channel else "0")
        c("SYSTem:CTYPe", query=ctype_q)
        c("SYSTem:LFRequency", query=lambda a: format_int(int(self.pickup.nominal_hz)))


__all__ = ["ScanningDaq", "InputSignal", "SLOT_CHANNELS", "RELAY_CLOSE_S", "AUTO_DELAY_S",
           "READING_OVERHEAD_S", "MEMORY_DEPTH", "LAST_READINGS", "channel_list_block"]
