"""Split a TCP byte stream into IEEE 488.2 program messages.

Over a raw socket (VISA ``::SOCKET`` resources) the program message terminator is a
line feed (LF, 0x0A); a CR immediately before it is dropped too, so CR LF clients work.
An LF is *not* a terminator only inside the payload of a definite-length block
``#<n><len><payload>`` (``n`` = 1..9 digits of ``len``): its bytes are counted, never
inspected.  An LF inside a quoted string *does* end the message: over a socket the LF is
the only END a client can send, and a client that left a quote open (``DISP:TEXT "abc``)
must get its error (-151 from the lexer) and its next command served, not a connection
that swallows everything until the size limit.  A block whose declared length exceeds
the message limit is reported as oversize at once and the stream resynchronises at the
next LF, so ``#9999999999`` cannot swallow a gigabyte.

An indefinite block ``#0<payload>`` runs to the next LF, which ends both the block
and the message (IEEE 488.2 §7.7.6.2: NL^END); a CR just before that LF belongs to the
payload. A ``#`` not followed by a valid block header (e.g. ``#H1F``, ``#B101``) is
ordinary text, and a malformed length field hands its first non-digit byte back to
ordinary scanning; the engine's lexer applies exactly the same rules, so both agree on
where strings and blocks end.

A message whose body grows past ``max_message_bytes`` is dropped and reported once as
an :class:`Oversize` marker at the moment the limit is crossed; the rest of it is
discarded up to its terminator. While discarding, definite-length blocks are still
counted (their lengths are declared, so the true message end is still known) but
quotes are no longer tracked: a quote still open after the limit is almost certainly
unbalanced, and ignoring it lets the stream resynchronise at the next LF.
A client that leaves a quote open *below* the limit gets no message until it closes
it, exactly as the standard's lexical rules imply.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

__all__ = ["MessageFramer", "Oversize"]

_LF = 0x0A
_CR = 0x0D
_SPECIAL = re.compile(rb"[\n'\"#]")
_SPECIAL_DISCARDING = re.compile(rb"[\n#]")  # quotes are not tracked while discarding

# lexical states
_NORMAL, _STRING, _HASH, _BLOCK_LEN, _BLOCK_DATA, _INDEFINITE = range(6)


@dataclass(frozen=True, slots=True)
class Oversize:
    """Marker returned by :meth:`MessageFramer.feed` in place of a message that
    exceeded ``limit`` bytes (the device answers with -223 "Too much data")."""

    limit: int


class MessageFramer:
    """Incremental splitter of a byte stream into program messages.

    Args:
        max_message_bytes: largest accepted message body in bytes (terminator
            excluded); must be >= 1.
        max_bytes: alias of ``max_message_bytes`` (keyword only).
    """

    def __init__(self, max_message_bytes: int = 1 << 20, *, max_bytes: int | None = None):
        if max_bytes is not None:
            max_message_bytes = max_bytes
        if (not isinstance(max_message_bytes, int) or isinstance(max_message_bytes, bool)
                or max_message_bytes < 1):
            raise ValueError(f"max_message_bytes must be an int >= 1, got {max_message_bytes!r}")
        self.max_message_bytes = max_message_bytes
        self.reset()

    def reset(self) -> None:
        """Forget any partial message (e.g. on a device clear or a new connection)."""
        self._buf = bytearray()
        self._size = 0               # body bytes of the current message, discarded or not
        self._discarding = False
        self._state = _NORMAL
        self._quote = 0
        self._digits_left = 0        # block length digits still expected
        self._block_len = 0
        self._remaining = 0          # block payload bytes still expected
        self._protected = 0          # buf[:protected] ends inside block data: no CR strip

    @property
    def pending(self) -> int:
        """Number of body bytes received for the message in progress."""
        return self._size

    def _take(self, data: bytes, start: int, stop: int, out: list) -> None:
        """Append data[start:stop] to the current message, enforcing the size limit."""
        if stop <= start:
            return
        self._size += stop - start
        if self._discarding:
            return
        if self._size > self.max_message_bytes:
            self._overflow(out)
            return
        self._buf += data[start:stop]

    def _overflow(self, out: list) -> None:
        """Report the current message as oversize and start discarding it."""
        out.append(Oversize(self.max_message_bytes))
        self._discarding = True
        self._buf = bytearray()
        if self._state == _STRING:
            self._state = _NORMAL

    def _finish(self, out: list, strip_cr: bool) -> None:
        """End the current message at a terminator."""
        if not self._discarding:
            buf = self._buf
            if strip_cr and buf and buf[-1] == _CR and len(buf) > self._protected:
                del buf[-1]
            out.append(bytes(buf))
        self._buf = bytearray()
        self._size = 0
        self._discarding = False
        self._state = _NORMAL
        self._protected = 0

    def feed(self, data: bytes) -> list[bytes | Oversize]:
        """Consume ``data``; return the messages it completed, in stream order.

        Each message is returned without its terminator. Never raises for any input
        bytes; partial messages are kept for the next call.
        """
        data = bytes(data)
        out: list[bytes | Oversize] = []
        i, n = 0, len(data)
        while i < n:
            state = self._state
            if state == _NORMAL:
                pattern = _SPECIAL_DISCARDING if self._discarding else _SPECIAL
                m = pattern.search(data, i)
                if m is None:
                    self._take(data, i, n, out)
                    break
                j = m.start()
                c = data[j]
                if c == _LF:
                    self._take(data, i, j, out)
                    self._finish(out, strip_cr=True)
                    i = j + 1
                    continue
                self._take(data, i, j + 1, out)
                if c == 0x23:  # '#'
                    self._state = _HASH
                else:
                    self._state = _STRING if not self._discarding else _NORMAL
                    self._quote = c
                i = j + 1
            elif state == _STRING:
                j = data.find(self._quote, i)
                lf = data.find(b"\n", i)
                lf_first = lf >= 0 and (j < 0 or lf < j)
                end = lf if lf_first else (n if j < 0 else j + 1)
                room = self.max_message_bytes - self._size
                if end - i > room:
                    # the limit falls inside the string: stop tracking the quote there
                    # and rescan the rest as ordinary text so a LF can end the message
                    self._take(data, i, i + room, out)
                    self._overflow(out)
                    i += room
                    continue
                self._take(data, i, end, out)
                if lf_first:
                    # an LF inside an open string ends the message (the lexer reports the
                    # unterminated string): rescan from the LF as ordinary text
                    self._state = _NORMAL
                    i = end
                    continue
                if j < 0:
                    break
                self._state = _NORMAL
                i = end
            elif state == _HASH:
                c = data[i]
                if 0x31 <= c <= 0x39:  # '1'..'9': definite-length block header
                    self._digits_left = c - 0x30
                    self._block_len = 0
                    self._state = _BLOCK_LEN
                    self._take(data, i, i + 1, out)
                    i += 1
                elif c == 0x30:  # '0': indefinite block to the terminator
                    self._state = _INDEFINITE
                    self._take(data, i, i + 1, out)
                    i += 1
                else:  # '#H1F' etc.: ordinary text, rescan this byte normally
                    self._state = _NORMAL
            elif state == _BLOCK_LEN:
                c = data[i]
                if 0x30 <= c <= 0x39:
                    self._block_len = self._block_len * 10 + (c - 0x30)
                    self._digits_left -= 1
                    self._take(data, i, i + 1, out)
                    i += 1
                    if self._digits_left == 0:
                        self._remaining = self._block_len
                        self._state = _BLOCK_DATA if self._block_len else _NORMAL
                        if self._size + self._block_len > self.max_message_bytes:
                            # a declared length past the limit: report now, resync at LF
                            if not self._discarding:
                                self._overflow(out)
                            self._state = _NORMAL
                else:  # malformed length: rescan this byte normally
                    self._state = _NORMAL
            elif state == _BLOCK_DATA:
                k = min(n, i + self._remaining)
                self._take(data, i, k, out)
                self._remaining -= k - i
                i = k
                if self._remaining == 0:
                    self._state = _NORMAL
                    self._protected = len(self._buf)
            else:  # _INDEFINITE
                j = data.find(b"\n", i)
                if j < 0:
                    self._take(data, i, n, out)
                    break
                self._take(data, i, j, out)
                self._finish(out, strip_cr=False)
                i = j + 1
        return out
