"""IEEE 488.2 / SCPI-1999 device engine shared by every simulated SCPI instrument.

A server owns one :class:`ScpiDevice` (or a subclass), registers its command tree with
:meth:`ScpiDevice.command`, and either feeds raw socket bytes to :meth:`ScpiDevice.feed`
or frames them itself and calls :meth:`ScpiDevice.process` once per program message.
``process`` never raises (any ``Exception`` ends up in the error queue) and never
blocks except inside a device's own :meth:`ScpiDevice.wait_complete`.

Header matching
    Case-insensitive; each mnemonic must be exactly its short or its long form
    (``VOLT``/``VOLTAGE``, never ``VOLTA``); a ``#`` mnemonic takes an optional numeric
    suffix 1..999999999 (default 1; a suffix on a mnemonic without ``#`` is -113, a
    suffix 0 or above the handler's ``max_suffix`` is -114). Optional ``[nodes]`` may be
    given or omitted. A header ending in ``?`` is a query; a header with only a set
    handler used as a query, or vice versa, is -113.

Path rules (IEEE 488.2 §A.1.1 and SCPI-1999 Vol. 1 §6.2.4)
    * Every program message starts at the root.
    * A header with a leading ``:`` is resolved from the root; any other header is
      resolved relative to the current path.
    * After a successfully resolved header, the current path becomes the node reached
      by all of its mnemonics but the last, i.e. the header *as sent* minus its leaf
      (``SENS:VOLT:NPLC 1;RANG 10`` runs ``SENS:VOLT:RANG``; after ``OUTP ON`` — which
      is ``OUTPut[:STATe]`` — the path is the root because ``STATe`` was not sent).
      Numeric suffixes on the path carry over (``OUTP2:STAT ON;PROT:CLE`` → suffix 2).
    * Common commands (``*XXX``) neither use nor change the path.
    * A header that cannot be resolved leaves the path unchanged.

Errors inside a compound message
    Each unit is lexed, parsed and executed on its own. A unit with an error queues
    exactly one error (the first found) and is skipped; the following units still run,
    from the path left by the last good header. Lexical damage that has no safe resync
    point (an unterminated string, a block longer than the message) ends the message.
    Queries that fail produce no response element; if no query succeeded the
    response is ``None`` (a real instrument sends nothing, so the client times out).
    Command errors (-1xx) are queued with their bare standard text
    (``-113,"Undefined header"``) unless ``detailed_command_errors`` is set; other
    errors keep their detail (``-222,"Data out of range;NPLC 7 not in 0.001..100"``).

Status model (IEEE 488.2 §11)
    ESR bits: 0 OPC, 2 QYE (-4xx), 3 DDE (-3xx, positive codes), 4 EXE (-2xx),
    5 CME (-1xx), 7 PON (set at construction). STB: bit 2 EAV (queue not empty),
    bit 4 MAV is always 0 (the message-available flag has no meaning over a socket,
    where responses are written at once), bit 5 ESB (ESR & ESE), bit 6 MSS
    (STB & SRE over the other bits); bits 0, 1, 3, 7 come from
    :meth:`ScpiDevice.device_status_bits` (e.g. SCPI QUES/OPER summaries, 0 here).
    -410 Query INTERRUPTED and -420 Query UNTERMINATED are never generated for the
    same reason as MAV: every response is sent immediately.
    The error queue is FIFO with ``error_queue_size`` entries; on overflow the newest
    entry is replaced by -350 "Queue overflow" (SCPI-1999 Vol. 2 §21.8.1).
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable

from .common import CommonCommands
from .errors import ScpiError, esr_bit_for, format_error_entry
from .framing import MessageFramer, Oversize
from .lexer import lex_message, parse_unit
from .params import Args
from .tree import Node, compile_pattern, registered_patterns, resolve

__all__ = ["ScpiDevice"]

_CACHE_LIMIT = 4096
#: IEEE 488.2 §7.6.1.2: a program mnemonic has at most 12 characters (suffix excluded)
MAX_MNEMONIC_CHARS = 12


class ScpiDevice(CommonCommands):
    """An IEEE 488.2 device with a SCPI command tree.

    Args:
        idn: manufacturer, model, serial number, firmware (the ``*IDN?`` fields; no
            commas, semicolons or line breaks).
        options: the ``*OPT?`` response.
        error_queue_size: capacity of the error queue (>= 1).
        max_message_bytes: largest program message accepted; larger ones give -223.
    """

    #: Device-specific texts for positive error codes, e.g. ``{101: "Motor stalled"}``.
    error_texts: dict[int, str] = {}
    #: Command errors (-1xx) are queued with the bare standard text, as real Keysight
    #: instruments do (``-113,"Undefined header"``); set True to append the parser's
    #: detail while debugging a driver. Other errors always carry their detail.
    detailed_command_errors: bool = False

    def __init__(self, idn: tuple[str, str, str, str], options: str = "0",
                 error_queue_size: int = 20, max_message_bytes: int = 1 << 20):
        fields = tuple(idn)
        if len(fields) != 4 or not all(isinstance(f, str) for f in fields):
            raise ValueError(f"idn must be 4 strings (maker, model, serial, firmware), got {fields!r}")
        for field, forbidden in [(f, ",;\r\n") for f in fields] + [(options, ";\r\n")]:
            if not isinstance(field, str) or any(ch in field for ch in forbidden) or not field.isascii():
                raise ValueError(f"*IDN?/*OPT? field {field!r} must be ASCII without {forbidden!r}")
        if not isinstance(error_queue_size, int) or error_queue_size < 1:
            raise ValueError(f"error_queue_size must be an int >= 1, got {error_queue_size!r}")
        if not isinstance(max_message_bytes, int) or max_message_bytes < 1:
            raise ValueError(f"max_message_bytes must be an int >= 1, got {max_message_bytes!r}")
        self.idn = fields
        self.options = options
        self.error_queue_size = error_queue_size
        self.max_message_bytes = max_message_bytes
        self.esr = 0x80  # PON: the device has just been powered on
        self.ese = 0
        self.sre = 0
        self._errors: deque[tuple[int, str | None]] = deque()  # (code, detail)
        self._root = Node(None)
        self._commons: dict[str, Node] = {}
        self._cache: dict[tuple[Node, str], tuple] = {}
        self._lock = threading.RLock()
        self._framer = MessageFramer(max_message_bytes)
        self._register_builtins()

    # -- registration --------------------------------------------------------------
    def command(self, pattern: str, *, set: Callable[[Args], None] | None = None,
                query: Callable[[Args], str | bytes] | None = None,
                max_suffix: int | tuple[int | None, ...] | None = None) -> None:
        """Register handlers for a SCPI pattern such as ``[SENSe:]VOLTage[:DC]:NPLCycles``.

        ``max_suffix`` bounds the numeric suffix of every ``#`` (or one entry per ``#``);
        a later registration of the same pattern and kind replaces the earlier one.
        """
        if set is None and query is None:
            raise ValueError(f"pattern {pattern!r}: give set= and/or query=")
        with self._lock:
            compile_pattern(self._root, self._commons, pattern, set, query, max_suffix)
            self._cache.clear()

    def vocabulary(self) -> dict[str, set[str]]:
        """The registered command tree: ``{pattern: {"set", "query"}}``, patterns as
        registered (``[SENSe:]VOLTage[:DC]:NPLCycles``, ``*IDN``), built-ins included."""
        with self._lock:
            return registered_patterns(self._root, self._commons)

    def pattern_of(self, header: str) -> str | None:
        """The registered pattern a header *as sent from the root* reaches (``VOLT:DC:RANG?``
        -> ``[SENSe:]VOLTage[:DC]:RANGe[:UPPer]``), or None when it is undefined or has no
        handler of its kind (set, or query with ``?``).  Parameters after the header are
        ignored; nothing is executed."""
        header = (header.split(None, 1) or [""])[0]
        query = header.endswith("?")
        name = header[:-1] if query else header
        with self._lock:
            if name.startswith("*"):
                node = self._commons.get(name.upper())
            else:
                hit = self._resolve(self._root, name)
                node = hit[0] if len(hit) == 3 else None
            entry = None if node is None else (node.query_entry if query else node.set_entry)
        return None if entry is None else entry.pattern.strip().removesuffix("?")

    # -- status and errors --------------------------------------------------------------
    @property
    def stb(self) -> int:
        """Status byte: EAV (bit 2), ESB (bit 5), MSS (bit 6), device bits 0/1/3/7."""
        stb = self.device_status_bits() & 0x8B
        if self._errors:
            stb |= 0x04
        if self.esr & self.ese:
            stb |= 0x20
        if stb & self.sre & ~0x40:
            stb |= 0x40
        return stb

    @property
    def errors(self) -> list[str]:
        """Queued error entries, oldest first (not consumed)."""
        return [format_error_entry(code, detail, self.error_texts) for code, detail in self._errors]

    def push_error(self, code: int, detail: str | None = None) -> None:
        """Queue an error and set its ESR bit; code 0 is ignored."""
        if not isinstance(code, int) or isinstance(code, bool):
            raise TypeError(f"SCPI error code must be an int, got {code!r}")
        if code == 0:
            return
        if -200 < code <= -100 and not self.detailed_command_errors:
            detail = None
        with self._lock:
            self.esr |= esr_bit_for(code)
            if len(self._errors) < self.error_queue_size:
                self._errors.append((code, detail))  # formatted when read: cheap floods
            else:
                self.esr |= esr_bit_for(-350)
                self._errors[-1] = (-350, None)

    def pop_error(self) -> str:
        """Oldest error entry, removed from the queue; ``+0,"No error"`` when empty."""
        with self._lock:
            if self._errors:
                code, detail = self._errors.popleft()
                return format_error_entry(code, detail, self.error_texts)
            return format_error_entry(0)

    # -- message handling -----------------------------------------------------------------
    def feed(self, data: bytes) -> bytes:
        """Frame raw stream bytes, process each complete message, return all responses.

        The device keeps one framer for this method, so it suits one byte stream (one
        connection); a server with several clients keeps a :class:`MessageFramer` per
        connection and calls :meth:`process` itself. Oversize messages queue -223.
        """
        out = []
        with self._lock:
            try:
                items = self._framer.feed(data)
            except Exception as exc:  # defensive: the framer is total over bytes
                self.push_error(-310, f"framer: {exc}")
                return b""
            for item in items:
                if isinstance(item, Oversize):
                    self.push_error(-223, f"message longer than {item.limit} bytes")
                    continue
                response = self.process(item)
                if response is not None:
                    out.append(response)
        return b"".join(out)

    def ask(self, message: str) -> str | None:
        """Convenience for tests: process ``message`` and return the decoded response."""
        response = self.process(message.encode("ascii", "replace"))
        return None if response is None else response.decode("latin-1").rstrip("\n")

    def process(self, message: bytes) -> bytes | None:
        """Execute one program message (terminator already removed).

        Returns the response message (query responses joined by ``;`` and ended by
        LF) or ``None`` when no query produced a response. Never raises ``Exception``.
        """
        try:
            with self._lock:
                return self._process(message)
        except Exception as exc:  # last-resort guard: the engine itself failed
            try:
                self.push_error(-310, f"{type(exc).__name__}: {exc}")
            except Exception:
                pass
            return None

    def _process(self, message) -> bytes | None:
        if not isinstance(message, bytes):
            message = (message.encode("utf-8", "replace") if isinstance(message, str)
                       else bytes(message))
        if len(message) > self.max_message_bytes:
            self.push_error(-223, f"message of {len(message)} bytes exceeds {self.max_message_bytes}")
            return None
        responses: list[bytes] = []
        node, path_suffixes = self._root, ()
        for segs, lex_error in lex_message(message):
            if lex_error is not None:
                self.push_error(*lex_error)
                continue
            try:
                parsed = parse_unit(segs)
            except ScpiError as exc:
                self.push_error(exc.code, exc.detail)
                continue
            if parsed is None:
                continue
            header, params = parsed
            query = header.endswith("?")
            name = header[:-1] if query else header
            if name.startswith("*"):
                entry = self._common_entry(name, query)
                if entry is None:
                    continue
                suffixes: tuple[int, ...] = ()
            else:
                hit = self._cache.get((node, name))
                if hit is None:
                    hit = self._resolve(node, name)
                    if len(self._cache) >= _CACHE_LIMIT:
                        self._cache.clear()
                    self._cache[(node, name)] = hit
                if len(hit) == 2:  # (code, detail)
                    self.push_error(*hit)
                    continue
                target, given, absolute = hit
                entry = target.query_entry if query else target.set_entry
                if entry is None:
                    self.push_error(-113, f"{header} is {'not a query' if query else 'query only'}"
                                    if (target.set_entry or target.query_entry) else None)
                    continue
                full = given if absolute else path_suffixes + given
                node, path_suffixes = target.parent, full[:-1]
                suffixes = tuple(1 if d is None else full[d] for d in entry.slots)
                if entry.max_suffix and any(s > lim for s, lim in zip(suffixes, entry.max_suffix)):
                    self.push_error(-114, f"{header}: suffixes {suffixes} exceed {entry.max_suffix}")
                    continue
            try:
                result = entry.func(Args(params, suffixes, header))
            except ScpiError as exc:
                self.push_error(exc.code, exc.detail)
                continue
            except Exception as exc:  # a device bug must not kill the connection
                self.push_error(-300, f"{type(exc).__name__}: {exc}")
                continue
            if query:
                if result is None:
                    self.push_error(-300, f"{header} handler returned no response")
                    continue
                responses.append(_encode_response(result))
        if not responses:
            return None
        return b";".join(responses) + b"\n"

    def _common_entry(self, name: str, query: bool):
        if "?" in name or not name[1:].isalpha():
            self.push_error(-102, f"malformed common command header {name[:40]!r}")
            return None
        if len(name) - 1 > MAX_MNEMONIC_CHARS:
            self.push_error(-112, f"common command header {name[:40]!r} too long")
            return None
        node = self._commons.get(name.upper())
        entry = None if node is None else (node.query_entry if query else node.set_entry)
        if entry is None:
            if node is None:
                self.push_error(-113, None)
            else:
                self.push_error(-113, f"{name.upper()} is {'not a query' if query else 'query only'}")
        return entry

    def _resolve(self, node: Node, name: str) -> tuple:
        absolute = name.startswith(":")
        body = name[1:] if absolute else name
        tokens = body.upper().split(":")
        if "?" in body or "*" in body or any(not t or not t[0].isalpha() for t in tokens):
            return (-102, f"malformed header {name[:40]!r}")
        if any(len(t.rstrip("0123456789")) > MAX_MNEMONIC_CHARS for t in tokens):
            return (-112, f"a mnemonic of {name[:40]!r} exceeds {MAX_MNEMONIC_CHARS} characters")
        try:
            target, given = resolve(self._root if absolute else node, tokens)
        except LookupError as exc:
            return exc.args
        return (target, given, absolute)

def _encode_response(result) -> bytes:
    """A handler's return value as response bytes (str is sent as ASCII)."""
    if isinstance(result, (bytes, bytearray, memoryview)):
        return bytes(result)
    if isinstance(result, bool):
        return b"1" if result else b"0"
    return str(result).encode("ascii", "replace")
