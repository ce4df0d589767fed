"""Accelerometer multi-position (tumble) calibration on the dual-axis turntable, IEEE 1293.

1. Power the unit and let it warm up at the first position.
2. For each position of the plan (N equally spaced outer angles in one or two planes):
   move both axes, wait in position, settle, average the output voltage over a timed DMM
   trace; stream the position, the mean and its standard error to the run.
3. Fit K0, K1, K2, K3, δo, δp, Kip, Kio by weighted least squares (the identifiable ones for
   this plan; the rest are named as not identifiable) with standard errors.

The specific force at each position comes from the table angles, the fixture's mount
(IA along platform z by default) and local gravity.
Output current = voltage / sampling resistor (station wiring). Local gravity: the
station's ``[site]`` (measured ``local_g_mps2``, else normal gravity at its latitude and
height) unless the step is given ``local_g_mps2``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from bench.analysis.tumble import fit_tumble, specific_force_iapo_g, tumble_positions
from bench.core.site import STANDARD_GRAVITY_MPS2, site_gravity_mps2
from bench.core.step import Context, Step, parameter
from bench.values import Estimate
from procedures.common import averaged_voltage, check_ranges, move_table, power_accelerometer

#: produced measurement → (unit, description); names follow IEEE 1293 symbols
TUMBLE_PRODUCES = {
    "k0": ("g", "bias K0"),
    "k1": ("mA/g", "scale factor K1"),
    "k2": ("g/g^2", "second-order non-linearity K2"),
    "k3": ("g/g^3", "third-order non-linearity K3"),
    "delta_o": ("rad", "input-axis misalignment δo (toward PA)"),
    "delta_p": ("rad", "input-axis misalignment δp (toward OA)"),
    "kip": ("g/g^2", "cross-coupling Kip"),
    "kio": ("g/g^2", "cross-coupling Kio"),
    "fit_residual_rms": ("g", "rms residual of the fit"),
}
_PARAM = {"k0": "k0_g", "k1": "k1_ma_per_g", "k2": "k2_g_per_g2", "k3": "k3_g_per_g3",
          "delta_o": "delta_o_rad", "delta_p": "delta_p_rad", "kip": "kip_g_per_g2",
          "kio": "kio_g_per_g2"}


@dataclass
class TumbleParameters:
    positions: int = parameter(12, "equally spaced angles per plane (a multiple of 4)")
    planes: int = parameter(2, "1: the IA–OA plane; 2: also the IA–PA plane")
    warmup_s: float = parameter(600.0, "powered, before the first position, s")
    settle_s: float = parameter(5.0, "after in position, before averaging, s")
    average_s: float = parameter(10.0, "averaging time per position, s")
    nplc: float = parameter(10.0, "DMM integration per reading, power-line cycles (0.02|0.06|0.2|1|10|100)")
    local_g_mps2: float | None = parameter(None, "local gravity, m/s² (default: the station's site — "
                                                 "its measured g, else normal gravity)")

    def validate(self) -> None:
        check_ranges(asdict(self), {
            "positions": (4, 72), "planes": (1, 2), "warmup_s": (0, 86400), "settle_s": (0, 600),
            "average_s": (0.5, 3600), "nplc": (0.02, 100), "local_g_mps2": (9.7, 9.9)},
            integers=("positions", "planes"))
        if self.positions % 4:
            raise ValueError(f"positions = {self.positions} must be a multiple of 4")
        if self.nplc not in (0.02, 0.06, 0.2, 1.0, 10.0, 100.0):
            raise ValueError(f"nplc = {self.nplc} not in 0.02|0.06|0.2|1|10|100")


class TumbleCalibration(Step[TumbleParameters]):
    """Accelerometer multi-position (tumble) calibration, IEEE 1293, on the turntable.

    K0, K1, K2, K3, δo, δp, Kip, Kio (the identifiable ones for the plan) with standard
    errors, and the fit's rms residual.
    """

    name = "tumble"
    requires = ("dmm", "supply", "turntable")
    kinds = ("accelerometer",)
    produces = TUMBLE_PRODUCES

    Parameters = TumbleParameters

    def __init__(self, params: TumbleParameters | None = None, **overrides: Any) -> None:
        super().__init__(params, **overrides)
        self.plan = tumble_positions(self.p.positions, self.p.planes)

    def producible(self) -> set[str]:
        """The measurements this plan can produce: the identifiable IEEE 1293 terms."""
        forces = specific_force_iapo_g(self.plan[:, 0], self.plan[:, 1])
        fit = fit_tumble(forces, 1e-3 * (forces[:, 0] + 1e-3))  # identifiability needs positions only
        return {name for name, key in _PARAM.items() if key in fit.params} | {"fit_residual_rms"}

    def duration_s(self) -> float:
        return self.p.warmup_s + len(self.plan) * (self.p.settle_s + self.p.average_s + 3.0)

    def run(self, ctx: Context) -> dict[str, Estimate]:
        p, plan = self.p, self.plan
        ctx.run.add_stream("tumble", {"t_s": "s", "inner_deg": "deg", "outer_deg": "deg",
                                      "voltage_v": "V", "voltage_se_v": "V", "n_readings": "1"},
                           "mean output per tumble position")
        ctx.run.add_stream("tumble_readings", {"position": "1", "voltage_v": "V"},
                           "every DMM reading, by position index")
        move_table(ctx, *plan[0])
        power_accelerometer(ctx, on=True)
        ctx.progress(0, self.duration_s(), "warming up")
        ctx.clock.sleep(p.warmup_s)
        means, errors = np.empty(len(plan)), np.empty(len(plan))
        for k, (inner, outer) in enumerate(plan):
            move_table(ctx, inner, outer)
            ctx.clock.sleep(p.settle_s)
            mean, se, n = averaged_voltage(ctx, p.average_s, p.nplc, stream="tumble_readings", tag=k)
            means[k], errors[k] = mean, se
            ctx.run.append("tumble", t_s=[ctx.clock.now()], inner_deg=[inner], outer_deg=[outer],
                           voltage_v=[mean], voltage_se_v=[se], n_readings=[n])
            ctx.progress(p.warmup_s + (k + 1) * (self.duration_s() - p.warmup_s) / len(plan),
                         self.duration_s(), f"position {k + 1}/{len(plan)} ({inner:g}°, {outer:g}°)")
        return self.fit(ctx, means, errors)

    def fit(self, ctx: Context, means: np.ndarray, errors: np.ndarray) -> dict[str, Estimate]:
        """The IEEE 1293 fit of the positions' mean output voltages (and their standard
        errors), kept under ``tumble.fit``; the produced values (also a batch's, per socket)."""
        p, plan = self.p, self.plan
        ohm = float(ctx.wiring["sampling_resistor_ohm"])
        g_mps2 = p.local_g_mps2 or site_gravity_mps2(ctx.site)
        g_over_g0 = g_mps2 / STANDARD_GRAVITY_MPS2
        forces = specific_force_iapo_g(plan[:, 0], plan[:, 1], g_over_g0)
        # Readings within a position are correlated (coloured noise), so their standard error
        # understates the scatter between positions: σ comes from the residuals when the plan
        # leaves degrees of freedom, from the per-position errors only when it does not.
        fit = fit_tumble(forces, means, None, output_unit_per_ma=ohm * 1e-3)
        if fit.dof == 0:
            fit = fit_tumble(forces, means, errors, output_unit_per_ma=ohm * 1e-3)
        ctx.run.set_result("tumble.fit", {**fit.to_dict(), "g_mps2": g_mps2, "site": ctx.site,
                                          "positions": plan.tolist()})
        out = {name: Estimate(fit.params[key].value, fit.params[key].std)
               for name, key in _PARAM.items() if key in fit.params}
        out["fit_residual_rms"] = Estimate(fit.rms_g, None)
        for name, key in _PARAM.items():
            if key in fit.not_identifiable:
                ctx.run.event(ctx.clock.now(), "not_identifiable", f"{name}: {fit.not_identifiable[key]}")
        return out
