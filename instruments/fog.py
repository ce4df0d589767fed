"""Serial reader of a fibre-optic gyro's angle-increment frames (docs/FOG_SERIAL.md).

The driver talks through an open pyserial port — ``serial.serial_for_url(address,
baudrate=..., timeout=...)`` with ``socket://host:port`` (the simulator, a serial server)
or a device path such as ``/dev/ttyUSB0`` — and never knows which answers.

Configuration is ASCII while the stream is stopped; once started, the line carries only
binary frames until ``$STOP``.  Frames are decoded in bulk (:mod:`instruments.fog_decode`)
and converted to °/s with the scale factor (pulses per arc-second) and polarity:
``rate_dps = polarity · count · rate_hz / (SF · 3600)``.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import time
from collections.abc import Iterator, Sequence
from typing import Any

from .base import QUERY_RETRIES, Identity, InstrumentReplyError, in_range, in_set, int_in_range
from .fog_decode import FRAME_BYTES, Decoded, FrameDecoder
from .fog_types import (
    GyroCommandError,
    GyroConfig,
    GyroFrames,
    GyroLineError,
    GyroTimeoutError,
    LineCounters,
    line_broken,
)
from .protocols import SafeOrder, Wait

log = logging.getLogger(__name__)

BAUD_RATES = (115200, 230400, 460800, 921600)
RATE_RANGE_HZ = (1, 10000)
LINE_BITS_PER_BYTE = 10  # 8N1
STOP_ACK = b"$OK,STOP\r\n"
#: longest wait for the frames in flight after a ``wait`` (wall seconds)
SETTLE_S = 0.25
LATE_REPLY_EXCHANGES = 3  # exchanges after a query timed out during which its answer is expected
#: frames let pass per ``wait`` step (328 kB of line data): reading keeps pace with time,
#: so a long read never overruns the unit's line buffer
WAIT_STEP_FRAMES = 16384
READ_CHUNK_BYTES = 1 << 20
#: reply timeout of the snapshot's queries (a real unit answers in milliseconds)
SNAPSHOT_TIMEOUT_S = 0.5
#: line time (s, at least SILENT_FRAMES frame periods) let pass without a byte before a
#: ``wait``-paced read gives up: the unit is unpowered or hung, waiting longer only hides it
SILENT_S = 1.0
SILENT_FRAMES = 10
#: longest wait for ``$OK,STOP`` in a teardown (wall s): a powered unit answers at once
SAFE_STOP_S = 1.0


class SerialGyro:
    """A FOG on a serial line: identify, configure, start/stop, read frames in bulk.

    ``port`` is an open pyserial port; its ``timeout`` (seconds, default 2 s if None) is
    the reply timeout of commands.  ``scale_factor_pulses_per_arcsec`` (> 0) defaults to
    the unit's nominal value from ``$CFG?``; ``polarity`` (+1 or -1) flips the sign for
    a unit mounted with its input axis against the reference axis.
    """

    safe_order = SafeOrder.ACQUISITION
    safe_action = "stop"

    def __init__(self, port: Any, name: str | None = None, *,
                 scale_factor_pulses_per_arcsec: float | None = None, polarity: int = 1) -> None:
        self.port = port
        self.name = name or f"SerialGyro@{getattr(port, 'port', '?')}"
        self.reply_timeout_s = port.timeout if port.timeout else 2.0
        self._sf = (None if scale_factor_pulses_per_arcsec is None else
                    in_range("scale_factor_pulses_per_arcsec", scale_factor_pulses_per_arcsec,
                             (1e-6, 1e9)))
        self.polarity = int(in_set("polarity", polarity, (1, -1)))
        self._config: GyroConfig | None = None
        self._identity: Identity | None = None
        self._decoder = FrameDecoder()
        self.streaming = False
        self.counters = LineCounters()
        self._stale = False  # the line broke: reopen the port before the next transfer
        # reply prefix of a query that timed out -> exchanges during which its answer may still
        # arrive (a slow unit answers the first ask after the driver asked again)
        self._late: dict[str, int] = {}

    # -- ASCII commands ---------------------------------------------------------------------
    def _read_line(self, command: str) -> bytes:
        self.port.timeout = self.reply_timeout_s
        line = self.port.read_until(b"\n", 256)
        if not line.endswith(b"\n"):
            raise GyroTimeoutError(f"{self.name}: no reply to {command!r} within "
                              f"{self.reply_timeout_s:g} s (got {line[:40]!r}; unit unpowered?)")
        return line

    def _read_reply(self, command: str, expect: str) -> str:
        """The reply to ``command``; a late answer to a query that timed out (and was asked
        again) is recognised by its prefix and passed over once."""
        while True:
            reply = self._read_line(command).decode("ascii", errors="replace").strip()
            late = (None if reply.startswith(expect) else
                    next((p for p in self._late if reply.startswith(p)), None))
            if late is None:
                return reply
            del self._late[late]
            log.info("%s: passed over a late reply %r while waiting for the answer to %r",
                     self.name, reply[:40], command)

    def _command(self, command: str, expect: str, *, retry: bool = False) -> str:
        """Send one line while stopped; return the reply after ``expect`` (a prefix).

        ``retry`` (only for the read-only ``$ID?`` and ``$CFG?``): up to QUERY_RETRIES more
        attempts after a timeout, a lost line or a garbled reply."""
        if self.streaming:
            raise RuntimeError(f"{self.name}: {command!r} refused while streaming; stop() first")
        attempts = 1 + (QUERY_RETRIES if retry else 0)
        for attempt in range(1, attempts + 1):
            try:
                return self._command_once(command, expect)
            except (GyroTimeoutError, GyroLineError, InstrumentReplyError) as exc:
                if isinstance(exc, GyroTimeoutError):
                    self._late[expect] = LATE_REPLY_EXCHANGES
                if attempt == attempts:
                    raise
                log.warning("%s; asking again", exc)
        raise AssertionError("unreachable")

    def _command_once(self, command: str, expect: str) -> str:
        self._reopen_if_lost(command)
        try:
            self.port.reset_input_buffer()  # stale bytes (a stream cut by power loss) are not a reply
            log.debug("%s <- %s", self.name, command)
            self.port.write(command.encode("ascii") + b"\r\n")
            reply = self._read_reply(command, expect)
        except Exception as exc:
            if line_broken(exc):
                self._stale = True
                raise GyroLineError(self.name, command, exc) from exc
            raise
        finally:
            self._late = {k: n - 1 for k, n in self._late.items() if n > 1}
        log.debug("%s -> %s", self.name, reply)
        if reply.startswith("$ERR,"):
            _, code, message = (reply.split(",", 2) + ["", ""])[:3]
            raise GyroCommandError(self.name, command, int(code) if code.isdigit() else -1, message)
        if not reply.startswith("$"):
            raise InstrumentReplyError(f"{self.name}: {command!r} answered with binary data "
                                       f"{reply[:20]!r}: is the unit streaming (started elsewhere)?")
        if not reply.startswith(expect):
            raise InstrumentReplyError(f"{self.name}: {command!r} answered {reply!r}, "
                                       f"expected {expect!r}...")
        return reply[len(expect):]

    def _reopen_if_lost(self, command: str) -> None:
        if not self._stale:
            return
        try:
            self.port.close()
            self.port.open()
        except Exception as exc:
            raise GyroLineError(self.name, f"reopen before {command}", exc) from exc
        self._stale = False
        self._decoder.reset()  # a frame cut by the break is not continued by the new line
        log.warning("%s: line reopened", self.name)

    def identify(self, *, retry: bool = True) -> Identity:
        """``$ID?`` → manufacturer, model, serial, firmware (read once, cached)."""
        if self._identity is None:
            self._identity = Identity.parse(self._command("$ID?", "$ID,", retry=retry))
        return self._identity

    def read_config(self, *, retry: bool = True) -> GyroConfig:
        """``$CFG?``, parsed; also refreshes the cached configuration."""
        fields = dict(item.split("=", 1) for item in self._command("$CFG?", "$CFG,", retry=retry).split(",")
                      if "=" in item)
        try:
            cfg = GyroConfig(int(fields["RATE"]), int(fields["BAUD"]), int(fields["FRAME"]),
                             float(fields["SF"]), float(fields["FS"]), fields["STATE"])
        except (KeyError, ValueError) as exc:
            raise InstrumentReplyError(f"{self.name}: $CFG? reply lacks {exc}: {fields}") from None
        if cfg.frame_bytes != FRAME_BYTES:
            raise InstrumentReplyError(f"{self.name}: frames of {cfg.frame_bytes} bytes, this "
                                       f"driver reads {FRAME_BYTES}-byte frames")
        self._config = cfg
        return cfg

    @property
    def config(self) -> GyroConfig:
        return self._config if self._config is not None else self.read_config()

    @property
    def rate_hz(self) -> int:
        return self.config.rate_hz

    @property
    def scale_factor_pulses_per_arcsec(self) -> float:
        return self._sf if self._sf is not None else self.config.scale_factor_pulses_per_arcsec

    def configure(self, *, rate_hz: int | None = None, baud: int | None = None,
                  scale_factor_pulses_per_arcsec: float | None = None,
                  polarity: int | None = None) -> None:
        """Frame rate (whole Hz, 1..10000), baud rate (115200|230400|460800|921600) and the
        conversion to °/s.  Everything is validated before anything is sent; rate × 200
        must fit the baud rate (20-byte frames, 10 bits per byte)."""
        rate = None if rate_hz is None else int_in_range("rate_hz", rate_hz, RATE_RANGE_HZ)
        new_baud = None if baud is None else int(in_set("baud", baud, BAUD_RATES))
        sf = (None if scale_factor_pulses_per_arcsec is None else
              in_range("scale_factor_pulses_per_arcsec", scale_factor_pulses_per_arcsec, (1e-6, 1e9)))
        pol = None if polarity is None else int(in_set("polarity", polarity, (1, -1)))
        if rate is not None or new_baud is not None:
            current = self.config
            eff_rate = rate if rate is not None else current.rate_hz
            eff_baud = new_baud if new_baud is not None else current.baud
            per_hz = FRAME_BYTES * LINE_BITS_PER_BYTE
            if eff_rate * per_hz > eff_baud:
                raise ValueError(f"rate_hz={eff_rate} needs {eff_rate * per_hz} baud > baud "
                                 f"{eff_baud}; allowed rate_hz 1..{eff_baud // per_hz} at this baud")
            # order the two changes so the unit never sees a rate its line cannot carry
            if new_baud is not None and eff_rate * per_hz > current.baud:
                self._set_baud(new_baud)
                new_baud = None
            if rate is not None:
                self._command(f"$RATE {rate}", f"$OK,RATE,{rate}")
            if new_baud is not None:
                self._set_baud(new_baud)
            self.read_config()
        if sf is not None:
            self._sf = sf
        if pol is not None:
            self.polarity = pol

    def _set_baud(self, baud: int) -> None:
        self._command(f"$BAUD {baud}", f"$OK,BAUD,{baud}")
        self.port.baudrate = baud  # the unit switches after its reply

    # -- the stream ---------------------------------------------------------------------------
    def start(self) -> None:
        """``$START``: frames follow the reply, first sequence 0."""
        if self._config is None:  # the rate and scale factor are needed to convert frames
            self.read_config()
        self._command("$START", "$OK,START")
        self._decoder.reset()
        self._decoder.expect_start()
        self.streaming = True

    @contextlib.contextmanager
    def _port_timeout_restored(self) -> Iterator[None]:
        """Reads below change the port's timeout; the caller's port gets its own back."""
        try:
            yield
        finally:
            self.port.timeout = self.reply_timeout_s

    def stop(self) -> GyroFrames:
        """``$STOP``; returns the frames that arrived before the unit's ``$OK,STOP``.

        Not streaming (as far as this driver started it): nothing to stop, nothing is sent
        — a teardown after the supply was switched off does not wait for a silent unit.
        """
        if not self.streaming:
            return self._convert([])
        with self._port_timeout_restored():
            try:
                return self._stop_stream()
            except Exception as exc:
                if not line_broken(exc):
                    raise
                self._stale = True
                self.streaming = False
                raise GyroLineError(self.name, "$STOP", exc) from exc

    def make_safe(self) -> None:
        """Teardown: end a stream this driver started (``$STOP``); nothing to do otherwise.

        A unit that stays silent for :data:`SAFE_STOP_S` is taken as unpowered, hence at rest:
        a teardown switches the station's supply off first, and the station's gyro goes quiet
        with it.  A line that cannot be reopened still raises :class:`GyroLineError`.
        """
        if not self.streaming:
            return
        saved = self.reply_timeout_s
        self.reply_timeout_s = min(saved, SAFE_STOP_S)
        try:
            self.stop()
        except GyroTimeoutError as exc:
            log.info("%s: silent after $STOP, taken as unpowered: %s", self.name, exc)
        finally:
            self.reply_timeout_s = saved
            self.port.timeout = saved

    def _stop_stream(self) -> GyroFrames:
        # a broken line is reopened first: the unit goes on streaming through a line break
        self._reopen_if_lost("$STOP")
        self.port.write(b"$STOP\r\n")
        pending = self._decoder.take_tail()
        self.streaming = False
        deadline = time.monotonic() + self.reply_timeout_s
        while (at := pending.find(STOP_ACK)) < 0:
            left = deadline - time.monotonic()
            chunk = self._read_some(READ_CHUNK_BYTES, left) if left > 0 else b""
            if not chunk:
                frames = self._convert([self._decoder.feed(pending)])
                self._decoder.reset()
                raise GyroTimeoutError(f"{self.name}: no $OK,STOP within {self.reply_timeout_s:g} s "
                                  f"({len(frames)} frames read; unit unpowered?)", frames)
            pending += chunk
        frames = self._convert([self._decoder.feed(pending[:at])])
        self._decoder.reset()
        return frames

    def _read_some(self, max_bytes: int, timeout_s: float) -> bytes:
        """Whatever is there (up to ``max_bytes``), waiting up to ``timeout_s`` for the first byte."""
        self.port.timeout = 0
        data = self.port.read(max_bytes)
        if not data and timeout_s > 0:
            self.port.timeout = timeout_s
            data = self.port.read(1)
            if data:
                self.port.timeout = 0
                data += self.port.read(max_bytes - 1)
        return data

    def read_frames(self, n: int, timeout_s: float = 10.0, *, wait: Wait | None = None) -> GyroFrames:
        """The next ``n`` valid frames.

        Without ``wait`` the port is read until n frames arrived (real time).  With
        ``wait`` (the bench clock's sleep), the frames already received are taken first,
        then ``wait`` lets the missing frames' time pass, at most WAIT_STEP_FRAMES frame
        periods per step — on a simulated station that is what makes them exist.  ``timeout_s``
        bounds the wall time of the whole call; on expiry :class:`GyroTimeoutError` carries the frames read so far.
        """
        n = int_in_range("n", n, (1, 10**9))
        timeout_s = in_range("timeout_s", timeout_s, (0.0, 86400.0))
        if not self.streaming:
            raise RuntimeError(f"{self.name}: read_frames() before start()")
        blocks: list[Decoded] = []
        with self._port_timeout_restored():
            try:
                return self._read_frames(n, timeout_s, wait, blocks)
            except Exception as exc:
                if not line_broken(exc):
                    raise
                self._stale = True  # the unit still streams: stop() reopens and stops it
                raise GyroLineError(self.name, f"reading {n} frames", exc,
                                    self._convert(blocks)) from exc

    def _read_frames(self, n: int, timeout_s: float, wait: Wait | None,
                     blocks: list[Decoded]) -> GyroFrames:
        rate = self.rate_hz
        deadline = time.monotonic() + timeout_s
        have = 0
        first = True
        silent_s = 0.0  # line time waited since the last byte arrived
        silent_limit_s = max(SILENT_S, SILENT_FRAMES / rate)
        while have < n:
            need = (n - have) * FRAME_BYTES - self._decoder.pending_bytes
            left = deadline - time.monotonic()
            if wait is None:
                self.port.timeout = max(left, 0.0)
                data = self.port.read(min(need, READ_CHUNK_BYTES))
            elif first:  # what is already there, before letting time pass
                data = self._read_some(min(need, READ_CHUNK_BYTES), 0.0)
            else:
                step = min(n - have, WAIT_STEP_FRAMES)
                wait(step / rate)
                self.port.timeout = max(min(left, SETTLE_S), 0.0)
                data = self.port.read(min(step * FRAME_BYTES - self._decoder.pending_bytes,
                                          READ_CHUNK_BYTES))
                silent_s = 0.0 if data else silent_s + step / rate
                if silent_s >= silent_limit_s:
                    frames = self._convert(blocks)
                    raise GyroTimeoutError(f"{self.name}: no frame in {silent_s:g} s of line time "
                                      f"({have} of {n} frames; unit unpowered or hung?)", frames)
            first = False
            if data:
                block = self._decoder.feed(data)
                blocks.append(block)
                have += block.count.size
            if have < n and time.monotonic() >= deadline:
                frames = self._convert(blocks)
                raise GyroTimeoutError(f"{self.name}: {have} of {n} frames in {timeout_s:g} s "
                                  f"({frames.dropped} dropped, {frames.corrupt} corrupt)", frames)
        return self._convert(blocks)

    def _convert(self, blocks: Sequence[Decoded]) -> GyroFrames:
        rate = self.rate_hz
        per_count_dps = self.polarity * rate / (self.scale_factor_pulses_per_arcsec * 3600.0)
        converted = [GyroFrames(b.sequence, b.index, b.count, b.count * per_count_dps,
                                b.temperature_c, b.status, rate, b.dropped, b.corrupt,
                                b.resync_bytes, b.out_of_order) for b in blocks]
        frames = GyroFrames.concat(converted, rate)
        c = self.counters
        c.frames += len(frames)
        c.dropped += frames.dropped
        c.corrupt += frames.corrupt
        c.resync_bytes += frames.resync_bytes
        c.out_of_order += frames.out_of_order
        return frames

    # -- record ---------------------------------------------------------------------------------
    def snapshot(self) -> dict[str, Any]:
        """Identity, settings and line counters for the run record (no wire access while
        streaming; an unanswered query is recorded as an error, not raised)."""
        record: dict[str, Any] = {"idn": None, "settings": None}
        saved = self.reply_timeout_s
        self.reply_timeout_s = min(saved, SNAPSHOT_TIMEOUT_S)  # an unpowered unit is silent
        try:
            if not self.streaming:  # once, no retries: an unpowered unit is silent, not faulty
                self.identify(retry=False)
                self.read_config(retry=False)
            record["idn"] = dataclasses.asdict(self._identity) if self._identity else None
            record["settings"] = dataclasses.asdict(self._config) if self._config else None
        except Exception as exc:  # a snapshot must never stop a run from being recorded
            record["error"] = str(exc)
        finally:
            self.reply_timeout_s = saved
        record["conversion"] = {"scale_factor_pulses_per_arcsec": self._sf, "polarity": self.polarity}
        record["line"] = dataclasses.asdict(self.counters)
        return record

    def close(self) -> None:
        self.port.close()
