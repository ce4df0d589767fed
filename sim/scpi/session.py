"""One remote I/O session's part of an IEEE 488.2 instrument's status.

A Keysight LAN instrument of the recent families (34465A/34460A Truevolt, E36300 supplies,
DAQ970A) keeps an error queue per remote I/O session, as their programming guides describe
it under ``SYSTem:ERRor?``: an error appears in the queue of the session whose message
caused it, and ``SYSTem:ERRor?`` on another connection does not see it.  A
:class:`Session` holds that per-connection state; :class:`sim.scpi.engine.ScpiDevice` owns
the sessions and decides which one a command acts on (see the engine's module docstring
for the API, for what stays shared, and for the assumptions).

Per session: the error queue (FIFO, ``capacity`` entries, -350 replacing the newest on
overflow, SCPI-1999 Vol. 2 §21.8.1), the event status register and its enable (ESR, ESE:
the ESR's error bits summarise this queue's entries, IEEE 488.2 §11.5.1), the service
request enable (SRE), and the byte-stream framer of the connection's input.
"""

from __future__ import annotations

from collections import deque

from .errors import esr_bit_for
from .framing import MessageFramer

__all__ = ["Session"]


class Session:
    """The status and input state of one remote I/O session (one client connection).

    Args:
        capacity: error queue entries (>= 1); the device's ``error_queue_size``.
        max_message_bytes: the framer's message limit; the device's ``max_message_bytes``.
        name: what the session is, for messages and ``repr`` (``"default"``, ``"tcp 3"``).

    Attributes:
        esr, ese, sre: the event status register, its enable and the service request enable
            (IEEE 488.2 §11.5.1, §11.3.2), 0..255.
        framer: splits this connection's byte stream into program messages (a stream
            transport feeds it; a device clear resets it with ``framer.reset()``).
    """

    def __init__(self, capacity: int, max_message_bytes: int, name: str = "") -> None:
        self.capacity = capacity
        self.name = name
        self.esr = 0
        self.ese = 0
        self.sre = 0
        self.framer = MessageFramer(max_message_bytes)
        self._errors: deque[tuple[int, str | None]] = deque()  # (code, detail), formatted when read

    def __repr__(self) -> str:
        return f"<Session {self.name or hex(id(self))}: {len(self._errors)} error(s), ESR {self.esr}>"

    @property
    def count(self) -> int:
        """Entries queued."""
        return len(self._errors)

    @property
    def entries(self) -> list[tuple[int, str | None]]:
        """Queued ``(code, detail)`` pairs, oldest first (not consumed)."""
        return list(self._errors)

    def queue_error(self, code: int, detail: str | None) -> None:
        """Queue ``code`` and set its ESR bit; on a full queue the newest entry becomes -350."""
        self.esr |= esr_bit_for(code)
        if len(self._errors) < self.capacity:
            self._errors.append((code, detail))
        else:
            self.esr |= esr_bit_for(-350)
            self._errors[-1] = (-350, None)

    def pop_error(self) -> tuple[int, str | None] | None:
        """The oldest entry, removed; None when the queue is empty."""
        return self._errors.popleft() if self._errors else None

    def clear_errors(self) -> None:
        self._errors.clear()

    def clear_status(self) -> None:
        """``*CLS``: this session's error queue and ESR cleared (enables kept, §10.3)."""
        self._errors.clear()
        self.esr = 0

    def take_from(self, other: Session) -> None:
        """Move ``other``'s entries (in order, overflow rules applied) and ESR bits here."""
        self.esr |= other.esr
        while (entry := other.pop_error()) is not None:
            self.queue_error(*entry)
        other.esr = 0
