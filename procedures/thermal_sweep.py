"""Calibration over temperature in the chamber: ``thermal_sweep`` (accelerometer, a tumble at
each temperature) and ``gyro_thermal_sweep`` (gyro, a rate-table sequence at each temperature).

1. The unit powered and the chamber running, set point changes ramped at ``ramp_c_per_min``.
2. **Calibration**: ``set_points`` temperatures equally spaced from ``low_c`` to ``high_c``,
   in rising order. At each: soak until the unit's *own* sensor is stable
   (``procedures.thermal_common.soak``: the analysis's soak criterion; the soak time is
   recorded), then the measurement at temperature, streamed as it is taken — the unit's
   sensor read with every position or rate, the point's temperature their mean.
3. The per-temperature estimates fitted as polynomials of the unit's sensor temperature
   (order by BIC, :func:`bench.analysis.thermal._calibration.calibrate_over_temperature`),
   the temperature coefficients at ``reference_c`` read off, and the **compensation file**
   written (:mod:`bench.analysis.thermal._compensation_file`) and attached to the run as
   ``thermal_compensation.toml`` at once — before the verification, so an abort keeps it.
4. **Verification** on a different profile: ``verify_points`` temperatures between the
   calibration's (mid-way between neighbours), in *falling* order, measured the same way;
   the compensated and uncompensated errors over temperature
   (:func:`bench.analysis.thermal._verification.verify_compensation`).

Results under ``<step>.points``, ``<step>.calibration``, ``<step>.compensation`` and
``<step>.verification``; streams ``thermal_soak``, ``thermal_points`` and the measurement's
own (``thermal_tumble`` / ``thermal_tumble_readings``, ``thermal_rates`` /
``thermal_rate_frames``).
"""

from __future__ import annotations

import math
from abc import abstractmethod
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from typing import Any, ClassVar, Generic, TypeVar

import numpy as np

from bench.analysis.ratetable import fit_rate_table, rate_plan, whole_revolution_duration_s
from bench.analysis.thermal import (
    QuantityPoints,
    ThermalCalibration,
    calibrate_over_temperature,
    compensation_model,
    compensation_to_toml,
    verify_compensation,
)
from bench.analysis.tumble import fit_tumble, specific_force_iapo_g, tumble_positions
from bench.core.site import STANDARD_GRAVITY_MPS2, earth_rate_vertical_dph, site_gravity_mps2
from bench.core.step import Context, Step, parameter
from bench.values import Estimate
from instruments.fog_types import GyroFrames
from procedures.common import (
    averaged_voltage,
    check_ranges,
    level_table,
    move_table,
    power_accelerometer,
    power_gyro,
    read_gyro_frames,
)
from procedures.thermal_common import (
    AccelerometerThermometer,
    GyroThermometer,
    UnitThermometer,
    criterion_for,
    soak,
)
from procedures.typed_instruments import chamber, frame_gyro, turntable

COMPENSATION_FILE = "thermal_compensation.toml"
AT_RATE_TIMEOUT_S = 120.0
#: the soak poll's own allowance in the duration estimate: the unit's slow mode (≈ 600 s)
#: settles in a few time constants after the air arrives
SOAK_ESTIMATE_S = 3000.0


def sweep_temperatures(low_c: float, high_c: float, n: int) -> np.ndarray:
    """The calibration's set points: ``n`` equally spaced from ``low_c`` to ``high_c``, rising."""
    return np.linspace(low_c, high_c, n)


def verification_temperatures(low_c: float, high_c: float, n_calibration: int, n: int) -> np.ndarray:
    """The verification's set points: ``n`` of the mid-points between neighbouring calibration
    temperatures, spread evenly over them, falling (a different profile: other temperatures,
    reached from above)."""
    if n == 0:
        return np.empty(0)
    cal = sweep_temperatures(low_c, high_c, n_calibration)
    mid = 0.5 * (cal[:-1] + cal[1:])
    pick = np.unique(np.round(np.linspace(0, mid.size - 1, n)).astype(int))
    return mid[pick][::-1]


@dataclass
class SweepParameters:
    low_c: float = parameter(-40.0, "lowest calibration set point, °C")
    high_c: float = parameter(70.0, "highest calibration set point, °C")
    set_points: int = parameter(7, "calibration set points, equally spaced low…high")
    verify_points: int = parameter(4, "verification set points between the calibration's, run falling (0: none)")
    ramp_c_per_min: float = parameter(2.0, "chamber ramp between set points, °C/min")
    reference_c: float = parameter(25.0, "reference temperature of the compensation model, °C")
    soak_window_s: float = parameter(900.0, "soak: trailing window of the unit's sensor, s")
    soak_rate_c_per_min: float = parameter(0.02, "soak: largest |rate| of the unit's sensor over the window, °C/min")
    soak_band_c: float = parameter(0.3, "soak: largest spread of the unit's sensor over the window, °C")
    soak_tolerance_c: float = parameter(10.0, "soak: the unit's sensor within this of the set point "
                                             "(room for its self-heating), °C")
    soak_poll_s: float = parameter(60.0, "soak: chamber and unit sensor read every, s")
    soak_timeout_s: float = parameter(4 * 3600.0, "soak: give up after, s")

    def validate(self) -> None:
        check_ranges(asdict(self), {
            "low_c": (-70, 150), "high_c": (-70, 150), "set_points": (3, 30), "verify_points": (0, 29),
            "ramp_c_per_min": (0.01, 30), "reference_c": (-70, 150), "soak_window_s": (60, 86400),
            "soak_rate_c_per_min": (1e-4, 10), "soak_band_c": (1e-3, 20), "soak_tolerance_c": (0.1, 50),
            "soak_poll_s": (1, 3600), "soak_timeout_s": (60, 7 * 86400)},
            integers=("set_points", "verify_points"))
        if not self.low_c < self.high_c:
            raise ValueError(f"low_c = {self.low_c} must be < high_c = {self.high_c}")
        if self.verify_points > self.set_points - 1:
            raise ValueError(f"verify_points = {self.verify_points} must be ≤ set_points − 1 = "
                             f"{self.set_points - 1} (one between each pair of calibration points)")
        if self.soak_window_s < 3 * self.soak_poll_s:
            raise ValueError(f"soak_window_s = {self.soak_window_s} must hold ≥ 3 polls of "
                             f"soak_poll_s = {self.soak_poll_s}")


@dataclass(frozen=True)
class PointMeasurement:
    """What one temperature gave: each quantity's (value, std), the unit's sensor mean and its
    standard uncertainty over the measurement."""

    values: dict[str, tuple[float, float]]
    temperature_c: float
    temperature_std_c: float
    extra: dict[str, Any] = field(default_factory=dict)


P = TypeVar("P", bound=SweepParameters)


def sweep_produces(bias_unit: str, more_tcs: dict[str, tuple[str, str]] | None = None
                   ) -> dict[str, tuple[str, str]]:
    """What a calibration over temperature produces: the bias and scale-factor temperature
    coefficients (and ``more_tcs``), the verification's compensated and uncompensated rms
    errors, the longest soak; bias quantities in ``bias_unit``."""
    return {
        "bias_tc": (f"{bias_unit}/degC", "bias temperature coefficient at the reference temperature"),
        "sf_tc": ("ppm/degC", "scale-factor temperature coefficient at the reference temperature"),
        **(more_tcs or {}),
        "bias_residual": (bias_unit, "rms bias error over the verification profile, compensated"),
        "bias_uncompensated": (bias_unit, "rms bias error over the verification profile, "
                                          "room-temperature calibration only"),
        "sf_residual": ("ppm", "rms scale-factor error over the verification profile, compensated"),
        "sf_uncompensated": ("ppm", "rms scale-factor error over the verification profile, "
                                    "room-temperature calibration only"),
        "soak_time_max": ("s", "longest soak on the unit's own sensor"),
    }


class ThermalSweepBase(Step[P], Generic[P]):
    """The sweep (module docstring); a kind supplies its thermometer, its measurement at one
    temperature and its quantities."""

    #: quantity name → (role, unit) in the compensation model, in model order
    quantities: ClassVar[Mapping[str, tuple[str, str]]]
    input_unit: ClassVar[str]
    output_unit: ClassVar[str]
    #: produced name of each quantity's TC and its verification errors
    tc_names: ClassVar[Mapping[str, str]]
    residual_names: ClassVar[Mapping[str, tuple[str, str]]]

    def temperatures(self) -> tuple[np.ndarray, np.ndarray]:
        p = self.p
        return (sweep_temperatures(p.low_c, p.high_c, p.set_points),
                verification_temperatures(p.low_c, p.high_c, p.set_points, p.verify_points))

    def producible(self) -> set[str]:
        out = set(self.tc_names.values()) | {"soak_time_max"}
        if self.p.verify_points:
            out |= {n for pair in self.residual_names.values() for n in pair}
        return out

    def duration_s(self) -> float:
        cal, ver = self.temperatures()
        path = np.concatenate([[23.0], cal, ver])
        ramps = float(np.sum(np.abs(np.diff(path)))) / self.p.ramp_c_per_min * 60.0
        return ramps + path.size * (SOAK_ESTIMATE_S + self.point_duration_s())

    @abstractmethod
    def point_duration_s(self) -> float:
        """Time the measurement at one temperature takes."""

    @abstractmethod
    def thermometer(self) -> UnitThermometer: ...

    @abstractmethod
    def prepare(self, ctx: Context) -> None:
        """The unit powered and at its start state, before the first soak."""

    @abstractmethod
    def measure_point(self, ctx: Context, point: int, thermometer: UnitThermometer) -> PointMeasurement:
        """The measurement at one temperature, streamed as it is taken."""

    def finish(self, ctx: Context) -> None:
        """After the last point (the table at rest …); the unit stays powered."""

    def run(self, ctx: Context) -> dict[str, Estimate]:
        p = self.p
        cal_t, ver_t = self.temperatures()
        thermometer = self.thermometer()
        ch = chamber(ctx)
        ch.set_ramp(p.ramp_c_per_min)
        self.prepare(ctx)
        columns = {"point": "1", "phase": "1", "set_point_c": "degC", "soak_time_s": "s",
                   "temperature_c": "degC", "temperature_std_c": "degC"}
        for q in self.quantities:
            columns |= {q: self.quantities[q][1], f"{q}_std": self.quantities[q][1]}
        ctx.run.add_stream("thermal_points", columns,
                           "per temperature: soak time, the unit's sensor, each quantity ± std "
                           "(phase 0 calibration, 1 verification)")
        total, done = self.duration_s(), 0.0
        points: dict[int, list[tuple[float, PointMeasurement]]] = {0: [], 1: []}
        outcome: dict[str, Estimate] = {}
        soak_times: list[float] = []
        model = None
        k = 0
        for phase, temps in ((0, cal_t), (1, ver_t)):
            for sp in temps:
                label = f"{'calibration' if phase == 0 else 'verification'} point {k + 1} ({sp:g} °C)"
                ctx.progress(done, total, f"soaking, {label}")
                crit = criterion_for(float(sp), p.soak_window_s, p.soak_rate_c_per_min, p.soak_band_c,
                                     p.soak_tolerance_c)
                rec = soak(ctx, thermometer, float(sp), crit, poll_s=p.soak_poll_s, timeout_s=p.soak_timeout_s,
                           label=label)
                soak_times.append(rec.soak_time_s)
                done += SOAK_ESTIMATE_S
                ctx.progress(done, total, f"measuring, {label}")
                m = self.measure_point(ctx, k, thermometer)
                row: dict[str, Any] = {"point": [k], "phase": [phase], "set_point_c": [sp],
                                       "soak_time_s": [rec.soak_time_s], "temperature_c": [m.temperature_c],
                                       "temperature_std_c": [m.temperature_std_c]}
                for q in self.quantities:
                    value, std = m.values.get(q, (math.nan, math.nan))
                    row |= {q: [value], f"{q}_std": [std]}
                ctx.run.append("thermal_points", **row)
                points[phase].append((float(sp), m))
                done += self.point_duration_s()
                k += 1
            if phase == 0:
                calibration = self._calibrate(points[0])
                serial, unit_model = unit_identity(ctx, self.kinds[0])
                model = compensation_model(calibration, unit_serial=serial, unit_model=unit_model,
                                           input_unit=self.input_unit, output_unit=self.output_unit,
                                           created=f"run {ctx.run.id}")
                ctx.run.set_result(f"{self.name}.calibration", calibration.to_dict())
                ctx.run.set_result(f"{self.name}.compensation", model.to_dict())
                ctx.run.attach(COMPENSATION_FILE, compensation_to_toml(model).encode(), "application/toml")
                ctx.run.event(ctx.clock.now(), "compensation", f"{COMPENSATION_FILE} attached: "
                              + ", ".join(f"{q.name} order {q.fit.order}" for q in calibration.quantities))
                for q, name in self.tc_names.items():
                    tc = calibration[q].temperature_coefficient
                    outcome[name] = Estimate(tc.value, tc.std)
        self.finish(ctx)
        ctx.run.set_result(f"{self.name}.points", {
            phase_name: [{"set_point_c": sp, "temperature_c": m.temperature_c,
                          "temperature_std_c": m.temperature_std_c, "values": m.values, **m.extra}
                         for sp, m in points[phase]]
            for phase, phase_name in ((0, "calibration"), (1, "verification"))})
        outcome["soak_time_max"] = Estimate(max(soak_times), None)
        if points[1] and model is not None:
            verification = verify_compensation(model, self._points(points[1]), outside="skip")
            ctx.run.set_result(f"{self.name}.verification", verification.to_dict())
            for q, (comp_name, uncomp_name) in self.residual_names.items():
                v = verification[q]
                outcome[comp_name] = Estimate(v.compensated_rms, v.noise_rms)
                outcome[uncomp_name] = Estimate(v.uncompensated_rms, None)
        return outcome

    def _points(self, measured: list[tuple[float, PointMeasurement]]) -> list[QuantityPoints]:
        t = np.array([m.temperature_c for _, m in measured])
        ts = np.array([m.temperature_std_c for _, m in measured])
        out = []
        for q, (role, unit) in self.quantities.items():
            values = np.array([m.values[q][0] for _, m in measured])
            stds = np.array([m.values[q][1] for _, m in measured])
            out.append(QuantityPoints(q, role, unit, t, values, stds, ts))
        return out

    def _calibrate(self, measured: list[tuple[float, PointMeasurement]]) -> ThermalCalibration:
        # "birge": the per-temperature σ a tumble states come from a few degrees of freedom and
        # leave out the noise correlated across its positions; where the points scatter more
        # than they claim the curve's covariance is widened by the Birge ratio (never narrowed)
        return calibrate_over_temperature(self._points(measured), reference_c=self.p.reference_c,
                                          uncertainty="birge")


# --------------------------------------------------------------------------- accelerometer


@dataclass
class AccelerometerSweepParameters(SweepParameters):
    positions: int = parameter(12, "tumble positions per temperature (a multiple of 4, one plane: IA–OA; 12 leaves "
                                    "6 degrees of freedom for the per-temperature uncertainties)")
    settle_s: float = parameter(5.0, "tumble: after in position, before averaging, s")
    average_s: float = parameter(10.0, "tumble: averaging time per position, s")
    nplc: float = parameter(10.0, "tumble: DMM integration per reading, power-line cycles (0.02|0.06|0.2|1|10|100)")

    def validate(self) -> None:
        super().validate()
        check_ranges(asdict(self), {"positions": (8, 72), "settle_s": (0, 600), "average_s": (0.5, 3600),
                                    "nplc": (0.02, 100)}, integers=("positions",))
        if self.positions % 4:
            raise ValueError(f"positions = {self.positions} must be a multiple of 4")
        if self.nplc not in (0.02, 0.06, 0.2, 1.0, 10.0, 100.0):
            raise ValueError(f"nplc = {self.nplc} not in 0.02|0.06|0.2|1|10|100")


class ThermalSweep(ThermalSweepBase[AccelerometerSweepParameters]):
    """Accelerometer calibration over temperature: a tumble at each soaked temperature.

    Bias K0, scale factor K1 and K2 as polynomials of the unit's sensor temperature, their
    temperature coefficients, the compensation file, and its verification on a falling profile
    at other temperatures (compensated and uncompensated residuals).
    """

    name = "thermal_sweep"
    requires = ("dmm", "dmm_temp", "supply", "turntable", "chamber")
    kinds = ("accelerometer",)
    produces = sweep_produces("g", {"k2_tc": ("g/g^2/degC", "K2 temperature coefficient at the "
                                                        "reference temperature")})
    Parameters = AccelerometerSweepParameters
    quantities = {"k0": ("bias", "g"), "k1": ("scale_factor", "mA/g"), "k2": ("k2", "g/g^2")}
    input_unit, output_unit = "g", "mA"
    tc_names = {"k0": "bias_tc", "k1": "sf_tc", "k2": "k2_tc"}
    residual_names = {"k0": ("bias_residual", "bias_uncompensated"),
                      "k1": ("sf_residual", "sf_uncompensated")}

    def __init__(self, params: AccelerometerSweepParameters | None = None, **overrides: Any) -> None:
        super().__init__(params, **overrides)
        self.plan = tumble_positions(self.p.positions, 1)

    def point_duration_s(self) -> float:
        return len(self.plan) * (self.p.settle_s + self.p.average_s + 3.0)

    def thermometer(self) -> UnitThermometer:
        return AccelerometerThermometer()

    def prepare(self, ctx: Context) -> None:
        ctx.run.add_stream("thermal_tumble", {"point": "1", "t_s": "s", "inner_deg": "deg", "outer_deg": "deg",
                                              "voltage_v": "V", "voltage_se_v": "V", "n_readings": "1",
                                              "unit_c": "degC"},
                           "mean output per tumble position at each temperature, the unit's sensor")
        ctx.run.add_stream("thermal_tumble_readings", {"position": "1", "voltage_v": "V"},
                           "every DMM reading of the thermal tumbles (position = point·positions + k)")
        level_table(ctx)
        power_accelerometer(ctx, on=True)

    def measure_point(self, ctx: Context, point: int, thermometer: UnitThermometer) -> PointMeasurement:
        p, plan = self.p, self.plan
        ohm = float(ctx.wiring["sampling_resistor_ohm"])
        ch = chamber(ctx)
        means, errors, temps = np.empty(len(plan)), np.empty(len(plan)), np.empty(len(plan))
        for k, (inner, outer) in enumerate(plan):
            move_table(ctx, inner, outer)
            ctx.clock.sleep(p.settle_s)
            mean, se, n = averaged_voltage(ctx, p.average_s, p.nplc, stream="thermal_tumble_readings",
                                           tag=point * len(plan) + k)
            ch.check()  # a limit trip or an alarm ends the point, not only the soak
            temps[k] = thermometer.read_c(ctx)
            means[k], errors[k] = mean, se
            ctx.run.append("thermal_tumble", point=[point], t_s=[ctx.clock.now()], inner_deg=[inner],
                           outer_deg=[outer], voltage_v=[mean], voltage_se_v=[se], n_readings=[n],
                           unit_c=[temps[k]])
        move_table(ctx, 0.0, 0.0)
        forces = specific_force_iapo_g(plan[:, 0], plan[:, 1], site_gravity_mps2(ctx.site) / STANDARD_GRAVITY_MPS2)
        fit = fit_tumble(forces, means, None, output_unit_per_ma=ohm * 1e-3)
        if fit.dof == 0:
            fit = fit_tumble(forces, means, errors, output_unit_per_ma=ohm * 1e-3)
        keys = {"k0": "k0_g", "k1": "k1_ma_per_g", "k2": "k2_g_per_g2"}
        values = {q: _value_std(fit.params[key]) for q, key in keys.items() if key in fit.params}
        return PointMeasurement(values, float(temps.mean()), _temperature_std(temps),
                                {"fit_residual_rms_g": fit.rms_g})


def unit_identity(ctx: Context, kind: str) -> tuple[str, str]:
    """(serial, model) of the unit under test: the run's serial; the model of the spec an
    acceptance run judges against, else the unit's kind."""
    store = ctx.run.store
    serial = store.get_run(ctx.run.id).unit_serial or "unknown"
    spec = store.results(ctx.run.id).get("acceptance.spec") or {}
    return serial, str(spec.get("model") or kind)


def _value_std(estimate: Any) -> tuple[float, float]:
    """(value, standard uncertainty) of an estimate; NaN when it states none."""
    std = estimate.std
    return float(estimate.value), math.nan if std is None else float(std)


def _temperature_std(temps: np.ndarray) -> float:
    """The point's temperature uncertainty: the readings' spread over the measurement (the
    unit drifting while it is measured), at least the sensor's 0.01 °C resolution."""
    return float(max(np.std(temps, ddof=1) if temps.size > 1 else 0.0, 0.01))


# --------------------------------------------------------------------------- gyro


@dataclass
class GyroSweepParameters(SweepParameters):
    rates_per_sign: int = parameter(2, "table rates of each sign per temperature, log-spaced")
    min_fraction: float = parameter(0.05, "smallest rate as a fraction of full scale")
    max_fraction: float = parameter(0.9, "largest rate as a fraction of full scale")
    min_record_s: float = parameter(60.0, "record per rate, rounded up to whole revolutions, s")
    settle_s: float = parameter(2.0, "after 'at rate', before recording, s")
    frame_rate_hz: int = parameter(200, "gyro frame rate while recording, Hz")

    def validate(self) -> None:
        super().validate()
        check_ranges(asdict(self), {"rates_per_sign": (1, 30), "min_fraction": (1e-4, 0.99),
                                    "max_fraction": (0.01, 1.0), "min_record_s": (1, 36000),
                                    "settle_s": (0, 600), "frame_rate_hz": (1, 4608)},
                     integers=("rates_per_sign", "frame_rate_hz"))
        if not self.min_fraction < self.max_fraction:
            raise ValueError(f"min_fraction = {self.min_fraction} must be < max_fraction = {self.max_fraction}")


class GyroThermalSweep(ThermalSweepBase[GyroSweepParameters]):
    """Gyro calibration over temperature: a rate-table sequence at each soaked temperature.

    Bias and scale factor as polynomials of the gyro's sensor temperature, their temperature
    coefficients, the compensation file, and its verification on a falling profile at other
    temperatures (compensated and uncompensated residuals).
    """

    name = "gyro_thermal_sweep"
    requires = ("gyro", "supply", "turntable", "chamber")
    kinds = ("gyro",)
    produces = sweep_produces("deg/h")
    Parameters = GyroSweepParameters
    quantities = {"bias": ("bias", "deg/h"), "scale_factor": ("scale_factor", "1")}
    input_unit, output_unit = "deg/h", "deg/h indicated"
    tc_names = {"bias": "bias_tc", "scale_factor": "sf_tc"}
    residual_names = {"bias": ("bias_residual", "bias_uncompensated"),
                      "scale_factor": ("sf_residual", "sf_uncompensated")}

    def _plan(self, full_scale_dps: float) -> np.ndarray:
        p = self.p
        return rate_plan(full_scale_dps, p.rates_per_sign, min_fraction=p.min_fraction, max_fraction=p.max_fraction)

    def point_duration_s(self) -> float:
        plan = self._plan(500.0)
        return sum(whole_revolution_duration_s(r, self.p.min_record_s) + self.p.settle_s + 10.0 for r in plan)

    def thermometer(self) -> UnitThermometer:
        return GyroThermometer()

    def prepare(self, ctx: Context) -> None:
        ctx.run.add_stream("thermal_rate_frames", {"point": "1", "t_s": "s", "table_rate_dps": "deg/s",
                                                   "rate_dps": "deg/s", "temperature_c": "degC",
                                                   "status": "1"},
                           "every gyro frame recorded at rate, at each temperature")
        ctx.run.add_stream("thermal_rates", {"point": "1", "table_rate_dps": "deg/s", "input_rate_dps": "deg/s",
                                             "output_dps": "deg/s", "output_se_dps": "deg/s", "frames": "1",
                                             "unit_c": "degC"},
                           "mean indicated rate per table rate at each temperature")
        level_table(ctx)
        power_gyro(ctx, on=True)
        ctx.clock.sleep(5.0)  # boot before the first question
        self.full_scale_dps = frame_gyro(ctx).config.full_scale_dps

    def measure_point(self, ctx: Context, point: int, thermometer: UnitThermometer) -> PointMeasurement:
        p = self.p
        gyro, axis, ch = frame_gyro(ctx), turntable(ctx).axis[1], chamber(ctx)
        fs = self.full_scale_dps
        plan = self._plan(fs)
        earth_dps = earth_rate_vertical_dph(ctx.site["latitude_deg"]) / 3600.0
        gyro.configure(rate_hz=p.frame_rate_hz)
        previous_limit = axis.rate_limit_dps
        axis.rate_limit_dps = float(np.max(np.abs(plan))) * 1.02
        means, errors, temps = np.empty(plan.size), np.empty(plan.size), np.empty(plan.size)
        try:
            for j, rate in enumerate(plan):
                axis.set_rate(float(rate))
                axis.wait_at_rate(ctx.clock.sleep, timeout_s=AT_RATE_TIMEOUT_S)
                ctx.clock.sleep(p.settle_s)
                n = int(round(whole_revolution_duration_s(float(rate), p.min_record_s) * p.frame_rate_hz))
                t_start = ctx.clock.now()

                def store(frames: GyroFrames, rate: float = float(rate), t_start: float = t_start) -> None:
                    ctx.run.append("thermal_rate_frames", point=np.full(len(frames), point),
                                   t_s=t_start + frames.t_s, table_rate_dps=np.full(len(frames), rate),
                                   rate_dps=frames.rate_dps, temperature_c=frames.temperature_c,
                                   status=frames.status)

                gyro.start()
                frames = read_gyro_frames(ctx, n, store, stop=True)
                ch.check()
                revolutions = n / p.frame_rate_hz * abs(rate) / 360.0
                means[j] = float(frames.rate_dps.mean())
                errors[j] = revolution_standard_error(frames.rate_dps, revolutions)
                temps[j] = float(frames.temperature_c.mean())
                ctx.run.append("thermal_rates", point=[point], table_rate_dps=[rate], input_rate_dps=[rate + earth_dps],
                               output_dps=[means[j]], output_se_dps=[errors[j]], frames=[len(frames)],
                               unit_c=[temps[j]])
        finally:
            try:
                axis.stop()
                axis.wait_in_position(ctx.clock.sleep, timeout_s=AT_RATE_TIMEOUT_S)
            finally:
                axis.rate_limit_dps = previous_limit
        common = np.full(plan.size, float(np.sqrt(np.mean(errors**2))))
        fit = fit_rate_table(plan + earth_dps, means, common, full_scale_dps=fs)
        sfe = fit.scale_factor_error_ppm
        sfe_value, sfe_std = _value_std(sfe)
        values = {"bias": _value_std(fit.bias_dph), "scale_factor": (1.0 + 1e-6 * sfe_value, 1e-6 * sfe_std)}
        return PointMeasurement(values, float(temps.mean()), _temperature_std(temps),
                                {"scale_factor_error_ppm": sfe.value, "nonlinearity_ppm": fit.nonlinearity_ppm.value})


def revolution_standard_error(rate_dps: np.ndarray, revolutions: float) -> float:
    """σ of a record's mean from the spread of its whole-revolution means (8 equal blocks when
    it holds fewer than 3 revolutions)."""
    blocks = int(round(revolutions)) if revolutions >= 3 else 8
    blocks = max(2, min(blocks, rate_dps.size // 2))
    m = rate_dps.size // blocks
    means = rate_dps[: m * blocks].reshape(blocks, m).mean(axis=1)
    return float(means.std(ddof=1) / math.sqrt(blocks))


__all__ = ["ThermalSweep", "GyroThermalSweep", "SweepParameters", "AccelerometerSweepParameters",
           "GyroSweepParameters", "PointMeasurement", "sweep_temperatures", "verification_temperatures",
           "revolution_standard_error", "COMPENSATION_FILE"]
