"""Figures of the thermal steps in the acceptance report (registered in
``bench.app.reports.acceptance_plots.SECTIONS``):

* the sweep — each calibrated quantity against the unit's sensor temperature with its fitted
  polynomial and 2σ band, the calibration and the verification points, and the verification
  errors over temperature, compensated beside uncompensated;
* the ramp — the hysteresis loop: the static output against the unit's temperature, up and
  down branches apart, with the fitted curve;
* the turn-on repeatability — each turn-on's bias with its within-run uncertainty, by day.

Each builder takes ``(store, run_id, results, out_dir)`` and returns ``(title, png, caption)``
or None when the run holds nothing for that step.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from bench.app.reports.common import save_figure

Section = tuple[str, str, str]
#: display scale and unit of each stored unit
_DISPLAY = {"g": (1e6, "µg"), "mA/g": (1.0, "mA/g"), "g/g^2": (1e6, "µg/g²"), "deg/h": (1.0, "°/h"),
            "1": (1.0, ""), "ppm": (1.0, "ppm")}


def _curve(fit: dict[str, Any], t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    c, cov = np.asarray(fit["coefficients"]), np.asarray(fit["covariance"])
    rows = (t[:, None] - fit["reference_c"]) ** np.arange(c.size)
    return rows @ c, np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", rows, cov, rows), 0.0))


def sweep_section(step: str, store, run_id: str, results: dict[str, Any], out: Path) -> Section | None:
    cal = results.get(f"{step}.calibration")
    if not cal or "thermal_points" not in store.streams(run_id):
        return None
    pts = store.load(run_id, "thermal_points")
    ver = results.get(f"{step}.verification") or {"quantities": []}
    by_name = {v["name"]: v for v in ver["quantities"]}
    quantities = cal["quantities"]
    fig = Figure(figsize=(10, 3.0 * len(quantities)))
    lines = []
    for row, q in enumerate(quantities):
        name, fit = q["name"], q["fit"]
        scale, unit = _DISPLAY.get(q["unit"], (1.0, q["unit"]))
        ax = fig.add_subplot(len(quantities), 2, 2 * row + 1)
        lo, hi = fit["temperature_range_c"]
        grid = np.linspace(lo - 5, hi + 5, 200)
        value, std = _curve(fit, grid)
        ax.plot(grid, value * scale, "C0-", lw=1, label=f"fit, order {fit['order']} (BIC)")
        ax.fill_between(grid, (value - 2 * std) * scale, (value + 2 * std) * scale, color="C0", alpha=0.2)
        for phase, style, label in ((0, "o", "calibration (rising)"), (1, "s", "verification (falling)")):
            sel = pts["phase"] == phase
            if sel.any():
                ax.errorbar(pts["temperature_c"][sel], pts[name][sel] * scale, yerr=2 * pts[f"{name}_std"][sel] * scale,
                            fmt=style, ms=4, capsize=2, mfc="none" if phase else None, label=label)
        ax.set(xlabel="unit's sensor (°C)", ylabel=f"{name} ({unit})" if unit else name)
        ax.legend(fontsize=7)
        tc = q["temperature_coefficient"]
        lines.append(f"{name}: TC {tc['value']:.4g} ± {tc['std']:.2g} {q['tc_unit']} at {cal['reference_c']:g} °C, "
                     f"order {fit['order']}")
        v = by_name.get(name)
        ax2 = fig.add_subplot(len(quantities), 2, 2 * row + 2)
        if v is None:
            ax2.text(0.5, 0.5, "not verified", ha="center", va="center", transform=ax2.transAxes)
            continue
        vscale, vunit = _DISPLAY.get(v["error_unit"], (1.0, v["error_unit"]))
        t = np.asarray(v["temperature_c"])
        ax2.errorbar(t - 0.4, np.asarray(v["uncompensated_error"]) * vscale,
                     yerr=2 * np.asarray(v["uncompensated_std"]) * vscale, fmt="^", color="C3", ms=4, capsize=2,
                     label=f"uncompensated (rms {v['uncompensated_rms'] * vscale:.3g})")
        ax2.errorbar(t + 0.4, np.asarray(v["compensated_error"]) * vscale,
                     yerr=2 * np.asarray(v["compensated_std"]) * vscale, fmt="o", color="C2", ms=4, capsize=2,
                     label=f"compensated (rms {v['compensated_rms'] * vscale:.3g})")
        ax2.axhline(0, color="0.5", lw=0.6)
        ax2.set(xlabel="unit's sensor (°C)", ylabel=f"{name} error ({vunit})",
                title=f"verification: χ² = {v['chi2']:.1f} / {v['dof']}, p = {v['p_value']:.2g}")
        ax2.legend(fontsize=7)
    png = save_figure(fig, out / f"acceptance_{step}.png")
    soak = pts["soak_time_s"]
    caption = (f"{int(np.sum(pts['phase'] == 0))} calibration and {int(np.sum(pts['phase'] == 1))} verification "
               f"temperatures; soak on the unit's own sensor {soak.min() / 60:.0f}–{soak.max() / 60:.0f} min. "
               + "; ".join(lines) + ". Error bars 2σ; band: the fit's 2σ. The compensation file is stored "
               "with the run (thermal_compensation.toml).")
    return "Calibration over temperature", png, caption


def thermal_sweep_section(store, run_id: str, results: dict[str, Any], out: Path) -> Section | None:
    return sweep_section("thermal_sweep", store, run_id, results, out)


def gyro_thermal_sweep_section(store, run_id: str, results: dict[str, Any], out: Path) -> Section | None:
    return sweep_section("gyro_thermal_sweep", store, run_id, results, out)


def _block_means(t: np.ndarray, *columns: np.ndarray, block_s: float) -> list[np.ndarray]:
    k = np.floor((t - t[0]) / block_s).astype(np.int64)
    n = np.bincount(k)
    keep = n > 0
    return [np.bincount(k, c)[keep] / n[keep] for c in (t, *columns)]


def ramp_section(step: str, output: str, temperature: str, scale: float, unit: str, store, run_id: str,
                 results: dict[str, Any], out: Path) -> Section | None:
    a = results.get(f"{step}.analysis")
    if not a or "thermal_ramp" not in store.streams(run_id):
        return None
    rec = store.load(run_id, "thermal_ramp")
    tb, yb, temp = _block_means(rec["t_s"], rec[output] * scale, rec[temperature], block_s=a["block_s"])
    rising = np.gradient(temp, tb) >= 0
    fig = Figure(figsize=(10, 4.2))
    ax, ax2 = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
    grid = np.linspace(temp.min(), temp.max(), 200)
    value, _ = _curve(a["curve"], grid)
    curve_at, _ = _curve(a["curve"], temp)
    for sel, colour, label in ((rising, "C3", "temperature rising"), (~rising, "C0", "temperature falling")):
        ax.plot(temp[sel], yb[sel], ".", ms=3, color=colour, label=label)
        ax2.plot(temp[sel], yb[sel] - curve_at[sel] * scale, ".", ms=3, color=colour, label=label)
    ax.plot(grid, value * scale, "k-", lw=1, label="fitted curve (zero rate, mid-branch)")
    ax.set(xlabel="unit's sensor (°C)", ylabel=f"static output ({unit})",
           title=f"Static output over the ramps ({a['block_s']:g}-s blocks)")
    ax2.axhline(0, color="0.5", lw=0.6)
    ax2.set(xlabel="unit's sensor (°C)", ylabel=f"output − fitted curve ({unit})", title="Hysteresis loop")
    ax.legend(fontsize=8)
    ax2.legend(fontsize=8)
    png = save_figure(fig, out / f"acceptance_{step}.png")

    def est(key: str, per: str = "") -> str:
        e = a.get(key)
        if not e:
            return f"{key.replace('_', ' ')}: not separable ({a['not_separable'].get(key, '')})"
        return f"{key.replace('_', ' ')} {e['value'] * scale:.3g} ± {(e['std'] or 0) * scale:.2g} {unit}{per}"

    rates = ", ".join(f"{r:.2f}" for r in a["ramp_rates_c_per_min"])
    caption = (f"Static unit over up-and-down ramps (median rates {rates} °C/min); "
               f"{est('hysteresis')}; {est('rate_sensitivity', ' per °C/min')}; {est('branch_offset')} "
               f"at the record's rates; curve order {a['order']}.")
    return "Thermal ramp: hysteresis and rate sensitivity", png, caption


def thermal_ramp_section(store, run_id: str, results: dict[str, Any], out: Path) -> Section | None:
    return ramp_section("thermal_ramp", "output_g", "unit_c", 1e6, "µg", store, run_id, results, out)


def gyro_thermal_ramp_section(store, run_id: str, results: dict[str, Any], out: Path) -> Section | None:
    return ramp_section("gyro_thermal_ramp", "rate_dps", "temperature_c", 3600.0, "°/h", store, run_id, results, out)


def repeatability_section(step: str, store, run_id: str, results: dict[str, Any], out: Path) -> Section | None:
    a = results.get(f"{step}.analysis")
    if not a or "turn_on_cycles" not in store.streams(run_id):
        return None
    scale, unit = _DISPLAY.get(a["unit"], (1.0, a["unit"]))
    cyc = store.load(run_id, "turn_on_cycles")
    fig = Figure(figsize=(9, 3.6))
    ax = fig.add_subplot()
    for day in np.unique(cyc["day"]):
        sel = cyc["day"] == day
        ax.errorbar(cyc["cycle"][sel] + 1, cyc["bias"][sel] * scale, yerr=2 * cyc["bias_std"][sel] * scale, fmt="o",
                    capsize=2, label=f"day {int(day) + 1}")
    mean = a["mean"]["value"] * scale
    ax.axhline(mean, color="0.4", lw=0.8)
    ax.axhspan(mean - a["repeatability"]["sd"] * scale, mean + a["repeatability"]["sd"] * scale, color="0.85")
    ax.set(xlabel="turn-on", ylabel=f"bias ({unit})", title="Turn-on to turn-on bias")
    ax.legend(fontsize=8)
    png = save_figure(fig, out / f"acceptance_{step}.png")
    rep = a["repeatability"]
    caption = (f"{a['n_cycles']} turn-ons; repeatability (within-run noise removed) {rep['sd'] * scale:.3g} {unit} "
               f"({rep['confidence']:.0%} interval {rep['low'] * scale:.3g} … {rep['high'] * scale:.3g}); raw "
               f"standard deviation {a['raw_sd']['sd'] * scale:.3g} {unit}; within-run noise "
               f"{a['within_run_rms'] * scale:.2g} {unit} rms. Error bars 2σ; band ±1σ repeatability.")
    return "Turn-on to turn-on repeatability", png, caption


def turn_on_repeatability_section(store, run_id: str, results: dict[str, Any], out: Path) -> Section | None:
    return repeatability_section("turn_on_repeatability", store, run_id, results, out)


def gyro_turn_on_repeatability_section(store, run_id: str, results: dict[str, Any], out: Path) -> Section | None:
    return repeatability_section("gyro_turn_on_repeatability", store, run_id, results, out)


__all__ = ["thermal_sweep_section", "gyro_thermal_sweep_section", "thermal_ramp_section",
           "gyro_thermal_ramp_section", "turn_on_repeatability_section", "gyro_turn_on_repeatability_section"]
