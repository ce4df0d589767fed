"""What every procedure does the same way: power the unit, level or move the table, average
a meter, and leave the station safe.

The unit under test is powered through the station's wiring (``ctx.wiring``): the
accelerometer from two rails (positive and negative channel), the gyro from one channel.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from bench.core.procedure import each_safely
from bench.core.step import Context
from instruments.fog_types import GyroFrames
from instruments.protocols import SafeInstrument
from procedures.typed_instruments import frame_gyro, multimeter, power_supply, turntable

#: fastest integration that fits a reading interval, per mains frequency (NPLC values)
NPLC_CHOICES = (100.0, 10.0, 1.0, 0.2, 0.06, 0.02)
MOVE_TIMEOUT_S = 300.0


def check_ranges(values: dict[str, Any], ranges: dict[str, tuple[float, float]],
                 integers: tuple[str, ...] = ()) -> None:
    """ValueError naming the first parameter outside its inclusive range."""
    for name, (lo, hi) in ranges.items():
        value = values[name]
        if value is None:  # optional parameter left to the station (e.g. its site)
            continue
        ok = (not isinstance(value, bool) and isinstance(value, (int, float))
              and math.isfinite(value) and lo <= value <= hi)
        if ok and name in integers and value != int(value):
            ok = False
        if not ok:
            kind = "a whole number" if name in integers else "a number"
            raise ValueError(f"{name} = {value!r} must be {kind} in {lo:g}..{hi:g}")


def choose_nplc(interval_s: float, line_hz: float, autozero: bool = True) -> float:
    """Largest NPLC whose reading (×2 with autozero) fits in ``interval_s`` with 10 % spare."""
    for nplc in NPLC_CHOICES:
        reading_s = (2 if autozero else 1) * nplc / line_hz
        if reading_s <= 0.9 * interval_s:
            return nplc
    raise ValueError(f"reading interval {interval_s} s is too short for 0.02 NPLC at {line_hz} Hz")


def accelerometer_rails(ctx: Context) -> list[int]:
    w = ctx.wiring
    return [int(w["positive_rail_channel"]), int(w["negative_rail_channel"])]


def power_accelerometer(ctx: Context, on: bool) -> None:
    """Both rails to ``rail_voltage_v`` (current-limited) and on, or both off."""
    w, supply = ctx.wiring, power_supply(ctx)
    rails = accelerometer_rails(ctx)
    if on:
        for ch in rails:
            supply.ch[ch].apply(float(w["rail_voltage_v"]), float(w["rail_current_limit_a"]))
    supply.set_outputs(rails, on)
    ctx.run.event(ctx.clock.now(), "supply_on" if on else "supply_off",
                  f"accelerometer rails ±{w['rail_voltage_v']} V")


def power_gyro(ctx: Context, on: bool) -> None:
    """The gyro's supply channel to ``gyro_supply_voltage_v`` (current-limited) and on, or off."""
    w, supply = ctx.wiring, power_supply(ctx)
    ch = int(w["gyro_supply_channel"])
    if on:
        supply.ch[ch].apply(float(w["gyro_supply_voltage_v"]), float(w["gyro_current_limit_a"]))
    supply.set_outputs([ch], on)
    ctx.run.event(ctx.clock.now(), "gyro_supply_on" if on else "gyro_supply_off",
                  f"gyro supply CH{ch} {w['gyro_supply_voltage_v']} V")


def move_table(ctx: Context, inner_deg: float, outer_deg: float) -> None:
    """Both axes to a position, waiting until each is in position (bench clock)."""
    table = turntable(ctx)
    table.axis[1].move_to(inner_deg)
    table.axis[2].move_to(outer_deg)
    for axis in (1, 2):
        table.axis[axis].wait_in_position(ctx.clock.sleep, timeout_s=MOVE_TIMEOUT_S)


def level_table(ctx: Context) -> None:
    """The turntable level, both axes at 0° (platform z up: an input axis along z senses +1 g)."""
    turntable(ctx).interlock_close()
    move_table(ctx, 0.0, 0.0)
    ctx.run.event(ctx.clock.now(), "levelled", "turntable at 0°, 0°: platform z up")


def averaged_voltage(ctx: Context, average_s: float, nplc: float, *, stream: str | None = None,
                     tag: int = 0) -> tuple[float, float, int]:
    """Mean DC voltage of the ``dmm`` over ``average_s``: (mean V, standard error V, n).

    A timed trace of readings at the given NPLC (autozero off, one reading per interval);
    the standard error treats the readings as independent. With ``stream`` every reading is
    stored first (``position`` = ``tag``), so an overload still leaves the readings behind.
    """
    dmm = multimeter(ctx)
    interval = nplc / dmm.line_frequency_hz + 0.002
    n = max(2, int(average_s / interval))
    plan = dmm.configure_timed_trace(n, interval, nplc=nplc, range_v=10.0)
    dmm.initiate()
    ctx.clock.sleep(plan.duration_s)
    volts = dmm.fetch_all()
    if stream is not None:
        ctx.run.append(stream, position=np.full(volts.size, tag), voltage_v=volts)
    if not np.all(np.isfinite(volts)):
        raise RuntimeError(f"dmm overload: {int(np.sum(~np.isfinite(volts)))} of {volts.size} "
                           "readings out of range while averaging")
    return float(volts.mean()), float(volts.std(ddof=1) / math.sqrt(volts.size)), volts.size


FRAME_TIMEOUT_MARGIN_S = 60.0  # wall time allowed beyond a record's own length


def read_gyro_frames(ctx: Context, n: int, store: Callable[[GyroFrames], None], *,
                     stop: bool = False) -> GyroFrames:
    """The next ``n`` frames from the streaming ``gyro``; ``store(frames)`` is called first —
    also with the partial frames of a timeout — so nothing acquired is lost, then a line with
    dropped or corrupt frames raises (a whole-record mean or an Allan deviation needs every
    frame). ``stop``: stop the stream after reading."""
    gyro = frame_gyro(ctx)
    timeout_s = n / gyro.rate_hz + FRAME_TIMEOUT_MARGIN_S  # a real unit needs the record's time
    try:
        frames = gyro.read_frames(n, timeout_s=timeout_s, wait=ctx.clock.sleep)
    except Exception as exc:
        partial = getattr(exc, "frames", None)  # a GyroTimeout carries what did arrive
        if partial is not None and len(partial):
            store(partial)
        raise
    store(frames)
    if stop:
        gyro.stop()
    if frames.dropped or frames.corrupt:
        raise RuntimeError(f"gyro line: {frames.dropped} frames dropped, {frames.corrupt} corrupt "
                           f"in a {n}-frame record (stored); the analysis needs every frame")
    return frames


def make_safe(ctx: Context) -> None:
    """Teardown for every procedure: each instrument of the station brought to rest by its own
    ``make_safe()`` (supply off, meters aborted, streams, tables and shakers stopped), in
    ``safe_order`` (``instruments.protocols.SafeOrder``): power sources first — the supply going
    off is what silences the station's gyro — then acquisitions, then motion; ties in station
    order.  Tries every instrument even when one fails, then raises one error naming all
    failures (``<instrument> <action>: <error>``).
    """
    instruments: Mapping[str, SafeInstrument] = ctx.instruments
    ordered = sorted(instruments.items(), key=lambda item: item[1].safe_order)
    each_safely([(f"{name} {inst.safe_action}", inst.make_safe) for name, inst in ordered])


__all__ = ["check_ranges", "choose_nplc", "accelerometer_rails", "power_accelerometer",
           "power_gyro", "move_table", "level_table", "averaged_voltage", "read_gyro_frames",
           "make_safe", "FRAME_TIMEOUT_MARGIN_S", "MOVE_TIMEOUT_S", "NPLC_CHOICES"]
