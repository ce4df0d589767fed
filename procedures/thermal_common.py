"""What the thermal steps share: the unit's own thermometer, a soak on it, and the static
measurements a thermal test repeats (an accelerometer's up/down bias and scale factor, a
gyro's static record).

A **soak** sets the chamber's set point (ramped at the chamber's rate) and polls, every
``poll_s`` of the bench clock, the controller (``check``: a tripped limit or an active alarm
raises ``ChamberFaultError``) and the unit's own temperature sensor; every poll is streamed
to ``thermal_soak`` as it is read.  The unit is soaked when
:func:`bench.analysis.thermal._soak.soak_status` says its sensor is stable (the analysis's
criterion: trailing-window rate and spread, and within a tolerance of the set point so a unit
still at the previous temperature never passes); the soak time — from the set point's command
to the first stable window — is recorded with the point.

The unit's thermometer belongs to the unit's kind: the accelerometer's AD590 read by
``dmm_temp`` (1 µA/K through ``temp_resistor_ohm``), the gyro's sensor in its frames.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from bench.analysis.thermal import SoakCriterion, SoakStatus, soak_status
from bench.core.step import Context
from instruments.fog_types import GyroFrames
from procedures.common import averaged_voltage, move_table, read_gyro_frames
from procedures.typed_instruments import chamber, frame_gyro, multimeter

KELVIN_C = 273.15
AD590_A_PER_K = 1e-6


class UnitThermometer(Protocol):
    """The unit's own temperature sensor, read once (°C)."""

    def read_c(self, ctx: Context) -> float: ...


class AccelerometerThermometer:
    """The accelerometer's AD590 current across ``temp_resistor_ohm``, read by ``dmm_temp``
    (one reading at 1 NPLC per call)."""

    def __init__(self) -> None:
        self.configured = False

    def read_c(self, ctx: Context) -> float:
        meter = multimeter(ctx, "dmm_temp")
        if not self.configured:
            meter.configure_dc_voltage(range_v=10.0, nplc=1.0)
            self.configured = True
        volts = meter.measure_dc_voltage()
        if not math.isfinite(volts):
            raise RuntimeError(f"dmm_temp overload reading the unit's temperature sensor ({volts!r} V)")
        return volts / float(ctx.wiring["temp_resistor_ohm"]) / AD590_A_PER_K - KELVIN_C


class GyroThermometer:
    """The gyro's own sensor: the mean temperature of ``frames`` frames at ``rate_hz``
    (the stream started, read and stopped on each call; the gyro must be powered)."""

    def __init__(self, rate_hz: int = 100, frames: int = 10) -> None:
        self.rate_hz, self.frames = rate_hz, frames

    def read_c(self, ctx: Context) -> float:
        gyro = frame_gyro(ctx)
        if gyro.rate_hz != self.rate_hz:
            gyro.configure(rate_hz=self.rate_hz)
        gyro.start()
        got: list[GyroFrames] = []
        frames = read_gyro_frames(ctx, self.frames, got.append, stop=True)
        return float(np.mean(frames.temperature_c))


@dataclass(frozen=True)
class SoakRecord:
    """A finished soak: the set point, when it was commanded, the soak time on the unit's
    sensor and the criterion's last status."""

    set_point_c: float
    start_s: float
    soak_time_s: float
    status: SoakStatus


def soak(ctx: Context, thermometer: UnitThermometer, set_point_c: float, criterion: SoakCriterion, *,
         poll_s: float, timeout_s: float, label: str) -> SoakRecord:
    """Command ``set_point_c`` and wait until the unit's own sensor is stable (module docstring).
    Streams every poll to ``thermal_soak``; ``TimeoutError`` after ``timeout_s``."""
    ch = chamber(ctx)
    if "thermal_soak" not in ctx.run.store.streams(ctx.run.id):
        ctx.run.add_stream("thermal_soak", {"t_s": "s", "set_point_c": "degC", "air_c": "degC",
                                            "unit_c": "degC"},
                           "chamber air and the unit's own sensor while soaking, every poll")
    ch.set_set_point(set_point_c)
    if not ch.running:
        ch.run()
    start = ctx.clock.now()
    ctx.run.event(start, "set_point", f"{label}: chamber to {set_point_c:g} °C", set_point_c=set_point_c)
    times: list[float] = []
    temps: list[float] = []
    while True:
        air = ch.check().process_value_c
        unit_c = thermometer.read_c(ctx)
        t = ctx.clock.now()
        ctx.run.append("thermal_soak", t_s=[t], set_point_c=[set_point_c], air_c=[air], unit_c=[unit_c])
        if times and t <= times[-1]:  # a reading taken at the same instant adds nothing
            t = times[-1] + 1e-6
        times.append(t)
        temps.append(unit_c)
        status = soak_status(times, temps, criterion, start_s=start)
        if status.stable:
            record = SoakRecord(set_point_c, start, t - start, status)
            ctx.run.event(t, "soaked", f"{label}: unit stable at {status.mean_c:.2f} °C after "
                          f"{t - start:.0f} s", soak_time_s=t - start, unit_c=status.mean_c)
            return record
        if t - start >= timeout_s:
            raise TimeoutError(f"{label}: the unit's sensor not stable {timeout_s:g} s after the set point "
                               f"{set_point_c:g} °C ({status.reason}; unit {unit_c:.2f} °C, air {air:.2f} °C)")
        ctx.clock.sleep(poll_s)


def criterion_for(set_point_c: float, window_s: float, rate_c_per_min: float, band_c: float,
                  target_tolerance_c: float) -> SoakCriterion:
    """The soak criterion at one set point: stable, and within ``target_tolerance_c`` of it."""
    return SoakCriterion(window_s=window_s, max_rate_c_per_min=rate_c_per_min, band_c=band_c, min_samples=3,
                         target_c=set_point_c, target_tolerance_c=target_tolerance_c)


@dataclass(frozen=True)
class UpDown:
    """An accelerometer at IA up and IA down: bias (g, K2·g² included: constant for a unit)
    and scale factor (mA/g), each with its standard uncertainty, and the currents (mA)."""

    bias_g: float
    bias_std_g: float
    k1_ma_per_g: float
    k1_std_ma_per_g: float
    up_ma: float
    down_ma: float


def up_down(ctx: Context, *, settle_s: float, average_s: float, nplc: float, stream: str | None = None,
            tag: int = 0) -> UpDown:
    """IA up (0°, 0°) then IA down (0°, 180°): I± = K1·(K0 ± 1 + K2), so K0 + K2 = (I₊ + I₋)/(I₊ − I₋)
    and K1 = (I₊ − I₋)/2 — free of the scale factor's own drift."""
    ohm = float(ctx.wiring["sampling_resistor_ohm"])
    currents, errors = [], []
    for k, outer in enumerate((0.0, 180.0)):
        move_table(ctx, 0.0, outer)
        ctx.clock.sleep(settle_s)
        mean, se, _ = averaged_voltage(ctx, average_s, nplc, stream=stream, tag=2 * tag + k)
        currents.append(mean / ohm * 1e3)
        errors.append(se / ohm * 1e3)
    (iu, idn), (su, sd) = currents, errors
    diff = iu - idn
    if not diff > 0:
        raise RuntimeError(f"IA up reads {iu:.6g} mA, IA down {idn:.6g} mA: no 2 g difference "
                           "(unit unpowered or mounted upside down?)")
    bias = (iu + idn) / diff
    # ∂b/∂I₊ = −2I₋/d², ∂b/∂I₋ = 2I₊/d²
    bias_std = 2.0 * math.hypot(idn * su, iu * sd) / diff**2
    return UpDown(bias, bias_std, diff / 2.0, math.hypot(su, sd) / 2.0, iu, idn)


__all__ = ["UnitThermometer", "AccelerometerThermometer", "GyroThermometer", "SoakRecord", "soak",
           "criterion_for", "UpDown", "up_down"]
