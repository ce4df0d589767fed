"""Fault injection: the simulated station's instruments misbehave on request.

Faults are part of the seeded world: they act at a simulated instant (now, or a scheduled
``at_s``), and every random choice they make (which reply is garbled, which frame is lost)
comes from the instrument's own generator ``world.rng("fault:<name>")``.  The same seed and
the same fault schedule therefore give the same bytes on the wire.  The one wall-clock
fault is ``slow`` (a reply delay in milliseconds), which exists to exercise driver timeouts.

Kinds (the sim-control vocabulary is in docs/ARCHITECTURE.md):

========== =============================== ============================================
kind       instruments                     effect
========== =============================== ============================================
drop       all                             the server closes the client connection(s);
                                           reconnects are accepted and closed at once
                                           for ``refuse_s`` simulated seconds
stall      all                             messages are discarded unanswered (gyro: no
                                           frames either) for ``duration_s`` (inf: until
                                           cleared)
slow       SCPI                            each reply is held back ``delay_ms`` (wall)
garble     SCPI                            with probability ``probability`` a reply gets
                                           one byte flipped or inserted (the terminator
                                           is kept)
error      SCPI                            the next ``count`` messages are refused: not
                                           executed, ``code`` queued, no reply (error-
                                           queue and status reads still work)
frame      gyro                            each frame corrupted (one byte) with
                                           probability ``corrupt``, lost with ``loss``
power      all                             the instrument loses power: silent, outputs
                                           to zero (supply outputs off, DMM acquisition
                                           lost, table drives off, shaker drive cut,
                                           gyro unpowered); clearing powers it back up
                                           in its power-on state
interlock  turntable, angular_table        the interlock trips: drives off, status bits
                                           16 and 32, latched until ``:INT:RES``
overload   dmm, dmm_temp, dmm_mhd          the input is forced to ``volts`` (default
                                           1e4 V, beyond every range): readings ±9.9E37
========== =============================== ============================================
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from sim.devices.angular_table import AngularTableController
from sim.devices.dmm import Multimeter
from sim.devices.fog_serial import FogSerialDevice
from sim.devices.shaker import ShakerController
from sim.devices.supply import PowerSupply
from sim.devices.turntable import TurntableController
from sim.scpi import ScpiDevice
from sim.world import World

SCPI_KINDS = ("drop", "stall", "slow", "garble", "error", "power")
SERIAL_KINDS = ("drop", "stall", "frame", "power")
FRAME_BYTES = 20
#: longest slow-reply delay (wall ms): long enough for any timeout test, never a hang
MAX_DELAY_MS = 60_000.0
DEFAULT_OVERLOAD_V = 1e4
#: messages that still work under an ``error`` fault (reading the errors must be possible)
_ERROR_EXEMPT = (b"SYST:ERR", b"SYSTEM:ERR", b":SYST:ERR", b":SYSTEM:ERR", b"*CLS", b"*ESR?",
                 b"*STB?")


class FaultTargetError(ValueError):
    """An unknown instrument, or a fault kind the instrument does not have."""


@dataclass
class _State:
    """One instrument's active faults."""

    stall_until_s: float = -math.inf
    refuse_until_s: float = -math.inf
    delay_s: float = 0.0
    garble_p: float = 0.0
    error_count: int = 0
    error_code: int = 0
    frame_corrupt_p: float = 0.0
    frame_loss_p: float = 0.0
    powered: bool = True
    #: (t_from_s, t_to_s, volts) intervals of a forced DMM input
    overloads: list[tuple[float, float, float]] = field(default_factory=list)


def _number(name: str, value: Any, lo: float, hi: float) -> float:
    ok = not isinstance(value, bool) and isinstance(value, (int, float)) and not math.isnan(value)
    if not ok or not lo <= value <= hi:
        raise ValueError(f"{name} = {value!r} not in {lo:g}..{hi:g}")
    return float(value)


class Gate:
    """What the server asks about one instrument's connections and messages."""

    def __init__(self, injector: FaultInjector, name: str) -> None:
        self.injector, self.name = injector, name
        self.state = _State()
        self.writers: set[Any] = set()
        self.rng_name = f"fault:{name}"
        self.serial = isinstance(injector.devices[name], FogSerialDevice)

    @property
    def _now(self) -> float:
        return self.injector.world.now

    def admit(self, writer: Any) -> bool:
        """A client connects: False = close it at once (reconnects refused for a while)."""
        # a serial server stays up when the unit behind it loses power; a LAN port does not
        if self._now < self.state.refuse_until_s or not (self.state.powered or self.serial):
            return False
        self.writers.add(writer)
        return True

    def release(self, writer: Any) -> None:
        self.writers.discard(writer)

    def silent(self) -> bool:
        """Stalled or unpowered: messages are discarded unanswered."""
        return not self.state.powered or self._now < self.state.stall_until_s

    def intercept(self, device: ScpiDevice, message: bytes) -> bool:
        """True when ``message`` must not reach the device (stall, power, error fault)."""
        if self.silent():
            return True
        s = self.state
        if s.error_count > 0 and not message.lstrip().upper().startswith(_ERROR_EXEMPT):
            s.error_count -= 1
            device.push_error(s.error_code, "injected fault")
            return True
        return False

    def outgoing(self, reply: bytes) -> tuple[bytes, float]:
        """The reply as it leaves (maybe garbled) and its delay in wall seconds."""
        s = self.state
        if s.garble_p > 0:
            rng = self.injector.world.rng(self.rng_name)
            if rng.random() < s.garble_p:
                reply = _garble(reply, rng)
        return reply, s.delay_s

    def transmit(self, data: bytes) -> bytes:
        """Serial frames on their way out (gyro line): stall, power, corruption, loss."""
        if self.silent():
            return b""
        s = self.state
        if not (s.frame_corrupt_p or s.frame_loss_p) or len(data) % FRAME_BYTES:
            return data
        rng = self.injector.world.rng(self.rng_name)
        frames = np.frombuffer(data, dtype=np.uint8).reshape(-1, FRAME_BYTES).copy()
        n = frames.shape[0]
        corrupt = rng.random(n) < s.frame_corrupt_p
        lost = rng.random(n) < s.frame_loss_p
        k = int(corrupt.sum())
        if k:
            pos = rng.integers(0, FRAME_BYTES, k)
            frames[np.flatnonzero(corrupt), pos] ^= rng.integers(1, 256, k).astype(np.uint8)
        self.injector.frames_corrupted += k
        self.injector.frames_lost += int(lost.sum())
        return frames[~lost].tobytes()

    def drop(self) -> None:
        for writer in list(self.writers):
            try:
                writer.transport.abort()  # no flush: the cable is gone
            except Exception:
                pass
        self.writers.clear()


def _garble(reply: bytes, rng: np.random.Generator) -> bytes:
    """One byte flipped or inserted before the terminator (never a new terminator)."""
    body, end = (reply[:-1], reply[-1:]) if reply.endswith(b"\n") else (reply, b"")
    buf = bytearray(body)
    if buf and rng.random() < 0.5:
        pos = int(rng.integers(len(buf)))
        bit = int(rng.integers(8))
        flipped = buf[pos] ^ (1 << bit)
        # a flip that would make a terminator flips the next bit instead (still one change)
        buf[pos] = flipped if flipped != 0x0A else buf[pos] ^ (1 << ((bit + 1) % 8))
    else:
        byte = int(rng.integers(0, 255))
        buf.insert(int(rng.integers(len(buf) + 1)), byte if byte != 0x0A else 0xFF)
    return bytes(buf) + end


class FaultInjector:
    """Per-instrument faults of one simulated station (``station.faults``).

    ``devices`` maps instrument names to their simulated devices; ``call`` runs a function
    on the server thread (the world is only touched there); ``gyro_volts`` gives a serial
    unit's supply voltage now (to power it back up after a power fault): one callable for
    every serial line, or a dict of them by instrument name.
    """

    def __init__(self, world: World, devices: dict[str, Any],
                 call: Callable[..., Any] | None = None,
                 gyro_volts: Callable[[], float] | dict[str, Callable[[], float]] | None = None) -> None:
        self.world, self.devices = world, dict(devices)
        self.call = call or (lambda fn, *a: fn(*a))
        self.gyro_volts = gyro_volts
        self.gates = {name: Gate(self, name) for name in self.devices}
        self.frames_corrupted = 0
        self.frames_lost = 0
        for name, dev in self.devices.items():
            if isinstance(dev, FogSerialDevice):
                dev.fault_hook = self.gates[name]
            if isinstance(dev, Multimeter):
                dev.input_signal = self._forced_input(self.gates[name], dev.input_signal)

    # -- public API ----------------------------------------------------------------------
    def kinds(self, instrument: str) -> tuple[str, ...]:
        dev = self._device(instrument)
        kinds = SERIAL_KINDS if isinstance(dev, FogSerialDevice) else SCPI_KINDS
        if isinstance(dev, (TurntableController, AngularTableController)):
            kinds += ("interlock",)
        if isinstance(dev, Multimeter):
            kinds += ("overload",)
        return kinds

    def inject(self, kind: str, instrument: str, *, at_s: float | None = None, **params: Any) -> None:
        """Inject ``kind`` into ``instrument`` now or at simulated time ``at_s``.

        Parameters by kind: drop(refuse_s=0), stall(duration_s=inf), slow(delay_ms),
        garble(probability), error(count=1, code=-300), frame(corrupt=0, loss=0), power(),
        interlock(), overload(volts=1e4).  Bad values raise ValueError at once.
        """
        action = self.prepare(kind, instrument, params)
        if at_s is None:
            self.call(action)
        else:
            t = _number("at_s", at_s, 0.0, math.inf)
            self.call(lambda: self.world.schedule(max(t, self.world.now), action,
                                                  name=f"fault {kind} {instrument}"))

    def clear(self, instrument: str = "ALL") -> None:
        """End every active fault of ``instrument`` (or of all, ``"ALL"``)."""
        names = list(self.devices) if instrument.upper() == "ALL" else [self._name(instrument)]
        self.call(lambda: [self._clear(n) for n in names])

    def active(self) -> dict[str, list[str]]:
        """``{instrument: [kind, ...]}`` of the faults in force now."""
        out = {}
        for name, gate in self.gates.items():
            s, now = gate.state, self.world.now
            kinds = [k for k, on in (
                ("drop", now < s.refuse_until_s), ("stall", now < s.stall_until_s),
                ("slow", s.delay_s > 0), ("garble", s.garble_p > 0), ("error", s.error_count > 0),
                ("frame", s.frame_corrupt_p > 0 or s.frame_loss_p > 0), ("power", not s.powered),
                ("overload", bool(s.overloads) and s.overloads[-1][1] == math.inf)) if on]
            if kinds:
                out[name] = kinds
        return out

    # -- applying (server thread) -------------------------------------------------------------
    def _name(self, instrument: str) -> str:
        for name in self.devices:
            if name.lower() == str(instrument).strip().lower():
                return name
        raise FaultTargetError(f"instrument {instrument!r} not in {'|'.join(self.devices)}")

    def _device(self, instrument: str) -> Any:
        return self.devices[self._name(instrument)]

    def prepare(self, kind: str, instrument: str, params: dict) -> Callable[[], None]:
        """Validate ``kind`` and ``params`` now; return the action that applies them."""
        name = self._name(instrument)
        kind = str(kind).lower()
        if kind not in self.kinds(name):
            raise FaultTargetError(f"fault {kind!r} not in {'|'.join(self.kinds(name))} for {name}")
        allowed = {"drop": {"refuse_s": 0.0}, "stall": {"duration_s": math.inf},
                   "slow": {"delay_ms": None}, "garble": {"probability": None},
                   "error": {"count": 1, "code": -300}, "frame": {"corrupt": 0.0, "loss": 0.0},
                   "power": {}, "interlock": {}, "overload": {"volts": DEFAULT_OVERLOAD_V}}[kind]
        unknown = set(params) - set(allowed)
        if unknown:
            raise ValueError(f"fault {kind} takes {sorted(allowed) or 'no parameters'}, "
                             f"not {sorted(unknown)}")
        p = {**allowed, **params}
        missing = [k for k, v in p.items() if v is None]
        if missing:
            raise ValueError(f"fault {kind} needs {missing}")
        gate, dev = self.gates[name], self.devices[name]
        s = gate.state
        if kind == "drop":
            refuse = _number("refuse_s", p["refuse_s"], 0.0, math.inf)

            def act() -> None:
                s.refuse_until_s = self.world.now + refuse
                gate.drop()
        elif kind == "stall":
            dur = _number("duration_s", p["duration_s"], 0.0, math.inf)
            act = lambda: setattr(s, "stall_until_s", self.world.now + dur)
        elif kind == "slow":
            delay = _number("delay_ms", p["delay_ms"], 0.0, MAX_DELAY_MS) / 1000.0
            act = lambda: setattr(s, "delay_s", delay)
        elif kind == "garble":
            prob = _number("probability", p["probability"], 0.0, 1.0)
            act = lambda: setattr(s, "garble_p", prob)
        elif kind == "error":
            count = _number("count", p["count"], 1, 1e6)
            code = _number("code", p["code"], -999, 32767)
            if count != int(count) or code != int(code) or code == 0:
                raise ValueError(f"error fault: count {count!r} and code {code!r} must be whole, "
                                 "code non-zero in -999..32767")

            def act() -> None:
                s.error_count, s.error_code = int(count), int(code)
        elif kind == "frame":
            corrupt = _number("corrupt", p["corrupt"], 0.0, 1.0)
            loss = _number("loss", p["loss"], 0.0, 1.0)

            def act() -> None:
                s.frame_corrupt_p, s.frame_loss_p = corrupt, loss
        elif kind == "power":
            act = lambda: self._power_off(name, dev)
        elif kind == "interlock":
            act = lambda: self._trip(dev)
        else:
            volts = _number("volts", p["volts"], -1e6, 1e6)

            def act() -> None:
                self._end_overload(s)
                s.overloads.append((self.world.now, math.inf, volts))
        return lambda: (act(), self.world.note(f"fault {kind} {name}"))

    def _power_off(self, name: str, dev: Any) -> None:
        gate, now = self.gates[name], self.world.now
        if not gate.state.powered:
            return
        gate.state.powered = False
        if not gate.serial:
            gate.drop()  # a dead instrument's network interface is gone too
        if isinstance(dev, PowerSupply):
            for ch in dev.channels.values():
                ch.output = False
            dev._changed()
        elif isinstance(dev, Multimeter):
            dev.abort()
            dev.memory.clear()
        elif isinstance(dev, TurntableController):
            for axis in dev.table.axes:
                axis.command_off(now)
        elif isinstance(dev, ShakerController):
            dev.shaker.abort(now)
        elif isinstance(dev, AngularTableController):
            dev.cut_drive()
        elif isinstance(dev, FogSerialDevice):
            dev.gyro.set_supply(now, 0.0)
            dev.power_changed(now)

    def _power_on(self, name: str, dev: Any) -> None:
        gate = self.gates[name]
        if gate.state.powered:
            return
        gate.state.powered = True
        if isinstance(dev, FogSerialDevice):
            source = self.gyro_volts.get(name) if isinstance(self.gyro_volts, dict) else self.gyro_volts
            volts = source() if source is not None else 0.0
            dev.gyro.set_supply(self.world.now, volts)
            dev.power_changed(self.world.now)
            return
        dev.reset()  # power-on state; the error queue is empty, PON set
        dev._errors.clear()
        dev.esr = 0x80

    def _trip(self, dev: TurntableController | AngularTableController) -> None:
        if isinstance(dev, AngularTableController):
            dev.open_interlock()  # drive cut, ABORT latched until the interlock is reset
            return
        dev.tripped = True
        for axis in dev.table.axes:  # drives disabled: the axes coast to rest
            axis.command_off(self.world.now)

    def _end_overload(self, s: _State) -> None:
        if s.overloads and s.overloads[-1][1] == math.inf:
            t0, _, v = s.overloads[-1]
            s.overloads[-1] = (t0, self.world.now, v)

    def _clear(self, name: str) -> None:
        s = self.gates[name].state
        s.stall_until_s = s.refuse_until_s = -math.inf
        s.delay_s = s.garble_p = s.frame_corrupt_p = s.frame_loss_p = 0.0
        s.error_count = 0
        self._end_overload(s)
        self._power_on(name, self.devices[name])
        self.world.note(f"faults cleared {name}")

    @staticmethod
    def _forced_input(gate: Gate, base: Callable[[np.ndarray, float], np.ndarray]):
        def signal(t_start: np.ndarray, aperture_s: float) -> np.ndarray:
            volts = base(t_start, aperture_s)
            for t0, t1, v in gate.state.overloads:
                volts = np.where((t_start >= t0) & (t_start < t1), v, volts)
            return volts
        return signal

