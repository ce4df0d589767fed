"""The simulated FOG's serial line: ASCII configuration and the binary frame stream.

Protocol and frame layout: docs/FOG_SERIAL.md.  The stream is a World activity:
``run_until(t)`` produces the frames whose end instants fall in (last, t] — each frame's
interval-mean input rate and specific force come from the station's ``inputs`` callable,
the gyro model turns them into pulse counts, and the frames are encoded in bulk and
written to the connected client.  Work per advance is bounded: frames that cannot be
delivered (nobody connected, or the client stopped reading and the send buffer is full)
are never computed — the gyro model accepts a gap between calls and carries its noise
processes across it exactly — so even a year-long advance costs little.

Faults (``sim.faults``): the encoded frames leave through the line's
:meth:`sim.server.SerialLink.write_frames`, where the line's fault gate may corrupt, drop or
silence them; power comes and goes through :meth:`FogSerialDevice.power_off` /
:meth:`FogSerialDevice.power_on` (the unit's supply as wired, ``supply_volts``).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from sim.devices import fog_frames as ff
from sim.server import SerialLink
from sim.world import World

log = logging.getLogger(__name__)

BAUD_RATES = (115200, 230400, 460800, 921600)
DEFAULT_BAUD = 921600
DEFAULT_RATE_HZ = 2000
RATE_RANGE_HZ = (1, 10000)
MAX_LINE_BYTES = 64
#: frames encoded per batch (bounds the temporary arrays)
MAX_BATCH = 1 << 16
#: status bits the gyro model reports (READY .. BOOTING); bit 7 is the line's own
MODEL_STATUS_MASK = 0x7F
COMMANDS = "ID? CFG? RATE BAUD START STOP"


@dataclass
class GyroInputs:
    """Interval means over each frame interval, in the gyro's sensor axes (IA first)."""

    omega_dps: np.ndarray        # (n, 3) inertial angular rate, deg/s
    f_g: np.ndarray              # (n, 3) specific force, standard g
    vibration_g_rms: float | np.ndarray = 0.0  # g rms: scalar along IA, or (n, 3) per sensor axis


#: ``inputs(t_edges_s (n+1,)) -> GyroInputs`` over the n intervals between the edges
InputsFn = Callable[[np.ndarray], GyroInputs]


class LineError(Exception):
    def __init__(self, code: int, text: str) -> None:
        super().__init__(text)
        self.code, self.text = code, text


class FogSerialDevice:
    """The FOG's RS-422 line as a :class:`sim.server.ByteStreamDevice` and World activity.

    ``gyro`` has the interface of :class:`sim.physics.gyro.FiberOpticGyro` (``pulses``
    over contiguous or gapped interval grids, vectorised ``status`` and
    ``temperature_c``); its status bits 0-6 go into the frame as they are
    (docs/FOG_SERIAL.md), LINE_OVERFLOW is added here.  ``scale_factor_pulses_per_arcsec``
    and ``full_scale_dps`` are the nominal figures ``$CFG?`` reports.  Call
    :meth:`power_changed` after every change of the gyro's supply.  ``supply_volts()`` is
    the voltage the unit's supply gives it now, as wired (the station's supply output, the
    rig's own supply): what a power fault's end powers it back up with.
    """

    fault_kinds: tuple[str, ...] = ("frame", "power")

    def __init__(self, world: World, gyro: Any, inputs: InputsFn, *, serial: str,
                 scale_factor_pulses_per_arcsec: float, full_scale_dps: float,
                 model: str = "SFOG-2K",
                 firmware: str = "1.0.0", send_buffer_bytes: int = 1 << 20,
                 clock_ppm: float = 0.0, supply_volts: Callable[[], float] = lambda: 0.0) -> None:
        for field in (serial, model, firmware):
            if not field or any(c in field for c in ",\r\n$") or not field.isascii():
                raise ValueError(f"identity field {field!r} must be ASCII without , $ or line breaks")
        if not isinstance(send_buffer_bytes, int) or send_buffer_bytes < ff.FRAME_BYTES:
            raise ValueError(f"send_buffer_bytes {send_buffer_bytes!r} must be an int ≥ {ff.FRAME_BYTES}")
        self.world, self.gyro, self.inputs = world, gyro, inputs
        self.supply_volts = supply_volts
        self.identity = ("BENCHSIM", model, serial, firmware)
        self.scale_factor = float(scale_factor_pulses_per_arcsec)
        self.full_scale_dps = float(full_scale_dps)
        self.send_buffer_bytes = send_buffer_bytes
        if not (isinstance(clock_ppm, (int, float)) and math.isfinite(clock_ppm) and abs(clock_ppm) <= 1000):
            raise ValueError(f"clock_ppm {clock_ppm!r} not in -1000..1000 ppm")
        #: the unit's frame clock runs fast by this much: frames come every 1/(rate·(1 + ppm·1e-6)) s
        self.clock_ppm = float(clock_ppm)
        self.rate_hz = DEFAULT_RATE_HZ
        self.baud = DEFAULT_BAUD
        self.state = "STOPPED" if gyro.powered(world.now) else "OFF"
        self._link: SerialLink | None = None
        self._rx = bytearray()
        self._rx_overflow = False
        self._t0 = world.now           # instant of $START
        self._k = 0                    # frames produced (sent or lost) since $START
        self._overflowed = False       # frames discarded since the last frame sent
        #: counters for tests and diagnostics
        self.frames_sent = 0
        self.frames_lost = 0
        world.add_activity(self)

    # -- the line (ByteStreamDevice) -------------------------------------------------------
    def connect(self, link: SerialLink) -> bool:
        if self._link is not None:
            return False
        self._link = link
        self._rx.clear()
        self._rx_overflow = False
        return True

    def disconnect(self, link: SerialLink) -> None:
        if link is self._link:
            self._link = None

    def receive(self, link: SerialLink, data: bytes) -> None:
        if link is not self._link or self.state == "OFF":
            return  # an unpowered unit hears nothing
        self._rx += data
        while True:
            end = self._rx.find(b"\n")
            if end < 0:
                if len(self._rx) > MAX_LINE_BYTES:  # keep the buffer bounded
                    self._rx.clear()
                    self._rx_overflow = True
                return
            line = bytes(self._rx[:end]).rstrip(b"\r")
            del self._rx[:end + 1]
            if self._rx_overflow or len(line) > MAX_LINE_BYTES:
                self._rx_overflow = False
                self._reply_error(LineError(4, f"line longer than {MAX_LINE_BYTES} bytes discarded"))
                continue
            try:
                self._command(line)
            except LineError as exc:
                self._reply_error(exc)
            except Exception as exc:  # never let a command take the server down
                log.exception("FOG command %r failed", line)
                self._reply_error(LineError(2, f"internal error {type(exc).__name__}"))

    def _send(self, text: str) -> None:
        if self._link is not None:
            # "replace": an error echoing binary junk must not fail the reply (and drop the line)
            self._link.write(text.encode("ascii", "replace") + b"\r\n")

    def _reply_error(self, exc: LineError) -> None:
        if self.state != "STREAMING":  # never interleave text with frames
            self._send(f"$ERR,{exc.code},{exc.text}")

    # -- commands ---------------------------------------------------------------------------
    def _command(self, line: bytes) -> None:
        text = line.decode("ascii", errors="replace").strip()
        if not text:
            return
        head, _, arg = text.replace(",", " ", 1).partition(" ")
        keyword, arg = head.upper(), arg.strip()
        if self.state == "STREAMING":
            if keyword == "$STOP":  # everything else is ignored while streaming
                self.state = "STOPPED"
                self._send("$OK,STOP")
            return
        if not keyword.startswith("$") or keyword[1:] not in COMMANDS.split():
            shown = text[:24]
            raise LineError(1, f"unknown command {shown!r}; allowed {COMMANDS}")
        keyword = keyword[1:]
        if keyword in ("ID?", "CFG?", "START", "STOP") and arg:
            raise LineError(2, f"{keyword} takes no argument, got {arg[:16]!r}")
        if keyword == "ID?":
            self._send("$ID," + ",".join(self.identity))
        elif keyword == "CFG?":
            self._send(f"$CFG,RATE={self.rate_hz},BAUD={self.baud},FRAME={ff.FRAME_BYTES},"
                       f"SF={self.scale_factor:.9g},FS={self.full_scale_dps:.9g},STATE={self.state}")
        elif keyword == "RATE":
            self._set_rate(self._whole(keyword, arg))
        elif keyword == "BAUD":
            self._set_baud(self._whole(keyword, arg))
        elif keyword == "START":
            self._send("$OK,START")
            self._start()
        else:  # STOP while stopped: nothing to stop
            self._send("$OK,STOP")

    @staticmethod
    def _whole(keyword: str, arg: str) -> int:
        try:
            value = float(arg)
        except ValueError:
            raise LineError(2, f"{keyword} {arg[:16]!r} is not a whole number") from None
        if not math.isfinite(value) or not value.is_integer():
            raise LineError(2, f"{keyword} {arg[:16]!r} is not a whole number")
        return int(value)

    def _set_rate(self, rate_hz: int) -> None:
        lo, hi = RATE_RANGE_HZ
        if not lo <= rate_hz <= hi:
            raise LineError(3, f"RATE {rate_hz} not in {lo}..{hi}")
        if not ff.line_rate_ok(rate_hz, self.baud):
            need = rate_hz * ff.FRAME_BYTES * ff.BITS_PER_BYTE_ON_LINE
            raise LineError(3, f"RATE {rate_hz} needs {need} baud > BAUD {self.baud}; "
                               f"allowed RATE {lo}..{min(hi, ff.max_rate_hz(self.baud))} at this baud")
        self.rate_hz = rate_hz
        self._send(f"$OK,RATE,{rate_hz}")

    def _set_baud(self, baud: int) -> None:
        if baud not in BAUD_RATES:
            raise LineError(3, f"BAUD {baud} not in {'|'.join(map(str, BAUD_RATES))}")
        if not ff.line_rate_ok(self.rate_hz, baud):
            need = self.rate_hz * ff.FRAME_BYTES * ff.BITS_PER_BYTE_ON_LINE
            fits = "|".join(str(b) for b in BAUD_RATES if b >= need)
            raise LineError(3, f"BAUD {baud} cannot carry RATE {self.rate_hz} (needs {need} baud); "
                               f"allowed BAUD {fits} at this rate")
        self.baud = baud
        self._send(f"$OK,BAUD,{baud}")  # at the old speed; the line switches after it

    def _start(self) -> None:
        self.state = "STREAMING"
        self._t0 = self.world.now
        self._k = 0
        self._overflowed = False

    # -- power ------------------------------------------------------------------------------
    def power_changed(self, t_s: float) -> None:
        """The gyro's supply changed at ``t_s`` (= world.now): boot or go silent."""
        powered = bool(self.gyro.powered(t_s))
        if not powered and self.state != "OFF":
            self.state = "OFF"  # a stream cut by power loss ends without $OK,STOP
            self._rx.clear()
        elif powered and self.state == "OFF":
            self.state = "STOPPED"
            self._rx.clear()

    # -- lifecycle (sim.devices.lifecycle) ---------------------------------------------------
    def power_off(self) -> None:
        """The unit loses power: silent, a stream cut."""
        self.gyro.set_supply(self.world.now, 0.0)
        self.power_changed(self.world.now)

    def power_on(self) -> None:
        """Power back from its supply as wired (``supply_volts()``): it boots if that is in range."""
        self.gyro.set_supply(self.world.now, self.supply_volts())
        self.power_changed(self.world.now)

    # -- the frame stream (World activity) ---------------------------------------------------
    def run_until(self, t_s: float) -> None:
        try:
            if self.state == "STREAMING":
                self._stream_until(t_s)
        except Exception as exc:  # a model failure must not wedge the world's clock
            log.exception("FOG frame stream failed")
            self.state = "STOPPED"
            self.world.note(f"gyro stream stopped: {type(exc).__name__}: {exc}")

    def _edge(self, k: np.ndarray | int) -> np.ndarray | float:
        """End instant of frame k-1 = start of frame k (the one formula for frame times)."""
        return self._t0 + k / (self.rate_hz * (1.0 + 1e-6 * self.clock_ppm))

    def _frames_due(self, t_s: float) -> int:
        """Frames since $START whose end instant is ≤ t_s."""
        m = max(0, math.floor((t_s - self._t0) * self.rate_hz * (1.0 + 1e-6 * self.clock_ppm)))
        while self._edge(m + 1) <= t_s:
            m += 1
        while m > 0 and self._edge(m) > t_s:
            m -= 1
        return m

    def _capacity_frames(self) -> int:
        if self._link is None:
            return 0
        return max(0, self.send_buffer_bytes - self._link.pending_bytes) // ff.FRAME_BYTES

    def _stream_until(self, t_s: float) -> None:
        due = self._frames_due(t_s)
        while self._k < due:
            n = min(due - self._k, MAX_BATCH)
            n_send = min(n, self._capacity_frames())
            if n_send:
                self._produce(self._k, n_send)
            if n_send < n:  # the line cannot take more in this advance: the rest is lost
                self.frames_lost += due - self._k
                self._k = due
                self._overflowed = self._link is not None
                return

    def _produce(self, k0: int, n: int) -> None:
        edges = np.asarray(self._edge(np.arange(k0, k0 + n + 1, dtype=np.float64)))
        inputs = self.inputs(edges)
        counts = self.gyro.pulses(edges, inputs.omega_dps, inputs.f_g, inputs.vibration_g_rms)
        t_end = edges[1:]
        temperature = self.gyro.temperature_c(t_end)
        status = np.asarray(self.gyro.status(t_end), dtype=np.int64) & MODEL_STATUS_MASK
        if self._overflowed:
            status[0] |= ff.LINE_OVERFLOW
            self._overflowed = False
        counts = np.clip(np.asarray(counts, dtype=np.int64), -(2**31), 2**31 - 1)
        if self._link is not None:  # produced only while a client can take them
            self._link.write_frames(ff.encode_frames(np.arange(k0, k0 + n), counts, temperature, status),
                                    ff.FRAME_BYTES)
        self._k = k0 + n
        self.frames_sent += n
