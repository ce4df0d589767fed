"""Lexical analysis of one program message (IEEE 488.2 §7.3-7.7).

A program message is split into program message units at ``;``, each unit into a
header and program data elements at ``,``. Splitting ignores separators inside

* string data ``'..'`` / ``".."`` (doubled quotes lex as close-then-reopen),
* definite-length blocks ``#<n><len><payload>`` and the indefinite block ``#0...``
  (which runs to the end of the message),
* parentheses (expression data such as the channel list ``(@1,2:4)``) — commas only;
  a ``;`` always ends the unit so that an unbalanced ``(`` cannot swallow later units.

These are exactly the rules of :mod:`sim.scpi.framing`, so the framer and the lexer
agree on where strings and blocks end. White space (IEEE 488.2 §7.4.1.2) is any byte
0x00-0x09 or 0x0B-0x20.

Errors found here are attached to the unit they occur in; the engine queues them in
execution order and skips that unit. An unterminated string or a block running past the
end of the message swallows the rest of the message (there is no safe resync point).
"""

from __future__ import annotations

import re

from .errors import ScpiError
from .params import BLOCK, EXPR, PLAIN, STRING, Param

__all__ = ["lex_message", "parse_unit", "WHITESPACE"]

WHITESPACE = "".join(chr(c) for c in range(0x21) if c != 0x0A)
_WS_BYTES = WHITESPACE.encode("ascii")
_WS = r"\x00-\x09\x0b-\x20"
_LEX = re.compile(rb"[;,'\"#()]")
_COMPLEX = re.compile(rb"['\"#(]")
_HEADER = re.compile(rf"[{_WS}]*([A-Za-z0-9_:*?]*)")
_STRING = {"'": re.compile(r"'(?:[^']|'')*'"), '"': re.compile(r'"(?:[^"]|"")*"')}
_PLAIN = re.compile(rf"[A-Za-z0-9_+\-.#/{_WS}]*")


class Block:
    """Payload of an arbitrary block found by the lexer."""

    __slots__ = ("payload", "raw")

    def __init__(self, payload: bytes, raw: bytes):
        self.payload = payload
        self.raw = raw


# A lexed unit: (segments, error); a segment is [text, Block, text, Block, ..., text].
LexedUnit = tuple[list[list], "tuple[int, str] | None"]


def lex_message(msg: bytes) -> list[LexedUnit]:
    """Split ``msg`` into units and their comma-separated segments."""
    if _COMPLEX.search(msg) is None:  # no strings, blocks or parentheses: split in C
        return [([[seg] for seg in unit.split(b",")], None) for unit in msg.split(b";")]
    units: list[LexedUnit] = []
    segs: list[list] = []
    parts: list = []
    err = None
    pos = i = depth = 0
    n = len(msg)
    search = _LEX.search
    while True:
        m = search(msg, i)
        if m is None:
            break
        j = m.start()
        c = msg[j]
        if c == 0x3B:  # ';' ends the unit
            parts.append(msg[pos:j])
            segs.append(parts)
            units.append((segs, err))
            segs, parts, err, depth = [], [], None, 0
            i = pos = j + 1
        elif c == 0x2C:  # ','
            i = j + 1
            if depth == 0:
                parts.append(msg[pos:j])
                segs.append(parts)
                parts = []
                pos = i
        elif c == 0x28:  # '('
            depth += 1
            i = j + 1
        elif c == 0x29:  # ')'
            depth = max(0, depth - 1)
            i = j + 1
        elif c == 0x23:  # '#'
            d = msg[j + 1] if j + 1 < n else -1
            if 0x31 <= d <= 0x39:
                ndig = d - 0x30
                k = j + 2
                good = 0
                while good < ndig and k + good < n and 0x30 <= msg[k + good] <= 0x39:
                    good += 1
                if good < ndig:  # malformed length: rescan from the first non-digit
                    err = err or (-161, "malformed block length field")
                    i = k + good
                    continue
                start = k + ndig
                end = start + int(msg[k:start])
                if end > n:
                    err = err or (-161, f"block declares {end - start} bytes, {n - start} present")
                    i = n
                    break
                parts.append(msg[pos:j])
                parts.append(Block(msg[start:end], msg[j:end]))
                i = pos = end
            elif d == 0x30:  # indefinite block: the rest of the message
                parts.append(msg[pos:j])
                parts.append(Block(msg[j + 2:], msg[j:]))
                i = pos = n
                break
            else:  # '#H1F', '#B101', stray '#': ordinary text
                i = j + 1
        else:  # quote
            k = msg.find(c, j + 1)
            if k < 0:
                err = err or (-151, "unterminated string")
                i = n
                break
            i = k + 1
    parts.append(msg[pos:])
    segs.append(parts)
    units.append((segs, err))
    return units


def _decode(text: bytes) -> str:
    try:
        return text.decode("ascii")
    except UnicodeDecodeError as exc:
        raise ScpiError(-101, f"non-ASCII byte 0x{text[exc.start]:02X}") from None


def _bad_char(ch: str) -> str:
    return f"character {ch!r}"


def _classify(text: str) -> Param:
    """Turn one stripped, non-empty data element into a typed :class:`Param`."""
    c = text[0]
    if c == "'" or c == '"':
        if _STRING[c].fullmatch(text):
            return Param(STRING, text)
        raise ScpiError(-151, f"malformed string {text[:40]!r}")
    if c == "(":
        if text.endswith(")"):
            return Param(EXPR, text)
        raise ScpiError(-170, f"unbalanced expression {text[:40]!r}")
    if _PLAIN.fullmatch(text):
        return Param(PLAIN, text)
    bad = next(ch for ch in text if not _PLAIN.fullmatch(ch))
    raise ScpiError(-101, _bad_char(bad))


def parse_unit(segs: list[list]) -> tuple[str, list[Param]] | None:
    """Header and parameters of one lexed unit; ``None`` for an empty unit.

    Raises:
        ScpiError: -101/-102/-103/-151/-161/-170 for syntax errors.
    """
    raw_head = segs[0][0]
    if len(segs) == 1 and len(segs[0]) == 1 and not raw_head.strip(_WS_BYTES):
        return None  # empty unit (fast path: ';;' floods must stay cheap)
    head = _decode(raw_head)
    m = _HEADER.match(head)
    if m is None:  # cannot happen: the pattern matches the empty string
        raise ScpiError(-102, f"unreadable header {head[:40]!r}")
    header = m.group(1)
    rest = head[m.end():]
    more = len(segs) > 1 or len(segs[0]) > 1
    if not header:
        if not rest and not more:
            return None  # empty unit, e.g. after a trailing ';'
        if rest:
            if rest[0] == "'" or rest[0] == '"' or rest[0] in "(#+-.0123456789":
                raise ScpiError(-102, "data without a header")
            raise ScpiError(-101, _bad_char(rest[0]))
        if len(segs[0]) > 1:
            raise ScpiError(-102, "data without a header")
        raise ScpiError(-103, "',' without a header")
    if rest:
        if rest[0] not in WHITESPACE:
            raise ScpiError(-101, f"{_bad_char(rest[0])} after header {header}")
    elif len(segs[0]) > 1:
        raise ScpiError(-102, f"missing white space between {header} and its data")
    elif len(segs) > 1:
        raise ScpiError(-103, f"',' directly after header {header}")
    params: list[Param] = []
    last = len(segs) - 1
    for k, parts in enumerate(segs):
        first = rest if k == 0 else _decode(parts[0])
        if len(parts) > 1:
            if (len(parts) > 3 or first.strip(WHITESPACE)
                    or _decode(parts[2]).strip(WHITESPACE)):
                raise ScpiError(-161, "a block must be a whole parameter")
            blk = parts[1]
            params.append(Param(BLOCK, blk.raw, blk.payload))
            continue
        text = first.strip(WHITESPACE)
        if not text:
            if last == 0:
                break  # header without parameters
            raise ScpiError(-102, f"empty parameter {k + 1} of {header}")
        params.append(_classify(text))
    return header, params
