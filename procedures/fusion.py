"""Document B on the angular rig: record both sensors and the reference over a profile and
fuse them — every method of ``bench.analysis.fusion._analysis`` (each sensor alone, the
complementary filter, Document B's sequential adaptive-R Kalman filter, a fixed-R Kalman
filter, the complementary Kalman filter and its smoother) against the table's reference,
and the recommended one.

1. Sensor models: a stepped-sine FRF (``procedures.frf``, ``frf_points_per_decade``) and
   each sensor's fitted transfer function with its delay.
2. Static segment (``static_s``, table at rest): the MHD output offset (V) and the LF bias
   (°/s), subtracted from the profile's readings (the models have no DC terms).
3. The profile: a multi-tone demand (``tones_per_decade`` log-spaced tones from
   ``f_min_hz`` to ``f_max_hz``, each ``amplitude_dps``, phases spread so the peaks do not
   add up), ramped up, ``settle_s``, then ``duration_s`` recorded at ``rate_hz``.
4. Alignment: each sensor clock's rate error (the LF frames', the MHD DMM's) is estimated
   against the reference from the phase drift of the highest tone that sensor passes
   (``bench.analysis.frf._timebase``) and removed; each sensor's time axis is moved back by
   its fitted delay; the DMM aperture's droop is compensated (as the FRF divides it out);
   the LF frames and the reference are resampled onto the MHD readings' instants.
5. ``bench.analysis.fusion._analysis.analyze_fusion`` with the fitted models: every method
   tuned on the first ``tune_fraction`` of the aligned record and judged on the rest (amplitude
   and phase error per tone, RMS error, NIS); the recommended method picked by that judgement.

Streams: ``frf_*`` and ``fusion_ref|hf|lf`` (raw, as acquired; block 0 static, 1 profile)
and ``fusion_aligned`` (the evaluated part of the aligned series and every method's estimate).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from bench.analysis.frf import aperture_compensate, apply_time_base, estimate_time_base, resample
from bench.analysis.fusion import METHODS as ANALYSIS_METHODS
from bench.analysis.fusion import analyze_fusion
from bench.core.step import Context, FollowUp, Step, parameter
from bench.values import Estimate
from procedures.angular_record import MAX_RATE_HZ, add_streams, record
from procedures.common import check_ranges
from procedures.frf import LIMIT_USE, RUN_TIMEOUT_MARGIN_S, FrfParameters, measure_frf
from procedures.typed_instruments import angular_table

CLOCK_BLOCK_S = 5.0       # block length of the clock estimates
METRIC_SETTLE_S = 1.0     # the metrics skip the first second of the evaluated part (filter start-up)
METHODS = tuple(ANALYSIS_METHODS)


def estimate_column(method: str) -> str:
    """Column of ``fusion_aligned`` holding a method's rate estimate (deg/s)."""
    return {"hf": "hf_alone_dps", "lf": "lf_alone_dps"}.get(method, f"{method}_dps")

FUSION_PRODUCES = {
    **{f"rms_error_{k}": ("deg/s", f"RMS error of {m.label} vs the reference") for k, m in ANALYSIS_METHODS.items()},
    "rms_error_recommended": ("deg/s", "RMS error of the recommended method (picked on the judged part)"),
    "recommended_excess_sigma": ("1", "max over tones of the recommended method's excess amplitude error over the "
                                      "better sensor, in standard errors of the difference (≤ 2: no worse)"),
    "max_amplitude_error_fused": ("%", "largest |amplitude error| of the fused rate over the tones"),
    "max_phase_error_fused": ("deg", "largest |phase error| of the fused rate over the tones"),
    "fused_minus_best_sensor": ("%", "max over tones of |fused amplitude error| − the better single "
                                     "sensor's (≤ 0: never worse than the better sensor)"),
    "fused_excess_sigma": ("1", "max over tones of that excess in standard errors of the difference "
                                "(≤ 2: no worse within the estimates' noise)"),
    "lf_clock_error": ("ppm", "LF frame clock rate error (positive: fast) estimated against the reference"),
    "hf_clock_error": ("ppm", "MHD DMM sample clock rate error (positive: fast) estimated against the reference"),
}


@dataclass
class FusionParameters:
    f_min_hz: float = parameter(0.1, "lowest tone (and FRF frequency), Hz")
    f_max_hz: float = parameter(1000.0, "highest tone (and FRF frequency), Hz")
    tones_per_decade: int = parameter(2, "profile tones per decade, log-spaced")
    amplitude_dps: float = parameter(2.0, "rate amplitude of each tone, deg/s (all scaled down "
                                          "together to half of the table's limits where needed)")
    duration_s: float = parameter(60.0, "profile record, s")
    static_s: float = parameter(5.0, "static segment for the MHD offset and LF bias, s")
    settle_s: float = parameter(2.0, "after the profile runs, before recording, s")
    ramp_s: float = parameter(1.0, "table ramp time, s")
    rate_hz: float = parameter(10000.0, "MHD and reference sample rate, Hz")
    frame_rate_hz: int = parameter(4000, "LF sensor frame rate, Hz")
    frf_points_per_decade: int = parameter(2, "the sensor models' FRF: frequencies per decade")
    frf_amplitude_dps: float = parameter(5.0, "the sensor models' FRF: tone amplitude, deg/s")
    tune_fraction: float = parameter(0.4, "first part of the profile record that tunes Document B's "
                                          "filter (0: its default settings, no tuning)")

    def validate(self) -> None:
        check_ranges(asdict(self), {
            "f_min_hz": (0.1, 1000), "f_max_hz": (0.1, 1000), "tones_per_decade": (1, 3),
            "amplitude_dps": (0.01, 500), "duration_s": (1, 3600), "static_s": (0.5, 600),
            "settle_s": (0, 600), "ramp_s": (0.01, 60), "rate_hz": (1000, MAX_RATE_HZ),
            "frame_rate_hz": (100, 4608), "frf_points_per_decade": (1, 20),
            "frf_amplitude_dps": (0.01, 500), "tune_fraction": (0, 0.7)},
            integers=("tones_per_decade", "frame_rate_hz", "frf_points_per_decade"))
        if not self.f_min_hz < self.f_max_hz:
            raise ValueError(f"f_min_hz = {self.f_min_hz} must be < f_max_hz = {self.f_max_hz}")
        if self.f_max_hz >= self.rate_hz / 4:
            raise ValueError(f"f_max_hz = {self.f_max_hz} must be below rate_hz/4 = {self.rate_hz / 4:g} Hz")
        if 0 < self.tune_fraction < 0.1:
            raise ValueError(f"tune_fraction = {self.tune_fraction} must be 0 (no tuning) or in 0.1..0.7")
        evaluated = self.duration_s * (1 - self.tune_fraction) - METRIC_SETTLE_S
        if evaluated < 3 / self.f_min_hz:
            raise ValueError(f"duration_s = {self.duration_s} must leave 3 periods of f_min_hz "
                             f"(≥ {3 / self.f_min_hz:g} s) after the tuning part ({self.tune_fraction:g}) "
                             f"and the metrics' {METRIC_SETTLE_S:g}-s settling")
        self.frf().validate()  # the models come from this FRF: refuse a grid that cannot be fitted
        if len(self.tones_hz()) > 16:
            raise ValueError(f"{len(self.tones_hz())} tones; the table synthesises at most 16")

    def tones_hz(self) -> np.ndarray:
        decades = math.log10(self.f_max_hz / self.f_min_hz)
        n = max(2, int(round(decades * self.tones_per_decade)) + 1)
        return self.f_min_hz * (self.f_max_hz / self.f_min_hz) ** (np.arange(n) / (n - 1))

    def frf(self) -> FrfParameters:
        return FrfParameters(f_min_hz=self.f_min_hz, f_max_hz=self.f_max_hz,
                             points_per_decade=self.frf_points_per_decade,
                             amplitude_dps=self.frf_amplitude_dps, frame_rate_hz=self.frame_rate_hz)


def tone_demand(limits, tones_hz: np.ndarray, amplitude_dps: float) -> list[tuple[float, float, float]]:
    """Equal-amplitude tones, scaled down together if the sums of their angle, rate or
    acceleration amplitudes would pass ``LIMIT_USE`` of the table's limits; Schroeder phases
    (φₖ = −πk²/n) keep the peak of the sum low."""
    w = 2 * np.pi * tones_hz
    use = [np.sum(amplitude_dps / w) / limits.angle_deg, tones_hz.size * amplitude_dps / limits.rate_dps,
           np.sum(amplitude_dps * w) / limits.accel_dps2]
    scale = min(1.0, LIMIT_USE / max(use))
    n = tones_hz.size
    phases = np.degrees(np.mod(-np.pi * np.arange(n) ** 2 / n, 2 * np.pi))
    return [(float(amplitude_dps * scale), float(f), float(ph)) for f, ph in zip(tones_hz, phases)]


def _clock(rec, t_y, y, f_hz: float, span_s: float) -> tuple[np.ndarray, dict]:
    """``t_y`` on the table clock: the rate error estimated from the tone at ``f_hz`` in
    blocks of ≥ 10 periods (short enough that a 100-ppm clock drifts < ¼ period per
    block) and removed; left as it is, and said so, when the record holds < 3 blocks."""
    block = max(10.0 / f_hz, min(CLOCK_BLOCK_S, span_s / 4, 0.25 / (f_hz * 1e-4)))
    if span_s < 3 * block:
        return t_y, {"frequency_hz": f_hz, "block_s": block, "rate_ppm": None, "rate_std_ppm": None,
                     "note": f"record {span_s:.3g} s too short for 3 blocks of {block:.3g} s: clock not corrected"}
    tb = estimate_time_base(rec.t_ref_s, rec.ref_dps, t_y, y, f_hz, block)
    return apply_time_base(t_y, tb, epoch_s=rec.t0_s), {"frequency_hz": f_hz, **tb.to_dict()}


def align(rec, fits: dict, tones_hz: np.ndarray, hf_offset_v: float, lf_bias_dps: float) -> dict:
    """Put the LF frames and the reference on the MHD readings' instants (module docstring)."""
    lf_model, hf_model = fits["lf"].model, fits["hf"].model
    passed = tones_hz[np.abs(lf_model.response(tones_hz)) >= 0.5 * abs(lf_model.gain)]
    f_lf = float(passed.max()) if passed.size else float(tones_hz.min())
    passed = tones_hz[np.abs(hf_model.response(tones_hz)) >= 0.5 * abs(hf_model.gain)]
    f_hf = float(passed.max()) if passed.size else float(tones_hz.max())
    span = float(min(rec.t_lf_s[-1], rec.t_hf_s[-1], rec.t_ref_s[-1]) - max(rec.t_lf_s[0], rec.t_hf_s[0],
                                                                           rec.t_ref_s[0]))
    t_lf, clock_lf = _clock(rec, rec.t_lf_s, rec.lf_dps - lf_bias_dps, f_lf, span)
    t_hf, clock_hf = _clock(rec, rec.t_hf_s, rec.hf_v - hf_offset_v, f_hf, span)
    t_lf = t_lf - fits["lf"].delay_s
    t_hf = t_hf - fits["hf"].delay_s
    # the DMM aperture's droop (−1 % at 1 kHz with an 80-µs aperture) taken out, as in the FRF
    hf_v = aperture_compensate(rec.hf_v - hf_offset_v, rec.aperture_s, 1.0 / rec.rate_hz)
    lo, hi = max(t_lf[0], rec.t_ref_s[0]), min(t_lf[-1], rec.t_ref_s[-1])
    keep = (t_hf >= lo) & (t_hf <= hi)
    t = t_hf[keep]
    return {"t_s": t, "hf_v": hf_v[keep],
            "lf_dps": resample(t_lf, rec.lf_dps - lf_bias_dps, t),
            "ref_dps": resample(rec.t_ref_s, rec.ref_dps, t),
            "clock": clock_lf, "hf_clock": clock_hf,
            "hf_delay_s": fits["hf"].delay_s, "lf_delay_s": fits["lf"].delay_s}


class FusionTest(Step[FusionParameters]):
    """Angular rig: Document B's sequential Kalman fusion vs each sensor, fixed-R KF,
    complementary.

    A quick FRF for the sensor models, a static segment, a multi-tone profile recorded with
    the table reference; clocks, delays and the DMM aperture corrected; the filter tuned on
    the first part, judged on the rest.  The report is attached to every passed run.
    """

    name = "fusion"
    requires = ("angular_table", "dmm_mhd", "lf_gyro")
    kinds = ("angular",)
    produces = FUSION_PRODUCES

    Parameters = FusionParameters
    follow_up = FollowUp("angular", on_request=False,
                         summary="the rig's report (FRFs, tuning, errors per method) attached to the run")

    def duration_s(self) -> float:
        p = self.p
        frf = p.frf()
        return (sum(frf.dwell_s(f) + frf.settle_s + 2 * frf.ramp_s for f in frf.frequencies_hz())
                + p.static_s + p.duration_s + p.settle_s + 2 * p.ramp_s)

    def run(self, ctx: Context) -> dict[str, Estimate]:
        p = self.p
        table = angular_table(ctx)
        total = self.duration_s()
        frf_total = total - (p.static_s + p.duration_s + p.settle_s + 2 * p.ramp_s)
        frf = measure_frf(ctx, p.frf(), prefix="frf",
                          progress=lambda d, t, m="": ctx.progress(d * frf_total / t, total, m))
        fits = frf["fits"]
        add_streams(ctx, "fusion")
        table.stop()
        ctx.run.event(ctx.clock.now(), "static", "table at rest: MHD offset and LF bias")
        static = record(ctx, p.static_s, p.rate_hz, p.frame_rate_hz, "fusion", 0, require_motion=False,
                        progress=lambda x: ctx.progress(frf_total + x * p.static_s, total, "static"))
        hf_offset, lf_bias = float(np.mean(static.hf_v)), float(np.mean(static.lf_dps))
        tones = p.tones_hz()
        demand = tone_demand(table.limits(), tones, p.amplitude_dps)
        table.ramp_time_s = p.ramp_s
        table.set_tones(demand)
        table.start()
        table.wait_running(ctx.clock.sleep, timeout_s=p.ramp_s + RUN_TIMEOUT_MARGIN_S)
        ctx.clock.sleep(p.settle_s)
        ctx.run.event(ctx.clock.now(), "profile", f"{tones.size} tones {tones[0]:.3g}-{tones[-1]:.4g} Hz at "
                      f"{demand[0][0]:.3g} deg/s each", tones_hz=[float(f) for f in tones],
                      amplitude_dps=demand[0][0])
        base = frf_total + p.static_s + p.settle_s + p.ramp_s
        rec = record(ctx, p.duration_s, p.rate_hz, p.frame_rate_hz, "fusion", 1,
                     progress=lambda x: ctx.progress(base + x * p.duration_s, total, "profile"))
        table.stop()
        aligned = align(rec, fits, tones, hf_offset, lf_bias)
        ctx.run.set_result("fusion.alignment", {k: v for k, v in aligned.items() if not k.endswith(("_v", "_dps"))
                                                and k != "t_s"}
                           | {"hf_offset_v": hf_offset, "lf_bias_dps": lf_bias})
        analysis = analyze_fusion(aligned["t_s"], aligned["hf_v"], aligned["lf_dps"], aligned["ref_dps"], p.rate_hz,
                                  hf_model=fits["hf"].model, lf_model=fits["lf"].model, tones_hz=tones,
                                  settle_s=METRIC_SETTLE_S, tune_fraction=p.tune_fraction)
        if analysis.tuning is not None:
            ctx.run.set_result("fusion.tuning", analysis.tuning.to_dict())
        ctx.run.set_result("fusion.analysis", analysis.to_dict())
        judged = slice(analysis.tune_samples, None)
        aligned = {**aligned, **{k: aligned[k][judged] for k in ("t_s", "hf_v", "lf_dps", "ref_dps")}}
        ctx.run.add_stream("fusion_aligned", {"t_s": "s", "hf_v": "V", "lf_dps": "deg/s", "ref_dps": "deg/s",
                                              **{estimate_column(m): "deg/s" for m in METHODS}},
                           "aligned record on the MHD instants (after the tuning part) and every method's estimate")
        ctx.run.append("fusion_aligned", t_s=aligned["t_s"], hf_v=aligned["hf_v"], lf_dps=aligned["lf_dps"],
                       ref_dps=aligned["ref_dps"],
                       **{estimate_column(m): analysis.estimates[m][judged] for m in METHODS})
        return summarize(analysis, aligned["clock"], aligned["hf_clock"])


def summarize(analysis, clock: dict, hf_clock: dict | None = None) -> dict[str, Estimate]:
    j = analysis.judgement
    out = {f"rms_error_{m}": Estimate(j.rms_error[m], None) for m in METHODS}
    out["rms_error_recommended"] = Estimate(j.rms_error[analysis.recommended], None)
    out["recommended_excess_sigma"] = Estimate(j.worst_excess_sigma(analysis.recommended), None)
    out["max_amplitude_error_fused"] = Estimate(float(np.max(np.abs(j.amplitude_error_pct["fused"]))), None)
    out["max_phase_error_fused"] = Estimate(float(np.max(np.abs(j.phase_error_deg["fused"]))), None)
    excess, sd = j.excess_pct["fused"], j.excess_std_pct["fused"]
    worst = int(np.argmax(excess))
    out["fused_minus_best_sensor"] = Estimate(float(excess[worst]), float(sd[worst]))
    out["fused_excess_sigma"] = Estimate(j.worst_excess_sigma("fused"), None)
    # stamps are corrected by rate_ppm: a clock fast by δ needs −δ
    if clock["rate_ppm"] is not None:
        out["lf_clock_error"] = Estimate(-clock["rate_ppm"], clock["rate_std_ppm"])
    if hf_clock is not None and hf_clock["rate_ppm"] is not None:
        out["hf_clock_error"] = Estimate(-hf_clock["rate_ppm"], hf_clock["rate_std_ppm"])
    return out
