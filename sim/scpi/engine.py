"""IEEE 488.2 / SCPI-1999 device engine shared by every simulated SCPI instrument.

A server owns one :class:`ScpiDevice` (or a subclass), registers its command tree with
:meth:`ScpiDevice.command`, and either feeds raw socket bytes to :meth:`ScpiDevice.feed`
or frames them itself and calls :meth:`ScpiDevice.process` once per program message,
each connection in its own session (see "Sessions" below).
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

Sessions (one per client connection)
    Keysight's programming guides of its recent LAN instruments (34465A/34460A Truevolt,
    E36300 series, DAQ970A; ``SYSTem:ERRor?``) describe an error queue per remote I/O
    session: an error appears in the queue of the session whose message caused it.  (The
    guides' own text was not in our reference corpus; this follows their description as
    the task cited it, and what goes beyond it is marked as an assumption in
    docs/vocabulary/README.md, "Sessions".)  Per :class:`~sim.scpi.session.Session`: the
    error queue, the ESR (its error bits summarise that queue; ``*OPC`` sets its bit 0),
    ESE and SRE (assumption: the enables go with the ESR they summarise) and the byte-stream
    framer.  Shared on the device: settings, measurements, reading memory, the trigger
    system, ``*RST``, ``*TRG``, and the STB's instrument-wide bits 0, 1, 3, 7
    (:meth:`ScpiDevice.device_status_bits`, e.g. QUES/OPER summaries); EAV, ESB and MSS
    are each session's view.

    A transport (``sim.server.ScpiOverTcp``, a HiSLIP server) does, per connection::

        session = device.open_session()           # on connect
        reply = device.process(message, session)  # per program message (None: no reply)
        device.push_error(-223, "...", session=session)  # an error the transport detects
        with device.in_session(session): ...      # other code queueing errors for it (fault hooks)
        device.close_session(session)             # on disconnect (idempotent)

    ``session.framer`` splits a LF-terminated byte stream (``device.feed(data, session)``
    uses it); a transport with its own message boundaries (HiSLIP's DataEND) ignores it,
    and a device clear resets it (``session.framer.reset()``; the status is kept).
    Every method takes the device's lock, so a transport may call from any thread.

    ``session=None`` everywhere means the device's *default session*: what direct callers
    (tests, fixtures, ``feed``/``ask``/``process`` without a session) use, so they see one
    queue exactly as before sessions existed.  ``esr``, ``ese``, ``sre``, ``stb``,
    ``errors`` and ``pop_error`` act on the session being processed, else on the default one.

    An error queued while no message is being processed, or by
    :meth:`ScpiDevice.instrument_error` (a measurement failing as simulated time passes),
    was caused by no session: it goes to the default session and every open session; with
    none open, to the next session that opens, which also takes the power-on PON bit
    (assumption: what the instrument raised while nobody was connected is reported to the
    next client).
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from .common import CommonCommands
from .errors import ScpiError, format_error_entry
from .framing import Oversize
from .lexer import lex_message, parse_unit
from .params import Args
from .session import Session
from .tree import Node, compile_pattern, registered_patterns, resolve

__all__ = ["ScpiDevice"]

_CACHE_LIMIT = 4096
#: IEEE 488.2 §7.6.1.2: a program mnemonic has at most 12 characters (suffix excluded)
MAX_MNEMONIC_CHARS = 12
#: ESR bit 7, power on (IEEE 488.2 §11.5.1.1)
_PON = 0x80


class ScpiDevice(CommonCommands):
    """An IEEE 488.2 device with a SCPI command tree.

    Args:
        idn: manufacturer, model, serial number, firmware (the ``*IDN?`` fields; no
            commas, semicolons or line breaks).
        options: the ``*OPT?`` response.
        error_queue_size: capacity of each session's error queue (>= 1).
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
        self._default = Session(error_queue_size, max_message_bytes, "default")
        self._sessions: list[Session] = []  # open sessions, in the order they opened
        # events no open session saw (PON, instrument errors): the next session to open takes them
        self._unclaimed = Session(error_queue_size, max_message_bytes, "unclaimed")
        self._current: Session | None = None  # the session whose message is being processed
        self._opened = 0
        self._default.esr = self._unclaimed.esr = _PON  # the device has just been powered on
        self._root = Node(None)
        self._commons: dict[str, Node] = {}
        self._cache: dict[tuple[Node, str], tuple] = {}
        self._lock = threading.RLock()
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

    # -- sessions -----------------------------------------------------------------------
    def open_session(self) -> Session:
        """A new remote I/O session (a client connected): an empty error queue and ESR,
        enables 0, a fresh framer — plus the events no session has seen yet (PON, the
        instrument's own errors raised while no session was open)."""
        with self._lock:
            self._opened += 1
            session = Session(self.error_queue_size, self.max_message_bytes, f"session {self._opened}")
            session.take_from(self._unclaimed)
            self._sessions.append(session)
            return session

    def close_session(self, session: Session) -> None:
        """The client of ``session`` disconnected: its queue and status are discarded.
        Closing a closed session (or the default one) does nothing."""
        with self._lock:
            if session in self._sessions:
                self._sessions.remove(session)

    @property
    def sessions(self) -> tuple[Session, ...]:
        """The open sessions, oldest first (the default session is not among them)."""
        with self._lock:
            return tuple(self._sessions)

    @property
    def default_session(self) -> Session:
        """The session of direct callers (``process``/``feed``/``ask`` without a session)."""
        return self._default

    @property
    def session(self) -> Session:
        """The session status commands act on now: the one being processed, else the default."""
        return self._default if self._current is None else self._current

    @contextmanager
    def in_session(self, session: Session | None) -> Iterator[Session]:
        """Within the block, errors and status act on ``session`` (None: the default one),
        as while one of its messages is processed; e.g. a transport's fault hook."""
        with self._lock:
            outer, self._current = self._current, self._default if session is None else session
            try:
                yield self._current
            finally:
                self._current = outer

    def power_on_status(self) -> None:
        """Status at power-on: every session's queue empty and its ESR only PON (bit 7), and
        PON waiting for the next session to open; enables kept (IEEE 488.2 §11.5.1.1)."""
        with self._lock:
            for session in (self._default, self._unclaimed, *self._sessions):
                session.clear_status()
                session.esr = _PON

    # -- status and errors (of the current session) --------------------------------------
    @property
    def esr(self) -> int:
        """The current session's event status register."""
        return self.session.esr

    @esr.setter
    def esr(self, value: int) -> None:
        self.session.esr = value

    @property
    def ese(self) -> int:
        """The current session's event status enable register."""
        return self.session.ese

    @ese.setter
    def ese(self, value: int) -> None:
        self.session.ese = value

    @property
    def sre(self) -> int:
        """The current session's service request enable register."""
        return self.session.sre

    @sre.setter
    def sre(self, value: int) -> None:
        self.session.sre = value

    @property
    def stb(self) -> int:
        """Status byte as the current session sees it: EAV (bit 2, its queue), ESB (bit 5,
        its ESR & ESE), MSS (bit 6, with its SRE); the device's shared bits 0/1/3/7."""
        session = self.session
        stb = self.device_status_bits() & 0x8B
        if session.count:
            stb |= 0x04
        if session.esr & session.ese:
            stb |= 0x20
        if stb & session.sre & ~0x40:
            stb |= 0x40
        return stb

    @property
    def errors(self) -> list[str]:
        """The current session's queued error entries, oldest first (not consumed)."""
        return [format_error_entry(code, detail, self.error_texts) for code, detail in self.session.entries]

    def push_error(self, code: int, detail: str | None = None, *, session: Session | None = None) -> None:
        """Queue an error and set its ESR bit in ``session``, else in the session being
        processed; with neither, it is the instrument's own (:meth:`instrument_error`).
        Code 0 is ignored."""
        detail = self._checked(code, detail)
        if code == 0:
            return
        with self._lock:
            target = self._current if session is None else session
            if target is None:
                self._broadcast(code, detail)
            else:
                target.queue_error(code, detail)  # formatted when read: cheap floods

    def instrument_error(self, code: int, detail: str | None = None) -> None:
        """An error no session's message caused (a measurement failing in the instrument):
        queued in the default session and every open one; with none open, in the next to
        open.  Code 0 is ignored."""
        detail = self._checked(code, detail)
        if code != 0:
            with self._lock:
                self._broadcast(code, detail)

    def _checked(self, code: int, detail: str | None) -> str | None:
        """``detail`` as queued with ``code`` (bare text for -1xx unless detailed); a bad code raises."""
        if not isinstance(code, int) or isinstance(code, bool):
            raise TypeError(f"SCPI error code must be an int, got {code!r}")
        return None if -200 < code <= -100 and not self.detailed_command_errors else detail

    def _broadcast(self, code: int, detail: str | None) -> None:
        for session in (self._default, *(self._sessions or [self._unclaimed])):
            session.queue_error(code, detail)

    def pop_error(self) -> str:
        """The current session's oldest error entry, removed; ``+0,"No error"`` when empty."""
        with self._lock:
            entry = self.session.pop_error()
            return format_error_entry(0) if entry is None else format_error_entry(*entry, self.error_texts)

    # -- message handling -----------------------------------------------------------------
    def feed(self, data: bytes, session: Session | None = None) -> bytes:
        """Frame raw stream bytes with ``session``'s framer (None: the default session's),
        process each complete message in that session, return all responses.

        One framer per session, so each session suits one byte stream (one connection).
        Oversize messages queue -223.
        """
        out = []
        with self._lock, self.in_session(session) as current:
            try:
                items = current.framer.feed(data)
            except Exception as exc:  # defensive: the framer is total over bytes
                self.push_error(-310, f"framer: {exc}")
                return b""
            for item in items:
                if isinstance(item, Oversize):
                    self.push_error(-223, f"message longer than {item.limit} bytes")
                    continue
                response = self.process(item, current)
                if response is not None:
                    out.append(response)
        return b"".join(out)

    def ask(self, message: str, session: Session | None = None) -> str | None:
        """Convenience for tests: process ``message`` and return the decoded response."""
        response = self.process(message.encode("ascii", "replace"), session)
        return None if response is None else response.decode("latin-1").rstrip("\n")

    def process(self, message: bytes, session: Session | None = None) -> bytes | None:
        """Execute one program message (terminator already removed) in ``session`` (None:
        the default session): its errors and status commands act on that session only.

        Returns the response message (query responses joined by ``;`` and ended by
        LF) or ``None`` when no query produced a response. Never raises ``Exception``.
        """
        try:
            with self._lock, self.in_session(session):
                try:
                    return self._process(message)
                except Exception as exc:  # last-resort guard: the engine itself failed
                    self.push_error(-310, f"{type(exc).__name__}: {exc}")
                    return None
        except Exception:  # the guard itself failed: still never raise
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
