"""Reading a batch fixture's sockets through the scanning DAQ.

Socket ``n`` is wired to scanner channel ``fixture_first_channel + n − 1`` (the station's
``[wiring]``, 101 by default).  A scan takes every socket still in the batch, in one sweep per
interval; the readings are handed out per socket as they are drained.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping

import numpy as np

from bench.core.step import Context
from instruments.protocols import ScanningMultimeter
from procedures.common import NPLC_CHOICES
from procedures.typed_instruments import scanner

#: ``on_readings(socket, t_since_init_s, volts)`` for each drained chunk
OnReadings = Callable[[int, np.ndarray, np.ndarray], None]


def socket_channel(ctx: Context, socket: int) -> int:
    """The scanner channel a socket's unit is wired to."""
    return int(ctx.wiring.get("fixture_first_channel", 101)) + socket - 1


def scan_timing(daq: ScanningMultimeter, n_channels: int, interval_s: float, line_hz: float,
                *, autozero: bool, nplc: float | None = None) -> tuple[float, float]:
    """``(interval_s, nplc)`` for a scan of ``n_channels``: the given ``nplc`` (or the longest
    integration whose sweep fits 90 % of ``interval_s``); the interval stretched to the sweep
    when the sweep does not fit (the caller records the rate it got)."""
    choices = (nplc,) if nplc is not None else NPLC_CHOICES
    for candidate in choices:
        sweep = daq.channel_time_s(candidate, line_hz, None, autozero) * n_channels
        if sweep <= 0.9 * interval_s:
            return interval_s, candidate
    chosen = choices[-1]
    sweep = daq.channel_time_s(chosen, line_hz, None, autozero) * n_channels
    return math.ceil(sweep * 1000) / 1000, chosen


def drain(shared: Context, daq: ScanningMultimeter, channels: Mapping[int, int], expected: int,
          on_readings: OnReadings, *, poll_s: float, message: str = "",
          progress: Callable[[int], None] | None = None) -> None:
    """Read the running scan every ``poll_s`` until ``expected`` readings are in, handing each
    socket its own (``channels``: socket → channel); ``TimeoutError`` when none arrive for
    three polls and a minute."""
    got, quiet_s = 0, 0.0
    while got < expected:
        shared.clock.sleep(poll_s)
        chunk = daq.read_available()
        if not len(chunk):
            quiet_s += poll_s
            if quiet_s > 3 * poll_s + 60.0:
                raise TimeoutError(f"scanner: no readings for {quiet_s:g} s ({got}/{expected} "
                                   f"received{', ' + message if message else ''})")
            continue
        quiet_s = 0.0
        got += len(chunk)
        for socket, channel in channels.items():
            t, v = chunk.of(channel)
            if t.size:
                on_readings(socket, t, v)
        if progress is not None:
            progress(got)


def scan_means(shared: Context, units: Mapping[int, Context], *, sweeps: int, nplc: float,
               autozero: bool, line_hz: float) -> dict[int, np.ndarray]:
    """``sweeps`` back-to-back sweeps of every socket in ``units``: each socket's readings (V)."""
    daq = scanner(shared)
    channels = {n: socket_channel(shared, n) for n in units}
    interval, _ = scan_timing(daq, len(channels), 1e-3, line_hz, autozero=autozero, nplc=nplc)
    daq.configure_scan(sorted(channels.values()), interval_s=interval, sweeps=sweeps, nplc=nplc,
                       line_hz=line_hz, autozero=autozero)
    parts: dict[int, list[np.ndarray]] = {n: [] for n in units}
    daq.initiate()
    drain(shared, daq, channels, sweeps * len(channels),
          lambda n, t, v: parts[n].append(v), poll_s=interval * sweeps + 0.01)
    return {n: np.concatenate(p) if p else np.empty(0) for n, p in parts.items()}


__all__ = ["socket_channel", "scan_timing", "drain", "scan_means", "OnReadings"]
