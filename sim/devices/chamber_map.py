"""The Watlow F4T's Modbus register map as the simulated controller serves it (one loop, one
limit, six alarms, the real-time clock), and its 32-bit word order.

Register numbers are the PDU addresses (what a Modbus client's ``address=`` takes), as the
F4T documentation and Watlow's integrators list them; each 32-bit value (IEEE float, signed
32-bit) takes two consecutive registers, **low word first** — the F4T's default word order
("by default, the low order word contains the two low bytes of the 32-bit parameter",
TestEquity's F4T manual; ESPEC's ChamberConnectLibrary unpacks ``struct.pack('HH', r0, r1)``
on a little-endian host, the same).  Each register's bytes are big-endian, as every Modbus
register.  The table is stated in docs/CHAMBER.md; a test compares the two.

``source``: where the number comes from — ``F4T`` the F4T Setup and Operations User's Guide
appendix (registers 0..94, the alarm block 1328..1342), ``TestEquity`` the TestEquity F4T
chamber manual's common registers (set point 2782, working set point 2810, ramp 2794..2798,
chamber temperature 27586), ``ESPEC`` ESPEC North America's ChamberConnectLibrary for the
F4T (control mode 2730/2814, range 2774/2776, loop power 2784/2808, loop PV 2820, alarm state
1356, limit 11250/11264/11288, clock 14664..14674), ``assumed`` a number chosen here where none
of those gives one.

This module is the simulator's side.  The bench driver (``instruments/chamber.py``) writes
its own numbers and its own codec on purpose: a test holds both to docs/CHAMBER.md.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

#: Watlow enumeration values used here (the F4T's documented option numbers)
OFF, ON = 62, 63
AUTO, MANUAL = 10, 54
RAMP_OFF, RAMP_STARTUP, RAMP_SET_POINT, RAMP_BOTH = 62, 88, 85, 13
PER_MINUTE, PER_HOUR = 57, 39
UNITS_F, UNITS_C = 30, 15
DEVICE_OK, DEVICE_FAIL = 138, 32
ALARM_OFF, ALARM_PROCESS, ALARM_DEVIATION = 62, 76, 24
SIDES_BOTH, SIDES_HIGH, SIDES_LOW = 13, 37, 53
NON_LATCHING, LATCHING = 60, 49
#: alarm state: startup, none, blocked are the F4T's (ESPEC treats 88, 61, 12 as inactive);
#: alarm low / high / error numbers are assumed
ALARM_STARTUP, ALARM_NONE, ALARM_BLOCKED, ALARM_LOW, ALARM_HIGH, ALARM_ERROR = 88, 61, 12, 8, 7, 28
CLEAR, IGNORE = 129, 204
#: limit state (assumed numbers: the F4T's "low" / "high" / "none" option values)
LIMIT_NONE, LIMIT_LOW, LIMIT_HIGH = 61, 53, 37

#: how many registers each kind of parameter takes (a string: one character per register)
KINDS = {"uint16": 1, "int32": 2, "float": 2, "string": 15}
#: alarms of the controller: a part number with 'A' in digit 7 (no profiles) has six, as
#: ESPEC's ChamberConnectLibrary reads it (``process_controller``: alarms = 6)
ALARMS = 6
#: the clock's registers between its six parameters: ESPEC's ``get_datetime`` reads the clock in
#: one 12-register read from 14664 and keeps the even registers; the odd ones read 0 (assumed)
#: and are read-only
CLOCK_PADDING = tuple(range(14665, 14676, 2))


@dataclass(frozen=True)
class Register:
    """One parameter of the map."""

    address: int
    name: str
    kind: str      # uint16 | int32 | float | string
    access: str    # R | RW | W
    source: str    # F4T | TestEquity | ESPEC | assumed

    @property
    def words(self) -> int:
        return KINDS[self.kind]


#: alarm n's block starts at 1330 + 100·(n − 1) (F4T guide); the state register is ESPEC's
def _alarm(n: int) -> tuple[Register, ...]:
    base = 100 * (n - 1)
    return (
        Register(1330 + base, f"alarm{n}_type", "uint16", "RW", "F4T"),
        Register(1332 + base, f"alarm{n}_sides", "uint16", "RW", "F4T"),
        Register(1334 + base, f"alarm{n}_high_c", "float", "RW", "F4T"),
        Register(1336 + base, f"alarm{n}_low_c", "float", "RW", "F4T"),
        Register(1338 + base, f"alarm{n}_hysteresis_c", "float", "RW", "F4T"),
        Register(1342 + base, f"alarm{n}_latching", "uint16", "RW", "F4T"),
        Register(1352 + base, f"alarm{n}_clear", "uint16", "W", "assumed"),
        Register(1356 + base, f"alarm{n}_state", "uint16", "R", "ESPEC"),
    )


REGISTERS: tuple[Register, ...] = (
    Register(0, "hardware_id", "int32", "R", "F4T"),
    Register(4, "software_release", "int32", "R", "F4T"),
    Register(12, "serial_number", "int32", "R", "F4T"),
    Register(16, "part_number", "string", "R", "F4T"),
    Register(90, "device_status", "uint16", "R", "F4T"),
    Register(1328, "display_units", "uint16", "RW", "F4T"),
    *(reg for n in range(1, ALARMS + 1) for reg in _alarm(n)),
    Register(2730, "control_mode", "uint16", "RW", "ESPEC"),
    Register(2774, "set_point_low_c", "float", "RW", "ESPEC"),
    Register(2776, "set_point_high_c", "float", "RW", "ESPEC"),
    Register(2782, "set_point_c", "float", "RW", "TestEquity"),
    # loop power: ESPEC's get_loop_power reads 2784 ('constant', what set_loop_power writes: the
    # manual power) and 2808 ('current': the loop's output now); loop n adds 160·(n − 1)
    Register(2784, "manual_power_pct", "float", "RW", "ESPEC"),
    Register(2794, "ramp_action", "uint16", "RW", "TestEquity"),
    Register(2796, "ramp_scale", "uint16", "RW", "TestEquity"),
    Register(2798, "ramp_rate", "float", "RW", "TestEquity"),
    Register(2808, "loop_power_pct", "float", "R", "ESPEC"),
    Register(2810, "working_set_point_c", "float", "R", "TestEquity"),
    Register(2814, "control_mode_active", "uint16", "R", "ESPEC"),
    Register(2820, "process_value_c", "float", "R", "ESPEC"),
    Register(11250, "limit_state", "uint16", "R", "ESPEC"),
    Register(11252, "limit_low_c", "float", "RW", "assumed"),
    Register(11254, "limit_high_c", "float", "RW", "assumed"),
    Register(11256, "limit_clear", "uint16", "W", "assumed"),
    Register(11264, "limit_status", "uint16", "R", "ESPEC"),
    Register(11288, "limit_error", "uint16", "R", "ESPEC"),
    # the real-time clock: ESPEC's get_datetime / set_datetime (one parameter per two registers)
    Register(14664, "clock_hour", "uint16", "RW", "ESPEC"),
    Register(14666, "clock_minute", "uint16", "RW", "ESPEC"),
    Register(14668, "clock_second", "uint16", "RW", "ESPEC"),
    Register(14670, "clock_month", "uint16", "RW", "ESPEC"),
    Register(14672, "clock_day", "uint16", "RW", "ESPEC"),
    Register(14674, "clock_year", "uint16", "RW", "ESPEC"),
    Register(27586, "chamber_temperature_c", "float", "R", "TestEquity"),
)

BY_NAME = {r.name: r for r in REGISTERS}
BY_ADDRESS = {r.address: r for r in REGISTERS}


def float_to_words(value: float) -> list[int]:
    """An IEEE 754 single as the F4T serves it: [low word, high word]."""
    hi, lo = struct.unpack(">HH", struct.pack(">f", value))
    return [lo, hi]


def words_to_float(words: list[int]) -> float:
    lo, hi = words
    return float(struct.unpack(">f", struct.pack(">HH", hi, lo))[0])


def int32_to_words(value: int) -> list[int]:
    hi, lo = struct.unpack(">HH", struct.pack(">i", value))
    return [lo, hi]


def words_to_int32(words: list[int]) -> int:
    lo, hi = words
    return int(struct.unpack(">i", struct.pack(">HH", hi, lo))[0])


def string_to_words(text: str, words: int) -> list[int]:
    """One character per register, its code in the register, NUL (0) padded: the F4T guide's
    part number ("A to Z, 0 to 9 (Unicode character)", registers 16 to 30); ESPEC's
    ``read_holding_string`` reads the registers and ``chr()``s each one that is not 0."""
    codes = [ord(ch) for ch in text[:words]]
    if any(not 0 < code < 0x10000 for code in codes):
        raise ValueError(f"{text!r}: a register holds one character, U+0001..U+FFFF")
    return codes + [0] * (words - len(codes))
