"""Thermal ramp with the unit static: ``thermal_ramp`` (accelerometer, input axis horizontal)
and ``gyro_thermal_ramp`` (gyro, at rest, input axis up) → bias curve, thermal hysteresis and
temperature-rate sensitivity.

1. The chamber to ``low_c`` and the unit soaked there on its own sensor
   (``procedures.thermal_common.soak``); the accelerometer's scale factor from IA up / IA
   down (so its output reads in g), then IA horizontal.
2. Two ramp cycles, up to ``high_c`` and back down, at ``rate_1_c_per_min`` then at
   ``rate_2_c_per_min``, with ``dwell_s`` at each end: two ramp rates are what separates the
   hysteresis from the rate sensitivity (``bench.analysis.thermal._ramp``: with one rate only
   their combination, the branch offset, is determined).
3. The output and the unit's sensor recorded all along, in chunks of ``chunk_s`` streamed as
   they arrive (``thermal_ramp``), the chamber checked between chunks (a tripped limit or an
   alarm ends the run with the record kept).
4. :func:`bench.analysis.thermal.analyze_thermal_ramp` on the record (the hysteresis's
   switching width fitted as a play operator); kept under ``<step>.analysis``.
"""

from __future__ import annotations

from abc import abstractmethod
from dataclasses import asdict, dataclass
from typing import Generic, TypeVar

import numpy as np

from bench.analysis.thermal import analyze_thermal_ramp
from bench.core.step import Context, Step, parameter
from bench.values import Estimate
from instruments.fog_types import GyroFrames
from procedures.common import (
    check_ranges,
    choose_nplc,
    level_table,
    move_table,
    power_accelerometer,
    power_gyro,
    read_gyro_frames,
)
from procedures.thermal_common import (
    AD590_A_PER_K,
    KELVIN_C,
    AccelerometerThermometer,
    GyroThermometer,
    UnitThermometer,
    criterion_for,
    soak,
    up_down,
)
from procedures.typed_instruments import chamber, frame_gyro, multimeter


@dataclass
class RampParameters:
    low_c: float = parameter(-10.0, "low end of the ramps, °C")
    high_c: float = parameter(60.0, "high end of the ramps, °C")
    rate_1_c_per_min: float = parameter(0.7, "first ramp cycle's rate, °C/min")
    rate_2_c_per_min: float = parameter(1.4, "second ramp cycle's rate, °C/min (≠ the first: it separates "
                                              "hysteresis from rate sensitivity)")
    dwell_s: float = parameter(900.0, "dwell at each end of a ramp, s")
    sample_interval_s: float = parameter(1.0, "output and sensor sample interval, s")
    chunk_s: float = parameter(600.0, "record read (and stored) per chunk, s")
    block_s: float = parameter(60.0, "analysis: averaging block, s")
    reference_c: float = parameter(25.0, "analysis: reference temperature of the bias curve, °C")
    soak_window_s: float = parameter(900.0, "initial soak: trailing window of the unit's sensor, s")
    soak_rate_c_per_min: float = parameter(0.02, "initial soak: largest |rate| of the unit's sensor, °C/min")
    soak_tolerance_c: float = parameter(10.0, "initial soak: the unit's sensor within this of low_c, °C")

    def validate(self) -> None:
        check_ranges(asdict(self), {
            "low_c": (-70, 150), "high_c": (-70, 150), "rate_1_c_per_min": (0.01, 30),
            "rate_2_c_per_min": (0.01, 30), "dwell_s": (0, 86400), "sample_interval_s": (0.05, 60),
            "chunk_s": (10, 3600), "block_s": (1, 3600), "reference_c": (-70, 150),
            "soak_window_s": (60, 86400), "soak_rate_c_per_min": (1e-4, 10), "soak_tolerance_c": (0.1, 50)})
        if not self.high_c - self.low_c >= 5.0:
            raise ValueError(f"high_c = {self.high_c} must exceed low_c = {self.low_c} by ≥ 5 °C")
        if self.chunk_s < 10 * self.sample_interval_s:
            raise ValueError(f"chunk_s = {self.chunk_s} must hold ≥ 10 samples of {self.sample_interval_s} s")

    def segments(self) -> list[tuple[float, float]]:
        """(set point, time to hold it) in order: each ramp's travel plus the dwell."""
        span = self.high_c - self.low_c
        out = []
        for rate in (self.rate_1_c_per_min, self.rate_2_c_per_min):
            for sp in (self.high_c, self.low_c):
                out.append((sp, span / rate * 60.0 + self.dwell_s))
        return out


P = TypeVar("P", bound=RampParameters)
SOAK_ESTIMATE_S = 4000.0


class ThermalRampBase(Step[P], Generic[P]):
    """The ramp (module docstring); a kind supplies its thermometer, its static set-up and its
    continuous record."""

    produces_unit: str = ""

    def duration_s(self) -> float:
        return SOAK_ESTIMATE_S + sum(hold for _, hold in self.p.segments())

    @abstractmethod
    def thermometer(self) -> UnitThermometer: ...

    @abstractmethod
    def prepare(self, ctx: Context) -> None:
        """Unit powered, static, at the start of its record (after the soak)."""

    @abstractmethod
    def start_record(self, ctx: Context) -> None: ...

    @abstractmethod
    def record_chunk(self, ctx: Context, seconds: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The next ``seconds`` of (t_s, output, unit °C), already streamed to the run."""

    def stop_record(self, ctx: Context) -> None:
        """After the last chunk."""

    def run(self, ctx: Context) -> dict[str, Estimate]:
        p = self.p
        ch = chamber(ctx)
        thermometer = self.thermometer()
        self.power(ctx)
        ch.set_ramp(max(p.rate_1_c_per_min, p.rate_2_c_per_min))
        crit = criterion_for(p.low_c, p.soak_window_s, p.soak_rate_c_per_min, 0.3, p.soak_tolerance_c)
        ctx.progress(0, self.duration_s(), f"soaking at {p.low_c:g} °C")
        soak(ctx, thermometer, p.low_c, crit, poll_s=60.0, timeout_s=4 * 3600.0, label="ramp start")
        self.prepare(ctx)
        ctx.run.add_stream("thermal_ramp_setpoints", {"t_s": "s", "set_point_c": "degC",
                                                      "rate_c_per_min": "degC/min"},
                           "the chamber's set point changes during the ramp record")
        self.start_record(ctx)
        parts: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        rates = (p.rate_1_c_per_min, p.rate_1_c_per_min, p.rate_2_c_per_min, p.rate_2_c_per_min)
        done = SOAK_ESTIMATE_S
        for (sp, hold), rate in zip(p.segments(), rates):
            ch.set_ramp(rate)
            ch.set_set_point(sp)
            ctx.run.append("thermal_ramp_setpoints", t_s=[ctx.clock.now()], set_point_c=[sp], rate_c_per_min=[rate])
            ctx.run.event(ctx.clock.now(), "ramp", f"chamber to {sp:g} °C at {rate:g} °C/min")
            left = hold
            while left > 1e-9:
                chunk = min(p.chunk_s, left)
                parts.append(self.record_chunk(ctx, chunk))
                ch.check()
                left -= chunk
                done += chunk
                ctx.progress(done, self.duration_s(), f"ramp to {sp:g} °C at {rate:g} °C/min")
        self.stop_record(ctx)
        t = np.concatenate([x[0] for x in parts])
        y = np.concatenate([x[1] for x in parts])
        temp = np.concatenate([x[2] for x in parts])
        # the hysteresis's switch over a reversal is fitted (a play operator), not left out
        r = analyze_thermal_ramp(t, y, temp, reference_c=p.reference_c, block_s=p.block_s)
        ctx.run.set_result(f"{self.name}.analysis", r.to_dict())
        out = {"branch_offset": Estimate(r.branch_offset.value, r.branch_offset.std)}
        if r.hysteresis is not None:
            out["hysteresis"] = Estimate(r.hysteresis.value, r.hysteresis.std)
        if r.rate_sensitivity is not None:
            out["rate_sensitivity"] = Estimate(r.rate_sensitivity.value, r.rate_sensitivity.std)
        for term, why in r.not_separable.items():
            ctx.run.event(ctx.clock.now(), "not_separable", f"{term}: {why}")
        return out

    @abstractmethod
    def power(self, ctx: Context) -> None: ...


# --------------------------------------------------------------------------- accelerometer


@dataclass
class AccelerometerRampParameters(RampParameters):
    nplc: float = parameter(10.0, "output readings' integration, power-line cycles (0.02|0.06|0.2|1|10|100)")

    def validate(self) -> None:
        super().validate()
        if self.nplc not in (0.02, 0.06, 0.2, 1.0, 10.0, 100.0):
            raise ValueError(f"nplc = {self.nplc} not in 0.02|0.06|0.2|1|10|100")


class ThermalRamp(ThermalRampBase[AccelerometerRampParameters]):
    """Accelerometer static over up-and-down chamber ramps: bias curve, hysteresis, rate sensitivity.

    Input axis horizontal, output in g through the scale factor measured IA up / IA down
    first; two ramp rates separate the thermal hysteresis from the gradient (rate) sensitivity.
    """

    name = "thermal_ramp"
    requires = ("dmm", "dmm_temp", "supply", "turntable", "chamber")
    kinds = ("accelerometer",)
    produces = {
        "hysteresis": ("g", "thermal hysteresis: up- minus down-ramp bias at equal temperature, zero rate"),
        "rate_sensitivity": ("g/(degC/min)", "bias per °C/min of the unit's temperature rate"),
        "branch_offset": ("g", "up- minus down-ramp bias at equal temperature at the record's rates"),
    }
    Parameters = AccelerometerRampParameters

    def thermometer(self) -> UnitThermometer:
        return AccelerometerThermometer()

    def power(self, ctx: Context) -> None:
        level_table(ctx)
        power_accelerometer(ctx, on=True)

    def prepare(self, ctx: Context) -> None:
        ud = up_down(ctx, settle_s=5.0, average_s=20.0, nplc=10.0)
        self.ma_per_g = ud.k1_ma_per_g
        ctx.run.set_result(f"{self.name}.scale_factor", {"k1_ma_per_g": ud.k1_ma_per_g,
                                                         "k1_std_ma_per_g": ud.k1_std_ma_per_g})
        move_table(ctx, 0.0, 90.0)  # input axis horizontal: the output is the bias
        ctx.run.add_stream("thermal_ramp", {"t_s": "s", "voltage_v": "V", "output_g": "g", "unit_c": "degC"},
                           "static output (IA horizontal) and the unit's sensor over the ramps")

    def start_record(self, ctx: Context) -> None:
        dmm, temp = multimeter(ctx), multimeter(ctx, "dmm_temp")
        self.nplc_temp = choose_nplc(self.p.sample_interval_s, temp.line_frequency_hz)
        for meter in (dmm, temp):
            meter.reset()

    def record_chunk(self, ctx: Context, seconds: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        p, w = self.p, ctx.wiring
        dmm, temp = multimeter(ctx), multimeter(ctx, "dmm_temp")
        n = max(2, int(round(seconds / p.sample_interval_s)))
        dmm.configure_timed_trace(n, p.sample_interval_s, nplc=min(p.nplc, choose_nplc(p.sample_interval_s,
                                  dmm.line_frequency_hz, autozero=False)), range_v=10.0)
        temp.configure_timed_trace(n, p.sample_interval_s, nplc=self.nplc_temp, range_v=10.0)
        t0 = ctx.clock.now()
        dmm.initiate()
        temp.initiate()
        ctx.clock.sleep(n * p.sample_interval_s + max(dmm.trigger_delay_s, temp.trigger_delay_s))
        volts, tv = dmm.fetch_all(), temp.fetch_all()
        m = min(volts.size, tv.size)
        t = t0 + dmm.trigger_delay_s + np.arange(volts.size) * p.sample_interval_s
        unit_c = tv / float(w["temp_resistor_ohm"]) / AD590_A_PER_K - KELVIN_C
        g = volts / float(w["sampling_resistor_ohm"]) * 1e3 / self.ma_per_g
        ctx.run.append("thermal_ramp", t_s=t[:m], voltage_v=volts[:m], output_g=g[:m], unit_c=unit_c[:m])
        ok = np.isfinite(volts[:m]) & np.isfinite(unit_c)[:m]
        if not np.all(ok):
            raise RuntimeError(f"meter overload during the ramp record: {int(np.sum(~ok))} of {m} readings "
                               "out of range (stored)")
        if m < n:
            raise RuntimeError(f"ramp record: {m} of {n} readings in a chunk (stored); a meter stopped")
        return t[:m], g[:m], unit_c[:m]


# --------------------------------------------------------------------------- gyro


@dataclass
class GyroRampParameters(RampParameters):
    frame_rate_hz: int = parameter(10, "gyro frame rate over the record, Hz")

    def validate(self) -> None:
        super().validate()
        check_ranges(asdict(self), {"frame_rate_hz": (1, 4608)}, integers=("frame_rate_hz",))


class GyroThermalRamp(ThermalRampBase[GyroRampParameters]):
    """Gyro at rest over up-and-down chamber ramps: bias curve, hysteresis, Shupe rate sensitivity.

    Input axis up, frames streamed over the whole record; two ramp rates separate the
    thermal hysteresis from the temperature-rate (Shupe) sensitivity.
    """

    name = "gyro_thermal_ramp"
    requires = ("gyro", "supply", "turntable", "chamber")
    kinds = ("gyro",)
    produces = {
        "hysteresis": ("deg/h", "thermal hysteresis: up- minus down-ramp bias at equal temperature, zero rate"),
        "rate_sensitivity": ("deg/h/(degC/min)", "bias per °C/min of the unit's temperature rate (Shupe)"),
        "branch_offset": ("deg/h", "up- minus down-ramp bias at equal temperature at the record's rates"),
    }
    Parameters = GyroRampParameters

    def thermometer(self) -> UnitThermometer:
        return GyroThermometer()

    def power(self, ctx: Context) -> None:
        level_table(ctx)
        power_gyro(ctx, on=True)
        ctx.clock.sleep(5.0)  # boot

    def prepare(self, ctx: Context) -> None:
        ctx.run.add_stream("thermal_ramp", {"t_s": "s", "rate_dps": "deg/s", "temperature_c": "degC",
                                            "status": "1"}, "gyro frames at rest over the ramps")

    def start_record(self, ctx: Context) -> None:
        gyro = frame_gyro(ctx)
        gyro.configure(rate_hz=self.p.frame_rate_hz)
        self.t0 = ctx.clock.now()
        gyro.start()

    def record_chunk(self, ctx: Context, seconds: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        rate = self.p.frame_rate_hz
        kept: list[tuple[np.ndarray, GyroFrames]] = []

        def store(frames: GyroFrames) -> None:
            t = self.t0 + (frames.index + 1) / rate
            ctx.run.append("thermal_ramp", t_s=t, rate_dps=frames.rate_dps, temperature_c=frames.temperature_c,
                           status=frames.status)
            kept.append((t, frames))

        read_gyro_frames(ctx, max(1, int(round(seconds * rate))), store)
        t, frames = kept[-1]
        return t, frames.rate_dps * 3600.0, frames.temperature_c

    def stop_record(self, ctx: Context) -> None:
        frame_gyro(ctx).stop()


__all__ = ["ThermalRamp", "GyroThermalRamp", "RampParameters", "AccelerometerRampParameters",
           "GyroRampParameters"]

