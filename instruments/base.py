"""SCPI instrument base: declarative settings, error-queue checking, connection helper.

A driver talks only through an open pyvisa ``MessageBasedResource`` (or anything with
the same ``write``/``query``/``query_binary_values`` methods); it never knows whether a
simulator or real hardware answers.

Faults on the wire (policy, docs/ARCHITECTURE.md "Driver fault policy"): a query that gets
no reply raises :class:`InstrumentTimeoutError`, a broken connection
:class:`InstrumentConnectionError`, a reply that cannot be decoded or parsed
:class:`InstrumentReplyError` — each naming the instrument and the command, on one line.
After any of these the session may hold stale bytes, so the next operation first reopens
the resource (reconnect).  Only idempotent queries are re-sent (at most
:data:`QUERY_RETRIES` times, each after a reconnect): setting readbacks (every
:class:`Setting` getter) and the headers in ``idempotent_queries``.  Commands are never
re-sent, except those that only bring the station to rest (``OUTP OFF``, ``ABOR``,
``:STOP``, ``:MODE:OFF``), which are sent once more over a new connection when the first
attempt was lost — sending them twice is harmless, losing one is not.

Each setting is declared once with :func:`control` / :func:`measurement`: the SCPI
command, the validator, the allowed values and a docstring (the PyMeasure style).
Setting a value validates it *before* anything goes on the wire, writes one command,
then drains ``SYST:ERR?`` until ``+0,"No error"`` and raises :class:`InstrumentError`
for anything the instrument reported.  Inside ``with inst.configuring():`` the error
check is deferred to the end of the group, so a group of settings costs one check.

The wire helpers and validators live in :mod:`instruments.validate`, the :class:`Setting`
descriptors in :mod:`instruments.properties` and the fault classes in
:mod:`instruments.wire`; this module re-exports them all, so drivers import from here.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
from collections.abc import Callable, Iterator, Sequence
from typing import Any

import numpy as np
import pyvisa

from .properties import Setting, Validator, control, measurement, read_settings
from .validate import (
    boolean,
    channel_list,
    format_number,
    in_range,
    in_set,
    int_in_range,
    parse_bool,
    parse_error_reply,
    parse_float,
    parse_int,
    quote_string,
    unquote_string,
)
from .wire import (
    QUERY_RETRIES,
    InstrumentConnectionError,
    InstrumentReplyError,
    InstrumentTimeoutError,
    WireFaults,
    safe_to_resend,
    tcp_no_delay,
)

__all__ = [
    "BINARY_CHUNK_SIZE", "DEFAULT_TIMEOUT_MS", "MAX_ERROR_READS", "QUERY_RETRIES", "Identity",
    "InstrumentChannel", "InstrumentConnectionError", "InstrumentError", "InstrumentReplyError",
    "InstrumentTimeoutError", "SCPIInstrument", "Setting", "UnsupportedInstrumentError", "Validator", "boolean",
    "channel_list", "control", "format_number", "in_range", "in_set", "int_in_range", "measurement",
    "open_resource", "parse_bool", "parse_error_reply", "parse_float", "parse_int", "quote_string",
    "read_settings", "safe_to_resend", "unquote_string",
]

log = logging.getLogger(__name__)

DEFAULT_TIMEOUT_MS = 10_000
#: Read chunk for binary transfers: a 1 MiB chunk moves ~130 k REAL,64 readings per read.
BINARY_CHUNK_SIZE = 1 << 20
#: Upper bound on SYST:ERR? reads per check (Truevolt's queue holds 20 entries); protects
#: against an instrument whose queue never reports "No error".
MAX_ERROR_READS = 64


class InstrumentError(RuntimeError):
    """The instrument put an error in its SCPI error queue.

    ``code``/``message`` are the first error read after ``command`` (the command, or the
    ``;``-joined group of commands, written since the previous check); ``further`` holds
    any other ``(code, message)`` pairs drained from the queue at the same time.
    """

    def __init__(
        self,
        instrument_name: str,
        command: str,
        code: int,
        message: str,
        further: Sequence[tuple[int, str]] = (),
    ) -> None:
        self.instrument_name = instrument_name
        self.command = command
        self.code = code
        self.message = message
        self.further = tuple(further)
        text = f'{instrument_name}: {code:+d},"{message}" after {command!r}'
        if self.further:
            text += " (also: " + "; ".join(f'{c:+d},"{m}"' for c, m in self.further) + ")"
        super().__init__(text)


class UnsupportedInstrumentError(RuntimeError):
    """``*IDN?`` names a model this driver does not know how to drive."""


@dataclasses.dataclass(frozen=True)
class Identity:
    """The four fields of an IEEE 488.2 ``*IDN?`` reply."""

    manufacturer: str
    model: str
    serial: str
    firmware: str

    @classmethod
    def parse(cls, reply: str) -> Identity:
        fields = [f.strip() for f in reply.strip().split(",")]
        if len(fields) != 4:
            raise InstrumentReplyError(f"*IDN? reply {reply!r} does not have four fields")
        return cls(*fields)


# --- instruments and channels ---------------------------------------------------------


class SCPIInstrument(WireFaults):
    """Base of every SCPI driver: wire access, error queue, configuration groups, IEEE 488.2.

    ``resource`` is an open pyvisa MessageBasedResource with ``\\n`` terminations (see
    :func:`open_resource`).  The constructor does no I/O.
    """

    #: query headers (upper case, as this driver sends them) that read without side
    #: effects and may be re-sent after a failure; drivers add theirs.  Deliberately absent:
    #: ``SYST:ERR?`` and ``*ESR?`` (reading consumes), ``*OPC?`` (a synchronisation point).
    idempotent_queries: frozenset[str] = frozenset({"*IDN?", "*OPT?", "*STB?"})

    def __init__(self, resource: Any, name: str | None = None) -> None:
        self.resource = resource
        self.name = name or f"{type(self).__name__}@{getattr(resource, 'resource_name', '?')}"
        self._group_depth = 0
        self._group_commands: list[str] = []
        self._identity: Identity | None = None
        self._stale = False  # a transfer failed: reopen before the next one

    # wire access
    def write(self, command: str) -> None:
        """Send ``command`` once (never re-sent here; see :meth:`configure_command`)."""
        log.debug("%s <- %s", self.name, command)
        self._transact(command, lambda: self.resource.write(command), retry=False)

    def query(self, command: str, *, retry: bool | None = None) -> str:
        """Send a query and return its reply, stripped.  ``retry`` (default: the header is
        in ``idempotent_queries``) allows :data:`QUERY_RETRIES` more attempts."""
        return self.query_value(command, lambda reply: reply, retry=retry)

    def query_value(self, command: str, parse: Callable[[str], Any], *,
                    retry: bool | None = None) -> Any:
        """``parse(reply)`` of a query; a reply that fails to parse counts as garbled."""
        if retry is None:
            retry = command.split(maxsplit=1)[0].upper() in self.idempotent_queries if command.strip() else False

        def once() -> Any:
            reply = self.resource.query(command).strip()
            log.debug("%s <- %s -> %s", self.name, command, reply)
            return parse(reply)
        return self._transact(command, once, retry=retry)

    def query_real64(self, command: str) -> np.ndarray:
        """Query a definite-length block of little-endian float64 (``FORM REAL,64``,
        ``FORM:BORD SWAP``); returns a new writable native float64 array.

        The block is read by byte count with the termination character disabled: a binary
        payload holds 0x0A bytes, and a termchar-enabled VISA read would return at each of
        them (pyvisa-py then moves 100 k readings ~20x slower).  The terminator after the
        block is read and checked, so the session stays in step with the instrument.
        """
        return self._transact(command, lambda: self._query_real64(command), retry=False)

    def _query_real64(self, command: str) -> np.ndarray:
        res = self.resource
        res.write(command)
        saved = res.read_termination
        res.read_termination = None
        try:
            head = bytes(res.read_bytes(2))
            if head[:1] != b"#" or not head[1:2].isdigit() or head[1:2] == b"0":
                raise InstrumentReplyError(
                    f"{self.name}: {command!r} answered {head!r}, not a definite-length block")
            length = int(bytes(res.read_bytes(int(head[1:2]))))
            if length % 8:
                raise InstrumentReplyError(
                    f"{self.name}: {command!r} block of {length} bytes is not whole float64 values")
            payload = bytes(res.read_bytes(length + 1))
        finally:
            res.read_termination = saved
        if payload[length:] != b"\n":
            raise InstrumentReplyError(
                f"{self.name}: {command!r} block not followed by the terminator: {payload[length:]!r}")
        values = np.frombuffer(payload, dtype="<f8", count=length // 8).astype(np.float64)
        log.debug("%s <- %s -> %d values", self.name, command, values.size)
        return values

    # settings plumbing used by Setting
    def command_fields(self) -> dict[str, Any]:
        return {}

    def label(self, setting_name: str) -> str:
        return setting_name

    def configure_command(self, command: str) -> None:
        """Write a configuring command; check the error queue now, or at the group's end.

        A command that only brings the instrument to rest (``OUTP OFF``, ``ABOR``,
        ``:STOP``, ``:MODE:OFF``) whose transfer or check failed on the wire is sent once
        more over a reopened connection; any other command is never re-sent.
        """
        try:
            self.write(command)
            if self._group_depth:
                self._group_commands.append(command)
            else:
                self.check_errors(command)
        except (InstrumentTimeoutError, InstrumentConnectionError) as exc:
            if self._group_depth or not safe_to_resend(command):
                raise
            log.warning("%s; sending %r again", exc, command)
            self.write(command)
            self.check_errors(command)

    @contextlib.contextmanager
    def configuring(self) -> Iterator[SCPIInstrument]:
        """Group settings so that ``SYST:ERR?`` is drained once, when the group ends.

        If the block raises, the queue is still drained (and logged) so stale errors are
        not blamed on later commands; the block's exception propagates.
        """
        self._group_depth += 1
        completed = False
        try:
            yield self
            completed = True
        finally:
            self._group_depth -= 1
            if self._group_depth == 0 and self._group_commands:
                commands = "; ".join(self._group_commands)
                self._group_commands.clear()
                if completed:
                    self.check_errors(commands)
                else:
                    self._drain_errors_quietly(commands)

    def check_errors(self, command: str = "") -> None:
        """Read ``SYST:ERR?`` until ``+0,"No error"``; raise :class:`InstrumentError` if any."""
        errors: list[tuple[int, str]] = []
        for _ in range(MAX_ERROR_READS):
            # never re-sent: reading consumes the entry, a lost reply would lose the error
            code, message = self._transact(
                "SYST:ERR?", lambda: parse_error_reply(self.resource.query("SYST:ERR?").strip()),
                retry=False, after=command)
            if code == 0:
                break
            errors.append((code, message))
        else:
            raise InstrumentReplyError(
                f"{self.name}: SYST:ERR? did not report 'No error' in {MAX_ERROR_READS} reads"
            )
        if errors:
            raise InstrumentError(self.name, command, *errors[0], further=errors[1:])

    def _drain_errors_quietly(self, command: str) -> None:
        try:
            self.check_errors(command)
        except Exception as exc:  # already unwinding from another error: report, don't mask
            log.warning("%s: while handling an earlier failure: %s", self.name, exc)

    # IEEE 488.2 common commands
    @property
    def idn(self) -> Identity:
        """``*IDN?`` parsed into manufacturer, model, serial, firmware (read once, cached)."""
        if self._identity is None:
            self._identity = Identity.parse(self.query("*IDN?"))
        return self._identity

    @property
    def options(self) -> tuple[str, ...]:
        """``*OPT?``: installed option codes; ``0``/empty placeholders dropped."""
        fields = (unquote_string(f) for f in self.query("*OPT?").split(","))
        return tuple(f.upper() for f in fields if f and f != "0")

    def reset(self) -> None:
        """``*RST`` (factory state), ``*OPC?`` to wait for it, then check the error queue."""
        self.write("*RST")
        self.query("*OPC?")
        self.check_errors("*RST")

    def clear(self) -> None:
        """``*CLS``: clear the error queue and the status event registers."""
        self.write("*CLS")

    #: Settings :meth:`snapshot` records (names of attributes readable over the wire).
    snapshot_settings: tuple[str, ...] = ()

    def snapshot(self) -> dict[str, Any]:
        """Identity and present settings, for the run record.

        A setting that cannot be read is recorded as ``"error: ..."`` rather than failing
        the snapshot, and the error queue is drained afterwards (logged) so a failed read
        is not blamed on the next command.
        """
        record = {"idn": dataclasses.asdict(self.idn),
                  "settings": read_settings(self, self.snapshot_settings)}
        record.update(self.snapshot_details())
        self._drain_errors_quietly("snapshot")
        return record

    def snapshot_details(self) -> dict[str, Any]:
        """Driver-specific additions to :meth:`snapshot` (channels, options ...)."""
        return {}

    def close(self) -> None:
        self.resource.close()


class InstrumentChannel:
    """A numbered sub-unit (supply output, table axis) that speaks through its parent."""

    #: Name of the format field the channel number fills in commands ("ch", "axis").
    field_name = "ch"

    def __init__(self, parent: SCPIInstrument, number: int) -> None:
        self.parent = parent
        self.number = number

    def write(self, command: str) -> None:
        self.parent.write(command)

    def query(self, command: str, *, retry: bool | None = None) -> str:
        return self.parent.query(command, retry=retry)

    def query_value(self, command: str, parse: Callable[[str], Any], *,
                    retry: bool | None = None) -> Any:
        return self.parent.query_value(command, parse, retry=retry)

    def command_fields(self) -> dict[str, Any]:
        return {self.field_name: self.number}

    def label(self, setting_name: str) -> str:
        return f"{self.field_name}[{self.number}].{setting_name}"

    def configure_command(self, command: str) -> None:
        self.parent.configure_command(command)

    def configuring(self) -> contextlib.AbstractContextManager[SCPIInstrument]:
        return self.parent.configuring()

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.number} of {self.parent.name}>"


def open_resource(
    address: str,
    backend: str = "@py",
    timeout_ms: int = DEFAULT_TIMEOUT_MS,
    resource_manager: Any = None,
    **kwargs: Any,
) -> Any:
    """Open a message-based VISA resource set up for these drivers.

    ``address`` e.g. ``TCPIP::127.0.0.1::5025::SOCKET``; ``backend`` is the pyvisa
    backend (``"@py"``, or ``"path/to.yaml@sim"`` for pyvisa-sim), used unless an open
    ``resource_manager`` is given.  Terminations are ``\\n`` both ways and the read
    chunk is large for binary reading transfers; extra keyword arguments go to
    ``ResourceManager.open_resource``.
    """
    manager = resource_manager if resource_manager is not None else pyvisa.ResourceManager(backend)
    options: dict[str, Any] = {
        "read_termination": "\n",
        "write_termination": "\n",
        "timeout": timeout_ms,
        "chunk_size": BINARY_CHUNK_SIZE,
    }
    options.update(kwargs)
    resource = manager.open_resource(address, **options)
    tcp_no_delay(resource)
    return resource
