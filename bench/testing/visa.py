"""Stand-ins for a VISA resource: test a driver without its instrument.

A driver of this bench (``instruments.base.SCPIInstrument`` and its subclasses) speaks through
an open pyvisa ``MessageBasedResource``. These doubles take its place:

* :func:`expected_protocol` — the whole exchange, message by message, as
  ``pymeasure.test.expected_protocol``: the driver must write exactly the messages listed, in
  order, and read exactly the replies listed. A test per behaviour that names the bytes on the
  wire.
* :class:`FakeResource` — a table of replies: every written message is recorded, queries are
  answered from the table, ``SYST:ERR?`` from an error queue. For tests that care about what
  was written more than about the order of every read.
* :func:`pack_real64_block` — readings packed as a meter sends them in a definite-length block
  (``FORM REAL,64``, ``FORM:BORD SWAP``), written apart from the drivers' decoder and from
  pyvisa's encoder.
* :data:`SIM_YAML_DIR` — the pyvisa-sim files describing each simulated instrument's static
  vocabulary: ``pyvisa.ResourceManager(f"{SIM_YAML_DIR / 'turntable.yaml'}@sim")``.

Binary reads go through pyvisa's own ``read_binary_values``; ``_read_raw`` stops at the first
``\\n`` byte as a VISA read with the termination character enabled does, so a payload holding
0x0A exercises pyvisa's "read the rest of the block" path. Needs only pyvisa (no pytest).
"""

from __future__ import annotations

import struct
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from importlib.resources import files
from pathlib import Path
from typing import Any, TypeVar

from pyvisa.resources import MessageBasedResource

#: the reply to ``SYST:ERR?`` when the error queue is empty (SCPI-99, SYSTem:ERRor)
NO_ERROR = '+0,"No error"'
#: the folder of the pyvisa-sim YAML files, one per simulated instrument (package data of ``sim``)
SIM_YAML_DIR = Path(str(files("sim") / "visa_yaml"))

Reply = str | bytes
Exchange = Sequence[tuple[str | None, Reply | None]]
Driver = TypeVar("Driver")


class _WireBuffer:
    """What the instrument has sent and the driver has not read yet, read the ways pyvisa does."""

    resource_name = "FAKE0::INSTR"
    _read_termination = "\n"
    read_termination = "\n"
    query_delay = 0.0
    # pyvisa's own block reader, running on the methods below
    read_binary_values: Callable[..., Any] = MessageBasedResource.read_binary_values
    query_binary_values: Callable[..., Any] = MessageBasedResource.query_binary_values

    def __init__(self) -> None:
        self.written: list[str] = []
        self.chunk_size = 20 * 1024
        self.closed = False
        self._output = bytearray()

    def _send(self, reply: Reply) -> None:
        """Queue ``reply`` and its terminator for the driver to read."""
        self._output += (reply.encode() if isinstance(reply, str) else bytes(reply)) + b"\n"

    def _before_read(self) -> None:
        """Called before every read; a subclass may queue an unsolicited reply here."""

    def write(self, message: str) -> int:
        raise NotImplementedError

    def read(self) -> str:
        self._before_read()
        end = self._output.find(b"\n")
        if end < 0:
            raise AssertionError(f"the driver read a line but the instrument sent {bytes(self._output)!r}")
        text = bytes(self._output[:end]).decode()
        del self._output[: end + 1]
        return text

    def query(self, message: str) -> str:
        self.write(message)
        return self.read()

    def _read_raw(self, size: int | None = None, monitoring_interface: Any = None) -> bytearray:
        self._before_read()
        end = self._output.find(b"\n")
        take = len(self._output) if end < 0 else end + 1
        chunk = bytearray(self._output[:take])
        del self._output[:take]
        return chunk

    def read_bytes(self, count: int, chunk_size: int | None = None,
                   break_on_termchar: bool = False, monitoring_interface: Any = None) -> bytes:
        if count > len(self._output):  # pyvisa asks for 0 bytes when the block came whole
            self._before_read()
        assert count <= len(self._output), (
            f"the driver read {count} bytes; the instrument sent {len(self._output)}")
        chunk = bytes(self._output[:count])
        del self._output[:count]
        return chunk

    def close(self) -> None:
        self.closed = True


class FakeResource(_WireBuffer):
    """A pyvisa ``MessageBasedResource`` answering from a table of replies.

    Every written message is recorded in ``written``. A written message found in ``replies``
    queues its reply; ``SYST:ERR?`` pops ``error_queue`` and answers ``+0,"No error"`` when it
    is empty; any other query (a header ending in ``?``) is unexpected and fails the test.

    Parameters
    ----------
    replies : dict, optional
        Message → reply: a str, bytes (a binary block, see :func:`pack_real64_block`), or a
        callable ``message -> str | bytes``. Editable afterwards through ``replies``.
    errors : tuple of str, optional
        Entries of the instrument's error queue, oldest first, as ``SYST:ERR?`` reads them
        (``'-222,"Data out of range"'``).

    Attributes
    ----------
    written : list of str
        Every message the driver wrote, in order (queries included).
    error_queue : collections.deque of str
        The error queue still to be read.
    closed : bool
        Whether the driver closed the resource.

    Examples
    --------
    >>> from instruments.base import SCPIInstrument, control, in_range
    >>> class Source(SCPIInstrument):
    ...     level_v = control("LEV?", "LEV {value}", "Output level, volts.", validator=in_range,
    ...                       values=(0.0, 5.0))
    >>> fake = FakeResource(replies={"LEV?": "+2.5E+00"})
    >>> source = Source(fake)
    >>> source.level_v = 2.5
    >>> source.level_v
    2.5
    >>> fake.written
    ['LEV 2.5', 'SYST:ERR?', 'LEV?']
    """

    def __init__(self, replies: dict[str, Any] | None = None, errors: tuple[str, ...] = ()) -> None:
        super().__init__()
        self.replies: dict[str, Any] = dict(replies or {})
        self.error_queue: deque[str] = deque(errors)

    def write(self, message: str) -> int:
        self.written.append(message)
        reply = self._answer(message)
        if reply is not None:
            self._send(reply)
        return len(message) + 1

    def _answer(self, message: str) -> Reply | None:
        if message == "SYST:ERR?":
            return self.error_queue.popleft() if self.error_queue else NO_ERROR
        if message in self.replies:
            reply = self.replies[message]
            return reply(message) if callable(reply) else reply
        if message.split(" ")[0].endswith("?"):
            raise AssertionError(f"unexpected query {message!r}")
        return None


class ProtocolResource(_WireBuffer):
    """A pyvisa ``MessageBasedResource`` that holds the driver to one exchange, pair by pair.

    See :func:`expected_protocol`, which builds one and checks it is done.

    Parameters
    ----------
    exchange : sequence of (message, reply)
        ``message``: what the driver must write next (None: it reads without writing);
        ``reply``: what the instrument sends back, str or bytes (None: nothing).

    Attributes
    ----------
    written : list of str
        Every message the driver wrote, in order.
    done : int
        How many pairs of the exchange have taken place.
    """

    def __init__(self, exchange: Exchange) -> None:
        super().__init__()
        self.exchange = list(exchange)
        self.done = 0

    def _pair(self, index: int) -> str:
        message, reply = self.exchange[index]
        return f"pair {index} ({message!r}, {reply!r})"

    def write(self, message: str) -> int:
        self.written.append(message)
        if self._output:
            raise AssertionError(f"the driver wrote {message!r} before reading {bytes(self._output)!r}, "
                                 f"the reply to pair {self.done - 1}")
        if self.done == len(self.exchange):
            raise AssertionError(f"the driver wrote {message!r} after the last of {len(self.exchange)} pairs")
        expected, reply = self.exchange[self.done]
        if expected is None:
            raise AssertionError(f"the driver wrote {message!r}; {self._pair(self.done)} has it read without writing")
        if message != expected:
            raise AssertionError(f"the driver wrote {message!r}; {self._pair(self.done)} expects {expected!r}")
        self.done += 1
        if reply is not None:
            self._send(reply)
        return len(message) + 1

    def _before_read(self) -> None:
        if self._output:
            return
        if self.done == len(self.exchange) or self.exchange[self.done][0] is not None:
            what = "nothing is left" if self.done == len(self.exchange) else f"{self._pair(self.done)} is next"
            raise AssertionError(f"the driver read with nothing sent to it; {what}")
        reply = self.exchange[self.done][1]
        self.done += 1
        if reply is not None:
            self._send(reply)

    def assert_done(self) -> None:
        """Raise ``AssertionError`` unless every pair took place and every reply was read."""
        if self.done < len(self.exchange):
            left = ", ".join(self._pair(i) for i in range(self.done, len(self.exchange)))
            raise AssertionError(f"{len(self.exchange) - self.done} pair(s) of the exchange never took place: {left}")
        if self._output:
            raise AssertionError(f"the driver left {bytes(self._output)!r} unread")


@contextmanager
def expected_protocol(driver: Callable[..., Driver], exchange: Exchange, **kwargs: Any) -> Iterator[Driver]:
    """A driver on a resource that expects exactly ``exchange``: what it writes and reads.

    The driver is built as ``driver(resource, **kwargs)`` on a :class:`ProtocolResource`. Inside
    the block every write must be the next message of the exchange, and every read must find a
    reply; when the block ends without an error, every pair must have taken place and every
    reply been read. As ``pymeasure.test.expected_protocol``, for a driver of this bench.

    Parameters
    ----------
    driver : callable
        The driver class (or any callable taking the resource first).
    exchange : sequence of (message, reply)
        In order: ``message`` the driver writes (str, without the terminator; None when it reads
        without writing, e.g. a second reply to one query), ``reply`` the instrument sends back
        (str or bytes, without the terminator; None when it sends nothing). A query is one
        pair; a setting is its command with no reply, then the error check the driver does.
    **kwargs
        Passed to ``driver`` after the resource (e.g. ``name="psu"``).

    Yields
    ------
    object
        The driver, on the resource.

    Raises
    ------
    AssertionError
        At the first write that is not the next message, a read with nothing sent, or at the
        end when pairs are left or a reply was not read.

    Examples
    --------
    A user's driver for their own source, tested without the instrument:

    >>> from bench.testing import expected_protocol
    >>> from instruments.base import SCPIInstrument, control, in_range
    >>> class Source(SCPIInstrument):
    ...     level_v = control("LEV?", "LEV {value}", "Output level, volts.", validator=in_range,
    ...                       values=(0.0, 5.0))
    >>> with expected_protocol(Source, [("LEV 2.5", None), ("SYST:ERR?", '+0,"No error"'),
    ...                                 ("LEV?", "+2.50000E+00")], name="source") as source:
    ...     source.level_v = 2.5
    ...     source.level_v
    2.5

    A value outside the range is refused before anything goes on the wire (an empty exchange):

    >>> with expected_protocol(Source, []) as source:
    ...     source.level_v = 7.0
    Traceback (most recent call last):
    ...
    ValueError: level_v=7.0 is outside the allowed range [0, 5]

    A driver that writes something else fails at that write:

    >>> with expected_protocol(Source, [("LEV 2.5", None), ("SYST:ERR?", '+0,"No error"')]) as source:
    ...     source.level_v = 3
    Traceback (most recent call last):
    ...
    AssertionError: the driver wrote 'LEV 3'; pair 0 ('LEV 2.5', None) expects 'LEV 2.5'
    """
    resource = ProtocolResource(exchange)
    instrument = driver(resource, **kwargs)
    yield instrument
    resource.assert_done()


def pack_real64_block(values: Iterable[float]) -> bytes:
    """Readings as a meter sends them with ``FORM REAL,64`` and ``FORM:BORD SWAP``.

    An IEEE 488.2 definite-length arbitrary block of little-endian float64:
    ``#<n digits><length><payload>``, without the terminator (the doubles add it).

    Parameters
    ----------
    values : iterable of float
        The readings.

    Returns
    -------
    bytes
        The block.

    Examples
    --------
    >>> pack_real64_block([1.0])
    b'#18\\x00\\x00\\x00\\x00\\x00\\x00\\xf0?'
    """
    payload = b"".join(struct.pack("<d", float(v)) for v in values)
    length = str(len(payload))
    return b"#" + str(len(length)).encode() + length.encode() + payload
