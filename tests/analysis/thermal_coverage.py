"""Coverage figures of the thermal analysis, measured on the tests' own generator.

    .venv/bin/python -m tests.analysis.thermal_coverage [--quick] [--only order|compensation|ramp|record|repeatability]

Prints what docs/METHODS.md ("Calibration over temperature") states: the order choice (BIC
against leave-one-out), 2σ coverage of the temperature coefficients (selected curve and
BIC-averaged), the compensated residual on a second temperature profile against the noise,
the ramp's hysteresis, rate sensitivity and switching width (a play operator), the chamber
record's bias TC, SF TC and element lag, and the turn-on repeatability interval. Not a test
(pytest does not collect it): the suite asserts the same properties on fewer draws.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from bench.analysis.thermal import (
    QuantityPoints,
    analyze_thermal_ramp,
    analyze_thermal_record,
    calibrate_over_temperature,
    compensation_model,
    fit_temperature_polynomial,
    verify_compensation,
)
from bench.analysis.turn_on import turn_on_repeatability
from bench.testing.generators.thermal_truth import (
    Program,
    ThermalUnit,
    draw_chamber_case,
    rate_table,
    simulate_chamber_record,
    simulate_ramp,
    sweep_points,
)

SWEEP_C = (-40.0, -20.0, 0.0, 25.0, 45.0, 60.0, 70.0)
VERIFY_C = (-35.0, -10.0, 10.0, 35.0, 55.0, 65.0)


def draw_bias(rng):
    """A bias curve in g: TC 1–30 µg/°C, curvature and (half the time) a cubic near the noise."""
    scale = 10 ** rng.uniform(-6, -4.5)
    return (rng.normal(0, 1e-3), rng.normal(0, 1) * scale, rng.normal(0, 1) * scale / 100,
            rng.normal(0, 1) * scale / 3e4 * (rng.uniform() < 0.5))


def _covers(est, truth: float) -> bool:
    return est.std is not None and abs(est.value - truth) <= 2 * est.std


def order_choice(n: int) -> None:
    rng = np.random.default_rng(7)
    true_order = {"bic": 0, "loo": 0}
    covered = {"bic": 0, "loo": 0}
    resid: dict[str, list[float]] = {"bic": [], "loo": []}
    averaged = 0
    for i in range(n):
        b = draw_bias(rng)
        truth = 3 if b[3] else 2
        std, ts = rng.uniform(0.5e-6, 3e-6), rng.uniform(0, 0.2)
        cal, ver = sweep_points(b, SWEEP_C, std, ts, 2 * i), sweep_points(b, VERIFY_C, std, ts, 2 * i + 1)
        for crit in ("bic", "loo"):
            f = fit_temperature_polynomial(cal.temperature_c, cal.value, cal.std,
                                           temperature_std_c=cal.temperature_std_c, criterion=crit)
            true_order[crit] += f.order == truth
            covered[crit] += _covers(f.slope_at(25.0), b[1])
            resid[crit].append(float(np.sqrt(np.mean((ver.value - f.evaluate(ver.temperature_c)) ** 2)) / std))
            if crit == "bic":
                averaged += _covers(f.averaged(lambda c: c.slope_at(25.0)), b[1])
    print(f"order choice over {n} units (7 temperatures -40..70 °C):")
    for crit in ("bic", "loo"):
        print(f"  {crit}: true order {true_order[crit] / n:.3f}, selected-curve TC 2σ coverage "
              f"{covered[crit] / n:.3f}, residual on the second profile / point σ: mean {np.mean(resid[crit]):.3f}")
    print(f"  BIC-averaged TC 2σ coverage {averaged / n:.3f}")


def _points(b, s, bstd, sstd, ts, temps, seed) -> list[QuantityPoints]:
    pb, ps = sweep_points(b, temps, bstd, ts, seed), sweep_points(s, temps, sstd, ts, seed + 1)
    return [QuantityPoints("k0", "bias", "g", pb.temperature_c, pb.value, pb.std, pb.temperature_std_c),
            QuantityPoints("k1", "scale_factor", "mA/g", ps.temperature_c, ps.value, ps.std, ps.temperature_std_c)]


def compensated_residual(n: int) -> None:
    """Bias and scale factor calibrated on one sweep, verified on another: compensated rms over
    the rms the uncertainties allow, and the χ² p-values' spread."""
    rng = np.random.default_rng(9)
    ratio: dict[str, list[float]] = {"k0": [], "k1": []}
    pvals: dict[str, list[float]] = {"k0": [], "k1": []}
    unc: list[float] = []
    for i in range(n):
        b = draw_bias(rng)
        sf0 = rng.uniform(1.2, 1.46)
        s = (sf0, sf0 * rng.normal(0, 40e-6), sf0 * rng.normal(0, 1e-7))
        bstd, sstd, ts = rng.uniform(0.5e-6, 3e-6), sf0 * rng.uniform(1e-6, 5e-6), rng.uniform(0, 0.1)
        cal = calibrate_over_temperature(_points(b, s, bstd, sstd, ts, SWEEP_C, 4 * i))
        model = compensation_model(cal, unit_serial="SN", unit_model="M", input_unit="g", output_unit="mA")
        ver = verify_compensation(model, _points(b, s, bstd, sstd, ts, VERIFY_C, 4 * i + 2), outside="skip")
        for q in ver.quantities:
            ratio[q.name].append(q.compensated_rms / q.noise_rms)
            pvals[q.name].append(q.p_value)
        unc.append(ver["k0"].uncompensated_max_abs / ver["k0"].compensated_max_abs)
    print(f"compensated residual over {n} units (second profile {VERIFY_C} °C):")
    for name in ratio:
        p = np.array(pvals[name])
        print(f"  {name}: compensated rms / noise-allowed rms: median {np.median(ratio[name]):.3f}, "
              f"90th pct {np.percentile(ratio[name], 90):.3f}; χ² p < 0.05 for {np.mean(p < 0.05):.3f} of units")
    print(f"  bias: uncompensated max / compensated max: median {np.median(unc):.0f}")


def _report(z: dict[str, list[float]], n: int) -> None:
    for name, values in z.items():
        v = np.array(values)
        print(f"  {name}: estimated in {v.size}/{n}; 2σ coverage {np.mean(np.abs(v) <= 2):.3f}; "
              f"z mean {v.mean():+.2f}, sd {v.std():.2f}")


def ramp(n: int) -> None:
    """The ramp as the suite draws it (tests/analysis/test_analysis_thermal_ramp.py): a play
    hysteresis of half width 1–8 °C, the width fitted. h is drawn over ±40 µg for h, k and the
    curve; the width's coverage counts the units whose |h| ≥ 10 µg (a hysteresis the record
    shows: the suite draws only those)."""
    rng = np.random.default_rng(13)
    prog = Program.cycles(25.0, -40.0, 70.0, (1.0, 2.0))
    z: dict[str, list[float]] = {"hysteresis": [], "rate_sensitivity": [], "switching half width (|h| ≥ 10 µg)": [],
                                 "curve at 60 °C": []}
    for i in range(n):
        h, k = rng.uniform(-40e-6, 40e-6), rng.uniform(-30e-6, 30e-6)
        white, width = rng.uniform(2e-6, 10e-6), rng.uniform(1.0, 8.0)
        coef = (1e-3, rng.uniform(1e-6, 4e-5), rng.uniform(-1e-7, 1e-7))
        unit = ThermalUnit(bias_coef=coef, hysteresis=h, rate_coef=k, tau_case_s=rng.uniform(120.0, 600.0),
                           white_sd=white, ar1_sd=white * rng.uniform(0.0, 0.1), ar1_phi=0.995, sensor_noise_c=0.01,
                           hysteresis_width_c=width)
        d = simulate_ramp(unit, prog, 10.0, seed=i)
        r = analyze_thermal_ramp(d["t"], d["output"], d["sensor"], lag_s=0.0)
        if r.hysteresis is None or r.rate_sensitivity is None or not (r.hysteresis.std and r.rate_sensitivity.std):
            continue
        z["hysteresis"].append((r.hysteresis.value - h) / r.hysteresis.std)
        z["rate_sensitivity"].append((r.rate_sensitivity.value - k) / r.rate_sensitivity.std)
        if abs(h) >= 10e-6:
            z["switching half width (|h| ≥ 10 µg)"].append((r.hysteresis_width_c.value - width)
                                                         / (r.hysteresis_width_c.std or np.inf))
        at60 = r.curve.value_at(60.0)
        z["curve at 60 °C"].append((at60.value - coef[0] - coef[1] * 35.0 - coef[2] * 35.0**2) / (at60.std or 1.0))
    print(f"thermal ramp over {n} units (two rates, 1 and 2 °C/min, play hysteresis w 1–8 °C, "
          "white + Gauss-Markov drift):")
    _report(z, n)


def _table(rates, dwell: float):
    return lambda t: rate_table(t, rates, dwell)


def record(n: int) -> None:
    """Chamber records of the chamber-record population (draw_chamber_case): bias TC, SF TC and the
    element's lag behind the case sensor."""
    rng = np.random.default_rng(41)
    z: dict[str, list[float]] = {"bias TC": [], "SF TC": [], "lag": []}
    for i in range(n):
        unit, program, rates, dwell = draw_chamber_case(rng)
        d = simulate_chamber_record(unit, program, _table(rates, dwell), 2.0, seed=100_000 + i)
        r = analyze_thermal_record(d["t"], d["output"], d["sensor"], d["applied"])
        sf = r.scale_factor_tc_ppm_per_c
        assert sf is not None  # applied was given
        z["bias TC"].append((r.bias_tc.value - unit.bias_coef[1]) / (r.bias_tc.std or np.inf))
        z["SF TC"].append((sf.value - unit.sf_ppm_coef[0]) / (sf.std or np.inf))
        z["lag"].append((r.lag_s.value - unit.tau_element_s) / (r.lag_s.std or np.inf))
    print(f"chamber record over {n} units (gyro on a rate table, -20..60 °C over 5.75 h, sensor on the case, "
          "element 300-600 s behind it):")
    _report(z, n)


def repeatability(n: int) -> None:
    rng = np.random.default_rng(17)
    hits = 0
    for _ in range(n):
        k = int(rng.integers(5, 21))
        sigma_r = 10 ** rng.uniform(-1, 1)
        u = 10 ** rng.uniform(-1, 0, k) * sigma_r * rng.uniform(0.2, 3.0)
        r = turn_on_repeatability(rng.normal(0, sigma_r, k) + rng.normal(0, 1, k) * u, u).repeatability
        hits += r.low <= sigma_r <= r.high
    print(f"turn-on repeatability: 95 % Q-profile interval coverage over {n} draws {hits / n:.4f}")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="a tenth of the draws")
    p.add_argument("--only", choices=("order", "compensation", "ramp", "record", "repeatability"), default=None)
    args = p.parse_args()
    scale = 10 if args.quick else 1
    sections = {"order": (order_choice, 1000), "compensation": (compensated_residual, 500), "ramp": (ramp, 200),
                "record": (record, 200),
                "repeatability": (repeatability, 10000)}
    for name, (fn, n) in sections.items():
        if args.only not in (None, name):
            continue
        t0 = time.perf_counter()
        fn(n // scale)
        print(f"  ({time.perf_counter() - t0:.1f} s)")


if __name__ == "__main__":
    main()
