"""Wire faults of the SCPI drivers: timeouts, lost connections, garbled replies.

The policy (docs/ARCHITECTURE.md, "Driver fault policy"): every failure names the
instrument and the command on one line; the session is reopened before the next transfer
(stale bytes of a late reply or half a block must not be read as the next reply); only
idempotent queries are re-sent, at most :data:`QUERY_RETRIES` times; commands are never
re-sent, except those that only bring an instrument to rest (:func:`safe_to_resend`).
"""

from __future__ import annotations

import logging
import re
import socket
from collections.abc import Callable
from typing import Any

log = logging.getLogger("instruments.base")

#: extra attempts of an idempotent query after a timeout, a lost connection or a garbled reply
QUERY_RETRIES = 2
#: pyvisa's VI_ERROR_TMO status code (no import of pyvisa needed to recognise it)
_VI_ERROR_TMO = -1073807339
#: commands that only bring an instrument to rest: safe to send twice, never harmful
_SAFE_TO_RESEND = re.compile(
    r"^\s*(?:OUTP(?:UT)?(?::STAT(?:E)?)?\s+(?:OFF|0)\b|:?ABOR(?:T)?\s*$|:?STOP\b|:?MODE:OFF\b)",
    re.IGNORECASE)


def safe_to_resend(command: str) -> bool:
    """True for ``OUTP OFF``, ``ABOR``, ``:STOP``, ``:MODE:OFF``: sending one twice is harmless."""
    return _SAFE_TO_RESEND.match(command) is not None


class InstrumentReplyError(RuntimeError):
    """A reply did not have the form the programming reference documents."""


class InstrumentTimeoutError(TimeoutError):
    """No reply in time: names the instrument, the query and (``after``) the command it
    was checking, the timeout and the attempts made."""

    def __init__(self, instrument_name: str, command: str, timeout_ms: Any, attempts: int,
                 after: str = "") -> None:
        self.instrument_name, self.command, self.attempts = instrument_name, command, attempts
        context = f" after {after!r}" if after else ""
        super().__init__(f"{instrument_name}: no reply to {command!r}{context} within "
                         f"{timeout_ms} ms ({attempts} attempt{'s' if attempts > 1 else ''})")


class InstrumentConnectionError(ConnectionError):
    """The connection to the instrument broke (or could not be reopened) during ``command``."""

    def __init__(self, instrument_name: str, command: str, cause: BaseException,
                 after: str = "") -> None:
        self.instrument_name, self.command = instrument_name, command
        text = " ".join(str(cause).split()) or type(cause).__name__
        context = f" after {after!r}" if after else ""
        # a connection that was never made is said as refused, not as lost
        what = "connection refused" if isinstance(cause, ConnectionRefusedError) or "refused" in text.lower() \
            else "connection lost"
        super().__init__(f"{instrument_name}: {what} at {command!r}{context} "
                         f"({type(cause).__name__}: {text[:160]})")


class WireFaults:
    """Mixin of :class:`instruments.base.SCPIInstrument`: failure handling of transfers.

    Needs ``self.resource``, ``self.name`` and ``self._stale`` (set False initially).
    """

    resource: Any
    name: str
    _stale: bool

    def _transact(self, command: str, operation: Callable[[], Any], *, retry: bool,
                  after: str = "") -> Any:
        attempts = 1 + (QUERY_RETRIES if retry else 0)
        for attempt in range(1, attempts + 1):
            if self._stale:
                self.reconnect(command)
            try:
                return operation()
            except Exception as exc:
                failure = self._classify(exc, command, attempt, after)
                if failure is None:
                    raise
                self._stale = True  # a late reply or half a block may follow: reopen first
                if attempt == attempts:
                    raise failure from exc
                log.warning("%s; asking again", failure)
        raise AssertionError("unreachable")

    def _classify(self, exc: Exception, command: str, attempt: int,
                  after: str = "") -> Exception | None:
        """The driver's error for a transfer failure, or None for anything else."""
        if getattr(exc, "error_code", None) == _VI_ERROR_TMO or isinstance(exc, TimeoutError):
            return InstrumentTimeoutError(self.name, command, getattr(self.resource, "timeout", "?"),
                                     attempt, after)
        if isinstance(exc, (UnicodeDecodeError, InstrumentReplyError)):
            context = f" after {after!r}" if after else ""
            return InstrumentReplyError(f"{self.name}: garbled reply to {command!r}{context}: "
                                        f"{' '.join(str(exc).split())[:160]}")
        if isinstance(exc, OSError) or type(exc).__name__ == "VisaIOError":
            return InstrumentConnectionError(self.name, command, exc, after)
        return None

    def reconnect(self, command: str = "reconnect") -> None:
        """Close and reopen the resource (fresh connection, no stale bytes), keeping its
        timeout and terminations.  Raises :class:`InstrumentConnectionError` on failure."""
        res = self.resource
        if not callable(getattr(res, "open", None)):  # a session that cannot be reopened
            self._stale = False
            return
        saved = {}
        for attr in ("timeout", "read_termination", "write_termination"):
            try:
                saved[attr] = getattr(res, attr)
            except Exception:  # a closed session cannot report its attributes
                pass
        saved = {**getattr(self, "_saved_session", {}), **saved}
        self._saved_session = saved
        try:
            try:
                res.close()
            except Exception:  # already broken: reopening is what matters
                pass
            res.open()
            for attr, value in saved.items():
                setattr(res, attr, value)
            tcp_no_delay(res)
        except Exception as exc:
            raise InstrumentConnectionError(self.name, f"reopen before {command}", exc) from exc
        self._stale = False
        log.warning("%s: reconnected", self.name)


def tcp_no_delay(resource: object) -> None:
    """Send each message at once on a pyvisa-py TCPIP socket session (TCP_NODELAY), as NI-VISA
    does by default (VI_ATTR_TCPIP_NODELAY = true).  pyvisa-py leaves Nagle's algorithm on and
    does not let the attribute be set, so a command followed by ``SYST:ERR?`` waits for the
    instrument's delayed ACK (≈ 6 ms a pair on loopback: two thirds of a simulated acceptance
    run).  Other backends and sessions are left as they are."""
    sessions = getattr(getattr(resource, "visalib", None), "sessions", None)
    session = sessions.get(getattr(resource, "session", None)) if isinstance(sessions, dict) else None
    interface = getattr(session, "interface", None)
    if isinstance(interface, socket.socket) and interface.family in (socket.AF_INET, socket.AF_INET6):
        interface.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
