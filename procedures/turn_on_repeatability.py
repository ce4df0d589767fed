"""Turn-on to turn-on bias repeatability, IEEE 1293 (``turn_on_repeatability``, accelerometer)
and IEEE 952 (``gyro_turn_on_repeatability``, gyro), in the chamber at one temperature.

1. The chamber to ``temperature_c``; the unit powered and soaked there on its own sensor.
2. ``cycles`` power cycles, spread over ``days`` days: each cycle the unit off for ``off_s``
   (``day_gap_s`` between the last cycle of a day and the first of the next — days apart on
   the bench clock), on, ``warmup_s``, then its bias measured with its own standard
   uncertainty — the accelerometer's from IA up and IA down (free of its scale factor), the
   gyro's from a static record at rest, IA up. Each cycle is streamed (``turn_on_cycles``) as
   it ends.
3. :func:`bench.analysis.turn_on._repeatability.turn_on_repeatability`: the repeatability with
   the within-run noise removed (and, over several days, day-to-day apart from within-day),
   kept under ``<step>.analysis``.
"""

from __future__ import annotations

from abc import abstractmethod
from dataclasses import asdict, dataclass
from typing import Generic, TypeVar

import numpy as np

from bench.analysis.turn_on import turn_on_repeatability
from bench.core.site import earth_rate_vertical_dph
from bench.core.step import Context, Step, parameter
from bench.values import Estimate
from instruments.fog_types import GyroFrames
from procedures.common import check_ranges, level_table, power_accelerometer, power_gyro, read_gyro_frames
from procedures.thermal_common import (
    AccelerometerThermometer,
    GyroThermometer,
    UnitThermometer,
    criterion_for,
    soak,
    up_down,
)
from procedures.thermal_sweep import revolution_standard_error
from procedures.typed_instruments import chamber, frame_gyro


@dataclass
class RepeatabilityParameters:
    temperature_c: float = parameter(23.0, "chamber set point for the cycles, °C")
    cycles: int = parameter(6, "power cycles (turn-ons)")
    days: int = parameter(1, "days the cycles are spread over (≥ 2: day-to-day apart from within-day)")
    off_s: float = parameter(1800.0, "unpowered between cycles of a day (cool-down), s")
    day_gap_s: float = parameter(86400.0, "unpowered between the last cycle of a day and the next day's first, s")
    warmup_s: float = parameter(600.0, "powered before the bias is measured, s")
    soak_window_s: float = parameter(900.0, "initial soak: trailing window of the unit's sensor, s")
    soak_tolerance_c: float = parameter(10.0, "initial soak: the unit's sensor within this of the set point, °C")

    def validate(self) -> None:
        check_ranges(asdict(self), {
            "temperature_c": (-70, 150), "cycles": (2, 1000), "days": (1, 365), "off_s": (0, 7 * 86400),
            "day_gap_s": (0, 30 * 86400), "warmup_s": (0, 86400), "soak_window_s": (60, 86400),
            "soak_tolerance_c": (0.1, 50)}, integers=("cycles", "days"))
        if self.days > 1 and self.cycles < self.days + 1:
            raise ValueError(f"cycles = {self.cycles} must exceed days = {self.days} (a day needs two cycles "
                             "to tell within-day from day-to-day)")

    def day_of(self, cycle: int) -> int:
        """The day (0, 1, …) of cycle ``cycle``: cycles shared out as evenly as they go."""
        return cycle * self.days // self.cycles


P = TypeVar("P", bound=RepeatabilityParameters)
SOAK_ESTIMATE_S = 3000.0


class RepeatabilityBase(Step[P], Generic[P]):
    """The cycles (module docstring); a kind supplies its power switch, thermometer and bias."""

    def duration_s(self) -> float:
        p = self.p
        per_cycle = p.warmup_s + self.bias_duration_s()
        return SOAK_ESTIMATE_S + p.cycles * (p.off_s + per_cycle) + (p.days - 1) * max(p.day_gap_s - p.off_s, 0.0)

    def producible(self) -> set[str]:
        out = {"turn_on_repeatability", "turn_on_raw_sd"}
        if self.p.days > 1:
            out |= {"day_to_day", "within_day"}
        return out

    @abstractmethod
    def power(self, ctx: Context, on: bool) -> None: ...

    @abstractmethod
    def thermometer(self) -> UnitThermometer: ...

    @abstractmethod
    def bias_duration_s(self) -> float: ...

    @abstractmethod
    def measure_bias(self, ctx: Context, cycle: int) -> tuple[float, float]:
        """The unit's bias now and its within-run standard uncertainty, streamed first."""

    def run(self, ctx: Context) -> dict[str, Estimate]:
        p = self.p
        level_table(ctx)
        self.power(ctx, True)
        crit = criterion_for(p.temperature_c, p.soak_window_s, 0.02, 0.3, p.soak_tolerance_c)
        ch = chamber(ctx)
        ctx.progress(0, self.duration_s(), f"soaking at {p.temperature_c:g} °C")
        thermometer = self.thermometer()
        soak(ctx, thermometer, p.temperature_c, crit, poll_s=60.0, timeout_s=4 * 3600.0, label="turn-on cycles")
        ctx.run.add_stream("turn_on_cycles", {"cycle": "1", "day": "1", "t_on_s": "s", "bias": "1",
                                              "bias_std": "1", "unit_c": "degC", "air_c": "degC"},
                           f"each turn-on's bias (unit: {self.bias_unit}) and its within-run uncertainty")
        biases, stds, days = np.empty(p.cycles), np.empty(p.cycles), []
        done = SOAK_ESTIMATE_S
        for k in range(p.cycles):
            day = p.day_of(k)
            off = p.day_gap_s if k and day != p.day_of(k - 1) else p.off_s
            self.power(ctx, False)
            ctx.progress(done, self.duration_s(), f"cycle {k + 1}/{p.cycles}: off {off:g} s (day {day + 1})")
            ctx.clock.sleep(off)
            ch.check()
            self.power(ctx, True)
            t_on = ctx.clock.now()
            ctx.run.event(t_on, "turn_on", f"cycle {k + 1} of {p.cycles}, day {day + 1}")
            ctx.clock.sleep(p.warmup_s)
            biases[k], stds[k] = self.measure_bias(ctx, k)
            unit_c, air = thermometer.read_c(ctx), ch.check().process_value_c
            ctx.run.append("turn_on_cycles", cycle=[k], day=[day], t_on_s=[t_on], bias=[biases[k]],
                           bias_std=[stds[k]], unit_c=[unit_c], air_c=[air])
            days.append(day)
            done += off + p.warmup_s + self.bias_duration_s()
        r = turn_on_repeatability(biases, stds, day=days if p.days > 1 else None)
        ctx.run.set_result(f"{self.name}.analysis", {**r.to_dict(), "unit": self.bias_unit})
        rep = r.repeatability
        out = {"turn_on_repeatability": Estimate(rep.sd, (rep.high - rep.low) / (2 * 1.96)),
               "turn_on_raw_sd": Estimate(r.raw_sd.sd, (r.raw_sd.high - r.raw_sd.low) / (2 * 1.96))}
        if r.days is not None:
            for name, comp in (("day_to_day", r.days.day_to_day), ("within_day", r.days.within_day)):
                out[name] = Estimate(comp.sd, (comp.high - comp.low) / (2 * 1.96))
        return out

    bias_unit: str = ""


def _produces(unit: str) -> dict[str, tuple[str, str]]:
    return {
        "turn_on_repeatability": (unit, "turn-on to turn-on bias repeatability (1σ, within-run noise removed)"),
        "turn_on_raw_sd": (unit, "standard deviation of the turn-on biases (within-run noise included)"),
        "day_to_day": (unit, "day-to-day bias repeatability (1σ)"),
        "within_day": (unit, "within-day turn-on repeatability (1σ)"),
    }


@dataclass
class AccelerometerRepeatabilityParameters(RepeatabilityParameters):
    settle_s: float = parameter(5.0, "after in position, before averaging, s")
    average_s: float = parameter(30.0, "averaging time at IA up and at IA down, s")
    nplc: float = parameter(10.0, "DMM integration per reading, power-line cycles (0.02|0.06|0.2|1|10|100)")

    def validate(self) -> None:
        super().validate()
        check_ranges(asdict(self), {"settle_s": (0, 600), "average_s": (0.5, 3600), "nplc": (0.02, 100)})
        if self.nplc not in (0.02, 0.06, 0.2, 1.0, 10.0, 100.0):
            raise ValueError(f"nplc = {self.nplc} not in 0.02|0.06|0.2|1|10|100")


class TurnOnRepeatabilityTest(RepeatabilityBase[AccelerometerRepeatabilityParameters]):
    """Accelerometer turn-on to turn-on bias repeatability (IEEE 1293) over power cycles in the chamber.

    Each turn-on's bias from IA up and IA down after the warm-up; the repeatability with the
    within-run noise removed, day-to-day apart when the cycles span days.
    """

    name = "turn_on_repeatability"
    requires = ("dmm", "dmm_temp", "supply", "turntable", "chamber")
    kinds = ("accelerometer",)
    produces = _produces("g")
    Parameters = AccelerometerRepeatabilityParameters
    bias_unit = "g"

    def power(self, ctx: Context, on: bool) -> None:
        power_accelerometer(ctx, on)

    def thermometer(self) -> UnitThermometer:
        return AccelerometerThermometer()

    def bias_duration_s(self) -> float:
        return 2 * (self.p.settle_s + self.p.average_s + 3.0)

    def measure_bias(self, ctx: Context, cycle: int) -> tuple[float, float]:
        if cycle == 0:
            ctx.run.add_stream("turn_on_readings", {"position": "1", "voltage_v": "V"},
                               "every DMM reading of the turn-on biases (position = 2·cycle + 0 up / 1 down)")
        ud = up_down(ctx, settle_s=self.p.settle_s, average_s=self.p.average_s, nplc=self.p.nplc,
                     stream="turn_on_readings", tag=cycle)
        return ud.bias_g, ud.bias_std_g


@dataclass
class GyroRepeatabilityParameters(RepeatabilityParameters):
    record_s: float = parameter(300.0, "static record per turn-on, s")
    frame_rate_hz: int = parameter(100, "gyro frame rate, Hz")
    boot_wait_s: float = parameter(5.0, "powered, before the gyro is asked to stream, s")

    def validate(self) -> None:
        super().validate()
        check_ranges(asdict(self), {"record_s": (10, 86400), "frame_rate_hz": (1, 4608), "boot_wait_s": (0, 600)},
                     integers=("frame_rate_hz",))


class GyroTurnOnRepeatabilityTest(RepeatabilityBase[GyroRepeatabilityParameters]):
    """Gyro turn-on to turn-on bias repeatability (IEEE 952) over power cycles in the chamber.

    Each turn-on's bias from a static record at rest (IA up, the Earth rate's vertical part
    removed) after the warm-up; the repeatability with the within-run noise removed,
    day-to-day apart when the cycles span days.
    """

    name = "gyro_turn_on_repeatability"
    requires = ("gyro", "supply", "turntable", "chamber")
    kinds = ("gyro",)
    produces = _produces("deg/h")
    Parameters = GyroRepeatabilityParameters
    bias_unit = "deg/h"

    def power(self, ctx: Context, on: bool) -> None:
        power_gyro(ctx, on)
        if on:
            ctx.clock.sleep(self.p.boot_wait_s)

    def thermometer(self) -> UnitThermometer:
        return GyroThermometer()

    def bias_duration_s(self) -> float:
        return self.p.record_s

    def measure_bias(self, ctx: Context, cycle: int) -> tuple[float, float]:
        p = self.p
        gyro = frame_gyro(ctx)
        if cycle == 0:
            ctx.run.add_stream("turn_on_frames", {"cycle": "1", "t_s": "s", "rate_dps": "deg/s",
                                                  "temperature_c": "degC", "status": "1"},
                               "gyro frames of each turn-on's static record")
        gyro.configure(rate_hz=p.frame_rate_hz)
        t0 = ctx.clock.now()

        def store(frames: GyroFrames) -> None:
            ctx.run.append("turn_on_frames", cycle=np.full(len(frames), cycle), t_s=t0 + frames.t_s,
                           rate_dps=frames.rate_dps, temperature_c=frames.temperature_c, status=frames.status)

        gyro.start()
        frames = read_gyro_frames(ctx, int(round(p.record_s * p.frame_rate_hz)), store, stop=True)
        earth_dph = earth_rate_vertical_dph(ctx.site["latitude_deg"])
        rate_dph = frames.rate_dps * 3600.0
        # within-run σ of the mean from 10 equal blocks (a static record has no revolutions)
        return float(rate_dph.mean() - earth_dph), revolution_standard_error(rate_dph, 10.0)


__all__ = ["TurnOnRepeatabilityTest", "GyroTurnOnRepeatabilityTest", "RepeatabilityParameters",
           "AccelerometerRepeatabilityParameters", "GyroRepeatabilityParameters"]

