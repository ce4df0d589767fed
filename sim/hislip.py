"""HiSLIP (IVI-6.1, the High-Speed LAN Instrument Protocol) for the simulated LAN instruments.

What pyvisa opens for ``TCPIP::host::hislip0,port::INSTR`` (``TCPIP::host::hislip0::INSTR`` on
the IANA port 4880): each SCPI instrument of the station answers here as well as on its raw
socket, with the same device, so settings and readings are shared; each HiSLIP session is one
I/O session of the device (its own error queue and status, ``sim.scpi.engine``).

The wire, headers and message types, is ``sim.hislip_wire``.  A session is two TCP connections
to the one port (§4.1): the *synchronous* channel opened with ``Initialize`` (sub-address
``hislip0`` or empty; the answer carries the session id) and the *asynchronous* one opened with
``AsyncInitialize`` naming that id.

Synchronous channel: ``Data``/``DataEnd`` carry program messages; DataEnd is the END of
IEEE 488.2, and a LF inside still ends a message, so the bytes go through the session's
:class:`~sim.scpi.MessageFramer` with END closing what is left (a CR LF or LF a driver appends
is a terminator, as on the socket).  Each reply leaves as ``Data``... ``DataEnd`` no larger
than the client's maximum message size, its LF kept, the DataEnd carrying the MessageID of
the client message whose eom produced it.  ``Trigger`` is ``*TRG`` (IEEE 488.2 §10.37: the
same as GET).  The server runs in *synchronized* mode only (§3: a server may offer one mode):
the InitializeResponse and the device-clear feature negotiation always say so, and:

* RMT (§3.1.1): a DataEnd sent sets *RMT-expected* and MAV; RMT-delivered from the client
  (control bit 0 of Data, DataEnd, Trigger, AsyncStatusQuery) clears both.  A new message
  while RMT is expected and not delivered is a query interrupted: -410 in the session's
  error queue (rule 2; no message goes to the client).  The reverse (delivered, not
  expected) is tolerated: pyvisa-py 0.8 keeps its flag across a device clear.
* A reply ready while more input is already waiting (another program message of the same
  payload, or a whole Data/DataEnd/Trigger header received) is discarded: -410, and
  ``AsyncInterrupted`` then ``Interrupted`` carrying the interrupting MessageID (§3.1.1
  rule 1, §4.11).

Asynchronous channel: ``AsyncMaximumMessageSize`` (the size is read header included, as
pyvisa-py does; the answer is ours, a whole program message plus a header),
``AsyncStatusQuery`` (the session's status byte with MAV as above in bit 4 and MSS
recomputed with it), ``AsyncDeviceClear`` → ``AsyncDeviceClearAcknowledge``, then
``DeviceClearComplete`` → ``DeviceClearAcknowledge`` on the synchronous channel, messages
in between discarded (§4.12; the device's settings and error queue are untouched, as IEEE
488.2's device clear leaves them), ``AsyncLock`` (exclusive with an empty lock string,
shared with a key; Table 15, waiting up to the request's timeout), ``AsyncLockInfo``,
``AsyncRemoteLocalControl`` (Table 18's three variables; the simulator has no front panel).
A client that holds no lock while another does has its synchronous messages left unread
until the lock is gone (§2.6.1).  A status query, an unlock or a remote/local request names
the client's last MessageID; the server first lets synchronous messages already received be
processed (§4.14.3, §4.5.1).

Errors (§4.2, §4.3): a bad prologue is a ``FatalError`` (poorly formed header) on both
channels and the session closed; so is anything but an Initialize/AsyncInitialize opening a
connection, an unknown session id, a second Initialize, or a Data/Trigger before both channels
exist.  A header that is well formed but cannot be used gets ``Error`` on its channel and is
skipped with its payload: an unknown or reserved message type (1), a vendor-defined one (3),
an unknown control code (2), a payload too large (4: a Data payload above the device's message
limit, which also discards the program message with -223; an asynchronous payload above
:data:`MAX_ASYNC_PAYLOAD`).

Faults (``sim.faults``): each connection is admitted by the instrument's gate and released
when it ends (a drop closes both channels); each program message passes ``intercept`` (stall,
power, injected errors), each reply ``outgoing`` (garble, delay); while the gate is
``silent`` every other message after the handshake is discarded unanswered.  Program
messages reach the device through ``sim.server.deliver``, so a paced world runs as on the socket.

Not implemented: overlapped mode, ``AsyncServiceRequest`` (no SRQ), HiSLIP 2.0's secure
connection, credentials and ``GetDescriptors`` (protocol version 1.0 is offered; a 2.0 client
falls back to it, §4.1).
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Awaitable, Callable
from dataclasses import dataclass

from sim.hislip_wire import (
    HEADER,
    VENDOR_DEFINED,
    Channel,
    ErrorCode,
    FatalCode,
    Header,
    LockResponse,
    Message,
    PoorlyFormedHeaderError,
)
from sim.scpi import Oversize, ScpiDevice, Session
from sim.server import ConnectionGate, Listener, ScpiOverTcp, Transport, deliver

log = logging.getLogger(__name__)

#: HiSLIP protocol version offered (upper byte major, lower minor): the 1.0 message set
PROTOCOL_VERSION = 0x0100
#: the server's vendor id, two ASCII letters (VPP-9 assigns them; none is registered here)
VENDOR_ID = b"IB"
#: the MessageID before a client's first (0xffffff00 after initialization or device clear,
#: §3.1.2): "no message yet" in an unlock, status or remote/local request
NO_MESSAGE_ID = 0xFFFF_FEFE
#: the MessageID of a Data message whose eom is not at the end of a client message (§3.1.1)
UNKNOWN_MESSAGE_ID = 0xFFFF_FFFF
#: §2.7: VISA limits lock strings and error texts to 256 characters, 272 bytes with a header;
#: four times that covers every asynchronous message a client has reason to send
MAX_ASYNC_PAYLOAD = 1024
MAX_SUB_ADDRESS = 256    # §4.1: the sub-address is at most 256 characters
MAX_SESSIONS = 64        # beyond this, Initialize is refused (fatal error 4)
#: a status, unlock or remote/local request naming a synchronous message not yet processed
#: waits this many event-loop turns for it: a message already received is processed within
#: two (its header and payload are buffered, the device answers without suspending), and a
#: client that names one it never sends (pyvisa-py 0.8 names its next MessageID) costs µs
CATCH_UP_TURNS = 8
MAV = 0x10   # IEEE 488.2 status byte bit 4, message available
MSS = 0x40   # bit 6, master summary status
SYNCHRONIZED = 0  # feature bit 0 clear: synchronized mode (the only one served)

#: AsyncRemoteLocalControl request → (RemoteEnable, LocalLockout, Remote); None: unchanged (Table 18)
REMOTE_LOCAL: dict[int, tuple[bool | None, bool | None, bool | None]] = {
    0: (False, False, False),   # disable remote
    1: (True, None, None),      # enable remote
    2: (False, False, False),   # disable remote and go to local
    3: (True, None, True),      # enable remote and go to remote
    4: (True, True, None),      # enable remote and lock out local
    5: (True, True, True),      # enable remote, go to remote, set local lockout
    6: (None, None, False),     # go to local without changing REN or lockout
}
_DATA_TYPES = (Message.DATA, Message.DATA_END, Message.TRIGGER)


class _Client:
    """One HiSLIP session: its two channels, its I/O session of the device and its
    synchronized-mode state."""

    def __init__(self, ident: int, sync: Channel, io: Session, gate: ConnectionGate | None) -> None:
        self.ident, self.sync, self.io, self.gate = ident, sync, io, gate
        self.asynchronous: Channel | None = None
        self.max_payload: int | None = None    # the client's maximum message size less a header
        self.last_id = NO_MESSAGE_ID           # last Data/DataEnd/Trigger MessageID received
        self.rmt_expected = False
        self.mav = False
        self.clearing = False                  # between AsyncDeviceClear and DeviceClearComplete
        self.dropping = False                  # the rest of a too-large program message
        self.lock_wait: asyncio.Task[None] | None = None
        self.closed = False

    def channels(self) -> list[Channel]:
        return [self.sync] if self.asynchronous is None else [self.sync, self.asynchronous]


class _Changes:
    """Wakes whoever waits for the lock state (or a client's clear or close) to change."""

    def __init__(self) -> None:
        self._event = asyncio.Event()

    def notify(self) -> None:
        self._event.set()
        self._event = asyncio.Event()

    async def wait(self) -> None:
        await self._event.wait()


class _Locks:
    """The instrument's HiSLIP locks across its sessions (§2.6, Table 15)."""

    def __init__(self) -> None:
        self.exclusive: _Client | None = None
        self.shared: set[_Client] = set()
        self.key = b""  # the shared holders' lock string

    @property
    def holders(self) -> int:
        return len(self.shared) + (self.exclusive is not None and self.exclusive not in self.shared)

    def permits(self, client: _Client) -> bool:
        """May ``client``'s synchronous messages be processed now?"""
        if self.exclusive is not None:
            return self.exclusive is client
        return not self.shared or client in self.shared

    def request(self, client: _Client, key: bytes) -> LockResponse | None:
        """Grant the lock now, refuse a redundant request, or None: it must wait."""
        if not key:  # exclusive
            if self.exclusive is client:
                return LockResponse.ERROR
            if self.exclusive is not None or (self.shared and client not in self.shared):
                return None
            self.exclusive = client
            return LockResponse.SUCCESS
        if client in self.shared or (self.exclusive is client and not self.shared):
            return LockResponse.ERROR
        if (self.exclusive is not None and not self.shared) or (self.shared and key != self.key):
            return None
        self.shared.add(client)
        self.key = key
        return LockResponse.SUCCESS

    def release(self, client: _Client) -> LockResponse:
        if self.exclusive is client:
            self.exclusive = None
            return LockResponse.SUCCESS
        if client in self.shared:
            self.shared.discard(client)
            return LockResponse.SUCCESS_SHARED
        return LockResponse.ERROR

    def drop(self, client: _Client) -> None:
        """A closed session's locks are released at once (§2.6)."""
        if self.exclusive is client:
            self.exclusive = None
        self.shared.discard(client)


@dataclass
class RemoteLocal:
    """The server's remote/local variables (§4.7); the simulator has no front panel."""

    remote_enable: bool = True
    local_lockout: bool = False
    remote: bool = False

    def control(self, request: int) -> None:
        for name, value in zip(("remote_enable", "local_lockout", "remote"), REMOTE_LOCAL[request]):
            if value is not None:
                setattr(self, name, value)

    def activity(self) -> None:
        """Data, a trigger, a status query, a device clear or a lock: remote if enabled."""
        if self.remote_enable:
            self.remote = True


class HislipServer:
    """The HiSLIP server of one instrument: its sessions, locks and remote/local state.
    Runs on the station's event loop; :meth:`connection` serves each TCP connection."""

    def __init__(self, device: ScpiDevice, gate: Callable[[], ConnectionGate | None]) -> None:
        self.device = device
        self._gate_of = gate
        self.clients: dict[int, _Client] = {}
        self.locks = _Locks()
        self.remote_local = RemoteLocal()
        self._changes = _Changes()
        self._next_id = 1

    # -- connections -------------------------------------------------------------------------
    async def connection(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        """One TCP connection, either channel of a session (never raises; closes the writer)."""
        gate = self._gate_of()
        channel = Channel(reader, writer)
        client: _Client | None = None
        try:
            if gate is not None and not gate.admit(writer):
                return  # reconnects refused for now, or the instrument is off
            header = await channel.header()
            if header.type == Message.INITIALIZE:
                client = await self._initialize(channel, header, gate)
                if client is not None:
                    await self._serve_sync(client)
            elif header.type == Message.ASYNC_INITIALIZE:
                client = await self._attach(channel, header)
                if client is not None:
                    await self._serve_async(client)
            else:
                channel.send_error(FatalCode.INVALID_INITIALIZATION, f"message type {header.type} before "
                                   "Initialize or AsyncInitialize", fatal=True)
        except PoorlyFormedHeaderError as exc:
            for ch in client.channels() if client is not None else [channel]:
                ch.send_error(FatalCode.POORLY_FORMED_HEADER, str(exc), fatal=True)
        except (ConnectionError, EOFError, asyncio.CancelledError):
            pass
        except Exception:  # never let one client take the server down
            log.exception("HiSLIP client handler failed")
        finally:
            if client is not None:
                self._end(client)
            if gate is not None:
                gate.release(writer)
            channel.close()

    async def _initialize(self, channel: Channel, header: Header,
                          gate: ConnectionGate | None) -> _Client | None:
        """Initialize → InitializeResponse (§4.1): a new session, synchronized mode preferred."""
        if header.length > MAX_SUB_ADDRESS:
            channel.send_error(FatalCode.INVALID_INITIALIZATION, f"sub-address of {header.length} bytes; "
                               f"at most {MAX_SUB_ADDRESS}", fatal=True)
            return None
        sub_address = (await channel.payload(header.length)).decode("latin-1")
        if sub_address and sub_address.lower() != "hislip0":
            channel.send_error(FatalCode.UNIDENTIFIED, f"no device {sub_address!r} here; this instrument "
                               "is hislip0", fatal=True)
            return None
        if len(self.clients) >= MAX_SESSIONS:
            channel.send_error(FatalCode.TOO_MANY_CLIENTS, f"{MAX_SESSIONS} sessions open", fatal=True)
            return None
        ident = self._new_id()
        client = _Client(ident, channel, self.device.open_session(), gate)
        self.clients[ident] = client
        channel.send(Message.INITIALIZE_RESPONSE, SYNCHRONIZED, PROTOCOL_VERSION << 16 | ident)
        return client

    def _new_id(self) -> int:
        while self._next_id in self.clients:
            self._next_id = self._next_id % 0xFFFF + 1
        ident = self._next_id
        self._next_id = self._next_id % 0xFFFF + 1
        return ident

    async def _attach(self, channel: Channel, header: Header) -> _Client | None:
        """AsyncInitialize → AsyncInitializeResponse: the session's second channel."""
        client = self.clients.get(header.parameter)
        if client is None or client.asynchronous is not None or header.length > MAX_ASYNC_PAYLOAD:
            channel.send_error(FatalCode.INVALID_INITIALIZATION, f"no session {header.parameter} awaits "
                               "its asynchronous channel", fatal=True)
            return None
        await channel.skip(header.length)
        client.asynchronous = channel
        channel.send(Message.ASYNC_INITIALIZE_RESPONSE, 0, int.from_bytes(VENDOR_ID, "big"))
        return client

    def _end(self, client: _Client) -> None:
        """Either channel ended: close the session, its I/O session and its locks."""
        if client.closed:
            return
        client.closed = True
        self.clients.pop(client.ident, None)
        self.locks.drop(client)
        if client.lock_wait is not None:
            client.lock_wait.cancel()
        self.device.close_session(client.io)
        for ch in client.channels():
            ch.close()
        self._changes.notify()

    def _fatal(self, client: _Client, code: FatalCode, text: str) -> None:
        for ch in client.channels():
            ch.send_error(code, text, fatal=True)

    async def _unusable(self, channel: Channel, header: Header, which: str) -> None:
        """A well-formed message this channel does not take: Error, payload skipped (§4.3)."""
        await channel.skip(header.length)
        if header.type >= VENDOR_DEFINED:
            channel.send_error(ErrorCode.UNRECOGNIZED_VENDOR_MESSAGE, f"vendor-defined message {header.type}")
        else:
            channel.send_error(ErrorCode.UNRECOGNIZED_MESSAGE_TYPE,
                               f"message type {header.type} is not one a server takes on the {which} channel")

    def _silent(self, client: _Client) -> bool:
        return client.gate is not None and client.gate.silent()

    # -- synchronous channel -------------------------------------------------------------------
    async def _serve_sync(self, client: _Client) -> None:
        channel = client.sync
        while not client.closed:
            header = await channel.header()
            kind = header.type
            if kind in _DATA_TYPES:
                if client.asynchronous is None:
                    self._fatal(client, FatalCode.CHANNELS_NOT_ESTABLISHED, "data before AsyncInitialize")
                    return
                await self._until_permitted(client)  # a lock held elsewhere: leave it unread
                if client.closed:
                    return
                if kind == Message.TRIGGER:
                    await channel.skip(header.length)
                    self._arrived(client, header)
                    if not client.clearing:
                        client.dropping = False  # its eom ends a too-large message too
                        await self._trigger(client, header)
                else:
                    await self._data(client, header)
            elif self._silent(client) and kind not in (Message.ERROR, Message.FATAL_ERROR):
                await channel.skip(header.length)  # stalled or unpowered: unanswered
            elif kind == Message.DEVICE_CLEAR_COMPLETE:
                await channel.skip(header.length)
                self._clear_complete(client)
            elif kind == Message.ERROR:
                await self._client_error(channel, header)
            elif kind == Message.FATAL_ERROR:
                await self._client_error(channel, header)
                return
            elif kind == Message.INITIALIZE:
                self._fatal(client, FatalCode.INVALID_INITIALIZATION, "Initialize on an initialized session")
                return
            else:
                await self._unusable(channel, header, "synchronous")

    async def _until_permitted(self, client: _Client) -> None:
        while not (self.locks.permits(client) or client.clearing or client.closed):
            await self._changes.wait()

    def _arrived(self, client: _Client, header: Header) -> None:
        """A Data, DataEnd or Trigger: RMT bookkeeping (§3.1.1 rule 2) and remote."""
        if client.rmt_expected and not header.control & 1:
            self.device.push_error(-410, "a new message came before the response was read",
                                   session=client.io)
        client.rmt_expected = client.mav = False
        client.last_id = header.parameter
        self.remote_local.activity()

    async def _data(self, client: _Client, header: Header) -> None:
        channel, end = client.sync, header.type == Message.DATA_END
        limit = self.device.max_message_bytes
        if header.length > limit:
            channel.send_error(ErrorCode.MESSAGE_TOO_LARGE, f"{header.length} bytes; at most {limit}")
            await channel.skip(header.length)
            self._arrived(client, header)
            if not client.clearing and not client.dropping:
                client.io.framer.reset()
                self.device.push_error(-223, f"message longer than {limit} bytes discarded", session=client.io)
            client.dropping = not end and not client.clearing
            return
        payload = await channel.payload(header.length)
        self._arrived(client, header)
        if client.clearing or client.dropping:
            client.dropping = client.dropping and not end
            return
        framer = client.io.framer
        messages = framer.feed(payload)
        if end:
            messages += self._end_of_message(client)
        at_end = framer.pending == 0
        for i, message in enumerate(messages):
            last = i == len(messages) - 1
            await self._execute(client, message, header.parameter, whole=at_end and last, more=not last)
            if client.clearing or client.closed:
                return

    async def _trigger(self, client: _Client, header: Header) -> None:
        """Trigger: GET, i.e. ``*TRG``; its eom also ends a message left open (§1.3)."""
        messages = [*self._end_of_message(client), b"*TRG"]
        for i, message in enumerate(messages):
            last = i == len(messages) - 1
            await self._execute(client, message, header.parameter, whole=last, more=not last)
            if client.clearing or client.closed:
                return

    def _end_of_message(self, client: _Client) -> list[bytes | Oversize]:
        """END (or GET's implicit eom) ends the message no LF ended yet."""
        framer = client.io.framer
        if not framer.pending:
            return []
        messages = framer.feed(b"\n")
        if framer.pending:  # the END fell inside a definite-length block: its bytes never came
            framer.reset()
            self.device.push_error(-161, "END inside a definite-length block", session=client.io)
        return messages

    async def _execute(self, client: _Client, message: bytes | Oversize, message_id: int,
                       whole: bool, more: bool) -> None:
        device, gate = self.device, client.gate
        if isinstance(message, Oversize):
            device.push_error(-223, f"message longer than {device.max_message_bytes} bytes discarded",
                              session=client.io)
            return
        if gate is not None:
            with device.in_session(client.io):  # an injected error belongs to this client
                if gate.intercept(device, message):
                    return
        reply = await deliver(device, device.process, message, client.io)  # paced time: sim.server
        if reply:
            await self._respond(client, reply, message_id, whole, more)

    async def _respond(self, client: _Client, reply: bytes, message_id: int, whole: bool, more: bool) -> None:
        """Send a reply as Data... DataEnd, or declare it interrupted (§3.1.1 rule 1)."""
        if client.gate is not None:
            reply, delay_s = client.gate.outgoing(reply)
            if delay_s:
                await asyncio.sleep(delay_s)
        if client.clearing or client.closed:
            return  # abandoned by a device clear during the delay
        interrupting = self._input_waiting(client, message_id, more)
        if interrupting is not None:
            self.device.push_error(-410, "the next message came before the response was sent",
                                   session=client.io)
            if client.asynchronous is not None:
                client.asynchronous.send(Message.ASYNC_INTERRUPTED, 0, interrupting)
            client.sync.send(Message.INTERRUPTED, 0, interrupting)
            return
        view, step = memoryview(reply), client.max_payload or len(reply)
        data_id = message_id if whole else UNKNOWN_MESSAGE_ID
        start = 0
        while len(reply) - start > step:
            client.sync.send(Message.DATA, 0, data_id, view[start:start + step])
            start += step
        client.sync.send(Message.DATA_END, 0, message_id, view[start:])
        client.rmt_expected = client.mav = True
        await client.sync.drain()

    @staticmethod
    def _input_waiting(client: _Client, message_id: int, more: bool) -> int | None:
        """The MessageID of input already waiting behind a reply (another program message of
        this one's payload, or a whole Data/DataEnd/Trigger header received), else None."""
        if more or client.io.framer.pending:
            return message_id
        waiting = client.sync.waiting()
        return waiting.parameter if waiting is not None and waiting.type in _DATA_TYPES else None

    def _clear_complete(self, client: _Client) -> None:
        """DeviceClearComplete → DeviceClearAcknowledge: synchronized mode, whatever was asked."""
        client.clearing = client.dropping = client.rmt_expected = client.mav = False
        client.io.framer.reset()
        client.last_id = NO_MESSAGE_ID
        client.sync.send(Message.DEVICE_CLEAR_ACKNOWLEDGE, SYNCHRONIZED)

    async def _client_error(self, channel: Channel, header: Header) -> None:
        text = await channel.payload(header.length) if header.length <= MAX_ASYNC_PAYLOAD else b""
        if header.length > MAX_ASYNC_PAYLOAD:
            await channel.skip(header.length)
        log.info("HiSLIP client reported %s %d: %s", Message(header.type).name, header.control,
                 text.decode("latin-1")[:200])

    # -- asynchronous channel ------------------------------------------------------------------
    async def _serve_async(self, client: _Client) -> None:
        channel = client.asynchronous
        assert channel is not None
        handlers: dict[int, Callable[[_Client, Header, bytes], Awaitable[None]]] = {
            Message.ASYNC_LOCK: self._lock, Message.ASYNC_LOCK_INFO: self._lock_info,
            Message.ASYNC_REMOTE_LOCAL_CONTROL: self._remote_local,
            Message.ASYNC_MAXIMUM_MESSAGE_SIZE: self._maximum_message_size,
            Message.ASYNC_DEVICE_CLEAR: self._device_clear, Message.ASYNC_STATUS_QUERY: self._status_query,
        }
        while not client.closed:
            header = await channel.header()
            kind = header.type
            if kind in (Message.ERROR, Message.FATAL_ERROR):
                await self._client_error(channel, header)
                if kind == Message.FATAL_ERROR:
                    return
            elif self._silent(client):
                await channel.skip(header.length)  # stalled or unpowered: unanswered
            elif kind == Message.ASYNC_INITIALIZE:
                self._fatal(client, FatalCode.INVALID_INITIALIZATION, "AsyncInitialize on an initialized session")
                return
            elif kind not in handlers:
                await self._unusable(channel, header, "asynchronous")
            elif header.length > MAX_ASYNC_PAYLOAD:
                channel.send_error(ErrorCode.MESSAGE_TOO_LARGE, f"{header.length} bytes; at most {MAX_ASYNC_PAYLOAD}")
                await channel.skip(header.length)
            else:
                await handlers[kind](client, header, await channel.payload(header.length))
            await channel.drain()  # a client that never reads its answers is not buffered for

    def _reply(self, client: _Client, kind: Message, control: int = 0, parameter: int = 0,
               payload: bytes = b"") -> None:
        if client.asynchronous is not None and not client.closed:
            client.asynchronous.send(kind, control, parameter, payload)

    def _refuse(self, client: _Client, code: ErrorCode, text: str) -> None:
        """Error on the asynchronous channel: the request is not carried out (§4.3)."""
        self._reply(client, Message.ERROR, code, 0, text.encode("ascii", "replace"))

    async def _catch_up(self, client: _Client, message_id: int) -> None:
        """Let synchronous messages up to ``message_id`` that are already here be processed."""
        for _ in range(CATCH_UP_TURNS):
            ahead = (message_id - client.last_id) & 0xFFFF_FFFF
            if not 0 < ahead < 1 << 31:
                return
            await asyncio.sleep(0)

    async def _maximum_message_size(self, client: _Client, header: Header, payload: bytes) -> None:
        if len(payload) != 8:
            self._refuse(client, ErrorCode.UNIDENTIFIED, f"AsyncMaximumMessageSize carries 8 bytes, not {len(payload)}")
            return
        client.max_payload = max(int.from_bytes(payload, "big") - HEADER.size, 1)
        ours = HEADER.size + self.device.max_message_bytes
        self._reply(client, Message.ASYNC_MAXIMUM_MESSAGE_SIZE_RESPONSE, 0, 0, ours.to_bytes(8, "big"))

    async def _status_query(self, client: _Client, header: Header, payload: bytes) -> None:
        await self._catch_up(client, header.parameter)
        if header.control & 1:  # RMT delivered (§4.14.1)
            client.rmt_expected = client.mav = False
        self.remote_local.activity()
        # the world brought up to a paced clock first, but not queued behind a message in progress
        self._reply(client, Message.ASYNC_STATUS_RESPONSE, await deliver(None, self._status_byte, client))

    def _status_byte(self, client: _Client) -> int:
        """The session's status byte with MAV as HiSLIP keeps it, and MSS recomputed with it."""
        with self.device.in_session(client.io):
            stb, sre = self.device.stb, self.device.sre
        stb = stb & ~(MAV | MSS) | (MAV if client.mav else 0)
        return stb | MSS if stb & sre & ~MSS else stb

    async def _device_clear(self, client: _Client, header: Header, payload: bytes) -> None:
        """AsyncDeviceClear: a pending lock request fails now, the session's input and output
        are abandoned until DeviceClearComplete (§4.12)."""
        if client.lock_wait is not None and not client.lock_wait.done():
            client.lock_wait.cancel()
            self._reply(client, Message.ASYNC_LOCK_RESPONSE, LockResponse.FAILURE)
        client.clearing = True
        client.dropping = client.rmt_expected = client.mav = False
        client.io.framer.reset()
        self.remote_local.activity()
        self._changes.notify()  # a synchronous channel waiting for a lock goes on to discard
        self._reply(client, Message.ASYNC_DEVICE_CLEAR_ACKNOWLEDGE, SYNCHRONIZED)

    async def _remote_local(self, client: _Client, header: Header, payload: bytes) -> None:
        if header.control not in REMOTE_LOCAL:
            self._refuse(client, ErrorCode.UNRECOGNIZED_CONTROL_CODE,
                         f"remote/local request {header.control} not in 0..6")
            return
        await self._catch_up(client, header.parameter)
        self.remote_local.control(header.control)
        self._reply(client, Message.ASYNC_REMOTE_LOCAL_RESPONSE)

    async def _lock_info(self, client: _Client, header: Header, payload: bytes) -> None:
        self._reply(client, Message.ASYNC_LOCK_INFO_RESPONSE, int(self.locks.exclusive is not None),
                    self.locks.holders)

    async def _lock(self, client: _Client, header: Header, payload: bytes) -> None:
        """AsyncLock: request (1; the parameter is the timeout in ms, an empty lock string
        asks for the exclusive lock) or release (0; after the named message)."""
        if header.control not in (0, 1):
            self._refuse(client, ErrorCode.UNRECOGNIZED_CONTROL_CODE,
                         f"lock control {header.control} not 0 (release) or 1 (request)")
            return
        if client.lock_wait is not None and not client.lock_wait.done():
            self._refuse(client, ErrorCode.UNIDENTIFIED, "a lock request of this session is still pending")
            return
        self.remote_local.activity()
        if header.control == 0:
            await self._catch_up(client, header.parameter)
            outcome = self.locks.release(client)
            self._changes.notify()
            self._reply(client, Message.ASYNC_LOCK_RESPONSE, outcome)
            return
        granted = self.locks.request(client, payload)
        if granted is None and header.parameter > 0:
            client.lock_wait = asyncio.create_task(self._wait_for_lock(client, payload, header.parameter / 1000))
            return
        self._reply(client, Message.ASYNC_LOCK_RESPONSE, LockResponse.FAILURE if granted is None else granted)

    async def _wait_for_lock(self, client: _Client, key: bytes, timeout_s: float) -> None:
        outcome = LockResponse.FAILURE
        try:
            async with asyncio.timeout(timeout_s):
                while (granted := self.locks.request(client, key)) is None:
                    await self._changes.wait()
                outcome = granted
        except TimeoutError:
            pass
        self._reply(client, Message.ASYNC_LOCK_RESPONSE, outcome)


class HislipOverTcp(Transport):
    """A LAN SCPI instrument's HiSLIP server (IVI-6.1): what pyvisa opens for
    ``TCPIP::host::hislip0,port::INSTR``.  One :class:`HislipServer` per instrument holds
    its sessions and locks; the device is the one its raw socket serves."""

    name = "hislip"
    #: the raw socket's faults, through the same gate (module doc)
    wire_fault_kinds = ScpiOverTcp.wire_fault_kinds
    interface_in_instrument = True

    def resource(self, host: str, port: int) -> str:
        return f"TCPIP::{host}::hislip0::INSTR" if port == 4880 else f"TCPIP::{host}::hislip0,{port}::INSTR"

    async def listen(self, device: ScpiDevice, host: str, port: int,
                     gate: Callable[[], ConnectionGate | None]) -> tuple[Listener, int]:
        server = HislipServer(device, gate)
        listener = await asyncio.start_server(server.connection, host, port)
        return listener, int(listener.sockets[0].getsockname()[1])


#: the HiSLIP wire of the simulated station's SCPI instruments
HISLIP = HislipOverTcp()
