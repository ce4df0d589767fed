"""What a scanning DAQ's driver hands a procedure: the configured scan and its readings."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ScanPlan:
    """A configured scan: ``sweeps`` sweeps of ``channels`` every ``interval_s``."""

    channels: tuple[int, ...]
    interval_s: float
    sweeps: int
    nplc: float
    channel_time_s: float   # one channel's share of a sweep (relay, delay, reading)

    @property
    def sweep_s(self) -> float:
        return self.channel_time_s * len(self.channels)

    @property
    def duration_s(self) -> float:
        return (self.sweeps - 1) * self.interval_s + self.sweep_s


@dataclass(frozen=True)
class ScanReadings:
    """Readings in scan order: volts (NaN on overload), time since ``INIT`` (s), channel."""

    volts: np.ndarray
    t_s: np.ndarray
    channel: np.ndarray

    def __len__(self) -> int:
        return int(self.volts.size)

    def of(self, channel: int) -> tuple[np.ndarray, np.ndarray]:
        """``(t_s, volts)`` of one channel."""
        keep = self.channel == channel
        return self.t_s[keep], self.volts[keep]


__all__ = ["ScanPlan", "ScanReadings"]
