"""TCP servers for simulated instruments: one loopback port per instrument, one thread.

All servers run on one asyncio event loop in one background thread, so the World is only
ever touched by that thread — no locks, and commands from different clients are applied
in the order they arrive, as the physics requires.  A raw-socket SCPI instrument (port
5025 on real Keysight meters) is what pyvisa-py opens for ``TCPIP::host::port::SOCKET``.
A serial-line device (a :class:`ByteStreamDevice`, e.g. the FOG's frame output) is served
as a raw byte stream that pyserial opens as ``socket://host:port``; it writes to its one
client through a :class:`SerialLink` whenever the world runs it, on the same thread.

Robustness: every message goes through the device's ``process()``, which never raises;
a misbehaving client is disconnected on a socket error and never takes the server down.

Faults (``sim.faults``): when ``faults`` is set, each instrument's :class:`sim.faults.Gate`
decides whether a client is admitted, whether a message reaches the device (stall, power
loss, injected errors) and how a reply leaves (garbled, delayed); it can close the
instrument's connections (a dropped cable).
"""

from __future__ import annotations

import asyncio
import logging
import threading
import warnings
from dataclasses import dataclass
from typing import Protocol

from sim.scpi import MessageFramer, Oversize, ScpiDevice

log = logging.getLogger(__name__)
LOOPBACK = ("127.0.0.1", "::1", "localhost")


@dataclass
class Endpoint:
    name: str
    kind: str
    host: str
    port: int

    transport: str = "scpi"  # "scpi" (VISA raw socket) or "serial" (pyserial socket://)

    @property
    def resource(self) -> str:
        if self.transport == "serial":
            return f"socket://{self.host}:{self.port}"
        return f"TCPIP::{self.host}::{self.port}::SOCKET"


class SerialLink:
    """The server end of a connected serial line, as a byte-stream device sees it."""

    def __init__(self, writer: asyncio.StreamWriter) -> None:
        self._writer = writer

    def write(self, data: bytes) -> None:
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


class InstrumentServer:
    """Serves a set of SCPI devices, each on its own TCP port, from a background thread."""

    def __init__(self, host: str = "127.0.0.1") -> None:
        if host not in LOOPBACK:
            warnings.warn(f"simulated instruments will listen on {host}, reachable from the network",
                          stacklevel=2)
        self.host = host
        self._devices: list[tuple[str, str, ScpiDevice | ByteStreamDevice, int]] = []
        self.endpoints: list[Endpoint] = []
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._servers: list[asyncio.base_events.Server] = []
        self._ready = threading.Event()
        self._error: BaseException | None = None
        #: a ``sim.faults.FaultInjector`` (or None): per-instrument gates, see the module doc
        self.faults = None

    def add(self, name: str, kind: str, device: ScpiDevice | ByteStreamDevice,
            port: int = 0) -> None:
        if self._thread is not None:
            raise RuntimeError("add devices before start()")
        self._devices.append((name, kind, device, port))

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
        for name, kind, device, port in self._devices:
            serial = not isinstance(device, ScpiDevice)
            handler = self._serve_stream if serial else self._serve
            server = await asyncio.start_server(
                lambda r, w, d=device, h=handler, n=name: h(d, r, w, n), self.host, port,
                limit=1 << 22)
            self._servers.append(server)
            bound = server.sockets[0].getsockname()[1]
            self.endpoints.append(Endpoint(name, kind, self.host, bound,
                                           "serial" if serial else "scpi"))

    def stop(self) -> None:
        if self._loop is not None and self._loop.is_running():
            self._loop.call_soon_threadsafe(self._loop.stop)
        if self._thread is not None:
            self._thread.join(5)

    def call(self, fn, *args):
        """Run ``fn(*args)`` on the server thread (for fixtures and sim-control in-process)."""
        if self._loop is None:
            return fn(*args)
        fut = asyncio.run_coroutine_threadsafe(self._call(fn, *args), self._loop)
        return fut.result(60)

    @staticmethod
    async def _call(fn, *args):
        return fn(*args)

    # -- one client connection ---------------------------------------------------------------
    def _gate(self, name: str):
        return None if self.faults is None else self.faults.gates.get(name)

    async def _serve(self, device: ScpiDevice, reader: asyncio.StreamReader,
                     writer: asyncio.StreamWriter, name: str = "") -> None:
        framer = MessageFramer(max_message_bytes=device.max_message_bytes)
        gate = self._gate(name)
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
            if gate is not None:
                gate.release(writer)
            try:
                writer.close()
            except Exception:
                pass

    async def _serve_stream(self, device: ByteStreamDevice, reader: asyncio.StreamReader,
                            writer: asyncio.StreamWriter, name: str = "") -> None:
        link = SerialLink(writer)
        gate = self._gate(name)
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
            if gate is not None:
                gate.release(writer)
            try:
                writer.close()
            except Exception:
                pass
