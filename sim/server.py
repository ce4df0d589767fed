"""TCP servers for simulated instruments: one loopback port per instrument, one thread.

All servers run on one asyncio event loop in one background thread, so the World is only
ever touched by that thread — no locks, and commands from different clients are applied
in the order they arrive, as the physics requires.

Each instrument is served over a :class:`Transport`, the kind of wire it has: a raw-socket
SCPI instrument (:data:`SCPI`; port 5025 on real Keysight meters) is what pyvisa-py opens for
``TCPIP::host::port::SOCKET``; a serial-line device (:data:`SERIAL`, a
:class:`ByteStreamDevice`, e.g. the FOG's frame output) is served as a raw byte stream that
pyserial opens as ``socket://host:port``, and writes to its one client through a
:class:`SerialLink` whenever the world runs it, on the same thread; a register-map device
(:data:`MODBUS`, a chamber controller) is served by pymodbus's asyncio Modbus TCP server on
the same loop, ``modbus://host:port``.

Robustness: every message goes through the device's ``process()``, which never raises;
a misbehaving client is disconnected on a socket error and never takes the server down.

Faults (``sim.faults``): when ``faults`` is set, each instrument's gate (a
:class:`ConnectionGate`) decides whether a client is admitted, whether a message reaches the
device (stall, power loss, injected errors), how a reply leaves (garbled, delayed) and what
becomes of a frame stream (corrupted, lost); it can close the instrument's connections (a
dropped cable).
"""

from __future__ import annotations

import asyncio
import logging
import threading
import warnings
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol, cast

from pymodbus.server import ModbusTcpServer
from pymodbus.server.requesthandler import ServerRequestHandler
from pymodbus.simulator import SimDevice

from sim.scpi import MessageFramer, Oversize, ScpiDevice

log = logging.getLogger(__name__)
LOOPBACK = ("127.0.0.1", "::1", "localhost")


class ConnectionGate(Protocol):
    """What a transport asks the fault layer about one instrument (``sim.faults.Gate``).

    Every transport calls the hooks that fit its wire: ``admit``/``release`` around each
    client, ``silent`` before a message reaches the device, ``intercept`` and ``outgoing``
    around a request/reply exchange, ``transmit`` on a device's unsolicited frame stream.
    """

    def admit(self, writer: Any) -> bool:
        """A client connects: False = close it at once."""

    def release(self, writer: Any) -> None:
        """The client's connection ended."""

    def silent(self) -> bool:
        """Stalled or unpowered: messages are discarded unanswered."""

    def intercept(self, device: ScpiDevice, message: bytes) -> bool:
        """True when ``message`` must not reach the device."""

    def outgoing(self, reply: bytes) -> tuple[bytes, float]:
        """The reply as it leaves and its delay in wall seconds."""

    def transmit(self, data: bytes, frame_bytes: int) -> bytes:
        """Whole frames of ``frame_bytes`` each on their way out: maybe corrupted, lost or silenced."""


class Listener(Protocol):
    """A started server of one instrument; closed when the station stops."""

    def close(self) -> None: ...


class SerialLink:
    """The server end of a connected serial line, as a byte-stream device sees it.

    Replies go out as written (:meth:`write`); a frame stream goes through the line's fault
    gate first (:meth:`write_frames`).
    """

    def __init__(self, writer: asyncio.StreamWriter, gate: ConnectionGate | None = None) -> None:
        self._writer = writer
        self._gate = gate

    def write(self, data: bytes) -> None:
        self._writer.write(data)

    def write_frames(self, data: bytes, frame_bytes: int) -> None:
        """Whole frames of ``frame_bytes`` bytes each; the line's faults may corrupt or lose them."""
        if self._gate is not None:
            data = self._gate.transmit(data, frame_bytes)
        if data:
            self._writer.write(data)

    @property
    def pending_bytes(self) -> int:
        """Bytes written but not yet taken by the socket (user-space send buffer)."""
        return self._writer.transport.get_write_buffer_size()


class ByteStreamDevice(Protocol):
    """A serial-line device: raw bytes both ways, one client at a time."""

    def connect(self, link: SerialLink) -> bool:
        """A client opened the line; False refuses it (the line is taken)."""

    def receive(self, link: SerialLink, data: bytes) -> None:
        """Bytes from the client (never raises)."""

    def disconnect(self, link: SerialLink) -> None:
        """The client closed the line."""


class Transport(ABC):
    """How a simulated instrument is served on loopback: its listener and connection loop,
    the address a client opens, and the faults its wire carries.

    One instance per kind of wire (:data:`SCPI`, :data:`SERIAL`, :data:`MODBUS`).  Another wire is one more
    subclass: set the class attributes, format the client's address in :meth:`resource`, and
    either implement :meth:`serve` (one asyncio stream connection, as the two here) or
    override :meth:`listen` to start a library's own asyncio server on the running loop
    (e.g. pymodbus's ``ModbusTcpServer`` for a Modbus TCP instrument, the gate's hooks in its
    ``trace_connect`` / ``trace_packet`` callbacks).
    """

    #: the endpoint's transport name, as ``bench sim serve`` prints it
    name: ClassVar[str]
    #: fault kinds this wire's server path applies (``sim.faults``); the device adds its own
    wire_fault_kinds: ClassVar[tuple[str, ...]]
    #: True when the network interface is the instrument's own (a LAN instrument): it dies with
    #: the instrument's power — connections dropped, new ones refused while off.  False for a
    #: serial line behind a terminal server, which stays up when the unit behind it goes dark.
    interface_in_instrument: ClassVar[bool]

    @abstractmethod
    def resource(self, host: str, port: int) -> str:
        """The address a driver opens (a VISA resource string, a pyserial URL, ...)."""

    async def listen(self, device: Any, host: str, port: int,
                     gate: Callable[[], ConnectionGate | None]) -> tuple[Listener, int]:
        """Start serving ``device`` on ``host:port`` (0: any free port) on the running loop;
        return the listener and the port bound.  ``gate()`` is the instrument's fault gate
        now (None without fault injection), asked once per connection."""
        server = await asyncio.start_server(
            lambda r, w: self.serve(device, r, w, gate()), host, port, limit=1 << 22)
        return server, server.sockets[0].getsockname()[1]

    async def serve(self, device: Any, reader: asyncio.StreamReader, writer: asyncio.StreamWriter,
                    gate: ConnectionGate | None) -> None:
        """One client connection (never raises; closes the writer when done)."""
        raise NotImplementedError(f"{type(self).__name__} serves through its own listen()")


class ScpiOverTcp(Transport):
    """A raw-socket SCPI instrument (port 5025 on real Keysight meters): newline-terminated
    program messages in, replies out; what pyvisa-py opens for ``TCPIP::host::port::SOCKET``."""

    name = "scpi"
    wire_fault_kinds = ("drop", "stall", "slow", "garble", "error")
    interface_in_instrument = True

    def resource(self, host: str, port: int) -> str:
        return f"TCPIP::{host}::{port}::SOCKET"

    async def serve(self, device: ScpiDevice, reader: asyncio.StreamReader,
                    writer: asyncio.StreamWriter, gate: ConnectionGate | None) -> None:
        framer = MessageFramer(max_message_bytes=device.max_message_bytes)
        try:
            if gate is not None and not gate.admit(writer):
                return  # reconnects refused for now: close at once
            while True:
                data = await reader.read(1 << 16)
                if not data:
                    break
                for message in framer.feed(data):
                    if isinstance(message, Oversize):
                        device.push_error(-223, "message longer than "
                                                f"{device.max_message_bytes} bytes discarded")
                        continue
                    if gate is not None and gate.intercept(device, message):
                        continue
                    reply = device.process(message)
                    if reply:
                        if gate is not None:
                            reply, delay_s = gate.outgoing(reply)
                            if delay_s:
                                await asyncio.sleep(delay_s)
                        writer.write(reply)
                        await writer.drain()
        except (ConnectionError, asyncio.IncompleteReadError, asyncio.CancelledError):
            pass
        except Exception:  # never let one client take the server down
            log.exception("client handler failed")
        finally:
            _close(writer, gate)


class SerialOverTcp(Transport):
    """A serial line served as a raw byte stream (a terminal server's TCP port), which pyserial
    opens as ``socket://host:port``; the device (a :class:`ByteStreamDevice`) writes to its one
    client through a :class:`SerialLink` whenever the world runs it, on the same thread."""

    name = "serial"
    wire_fault_kinds = ("drop", "stall")
    interface_in_instrument = False

    def resource(self, host: str, port: int) -> str:
        return f"socket://{host}:{port}"

    async def serve(self, device: ByteStreamDevice, reader: asyncio.StreamReader,
                    writer: asyncio.StreamWriter, gate: ConnectionGate | None) -> None:
        link = SerialLink(writer, gate)
        try:
            if gate is not None and not gate.admit(writer):
                return
            if not device.connect(link):
                return  # one client per line: close the second at once
            try:
                while True:
                    data = await reader.read(1 << 16)
                    if not data:
                        break
                    if gate is None or not gate.silent():
                        device.receive(link, data)
            finally:
                device.disconnect(link)
        except (ConnectionError, asyncio.IncompleteReadError, asyncio.CancelledError):
            pass
        except Exception:  # never let one client take the server down
            log.exception("serial client handler failed")
        finally:
            _close(writer, gate)


class ModbusDevice(Protocol):
    """A register-map device served over Modbus TCP: pymodbus's ``SimDevice`` of it, whose
    action callback reads and writes the device (on the server thread)."""

    def simdevice(self) -> SimDevice: ...


class _GatedModbusHandler(ServerRequestHandler):
    """pymodbus's per-connection handler with the instrument's fault gate in its path: admitted
    or closed at connect, a silent instrument discards requests unanswered.  The handler is what
    the gate holds as the connection (``gate.drop`` aborts its ``transport``)."""

    def __init__(self, owner: ModbusTcpServer, gate: ConnectionGate | None) -> None:
        super().__init__(owner, owner.trace_packet, owner.trace_pdu, owner.trace_connect)
        self._gate = gate

    def callback_connected(self) -> None:
        super().callback_connected()
        if self._gate is not None and not self._gate.admit(self):
            cast(asyncio.Transport, self.transport).abort()  # reconnects refused now, or powered off

    def callback_disconnected(self, exc: Exception | None) -> None:
        if self._gate is not None:
            self._gate.release(self)
        super().callback_disconnected(exc)

    def callback_data(self, data: bytes, addr: tuple | None = None) -> int:
        if self._gate is not None and self._gate.silent():
            return len(data)  # stalled or unpowered: the request is lost, no reply
        try:
            return super().callback_data(data, addr)
        except Exception:  # never let one client take the server down
            log.exception("modbus client handler failed")
            return len(data)


class _GatedModbusServer(ModbusTcpServer):
    def __init__(self, device: ModbusDevice, host: str, port: int,
                 gate: Callable[[], ConnectionGate | None]) -> None:
        super().__init__(device.simdevice(), address=(host, port))
        self._gate_of = gate

    def callback_new_connection(self) -> _GatedModbusHandler:
        return _GatedModbusHandler(self, self._gate_of())

    @property
    def sockets(self) -> tuple[Any, ...]:
        """The listening sockets (as an asyncio server has them)."""
        listening: Any = self.transport
        return tuple(listening.sockets) if listening is not None else ()


class ModbusTcp(Transport):
    """A Modbus TCP instrument (a chamber controller's Ethernet port, 502 on the real one):
    pymodbus's asyncio ``ModbusTcpServer`` on the one server loop, the device's register map
    as its data store; what a pymodbus ``ModbusTcpClient`` opens for ``modbus://host:port``."""

    name = "modbus"
    wire_fault_kinds = ("drop", "stall")
    interface_in_instrument = True

    def resource(self, host: str, port: int) -> str:
        return f"modbus://{host}:{port}"

    async def listen(self, device: Any, host: str, port: int,
                     gate: Callable[[], ConnectionGate | None]) -> tuple[Listener, int]:
        server = _GatedModbusServer(device, host, port, gate)
        await server.serve_forever(background=True)
        return server, int(server.sockets[0].getsockname()[1])


def _close(writer: asyncio.StreamWriter, gate: ConnectionGate | None) -> None:
    if gate is not None:
        gate.release(writer)
    try:
        writer.close()
    except Exception:
        pass


#: the wires of the simulated station
SCPI = ScpiOverTcp()
SERIAL = SerialOverTcp()
MODBUS = ModbusTcp()


@dataclass
class Endpoint:
    name: str
    kind: str
    host: str
    port: int
    transport: Transport = SCPI

    @property
    def resource(self) -> str:
        return self.transport.resource(self.host, self.port)


class FaultGates(Protocol):
    """The fault layer as the server sees it (``sim.faults.FaultInjector``)."""

    @property
    def gates(self) -> Mapping[str, ConnectionGate]: ...


class InstrumentServer:
    """Serves a set of devices, each on its own TCP port and transport, from a background thread."""

    def __init__(self, host: str = "127.0.0.1") -> None:
        if host not in LOOPBACK:
            warnings.warn(f"simulated instruments will listen on {host}, reachable from the network",
                          stacklevel=2)
        self.host = host
        self._devices: list[tuple[str, str, Any, Transport, int]] = []
        self.endpoints: list[Endpoint] = []
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._servers: list[Listener] = []
        self._ready = threading.Event()
        self._error: BaseException | None = None
        #: a ``sim.faults.FaultInjector`` (or None): per-instrument gates, see the module doc
        self.faults: FaultGates | None = None

    def add(self, name: str, kind: str, device: Any, transport: Transport = SCPI, port: int = 0) -> None:
        """Serve ``device`` as instrument ``name`` over ``transport`` (port 0: any free port)."""
        if self._thread is not None:
            raise RuntimeError("add devices before start()")
        self._devices.append((name, kind, device, transport, port))

    # -- lifecycle -------------------------------------------------------------------------
    def start(self) -> list[Endpoint]:
        self._thread = threading.Thread(target=self._run, name="sim-instruments", daemon=True)
        self._thread.start()
        self._ready.wait(10)
        if self._error is not None:
            raise RuntimeError(f"simulated station failed to start: {self._error}") from self._error
        return self.endpoints

    def _run(self) -> None:
        loop = asyncio.new_event_loop()
        self._loop = loop
        asyncio.set_event_loop(loop)
        try:
            loop.run_until_complete(self._open_all())
        except BaseException as exc:  # port in use, bad host: report to start()
            self._error = exc
            self._ready.set()
            return
        self._ready.set()
        loop.run_forever()
        # Orderly shutdown: stop listening, cancel client handlers, let them close sockets.
        for server in self._servers:
            server.close()
        tasks = [t for t in asyncio.all_tasks(loop) if not t.done()]
        for task in tasks:
            task.cancel()
        loop.run_until_complete(asyncio.gather(*tasks, return_exceptions=True))
        loop.close()

    async def _open_all(self) -> None:
        for name, kind, device, transport, port in self._devices:
            listener, bound = await transport.listen(device, self.host, port, self._gate_of(name))
            self._servers.append(listener)
            self.endpoints.append(Endpoint(name, kind, self.host, bound, transport))

    def stop(self) -> None:
        if self._loop is not None and self._loop.is_running():
            self._loop.call_soon_threadsafe(self._loop.stop)
        if self._thread is not None:
            self._thread.join(5)

    def call(self, fn: Callable[..., Any], *args: Any) -> Any:
        """Run ``fn(*args)`` on the server thread (for fixtures and sim-control in-process)."""
        if self._loop is None:
            return fn(*args)
        fut = asyncio.run_coroutine_threadsafe(self._call(fn, *args), self._loop)
        return fut.result(60)

    @staticmethod
    async def _call(fn: Callable[..., Any], *args: Any) -> Any:
        return fn(*args)

    def _gate_of(self, name: str) -> Callable[[], ConnectionGate | None]:
        """``name``'s fault gate when asked (the injector may be attached after ``add``)."""
        return lambda: None if self.faults is None else self.faults.gates.get(name)
