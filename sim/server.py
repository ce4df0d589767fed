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

Paced time (``sim.world``): when the served World follows the wall (``World.pace``), the
server's :class:`WallPacer` runs it up to the paced clock before each message (every
transport hands its messages over through :func:`deliver`) and every :data:`PACE_TICK_S`, so
readings, ramps and frame streams progress for a client that only sleeps.  A message is
handled in a greenlet on the server thread: where it waits ahead of the paced clock
(``FETC?``, ``*OPC?``, ``SIM:TIME:ADV``) it is suspended until the wall catches up, and the
loop serves everyone else meanwhile — still one thread, so the World needs no locks.  Messages
to one instrument are handled one at a time, as by an instrument's one parser.

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
from dataclasses import dataclass, field
from typing import Any, ClassVar, Protocol, TypeVar, cast

from greenlet import getcurrent, greenlet
from pymodbus.server import ModbusTcpServer
from pymodbus.server.requesthandler import ServerRequestHandler
from pymodbus.simulator import SimDevice

from sim.scpi import Oversize, ScpiDevice, Session
from sim.world import World

log = logging.getLogger(__name__)
LOOPBACK = ("127.0.0.1", "::1", "localhost")
#: how often (wall s) the loop runs a paced world on by itself: a frame stream leaves, and a
#: ramp or an acquisition shows, within this of its simulated time for a client that only waits
PACE_TICK_S = 0.005
_T = TypeVar("_T")


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


class _Message(greenlet):
    """One message's handling on the server thread, suspended where it waits for the paced clock."""


class WallPacer:
    """Paced time on the server loop: runs ``world`` (paced, ``world.pace``) along the wall."""

    def __init__(self, world: World) -> None:
        if world.pace is None:
            raise ValueError("WallPacer needs a paced world (World(seed, pace=N))")
        self.world = world
        self._busy: dict[int, asyncio.Lock] = {}  # by id(device): one message at a time per instrument

    def start(self) -> None:
        """On the server thread, as it starts serving: the paced clock runs on from now, and
        a wait ahead of it suspends its message (:meth:`_suspend`)."""
        self.world.anchor_pace()
        self.world.wait_for_wall = self._suspend

    def catch_up(self) -> None:
        """The world up to the paced clock now (never raises)."""
        try:
            self.world.catch_up()
        except Exception:  # an event's failure must neither stop the clock nor drop a client
            log.exception("paced world failed to catch up")

    async def tick(self) -> None:
        """The loop's own task: keep the world up to the paced clock."""
        while True:
            self.catch_up()
            await asyncio.sleep(PACE_TICK_S)

    async def deliver(self, device: object | None, handle: Callable[..., Any], *args: Any) -> Any:
        """``handle(*args)`` once the world has caught up, suspended wherever it waits ahead of
        the paced clock; messages to ``device`` (when given) one at a time."""
        if device is None:
            return await self._run_message(handle, *args)
        async with self._busy.setdefault(id(device), asyncio.Lock()):
            return await self._run_message(handle, *args)

    async def _run_message(self, handle: Callable[..., Any], *args: Any) -> Any:
        self.catch_up()
        message = _Message(handle)
        result = message.switch(*args)  # back here when it ends, or waits: then `result` is the time
        try:
            while not message.dead:
                while (delay_s := self.world.wall_delay(result)) > 0:
                    await asyncio.sleep(delay_s)
                result = message.switch()
        except BaseException:  # cancelled (server stopping): unwind the message's stack
            if not message.dead:
                message.throw()
            raise
        return result

    def _suspend(self, t_s: float) -> None:
        """``world.wait_for_wall``: a message hands ``t_s`` to its :meth:`deliver` and sleeps;
        anything else (an in-process caller on another greenlet) sleeps its thread."""
        current = getcurrent()
        if isinstance(current, _Message):
            current.parent.switch(t_s)
        else:
            self.world.sleep_until(t_s)


class _ServingThread(threading.local):
    #: the pacer of the server whose loop runs on this thread (None: its world is event-driven)
    pacer: WallPacer | None = None


_serving = _ServingThread()


async def deliver(device: object | None, handle: Callable[..., _T], *args: Any) -> _T:
    """Hand one message to ``device``: ``handle(*args)`` (e.g. ``device.process``), on the
    server thread.  Event-driven, at once; paced, through the server's :class:`WallPacer`.
    Every transport passes its messages through here."""
    pacer = _serving.pacer
    if pacer is None:
        return handle(*args)
    return cast(_T, await pacer.deliver(device, handle, *args))


def _catch_up() -> None:
    """A paced world up to the wall now (for a transport whose messages arrive in a callback)."""
    if _serving.pacer is not None:
        _serving.pacer.catch_up()


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
        """One client connection is one I/O session of the device (its own error queue and
        status, ``sim.scpi.engine``), opened once admitted and closed when the connection ends."""
        session: Session | None = None
        try:
            if gate is not None and not gate.admit(writer):
                return  # reconnects refused for now: close at once
            session = device.open_session()
            while True:
                data = await reader.read(1 << 16)
                if not data:
                    break
                for message in session.framer.feed(data):
                    if isinstance(message, Oversize):
                        device.push_error(-223, "message longer than "
                                                f"{device.max_message_bytes} bytes discarded", session=session)
                        continue
                    if gate is not None:
                        with device.in_session(session):  # an injected error belongs to this client
                            refused = gate.intercept(device, message)
                        if refused:
                            continue
                    reply = await deliver(device, device.process, message, session)
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
            if session is not None:
                device.close_session(session)
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
                        await deliver(device, device.receive, link, data)
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
            _catch_up()
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
    #: the same instrument on its other wires, by transport name (a LAN SCPI instrument's
    #: HiSLIP port beside its raw socket): same device, its own port
    also: dict[str, Endpoint] = field(default_factory=dict)

    @property
    def resource(self) -> str:
        return self.transport.resource(self.host, self.port)


class FaultGates(Protocol):
    """The fault layer as the server sees it (``sim.faults.FaultInjector``)."""

    @property
    def gates(self) -> Mapping[str, ConnectionGate]: ...


class InstrumentServer:
    """Serves a set of devices, each on its own TCP port and transport, from a background thread."""

    def __init__(self, host: str = "127.0.0.1", world: World | None = None) -> None:
        """``world``: the World the served devices view; when it is paced (``world.pace``),
        the server's loop runs it along the wall (:class:`WallPacer`)."""
        if host not in LOOPBACK:
            warnings.warn(f"simulated instruments will listen on {host}, reachable from the network",
                          stacklevel=2)
        self.host = host
        self._devices: list[tuple[str, str, Any, Transport, int]] = []
        self.endpoints: list[Endpoint] = []
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._servers: list[Listener] = []
        self._also: dict[str, tuple[Transport, ...]] = {}  # an instrument's further wires
        self._also_servers: list[Listener] = []  # their listeners; _servers has one per endpoint
        self._ready = threading.Event()
        self._error: BaseException | None = None
        #: a ``sim.faults.FaultInjector`` (or None): per-instrument gates, see the module doc
        self.faults: FaultGates | None = None
        #: paced time on this server's loop (None: event-driven), see the module doc
        self.pacer = WallPacer(world) if world is not None and world.pace is not None else None

    def add(self, name: str, kind: str, device: Any, transport: Transport = SCPI, port: int = 0,
            also: tuple[Transport, ...] = ()) -> None:
        """Serve ``device`` as instrument ``name`` over ``transport`` (port 0: any free port),
        and over each of ``also`` on a free port of its own (``Endpoint.also``)."""
        if self._thread is not None:
            raise RuntimeError("add devices before start()")
        self._devices.append((name, kind, device, transport, port))
        if also:
            self._also[name] = also

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
        _serving.pacer = self.pacer
        try:
            loop.run_until_complete(self._open_all())
        except BaseException as exc:  # port in use, bad host: report to start()
            self._error = exc
            self._ready.set()
            return
        if self.pacer is not None:  # the paced clock starts as the addresses are handed out
            self.pacer.start()
            loop.create_task(self.pacer.tick())
        self._ready.set()
        loop.run_forever()
        # Orderly shutdown: stop listening, cancel client handlers, let them close sockets.
        for server in self._servers + self._also_servers:
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
            endpoint = Endpoint(name, kind, self.host, bound, transport)
            for other in self._also.get(name, ()):
                listener, bound = await other.listen(device, self.host, 0, self._gate_of(name))
                self._also_servers.append(listener)
                endpoint.also[other.name] = Endpoint(name, kind, self.host, bound, other)
            self.endpoints.append(endpoint)

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
        return await deliver(None, fn, *args)

    def _gate_of(self, name: str) -> Callable[[], ConnectionGate | None]:
        """``name``'s fault gate when asked (the injector may be attached after ``add``)."""
        return lambda: None if self.faults is None else self.faults.gates.get(name)
