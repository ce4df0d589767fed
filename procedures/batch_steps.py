"""The catalogue's accelerometer steps run for a whole fixture at once (``bench.core.batch``).

Each batch step is built from the single-unit step the spec names (the same parameters, the
same validation) and does what that step does, with the shared actions once and the output
of every socket read through the scanning DAQ:

* ``turn_on`` — level check of every socket (5 sweeps at 10 NPLC), supply off, cool-down,
  a timed scan armed, supply on (t = 0 for every unit), every socket's record streamed to
  its run as ``output``, each reduced to turn-on time and warm-up drift;
* ``tumble`` — each position of the plan once for the batch (the table moves, settles), a
  scan averaged per socket (``tumble`` / ``tumble_readings`` streams), each socket's IEEE
  1293 fit;
* ``accelerometer_noise`` — one static record of every socket (``noise`` streams), each
  reduced to noise density and bias instability.

Streams, results and measurements keep the single steps' names, so a socket's run is read
by the reports as a single unit's.  Where the scanner cannot keep the step's rate for this
many channels, the rate it got is recorded (event ``scan_rate``) and used.

What is per socket stays per socket: a socket whose data cannot be reduced (an overloaded
channel, a fit that fails) gets its exception back to the runner and is aborted alone.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from types import MappingProxyType

import numpy as np

from bench.analysis.turn_on import turn_on_metrics
from bench.core.batch import BatchStep, SocketResult
from bench.core.step import Context, Limit, Step
from bench.values import Estimate
from procedures.common import level_table, move_table, power_accelerometer
from procedures.fixture import drain, scan_means, scan_timing, socket_channel
from procedures.noise import AccelerometerNoise
from procedures.tumble import TumbleCalibration
from procedures.turn_on import TurnOnTest
from procedures.typed_instruments import power_supply, scanner

_REQUIRES = ("daq", "supply", "turntable")


def _each(units: Mapping[int, Context], reduce) -> dict[int, SocketResult]:
    """``reduce(socket, ctx)`` for every socket, an exception kept as that socket's result."""
    out: dict[int, SocketResult] = {}
    for n, unit in units.items():
        try:
            out[n] = reduce(n, unit)
        except Exception as exc:
            out[n] = exc
    return out


def _finite(n: int, channel: int, volts: np.ndarray, what: str) -> np.ndarray:
    bad = int(np.count_nonzero(~np.isfinite(volts)))
    if bad:
        raise RuntimeError(f"socket {n} (channel {channel}): {bad} of {volts.size} readings "
                           f"overloaded during the {what}")
    return volts


class BatchTurnOn(BatchStep):
    """``turn_on`` for the fixture: one cold start of every unit, one record each."""

    requires = _REQUIRES

    def __init__(self, step: Step) -> None:
        if not isinstance(step, TurnOnTest):
            raise TypeError(f"BatchTurnOn batches turn_on, not {step.name}")
        super().__init__(step)
        self.turn_on = step

    def run_batch(self, shared: Context, units: Mapping[int, Context]) -> dict[int, SocketResult]:
        p, sp = self.turn_on.p, self.turn_on.acquisition.p
        daq, supply = scanner(shared), power_supply(shared)
        line_hz = daq.line_frequency_hz
        volts_per_g = sp.nominal_scale_factor_ma_per_g * 1e-3 * shared.wiring["sampling_resistor_ohm"]
        level_table(shared)
        supply.outputs_off()
        power_accelerometer(shared, on=True)
        shared.clock.sleep(sp.check_settle_s)
        checks = scan_means(shared, units, sweeps=5, nplc=10.0, autozero=True, line_hz=line_hz)
        checked = {}
        for n, unit in units.items():
            one_g = float(np.mean(checks[n])) / volts_per_g if checks[n].size else float("nan")
            unit.measure("level_check_g", one_g, "g",
                         Limit(1.0 - sp.one_g_tolerance, 1.0 + sp.one_g_tolerance),
                         "reading with the input axis up, nominal scale factor")
            if math.isfinite(one_g) and abs(one_g - 1.0) <= sp.one_g_tolerance:
                checked[n] = unit
            else:
                unit.run.event(shared.clock.now(), "level_check_failed",
                               f"read {one_g:.4f} g, expected 1 ± {sp.one_g_tolerance} g — check "
                               "the socket's seating and wiring; no trace taken")
        supply.outputs_off()
        shared.run.event(shared.clock.now(), "supply_off", "cool-down before the cold start")
        shared.clock.sleep(sp.off_wait_s)
        results: dict[int, SocketResult] = {n: {} for n in units if n not in checked}
        if not checked:
            power_accelerometer(shared, on=True)  # as a single unit's test leaves it
            return results
        channels = {n: socket_channel(shared, n) for n in checked}
        interval, nplc = scan_timing(daq, len(channels), 1.0 / p.rate_hz, line_hz, autozero=False)
        sweeps = int(round((p.duration_s + sp.pre_trigger_s) / interval))
        daq.configure_scan(sorted(channels.values()), interval_s=interval, sweeps=sweeps, nplc=nplc,
                           line_hz=line_hz, autozero=False)
        for unit in checked.values():
            unit.run.add_stream("output", {"t_s": "s", "voltage_v": "V", "acceleration_g": "g"},
                                "accelerometer output across the sampling resistor (scanned)")
        t_arm = shared.clock.now()
        daq.initiate()
        shared.clock.sleep(sp.pre_trigger_s)
        power_accelerometer(shared, on=True)
        t_on = shared.clock.now()
        shared.run.event(t_on, "t0", "power-on: t = 0 of the start-up test", nplc=nplc,
                         line_hz=line_hz, n_output=sweeps, interval_s=interval)
        shared.run.set_result("power_on_clock_s", t_on)
        if interval > 1.0 / p.rate_hz + 1e-9:
            shared.run.event(t_on, "scan_rate", f"{len(channels)} sockets: {1 / interval:.4g} Hz "
                             f"per socket instead of {p.rate_hz:g} Hz")
        records: dict[int, tuple[list[np.ndarray], list[np.ndarray]]] = {n: ([], []) for n in checked}

        def store(n: int, t_rel: np.ndarray, volts: np.ndarray) -> None:
            t = t_arm + t_rel - t_on
            checked[n].run.append("output", t_s=t, voltage_v=volts, acceleration_g=volts / volts_per_g)
            records[n][0].append(t)
            records[n][1].append(volts)

        drain(shared, daq, channels, sweeps * len(channels), store,
              poll_s=min(sp.chunk_s, 0.4 * 1_000_000 / len(channels) * interval),
              message="turn-on record",
              progress=lambda got: shared.progress(min(got / len(channels) * interval, p.duration_s),
                                                   p.duration_s, "start-up record"))

        def reduce(n: int, unit: Context) -> Mapping[str, Estimate]:
            t = np.concatenate(records[n][0])
            g = _finite(n, channels[n], np.concatenate(records[n][1]), "turn-on record") / volts_per_g
            unit.measure("readings_lost", sweeps - t.size, "readings", Limit(0, 0),
                         "output readings expected minus stored")
            keep = t >= 0.0
            r = turn_on_metrics(t[keep], g[keep], band=p.band_g, smooth_s=p.smooth_s,
                                settled_window_s=p.settled_window_s)
            unit.run.set_result("startup.turn_on", r.to_dict())
            return {"turn_on_time": Estimate(r.turn_on_time_s, None,
                                                   bound=None if r.resolved else "upper"),
                    "warmup_drift": Estimate(r.warmup_drift, r.warmup_drift_std)}
        results.update(_each(checked, reduce))
        return results


class BatchTumble(BatchStep):
    """``tumble`` for the fixture: each position once, every socket averaged and fitted."""

    requires = _REQUIRES

    def __init__(self, step: Step) -> None:
        if not isinstance(step, TumbleCalibration):
            raise TypeError(f"BatchTumble batches tumble, not {step.name}")
        super().__init__(step)
        self.tumble = step

    def run_batch(self, shared: Context, units: Mapping[int, Context]) -> dict[int, SocketResult]:
        step = self.tumble
        p, plan = step.p, step.plan
        daq = scanner(shared)
        line_hz = daq.line_frequency_hz
        channels = {n: socket_channel(shared, n) for n in units}
        for unit in units.values():
            unit.run.add_stream("tumble", {"t_s": "s", "inner_deg": "deg", "outer_deg": "deg",
                                           "voltage_v": "V", "voltage_se_v": "V", "n_readings": "1"},
                                "mean output per tumble position")
            unit.run.add_stream("tumble_readings", {"position": "1", "voltage_v": "V"},
                                "every scanned reading, by position index")
        move_table(shared, *plan[0])
        power_accelerometer(shared, on=True)
        shared.progress(0, step.duration_s(), "warming up")
        shared.clock.sleep(p.warmup_s)
        interval, _ = scan_timing(daq, len(channels), 1e-3, line_hz, autozero=False, nplc=p.nplc)
        sweeps = max(2, int(math.ceil(p.average_s / interval)))
        daq.configure_scan(sorted(channels.values()), interval_s=interval, sweeps=sweeps,
                           nplc=p.nplc, line_hz=line_hz, autozero=False)
        means = {n: np.full(len(plan), np.nan) for n in units}
        errors = {n: np.full(len(plan), np.nan) for n in units}
        for k, (inner, outer) in enumerate(plan):
            move_table(shared, inner, outer)
            shared.clock.sleep(p.settle_s)
            got: dict[int, list[np.ndarray]] = {n: [] for n in units}

            def keep(n: int, t: np.ndarray, v: np.ndarray, k: int = k,
                     got: dict[int, list[np.ndarray]] = got) -> None:
                units[n].run.append("tumble_readings", position=np.full(v.size, k), voltage_v=v)
                got[n].append(v)
            daq.initiate()
            drain(shared, daq, channels, sweeps * len(channels), keep,
                  poll_s=interval * sweeps + 0.01, message=f"tumble position {k + 1}")
            for n, unit in units.items():
                v = np.concatenate(got[n])
                finite = v[np.isfinite(v)]
                if finite.size == v.size and v.size > 1:
                    means[n][k] = float(np.mean(v))
                    errors[n][k] = float(np.std(v, ddof=1) / math.sqrt(v.size))
                unit.run.append("tumble", t_s=[shared.clock.now()], inner_deg=[inner], outer_deg=[outer],
                                voltage_v=[means[n][k]], voltage_se_v=[errors[n][k]], n_readings=[v.size])
            shared.progress(p.warmup_s + (k + 1) * (step.duration_s() - p.warmup_s) / len(plan),
                            step.duration_s(), f"position {k + 1}/{len(plan)} ({inner:g}°, {outer:g}°)")

        def reduce(n: int, unit: Context) -> Mapping[str, Estimate]:
            bad = int(np.count_nonzero(~np.isfinite(means[n])))
            if bad:
                raise RuntimeError(f"socket {n} (channel {channels[n]}): overloaded readings at "
                                   f"{bad} of {len(plan)} tumble positions")
            return step.fit(unit, means[n], errors[n])
        return _each(units, reduce)


class BatchNoise(BatchStep):
    """``accelerometer_noise`` for the fixture: one static record, every socket reduced."""

    requires = _REQUIRES

    def __init__(self, step: Step) -> None:
        if not isinstance(step, AccelerometerNoise):
            raise TypeError(f"BatchNoise batches accelerometer_noise, not {step.name}")
        super().__init__(step)
        self.noise = step

    def run_batch(self, shared: Context, units: Mapping[int, Context]) -> dict[int, SocketResult]:
        step = self.noise
        p = step.p
        daq = scanner(shared)
        line_hz = daq.line_frequency_hz
        channels = {n: socket_channel(shared, n) for n in units}
        level_table(shared)
        power_accelerometer(shared, on=True)
        shared.progress(0, step.duration_s(), "warming up")
        shared.clock.sleep(p.warmup_s)
        interval = 1.0 / p.rate_hz
        got_interval, nplc = scan_timing(daq, len(channels), interval, line_hz, autozero=False)
        if got_interval > interval + 1e-9:
            raise ValueError(f"{len(channels)} sockets cannot be scanned at rate_hz = {p.rate_hz:g} "
                             f"(a sweep takes {got_interval:g} s); lower rate_hz in the spec")
        aperture = nplc / line_hz
        sweeps = int(round(p.duration_s * p.rate_hz))
        daq.configure_scan(sorted(channels.values()), interval_s=interval, sweeps=sweeps, nplc=nplc,
                           line_hz=line_hz, autozero=False)
        for unit in units.values():
            unit.run.add_stream("noise", {"t_s": "s", "voltage_v": "V"}, "static output record (scanned)")
        parts: dict[int, list[np.ndarray]] = {n: [] for n in units}
        t_init = shared.clock.now()

        def store(n: int, t_rel: np.ndarray, volts: np.ndarray) -> None:
            units[n].run.append("noise", t_s=t_init + t_rel, voltage_v=volts)
            parts[n].append(volts)
        daq.initiate()
        drain(shared, daq, channels, sweeps * len(channels), store,
              poll_s=min(p.chunk_s, 0.4 * 1_000_000 / len(channels) * interval), message="static record",
              progress=lambda got: shared.progress(p.warmup_s + got / len(channels) * interval,
                                                   step.duration_s(), "static record"))

        def reduce(n: int, unit: Context) -> Mapping[str, Estimate]:
            volts = _finite(n, channels[n], np.concatenate(parts[n]), "static record")
            return step.reduce(unit, volts, aperture, interval)
        return _each(units, reduce)


#: the steps a fixture can run as a batch: step name → its batch form
BATCHED: Mapping[str, type[BatchStep]] = MappingProxyType({
    "turn_on": BatchTurnOn,
    "tumble": BatchTumble,
    "accelerometer_noise": BatchNoise,
})


__all__ = ["BatchTurnOn", "BatchTumble", "BatchNoise", "BATCHED"]
