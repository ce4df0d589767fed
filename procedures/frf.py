"""Frequency response of the angular rig's two rate sensors against the table reference
(Document B, step 1): stepped sine over a log grid.

First a **clock dwell** (``CLOCK_DWELL_S`` at ``CLOCK_HZ``): the rate errors of the MHD
DMM's and the LF unit's sample clocks against the table's are estimated from the tone's
phase drift and removed from every later dwell's time stamps (each clock starts with the
table's at a record's start), so the FRF phases and the fitted delays hold no clock drift.

Then, for each frequency of the grid (``points_per_decade`` per decade from ``f_min_hz`` to
``f_max_hz``, both ends included):

1. demand one tone of rate amplitude ``amplitude_dps`` (reduced where the table's angle or
   angular-acceleration limit would be exceeded — at most ``LIMIT_USE`` of the limit),
   ramp up and wait until the controller reports RUN, then ``settle_s`` more (at least one
   period) for the sensors' transients;
2. record the reference, the MHD (DMM) and the LF frames together for ``max(min_dwell_s,
   min_periods / f)`` at ``rate_hz = clip(RATE_PER_HZ·f, MIN_RATE_HZ, MAX_RATE_HZ)``
   (``procedures.angular_record``);
3. least-squares sine fits at f (with its 2nd and 3rd harmonics) of each signal over the
   same whole periods → complex ratio sensor/reference with its standard uncertainty
   (``bench.analysis.frf._stepped_sine``); the known averaging of each sample (the DMM aperture, the
   frame interval: sinc(f·T)) is divided out; LF points only below 80 % of the frames'
   Nyquist frequency.

Then each sensor's transfer function is fitted to its FRF (high-pass for the MHD, low-pass
for the LF sensor; order 1 or 2 by fit quality; a pure delay for latency and time-stamp
offsets), and the points, the fits and their residuals are stored.  The table is
stopped between frequencies and at the end.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from bench.analysis.frf import apply_time_base, component_std, estimate_time_base, frf_point
from bench.analysis.fusion import fit_transfer_function
from bench.core.step import Context, FollowUp, Progress, Step, parameter
from bench.values import Estimate
from procedures.angular_record import MAX_RATE_HZ, add_streams, record
from procedures.common import check_ranges
from procedures.typed_instruments import angular_table

LIMIT_USE = 0.5          # a dwell uses at most half of any table limit
MIN_RATE_HZ = 1000.0
RATE_PER_HZ = 40.0       # samples per period at the top of the band (10 kHz at 250 Hz and above)
RUN_TIMEOUT_MARGIN_S = 30.0
MIN_POINTS = 5           # a first-order model with a delay has 3 parameters; 5 points leave it 7 dof
LF_NYQUIST_USE = 0.8     # LF points only below 80 % of the frames' Nyquist frequency
CLOCK_HZ = 10.0          # the clock dwell's tone: both sensors pass it well
CLOCK_DWELL_S = 20.0     # ten blocks of CLOCK_BLOCK_PERIODS periods at 10 Hz
CLOCK_BLOCK_PERIODS = 20

FRF_PRODUCES = {
    "hf_corner": ("Hz", "MHD sensor: fitted high-pass corner"),
    "hf_gain": ("V/(deg/s)", "MHD sensor: fitted passband sensitivity"),
    "hf_delay": ("s", "MHD chain: fitted pure delay (latency + time-stamp offset)"),
    "lf_corner": ("Hz", "LF sensor: fitted low-pass corner"),
    "lf_gain": ("1", "LF sensor: fitted passband gain (deg/s per deg/s)"),
    "lf_delay": ("s", "LF chain: fitted pure delay (latency + time-stamp offset)"),
    "hf_fit_misfit": ("1", "MHD fit: relative RMS misfit of the fitted model to the FRF"),
    "lf_fit_misfit": ("1", "LF fit: relative RMS misfit of the fitted model to the FRF"),
    "hf_clock_error": ("ppm", "MHD DMM sample clock rate error against the table (positive: fast)"),
    "lf_clock_error": ("ppm", "LF frame clock rate error against the table (positive: fast)"),
}


@dataclass
class FrfParameters:
    f_min_hz: float = parameter(0.1, "lowest frequency of the grid, Hz")
    f_max_hz: float = parameter(1000.0, "highest frequency of the grid, Hz")
    points_per_decade: int = parameter(3, "frequencies per decade")
    amplitude_dps: float = parameter(5.0, "rate amplitude of each tone, deg/s (reduced to half of "
                                          "the table's limits where needed)")
    min_periods: float = parameter(5.0, "each dwell records at least this many periods")
    min_dwell_s: float = parameter(2.0, "and at least this long, s")
    settle_s: float = parameter(0.5, "after the tone runs, before recording, s (at least one period)")
    ramp_s: float = parameter(0.5, "table ramp time, s")
    frame_rate_hz: int = parameter(4000, "LF sensor frame rate, Hz")

    def validate(self) -> None:
        check_ranges(asdict(self), {
            "f_min_hz": (0.1, 1000), "f_max_hz": (0.1, 1000), "points_per_decade": (1, 20),
            "amplitude_dps": (0.01, 500), "min_periods": (2, 1000), "min_dwell_s": (0.1, 600),
            "settle_s": (0, 600), "ramp_s": (0.01, 60), "frame_rate_hz": (100, 4608)},
            integers=("points_per_decade", "frame_rate_hz"))
        if not self.f_min_hz < self.f_max_hz:
            raise ValueError(f"f_min_hz = {self.f_min_hz} must be < f_max_hz = {self.f_max_hz}")
        f = self.frequencies_hz()
        n_lf = int(np.count_nonzero(f < self.lf_max_hz()))
        if f.size < MIN_POINTS or n_lf < MIN_POINTS:
            raise ValueError(f"{f.size} frequencies from f_min_hz = {self.f_min_hz} to f_max_hz = {self.f_max_hz} at "
                             f"points_per_decade = {self.points_per_decade}, {n_lf} of them below the LF frames' "
                             f"usable {self.lf_max_hz():g} Hz (frame_rate_hz = {self.frame_rate_hz}); at least "
                             f"{MIN_POINTS} of each are needed to fit a transfer function with a delay")

    def frequencies_hz(self) -> np.ndarray:
        decades = math.log10(self.f_max_hz / self.f_min_hz)
        n = max(2, int(math.ceil(decades * self.points_per_decade)) + 1)
        return self.f_min_hz * (self.f_max_hz / self.f_min_hz) ** (np.arange(n) / (n - 1))

    def lf_max_hz(self) -> float:
        """LF points are measured only below this (80 % of the frames' Nyquist frequency)."""
        return LF_NYQUIST_USE * self.frame_rate_hz / 2

    def dwell_s(self, f_hz: float) -> float:
        return max(self.min_dwell_s, self.min_periods / f_hz)

    def rate_hz(self, f_hz: float) -> float:
        return float(min(MAX_RATE_HZ, max(MIN_RATE_HZ, RATE_PER_HZ * f_hz)))


def safe_amplitude_dps(limits, f_hz: float, wanted_dps: float) -> float:
    """The wanted rate amplitude, reduced to ``LIMIT_USE`` of the table's angle, rate and
    angular-acceleration limits at ``f_hz`` (a sine of rate amplitude A has angle amplitude
    A/2πf and acceleration amplitude A·2πf)."""
    w = 2 * math.pi * f_hz
    return min(wanted_dps, LIMIT_USE * limits.angle_deg * w, LIMIT_USE * limits.rate_dps,
               LIMIT_USE * limits.accel_dps2 / w)


def _dwell(ctx: Context, p: FrfParameters, table, limits, f: float, block: int, label: str, duration_s: float,
           rate_hz: float, prefix: str, progress) -> tuple:
    """One tone: ramp up, settle, record everything, stop (the ramp down is awaited later)."""
    amp = safe_amplitude_dps(limits, f, p.amplitude_dps)
    table.set_tones([(amp, f, 0.0)])
    table.start()
    table.wait_running(ctx.clock.sleep, timeout_s=p.ramp_s + RUN_TIMEOUT_MARGIN_S + 2.0 / f)
    ctx.clock.sleep(max(p.settle_s, 1.0 / f))
    ctx.run.event(ctx.clock.now(), label, f"{f:.4g} Hz at {amp:.4g} deg/s", block=block, freq_hz=f,
                  amplitude_dps=amp)
    rec = record(ctx, duration_s, rate_hz, p.frame_rate_hz, prefix, block, progress=progress)
    table.stop()
    return rec, amp


def clock_frequency_hz(p: FrfParameters) -> float:
    """The clock dwell's tone: CLOCK_HZ, kept inside the grid and well below the LF limit."""
    return float(min(max(CLOCK_HZ, p.f_min_hz), p.f_max_hz, 0.5 * p.lf_max_hz()))


def measure_clocks(rec, f_hz: float) -> dict:
    """Rate error of the MHD DMM's and the LF unit's sample clocks against the table's, from
    the tone's phase drift in blocks of ``CLOCK_BLOCK_PERIODS`` periods (``bench.analysis.frf._timebase``)."""
    block = CLOCK_BLOCK_PERIODS / f_hz
    return {"hf": estimate_time_base(rec.t_ref_s, rec.ref_dps, rec.t_hf_s, rec.hf_v, f_hz, block),
            "lf": estimate_time_base(rec.t_ref_s, rec.ref_dps, rec.t_lf_s, rec.lf_dps, f_hz, block)}


def on_reference_clock(rec, clocks: dict | None):
    """The record's MHD and LF time stamps mapped onto the table clock (rate errors removed;
    each clock agrees with the table's at the record's start, where all three started)."""
    if not clocks:
        return rec.t_hf_s, rec.t_lf_s
    return (apply_time_base(rec.t_hf_s, clocks["hf"], epoch_s=rec.t0_s),
            apply_time_base(rec.t_lf_s, clocks["lf"], epoch_s=rec.t0_s))


def measure_frf(ctx: Context, p: FrfParameters, *, prefix: str = "frf", progress: Progress | None = None) -> dict:
    """Stepped-sine FRF of both sensors after a clock dwell; returns the clocks, points and
    fits (also stored in the run)."""
    table = angular_table(ctx)
    limits = table.limits()
    freqs = p.frequencies_hz()
    f_clk = clock_frequency_hz(p)
    total = CLOCK_DWELL_S + sum(p.dwell_s(f) + p.settle_s + 2 * p.ramp_s for f in freqs)
    add_streams(ctx, prefix)
    table.stop()
    table.ramp_time_s = p.ramp_s
    rec, _ = _dwell(ctx, p, table, limits, f_clk, -1, "clock dwell", CLOCK_DWELL_S, MIN_RATE_HZ, prefix,
                    lambda x: progress(x * CLOCK_DWELL_S, total, "clocks") if progress else None)
    clocks = measure_clocks(rec, f_clk)
    ctx.run.set_result(f"{prefix}.clocks", {k: v.to_dict() for k, v in clocks.items()})
    table.wait_idle(ctx.clock.sleep, timeout_s=p.ramp_s + RUN_TIMEOUT_MARGIN_S + 2.0 / f_clk)
    done = CLOCK_DWELL_S
    points: dict[str, list[Any]] = {"freq_hz": [], "amplitude_dps": [], "hf": [], "lf": []}
    for i, f in enumerate(freqs):
        dwell = p.dwell_s(float(f))

        def step_progress(fraction, base=done, dwell=dwell, f=f):
            if progress is not None:
                progress(base + fraction * dwell, total, f"FRF {f:.3g} Hz")

        rec, amp = _dwell(ctx, p, table, limits, float(f), i, "dwell", dwell, p.rate_hz(float(f)), prefix,
                          step_progress)
        t_hf, t_lf = on_reference_clock(rec, clocks)
        hf = frf_point(rec.t_ref_s, rec.ref_dps, t_hf, rec.hf_v, float(f))
        points["freq_hz"].append(float(f))
        points["amplitude_dps"].append(amp)
        points["hf"].append(corrected_point(hf, rec.aperture_s))
        if f < p.lf_max_hz():
            lf = frf_point(rec.t_ref_s, rec.ref_dps, t_lf, rec.lf_dps, float(f))
            points["lf"].append(corrected_point(lf, 1.0 / p.frame_rate_hz))
        else:  # too close to the frames' Nyquist frequency to be measured
            points["lf"].append(None)
        ctx.run.set_result(f"{prefix}.points", points)
        done += dwell + p.settle_s + 2 * p.ramp_s
        table.wait_idle(ctx.clock.sleep, timeout_s=p.ramp_s + RUN_TIMEOUT_MARGIN_S + 2.0 / f)
    fits = fit_sensors(points)
    ctx.run.set_result(f"{prefix}.fits", {k: v.to_dict() for k, v in fits.items()})
    return {"points": points, "fits": fits, "clocks": clocks}


def response_of(points: dict, sensor: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Frequencies, complex responses and standard uncertainties (per real/imaginary part)
    of one sensor's measured points (the frequencies it could be measured at)."""
    rows = [(f, r) for f, r in zip(points["freq_hz"], points[sensor]) if r is not None]
    f = np.array([fk for fk, _ in rows], dtype=float)
    h = np.array([r["mag"] * np.exp(1j * math.radians(r["phase_deg"])) for _, r in rows])
    sd = component_std([r["mag"] for _, r in rows], [r["mag_std"] for _, r in rows],
                       [r["phase_std_deg"] for _, r in rows])
    return f, h, sd


def fit_sensors(points: dict) -> dict:
    """High-pass + delay for the MHD, low-pass + delay for the LF sensor, order by fit
    quality, each point weighted by its uncertainty."""
    out = {}
    for sensor, kind in (("hf", "highpass"), ("lf", "lowpass")):
        f, h, sd = response_of(points, sensor)
        max_order = 2 if f.size >= 6 else 1  # order 2 with a delay has 5 parameters
        out[sensor] = fit_transfer_function(f, h, kind, max_order=max_order, fit_delay=True, weights=1.0 / sd)
    return out


def sample_average_response(f_hz, window_s: float) -> np.ndarray:
    """Response of a sample that is the mean over ``window_s`` centred on its time stamp
    (DMM aperture, frame interval): sinc(f·T), real — divided out of the measured FRF so the
    fitted model is the sensor's, not the sampling's."""
    return np.sinc(np.asarray(f_hz, dtype=float) * window_s)


def corrected_point(point, window_s: float) -> dict:
    d = point.to_dict()
    droop = float(sample_average_response(point.freq_hz, window_s))
    d.update(mag=d["mag"] / droop, mag_std=d["mag_std"] / droop, sample_average=droop)
    return d


class FrfTest(Step[FrfParameters]):
    """Angular rig: frequency response of the MHD and LF rate sensors (stepped sine) and their
    models.

    A clock dwell, then one tone per frequency; sine fits against the table reference; a
    high-pass (MHD) and a low-pass (LF) transfer function with a delay fitted to each FRF.
    The report (FRFs with fits) is attached to every passed run.
    """

    name = "frf"
    requires = ("angular_table", "dmm_mhd", "lf_gyro")
    kinds = ("angular",)
    produces = FRF_PRODUCES

    Parameters = FrfParameters
    follow_up = FollowUp("angular", on_request=False,
                         summary="the rig's report (FRFs, fits) attached to the run")

    def duration_s(self) -> float:
        p = self.p
        return CLOCK_DWELL_S + sum(p.dwell_s(f) + p.settle_s + 2 * p.ramp_s for f in p.frequencies_hz())

    def run(self, ctx: Context) -> dict[str, Estimate]:
        result = measure_frf(ctx, self.p, progress=ctx.progress)
        hf, lf = result["fits"]["hf"], result["fits"]["lf"]
        clocks = result["clocks"]
        return {"hf_corner": Estimate(hf.corner_hz, None), "hf_gain": Estimate(hf.gain, None),
                "hf_delay": Estimate(hf.delay_s, None), "lf_corner": Estimate(lf.corner_hz, None),
                "lf_gain": Estimate(lf.gain, None), "lf_delay": Estimate(lf.delay_s, None),
                "hf_fit_misfit": Estimate(hf.residual, None), "lf_fit_misfit": Estimate(lf.residual, None),
                # stamps are corrected by rate_ppm: a sample clock running fast by δ needs −δ
                "hf_clock_error": Estimate(-clocks["hf"].rate_ppm, clocks["hf"].rate_std_ppm),
                "lf_clock_error": Estimate(-clocks["lf"].rate_ppm, clocks["lf"].rate_std_ppm)}
