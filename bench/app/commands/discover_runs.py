"""Stored runs as discovery records: which stream of which procedure, mapped onto which columns.

A run is mapped by the *streams* it holds (an acceptance run holds the streams of the steps it
ran), each described by a :class:`StreamMap`:

================  ==============  ==============================================================
stream            sensor          mapping
================  ==============  ==============================================================
``output``        accelerometer   ``startup``: t_s (s from power-on, t ≥ 0 kept) → t and t_on,
                                  acceleration_g → y, the ``temperature`` stream interpolated
                                  → temp; input = +1 g (Document A holds the axis vertical)
``noise``         accelerometer   ``accelerometer_noise``: voltage_v / its mean → y in g (the
                                  procedure's own normalisation: level, IA up, so the mean is
                                  1 g; a scale-factor error of ~1e-3 scales the structure by as
                                  much), input = +1 g, t_on from the supply events
``gyro_startup``  gyro            ``gyro_startup``: t_s (from power-on) → t and t_on, rate_dps →
                                  y, temperature_c → temp; frames flagged READY only
``gyro_static``   gyro            ``gyro_noise`` (and acceptance): rate_dps → y, temperature_c →
                                  temp, t_on from the gyro supply events; READY frames only
``gyro_frames``   gyro            ``vibration`` (the stream with ``level_grms``): rate_dps → y,
                                  level_grms → vib, temperature_c → temp, t_on from the events
``thermal_ramp``  accelerometer   ``thermal_ramp`` (the stream with ``output_g``): output_g → y,
                                  unit_c (its AD590 on the case) → temp, input = 0 g (IA
                                  horizontal), t_on from the supply events
``thermal_ramp``  gyro            ``gyro_thermal_ramp`` (the stream with ``rate_dps``): rate_dps →
                                  y, temperature_c → temp, READY frames only, t_on from the events
``record``        as imported     ``bench runs import`` (``<kind>_record``): output → y,
                                  temperature_c → temp, applied → input; t_s counts from
                                  power-on for a ``startup`` record; the sensor is the one the
                                  import named (``--sensor``), the output converted from its
                                  unit to deg/s or g
================  ==============  ==============================================================

Time since power-on for streams on the bench clock comes from the run's supply events
(``supply_on``/``supply_off`` for the accelerometer, ``gyro_supply_on``/``gyro_supply_off`` for
the gyro): the last switch-on before the stream's first sample that no switch-off followed.
A record with gaps (dropped frames, a reading lost) is cut to its longest unbroken stretch
(every interval within 5 % of the median) when that holds at least 90 % of the samples; the
label says so. Otherwise ValueError naming the gap.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from bench.app.commands.common import require_store, resolve_run_id
from bench.app.records import to_sensor_unit
from bench.core.store import RunStore
from bench.discovery.data import Record

STATUS_READY = 0x01  # docs/FOG_SERIAL.md: powered and booted, the output is valid
#: fraction of the samples the longest unbroken stretch must hold to stand for the record
MIN_STRETCH = 0.9


@dataclass(frozen=True)
class StreamMap:
    """How one stored stream becomes a :class:`Record`."""

    stream: str
    sensor: str
    y: str
    procedures: str  # who writes it (for the error messages)
    needs: tuple[str, ...] = ()  # further columns the stream must have to be this kind
    from_power_on: bool = False  # t_s already counts from power-on
    applied_input: float | None = None  # a constant applied input (g)
    temp: tuple[str, str] | None = None  # (stream, column) of the temperature
    vib: str | None = None  # column → vib
    normalise_mean: bool = False  # y / mean(y): volts to g for a level, IA-up record
    ready_only: bool = False  # keep frames whose status has the READY bit
    power_events: tuple[str, str] | None = None  # (on, off) event kinds for t_on
    input_col: str | None = None  # column → input (the applied input, when recorded)


STREAM_MAPS: tuple[StreamMap, ...] = (
    StreamMap("output", "accelerometer", "acceleration_g", "startup", from_power_on=True,
              applied_input=1.0, temp=("temperature", "temperature_c")),
    StreamMap("gyro_startup", "gyro", "rate_dps", "gyro_startup", from_power_on=True,
              temp=("gyro_startup", "temperature_c"), ready_only=True),
    StreamMap("gyro_static", "gyro", "rate_dps", "gyro_noise, acceptance",
              temp=("gyro_static", "temperature_c"), ready_only=True,
              power_events=("gyro_supply_on", "gyro_supply_off")),
    StreamMap("gyro_frames", "gyro", "rate_dps", "vibration", needs=("level_grms",),
              temp=("gyro_frames", "temperature_c"), vib="level_grms", ready_only=True,
              power_events=("gyro_supply_on", "gyro_supply_off")),
    StreamMap("noise", "accelerometer", "voltage_v", "accelerometer_noise", applied_input=1.0,
              normalise_mean=True, power_events=("supply_on", "supply_off")),
    StreamMap("thermal_ramp", "accelerometer", "output_g", "thermal_ramp", needs=("unit_c",),
              applied_input=0.0, temp=("thermal_ramp", "unit_c"), power_events=("supply_on", "supply_off")),
    StreamMap("thermal_ramp", "gyro", "rate_dps", "gyro_thermal_ramp", needs=("temperature_c",),
              temp=("thermal_ramp", "temperature_c"), ready_only=True,
              power_events=("gyro_supply_on", "gyro_supply_off")),
    StreamMap("record", "", "output", "bench runs import", temp=("record", "temperature_c"), input_col="applied"),
)
#: the stream ``bench runs import`` stores a record in (its sensor is in the run's parameters)
IMPORTED = "record"


def mappable(streams: dict) -> list[StreamMap]:
    """The maps whose stream (with every column they need) the run holds, in table order."""
    out = []
    for m in STREAM_MAPS:
        info = streams.get(m.stream)
        if info is not None and all(c in info.columns for c in ("t_s", m.y, *m.needs)):
            out.append(m)
    return out


def power_on_time(events, first_t_s: float, on_off: tuple[str, str]) -> float | None:
    """Bench-clock time of the switch-on the sensor has been powered since at ``first_t_s``
    (None when the events do not show it powered then)."""
    on_kind, off_kind = on_off
    since = None
    for e in sorted((e for e in events if np.isfinite(e.t_s)), key=lambda e: e.t_s):
        if e.t_s > first_t_s:
            break
        if e.kind == on_kind and since is None:
            since = e.t_s
        elif e.kind == off_kind:
            since = None
    return since


def longest_stretch(t: np.ndarray, rtol: float = 0.05) -> tuple[int, int]:
    """[start, stop) of the longest run of samples whose every interval is within ``rtol`` of
    the median interval."""
    dt = np.diff(t)
    ok = np.abs(dt - np.median(dt)) <= rtol * np.median(dt)
    best, start, best_span = (0, 1), 0, 1
    for i, good in enumerate(np.append(ok, False)):
        if not good:
            if i + 1 - start > best_span:
                best, best_span = (start, i + 1), i + 1 - start
            start = i + 1
    return best


def record_of(store, run_id: str, m: StreamMap, streams: dict) -> tuple[Record, str]:
    """(record, what was done to it) of stream ``m`` of a stored run holding ``streams``."""
    data = store.load(run_id, m.stream)
    t = np.asarray(data["t_s"], float)
    y = np.asarray(data[m.y], float)
    keep = np.isfinite(t) & np.isfinite(y)
    if m.from_power_on:
        keep &= t >= 0.0
    if m.ready_only and "status" in data:
        keep &= (np.nan_to_num(np.asarray(data["status"], float)).astype(np.int64) & STATUS_READY) != 0
    if keep.sum() < 2:
        raise ValueError(f"stream {m.stream!r} of run {run_id} has {int(keep.sum())} usable samples")
    cols = {"t": t[keep], "y": y[keep]}
    if m.normalise_mean:
        cols["y"] = cols["y"] / float(np.mean(cols["y"]))
    if m.applied_input is not None:
        cols["input"] = np.full(cols["t"].size, m.applied_input)
    if m.input_col is not None and m.input_col in data:
        cols["input"] = np.asarray(data[m.input_col], float)[keep]
    if m.vib is not None:
        cols["vib"] = np.asarray(data[m.vib], float)[keep]
    if m.temp is not None and m.temp[0] in streams:
        td = data if m.temp[0] == m.stream else store.load(run_id, m.temp[0])
        if m.temp[1] in td and "t_s" in td:
            tt, vv = np.asarray(td["t_s"], float), np.asarray(td[m.temp[1]], float)
            ok = np.isfinite(vv) & np.isfinite(tt)
            if ok.sum() >= 2:
                cols["temp"] = np.interp(cols["t"], tt[ok], vv[ok])
    if m.from_power_on:
        cols["t_on"] = cols["t"].copy()
    elif m.power_events is not None:
        t_power = power_on_time(store.events(run_id), float(cols["t"][0]), m.power_events)
        if t_power is not None:
            cols["t_on"] = cols["t"] - t_power
    _, first = np.unique(cols["t"], return_index=True)  # a store may repeat a timestamp
    cols = {k: v[first] for k, v in cols.items()}
    done = ""
    if cols["t"].size >= 3:
        lo, hi = longest_stretch(cols["t"])
        if hi - lo < cols["t"].size:
            share = (hi - lo) / cols["t"].size
            if share < MIN_STRETCH:
                gap = int(np.argmax(np.abs(np.diff(cols["t"]) - np.median(np.diff(cols["t"])))))
                raise ValueError(f"stream {m.stream!r} of run {run_id} has gaps (e.g. {cols['t'][gap]:.6g} → "
                                 f"{cols['t'][gap + 1]:.6g} s); its longest unbroken stretch holds {share:.0%} "
                                 f"of the samples, at least {MIN_STRETCH:.0%} needed")
            cols = {k: v[lo:hi] for k, v in cols.items()}
            done = f", longest unbroken stretch: {share:.1%} of the samples"
    return Record.from_columns(cols), done


def read_run(store_path, run_id: str, stream: str | None = None) -> tuple[Record, str, str]:
    """(record, sensor kind, label) of a stored run: ``stream`` names which of its mappable
    streams (default: the first in :data:`STREAM_MAPS` order)."""
    require_store(store_path)
    with RunStore(store_path) as store:
        run_id = resolve_run_id(store, run_id)
        info = store.get_run(run_id)
        streams = store.streams(run_id)
        maps = mappable(streams)
        if not maps:
            known = "; ".join(f"{m.stream} ({m.procedures})" for m in STREAM_MAPS)
            raise ValueError(f"run {run_id} ({info.procedure}) has no stream discover can map; "
                             f"mappable streams: {known}")
        if stream is not None:
            pick = [m for m in maps if m.stream == stream]
            if not pick:
                raise ValueError(f"--stream {stream!r}: run {run_id} has no mappable stream of that name; "
                                 f"it has: {', '.join(m.stream for m in maps)}")
            maps = pick
        m = maps[0]
        if m.stream == IMPORTED:
            sensor = info.parameters.get("sensor")
            if sensor not in ("gyro", "accelerometer"):
                raise ValueError(f"run {run_id} ({info.procedure}) was imported without saying what the unit is; "
                                 "import it again with --sensor gyro|accelerometer")
            m = replace(m, sensor=sensor, from_power_on=info.parameters.get("kind") == "startup")
        rec, done = record_of(store, run_id, m, streams)
        if m.stream == IMPORTED:  # the catalogue reads deg/s and g: the record's own unit converted
            rec = rec.replace(y=to_sensor_unit(rec.y, streams[m.stream].columns.get("output"), m.sensor))
    others = [x.stream for x in maps[1:]]
    label = f"run {run_id} ({info.procedure}, stream {m.stream}{done})"
    if others:
        label += f" [other streams: {', '.join(others)}; --stream picks one]"
    return rec, m.sensor, label

