"""Start-up test of an accelerometer for acceptance: cold start, record, turn-on time and
warm-up drift.

The acquisition is the start-up procedure's (level check, cool-down, armed traces, power-on
at t = 0, streaming); the record is then read back from the run and reduced by
:func:`bench.analysis.turn_on.turn_on_metrics`.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from bench.analysis.turn_on import turn_on_metrics
from bench.procedure import Context
from procedures.steps import ParameterizedStep
from procedures.common import Estimate, check_ranges
from procedures.startup import StartupAcquisition, StartupParameters

TURN_ON_PRODUCES = {
    "turn_on_time": ("s", "time from power-on to within the band of the settled output"),
    "warmup_drift": ("g", "change of the start-up trend from power-on to the end of the record"),
}


@dataclass
class TurnOnParameters:
    duration_s: float = 1800.0
    rate_hz: float = 20.0
    off_wait_s: float = 600.0
    band_g: float = 20e-6          # the "within" band around the settled output
    smooth_s: float = 10.0         # averaging of the output before comparing with the band
    settled_window_s: float = 300.0

    def validate(self) -> None:
        check_ranges(asdict(self), {"duration_s": (120, 86400), "rate_hz": (0.1, 1000),
                                    "off_wait_s": (0, 86400), "band_g": (1e-7, 0.1),
                                    "smooth_s": (0.1, 600), "settled_window_s": (1, 43200)})
        if not self.smooth_s * 4 <= self.duration_s or not self.settled_window_s * 2 <= self.duration_s:
            raise ValueError(f"duration_s = {self.duration_s} must cover 4 × smooth_s and "
                             "2 × settled_window_s")


class TurnOnTest(ParameterizedStep):
    name = "startup"
    requires = ("dmm", "dmm_temp", "supply", "turntable")
    kinds = ("accelerometer",)
    produces = TURN_ON_PRODUCES

    Parameters = TurnOnParameters

    def __init__(self, params: TurnOnParameters | None = None, **overrides) -> None:
        super().__init__(params, **overrides)
        self.acquisition = StartupAcquisition(StartupParameters(
            duration_s=self.p.duration_s, rate_hz=self.p.rate_hz, off_wait_s=self.p.off_wait_s))

    def duration_s(self) -> float:
        return self.p.duration_s + self.p.off_wait_s

    def run(self, ctx: Context) -> dict[str, Estimate]:
        self.acquisition.setup(ctx)  # meters reset, supply off, table level: IA up
        self.acquisition.run(ctx)
        streams = ctx.run.store.streams(ctx.run.id)
        if "output" not in streams:  # the level check failed: nothing to reduce
            return {}
        data = ctx.run.store.load(ctx.run.id, "output")
        t, g = np.asarray(data["t_s"]), np.asarray(data["acceleration_g"])
        keep = t >= 0.0
        r = turn_on_metrics(t[keep], g[keep], band=self.p.band_g, smooth_s=self.p.smooth_s,
                            settled_window_s=self.p.settled_window_s)
        ctx.run.set_result("startup.turn_on", r.to_dict())
        return {"turn_on_time": Estimate(r.turn_on_time_s, None),
                "warmup_drift": Estimate(r.warmup_drift, r.warmup_drift_std)}
