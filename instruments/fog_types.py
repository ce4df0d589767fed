"""What the FOG serial driver returns and raises: configuration, decoded frames, line
counters and the line's errors (docs/FOG_SERIAL.md)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


class GyroCommandError(RuntimeError):
    """The gyro answered ``$ERR,<code>,<text>`` to a command."""

    def __init__(self, name: str, command: str, code: int, message: str) -> None:
        self.name, self.command, self.code, self.message = name, command, code, message
        super().__init__(f"{name}: $ERR {code} {message!r} after {command!r}")


class GyroTimeoutError(TimeoutError):
    """No (complete) answer in time; ``frames`` holds what arrived before the timeout."""

    def __init__(self, message: str, frames: GyroFrames | None = None) -> None:
        super().__init__(message)
        self.frames = frames


class GyroLineError(ConnectionError):
    """The serial line broke (port closed, serial server gone) during ``command``;
    ``frames`` holds what arrived before.  The port is reopened before the next command."""

    def __init__(self, name: str, command: str, cause: BaseException,
                 frames: GyroFrames | None = None) -> None:
        self.name, self.command, self.frames = name, command, frames
        text = " ".join(str(cause).split()) or type(cause).__name__
        super().__init__(f"{name}: line lost at {command!r} ({type(cause).__name__}: {text[:120]})")


def line_broken(exc: BaseException) -> bool:
    """A port failure (pyserial's SerialException is an OSError), not a timeout."""
    return isinstance(exc, OSError) and not isinstance(exc, TimeoutError)


@dataclass(frozen=True)
class GyroConfig:
    """The ``$CFG?`` reply."""

    rate_hz: int
    baud: int
    frame_bytes: int
    scale_factor_pulses_per_arcsec: float
    full_scale_dps: float
    state: str


@dataclass(frozen=True)
class GyroFrames:
    """A block of decoded frames (arrays of equal length) and the line's troubles in it.

    ``index`` is the frame number since ``$START`` (the sequence unwrapped): the frame
    covers (index/rate_hz, (index+1)/rate_hz] s after the start and ``t_s`` is the end of
    that interval.  ``counts`` are pulses, ``rate_dps`` their mean rate over the interval.
    ``dropped`` counts frames missing from the sequence (lost in the unit, on the line or to
    corruption), ``corrupt`` frames whose CRC
    failed, ``resync_bytes`` bytes skipped outside valid frames, ``out_of_order`` valid
    frames discarded because their sequence did not advance.
    """

    sequence: np.ndarray
    index: np.ndarray
    counts: np.ndarray
    rate_dps: np.ndarray
    temperature_c: np.ndarray
    status: np.ndarray
    rate_hz: int
    dropped: int = 0
    corrupt: int = 0
    resync_bytes: int = 0
    out_of_order: int = 0

    def __len__(self) -> int:
        return int(self.counts.size)

    @property
    def t_s(self) -> np.ndarray:
        return (self.index + 1) / self.rate_hz

    @staticmethod
    def concat(blocks: Sequence[GyroFrames], rate_hz: int) -> GyroFrames:
        arrays = {f: np.concatenate([getattr(b, f) for b in blocks]) if blocks else np.zeros(0)
                  for f in ("sequence", "index", "counts", "rate_dps", "temperature_c", "status")}
        if not blocks:
            arrays.update(sequence=arrays["sequence"].astype(np.uint32),
                          index=arrays["index"].astype(np.int64),
                          counts=arrays["counts"].astype(np.int64),
                          status=arrays["status"].astype(np.uint16))
        return GyroFrames(arrays["sequence"], arrays["index"], arrays["counts"], arrays["rate_dps"],
                          arrays["temperature_c"], arrays["status"], rate_hz,
                          dropped=sum(b.dropped for b in blocks), corrupt=sum(b.corrupt for b in blocks),
                          resync_bytes=sum(b.resync_bytes for b in blocks),
                          out_of_order=sum(b.out_of_order for b in blocks))


@dataclass
class LineCounters:
    """Totals since the driver was created."""

    frames: int = 0
    dropped: int = 0
    corrupt: int = 0
    resync_bytes: int = 0
    out_of_order: int = 0
