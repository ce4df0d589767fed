"""Watlow F4T temperature-chamber controller over Modbus TCP (a pymodbus client).

The registers are the F4T's (docs/CHAMBER.md has the table and where each number comes
from): loop 1's set point (2782), its working set point during a ramp (2810), the process
value (2820), the user control mode (2730: Auto runs the chamber, Off is standby), the
set-point range (2774/2776), ramp action/scale/rate (2794/2796/2798), alarm 1 and 2 states
(1356/1456) and clear requests, the limit controller's state (11250) and clear (11256).
32-bit values take two registers, low word first (the F4T's default word order); °C.

Written apart from the simulated controller on purpose (its own register numbers and its
own word codec): a test holds both to the documented table.

Fault policy (as docs/ARCHITECTURE.md's for SCPI): a lost connection or no reply raises
:class:`instruments.wire.InstrumentConnectionError` / ``InstrumentTimeoutError`` naming the
instrument and the register; a Modbus exception reply raises :class:`ChamberRegisterError`
naming the register and the exception; reads are re-sent (over a reopened connection) at
most ``QUERY_RETRIES`` more times, writes never — except the two that bring the chamber to
rest (standby, the ambient set point), sent once more when the first was lost on the wire.
Waits take the bench clock's ``wait(seconds)``; the driver never sleeps.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

from .protocols import SafeOrder, Wait
from .wire import QUERY_RETRIES, InstrumentConnectionError, InstrumentTimeoutError

# -- the registers (PDU addresses) ----------------------------------------------------------
HARDWARE_ID, SOFTWARE_RELEASE, SERIAL_NUMBER, PART_NUMBER, PART_NUMBER_WORDS = 0, 4, 12, 16, 15
DISPLAY_UNITS = 1328
CONTROL_MODE, CONTROL_MODE_ACTIVE = 2730, 2814
SET_POINT_LOW, SET_POINT_HIGH, SET_POINT, WORKING_SET_POINT = 2774, 2776, 2782, 2810
RAMP_ACTION, RAMP_SCALE, RAMP_RATE = 2794, 2796, 2798
PROCESS_VALUE = 2820
ALARM_STATE = {1: 1356, 2: 1456}
ALARM_CLEAR = {1: 1352, 2: 1452}
LIMIT_STATE, LIMIT_LOW, LIMIT_HIGH, LIMIT_CLEAR = 11250, 11252, 11254, 11256
#: what each register is, for error messages
REGISTER_NAMES = {
    HARDWARE_ID: "hardware id", SOFTWARE_RELEASE: "software release", SERIAL_NUMBER: "serial number",
    PART_NUMBER: "part number", DISPLAY_UNITS: "display units", CONTROL_MODE: "control mode",
    CONTROL_MODE_ACTIVE: "active control mode", SET_POINT_LOW: "set point low limit",
    SET_POINT_HIGH: "set point high limit", SET_POINT: "set point", WORKING_SET_POINT: "working set point",
    RAMP_ACTION: "ramp action", RAMP_SCALE: "ramp scale", RAMP_RATE: "ramp rate", PROCESS_VALUE: "process value",
    ALARM_STATE[1]: "alarm 1 state", ALARM_STATE[2]: "alarm 2 state", ALARM_CLEAR[1]: "alarm 1 clear",
    ALARM_CLEAR[2]: "alarm 2 clear", LIMIT_STATE: "limit state", LIMIT_LOW: "limit low set point",
    LIMIT_HIGH: "limit high set point", LIMIT_CLEAR: "limit clear"}

# -- Watlow option values -------------------------------------------------------------------
AUTO, OFF = 10, 62
RAMP_OFF, RAMP_SET_POINT, RAMP_BOTH = 62, 85, 13
PER_MINUTE = 57
UNITS_C = 15
CLEAR = 129
ALARM_STATES = {88: "startup", 61: "none", 12: "blocked", 8: "low", 7: "high", 28: "error"}
LIMIT_STATES = {61: "ok", 37: "high", 53: "low"}
EXCEPTIONS = {1: "illegal function", 2: "illegal data address", 3: "illegal data value",
              4: "server device failure", 6: "server device busy"}
#: the ramp rates the F4T accepts (°/min)
RAMP_RANGE_C_PER_MIN = (1e-3, 99_999.0)


class ChamberRegisterError(RuntimeError):
    """The controller refused a request with a Modbus exception: names the register."""

    def __init__(self, instrument_name: str, action: str, code: int) -> None:
        self.instrument_name, self.action, self.code = instrument_name, action, code
        super().__init__(f"{instrument_name}: {action} refused: Modbus exception {code:02d} "
                         f"({EXCEPTIONS.get(code, 'unknown')})")


class ChamberFaultError(RuntimeError):
    """The chamber cannot hold its temperature: limit tripped or an alarm active."""

    def __init__(self, instrument_name: str, status: ChamberStatus, what: str) -> None:
        self.instrument_name, self.status = instrument_name, status
        super().__init__(f"{instrument_name}: {what} (air {status.process_value_c:.2f} °C, "
                         f"set point {status.set_point_c:.2f} °C)")


@dataclass(frozen=True)
class ChamberIdentity:
    model: str
    part_number: str
    serial_number: int
    hardware_id: int
    software_release: int


@dataclass(frozen=True)
class AlarmStatus:
    number: int
    state: str  # none | startup | blocked | low | high | error | unknown(<n>)

    @property
    def active(self) -> bool:
        return self.state in ("low", "high", "error") or self.state.startswith("unknown")


@dataclass(frozen=True)
class ChamberStatus:
    """One look at the controller (temperatures in °C)."""

    running: bool
    process_value_c: float
    set_point_c: float
    working_set_point_c: float
    limit: str  # ok | high | low | unknown(<n>)
    alarms: tuple[AlarmStatus, ...]

    @property
    def limit_tripped(self) -> bool:
        return self.limit != "ok"

    @property
    def alarm_active(self) -> bool:
        return any(a.active for a in self.alarms)


def words_to_float(words: list[int]) -> float:
    """Two registers, low word first, as an IEEE single."""
    return float(struct.unpack("<f", struct.pack("<HH", words[0], words[1]))[0])


def float_to_words(value: float) -> list[int]:
    low, high = struct.unpack("<HH", struct.pack("<f", value))
    return [low, high]


def words_to_int32(words: list[int]) -> int:
    return int(struct.unpack("<i", struct.pack("<HH", words[0], words[1]))[0])


class WatlowF4TChamber:
    """A thermal chamber run by a Watlow F4T (the ``ThermalChamber`` interface).

    ``client``: a connected pymodbus ``ModbusTcpClient`` (``connect()``, ``close()``, the
    register calls).  ``ambient_set_point_c``: where :meth:`make_safe` leaves the set point.
    """

    safe_order = SafeOrder.MOTION
    safe_action = "standby"

    def __init__(self, client: Any, name: str = "chamber", *, device_id: int = 1,
                 ambient_set_point_c: float = 23.0) -> None:
        self.client = client
        self.name = name
        self.device_id = int(device_id)
        self.ambient_set_point_c = float(ambient_set_point_c)
        self._range: tuple[float, float] | None = None

    # -- transfers ------------------------------------------------------------------------
    def _transfer(self, action: str, call: Callable[[], Any], resend: bool) -> Any:
        attempts = 1 + (QUERY_RETRIES if resend else 0)
        for attempt in range(1, attempts + 1):
            try:
                if not self.client.connected:
                    self.client.connect()
                    if not self.client.connected:
                        raise ConnectionError("cannot connect")
                reply = call()
            except Exception as exc:  # pymodbus: ConnectionException, ModbusIOException, OSError
                self.client.close()  # a late reply must never be read as the next one
                if attempt < attempts:
                    continue
                if "timeout" in str(exc).lower() or "no response" in str(exc).lower():
                    raise InstrumentTimeoutError(self.name, action, getattr(self.client, "timeout", "?"),
                                                 attempts) from exc
                raise InstrumentConnectionError(self.name, action, exc) from exc
            if reply.isError():
                code = int(getattr(reply, "exception_code", 0) or 0)
                if code == 0:  # not an exception reply: a transport failure pymodbus returned
                    self.client.close()
                    if attempt < attempts:
                        continue
                    raise InstrumentConnectionError(self.name, action, RuntimeError(str(reply)))
                raise ChamberRegisterError(self.name, action, code)
            return reply
        raise AssertionError("unreachable")

    def _read(self, address: int, count: int) -> list[int]:
        what = f"read register {address} ({REGISTER_NAMES.get(address, '?')})"
        reply = self._transfer(what, lambda: self.client.read_holding_registers(
            address, count=count, device_id=self.device_id), resend=True)
        regs = list(reply.registers)
        if len(regs) != count:
            raise InstrumentConnectionError(self.name, what, RuntimeError(f"{len(regs)} registers, not {count}"))
        return regs

    def _write(self, address: int, words: list[int], resend: bool = False) -> None:
        what = f"write register {address} ({REGISTER_NAMES.get(address, '?')})"
        if len(words) == 1:
            self._transfer(what, lambda: self.client.write_register(
                address, words[0], device_id=self.device_id), resend)
        else:
            self._transfer(what, lambda: self.client.write_registers(
                address, words, device_id=self.device_id), resend)

    def _read_float(self, address: int) -> float:
        return words_to_float(self._read(address, 2))

    # -- identity and settings ------------------------------------------------------------
    def identify(self) -> ChamberIdentity:
        raw = self._read(PART_NUMBER, PART_NUMBER_WORDS)
        part = "".join(chr(w) for w in raw if 0 < w < 0x110000)  # one character per register (F4T map)
        return ChamberIdentity("F4T", part, words_to_int32(self._read(SERIAL_NUMBER, 2)),
                               words_to_int32(self._read(HARDWARE_ID, 2)),
                               words_to_int32(self._read(SOFTWARE_RELEASE, 2)))

    @property
    def set_point_range_c(self) -> tuple[float, float]:
        """The controller's set point limits (read once, then kept)."""
        if self._range is None:
            self._range = (self._read_float(SET_POINT_LOW), self._read_float(SET_POINT_HIGH))
        return self._range

    @property
    def set_point_c(self) -> float:
        return self._read_float(SET_POINT)

    def set_set_point(self, set_point_c: float) -> None:
        """The loop's set point (°C), checked against the controller's range first."""
        lo, hi = self.set_point_range_c
        if isinstance(set_point_c, bool) or not isinstance(set_point_c, (int, float)) \
                or not math.isfinite(set_point_c) or not lo <= set_point_c <= hi:
            raise ValueError(f"{self.name}: set point {set_point_c!r} °C not in {lo:g}..{hi:g} °C")
        self._write(SET_POINT, float_to_words(float(set_point_c)))

    @property
    def working_set_point_c(self) -> float:
        """The set point the loop follows now (the ramp's present value while ramping)."""
        return self._read_float(WORKING_SET_POINT)

    @property
    def process_value_c(self) -> float:
        """The chamber air temperature (°C)."""
        return self._read_float(PROCESS_VALUE)

    @property
    def ramp_rate_c_per_min(self) -> float | None:
        """The ramp applied to set point changes (°C/min), None when set points step."""
        if self._read(RAMP_ACTION, 1)[0] == RAMP_OFF:
            return None
        rate = self._read_float(RAMP_RATE)
        return rate if self._read(RAMP_SCALE, 1)[0] == PER_MINUTE else rate / 60.0

    def set_ramp(self, rate_c_per_min: float | None) -> None:
        """Ramp later set point changes, and the start from standby, at ``rate_c_per_min``
        (ramp action Both; None: step them).  The chamber's own heating and cooling rates
        still bound the air."""
        if rate_c_per_min is None:
            self._write(RAMP_ACTION, [RAMP_OFF])
            return
        lo, hi = RAMP_RANGE_C_PER_MIN
        if isinstance(rate_c_per_min, bool) or not isinstance(rate_c_per_min, (int, float)) \
                or not math.isfinite(rate_c_per_min) or not lo <= rate_c_per_min <= hi:
            raise ValueError(f"{self.name}: ramp rate {rate_c_per_min!r} °C/min not in {lo:g}..{hi:g} °C/min")
        self._write(RAMP_SCALE, [PER_MINUTE])
        self._write(RAMP_RATE, float_to_words(float(rate_c_per_min)))
        self._write(RAMP_ACTION, [RAMP_BOTH])

    # -- run / stop -----------------------------------------------------------------------
    @property
    def running(self) -> bool:
        """The loop is in Auto (the chamber conditions its air); False: standby."""
        return self._read(CONTROL_MODE_ACTIVE, 1)[0] == AUTO

    def run(self) -> None:
        """Start conditioning toward the set point."""
        self._write(CONTROL_MODE, [AUTO])

    def standby(self) -> None:
        """Stop conditioning: the air drifts toward the lab's ambient."""
        self._write(CONTROL_MODE, [OFF], resend=True)

    # -- alarms and limit -------------------------------------------------------------------
    def alarms(self) -> tuple[AlarmStatus, ...]:
        return tuple(AlarmStatus(n, _state(ALARM_STATES, self._read(reg, 1)[0])) for n, reg in ALARM_STATE.items())

    def clear_alarms(self) -> None:
        """Clear latched alarms whose condition has gone."""
        for reg in ALARM_CLEAR.values():
            self._write(reg, [CLEAR])

    @property
    def limit_state(self) -> str:
        """The over-temperature limit: ``ok``, or ``high`` / ``low`` when tripped (latched)."""
        return _state(LIMIT_STATES, self._read(LIMIT_STATE, 1)[0])

    @property
    def limit_range_c(self) -> tuple[float, float]:
        return self._read_float(LIMIT_LOW), self._read_float(LIMIT_HIGH)

    def clear_limit(self) -> None:
        """Reset a tripped limit (it stays tripped while the air is beyond it)."""
        self._write(LIMIT_CLEAR, [CLEAR])

    def status(self) -> ChamberStatus:
        return ChamberStatus(self.running, self.process_value_c, self.set_point_c, self.working_set_point_c,
                             self.limit_state, self.alarms())

    def check(self) -> ChamberStatus:
        """The status, raising :class:`ChamberFaultError` when the limit is tripped or an alarm is active."""
        s = self.status()
        if s.limit_tripped:
            raise ChamberFaultError(self.name, s, f"over-temperature limit tripped ({s.limit})")
        if s.alarm_active:
            active = ", ".join(f"alarm {a.number} {a.state}" for a in s.alarms if a.active)
            raise ChamberFaultError(self.name, s, f"controller alarm: {active}")
        return s

    # -- waits ------------------------------------------------------------------------------
    def wait_for_temperature(self, wait: Wait, target_c: float, tolerance_c: float, hold_s: float,
                             timeout_s: float, poll_s: float = 30.0) -> ChamberStatus:
        """Poll until the air has stayed within ``tolerance_c`` of ``target_c`` for ``hold_s``
        (polls every ``poll_s`` with ``wait``, the bench clock's); the status then.  Raises
        :class:`ChamberFaultError` on a tripped limit or active alarm, ``TimeoutError`` after
        ``timeout_s`` of waiting."""
        for name, value, lo in (("tolerance_c", tolerance_c, 0.0), ("hold_s", hold_s, 0.0),
                                ("timeout_s", timeout_s, 0.0), ("poll_s", poll_s, 1e-3)):
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not lo <= value < math.inf:
                raise ValueError(f"{self.name}: {name} = {value!r} must be a finite number ≥ {lo:g}")
        waited = inside_for = 0.0
        while True:
            s = self.check()
            inside = abs(s.process_value_c - target_c) <= tolerance_c
            inside_for = inside_for if inside else 0.0
            if inside and inside_for >= hold_s:
                return s
            if waited >= timeout_s:
                raise TimeoutError(f"{self.name}: air not within {tolerance_c:g} °C of {target_c:g} °C for "
                                   f"{hold_s:g} s after {waited:g} s (now {s.process_value_c:.2f} °C)")
            step = min(poll_s, timeout_s - waited) if timeout_s > waited else poll_s
            wait(step)
            waited += step
            if inside:
                inside_for += step

    def wait_until_settled(self, wait: Wait, tolerance_c: float = 0.3, hold_s: float = 300.0,
                           timeout_s: float = 4 * 3600.0, poll_s: float = 30.0) -> ChamberStatus:
        """:meth:`wait_for_temperature` at the present set point."""
        return self.wait_for_temperature(wait, self.set_point_c, tolerance_c, hold_s, timeout_s, poll_s)

    # -- lifecycle -------------------------------------------------------------------------
    def make_safe(self) -> None:
        """Standby at the lab-ambient set point: both written, each tried even if one fails."""
        failures = []
        lo, hi = (-math.inf, math.inf)
        try:
            lo, hi = self.set_point_range_c
        except Exception as exc:
            failures.append(f"set point range: {exc}")
        ambient = min(max(self.ambient_set_point_c, lo), hi)
        for what, act in (("set point", lambda: self._write(SET_POINT, float_to_words(ambient), resend=True)),
                          ("standby", self.standby)):
            try:
                act()
            except Exception as exc:
                failures.append(f"{what}: {exc}")
        if failures:
            raise RuntimeError(f"{self.name}: not made safe: {'; '.join(failures)}")

    def snapshot(self) -> dict[str, Any]:
        ident = self.identify()
        s = self.status()
        lo, hi = self.set_point_range_c
        return {"identity": asdict(ident), "running": s.running, "set_point_c": s.set_point_c,
                "process_value_c": s.process_value_c, "set_point_range_c": [lo, hi],
                "ramp_rate_c_per_min": self.ramp_rate_c_per_min, "limit": s.limit,
                "alarms": {a.number: a.state for a in s.alarms}}


def _state(table: dict[int, str], value: int) -> str:
    return table.get(value, f"unknown({value})")
