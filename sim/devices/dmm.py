"""Simulated Keysight 34465A digital multimeter: the trigger model and reading memory, as a
view of the World (its command vocabulary is in ``sim.devices.dmm_scpi``).

Trigger model (as the real instrument): ``INIT`` → *wait-for-trigger*; each trigger
(``TRIG:SOUR IMM`` immediately, ``BUS`` on ``*TRG``) waits ``TRIG:DEL`` then takes
``SAMP:COUN`` readings, spaced by ``SAMP:TIM`` (``SAMP:SOUR TIM``) or back to back
(``IMM``); after ``TRIG:COUN`` triggers the meter returns to idle.  Readings go to a
FIFO reading memory (50 000 readings, 2 000 000 with the MEM option); when it overflows
the oldest readings are lost and questionable-data bit 14 is set.

``TRIG:SOUR EXT`` is accepted and waits for an edge on the Ext Trig input, which nothing
on the simulated station drives (as a real meter with the BNC left open).  Level
triggering (``TRIG:SOUR INT``) and pretrigger capture (``SAMP:COUN:PRET`` > 0) sample
continuously from ``INIT`` (``sim.devices.dmm_capture``); they take one trigger
(``TRIG:COUN 1``; more is refused at ``INIT`` with -221).

Virtual time: readings appear as the world advances (this object is a World activity).
Queries that block on the real meter (``FETC?``/``READ?`` before the acquisition ends,
``*OPC?``, ``DATA:REM? n,WAIT``) let simulated time pass until they can answer.  A wait
that can never end (bus trigger pending, infinite trigger count) is answered with
``-230`` in the error queue and no response — the client times out, as with hardware.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable

import numpy as np

from sim.devices.dmm_capture import CaptureGrid
from sim.devices.dmm_model import DmmConverter, DmmFrontEnd, ForcedInput, LinePickup
from sim.devices.dmm_scpi import Keysight34465AVocabulary
from sim.devices.lifecycle import scpi_power_on
from sim.scpi import ScpiError
from sim.world import World

#: the source the DMM's input terminals are wired to: (start times, aperture) -> mean volts
InputSignal = Callable[[np.ndarray, float], np.ndarray]
MAX_BATCH = 500_000  # readings generated per step, bounds memory per advance
#: how long a query waits (simulated s) for a level trigger before giving up (-230, no reply)
LEVEL_WAIT_S = 60.0


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

    def keep_newest(self, n: int) -> None:
        """Drop all but the ``n`` newest readings (a pretrigger ring: no overflow flag)."""
        while self.count > n:
            excess = self.count - n
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


class Multimeter(Keysight34465AVocabulary):
    """34465A view of the world. ``input_signal`` is wired by the station."""

    memory: _Memory
    fault_kinds: tuple[str, ...] = ("power", "overload")

    def __init__(self, world: World, name: str, input_signal: InputSignal,
                 serial: str = "MY59001234", options: tuple[str, ...] = ("DIG", "MEM"),
                 line_pickup: LinePickup | None = None, ideal: bool = False,
                 timebase_ppm: float = 0.0) -> None:
        super().__init__(("Keysight Technologies", "34465A", serial,
                          "A.03.01-02.40-03.01-00.52-01-02"),
                         options=",".join(options) if options else "0")
        self.world, self.name, self.input_signal = world, name, input_signal
        if not (isinstance(timebase_ppm, (int, float)) and abs(timebase_ppm) <= 1000):
            raise ValueError(f"timebase_ppm {timebase_ppm!r} not in -1000..1000 ppm")
        #: the meter's timebase runs slow by this much: a SAMP:TIM interval lasts (1 + ppm·1e-6)× longer
        self.timebase_ppm = float(timebase_ppm)
        self.has_dig = "DIG" in options
        self.memory = _Memory(2_000_000 if "MEM" in options else 50_000)
        self.pickup = line_pickup or LinePickup()
        self.converter = DmmConverter(world.rng(f"{name}.converter"), noise_scale=0.0 if ideal else 1.0)
        self.format_real = False
        self.swapped = False
        self.forced = ForcedInput()  # the overload fault's windows
        self._defaults()
        self._register()

    # -- state ---------------------------------------------------------------------------
    def _defaults(self) -> None:
        self.fe = DmmFrontEnd(line_hz=self.pickup.nominal_hz)
        self.trig_source, self.trig_count, self.trig_delay_s = "IMMEDIATE", 1.0, 0.0
        self.trig_delay_auto = True
        self.trig_slope = "NEG"      # Ext Trig edge / level-trigger direction (*RST: NEG)
        self.trig_level_v = 0.0      # level of TRIG:SOUR INT (*RST: 0 V)
        self.pretrigger_count = 0    # SAMP:COUN:PRET (*RST: 0)
        self.display, self.display_on = "", True
        self.beeper_on = True
        self.impedance_auto = False  # 10 MOhm on every range (*RST); the loading is not modelled
        self.samp_source, self.samp_count, self.samp_timer_s = "IMMEDIATE", 1, 1.0
        self.state = "IDLE"  # IDLE | WAIT_TRIGGER | ACQUIRING
        self.aperture_value_s = 0.1  # VOLT:APER value (used only while enabled)
        # the current *segment*: readings of one or more back-to-back triggers
        self._seg_t0 = 0.0           # time of the trigger that started it
        self._seg_triggers = 1.0     # triggers in it (IMM: all remaining; BUS: one)
        self._g = 0                  # next reading index within it
        self._triggers_done = 0.0
        self._capture: CaptureGrid | None = None  # level-triggered / pretrigger acquisition

    def reset(self) -> None:
        self.abort()
        self._defaults()
        self.memory.clear()
        self.memory.last = np.nan
        self.format_real, self.swapped = False, False

    # -- lifecycle (sim.devices.lifecycle) ------------------------------------------------
    def power_off(self) -> None:
        """Power lost: the acquisition and the reading memory are gone."""
        self.abort()
        self.memory.clear()

    def power_on(self) -> None:
        scpi_power_on(self)

    @property
    def overloaded(self) -> bool:
        return self.forced.active

    def overload(self, volts: float) -> None:
        """The input forced to ``volts`` from now on (beyond range: readings ±9.9E37)."""
        self.forced.force(self.world.now, volts)

    def end_overload(self) -> None:
        self.forced.release(self.world.now)

    def _input_volts(self, t_start: np.ndarray, aperture_s: float) -> np.ndarray:
        """The input terminals' mean volts over each aperture, forced where an overload was."""
        volts = self.input_signal(t_start, aperture_s)
        return self.forced.apply(t_start, volts)

    @property
    def delay_s(self) -> float:
        # Auto delay for DCV: 1.5 ms up to 1 NPLC (settling), none above (data sheet table).
        return (0.0015 if self.fe.nplc <= 1 else 0.0) if self.trig_delay_auto else self.trig_delay_s

    @property
    def interval_s(self) -> float:
        """Spacing of readings within a trigger; a timer shorter than a reading is stretched."""
        if self.samp_source == "TIMER":
            return max(self.samp_timer_s * (1.0 + 1e-6 * self.timebase_ppm), self.fe.reading_time_s)
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
        level = self.trig_source == "INTERNAL"
        if level and not self.fe.autorange and abs(self.trig_level_v) > 1.2 * self.fe.range_v:
            # the guide: a level outside ±120 % of a manual range reverts the source to IMM
            self.push_error(-221, f"TRIG:LEV {self.trig_level_v:g} V outside +-120 % of the "
                                  f"{self.fe.range_v:g} V range: trigger source set to IMM")
            self.trig_source, level = "IMMEDIATE", False
        continuous = level or self.pretrigger_count > 0
        if continuous and self.trig_count != 1:
            raise ScpiError(-221, f"TRIG:COUN {_count_text(self.trig_count)} with level trigger or "
                                  "pretrigger: the simulated meter takes one such trigger (TRIG:COUN 1)")
        if self.pretrigger_count >= self.samp_count:
            raise ScpiError(-221, f"SAMP:COUN:PRET {self.pretrigger_count} not below SAMP:COUN "
                                  f"{self.samp_count}")
        self.memory.clear()
        self._triggers_done = 0.0
        self._capture = None
        self.state = "WAIT_TRIGGER"
        self.world.add_activity(self)
        if continuous:
            self._capture = CaptureGrid(
                t_arm=self.world.now, interval_s=self.interval_s, aperture_s=self.fe.aperture_s,
                delay_s=self.delay_s, pretrigger=self.pretrigger_count,
                post_count=self.samp_count - self.pretrigger_count,
                level_v=self.trig_level_v if level else None, slope=self.trig_slope)
            if level:
                # the comparator knows the input as it stands at INIT, so an edge in the same
                # instant (INIT, then a supply switched on, with no time between) still counts
                now = np.array([self.world.now])
                self._capture.previous_v = float(self._input_volts(now, self.fe.aperture_s)[0]
                                                 + self.pickup.averaged(now, self.fe.aperture_s)[0])
            if self.trig_source == "IMMEDIATE":
                self._capture.trigger_at_arm()
        elif self.trig_source == "IMMEDIATE":
            self._fire(self.world.now, self.trig_count)

    def _fire(self, t: float, triggers: float) -> None:
        self._seg_t0, self._seg_triggers, self._g = t, triggers, 0
        self.state = "ACQUIRING"

    def trigger(self) -> None:
        if self.state == "WAIT_TRIGGER" and self.trig_source == "BUS":
            if self._capture is not None:
                self._capture.trigger_now(self.world.now)
                self.state = "ACQUIRING"
            else:
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
            # the instrument's own failure, whichever session's message let time run: every session
            self.instrument_error(-240, f"measurement failed: {type(exc).__name__}: {exc}")

    def _take(self, t_start: np.ndarray) -> np.ndarray:
        """Readings whose apertures start at ``t_start`` (increasing, in time order)."""
        ap = self.fe.aperture_s
        mean_v = self._input_volts(t_start, ap) + self.pickup.averaged(t_start, ap)
        return self.converter.convert(mean_v, self.fe)

    def _run_capture(self, t: float) -> None:
        """The continuous acquisition (level trigger, pretrigger) up to ``t``."""
        cap = self._capture
        assert cap is not None
        while self.state != "IDLE":
            stop = cap.due(t)
            if cap.end_index is not None:
                stop = min(stop, cap.end_index)
            n = min(stop - cap.next_index, MAX_BATCH)
            if n <= 0:
                return
            first = cap.next_index
            values = self._take(cap.t_start(np.arange(first, first + n, dtype=np.float64)))
            if cap.trigger_index is None:
                hit = cap.crossing(values)
                if hit is not None:
                    cap.trigger_index = first + hit
            pre = n if cap.trigger_index is None else min(n, cap.trigger_index - first + 1)
            if pre > 0:
                self.memory.push(values[:pre])
                self.memory.keep_newest(cap.pretrigger)
            if cap.trigger_index is not None:
                self.state = "ACQUIRING"
                end = cap.end_index
                assert end is not None
                lo, hi = max(cap.first_post_index - first, 0), min(end - first, n)
                if hi > lo:
                    self.memory.push(values[lo:hi])
            cap.previous_v = float(values[-1])
            cap.next_index += n
            if cap.end_index is not None and cap.next_index >= cap.end_index:
                self.abort()
                return

    def _run_until(self, t: float) -> None:
        if self._capture is not None:
            self._run_capture(t)
            return
        while self.state == "ACQUIRING":
            due = self._due(t)
            if due - self._g > self.memory.depth:
                self._g = due - self.memory.depth
                self.memory.clear()
                self.memory.overflowed = True
            n = min(due - self._g, MAX_BATCH)
            if n > 0:
                g = np.arange(self._g, self._g + n, dtype=np.float64)
                self.memory.push(self._take(self._t_start(g)))
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
        if self._capture is not None:
            return self._capture.completion_time()
        last_segment = self._triggers_done + self._seg_triggers >= self.trig_count
        if self.state != "ACQUIRING" or not last_segment or self._seg_total >= 9.9e37:
            return None
        return self._t_end(self._seg_total - 1)

    def _wait_for_level(self) -> None:
        """Let simulated time pass, up to LEVEL_WAIT_S, until the level trigger fires."""
        cap = self._capture
        if cap is None or cap.level_v is None:
            return
        give_up = self.world.now + LEVEL_WAIT_S
        # steps from the acquisition's own length, doubling to 1 s: time overshoots the
        # crossing by at most one step, and a crossing that came already costs nothing
        step = max(cap.post_count * cap.interval_s, 1e-3)
        while cap.trigger_index is None and self.state != "IDLE" and self.world.now < give_up:
            self.world.advance_to(min(give_up, self.world.now + step))
            step = min(2 * step, 1.0)

    def wait_complete(self) -> None:
        if self.completion_time() is None:
            self._wait_for_level()
        t_end = self.completion_time()
        if t_end is None:
            raise ScpiError(-230, "acquisition waits for a trigger that cannot arrive"
                            + (f" (no level crossing within {LEVEL_WAIT_S:g} s)"
                               if self._capture is not None and self._capture.level_v is not None else ""))
        self.world.advance_to(max(t_end, self.world.now))

    def _wait_for_points(self, n: int) -> None:
        """Let simulated time pass until ``n`` readings are in memory."""
        if self._capture is not None:
            self._wait_for_capture_points(n)
            return
        while self.memory.count < n:
            missing = n - self.memory.count
            if self.state != "ACQUIRING" or self._g + missing > self._seg_total:
                raise ScpiError(-230, f"waiting for {n} readings that cannot arrive")
            self.world.advance_to(max(self.world.now, self._t_end(self._g + missing - 1)))

    def _wait_for_capture_points(self, n: int) -> None:
        cap = self._capture
        assert cap is not None
        self._wait_for_level()
        while self.memory.count < n:
            end = cap.end_index
            if self.state == "IDLE" or end is None:
                raise ScpiError(-230, f"waiting for {n} readings that cannot arrive")
            # readings still to come at most: the rest of the acquisition
            ahead = cap.next_index + (n - self.memory.count) + max(cap.first_post_index - cap.next_index, 0)
            target = cap.time_of_reading(max(min(ahead, end) - 1, cap.next_index))  # at least one more
            self.world.advance_to(max(self.world.now, target))


def _count_text(count: float) -> str:
    return "INF" if count >= 9.9e37 else f"{count:g}"


__all__ = ["Multimeter"]

