"""SCPI wire formatting, reply parsing and setting validators for the instrument drivers.

This module holds the pure helpers every driver shares and that need no VISA stack: the
text forms SCPI expects on the wire (:func:`format_number` <NRf>, :func:`quote_string`,
:func:`channel_list`), the parsers of instrument replies (:func:`parse_bool`,
:func:`parse_float`, :func:`parse_int`, :func:`parse_error_reply`, :func:`unquote_string`),
which raise :class:`~instruments.wire.InstrumentReplyError` for a malformed reply, and the
setting validators ``(name, value, allowed) -> canonical value`` (:func:`in_range`,
:func:`int_in_range`, :func:`in_set`, :func:`boolean`), which raise ``ValueError`` naming
the value and the allowed range before anything is sent.  :mod:`instruments.base`
re-exports every name here.
"""

from __future__ import annotations

import math
import numbers
import re
from collections.abc import Iterable
from typing import Any

from .wire import InstrumentReplyError

_ERROR_REPLY = re.compile(r'^\s*([+-]?\d+)\s*,\s*"(.*)"\s*$', re.DOTALL)


# --- wire formatting and reply parsing -----------------------------------------------


def format_number(value: float | int) -> str:
    """SCPI <NRf> text: integers as such, floats with 12 significant digits ("10", "2e-05")."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{value!r} is not a real number")
    if isinstance(value, numbers.Integral):
        return str(int(value))
    return f"{float(value):.12g}"


def quote_string(text: str) -> str:
    """SCPI <string> data: double-quoted, embedded quotes doubled."""
    return '"' + text.replace('"', '""') + '"'


def unquote_string(reply: str) -> str:
    """Inverse of :func:`quote_string`; an unquoted reply is returned stripped."""
    reply = reply.strip()
    if len(reply) >= 2 and reply[0] == reply[-1] and reply[0] in "\"'":
        return reply[1:-1].replace(reply[0] * 2, reply[0])
    return reply


def parse_bool(reply: str) -> bool:
    """Boolean reply: ``1``/``0`` (what SCPI returns) or ``ON``/``OFF``."""
    token = reply.strip().upper()
    if token in ("1", "ON", "+1"):
        return True
    if token in ("0", "OFF", "+0"):
        return False
    raise InstrumentReplyError(f"{reply!r} is not a boolean reply (1/0/ON/OFF)")


def parse_float(reply: str) -> float:
    try:
        return float(reply.strip())
    except ValueError:
        raise InstrumentReplyError(f"{reply!r} is not a number") from None


def parse_int(reply: str) -> int:
    """Integer reply, also in NR3 form ("+1.00000000E+03")."""
    value = parse_float(reply)
    if not value.is_integer():
        raise InstrumentReplyError(f"{reply!r} is not an integer")
    return int(value)


def parse_error_reply(reply: str) -> tuple[int, str]:
    """``SYST:ERR?`` reply ``-222,"Data out of range"`` -> ``(-222, "Data out of range")``."""
    match = _ERROR_REPLY.match(reply)
    if match is None:
        raise InstrumentReplyError(f"SYST:ERR? reply {reply!r} is not <code>,\"<message>\"")
    return int(match.group(1)), match.group(2)


def channel_list(channels: Iterable[int]) -> str:
    """SCPI channel list ``(@1,2,3)`` of distinct positive channel numbers, in the given order."""
    numbers_ = list(channels)
    if not numbers_:
        raise ValueError("channel list is empty; give at least one channel number")
    for n in numbers_:
        if isinstance(n, bool) or not isinstance(n, numbers.Integral) or n < 1:
            raise ValueError(f"channel {n!r} is not a positive integer channel number")
    if len(set(numbers_)) != len(numbers_):
        raise ValueError(f"channel list {numbers_!r} repeats a channel")
    return "(@" + ",".join(str(int(n)) for n in numbers_) + ")"


# --- validators: (name, value, allowed) -> canonical value, ValueError otherwise ------


def _real(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name}={value!r} is not a real number")
    return float(value)


def in_range(name: str, value: Any, bounds: tuple[float, float]) -> float:
    """A finite real number in the closed interval ``bounds``."""
    lo, hi = bounds
    x = _real(name, value)
    if not (lo <= x <= hi):  # also rejects NaN
        raise ValueError(f"{name}={value!r} is outside the allowed range [{lo:g}, {hi:g}]")
    return x


def int_in_range(name: str, value: Any, bounds: tuple[int, int]) -> int:
    """An integer (an integral float is accepted) in the closed interval ``bounds``."""
    lo, hi = bounds
    x = _real(name, value)
    if not x.is_integer() or not (lo <= x <= hi):
        raise ValueError(f"{name}={value!r} is not an integer in the allowed range [{lo}, {hi}]")
    return int(x)


def in_set(name: str, value: Any, allowed: Iterable[Any]) -> Any:
    """One of ``allowed``: strings match case-insensitively, numbers to 1e-9 relative."""
    allowed = tuple(allowed)
    for candidate in allowed:
        if isinstance(candidate, str):
            if isinstance(value, str) and value.strip().upper() == candidate.upper():
                return candidate
        elif (
            isinstance(value, numbers.Real)
            and not isinstance(value, bool)
            and math.isclose(float(value), candidate, rel_tol=1e-9, abs_tol=0.0)
        ):
            return candidate
    shown = ", ".join(c if isinstance(c, str) else format_number(c) for c in allowed)
    raise ValueError(f"{name}={value!r} is not one of the allowed values ({shown})")


def boolean(name: str, value: Any, _allowed: Any = None) -> bool:
    """Exactly ``True`` or ``False`` (0/1 integers are refused, to catch mix-ups)."""
    if not isinstance(value, bool):
        raise ValueError(f"{name}={value!r} is not a bool (True or False)")
    return value
