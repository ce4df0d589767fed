"""Start-up acquisition of a quartz flexure accelerometer (Document A, step 1).

1. On the level turntable (input axis vertical, both axes at 0°: the procedure's set-up
   levels it — ``procedures.running`` — and the turn-on test does before this record),
   check that the powered unit reads ≈ +1 g.
2. Supply off; wait for the unit to cool back to a cold start.
3. Arm a timed DMM trace of the output (and a slower one of the internal temperature),
   then switch the supply on: that instant is t = 0.
4. Stream both traces to the run store as they arrive, for the requested duration.
5. The procedure's teardown — always — leaves the supply off, the meters idle and the
   turntable stopped.

Times in the record are seconds since power-on on the bench clock.  Acceleration in g is
``V / R_sample / K1_nominal``; the analysis works on volts or g alike.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bench.core.step import Context, FollowUp, Limit, Step, parameter
from bench.values import Estimate
from procedures.common import choose_nplc, power_accelerometer
from procedures.typed_instruments import multimeter, power_supply


@dataclass
class StartupParameters:
    duration_s: float = parameter(1800.0, "trace after power-on, s")
    rate_hz: float = parameter(100.0, "output sample rate, Hz")
    temperature_rate_hz: float = parameter(1.0, "temperature sample rate, Hz")
    off_wait_s: float = parameter(600.0, "cool-down with the supply off before the cold start, s")
    pre_trigger_s: float = parameter(1.0, "the traces start this long before power-on, s")
    check_settle_s: float = parameter(5.0, "powered, before the level check's readings, s")
    nominal_scale_factor_ma_per_g: float = parameter(1.33, "nominal K1 that converts the output to g, mA/g")
    one_g_tolerance: float = parameter(0.15, "|reading − 1 g| the level check allows (K1 spread), g")
    chunk_s: float = parameter(60.0, "how often the traces are drained to the store, s")

    def validate(self) -> None:
        checks = {
            "duration_s": (self.duration_s, 1.0, 86400.0),
            "rate_hz": (self.rate_hz, 0.01, 1000.0),  # 2 × 0.02 NPLC must fit the interval
            "temperature_rate_hz": (self.temperature_rate_hz, 0.01, 10.0),
            "off_wait_s": (self.off_wait_s, 0.0, 86400.0),
            "pre_trigger_s": (self.pre_trigger_s, 0.0, 60.0),
            "check_settle_s": (self.check_settle_s, 0.0, 600.0),
            "nominal_scale_factor_ma_per_g": (self.nominal_scale_factor_ma_per_g, 0.5, 5.0),
            "one_g_tolerance": (self.one_g_tolerance, 0.001, 0.5),
            "chunk_s": (self.chunk_s, 0.1, 3600.0),
        }
        for name, (value, lo, hi) in checks.items():
            if not isinstance(value, (int, float)) or not math.isfinite(value) or not lo <= value <= hi:
                raise ValueError(f"{name} = {value!r} not in {lo:g}..{hi:g}")
        if self.duration_s * self.rate_hz > 50_000_000:
            raise ValueError(f"duration_s × rate_hz = {self.duration_s * self.rate_hz:.0f} "
                             "readings exceeds 5e7")


class StartupAcquisition(Step[StartupParameters]):
    """Start-up acquisition of a quartz accelerometer (Document A, step 1): level check, cold
    start, output and temperature traces from power-on.

    Produces no value of its own — its record is what Document A's start-up model
    (``--analyze``, ``bench analyze run``) and the turn-on test reduce — and judges two
    guards itself: the level check (≈ +1 g) and no reading lost.
    """

    name = "startup"
    requires = ("dmm", "dmm_temp", "supply", "turntable")
    kinds = ("accelerometer",)
    Parameters = StartupParameters
    follow_up = FollowUp("startup", on_request=True,
                         summary="fit Document A's start-up model to the run and attach the report")

    def duration_s(self) -> float:
        return self.p.check_settle_s + self.p.off_wait_s + self.p.pre_trigger_s + self.p.duration_s

    def run(self, ctx: Context) -> dict[str, Estimate]:
        p, w = self.p, ctx.wiring
        dmm, dmm_temp, supply = multimeter(ctx), multimeter(ctx, "dmm_temp"), power_supply(ctx)
        volts_per_g = p.nominal_scale_factor_ma_per_g * 1e-3 * w["sampling_resistor_ohm"]

        # 0. a known start: meters reset, unit unpowered (the table is level, input axis up:
        #    the procedure's set-up levels it, and so does the turn-on test before this record)
        for meter in (dmm, dmm_temp):
            meter.reset()
        supply.outputs_off()

        # 1. level check: powered, settled, averaged reading ≈ +1 g
        power_accelerometer(ctx, on=True)
        ctx.clock.sleep(p.check_settle_s)
        dmm.configure_dc_voltage(range_v=10.0, nplc=10.0)
        one_g = float(np.mean([dmm.measure_dc_voltage() for _ in range(5)])) / volts_per_g
        ctx.measure("level_check_g", one_g, "g",
                    Limit(1.0 - p.one_g_tolerance, 1.0 + p.one_g_tolerance),
                    "reading with the input axis up, nominal scale factor")
        if abs(one_g - 1.0) > p.one_g_tolerance:
            # a failed measurement, not a fault: the run ends 'failed' (exit 1) with the reading
            ctx.run.event(ctx.clock.now(), "level_check_failed",
                          f"read {one_g:.4f} g, expected 1 ± {p.one_g_tolerance} g — check "
                          "mounting, wiring and the sampling resistor; no trace taken")
            return {}
        # 2. cold start
        supply.outputs_off()
        ctx.run.event(ctx.clock.now(), "supply_off", "cool-down before the cold start")
        ctx.clock.sleep(p.off_wait_s)

        # 3. arm the traces, then power on (t = 0)
        line_hz = dmm.line_frequency_hz
        n_out = int(round((p.duration_s + p.pre_trigger_s) * p.rate_hz))
        n_temp = int(round((p.duration_s + p.pre_trigger_s) * p.temperature_rate_hz))
        nplc = choose_nplc(1.0 / p.rate_hz, line_hz)
        dmm.configure_timed_trace(n_out, 1.0 / p.rate_hz, nplc=nplc, range_v=10.0)
        dmm_temp.configure_timed_trace(n_temp, 1.0 / p.temperature_rate_hz,
                                       nplc=choose_nplc(1.0 / p.temperature_rate_hz, line_hz),
                                       range_v=10.0)
        ctx.run.add_stream("output", {"t_s": "s", "voltage_v": "V", "acceleration_g": "g"},
                           "accelerometer output across the sampling resistor")
        ctx.run.add_stream("temperature", {"t_s": "s", "temperature_c": "degC"},
                           "internal temperature sensor (1 uA/K)")
        t_arm = ctx.clock.now()
        dmm.initiate()
        dmm_temp.initiate()
        ctx.clock.sleep(p.pre_trigger_s)
        power_accelerometer(ctx, on=True)
        t_on = ctx.clock.now()
        # Events carry bench-clock time; the streams' t_s count from this instant.
        ctx.run.event(t_on, "t0", "power-on: t = 0 of the start-up test",
                      nplc=nplc, line_hz=line_hz, n_output=n_out, n_temperature=n_temp)
        ctx.run.set_result("power_on_clock_s", t_on)

        # 4. stream to the store as the readings arrive; drain well before memory fills
        chunk_s = min(p.chunk_s, 0.5 * dmm.memory_depth / p.rate_hz)
        stall_s = max(30.0, 5 * chunk_s)  # no new reading for this long while due: a fault
        t0_out = t_arm + dmm.trigger_delay_s - t_on
        t0_temp = t_arm + dmm_temp.trigger_delay_s - t_on
        got_out = got_temp = 0
        ohm_t = w["temp_resistor_ohm"]
        t_last_data = ctx.clock.now()
        while got_out < n_out or got_temp < n_temp:
            remaining = max((n_out - got_out) / p.rate_hz, (n_temp - got_temp) / p.temperature_rate_hz)
            ctx.clock.sleep(min(chunk_s, max(remaining, 1.0 / p.rate_hz)))
            volts = dmm.read_available()
            if volts.size:
                t = t0_out + (got_out + np.arange(volts.size)) / p.rate_hz
                ctx.run.append("output", t_s=t, voltage_v=volts, acceleration_g=volts / volts_per_g)
                got_out += volts.size
            temp_v = dmm_temp.read_available()
            if temp_v.size:
                t = t0_temp + (got_temp + np.arange(temp_v.size)) / p.temperature_rate_hz
                ctx.run.append("temperature", t_s=t,
                               temperature_c=temp_v / ohm_t / 1e-6 - 273.15)
                got_temp += temp_v.size
            ctx.progress(min(got_out / p.rate_hz - p.pre_trigger_s, p.duration_s), p.duration_s,
                         "acquiring start-up trace")
            now = ctx.clock.now()
            if volts.size or temp_v.size:
                t_last_data = now
            elif now - t_last_data > stall_s:
                raise TimeoutError(
                    f"no readings for {now - t_last_data:.0f} s: output {got_out}/{n_out}, "
                    f"temperature {got_temp}/{n_temp} received (meter stopped, or its memory "
                    "overflowed)")
        ctx.measure("readings_lost", n_out - got_out, "readings", Limit(0, 0),
                    "output readings expected minus stored")
        ctx.run.set_result("samples", {"output": got_out, "temperature": got_temp})
        return {}
