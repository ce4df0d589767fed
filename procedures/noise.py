"""Bias stability and noise from a static record → overlapping Allan deviation (IEEE 952).

* ``accelerometer_noise`` — the unit powered, warm and level (IA up); a timed DMM trace whose
  aperture fills the reading interval (so no noise is lost between readings); produces the
  white-noise density (one-sided, the data-sheet convention: √2 × IEEE N) and the bias
  instability B.
* ``gyro_noise`` — the gyro powered, warm, the table at rest; frames at a low frame rate
  for hours; produces the angle random walk N and the bias instability B.

Every sample streams to the run; the Allan result is kept under ``<step>.allan``.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from bench.analysis.allan import adev_interval, edf_greenhall, overlapping_adev
from bench.core.step import Context, Step, parameter
from bench.values import Estimate
from instruments.fog_types import GyroFrames
from procedures.common import check_ranges, level_table, power_accelerometer, power_gyro, read_gyro_frames
from procedures.typed_instruments import frame_gyro, multimeter

ACCEL_NOISE_PRODUCES = {
    "noise_density": ("g/rtHz", "white-noise density, one-sided (√2 × IEEE 952 N)"),
    "bias_instability": ("g", "bias instability B (IEEE 952, flicker floor / 0.664)"),
}
GYRO_NOISE_PRODUCES = {
    "arw": ("deg/rth", "angle random walk N (IEEE 952)"),
    "bias_instability": ("deg/h", "bias instability B (IEEE 952, flicker floor / 0.664)"),
}
_DMM_OVERHEAD_S = 0.001  # left between readings of a timed trace
_ALPHA = {"N": 0, "B": -1}  # power-law exponent of the noise each term describes


def _coefficient(allan, name: str) -> Estimate:
    """IEEE 952's slope-line read-off (N on the −1/2 line at τ = 1 s, B from the flat
    minimum), its standard uncertainty from the ADEV confidence interval at the τ it was read
    at; the fitted model's value when the curve has no such part.

    The read-off is preferred: on simulated units with coloured noise the five-term fit
    trades N and B against terms the process does not have (a Gauss–Markov bump), while the
    read-off stays within the curve's own confidence interval of the truth.
    """
    c = allan.coefficients[name]
    if c.read_off is not None and c.read_off_tau_s is not None:
        k = int(np.argmin(np.abs(allan.tau_s - c.read_off_tau_s)))
        # the interval for the noise the term *is* (white for N, flicker for B), at that τ
        edf = edf_greenhall(_ALPHA[name], int(allan.averaging_factor[k]), allan.n_samples + 1)
        lo, hi = adev_interval(np.array([1.0]), edf)[0]
        return Estimate(c.read_off, c.read_off * float(hi - lo) / 2.0)
    if c.fit is not None and c.fit > 0:
        return Estimate(c.fit, c.fit_std)
    return Estimate(float("nan"), None)


@dataclass
class AccelerometerNoiseParameters:
    duration_s: float = parameter(3600.0, "static record, s")
    rate_hz: float = parameter(10.0, "reading rate, Hz (the aperture fills each interval)")
    warmup_s: float = parameter(900.0, "powered and level, before the record, s")
    chunk_s: float = parameter(300.0, "readings drained (and stored) per chunk, s")

    def validate(self) -> None:
        check_ranges(asdict(self), {"duration_s": (60, 86400), "rate_hz": (1, 100),
                                    "warmup_s": (0, 86400), "chunk_s": (1, 3600)})
        if self.duration_s * self.rate_hz > 2_000_000:
            raise ValueError(f"duration_s × rate_hz = {self.duration_s * self.rate_hz:.0f} readings exceeds 2e6")


class AccelerometerNoise(Step[AccelerometerNoiseParameters]):
    """Accelerometer static record → Allan deviation: noise density, bias instability.

    The unit powered, warm and level (IA up); white-noise density (one-sided) and bias
    instability B read off the overlapping Allan deviation (IEEE 952).
    """

    name = "accelerometer_noise"
    requires = ("dmm", "supply", "turntable")
    kinds = ("accelerometer",)
    produces = ACCEL_NOISE_PRODUCES

    Parameters = AccelerometerNoiseParameters

    def duration_s(self) -> float:
        return self.p.warmup_s + self.p.duration_s

    def run(self, ctx: Context) -> dict[str, Estimate]:
        p = self.p
        dmm = multimeter(ctx)
        level_table(ctx)  # IA up: the record's mean is then 1 g (the normalisation below)
        power_accelerometer(ctx, on=True)
        ctx.progress(0, self.duration_s(), "warming up")
        ctx.clock.sleep(p.warmup_s)
        interval = 1.0 / p.rate_hz
        n = int(round(p.duration_s * p.rate_hz))
        # whole mains cycles reject line pickup; the gap it leaves is corrected below
        cycles = math.floor((interval - _DMM_OVERHEAD_S) * dmm.line_frequency_hz)
        aperture = cycles / dmm.line_frequency_hz if cycles >= 1 else interval - _DMM_OVERHEAD_S
        plan = dmm.configure_timed_trace(n, interval, aperture_s=aperture, range_v=10.0)
        ctx.run.add_stream("noise", {"t_s": "s", "voltage_v": "V"}, "static output record")
        t0 = ctx.clock.now() + plan.trigger_delay_s
        chunk = max(1, min(int(p.chunk_s * p.rate_hz), dmm.memory_depth // 2))
        parts, got = [], 0
        for volts in dmm.stream_trace(chunk, wait=ctx.clock.sleep):
            ctx.run.append("noise", t_s=t0 + (got + np.arange(volts.size)) * interval, voltage_v=volts)
            parts.append(volts)
            got += volts.size
            ctx.progress(p.warmup_s + got / p.rate_hz, self.duration_s(), "static record")
        return self.reduce(ctx, np.concatenate(parts), aperture, interval)

    def reduce(self, ctx: Context, volts: np.ndarray, aperture: float, interval: float) -> dict[str, Estimate]:
        """The static record (readings of ``aperture`` s every ``interval`` s) → the Allan
        deviation, kept under ``accelerometer_noise.allan``; the produced values (also a
        batch's, per socket)."""
        p = self.p
        if not np.all(np.isfinite(volts)):
            raise RuntimeError("overload during the static record")
        # volts → g with the record's own mean as 1 g: the unit is level, IA up; the scale
        # factor's error (~1e-3) is far below what an Allan estimate resolves
        g = volts / float(np.mean(volts))
        allan = overlapping_adev(g, p.rate_hz, "octave", unit="g")
        ctx.run.set_result("accelerometer_noise.allan", {**allan.to_dict(),
                           "aperture_s": aperture, "interval_s": interval})
        n_est = _coefficient(allan, "N")
        # a reading integrates only its aperture: white noise per reading is larger by
        # √(interval/aperture) than a gap-free average would be; undo it, then one-sided ×√2
        duty = math.sqrt(aperture / interval) * math.sqrt(2.0)
        density = Estimate(n_est.value * duty, None if n_est.std is None else n_est.std * duty)
        return {"noise_density": density, "bias_instability": _coefficient(allan, "B")}


@dataclass
class GyroNoiseParameters:
    duration_s: float = parameter(7200.0, "static record, s")
    frame_rate_hz: int = parameter(100, "gyro frame rate, Hz")
    warmup_s: float = parameter(900.0, "powered, table at rest, before the record, s")
    chunk_s: float = parameter(600.0, "frames read (and stored) per chunk, s")

    def validate(self) -> None:
        check_ranges(asdict(self), {"duration_s": (60, 86400 * 3), "frame_rate_hz": (1, 4608),
                                    "warmup_s": (0, 86400), "chunk_s": (1, 3600)},
                     integers=("frame_rate_hz",))
        if self.duration_s * self.frame_rate_hz > 50_000_000:
            raise ValueError(f"duration_s × frame_rate_hz = {self.duration_s * self.frame_rate_hz:.0f} "
                             "frames exceeds 5e7")


class GyroNoise(Step[GyroNoiseParameters]):
    """Gyro static record → Allan deviation: ARW, bias instability.

    The gyro powered, warm, the table at rest; angle random walk N and bias instability B
    read off the overlapping Allan deviation (IEEE 952).
    """

    name = "gyro_noise"
    requires = ("gyro", "supply", "turntable")
    kinds = ("gyro",)
    produces = GYRO_NOISE_PRODUCES

    Parameters = GyroNoiseParameters

    def duration_s(self) -> float:
        return self.p.warmup_s + self.p.duration_s

    def run(self, ctx: Context) -> dict[str, Estimate]:
        p = self.p
        gyro = frame_gyro(ctx)
        level_table(ctx)  # at rest, input axis up
        power_gyro(ctx, on=True)
        ctx.progress(0, self.duration_s(), "gyro warming up")
        ctx.clock.sleep(p.warmup_s)
        gyro.configure(rate_hz=p.frame_rate_hz)
        ctx.run.add_stream("gyro_static", {"t_s": "s", "counts": "pulses", "rate_dps": "deg/s",
                                           "temperature_c": "degC", "status": "1"},
                           "static gyro record (table at rest)")
        n_total = int(round(p.duration_s * p.frame_rate_hz))
        chunk = max(1, int(p.chunk_s * p.frame_rate_hz))
        t0 = ctx.clock.now()
        gyro.start()
        parts: list[np.ndarray] = []

        def store(frames: GyroFrames) -> None:
            ctx.run.append("gyro_static", t_s=t0 + (frames.index + 1) / p.frame_rate_hz,
                           counts=frames.counts, rate_dps=frames.rate_dps,
                           temperature_c=frames.temperature_c, status=frames.status)

        got = 0
        while got < n_total:
            frames = read_gyro_frames(ctx, min(chunk, n_total - got), store)
            parts.append(frames.rate_dps)
            got += len(frames)
            ctx.progress(p.warmup_s + got / p.frame_rate_hz, self.duration_s(), "static record")
        gyro.stop()
        rate = np.concatenate(parts)
        allan = overlapping_adev(rate, float(p.frame_rate_hz), "octave", unit="dps")
        ctx.run.set_result("gyro_noise.allan", allan.to_dict())
        return {"arw": _coefficient(allan, "N"), "bias_instability": _coefficient(allan, "B")}
