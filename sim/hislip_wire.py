"""The HiSLIP wire (IVI-6.1 §2.3, the High-Speed LAN Instrument Protocol): what the server in
``sim.hislip`` reads and writes.

Every message is a 16-byte header — prologue ``HS``, message type, control code, a 32-bit
message parameter and a 64-bit payload length, big-endian — and its payload.  The message
types (Table 4) and the control codes the server sends (Tables 7, 9, 14) are the enums here.
:class:`Channel` reads one TCP connection a whole message at a time, through a buffer of its
own so the server can see what input is already waiting, and writes messages to it; a header
without the ``HS`` prologue raises :class:`PoorlyFormedHeaderError` (the stream cannot be
resynchronised).
"""

from __future__ import annotations

import asyncio
import struct
from dataclasses import dataclass
from enum import IntEnum

HEADER = struct.Struct(">2sBBIQ")  # prologue, type, control code, parameter, payload length
PROLOGUE = b"HS"


class Message(IntEnum):
    """HiSLIP message types (IVI-6.1 Table 4); 128..255 are vendor-defined."""

    INITIALIZE = 0
    INITIALIZE_RESPONSE = 1
    FATAL_ERROR = 2
    ERROR = 3
    ASYNC_LOCK = 4
    ASYNC_LOCK_RESPONSE = 5
    DATA = 6
    DATA_END = 7
    DEVICE_CLEAR_COMPLETE = 8
    DEVICE_CLEAR_ACKNOWLEDGE = 9
    ASYNC_REMOTE_LOCAL_CONTROL = 10
    ASYNC_REMOTE_LOCAL_RESPONSE = 11
    TRIGGER = 12
    INTERRUPTED = 13
    ASYNC_INTERRUPTED = 14
    ASYNC_MAXIMUM_MESSAGE_SIZE = 15
    ASYNC_MAXIMUM_MESSAGE_SIZE_RESPONSE = 16
    ASYNC_INITIALIZE = 17
    ASYNC_INITIALIZE_RESPONSE = 18
    ASYNC_DEVICE_CLEAR = 19
    ASYNC_SERVICE_REQUEST = 20
    ASYNC_STATUS_QUERY = 21
    ASYNC_STATUS_RESPONSE = 22
    ASYNC_DEVICE_CLEAR_ACKNOWLEDGE = 23
    ASYNC_LOCK_INFO = 24
    ASYNC_LOCK_INFO_RESPONSE = 25


VENDOR_DEFINED = 128


class FatalCode(IntEnum):
    """FatalError codes (Table 7): the session is closed after it."""

    UNIDENTIFIED = 0
    POORLY_FORMED_HEADER = 1
    CHANNELS_NOT_ESTABLISHED = 2
    INVALID_INITIALIZATION = 3
    TOO_MANY_CLIENTS = 4


class ErrorCode(IntEnum):
    """Error codes (Table 9): the message is skipped, the session goes on."""

    UNIDENTIFIED = 0
    UNRECOGNIZED_MESSAGE_TYPE = 1
    UNRECOGNIZED_CONTROL_CODE = 2
    UNRECOGNIZED_VENDOR_MESSAGE = 3
    MESSAGE_TOO_LARGE = 4


class LockResponse(IntEnum):
    """AsyncLockResponse control codes (Table 14)."""

    FAILURE = 0
    SUCCESS = 1          # a lock granted, or an exclusive lock released
    SUCCESS_SHARED = 2   # a shared lock released
    ERROR = 3            # a redundant request, or a release of a lock not held




@dataclass(frozen=True, slots=True)
class Header:
    """A HiSLIP message header (the prologue checked when it was read)."""

    type: int
    control: int
    parameter: int
    length: int


class PoorlyFormedHeaderError(Exception):
    """A header without the ``HS`` prologue: the stream cannot be resynchronised."""


class Channel:
    """One TCP connection of a session: whole messages in, through a buffer of its own so
    the server can see what input is already waiting (§3.1.1 rule 1); messages out."""

    def __init__(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self.reader, self.writer = reader, writer
        self._buf = bytearray()
        self._start = 0  # bytes of _buf already consumed

    @property
    def _available(self) -> int:
        return len(self._buf) - self._start

    async def _fill(self, n: int) -> None:
        while self._available < n:
            data = await self.reader.read(1 << 16)
            if not data:
                raise EOFError
            if self._start and self._start * 2 >= len(self._buf):
                del self._buf[:self._start]  # compact: consumed bytes never accumulate
                self._start = 0
            self._buf += data

    def _take(self, n: int) -> bytes:
        out = bytes(self._buf[self._start:self._start + n])
        self._start += n
        return out

    async def header(self) -> Header:
        await self._fill(HEADER.size)
        prologue, kind, control, parameter, length = HEADER.unpack(self._take(HEADER.size))
        if prologue != PROLOGUE:
            raise PoorlyFormedHeaderError(f"prologue {prologue!r}, not {PROLOGUE!r}")
        return Header(kind, control, parameter, length)

    async def payload(self, n: int) -> bytes:
        await self._fill(n)
        return self._take(n)

    async def skip(self, n: int) -> None:
        """Consume ``n`` payload bytes without keeping them (any length, any pace)."""
        k = min(n, self._available)
        self._start += k
        n -= k
        while n > 0:
            data = await self.reader.read(min(n, 1 << 16))
            if not data:
                raise EOFError
            n -= len(data)

    def waiting(self) -> Header | None:
        """The next message's header if it is already here whole, else None."""
        if self._available < HEADER.size:
            return None
        prologue, kind, control, parameter, length = HEADER.unpack_from(self._buf, self._start)
        return Header(kind, control, parameter, length) if prologue == PROLOGUE else None

    def send(self, kind: int, control: int = 0, parameter: int = 0, payload: bytes | memoryview = b"") -> None:
        if not self.writer.is_closing():
            self.writer.write(HEADER.pack(PROLOGUE, kind, control, parameter, len(payload)))
            if payload:
                self.writer.write(payload)

    def send_error(self, code: int, text: str, fatal: bool = False) -> None:
        self.send(Message.FATAL_ERROR if fatal else Message.ERROR, code, 0, text.encode("ascii", "replace"))

    async def drain(self) -> None:
        if not self.writer.is_closing():
            await self.writer.drain()

    def close(self) -> None:
        try:
            self.writer.close()
        except Exception:
            pass
