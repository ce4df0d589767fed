"""FOG under random vibration (Document C's test): static, random vibration, static.

1. Power the gyro and let it warm up (the fixture at rest: the step adapter levels the
   turntable, whose platform is the shaker's fixture on the simulated station).
2. Set the random profile (flat ASD between ``f_lo_hz`` and ``f_hi_hz`` at ``level_grms``),
   0 dB, the ramp time; configure the frame rate and start the frame stream once — every
   frame of the three segments is read and stored, with no gap.
3. Static segment (``static_s``); ``:STARt``, frames through the ramp until the controller
   reports RUN, then ``duration_s`` of steady vibration; ``:STOP``, frames through the ramp
   down until IDLE, then ``static_s`` static again.
4. From the frames: static noise, rms rate under vibration, and the vibration-induced bias
   shift (mean rate under steady vibration minus the line through the static segments'
   1-s means at the vibration's mid-time: the rectification, linear drift removed).

Streams (bench-clock seconds): ``gyro_frames`` — every frame's counts, rate (°/s),
temperature, status, ``segment`` (0 static before, 1 vibration from ``:STARt``, 2 static
after from ``:STOP``), ``steady`` (1 outside the ramps: segment 1 from RUN, segment 2 from
IDLE) and ``level_grms``, the controller's level read after the frame's chunk (the rms
of its last second, so with ``chunk_s`` = 1 s the chunk's own level); ``shaker_level`` —
each poll's time, level and state.  Events mark every segment boundary.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from bench.core.step import Context, FollowUp, Step, parameter
from bench.values import Estimate
from procedures.common import check_ranges, power_gyro
from procedures.typed_instruments import frame_gyro, shaker

VIBRATION_PRODUCES = {
    "static_noise": ("deg/s", "rms rate at the frame rate, static segments (each segment's mean removed)"),
    "vibration_rms": ("deg/s", "rms rate at the frame rate under steady vibration (mean removed)"),
    "vibration_bias_shift": ("deg/h", "mean rate under vibration minus the static line at its "
                                      "mid-time (rectification)"),
    "vibration_level": ("g", "mean control level achieved under steady vibration, g rms"),
}
STATE_CODES = {"IDLE": 0, "RAMP": 1, "RUN": 2, "ABORT": 3}
SEGMENT_NAMES = ("static before", "vibration", "static after")
RAMP_MARGIN_S = 30.0   # beyond the ramp time, how long a ramp may take before we give up
BLOCK_S = 1.0          # block length of the means behind the bias shift's uncertainty


@dataclass
class VibrationParameters:
    static_s: float = parameter(60.0, "each static segment, s")
    # Document C analyses 1320-1495 s: 175 s
    duration_s: float = parameter(175.0, "steady vibration segment, s")
    level_grms: float = parameter(6.0, "flat random level, g rms")
    f_lo_hz: float = parameter(20.0, "profile start, Hz")
    f_hi_hz: float = parameter(2000.0, "profile end, Hz")
    ramp_s: float = parameter(2.0, "shaker ramp time, s")
    warmup_s: float = parameter(600.0, "gyro warm-up, s")
    frame_rate_hz: int = parameter(2000, "gyro frame rate, Hz", aliases=("rate-hz",))
    chunk_s: float = parameter(1.0, "frames per read, s (the controller's level is polled per chunk)")

    def validate(self) -> None:
        check_ranges(asdict(self), {
            "static_s": (2 * BLOCK_S, 86400), "duration_s": (2 * BLOCK_S, 86400),
            "level_grms": (0.01, 30), "f_lo_hz": (5, 3000), "f_hi_hz": (5, 3000),
            "ramp_s": (0.01, 60), "warmup_s": (0, 86400), "frame_rate_hz": (100, 4608),
            "chunk_s": (0.05, 10)}, integers=("frame_rate_hz",))
        if not self.f_lo_hz < self.f_hi_hz:
            raise ValueError(f"f_lo_hz = {self.f_lo_hz} must be < f_hi_hz = {self.f_hi_hz}")


class _Recorder:
    """Reads the one frame stream in chunks, stores every frame with its segment and level."""

    def __init__(self, ctx: Context, p: VibrationParameters, t0: float, total_s: float) -> None:
        self.ctx, self.p, self.t0, self.total_s = ctx, p, t0, total_s
        self.gyro, self.shaker = frame_gyro(ctx), shaker(ctx)
        self.bounds = [-math.inf, math.inf, math.inf]  # start time of segments 0, 1, 2
        self.steady_from = [-math.inf, math.inf, math.inf]
        self.t: list[np.ndarray] = []
        self.rate: list[np.ndarray] = []
        self.level: list[np.ndarray] = []

    def mark(self, segment: int, steady: bool = False) -> float:
        now = self.ctx.clock.now()
        (self.steady_from if steady else self.bounds)[segment] = now
        if not steady:  # static before is steady from its start; the others after their ramp
            self.steady_from[segment] = now if segment == 0 else math.inf
        kind = "steady" if steady else "segment"
        self.ctx.run.event(now, kind, f"{SEGMENT_NAMES[segment]}{' steady' if steady else ''}",
                           segment=segment)
        return now

    def read(self, seconds: float) -> None:
        """Record ``seconds`` worth of frames (whole frames), chunk by chunk."""
        n_total = max(1, int(round(seconds * self.p.frame_rate_hz)))
        chunk = max(1, int(round(self.p.chunk_s * self.p.frame_rate_hz)))
        while n_total > 0:
            n = min(chunk, n_total)
            frames = self.gyro.read_frames(n, timeout_s=max(60.0, n / self.p.frame_rate_hz),
                                           wait=self.ctx.clock.sleep)
            n_total -= n
            level, state, now = self.shaker.level_grms, self.shaker.state, self.ctx.clock.now()
            t = self.t0 + frames.t_s
            segment = np.searchsorted(self.bounds, t, side="left") - 1
            steady = t > np.asarray(self.steady_from)[segment]
            self.ctx.run.append("gyro_frames", t_s=t, counts=frames.counts, rate_dps=frames.rate_dps,
                                temperature_c=frames.temperature_c, status=frames.status,
                                segment=segment, steady=steady, level_grms=np.full(n, level))
            self.ctx.run.append("shaker_level", t_s=[now], level_grms=[level],
                                state=[STATE_CODES.get(state, -1)])
            if frames.dropped or frames.corrupt:
                raise RuntimeError(f"gyro line: {frames.dropped} frames dropped, {frames.corrupt} "
                                   "corrupt; the segments' means need every frame")
            if state == "ABORT":  # interlock or emergency stop: the frames so far are stored
                raise RuntimeError(f"shaker in ABORT at {now:.6g} s (interlock or emergency stop); "
                                   f"frames recorded up to {t[-1]:.6g} s")
            self.t.append(t)
            self.rate.append(frames.rate_dps)
            self.level.append(np.full(n, level))
            self.ctx.progress(self.p.warmup_s + (now - self.t0), self.total_s, SEGMENT_NAMES[
                int(segment[-1])])

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        t, rate, level = (np.concatenate(x) for x in (self.t, self.rate, self.level))
        segment = np.searchsorted(self.bounds, t, side="left") - 1
        steady = t > np.asarray(self.steady_from)[segment]
        return t, rate, level, segment, steady


class VibrationTest(Step[VibrationParameters]):
    """Gyro frames through static, random vibration, static (Document C): noise, rms under
    vibration, rectified bias shift.

    Every frame stored with its segment; with ``--analyze`` the steady vibration segment goes
    through Document C's EMD → AR → AR-Kalman model.
    """

    name = "vibration"
    requires = ("gyro", "supply", "shaker")
    kinds = ("gyro",)
    produces = VIBRATION_PRODUCES

    Parameters = VibrationParameters
    follow_up = FollowUp("vibration", on_request=True,
                         summary="model the vibration segment (EMD → AR → AR-Kalman) and attach the report")

    def duration_s(self) -> float:
        p = self.p
        return p.warmup_s + 2 * p.static_s + p.duration_s + 2 * p.ramp_s

    def run(self, ctx: Context) -> dict[str, Estimate]:
        p = self.p
        gyro, vibration_table = frame_gyro(ctx), shaker(ctx)
        vibration_table.stop()
        vibration_table.set_random_profile(grms=p.level_grms, f_lo_hz=p.f_lo_hz, f_hi_hz=p.f_hi_hz)
        with vibration_table.configuring():
            vibration_table.level_db = 0.0
            vibration_table.ramp_time_s = p.ramp_s
        ctx.run.event(ctx.clock.now(), "profile", f"flat random {p.level_grms:g} g rms, "
                      f"{p.f_lo_hz:g}-{p.f_hi_hz:g} Hz", target_grms=vibration_table.target_grms)
        power_gyro(ctx, on=True)
        ctx.progress(0, self.duration_s(), "gyro warming up")
        ctx.clock.sleep(p.warmup_s)
        gyro.configure(rate_hz=p.frame_rate_hz)
        ctx.run.add_stream("gyro_frames", {
            "t_s": "s", "counts": "pulses", "rate_dps": "deg/s", "temperature_c": "degC",
            "status": "1", "segment": "1", "steady": "1", "level_grms": "g"},
            "every gyro frame: 0 static before, 1 vibration, 2 static after; steady outside ramps",
            dtypes={"counts": np.int64, "status": np.int64, "segment": np.int8, "steady": np.bool_})
        ctx.run.add_stream("shaker_level", {"t_s": "s", "level_grms": "g", "state": "1"},
                           "controller level and state (0 IDLE, 1 RAMP, 2 RUN, 3 ABORT) per chunk",
                           dtypes={"state": np.int8})
        t0 = ctx.clock.now()
        gyro.start()
        rec = _Recorder(ctx, p, t0, self.duration_s())
        rec.mark(0)
        rec.read(p.static_s)
        rec.mark(1)
        vibration_table.start()
        vibration_table.wait_running(rec.read, timeout_s=p.ramp_s + RAMP_MARGIN_S, poll_s=p.chunk_s)
        rec.mark(1, steady=True)
        rec.read(p.duration_s)
        rec.mark(2)
        vibration_table.stop()
        vibration_table.wait_idle(rec.read, timeout_s=p.ramp_s + RAMP_MARGIN_S, poll_s=p.chunk_s)
        rec.mark(2, steady=True)
        rec.read(p.static_s)
        gyro.stop()
        result = vibration_statistics(*rec.arrays())
        ctx.run.set_result("vibration.segments", {**result.pop("segments"), "t0_s": t0})
        ctx.run.set_result("vibration.statistics", dict(result))
        return {"static_noise": Estimate(result["static_noise_dps"], None),
                "vibration_rms": Estimate(result["vibration_rms_dps"], None),
                "vibration_bias_shift": Estimate(result["bias_shift_dph"], result["bias_shift_se_dph"]),
                "vibration_level": Estimate(result["level_grms"], result["level_sd_grms"])}


def _block_means(t: np.ndarray, rate: np.ndarray, block_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Means of consecutive blocks of ``block_s`` (whole blocks only) and their mid-times."""
    if t.size < 2:
        raise ValueError(f"{t.size} frames: too few for block means")
    per = max(1, int(round(block_s / float(np.median(np.diff(t))))))
    m = t.size // per
    if m < 1:
        raise ValueError(f"{t.size} frames shorter than one {block_s:g} s block")
    return (t[: m * per].reshape(m, per).mean(axis=1), rate[: m * per].reshape(m, per).mean(axis=1))


def vibration_statistics(t: np.ndarray, rate_dps: np.ndarray, level_grms: np.ndarray,
                         segment: np.ndarray, steady: np.ndarray, block_s: float = BLOCK_S) -> dict:
    """Static noise, vibration rms and bias shift from frames marked by segment and steadiness.

    The bias shift's standard error combines the vibration mean's (spread of ``block_s``
    block means) with the static line's at the vibration mid-time (least squares on the
    static block means); the blocks are treated as independent.
    """
    parts = [(segment == k) & steady for k in range(3)]
    for k, sel in enumerate(parts):
        if np.count_nonzero(sel) < 2:
            raise ValueError(f"segment {SEGMENT_NAMES[k]!r} has {np.count_nonzero(sel)} steady frames")
    static = [rate_dps[parts[0]], rate_dps[parts[2]]]
    static_var = sum(float(np.sum((x - x.mean()) ** 2)) for x in static) / (sum(x.size for x in static) - 2)
    vib = rate_dps[parts[1]]
    tb, mb = zip(*(_block_means(t[sel], rate_dps[sel], block_s) for sel in (parts[0], parts[2])))
    ts, ms = np.concatenate(tb), np.concatenate(mb)
    tv, mv = _block_means(t[parts[1]], vib, block_s)
    t_mid = float(np.mean(t[parts[1]]))
    design = np.column_stack([np.ones(ts.size), ts - t_mid])  # intercept = the line at t_mid
    coef, *_ = np.linalg.lstsq(design, ms, rcond=None)
    resid = ms - design @ coef
    dof = max(ts.size - 2, 1)
    cov = np.linalg.inv(design.T @ design) * float(resid @ resid) / dof
    shift = float(vib.mean() - coef[0])
    se = math.sqrt(float(np.var(mv, ddof=1)) / mv.size + float(cov[0, 0])) if mv.size > 1 else math.nan
    lv = level_grms[parts[1]]
    return {
        "static_noise_dps": math.sqrt(static_var),
        "vibration_rms_dps": float(vib.std(ddof=1)),
        "bias_shift_dph": shift * 3600.0, "bias_shift_se_dph": se * 3600.0,
        "static_line_dph": [float(coef[0]) * 3600.0, float(coef[1]) * 3600.0],
        "level_grms": float(lv.mean()), "level_sd_grms": float(lv.std(ddof=1)) if lv.size > 1 else 0.0,
        "segments": {name: {"t_start_s": float(t[segment == k][0]) if np.any(segment == k) else None,
                            "t_steady_s": float(t[parts[k]][0]), "t_end_s": float(t[parts[k]][-1]),
                            "frames": int(np.count_nonzero(segment == k)),
                            "steady_frames": int(np.count_nonzero(parts[k]))}
                     for k, name in enumerate(("static_before", "vibration", "static_after"))},
    }
