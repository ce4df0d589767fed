"""Byte-level fuzzing of a SCPI server or the FOG line over real TCP: clients that know each
message's fate, and generators of messages (valid, invalid, oversize, junk).

A :class:`ScpiFuzzClient` sends one fuzz message followed by the probe
``SYST:ERR?;*CLS`` and reads the probe's answer: the first error the message queued (or
``+0``), with the queue cleared for the next message.  Whether the probe *should* be
answered is decided beforehand by feeding the same bytes to a reference
:class:`~sim.scpi.MessageFramer`: a message that opens a definite-length block within the
size limit rightly swallows the probe (the device waits for the declared payload), so
the client then reconnects, the only device clear a raw socket has.  A probe that
should be answered and is not within ``timeout_s`` is a hang.

A :class:`GyroFuzzClient` does the same on the FOG line with the probe ``$ID?``: every
non-empty line gets exactly one reply, ``$ERR,<code>,...`` for a bad one.
"""

from __future__ import annotations

import random
import re
import socket
from dataclasses import dataclass, field

from sim.scpi import MessageFramer

PROBE = b"SYST:ERR?;*CLS"
GYRO_PROBE = b"$ID?"
ERROR_LINE = re.compile(rb'^([+-]\d+),"')
UNDEFINED = -113


class NoReplyError(AssertionError):
    """A reply that should have come did not come within the timeout."""


@dataclass
class Tally:
    """What a fuzz client saw, by message class."""

    sent: int = 0
    answered: int = 0               # probe answered after the message
    silent: int = 0                 # probe rightly swallowed (open block): reconnected
    invalid: int = 0                # messages that must queue a standard error
    invalid_standard_error: int = 0  # ... and did (code in the expected class)
    wrong: list = field(default_factory=list)  # (message head, what came back)

    def add(self, other: Tally) -> None:
        for name in ("sent", "answered", "silent", "invalid", "invalid_standard_error"):
            setattr(self, name, getattr(self, name) + getattr(other, name))
        self.wrong += other.wrong


class _Line:
    """A TCP connection read line by line with a timeout."""

    def __init__(self, host: str, port: int, timeout_s: float) -> None:
        self.addr, self.timeout_s = (host, port), timeout_s
        self.sock: socket.socket | None = None
        self.buf = b""
        self.connect()

    def connect(self) -> None:
        self.close()
        self.sock = socket.create_connection(self.addr, timeout=self.timeout_s)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.buf = b""

    def close(self) -> None:
        if self.sock is not None:
            self.sock.close()
            self.sock = None

    def _open(self) -> socket.socket:
        if self.sock is None:
            raise ConnectionError(f"the connection to {self.addr} is closed; connect() first")
        return self.sock

    def send(self, data: bytes) -> None:
        self._open().sendall(data)

    def line(self, what: str) -> bytes:
        while b"\n" not in self.buf:
            try:
                chunk = self._open().recv(1 << 16)
            except TimeoutError:
                raise NoReplyError(f"no reply within {self.timeout_s} s to {what}") from None
            if not chunk:
                raise NoReplyError(f"connection closed by the server while waiting for {what}")
            self.buf += chunk
        line, _, self.buf = self.buf.partition(b"\n")
        return line.rstrip(b"\r")


class ScpiFuzzClient:
    """Fuzz one SCPI server; ``max_message_bytes`` must be the server's limit."""

    def __init__(self, host: str, port: int, *, max_message_bytes: int = 1 << 20,
                 timeout_s: float = 5.0) -> None:
        self.conn = _Line(host, port, timeout_s)
        self.limit = max_message_bytes
        self.reference = MessageFramer(max_message_bytes)

    def close(self) -> None:
        self.conn.close()

    def identify(self) -> bytes:
        self.conn.send(b"*IDN?\n")
        return self.conn.line("*IDN?")

    def send(self, message: bytes, expect: str, replies: int = 0, tally: Tally | None = None) -> None:
        """Send ``message`` + LF then the probe.  ``expect``: ``"ok"`` (no error),
        ``"command"`` (a -1xx error; ``"undefined"`` exactly -113), ``"oversize"`` (-223),
        ``"any"`` (junk: whatever, as long as the server stays sane).  ``replies``:
        response lines the message itself produces (a valid query: 1)."""
        tally = tally if tally is not None else Tally()
        tally.sent += 1
        data = message + b"\n" + PROBE + b"\n"
        self.reference.reset()
        framed = self.reference.feed(data)
        self.conn.send(data)
        if not framed or framed[-1] != PROBE:  # the probe is inside an open block: silent
            tally.silent += 1
            self.conn.connect()
            return
        lines = [self.conn.line(repr(message[:40])) for _ in range(replies)] if expect != "any" else []
        answer = self.conn.line(f"the probe after {message[:40]!r}")
        while expect == "any" and not ERROR_LINE.match(answer):  # junk may hold queries
            answer = self.conn.line(f"the probe after {message[:40]!r}")
        tally.answered += 1
        m = ERROR_LINE.match(answer)
        code = int(m.group(1)) if m else None
        if expect in ("command", "undefined", "oversize"):
            tally.invalid += 1
            good = {"command": code is not None and -199 <= code <= -100,
                    "undefined": code == UNDEFINED,
                    "oversize": code == -223}[expect]
            tally.invalid_standard_error += good
            if not good:
                tally.wrong.append((message[:40], answer[:80]))
        elif expect == "ok" and (code != 0 or len(lines) != replies):
            tally.wrong.append((message[:40], answer[:80]))
        elif expect == "any" and code is None:
            tally.wrong.append((message[:40], answer[:80]))


class GyroFuzzClient:
    """Fuzz the FOG line (the unit must be powered, else it is silent by design)."""

    def __init__(self, host: str, port: int, *, timeout_s: float = 5.0) -> None:
        self.conn = _Line(host, port, timeout_s)

    def close(self) -> None:
        self.conn.close()

    def identify(self) -> bytes:
        self.conn.send(GYRO_PROBE + b"\r\n")
        return self.conn.line("$ID?")

    def send(self, line: bytes, expect: str, tally: Tally | None = None) -> None:
        """``expect``: ``"ok"`` (a reply that is not ``$ERR``), ``"error"`` (one
        ``$ERR,<1..4>``), ``"any"`` (junk: replies until the probe's ``$ID``)."""
        tally = tally if tally is not None else Tally()
        tally.sent += 1
        self.conn.send(line + b"\r\n" + GYRO_PROBE + b"\r\n")
        replies: list[bytes] = []
        while True:
            reply = self.conn.line(f"$ID? after {line[:40]!r}")
            if reply.startswith(b"$ID,") and (expect == "any" or replies or not line.strip()):
                break
            replies.append(reply)
        tally.answered += 1
        if expect == "error":
            tally.invalid += 1
            good = len(replies) == 1 and re.match(rb"^\$ERR,[1-4],", replies[0]) is not None
            tally.invalid_standard_error += good
            if not good:
                tally.wrong.append((line[:40], replies))
        elif expect == "ok" and (len(replies) != 1 or replies[0].startswith(b"$ERR")):
            tally.wrong.append((line[:40], replies))


# -- message generators ---------------------------------------------------------------------
def _word(rng: random.Random, n: int) -> str:
    return "".join(rng.choice("ABCDEFGHIJKLMNOPQRSTUVWXYZ") for _ in range(n))


def scpi_message(rng: random.Random, valid: list[tuple[str, int]],
                 big: bool = True) -> tuple[bytes, str, int]:
    """One fuzz message for a SCPI server: (bytes, expect, reply lines)."""
    r = rng.random()
    if r < 0.25:
        text, replies = rng.choice(valid)
        return text.encode(), "ok", replies
    if r < 0.45:
        return f"ZQX{_word(rng, rng.randint(1, 6))}{rng.choice(['', '?'])} {rng.randint(0, 99)}".encode(), \
            "undefined", 0
    if r < 0.65:
        return rng.choice([
            b'ZQX "unterminated', b"*ESE 'x", b"ZQX #5123", b"*IDN? junk", b"::", b"*ESE 1,",
            b"1VOLT", b"SYST:ERR?:", b"ABCDEFGHIJKLMNOPQRSTUVWXYZ",
            b"*ESE 1e99999", b"*ESE (1", b"*SRE \"" + b"x" * 500,
        ]), "command", 0
    if big and r < 0.652:
        return rng.choice([b"ZQX " + b"A" * ((1 << 20) + 10), b"*ESE #9999999999" + b"\0" * 64]), \
            "oversize", 0
    if r < 0.7:  # a definite block declared within the limit and never sent: silent
        return f"*ESE #{rng.randint(5, 6)}{rng.randint(10000, 99999):05d}".encode()[:12], "any", 0
    junk = bytes(rng.randrange(256) for _ in range(rng.randint(1, 120)))
    return junk.replace(b"\n", b" ") if rng.random() < 0.5 else junk, "any", 0


GYRO_VALID = [b"$ID?", b"$CFG?", b"$RATE 100", b"$RATE 2000", b"$STOP", b"$id?"]


def gyro_line(rng: random.Random) -> tuple[bytes, str]:
    """One fuzz line for the FOG line: (bytes without the terminator, expect)."""
    r = rng.random()
    if r < 0.3:
        return rng.choice(GYRO_VALID), "ok"
    if r < 0.6:
        return rng.choice([b"$FOO", b"$RATE abc", b"$RATE 0", b"$RATE 99999", b"$ID? 1",
                           b"$BAUD 12", b"ID?", b"$" + b"X" * 100, b"$START now",
                           ("$" + _word(rng, 5)).encode()]), "error"
    junk = bytes(rng.randrange(256) for _ in range(rng.randint(1, 200)))
    return junk.replace(b"\n", b"").replace(b"\r", b"") or b"\x00", "any"
