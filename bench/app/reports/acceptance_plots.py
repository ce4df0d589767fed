"""One figure per acceptance step, drawn from what the run stored (streams + results).

Each builder takes ``(store, run_id, results, out_dir)`` and returns ``(title, png file name,
caption)`` or None when the run holds nothing for that step (e.g. an aborted run).  New
steps register here in :data:`SECTIONS`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from bench.analysis.allan import AllanResult, overlapping_adev
from bench.app.reports.allan_plot import model_spans_text, plot_allan
from bench.app.reports.common import save_figure as _save
from bench.app.reports.thermal_plots import (
    gyro_thermal_ramp_section,
    gyro_thermal_sweep_section,
    gyro_turn_on_repeatability_section,
    thermal_ramp_section,
    thermal_sweep_section,
    turn_on_repeatability_section,
)

Section = tuple[str, str, str]


def tumble_section(store, run_id: str, results: dict[str, Any], out: Path) -> Section | None:
    fit = results.get("tumble.fit")
    if not fit or "tumble" not in store.streams(run_id):
        return None
    data = store.load(run_id, "tumble")
    res_ug = np.asarray(fit["residuals_g"]) * 1e6
    inner, outer = data["inner_deg"], data["outer_deg"]
    fig = Figure(figsize=(9, 3.8))
    ax = fig.add_subplot()
    for plane, marker in ((0.0, "o"), (90.0, "s")):
        sel = np.isclose(inner, plane)
        if sel.any():
            ax.plot(outer[sel], res_ug[sel], marker, ls="-", lw=0.6,
                    label=f"inner {plane:g}° ({'IA–OA' if plane == 0 else 'IA–PA'} plane)")
    ax.axhline(0, color="0.5", lw=0.6)
    ax.set(xlabel="outer axis angle (deg)", ylabel="fit residual (µg)",
           title="Tumble: residual of the IEEE 1293 fit per position")
    ax.legend(fontsize=8)
    name = _save(fig, out / "acceptance_tumble.png")
    dropped = fit.get("not_identifiable") or {}
    caption = (f"{len(res_ug)} positions, rms residual {fit['rms_g'] * 1e6:.3g} µg, "
               f"{fit['dof']} degrees of freedom, σ from {fit['sigma_source']}, local g "
               f"{fit['g_mps2']:.6f} m/s²." + (f" Not identifiable here: {', '.join(dropped)}."
                                                if dropped else ""))
    return "Tumble calibration", name, caption


def _turn_on_figure(t, y, r: dict[str, Any], scale: float, unit: str, png: Path) -> str:
    """Output relative to its settled value, its causal average, the band, the turn-on time."""
    n = max(1, int(round(r["smooth_s"] / float(np.median(np.diff(t))))))
    smooth = np.convolve(y, np.ones(n) / n, mode="valid")
    ts = t[n - 1:]
    step = max(1, t.size // 20000)
    settled, band = r["settled_value"], r["band"]
    k = max(1, n // 20)  # short means for the grey trace: a fast gyro's raw rate hides everything
    m = t.size // k
    tk, yk = t[: m * k].reshape(m, k).mean(axis=1), y[: m * k].reshape(m, k).mean(axis=1)
    fig = Figure(figsize=(9, 3.8))
    ax = fig.add_subplot()
    ax.plot(tk, (yk - settled) * scale, lw=0.4, color="0.7",
            label=f"output, {k * float(np.median(np.diff(t))):.3g} s means")
    ax.plot(ts[::step], (smooth[::step] - settled) * scale, lw=1.0, color="C0",
            label=f"{r['smooth_s']:g} s average")
    ax.axhspan(-band * scale, band * scale, color="C2", alpha=0.15, label=f"±{band * scale:g} {unit} band")
    ax.axvline(r["turn_on_time_s"], color="C3", lw=1.0, label=f"turn-on time {_turn_on_text(r)}")
    lim = max(5 * band, 1.2 * float(np.max(np.abs(smooth - settled)))) * scale
    ax.set(xlabel="time since power-on (s)", ylabel=f"output − settled ({unit})", ylim=(-lim, lim),
           title="Start-up: output relative to its settled value")
    ax.legend(fontsize=8, loc="upper right")
    return _save(fig, png)


def _turn_on_text(r: dict[str, Any]) -> str:
    """The turn-on time as measured, or as the upper bound it is when the first full average
    was already in the band."""
    if r.get("resolved", True):
        return f"{r['turn_on_time_s']:.0f} s"
    return f"≤ {r['turn_on_time_s']:.0f} s (in the band from the first full {r['smooth_s']:g}-s average)"


def _bound_note(r: dict[str, Any]) -> str:
    if r.get("resolved", True):
        return ""
    return (f" The output was within the band from the first full {r['smooth_s']:g}-s average, so the "
            f"turn-on time ({r['turn_on_time_s']:.0f} s in the table) is an upper bound: the unit settled "
            "sooner than the averaging window can resolve.")


def startup_section(store, run_id: str, results: dict[str, Any], out: Path) -> Section | None:
    r = results.get("startup.turn_on")
    if not r or "output" not in store.streams(run_id):
        return None
    data = store.load(run_id, "output")
    t, g = np.asarray(data["t_s"]), np.asarray(data["acceleration_g"])
    keep = t >= 0
    name = _turn_on_figure(t[keep], g[keep], r, 1e6, "µg", out / "acceptance_startup.png")
    caption = (f"Settled value {r['settled_value']:.7g} g (mean of the last part of the record); "
               f"warm-up drift of the fitted trend {r['warmup_drift'] * 1e6:.3g} µg ({r['trend']['kind']})."
               + _bound_note(r))
    return "Start-up", name, caption


def gyro_startup_section(store, run_id: str, results: dict[str, Any], out: Path) -> Section | None:
    r = results.get("gyro_startup.turn_on")
    if not r or "gyro_startup" not in store.streams(run_id):
        return None
    data = store.load(run_id, "gyro_startup")
    valid = (np.asarray(data["status"]).astype(np.int64) & 1) != 0  # READY
    t, rate = np.asarray(data["t_s"])[valid], np.asarray(data["rate_dps"])[valid] * 3600.0
    name = _turn_on_figure(t, rate, r, 1.0, "°/h", out / "acceptance_gyro_startup.png")
    caption = (f"First valid output {r['first_valid_s']:.2f} s after power-on; settled rate "
               f"{r['settled_value']:.4g} °/h (Earth rate included); warm-up drift of the fitted "
               f"trend {r['warmup_drift']:.3g} °/h ({r['trend']['kind']})." + _bound_note(r))
    return "Start-up", name, caption


def ratetable_section(store, run_id: str, results: dict[str, Any], out: Path) -> Section | None:
    fit = results.get("ratetable.fit")
    if not fit:
        return None
    w = np.asarray(fit["input_rate_dps"])
    res = np.asarray(fit["residuals_ppm_fs"])
    err = np.asarray(fit["residual_std_ppm_fs"])
    fig = Figure(figsize=(9, 3.8))
    ax = fig.add_subplot()
    for sign, colour, label in ((1, "C0", "positive rates"), (-1, "C3", "negative rates")):
        sel = np.sign(w) == sign
        ax.errorbar(np.abs(w[sel]), res[sel], yerr=err[sel], fmt="o", color=colour, ms=4,
                    capsize=2, label=label)
    ax.axhline(0, color="0.5", lw=0.6)
    ax.set_xscale("log")
    ax.set(xlabel="|input rate| (°/s)", ylabel="residual (ppm of full-scale output)",
           title="Rate table: residuals of the least-squares line")
    ax.legend(fontsize=8)
    name = _save(fig, out / "acceptance_ratetable.png")
    sf, asym = fit["scale_factor_error_ppm"], fit["asymmetry_ppm"]
    caption = (f"{w.size} rates, whole revolutions each; Earth rate {fit['earth_rate_dps'] * 3600:.3f} °/h "
               f"added to the table rate. Scale-factor error {sf['value']:.2f} ± {sf['std']:.2g} ppm, "
               f"asymmetry {asym['value']:.2f} ± {asym['std']:.2g} ppm, nonlinearity at "
               f"{fit['nonlinearity_at_rate_dps']:.4g} °/s.")
    return "Rate-table calibration", name, caption


def _allan_section(title: str, png: str, record, rate_hz: float, unit: str,
                   out: Path) -> tuple[str, str, AllanResult]:
    result = overlapping_adev(record, rate_hz, "octave", unit=unit)  # the same reduction as the step
    fig = Figure(figsize=(8, 5))
    plot_allan(fig.add_subplot(), result, title=title, fit_values=False)
    spans = model_spans_text(result)
    drawn = (f"; the fitted model is drawn where it lies within the intervals ({spans})" if spans
             else "; the fitted model lies outside the intervals everywhere and is not drawn")
    caption = (f"{result.n_samples} samples at {rate_hz:g} Hz ({result.n_samples / rate_hz / 3600:.2f} h); "
               f"68 % confidence intervals{drawn}.")
    return _save(fig, out / png), caption, result


def _fmt(x) -> str:
    return "—" if x is None else f"{x:.4g}"


def _micro(x: float | None) -> str:
    return "—" if x is None else f"{x * 1e6:.4g}"


def accelerometer_noise_section(store, run_id: str, results: dict[str, Any], out: Path) -> Section | None:
    r = results.get("accelerometer_noise.allan")
    if not r or "noise" not in store.streams(run_id):
        return None
    v = np.asarray(store.load(run_id, "noise")["voltage_v"])
    name, caption, result = _allan_section("Accelerometer static record: Allan deviation",
                                           "acceptance_noise.png", v / v.mean(), r["sample_rate_hz"], "g", out)
    n, b = result.coefficients["N"], result.coefficients["B"]
    duty = math.sqrt(r["aperture_s"] / r["interval_s"])
    density = None if n.read_off is None else n.read_off * math.sqrt(2.0) * duty
    return "Bias stability and noise", name, caption + (
        f" The table's values are read off this curve: N (IEEE 952 velocity random walk, the −½ slope line "
        f"at τ = 1 s) = {_micro(n.read_off)} µg/√Hz; noise_density is the one-sided density √2·N, corrected "
        f"for the DMM aperture ({r['aperture_s']:g} s of each {r['interval_s']:g} s reading, "
        f"×√{r['aperture_s'] / r['interval_s']:.3g}) = {_micro(density)} µg/√Hz; bias_instability is B, the "
        f"curve's minimum ÷ 0.664 = {_micro(b.read_off)} µg.")


def gyro_noise_section(store, run_id: str, results: dict[str, Any], out: Path) -> Section | None:
    r = results.get("gyro_noise.allan")
    if not r or "gyro_static" not in store.streams(run_id):
        return None
    rate = np.asarray(store.load(run_id, "gyro_static")["rate_dps"])
    name, caption, result = _allan_section("Gyro static record: Allan deviation", "acceptance_gyro_noise.png",
                                           rate, r["sample_rate_hz"], "dps", out)
    n, b = result.coefficients["N"], result.coefficients["B"]
    return "Bias stability and noise", name, caption + (
        f" The table's values are read off this curve: arw is N (IEEE 952 angle random walk, the −½ slope "
        f"line at τ = 1 s) = {_fmt(n.read_off)} {n.unit} ({_fmt(n.to_dict()['alt']['read_off'])} "
        f"{n.alt_unit}); bias_instability is B, the curve's minimum ÷ 0.664 = {_fmt(b.read_off)} {b.unit} "
        f"({_fmt(b.to_dict()['alt']['read_off'])} {b.alt_unit}).")


def vibration_section(store, run_id: str, results: dict[str, Any], out: Path) -> Section | None:
    stats = results.get("vibration.statistics")
    if not stats or "gyro_frames" not in store.streams(run_id):
        return None
    f = store.load(run_id, "gyro_frames")
    t, rate, seg = np.asarray(f["t_s"]), np.asarray(f["rate_dps"]), np.asarray(f["segment"])
    # 1-s means show the rectified shift the raw 2 kHz rate buries in its noise
    per_s = max(1, int(round(1.0 / float(np.median(np.diff(t))))))
    m = t.size // per_s
    tm = t[: m * per_s].reshape(m, per_s).mean(axis=1) - t[0]
    rm = rate[: m * per_s].reshape(m, per_s).mean(axis=1) * 3600.0
    sm = seg[: m * per_s].reshape(m, per_s).max(axis=1)
    fig = Figure(figsize=(9, 4.5))
    ax, ax2 = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [3, 1]})
    for k, (colour, label) in enumerate((("C0", "static"), ("C3", "random vibration"),
                                         ("C0", None))):
        sel = sm == k
        ax.plot(tm[sel], rm[sel], ".", ms=2, color=colour, label=label)
    ax.set(ylabel="1-s mean rate (°/h)",
           title=f"Vibration: bias shift {stats['bias_shift_dph']:.3g} ± {stats['bias_shift_se_dph']:.2g} °/h")
    ax.legend(fontsize=8)
    if "shaker_level" in store.streams(run_id):
        lv = store.load(run_id, "shaker_level")
        ax2.plot(np.asarray(lv["t_s"]) - t[0], lv["level_grms"], color="0.3")
    ax2.set(xlabel="time (s)", ylabel="level (g rms)")
    name = _save(fig, out / "acceptance_vibration.png")
    caption = (f"Control level {stats['level_grms']:.3g} ± {stats['level_sd_grms']:.2g} g rms; rate noise "
               f"{stats['static_noise_dps']:.3g} °/s static, {stats['vibration_rms_dps']:.3g} °/s under "
               "vibration; the shift is the vibrated mean minus the line through the static segments. "
               "Document C's model of the record: bench run vibration --analyze.")
    return "Random vibration", name, caption


#: step name → section builder
SECTIONS: dict[str, Callable[..., Section | None]] = {
    "turn_on": startup_section,
    "gyro_turn_on": gyro_startup_section,
    "tumble": tumble_section,
    "ratetable": ratetable_section,
    "accelerometer_noise": accelerometer_noise_section,
    "gyro_noise": gyro_noise_section,
    "vibration": vibration_section,
    "thermal_sweep": thermal_sweep_section,
    "gyro_thermal_sweep": gyro_thermal_sweep_section,
    "thermal_ramp": thermal_ramp_section,
    "gyro_thermal_ramp": gyro_thermal_ramp_section,
    "turn_on_repeatability": turn_on_repeatability_section,
    "gyro_turn_on_repeatability": gyro_turn_on_repeatability_section,
}
