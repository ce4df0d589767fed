"""Typed access to program data (IEEE 488.2 §7.7, SCPI-1999 Vol. 1 §7).

Handlers receive an :class:`Args`. Every accessor raises :class:`ScpiError` with the
standard code, so a handler can simply let it propagate to the error queue:

========================  ==================================================
situation                 error
========================  ==================================================
parameter absent          -109 Missing parameter
string/block/expression   -104 Data type error (where another type is expected)
  or a word where a
  number is expected
malformed number          -121 Invalid character in number
exponent beyond ±32000    -123 Exponent too large (also a finite text that
  or overflow               overflows a double)
mantissa over 255 digits  -124 Too many digits
wrong unit suffix         -131 Invalid suffix (-138 when no unit is allowed)
out of range              -222 Data out of range (detail: value and range)
bad word / bad boolean    -224 Illegal parameter value
malformed channel list    -171 Invalid expression
========================  ==================================================

Numbers accept NRf (``1``, ``-2.5``, ``.5e-3``, white space before ``E``), the
non-decimal forms ``#H1F``/``#Q17``/``#B101``, the keywords MINimum/MAXimum/DEFault and
INFinity/NINFinity/NAN (SCPI sentinels 9.9E37/-9.9E37/9.91E37), and with ``units``
an optional suffix with an IEEE 488.2 multiplier (``100 mV``, ``1 KHZ``; ``MHZ`` and
``MOHM`` mean mega, as SCPI specifies). Suffixes are case-insensitive, so ``MV`` is
millivolt. Integer parameters round half away from zero (IEEE 488.2 §7.7.2.4.1).

Booleans accept ON/OFF or a number equal to 0 or 1 (SCPI-1999 §7.3 would take any
non-zero number as ON; we are stricter on purpose: anything else is -224, which
catches driver bugs such as sending ``2`` or ``TRUE``).
"""

from __future__ import annotations

import math
import re

from .errors import ScpiError
from .formatting import SCPI_INF, SCPI_NAN, SCPI_NINF

__all__ = ["Args", "Param", "PLAIN", "STRING", "BLOCK", "EXPR", "MAX_CHANNELS"]

PLAIN, STRING, BLOCK, EXPR = range(4)
_KIND_NAMES = {PLAIN: "character/numeric data", STRING: "string data",
               BLOCK: "block data", EXPR: "expression data"}

#: Largest channel list :meth:`Args.channel_list` expands (protects memory).
MAX_CHANNELS = 10_000

_WS = r"\x00-\x09\x0b-\x20"
_NUMBER = re.compile(
    rf"([+-]?)([0-9]*)(?:\.([0-9]*))?(?:[{_WS}]*[Ee][{_WS}]*([+-]?[0-9]+))?[{_WS}]*([A-Za-z/]*)")
_NONDECIMAL = re.compile(r"#([HhQqBb])([0-9A-Za-z]+)")
_BASES = {"H": 16, "Q": 8, "B": 2}
_CHANNEL_LIST = re.compile(rf"\([{_WS}]*@(.*)\)", re.S)
_CHANNEL_ITEM = re.compile(rf"[{_WS}]*([0-9]+)(?:[{_WS}]*:[{_WS}]*([0-9]+))?[{_WS}]*")
_WORD = re.compile(r"[A-Za-z][A-Za-z0-9_]*")

_KEYWORDS = {"MIN": "MIN", "MINIMUM": "MIN", "MAX": "MAX", "MAXIMUM": "MAX",
             "DEF": "DEF", "DEFAULT": "DEF", "INF": "INF", "INFINITY": "INF",
             "NINF": "NINF", "NINFINITY": "NINF", "NAN": "NAN"}
_SENTINELS = {"INF": SCPI_INF, "NINF": SCPI_NINF, "NAN": SCPI_NAN}
# IEEE 488.2 Table 7-1 suffix multipliers.
_MULTIPLIERS = {"EX": 1e18, "PE": 1e15, "T": 1e12, "G": 1e9, "MA": 1e6, "K": 1e3,
                "M": 1e-3, "U": 1e-6, "N": 1e-9, "P": 1e-12, "F": 1e-15, "A": 1e-18}
_MEGA_UNITS = {"HZ", "OHM"}  # SCPI: MHZ and MOHM are mega, not milli
_choice_cache: dict[tuple[str, ...], dict[str, str]] = {}


class Param:
    """One program data element: ``kind`` (PLAIN/STRING/BLOCK/EXPR), its text as
    sent (bytes for a block), and for blocks the payload."""

    __slots__ = ("kind", "text", "payload")

    def __init__(self, kind: int, text, payload: bytes | None = None):
        self.kind = kind
        self.text = text
        self.payload = payload

    def __repr__(self) -> str:
        return f"Param({_KIND_NAMES[self.kind]}, {self.text!r:.60})"


def _g(x: float) -> str:
    return f"{x:g}"


def _choice_map(choices) -> dict[str, str]:
    key = tuple(choices)
    table = _choice_cache.get(key)
    if table is None:
        table = {}
        for choice in key:
            short = "".join(ch for ch in choice if not ch.islower())
            table[short.upper()] = table[choice.upper()] = choice.upper()
        if len(_choice_cache) > 1024:
            _choice_cache.clear()
        _choice_cache[key] = table
    return table


class _RawParams(list):
    def __getitem__(self, index):
        try:
            return super().__getitem__(index)
        except IndexError:
            raise ScpiError(-109, f"parameter {index + 1 if isinstance(index, int) else index}"
                            " is required") from None


class Args:
    """Parameters of one program message unit, with typed accessors.

    Attributes:
        suffixes: numeric header suffixes, one per ``#`` in the registered pattern
            (1 where the suffix or its optional node was omitted).
        header: the header as sent (e.g. ``SENS:VOLT:NPLC``), for messages.
    """

    __slots__ = ("_params", "suffixes", "header")

    def __init__(self, params: list[Param], suffixes: tuple[int, ...] = (), header: str = ""):
        self._params = params
        self.suffixes = suffixes
        self.header = header

    # -- generic ----------------------------------------------------------------
    @property
    def count(self) -> int:
        """Number of parameters received."""
        return len(self._params)

    @property
    def raw(self) -> _RawParams:
        """Parameters as sent (white space trimmed; blocks decoded as Latin-1).  Indexing
        past the last one raises ScpiError -109 "Missing parameter", so a handler that
        reads ``args.raw[0]`` answers a bare header with the standard error."""
        return _RawParams(p.text.decode("latin-1") if p.kind == BLOCK else p.text
                          for p in self._params)

    def __repr__(self) -> str:
        return f"Args({self.header!r}, {self._params!r}, suffixes={self.suffixes})"

    def optional(self, i: int) -> bool:
        """True when parameter ``i`` (0-based) is present."""
        return 0 <= i < len(self._params)

    def keyword(self, i: int) -> str | None:
        """The numeric keyword parameter ``i`` spells, canonical (``MIN``, ``MAX``, ``DEF``,
        ``INF``, ``NINF``, ``NAN``; short or long form, any case), or None when it is absent
        or not such a keyword.  For queries like ``SAMP:COUN? MAX`` that answer a limit."""
        if not 0 <= i < len(self._params) or self._params[i].kind != PLAIN:
            return None
        return _KEYWORDS.get(self._params[i].text.upper())

    def require_count(self, lo: int, hi: int | None = None) -> None:
        """Check lo <= count <= hi (hi defaults to lo): -109 if fewer, -108 if more."""
        hi = lo if hi is None else hi
        n = len(self._params)
        if n < lo:
            raise ScpiError(-109, f"{self._name()} needs {lo} parameter{'s' * (lo != 1)}, got {n}")
        if n > hi:
            raise ScpiError(-108, f"{self._name()} takes at most {hi} parameter{'s' * (hi != 1)}, got {n}")

    def _name(self) -> str:
        return self.header.rsplit(":", 1)[-1].rstrip("?") or self.header

    def _get(self, i: int) -> Param:
        if not 0 <= i < len(self._params):
            raise ScpiError(-109, f"{self._name()} parameter {i + 1} missing")
        return self._params[i]

    def _type_error(self, p: Param, wanted: str) -> ScpiError:
        return ScpiError(-104, f"{self._name()} expects {wanted}, got {_KIND_NAMES[p.kind]}")

    # -- numbers ----------------------------------------------------------------
    def number(self, i: int, *, min: float | None, max: float | None,
               default: float | None = None, units: str | None = None) -> float:
        """Parameter ``i`` as a float within [min, max] (None = unbounded).

        MIN/MAX return the bounds, DEF returns ``default``; with ``units`` (e.g.
        ``"V"``) a suffix such as ``mV`` scales the value to that base unit.
        """
        p = self._get(i)
        if p.kind != PLAIN:
            raise self._type_error(p, "a number")
        text = p.text
        word = _KEYWORDS.get(text.upper())
        if word is not None:
            if word == "MIN" or word == "MAX" or word == "DEF":
                value = {"MIN": min, "MAX": max, "DEF": default}[word]
                if value is None:
                    raise ScpiError(-224, f"{self._name()} has no {text.upper()} value")
                return float(value)
            value = _SENTINELS[word]
        else:
            value = self._parse_number(text, units)
        if (min is not None and not value >= min) or (max is not None and not value <= max):
            lo = "-inf" if min is None else _g(min)
            hi = "inf" if max is None else _g(max)
            raise ScpiError(-222, f"{self._name()} {_g(value)}{' ' + units if units else ''} "
                                  f"not in {lo}..{hi}")
        return value

    def _parse_number(self, text: str, units: str | None) -> float:
        m = _NUMBER.fullmatch(text)
        if m is None or not (m.group(2) or m.group(3)):
            if text[0] == "#":
                nd = _NONDECIMAL.fullmatch(text)
                if nd:
                    try:
                        return float(int(nd.group(2), _BASES[nd.group(1).upper()]))
                    except ValueError:
                        pass
                raise ScpiError(-121, f"{self._name()}: {text[:40]!r} is not a valid non-decimal number")
            if _WORD.fullmatch(text):
                raise ScpiError(-104, f"{self._name()} expects a number, got {text[:40]!r}")
            raise ScpiError(-121, f"{self._name()}: {text[:40]!r} is not a number")
        sign, whole, frac, exp, suffix = m.groups()
        if len(whole) + len(frac or "") > 255:
            raise ScpiError(-124, f"{self._name()}: mantissa has more than 255 digits")
        if exp is not None and abs(int(exp)) > 32000:
            raise ScpiError(-123, f"{self._name()}: exponent {exp} beyond +/-32000")
        value = float(f"{sign}{whole or '0'}.{frac or '0'}e{exp or '0'}")
        if math.isinf(value):
            raise ScpiError(-123, f"{self._name()}: {text[:40]!r} overflows")
        if suffix:
            value *= self._multiplier(suffix, units)
        return value

    def _multiplier(self, suffix: str, units: str | None) -> float:
        if units is None:
            raise ScpiError(-138, f"{self._name()} takes no unit, got {suffix!r}")
        s, u = suffix.upper(), units.upper()
        if s == u:
            return 1.0
        if s.endswith(u):
            prefix = s[: len(s) - len(u)]
            if prefix == "M" and u in _MEGA_UNITS:
                return 1e6
            mult = _MULTIPLIERS.get(prefix)
            if mult is not None:
                return mult
        raise ScpiError(-131, f"{self._name()}: suffix {suffix!r} is not a multiple of {units}")

    def integer(self, i: int, *, min: int | None, max: int | None,
                default: int | None = None, units: str | None = None) -> int:
        """Parameter ``i`` as an int within [min, max]; decimals round half away from 0."""
        p = self._get(i)
        if p.kind != PLAIN:
            raise self._type_error(p, "an integer")
        word = _KEYWORDS.get(p.text.upper())
        if word == "MIN" or word == "MAX" or word == "DEF":
            return int(self.number(i, min=min, max=max, default=default, units=units))
        value = self.number(i, min=None, max=None, units=units)
        if math.isnan(value) or math.isinf(value):
            raise ScpiError(-222, f"{self._name()} {p.text} is not an integer")
        rounded = int(math.floor(abs(value) + 0.5)) * (1 if value >= 0 else -1)
        if (min is not None and rounded < min) or (max is not None and rounded > max):
            lo = "-inf" if min is None else str(min)
            hi = "inf" if max is None else str(max)
            raise ScpiError(-222, f"{self._name()} {rounded} not in {lo}..{hi}")
        return rounded

    # -- words, booleans, strings -------------------------------------------------
    def boolean(self, i: int) -> bool:
        """ON/OFF/1/0 (any case; numbers equal to 0 or 1) -> bool, else -224."""
        p = self._get(i)
        if p.kind != PLAIN:
            raise self._type_error(p, "ON|OFF|1|0")
        word = p.text.upper()
        if word == "ON":
            return True
        if word == "OFF":
            return False
        try:
            value = self._parse_number(p.text, None)
        except ScpiError:
            value = None
        if value == 0.0 or value == 1.0:
            return value == 1.0
        raise ScpiError(-224, f"{self._name()} expects ON|OFF|1|0, got {p.text[:40]!r}")

    def choice(self, i: int, choices) -> str:
        """Parameter ``i`` matched against SCPI-form ``choices`` (e.g. ``"IMMediate"``):
        exactly the short or long form, any case; returns the long form upper-cased."""
        p = self._get(i)
        if p.kind != PLAIN:
            raise self._type_error(p, "character data")
        found = _choice_map(choices).get(p.text.upper())
        if found is None:
            raise ScpiError(-224, f"{self._name()} {p.text[:40]!r} not one of {'|'.join(choices)}")
        return found

    def string(self, i: int) -> str:
        """Quoted string parameter, quotes removed and doubled quotes undone."""
        p = self._get(i)
        if p.kind != STRING:
            raise self._type_error(p, "a quoted string")
        q = p.text[0]
        return p.text[1:-1].replace(q + q, q)

    def block(self, i: int) -> bytes:
        """Payload of an arbitrary block parameter (definite or indefinite)."""
        p = self._get(i)
        if p.kind != BLOCK:
            raise self._type_error(p, "block data")
        if p.payload is None:  # the lexer gives every block its payload
            raise ScpiError(-161, f"{self._name()}: block without payload")
        return p.payload

    def channel_list(self, i: int, *, min: int | None = None, max: int | None = None) -> list[int]:
        """Channel list ``(@1,2:4)`` -> ``[1, 2, 3, 4]``; a range ``4:2`` counts down."""
        p = self._get(i)
        if p.kind != EXPR:
            raise self._type_error(p, "a channel list (@...)")
        m = _CHANNEL_LIST.fullmatch(p.text)
        if m is None:
            raise ScpiError(-171, f"{self._name()}: {p.text[:40]!r} is not a channel list")
        channels: list[int] = []
        for item in m.group(1).split(","):
            im = _CHANNEL_ITEM.fullmatch(item)
            if im is None:
                raise ScpiError(-171, f"{self._name()}: bad channel list entry {item[:20]!r}")
            a = int(im.group(1))
            b = a if im.group(2) is None else int(im.group(2))
            if len(channels) + abs(b - a) + 1 > MAX_CHANNELS:
                raise ScpiError(-223, f"{self._name()}: more than {MAX_CHANNELS} channels")
            channels.extend(range(a, b + 1) if b >= a else range(a, b - 1, -1))
        for ch in channels:
            if (min is not None and ch < min) or (max is not None and ch > max):
                raise ScpiError(-222, f"{self._name()} channel {ch} not in {min}..{max}")
        return channels
