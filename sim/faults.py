"""Fault injection: the simulated station's instruments misbehave on request.

Faults are part of the seeded world: they act at a simulated instant (now, or a scheduled
``at_s``), and every random choice they make (which reply is garbled, which frame is lost)
comes from the instrument's own generator ``world.rng("fault:<name>")``.  The same seed and
the same fault schedule therefore give the same bytes on the wire.  The one wall-clock
fault is ``slow`` (a reply delay in milliseconds), which exists to exercise driver timeouts.

Which faults an instrument has is not decided here: its wire offers some
(``sim.server.Transport.wire_fault_kinds``) and the device declares its own
(``fault_kinds``, with the hooks of ``sim.devices.lifecycle``).  This module keeps the wire's
fault state (a :class:`Gate` per instrument, which the transport consults) and calls the
device's hooks; it never looks inside a device.

Kinds (the sim-control vocabulary is in docs/ARCHITECTURE.md):

========== =============================== ============================================
kind       offered by                      effect
========== =============================== ============================================
drop       every wire                      the server closes the client connection(s);
                                           reconnects are accepted and closed at once
                                           for ``refuse_s`` simulated seconds
stall      every wire                      messages are discarded unanswered (gyro: no
                                           frames either) for ``duration_s`` (inf: until
                                           cleared)
slow       the SCPI wire                   each reply is held back ``delay_ms`` (wall)
garble     the SCPI wire                   with probability ``probability`` a reply gets
                                           one byte flipped or inserted (the terminator
                                           is kept)
error      the SCPI wire                   the next ``count`` messages are refused: not
                                           executed, ``code`` queued, no reply (error-
                                           queue and status reads still work)
frame      a frame-streaming device        each frame corrupted (one byte) with
           (the gyro lines)                probability ``corrupt``, lost with ``loss``
power      every device                    the instrument loses power: silent (a LAN
                                           instrument's connections dropped), outputs
                                           to zero (``power_off``: supply outputs off,
                                           DMM acquisition lost, table drives off, shaker
                                           drive cut, gyro unpowered); clearing powers it
                                           back up (``power_on``: its power-on state)
interlock  a device with an interlock      ``trip_interlock``: drives off, latched until
           (turntable, angular_table)      ``:INT:RES``
overload   a meter (dmm, dmm_temp,         ``overload(volts)``: the input forced to
           dmm_mhd)                        ``volts`` (default 1e4 V, beyond every range):
                                           readings ±9.9E37
limit      a controller with an over-      ``trip_limit``: heating and cooling cut,
           temperature limit (chamber)     latched until the limit is cleared over its wire
alarm      a controller with alarms        ``raise_alarm``: an alarm active (the chamber's
           (chamber)                       alarm 2 high), latched until cleared
========== =============================== ============================================
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, cast

import numpy as np

from sim.devices.lifecycle import AlarmingDevice, InterlockedDevice, LimitDevice, OverloadableDevice, SimDevice
from sim.scpi import ScpiDevice
from sim.server import Transport
from sim.world import World

#: longest slow-reply delay (wall ms): long enough for any timeout test, never a hang
MAX_DELAY_MS = 60_000.0
DEFAULT_OVERLOAD_V = 1e4
#: every kind's parameters with their defaults (None: required)
PARAMETERS: dict[str, dict[str, float | None]] = {
    "drop": {"refuse_s": 0.0}, "stall": {"duration_s": math.inf}, "slow": {"delay_ms": None},
    "garble": {"probability": None}, "error": {"count": 1, "code": -300},
    "frame": {"corrupt": 0.0, "loss": 0.0}, "power": {}, "interlock": {},
    "overload": {"volts": DEFAULT_OVERLOAD_V}, "limit": {}, "alarm": {}}
#: messages that still work under an ``error`` fault (reading the errors must be possible)
_ERROR_EXEMPT = (b"SYST:ERR", b"SYSTEM:ERR", b":SYST:ERR", b":SYSTEM:ERR", b"*CLS", b"*ESR?",
                 b"*STB?")


class FaultTargetError(ValueError):
    """An unknown instrument, or a fault kind the instrument does not have."""


@dataclass
class _State:
    """One instrument's active faults on its wire, and whether it has power."""

    stall_until_s: float = -math.inf
    refuse_until_s: float = -math.inf
    delay_s: float = 0.0
    garble_p: float = 0.0
    error_count: int = 0
    error_code: int = 0
    frame_corrupt_p: float = 0.0
    frame_loss_p: float = 0.0
    powered: bool = True


def _number(name: str, value: Any, lo: float, hi: float) -> float:
    ok = not isinstance(value, bool) and isinstance(value, (int, float)) and not math.isnan(value)
    if not ok or not lo <= value <= hi:
        raise ValueError(f"{name} = {value!r} not in {lo:g}..{hi:g}")
    return float(value)


class Gate:
    """What the server asks about one instrument's connections and messages
    (a :class:`sim.server.ConnectionGate`)."""

    def __init__(self, injector: FaultInjector, name: str, transport: Transport) -> None:
        self.injector, self.name, self.transport = injector, name, transport
        self.state = _State()
        self.writers: set[Any] = set()
        self.rng_name = f"fault:{name}"

    @property
    def _now(self) -> float:
        return self.injector.world.now

    def admit(self, writer: Any) -> bool:
        """A client connects: False = close it at once (reconnects refused for a while)."""
        # a serial server stays up when the unit behind it loses power; a LAN port does not
        unpowered_port = not self.state.powered and self.transport.interface_in_instrument
        if self._now < self.state.refuse_until_s or unpowered_port:
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
                reply = garble_reply(reply, rng)
        return reply, s.delay_s

    def transmit(self, data: bytes, frame_bytes: int) -> bytes:
        """Frames on their way out (a gyro line): stall, power, corruption, loss."""
        if self.silent():
            return b""
        s = self.state
        if not (s.frame_corrupt_p or s.frame_loss_p) or len(data) % frame_bytes:
            return data
        rng = self.injector.world.rng(self.rng_name)
        frames = np.frombuffer(data, dtype=np.uint8).reshape(-1, frame_bytes).copy()
        n = frames.shape[0]
        corrupt = rng.random(n) < s.frame_corrupt_p
        lost = rng.random(n) < s.frame_loss_p
        k = int(corrupt.sum())
        if k:
            pos = rng.integers(0, frame_bytes, k)
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


def garble_reply(reply: bytes, rng: np.random.Generator) -> bytes:
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

    ``instruments`` maps each instrument name to its device (a
    :class:`sim.devices.lifecycle.SimDevice`) and the transport it is served over; ``call``
    runs a function on the server thread (the world is only touched there).
    """

    def __init__(self, world: World, instruments: Mapping[str, tuple[SimDevice, Transport]],
                 call: Callable[..., Any] | None = None) -> None:
        self.world = world
        self.devices: dict[str, SimDevice] = {name: dev for name, (dev, _) in instruments.items()}
        self.call: Callable[..., Any] = call or (lambda fn, *a: fn(*a))
        self.gates = {name: Gate(self, name, transport) for name, (_, transport) in instruments.items()}
        self.frames_corrupted = 0
        self.frames_lost = 0

    # -- public API ----------------------------------------------------------------------
    def kinds(self, instrument: str) -> tuple[str, ...]:
        """The fault kinds ``instrument`` has: its wire's, then its device's own."""
        name = self.resolve(instrument)
        return self.gates[name].transport.wire_fault_kinds + self.devices[name].fault_kinds

    def inject(self, kind: str, instrument: str, *, at_s: float | None = None, **params: Any) -> None:
        """Inject ``kind`` into ``instrument`` now or at simulated time ``at_s``.

        Parameters by kind: drop(refuse_s=0), stall(duration_s=inf), slow(delay_ms),
        garble(probability), error(count=1, code=-300), frame(corrupt=0, loss=0), power(),
        interlock(), overload(volts=1e4), limit(), alarm().  Bad values raise ValueError at once.
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
        self.call(self.prepare_clear(instrument))

    def active(self) -> dict[str, list[str]]:
        """``{instrument: [kind, ...]}`` of the faults in force now."""
        out = {}
        for name, gate in self.gates.items():
            s, now, dev = gate.state, self.world.now, self.devices[name]
            overloaded = "overload" in dev.fault_kinds and cast(OverloadableDevice, dev).overloaded
            kinds = [k for k, on in (
                ("drop", now < s.refuse_until_s), ("stall", now < s.stall_until_s),
                ("slow", s.delay_s > 0), ("garble", s.garble_p > 0), ("error", s.error_count > 0),
                ("frame", s.frame_corrupt_p > 0 or s.frame_loss_p > 0), ("power", not s.powered),
                ("overload", overloaded)) if on]
            if kinds:
                out[name] = kinds
        return out

    def resolve(self, instrument: str) -> str:
        """The instrument's name as the station spells it (any case), else FaultTargetError."""
        for name in self.devices:
            if name.lower() == str(instrument).strip().lower():
                return name
        raise FaultTargetError(f"instrument {instrument!r} not in {'|'.join(self.devices)}")

    # -- validating now, applying on the server thread -----------------------------------------
    def prepare(self, kind: str, instrument: str, params: dict[str, Any]) -> Callable[[], None]:
        """Validate ``kind`` and ``params`` now; return the action that applies them."""
        name = self.resolve(instrument)
        kind = str(kind).lower()
        kinds = self.kinds(name)
        if kind not in kinds:
            raise FaultTargetError(f"fault {kind!r} not in {'|'.join(kinds)} for {name}")
        allowed = PARAMETERS[kind]
        unknown = set(params) - set(allowed)
        if unknown:
            raise ValueError(f"fault {kind} takes {sorted(allowed) or 'no parameters'}, "
                             f"not {sorted(unknown)}")
        p = {**allowed, **params}
        missing = [k for k, v in p.items() if v is None]
        if missing:
            raise ValueError(f"fault {kind} needs {missing}")
        act = _ARM[kind](self, name, p)

        def action() -> None:
            act()
            self.world.note(f"fault {kind} {name}")
        return action

    def prepare_clear(self, instrument: str) -> Callable[[], None]:
        """Validate the target (a name, or ``ALL``) now; return the action that clears it."""
        names = list(self.devices) if instrument.upper() == "ALL" else [self.resolve(instrument)]

        def action() -> None:
            for name in names:
                self._clear(name)
        return action

    # one per kind: validate the parameters, return what applies them (table _ARM below)
    def _arm_drop(self, name: str, p: dict[str, Any]) -> Callable[[], None]:
        refuse = _number("refuse_s", p["refuse_s"], 0.0, math.inf)
        gate = self.gates[name]

        def act() -> None:
            gate.state.refuse_until_s = self.world.now + refuse
            gate.drop()
        return act

    def _arm_stall(self, name: str, p: dict[str, Any]) -> Callable[[], None]:
        duration = _number("duration_s", p["duration_s"], 0.0, math.inf)
        s = self.gates[name].state
        return lambda: setattr(s, "stall_until_s", self.world.now + duration)

    def _arm_slow(self, name: str, p: dict[str, Any]) -> Callable[[], None]:
        delay = _number("delay_ms", p["delay_ms"], 0.0, MAX_DELAY_MS) / 1000.0
        s = self.gates[name].state
        return lambda: setattr(s, "delay_s", delay)

    def _arm_garble(self, name: str, p: dict[str, Any]) -> Callable[[], None]:
        probability = _number("probability", p["probability"], 0.0, 1.0)
        s = self.gates[name].state
        return lambda: setattr(s, "garble_p", probability)

    def _arm_error(self, name: str, p: dict[str, Any]) -> Callable[[], None]:
        count = _number("count", p["count"], 1, 1e6)
        code = _number("code", p["code"], -999, 32767)
        if count != int(count) or code != int(code) or code == 0:
            raise ValueError(f"error fault: count {count!r} and code {code!r} must be whole, "
                             "code non-zero in -999..32767")
        s = self.gates[name].state

        def act() -> None:
            s.error_count, s.error_code = int(count), int(code)
        return act

    def _arm_frame(self, name: str, p: dict[str, Any]) -> Callable[[], None]:
        corrupt = _number("corrupt", p["corrupt"], 0.0, 1.0)
        loss = _number("loss", p["loss"], 0.0, 1.0)
        s = self.gates[name].state

        def act() -> None:
            s.frame_corrupt_p, s.frame_loss_p = corrupt, loss
        return act

    def _arm_power(self, name: str, p: dict[str, Any]) -> Callable[[], None]:
        return lambda: self._power_off(name)

    def _arm_interlock(self, name: str, p: dict[str, Any]) -> Callable[[], None]:
        return cast(InterlockedDevice, self.devices[name]).trip_interlock

    def _arm_limit(self, name: str, p: dict[str, Any]) -> Callable[[], None]:
        return cast(LimitDevice, self.devices[name]).trip_limit

    def _arm_alarm(self, name: str, p: dict[str, Any]) -> Callable[[], None]:
        return cast(AlarmingDevice, self.devices[name]).raise_alarm

    def _arm_overload(self, name: str, p: dict[str, Any]) -> Callable[[], None]:
        volts = _number("volts", p["volts"], -1e6, 1e6)
        meter = cast(OverloadableDevice, self.devices[name])
        return lambda: meter.overload(volts)

    def _power_off(self, name: str) -> None:
        gate = self.gates[name]
        if not gate.state.powered:
            return
        gate.state.powered = False
        if gate.transport.interface_in_instrument:
            gate.drop()  # a dead instrument's network interface is gone too
        self.devices[name].power_off()

    def _power_on(self, name: str) -> None:
        gate = self.gates[name]
        if gate.state.powered:
            return
        gate.state.powered = True
        self.devices[name].power_on()

    def _clear(self, name: str) -> None:
        s, dev = self.gates[name].state, self.devices[name]
        s.stall_until_s = s.refuse_until_s = -math.inf
        s.delay_s = s.garble_p = s.frame_corrupt_p = s.frame_loss_p = 0.0
        s.error_count = 0
        if "overload" in dev.fault_kinds:
            cast(OverloadableDevice, dev).end_overload()
        self._power_on(name)  # a tripped interlock stays latched: it is reset by command
        self.world.note(f"faults cleared {name}")


_ARM: dict[str, Callable[[FaultInjector, str, dict[str, Any]], Callable[[], None]]] = {
    "drop": FaultInjector._arm_drop, "stall": FaultInjector._arm_stall,
    "slow": FaultInjector._arm_slow, "garble": FaultInjector._arm_garble,
    "error": FaultInjector._arm_error, "frame": FaultInjector._arm_frame,
    "power": FaultInjector._arm_power, "interlock": FaultInjector._arm_interlock,
    "overload": FaultInjector._arm_overload, "limit": FaultInjector._arm_limit,
    "alarm": FaultInjector._arm_alarm}
