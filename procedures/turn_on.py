"""Turn-on tests: cold start, record, turn-on time and warm-up drift — of an accelerometer
(``turn_on``, through the DMM) and of a gyro (``gyro_turn_on``, its frames).

The accelerometer's record is the start-up acquisition's (``procedures.startup``: level
check, cool-down, armed traces, power-on at t = 0, streaming); it is read back from the run
and reduced by :func:`bench.analysis.turn_on._metrics.turn_on_metrics`.  The reductions are kept under
the start-up records' names (``startup.turn_on``, ``gyro_startup.turn_on``): what they reduce.

(Until the one step catalogue these steps were named ``startup`` and ``gyro_startup`` in
unit specs; ``startup`` is now only Document A's acquisition, ``bench run startup``.)
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from bench.analysis.turn_on import turn_on_metrics
from bench.core.step import Context, Step, parameter
from bench.values import Estimate
from instruments.fog_types import GyroFrames
from procedures.common import check_ranges, level_table, power_gyro, read_gyro_frames
from procedures.startup import StartupAcquisition, StartupParameters
from procedures.typed_instruments import frame_gyro

TURN_ON_PRODUCES = {
    "turn_on_time": ("s", "time from power-on to within the band of the settled output"),
    "warmup_drift": ("g", "change of the start-up trend from power-on to the end of the record"),
}


@dataclass
class TurnOnParameters:
    duration_s: float = parameter(1800.0, "record after power-on, s")
    rate_hz: float = parameter(20.0, "output sample rate, Hz")
    off_wait_s: float = parameter(600.0, "cool-down with the supply off before the cold start, s")
    band_g: float = parameter(20e-6, "the 'within' band around the settled output, g")
    smooth_s: float = parameter(10.0, "averaging of the output before it is compared with the band, s")
    settled_window_s: float = parameter(300.0, "end of the record whose mean is the settled output, s")

    def validate(self) -> None:
        check_ranges(asdict(self), {"duration_s": (120, 86400), "rate_hz": (0.1, 1000),
                                    "off_wait_s": (0, 86400), "band_g": (1e-7, 0.1),
                                    "smooth_s": (0.1, 600), "settled_window_s": (1, 43200)})
        if not self.smooth_s * 4 <= self.duration_s or not self.settled_window_s * 2 <= self.duration_s:
            raise ValueError(f"duration_s = {self.duration_s} must cover 4 × smooth_s and "
                             "2 × settled_window_s")


class TurnOnTest(Step[TurnOnParameters]):
    """Accelerometer cold start through the DMM: turn-on time and warm-up drift.

    The start-up acquisition (level check, cool-down, armed traces, power-on at t = 0),
    then the record reduced: time to within ``band_g`` of the settled output, and the change
    of the fitted start-up trend over the record.
    """

    name = "turn_on"
    requires = ("dmm", "dmm_temp", "supply", "turntable")
    kinds = ("accelerometer",)
    produces = TURN_ON_PRODUCES

    Parameters = TurnOnParameters

    def __init__(self, params: TurnOnParameters | None = None, **overrides: Any) -> None:
        super().__init__(params, **overrides)
        self.acquisition = StartupAcquisition(StartupParameters(
            duration_s=self.p.duration_s, rate_hz=self.p.rate_hz, off_wait_s=self.p.off_wait_s))

    def duration_s(self) -> float:
        return self.p.duration_s + self.p.off_wait_s

    def run(self, ctx: Context) -> dict[str, Estimate]:
        level_table(ctx)  # input axis up: the acquisition's level check expects +1 g
        self.acquisition.run(ctx)  # meters reset, supply off, the record from power-on
        streams = ctx.run.store.streams(ctx.run.id)
        if "output" not in streams:  # the level check failed: nothing to reduce
            return {}
        data = ctx.run.store.load(ctx.run.id, "output")
        t, g = np.asarray(data["t_s"]), np.asarray(data["acceleration_g"])
        keep = t >= 0.0
        r = turn_on_metrics(t[keep], g[keep], band=self.p.band_g, smooth_s=self.p.smooth_s,
                            settled_window_s=self.p.settled_window_s)
        ctx.run.set_result("startup.turn_on", r.to_dict())
        return {"turn_on_time": Estimate(r.turn_on_time_s, None, bound=None if r.resolved else "upper"),
                "warmup_drift": Estimate(r.warmup_drift, r.warmup_drift_std)}


GYRO_TURN_ON_PRODUCES = {
    "turn_on_time": ("s", "time from power-on to within the band of the settled rate (boot included)"),
    "warmup_drift": ("deg/h", "change of the start-up trend from the first valid output to the end"),
}
STATUS_READY = 0x01  # docs/FOG_SERIAL.md: powered and booted, the output is valid


@dataclass
class GyroTurnOnParameters:
    duration_s: float = parameter(1800.0, "record after power-on, s")
    frame_rate_hz: int = parameter(100, "gyro frame rate, Hz")
    off_wait_s: float = parameter(600.0, "cool-down with the supply off before the cold start, s")
    boot_wait_s: float = parameter(5.0, "powered, before the unit is asked to stream, s")
    band_dph: float = parameter(2.0, "the 'within' band around the settled rate, deg/h")
    # ARW 0.07 °/√h averages to 0.4 °/h over 120 s: well inside the band
    smooth_s: float = parameter(120.0, "averaging of the rate before it is compared with the band, s")
    settled_window_s: float = parameter(600.0, "end of the record whose mean is the settled rate, s")
    chunk_s: float = parameter(300.0, "frames read (and stored) per chunk, s")

    def validate(self) -> None:
        check_ranges(asdict(self), {"duration_s": (120, 86400), "frame_rate_hz": (1, 4608),
                                    "off_wait_s": (0, 86400), "boot_wait_s": (0, 600),
                                    "band_dph": (1e-4, 1e4), "smooth_s": (0.1, 3600),
                                    "settled_window_s": (1, 43200), "chunk_s": (1, 3600)},
                     integers=("frame_rate_hz",))
        if not self.smooth_s * 4 <= self.duration_s or not self.settled_window_s * 2 <= self.duration_s:
            raise ValueError(f"duration_s = {self.duration_s} must cover 4 × smooth_s and "
                             "2 × settled_window_s")


class GyroTurnOnTest(Step[GyroTurnOnParameters]):
    """Gyro cold start from its frames: turn-on time and warm-up drift.

    Supply off and cool-down, power on (t = 0), stream frames from boot; turn-on time and
    warm-up drift of the valid (READY) output, in °/h.
    """

    name = "gyro_turn_on"
    requires = ("gyro", "supply", "turntable")
    kinds = ("gyro",)
    produces = GYRO_TURN_ON_PRODUCES

    Parameters = GyroTurnOnParameters

    def duration_s(self) -> float:
        return self.p.off_wait_s + self.p.duration_s

    def run(self, ctx: Context) -> dict[str, Estimate]:
        p = self.p
        gyro = frame_gyro(ctx)
        level_table(ctx)  # at rest, input axis up
        power_gyro(ctx, on=False)
        ctx.progress(0, self.duration_s(), "cool-down before the cold start")
        ctx.clock.sleep(p.off_wait_s)
        power_gyro(ctx, on=True)
        t_on = ctx.clock.now()
        ctx.run.event(t_on, "t0", "gyro power-on: t = 0 of the start-up test")
        ctx.clock.sleep(p.boot_wait_s)
        gyro.configure(rate_hz=p.frame_rate_hz)
        ctx.run.add_stream("gyro_startup", {"t_s": "s", "rate_dps": "deg/s", "temperature_c": "degC",
                                            "status": "1"}, "gyro frames from power-on (t = 0)")
        t_start = ctx.clock.now() - t_on
        parts: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []

        def store(frames: GyroFrames) -> None:
            t = t_start + (frames.index + 1) / p.frame_rate_hz
            ctx.run.append("gyro_startup", t_s=t, rate_dps=frames.rate_dps,
                           temperature_c=frames.temperature_c, status=frames.status)
            parts.append((t, frames.rate_dps, frames.status))

        n_total = int(round((p.duration_s - t_start) * p.frame_rate_hz))
        chunk = max(1, int(p.chunk_s * p.frame_rate_hz))
        gyro.start()
        got = 0
        while got < n_total:
            got += len(read_gyro_frames(ctx, min(chunk, n_total - got), store))
            ctx.progress(p.off_wait_s + t_start + got / p.frame_rate_hz, self.duration_s(),
                         "start-up record")
        gyro.stop()
        t = np.concatenate([x[0] for x in parts])
        rate_dph = np.concatenate([x[1] for x in parts]) * 3600.0
        ready = (np.concatenate([x[2] for x in parts]).astype(np.int64) & STATUS_READY) != 0
        if ready.sum() < 64:
            raise RuntimeError(f"gyro gave {int(ready.sum())} valid frames in {p.duration_s:g} s "
                               "after power-on (never booted?)")
        r = turn_on_metrics(t[ready], rate_dph[ready], band=p.band_dph, smooth_s=p.smooth_s,
                            settled_window_s=p.settled_window_s)
        ctx.run.set_result("gyro_startup.turn_on", {**r.to_dict(),
                           "first_valid_s": float(t[ready][0])})
        return {"turn_on_time": Estimate(r.turn_on_time_s, None, bound=None if r.resolved else "upper"),
                "warmup_drift": Estimate(r.warmup_drift, r.warmup_drift_std)}
