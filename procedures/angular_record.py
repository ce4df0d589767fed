"""Recording the angular vibration rig: the table's reference, the MHD sensor on a
digitizing DMM and the low-frequency sensor's frames, started together and read together.

Instruments (station names): ``angular_table`` (controller with a reference capture on its
own clock), ``dmm_mhd`` (34465A with the DIG option, its input the MHD sensor's output
voltage), ``lf_gyro`` (the LF sensor's frames on the FOG serial line).

Time stamps (bench-clock seconds, the instant of the start commands = ``t0``):

* reference: ``t0 +`` the controller's own sample time (the table clock is the reference);
* MHD: ``t0 + trigger delay + k·interval + aperture/2`` — the mid-aperture instant of each
  DMM reading on the DMM's nominal timebase;
* LF: ``t0 + (index + ½)/frame rate`` — the mid-instant of each frame interval (a frame
  carries the angle increment over its interval) on the sensor's nominal clock.

Clock errors and latencies are not corrected here: that needs the reference and is the
analysis' job (``bench.analysis.frf._timebase``, ``procedures.frf``).  On the simulated
station the start commands reach every instrument at the same simulated instant; on
hardware the commands' latencies would add start offsets of milliseconds that differ from
record to record: there the DMM and the LF unit must be started by the table controller's
trigger output (not modelled yet).

Every chunk is appended to the run's streams as it arrives (nothing acquired is lost).
"""

from __future__ import annotations

import logging
import math
import sys
from dataclasses import dataclass

import numpy as np

from bench.core.step import Context
from instruments.angular_table import AngularTableAbortedError
from instruments.fog_types import GyroFrames
from procedures.typed_instruments import angular_table, frame_gyro, multimeter

log = logging.getLogger(__name__)
#: status bit of a frame whose rate was clipped at the unit's full scale (docs/FOG_SERIAL.md)
STATUS_OVER_RANGE = 0x08

#: the DMM needs this much of each reading interval outside the aperture (instruments.multimeter)
APERTURE_FRACTION = 0.8
MAX_RATE_HZ = 10_000.0   # the 34465A DIG option digitises at up to 50 kS/s; 10 kS/s covers 1 kHz
DMM_RANGE_V = 1.0
STALL_MARGIN_S = 30.0
STREAM_UNITS = {
    "ref": ({"t_s": "s", "angle_deg": "deg", "rate_dps": "deg/s", "block": "1"},
            "table reference on the table clock (encoder angle, reference rate)"),
    "hf": ({"t_s": "s", "voltage_v": "V", "block": "1"},
           "MHD sensor output read by the digitizing DMM (mid-aperture times)"),
    "lf": ({"t_s": "s", "rate_dps": "deg/s", "counts": "pulses", "status": "1", "block": "1"},
           "LF sensor frames (mid-interval times, nominal frame clock)"),
}


@dataclass
class Record:
    """One acquisition: each sensor's samples on its own (nominal) time axis."""

    t_ref_s: np.ndarray
    ref_dps: np.ndarray
    angle_deg: np.ndarray
    t_hf_s: np.ndarray
    hf_v: np.ndarray
    t_lf_s: np.ndarray
    lf_dps: np.ndarray
    rate_hz: float
    frame_rate_hz: float
    aperture_s: float
    t0_s: float              # the start commands' instant: every clock starts here


def add_streams(ctx: Context, prefix: str) -> None:
    for key, (units, description) in STREAM_UNITS.items():
        dtypes: dict[str, type] = {"block": np.int32}
        if key == "lf":
            dtypes.update(counts=np.int64, status=np.int64)
        ctx.run.add_stream(f"{prefix}_{key}", units, description, dtypes=dtypes)


def aperture_for(interval_s: float, aperture_range_s: tuple[float, float]) -> float:
    """The DMM aperture for a reading interval: most of it (less noise, less aliasing),
    leaving the meter its per-reading overhead."""
    lo, hi = aperture_range_s
    return float(min(max(APERTURE_FRACTION * interval_s, lo), hi))


def record(ctx: Context, duration_s: float, rate_hz: float, frame_rate_hz: int, prefix: str,
           block: int, *, chunk_s: float = 1.0, progress=None, require_motion: bool = True) -> Record:
    """Acquire ``duration_s`` of all three signals (HF and reference at ``rate_hz``, LF at
    ``frame_rate_hz``), streaming each chunk into ``<prefix>_ref|hf|lf`` tagged ``block``.

    After every chunk the table's state is read: ABORT raises
    :class:`~instruments.angular_table.AngularTableAbortedError`, and with
    ``require_motion`` anything but RUN raises — a recording of a table that stopped is not
    the profile asked for.  LF frames over range (clipped at full scale), dropped or corrupt
    raise.  Whatever happens, every sample that reached the bench is stored first (the LF
    frames of a timeout, the DMM and reference samples still in the instruments)."""
    table, dmm, lf = angular_table(ctx), multimeter(ctx, "dmm_mhd"), frame_gyro(ctx, "lf_gyro")
    if not (0 < rate_hz <= MAX_RATE_HZ):
        raise ValueError(f"rate_hz {rate_hz!r} not in (0, {MAX_RATE_HZ:g}] Hz")
    interval = 1.0 / rate_hz
    n = max(2, int(round(duration_s * rate_hz)))
    n_lf = max(2, int(math.floor(duration_s * frame_rate_hz)))
    aperture = aperture_for(interval, dmm.aperture_range_s)
    plan = dmm.configure_timed_trace(n, interval, aperture_s=aperture, range_v=DMM_RANGE_V,
                                     trigger_delay_s=0.0)
    table.configure_reference(rate_hz, n)
    lf.configure(rate_hz=frame_rate_hz)
    t0 = ctx.clock.now()
    dmm.initiate()
    table.start_reference()
    lf.start()
    got: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {"ref": [], "hf": [], "lf": []}
    counts = {"ref": 0, "hf": 0, "lf": 0}
    ref_angle: list[np.ndarray] = []
    frames_per_chunk = max(1, int(round(chunk_s * frame_rate_hz)))

    def store_frames(frames: GyroFrames) -> None:
        t = t0 + (np.asarray(frames.index, dtype=float) + 0.5) / frame_rate_hz
        ctx.run.append(f"{prefix}_lf", t_s=t, rate_dps=frames.rate_dps, counts=frames.counts,
                       status=frames.status, block=np.full(t.size, block))
        got["lf"].append((t, frames.rate_dps))
        counts["lf"] += t.size

    def drain() -> tuple[int, int]:
        """Store whatever the DMM and the reference capture hold now."""
        volts = dmm.read_available()
        if volts.size:
            k = counts["hf"] + np.arange(volts.size)
            t = t0 + plan.trigger_delay_s + k * interval + aperture / 2
            ctx.run.append(f"{prefix}_hf", t_s=t, voltage_v=volts, block=np.full(t.size, block))
            got["hf"].append((t, volts))
            counts["hf"] += volts.size
        t_ref, angle, rate = table.read_reference()
        if t_ref.size:
            t = t0 + t_ref
            ctx.run.append(f"{prefix}_ref", t_s=t, angle_deg=angle, rate_dps=rate, block=np.full(t.size, block))
            got["ref"].append((t, rate))
            ref_angle.append(angle)
            counts["ref"] += t.size
        return volts.size, t_ref.size

    stalled = 0.0
    try:
        while counts["lf"] < n_lf or counts["hf"] < n or counts["ref"] < n:
            before = ctx.clock.now()
            if counts["lf"] < n_lf:
                want = min(frames_per_chunk, n_lf - counts["lf"])
                try:
                    frames = lf.read_frames(want, timeout_s=chunk_s * want / frames_per_chunk + STALL_MARGIN_S,
                                            wait=ctx.clock.sleep)
                except Exception as exc:
                    partial = getattr(exc, "frames", None)  # a timeout or broken line carries what arrived
                    if partial is not None and len(partial):
                        store_frames(partial)
                    raise
                store_frames(frames)
                if frames.dropped or frames.corrupt:
                    raise RuntimeError(f"lf_gyro line: {frames.dropped} frames dropped, {frames.corrupt} corrupt "
                                       "(the frames received are stored)")
                over = int(np.count_nonzero(np.asarray(frames.status) & STATUS_OVER_RANGE))
                if over:
                    raise RuntimeError(f"lf_gyro: {over} frames over range (clipped at the unit's full scale); "
                                       "lower the amplitude")
            else:
                ctx.clock.sleep(max(interval, min(chunk_s, (n - min(counts["hf"], counts["ref"])) * interval)))
            new_hf, new_ref = drain()
            state = table.state
            if state == "ABORT":
                raise AngularTableAbortedError(f"angular_table went to ABORT at {ctx.clock.now():.6g} s "
                                               "(interlock or emergency stop) during the recording; data so far stored")
            if require_motion and state != "RUN":
                raise RuntimeError(f"angular_table is {state} during the recording (expected RUN); data so far stored")
            stalled = stalled + (ctx.clock.now() - before) if not (new_hf or new_ref) else 0.0
            if stalled > duration_s + STALL_MARGIN_S:
                raise TimeoutError(f"angular rig: after {stalled:.3g} s waiting, {counts['hf']}/{n} MHD "
                                   f"readings, {counts['ref']}/{n} reference samples")
            if progress is not None:
                progress(min(counts["hf"], counts["ref"]) / n)
    except BaseException as exc:
        try:  # keep what the instruments still hold: the run says why it stopped, with its data
            drain()
        except Exception as drain_exc:
            exc.add_note(f"(could not read the remaining MHD/reference samples: {drain_exc})")
        raise
    finally:
        if lf.streaming:
            try:
                lf.stop()
            except Exception as stop_exc:
                if sys.exc_info()[0] is None:
                    raise
                log.warning("lf_gyro stop failed after an error: %s", stop_exc)
    if not np.all(np.isfinite(np.concatenate([v for _, v in got["hf"]]))):
        raise RuntimeError("dmm_mhd overload: the MHD output left the 1 V range")

    def cat(key: str) -> tuple[np.ndarray, np.ndarray]:
        return (np.concatenate([t for t, _ in got[key]]), np.concatenate([v for _, v in got[key]]))

    (t_ref, ref), (t_hf, hf), (t_lf, lf_dps) = cat("ref"), cat("hf"), cat("lf")
    return Record(t_ref[:n], ref[:n], np.concatenate(ref_angle)[:n], t_hf[:n], hf[:n], t_lf[:n_lf],
                  lf_dps[:n_lf], float(rate_hz), float(frame_rate_hz), aperture, t0)
