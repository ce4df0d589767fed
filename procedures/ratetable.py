"""Gyro rate-table calibration, IEEE Std 952/647 style, turntable inner axis in rate mode.

1. Power the gyro, let it boot and warm up, input axis up (platform level).
2. For each rate of the plan (± pairs, log-spaced up to a fraction of full scale, smallest
   first, signs interleaved so slow drift does not pose as asymmetry): command the rate, wait
   until the table is at rate, then record the gyro's frames over a whole number of
   revolutions (so the horizontal Earth rate and table wobble average out); stream every
   frame and the per-rate mean with its standard error.
3. Fit scale factor, bias, nonlinearity and asymmetry with uncertainties
   (:func:`bench.analysis.ratetable._fit.fit_rate_table`); the input rate includes the Earth
   rate's vertical component at the station's site latitude (``[site]`` of the station file).

Indicated rates are the gyro's pulses through its nominal scale factor, in °/s.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from bench.analysis.ratetable import fit_rate_table, rate_plan, whole_revolution_duration_s
from bench.core.site import earth_rate_vertical_dph
from bench.core.step import Context, Step, parameter
from bench.values import Estimate
from instruments.fog_types import GyroFrames
from procedures.common import check_ranges, level_table, power_gyro, read_gyro_frames
from procedures.typed_instruments import frame_gyro, turntable

RATETABLE_PRODUCES = {
    "scale_factor_error": ("ppm", "scale factor relative to nominal, minus 1"),
    "bias": ("deg/h", "bias (indicated rate at zero input)"),
    "nonlinearity": ("ppm", "scale-factor nonlinearity, max residual of the LS line / full-scale output"),
    "asymmetry": ("ppm", "scale-factor asymmetry (SF+ − SF−)/SF"),
}
REVOLUTIONS_FOR_SPREAD = 3   # with fewer whole revolutions, σ comes from 8 equal blocks
AT_RATE_TIMEOUT_S = 120.0


@dataclass
class RateTableParameters:
    rates_per_sign: int = parameter(6, "table rates of each sign, log-spaced")
    min_fraction: float = parameter(0.01, "smallest rate as a fraction of full scale")
    max_fraction: float = parameter(0.95, "largest rate as a fraction of full scale (head-room for "
                                          "the Earth rate and the clip)")
    min_record_s: float = parameter(30.0, "record per rate, rounded up to whole revolutions, s")
    warmup_s: float = parameter(600.0, "powered, before the first rate, s")
    settle_s: float = parameter(2.0, "after 'at rate', before recording, s")
    frame_rate_hz: int = parameter(1000, "gyro frame rate, Hz")
    full_scale_dps: float = parameter(0.0, "full scale, deg/s (0: the gyro's own, $CFG?)")
    latitude_deg: float | None = parameter(None, "latitude for the Earth rate, deg (default: the station's site)")
    boot_wait_s: float = parameter(5.0, "powered, before the gyro is asked its configuration, s")

    def validate(self) -> None:
        check_ranges(asdict(self), {
            "rates_per_sign": (1, 30), "min_fraction": (1e-4, 0.99), "max_fraction": (0.01, 1.0),
            "min_record_s": (1, 36000), "warmup_s": (0, 86400), "settle_s": (0, 600),
            "frame_rate_hz": (1, 4608), "full_scale_dps": (0, 5000), "latitude_deg": (-90, 90),
            "boot_wait_s": (0, 600)},
            integers=("rates_per_sign", "frame_rate_hz"))
        if not self.min_fraction < self.max_fraction:
            raise ValueError(f"min_fraction = {self.min_fraction} must be < max_fraction = {self.max_fraction}")


class RateTableCalibration(Step[RateTableParameters]):
    """Gyro rate-table calibration (IEEE 952): scale factor, bias, nonlinearity, asymmetry.

    ± rates log-spaced up to a fraction of full scale, whole revolutions each, the Earth
    rate's vertical component at the station's latitude in the input.
    """

    name = "ratetable"
    requires = ("gyro", "supply", "turntable")
    kinds = ("gyro",)
    produces = RATETABLE_PRODUCES

    Parameters = RateTableParameters

    def _plan(self, full_scale_dps: float) -> np.ndarray:
        p = self.p
        return rate_plan(full_scale_dps, p.rates_per_sign, min_fraction=p.min_fraction,
                         max_fraction=p.max_fraction)

    def duration_s(self) -> float:  # progress weight: the plan at a nominal 500 °/s full scale
        plan = self._plan(self.p.full_scale_dps or 500.0)
        return self.p.warmup_s + sum(whole_revolution_duration_s(r, self.p.min_record_s)
                                     + self.p.settle_s + 5.0 for r in plan)

    def run(self, ctx: Context) -> dict[str, Estimate]:
        p = self.p
        gyro, table = frame_gyro(ctx), turntable(ctx)
        level_table(ctx)  # input axis up: the Earth rate's vertical component is the one sensed
        power_gyro(ctx, on=True)
        ctx.clock.sleep(p.boot_wait_s)
        gyro.configure(rate_hz=p.frame_rate_hz)
        fs = p.full_scale_dps or gyro.config.full_scale_dps
        plan = self._plan(fs)
        latitude = p.latitude_deg if p.latitude_deg is not None else ctx.site["latitude_deg"]
        earth_dps = earth_rate_vertical_dph(latitude) / 3600.0
        axis = table.axis[1]
        previous_limit = axis.rate_limit_dps
        # the user rate limit (often 30 °/s) must admit the plan; set now, so a table that
        # cannot do it refuses before the warm-up, and put back afterwards whatever happens
        axis.rate_limit_dps = float(np.max(np.abs(plan))) * 1.02
        try:
            return self._rates(ctx, plan, fs, earth_dps, latitude)
        finally:
            try:
                axis.stop()
                axis.wait_in_position(ctx.clock.sleep, timeout_s=AT_RATE_TIMEOUT_S)  # at rest
            finally:
                axis.rate_limit_dps = previous_limit

    def _rates(self, ctx: Context, plan: np.ndarray, fs: float, earth_dps: float,
               latitude: float) -> dict[str, Estimate]:
        p = self.p
        gyro, axis = frame_gyro(ctx), turntable(ctx).axis[1]
        total = self.duration_s()
        ctx.progress(0, total, "gyro warming up")
        ctx.clock.sleep(max(p.warmup_s - p.boot_wait_s, 0.0))
        ctx.run.add_stream("ratetable_frames", {"t_s": "s", "table_rate_dps": "deg/s", "counts": "pulses",
                                           "rate_dps": "deg/s", "temperature_c": "degC",
                                           "status": "1"}, "every gyro frame recorded at rate")
        ctx.run.add_stream("ratetable", {
            "table_rate_dps": "deg/s", "input_rate_dps": "deg/s", "output_dps": "deg/s",
            "output_se_dps": "deg/s", "frames": "1", "revolutions": "1", "dropped": "1",
            "corrupt": "1"}, "mean indicated rate per table rate (whole revolutions)")
        means, errors = np.empty(plan.size), np.empty(plan.size)
        done = p.warmup_s
        for k, rate in enumerate(plan):
            axis.set_rate(float(rate))
            axis.wait_at_rate(ctx.clock.sleep, timeout_s=AT_RATE_TIMEOUT_S)
            ctx.clock.sleep(p.settle_s)
            record_s = whole_revolution_duration_s(float(rate), p.min_record_s)
            n = int(round(record_s * p.frame_rate_hz))
            record_s = n / p.frame_rate_hz
            t_start = ctx.clock.now()

            def store(frames: GyroFrames, rate: float = float(rate), t_start: float = t_start) -> None:
                ctx.run.append("ratetable_frames", t_s=t_start + frames.t_s,
                               table_rate_dps=np.full(len(frames), rate), counts=frames.counts,
                               rate_dps=frames.rate_dps, temperature_c=frames.temperature_c,
                               status=frames.status)

            gyro.start()
            frames = read_gyro_frames(ctx, n, store, stop=True)
            revolutions = record_s * abs(rate) / 360.0
            means[k], errors[k] = frames.rate_dps.mean(), _standard_error(frames.rate_dps, revolutions)
            ctx.run.append("ratetable", table_rate_dps=[rate], input_rate_dps=[rate + earth_dps],
                           output_dps=[means[k]], output_se_dps=[errors[k]], frames=[len(frames)],
                           revolutions=[revolutions], dropped=[frames.dropped], corrupt=[frames.corrupt])
            done += record_s + p.settle_s + 5.0
            ctx.progress(done, total, f"rate {k + 1}/{plan.size}: {rate:+.4g} °/s")
        # IEEE 952's line is an unweighted least-squares line: one common σ (the rms of the
        # per-rate errors) keeps the fitted scale factor and nonlinearity a property of the
        # gyro and the plan, not of how noisy each record's error estimate happened to be.
        common = np.full(plan.size, float(np.sqrt(np.mean(errors**2))))
        fit = fit_rate_table(plan + earth_dps, means, common, full_scale_dps=fs)
        ctx.run.set_result("ratetable.fit", {**fit.to_dict(), "earth_rate_dps": earth_dps,
                                             "latitude_deg": latitude, "table_rates_dps": plan.tolist()})
        return {"scale_factor_error": _est(fit.scale_factor_error_ppm), "bias": _est(fit.bias_dph),
                "nonlinearity": _est(fit.nonlinearity_ppm), "asymmetry": _est(fit.asymmetry_ppm)}


def _est(e) -> Estimate:
    return Estimate(e.value, e.std)


def _standard_error(rate_dps: np.ndarray, revolutions: float) -> float:
    """σ of the mean from the spread of whole-revolution means (or of 8 blocks when the record
    has fewer than REVOLUTIONS_FOR_SPREAD revolutions: conservative, as the Earth rate's
    horizontal part then varies within a block)."""
    blocks = int(round(revolutions)) if revolutions >= REVOLUTIONS_FOR_SPREAD else 8
    blocks = min(blocks, rate_dps.size // 2)
    m = rate_dps.size // blocks
    means = rate_dps[: m * blocks].reshape(blocks, m).mean(axis=1)
    return float(means.std(ddof=1) / math.sqrt(blocks))
