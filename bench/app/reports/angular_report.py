"""HTML report of the angular rig (Document B): frequency response and fusion.

:func:`write_angular_report` writes into one directory:

* ``angular_report.html`` (``templates/angular.html.j2`` on the shared layout; its PDF beside
  it) — the story: each sensor's FRF and fitted model, the alignment, how every method was
  tuned, the side-by-side table of every method (RMS error, worst amplitude/phase error, worst
  excess over the better sensor, the recommended one in bold), the per-tone error tables, NIS,
  and whether Document B's claims hold on this run;
* ``angular_frf.png`` — FRF magnitude and phase of both sensors (points with ±2σ bars)
  and the fitted models (with their delays);
* ``angular_errors.png`` — amplitude error (%) and phase error (deg) against frequency for
  every method on one plot (the recommended one drawn heaviest);
* ``angular_tuning.png`` — every tuning candidate's RMS error against its worst excess
  amplitude error, fixed R and adaptive R at each process noise;
* ``angular_time.png`` — a window of the record: reference, each sensor alone, the fused
  rate, and every method's error;
* ``angular_report.json`` — the results it was made from.

It takes the run's stored results (``frf.points``, ``frf.fits``, ``fusion.analysis``,
``fusion.alignment``) and, for the time plot, the ``fusion_aligned`` stream; a run with
only an FRF gets the FRF part.  Figures use matplotlib's object API (no pyplot state).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from bench.analysis.fusion import METHODS, SensorModel, excess_over_best
from bench.app.reports.common import save_figure
from bench.app.reports.layout import context_header, write_report

#: plot style per method (colour, marker); every method of the registry has one
STYLE = {"hf": ("C1", "v"), "lf": ("C4", "D"), "complementary": ("C2", "^"), "fused": ("C3", "o"),
         "fixed_r_kf": ("C0", "s"), "complementary_kf": ("C5", "P"), "complementary_kf_adaptive": ("C6", "X"),
         "complementary_smoother": ("C9", "*"), "complementary_smoother_adaptive": ("C8", "h")}
SENSORS = {"hf": ("MHD (HF) sensor", "V/(deg/s)"), "lf": ("LF sensor", "(deg/s)/(deg/s)")}
WINDOW_S = 2.0


def column(method: str) -> str:
    """``fusion_aligned`` column of a method's estimate (as procedures.fusion.estimate_column writes it)."""
    return {"hf": "hf_alone_dps", "lf": "lf_alone_dps"}.get(method, f"{method}_dps")


def _methods(analysis: dict) -> list[str]:
    """The methods an analysis judged, in registry order (a run stored before the registry grew
    has fewer)."""
    return [k for k in METHODS if k in (analysis.get("rms_error") or {})]


def _label(method: str) -> str:
    return METHODS[method].label if method in METHODS else method


def _model_response(fit: dict, f: np.ndarray) -> np.ndarray:
    m = SensorModel(**fit["model"])
    return m.response(f) * np.exp(-2j * np.pi * f * fit.get("delay_s", 0.0))


def frf_figure(points: dict, fits: dict, path: Path) -> str:
    fig = Figure(figsize=(9, 6.5))
    axes = fig.subplots(2, 2, sharex=True)
    f = np.asarray(points["freq_hz"], dtype=float)
    fine = np.logspace(math.log10(f.min()), math.log10(f.max()), 400)
    for col, (sensor, (title, unit)) in enumerate(SENSORS.items()):
        measured = [(fk, r) for fk, r in zip(f, points[sensor]) if r is not None]
        fm = np.array([fk for fk, _ in measured])
        mag = np.array([r["mag"] for _, r in measured])
        mag_sd = np.array([r["mag_std"] for _, r in measured])
        ph = np.array([r["phase_deg"] for _, r in measured])
        ph_sd = np.array([r["phase_std_deg"] for _, r in measured])
        ax_m, ax_p = axes[0, col], axes[1, col]
        ax_m.errorbar(fm, mag, yerr=2 * mag_sd, fmt="o", ms=4, color="k", label="measured (±2σ)")
        ax_p.errorbar(fm, ph, yerr=2 * ph_sd, fmt="o", ms=4, color="k")
        if sensor in fits:
            g = _model_response(fits[sensor], fine)
            m = fits[sensor]["model"]
            label = (f"fit: {m['kind']} order {m['order']}, {m['corner_hz']:.3g} Hz, "
                     f"delay {1e6 * fits[sensor].get('delay_s', 0.0):.3g} µs")
            ax_m.plot(fine, np.abs(g), color="C3", lw=1.2, label=label)
            ax_p.plot(fine, np.degrees(np.angle(g)), color="C3", lw=1.2)
        ax_m.set_xscale("log")
        ax_m.set_yscale("log")
        ax_m.set_title(title, fontsize=9)
        ax_m.set_ylabel(f"|H| ({unit})", fontsize=8)
        ax_p.set_ylabel("phase (deg)", fontsize=8)
        ax_p.set_xlabel("frequency (Hz)", fontsize=8)
        ax_m.legend(fontsize=7)
        for ax in (ax_m, ax_p):
            ax.grid(True, which="both", lw=0.3)
            ax.tick_params(labelsize=7)
    return save_figure(fig, path)


def errors_figure(analysis: dict, path: Path) -> str:
    f = np.asarray(analysis["tones_hz"], dtype=float)
    fig = Figure(figsize=(9, 6.5))
    ax_a, ax_p = fig.subplots(2, 1, sharex=True)
    recommended = analysis.get("recommended")
    for method in _methods(analysis):
        colour, marker = STYLE.get(method, ("k", "."))
        lw = 2.4 if method == recommended else 1.0
        label = _label(method) + (" — recommended" if method == recommended else "")
        amp = np.abs(np.asarray(analysis["amplitude_error_pct"][method], dtype=float))
        ph = np.asarray(analysis["phase_error_deg"][method], dtype=float)
        ax_a.plot(f, np.maximum(amp, 1e-5), marker=marker, color=colour, lw=lw, ms=4, label=label)
        ax_p.plot(f, ph, marker=marker, color=colour, lw=lw, ms=4, label=label)
    ax_a.set_xscale("log")
    ax_a.set_yscale("log")
    ax_a.set_ylabel("|amplitude error| (%)")
    ax_p.set_ylabel("phase error (deg)")
    ax_p.set_yscale("symlog", linthresh=0.01)
    ax_p.set_xlabel("tone frequency (Hz)")
    ax_a.set_title("error against the table reference, every method on the same (judged) record")
    ax_a.legend(fontsize=6, ncol=2)
    for ax in (ax_a, ax_p):
        ax.grid(True, which="both", lw=0.3)
    return save_figure(fig, path)


def time_figure(aligned: dict, path: Path, recommended: str | None = None) -> str:
    t = np.asarray(aligned["t_s"], dtype=float)
    mid = t[0] + 0.5 * (t[-1] - t[0])
    sel = (t >= mid) & (t <= mid + WINDOW_S)
    tt = t[sel] - t[sel][0]
    ref = np.asarray(aligned["ref_dps"])[sel]
    fig = Figure(figsize=(9, 6))
    ax_s, ax_e = fig.subplots(2, 1, sharex=True)
    ax_s.plot(tt, ref, color="k", lw=1.5, label="table reference")
    shown = ["hf", "lf", "fused"] + ([recommended] if recommended not in (None, "hf", "lf", "fused") else [])
    for method in shown:
        if column(method) in aligned:
            ax_s.plot(tt, np.asarray(aligned[column(method)])[sel], color=STYLE.get(method, ("k", "."))[0], lw=0.8,
                      label=_label(method))
    for method in [m for m in METHODS if m not in ("hf", "lf")]:
        if column(method) in aligned:
            ax_e.plot(tt, np.asarray(aligned[column(method)])[sel] - ref, color=STYLE.get(method, ("k", "."))[0],
                      lw=1.2 if method == recommended else 0.5, label=_label(method))
    ax_s.set_ylabel("rate (deg/s)")
    ax_e.set_ylabel("error (deg/s)")
    ax_e.set_xlabel(f"time from {mid:.4g} s (s)")
    ax_s.legend(fontsize=7, ncol=2)
    ax_e.legend(fontsize=6, ncol=2)
    for ax in (ax_s, ax_e):
        ax.grid(True, lw=0.3)
    return save_figure(fig, path)


def tuning_figure(tuning: dict, path: Path) -> str:
    """RMS error against worst excess amplitude error of every tuning candidate: fixed R
    (``upper_factor`` 1) and adaptive R side by side at each process-noise factor."""
    fig = Figure(figsize=(9, 4.5))
    ax = fig.subplots()
    cands = tuning["candidates"]
    qs = sorted({c["q_factor"] for c in cands})
    for i, qf in enumerate(qs):
        for fixed in (True, False):
            sel = [c for c in cands if c["q_factor"] == qf and (c["upper_factor"] == 1.0) == fixed]
            if sel:
                ax.scatter([c["rms_error"] for c in sel], [c["excess_pct"] for c in sel], color=f"C{i}",
                           marker="s" if fixed else "o", s=40 if fixed else 18, facecolors="none" if fixed else None,
                           label=f"q×{qf:g} {'fixed R' if fixed else 'adaptive R'}")
    ch = tuning["chosen"]
    ax.scatter([ch["rms_error"]], [ch["excess_pct"]], marker="*", s=200, color="k", label="chosen")
    ax.set_xlabel("RMS error on the tuning stretch (deg/s)")
    ax.set_ylabel("worst excess amplitude error (pp)")
    ax.set_yscale("symlog", linthresh=0.1)
    ax.set_title("tuning: Document B's adaptive R against a fixed R at each process noise")
    ax.legend(fontsize=6, ncol=3)
    ax.grid(True, which="both", lw=0.3)
    return save_figure(fig, path)


def _fmt(x, digits: int = 4) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "—"
    return f"{x:.{digits}g}" if isinstance(x, (int, float)) else str(x)


def claims(analysis: dict) -> list[tuple[str, bool, str]]:
    """Document B's claims as checks on this run: (claim, holds, evidence).  "No worse"
    allows two standard errors of the difference (the estimates are noisy)."""
    worse, sd = excess_over_best(analysis, "fused")
    rms = analysis["rms_error"]
    f = np.asarray(analysis["tones_hz"], dtype=float)
    worst = int(np.argmax(worse - 2 * sd))
    diverged = any(v.get("diverged", False) for k, v in analysis["nis"].items() if k.startswith("fused"))
    return [
        ("fused amplitude error no worse than the better single sensor at every tone (within 2σ)",
         bool(np.all(worse <= 2 * sd)),
         f"closest: {worse[worst]:+.3g} pp ± {sd[worst]:.2g} (1σ) at {f[worst]:.4g} Hz"),
        ("fused RMS error below the fixed-R Kalman fusion's", bool(rms["fused"] < rms["fixed_r_kf"]),
         f"{rms['fused']:.5g} vs {rms['fixed_r_kf']:.5g} deg/s "
         f"({100 * (rms['fused'] / rms['fixed_r_kf'] - 1):+.3f} %)"),
        ("the sequential filter does not diverge (NIS)", not diverged,
         ", ".join(f"{k} mean NIS {v['mean']:.3g}" for k, v in analysis["nis"].items() if k.startswith("fused"))),
    ]


def _settings_text(analysis: dict) -> list[str]:
    """One line per tuned method: what the tuning part chose."""
    methods = analysis.get("methods") or {}
    out = []
    cf = (methods.get("complementary") or {}).get("settings") or {}
    if cf:
        out.append(f"complementary filter: crossover {cf['crossover_hz']:.4g} Hz")
    ckf = (methods.get("complementary_kf") or {}).get("settings") or {}
    if ckf:
        nz = ckf["noise"]
        out.append(f"complementary Kalman filter (maximum likelihood): HF noise σ² {nz['hf_var']:.3g}, LF noise σ² "
                   f"{nz['lf_var']:.3g}, HF offset walk {nz['offset_rw']:.3g} /s")
    ad = (methods.get("complementary_kf_adaptive") or {}).get("settings") or {}
    if ad:
        lfn = ad["lf_noise"]
        out.append(f"adaptive R on top: LF R between {lfn['r_lower']:.3g} and {lfn['r_upper']:.3g}, disturbed "
                   f"{lfn['a'][2]:.3g}")
    fixed = (methods.get("fixed_r_kf") or {}).get("settings") or {}
    if fixed:
        out.append(f"fixed-R Kalman filter: q {fixed['q']:.4g} (deg/s)²/s")
    return out


#: most tones in one per-tone table (a printed page holds this many number columns beside the method)
TONES_PER_TABLE = 8


def _frf_part(results: dict, folder: Path) -> dict | None:
    points, fits = results.get("frf.points"), results.get("frf.fits", {})
    if not points:
        return None
    png = frf_figure(points, fits, folder / "angular_frf.png")
    rows: list[list[object]] = []
    for sensor, (title, _unit) in SENSORS.items():
        fit = fits.get(sensor)
        if fit:
            m = fit["model"]
            rows.append([title, f"{m['kind']} order {m['order']}", _fmt(m["corner_hz"]), _fmt(m["gain"]),
                         _fmt(m.get("zeta")), _fmt(1e6 * fit.get("delay_s", 0.0)), _fmt(fit["residual"], 3)])
    return {"png": png, "rows": rows}


def _alignment_text(align: dict) -> str:
    clock = align.get("clock", {})
    return (f"MHD offset {_fmt(align.get('hf_offset_v'))} V and LF bias {_fmt(align.get('lf_bias_dps'))} deg/s "
            f"(static segment) removed; LF clock error {_fmt(clock.get('rate_error_ppm'))} ppm "
            f"(± {_fmt(clock.get('rate_error_std_ppm'))}) estimated at {_fmt(clock.get('frequency_hz'))} Hz and "
            f"removed; delays moved back: MHD {_fmt(1e6 * align.get('hf_delay_s', 0.0))} µs, "
            f"LF {_fmt(1e6 * align.get('lf_delay_s', 0.0))} µs.")


def _tuning_part(tuning: dict | None, folder: Path) -> dict | None:
    if not tuning:
        return None
    ch = tuning["chosen"]
    fixed_same_q = [c for c in tuning["candidates"] if c["q_factor"] == ch["q_factor"] and c["upper_factor"] == 1]
    same = (f"; a fixed R at the same q gives {fixed_same_q[0]['rms_error']:.5g} deg/s, excess "
            f"{fixed_same_q[0]['excess_pct']:.3g} pp") if fixed_same_q else ""
    return {"png": tuning_figure(tuning, folder / "angular_tuning.png"),
            "text": f"Chosen: q × {ch['q_factor']:g} (q = {tuning['q']:.4g} (deg/s)²/s), r_upper = "
                    f"{ch['upper_factor']:g} σ², disturbed R = {ch['inflate']:g} σ² — RMS {ch['rms_error']:.5g} deg/s, "
                    f"excess {ch['excess_pct']:.3g} pp{same}. Rule: {tuning['rule']}."}


def _method_rows(analysis: dict, methods: list[str], recommended: str) -> list[list[object]]:
    rms = analysis["rms_error"]
    rows: list[list[object]] = []
    for method in methods:
        amp = np.abs(np.asarray(analysis["amplitude_error_pct"][method], dtype=float))
        ph = np.abs(np.asarray(analysis["phase_error_deg"][method], dtype=float))
        ex, sd = excess_over_best(analysis, method)
        with np.errstate(divide="ignore", invalid="ignore"):
            z = np.where(sd > 0, ex / sd, np.where(ex > 0, np.inf, 0.0))
        sensor_ok = (analysis.get("feasible_sensor") or {}).get(method)
        rows.append([_label(method) + (" (recommended)" if method == recommended else ""), _fmt(rms[method]),
                     _fmt(float(amp.max())), _fmt(float(ph.max())),
                     f"{float(ex.max()):+.3g} pp ({float(z.max()):.3g}σ)",
                     ("yes" if bool(np.all(ex <= 2 * sd)) else "no") + " / "
                     + ("—" if sensor_ok is None else "yes" if sensor_ok else "no")])
    return rows


def _per_tone_tables(analysis: dict, methods: list[str]) -> list[dict]:
    """The per-tone errors as tables of one quantity each, a row per method and a column per
    tone, at most :data:`TONES_PER_TABLE` tones to a table (a page's width)."""
    f = analysis["tones_hz"]
    per_table = -(-len(f) // -(-len(f) // TONES_PER_TABLE))  # the tones spread evenly over the tables
    tables = []
    for key, what in (("amplitude_error_pct", "amplitude error (%)"), ("phase_error_deg", "phase error (deg)")):
        for start in range(0, len(f), per_table):
            tones = range(start, min(start + per_table, len(f)))
            tables.append({"header": [f"{what} at tone (Hz)"] + [_fmt(f[i]) for i in tones],
                           "rows": [[_label(m)] + [f"{analysis[key][m][i]:+.3g}" for i in tones] for m in methods],
                           "widths": [28] + [72 // per_table] * len(tones)})
    return tables


def _fusion_part(results: dict, folder: Path, aligned: dict | None) -> dict | None:
    analysis = results.get("fusion.analysis")
    if not (analysis and analysis.get("rms_error")):
        return None
    rms = analysis["rms_error"]
    methods = _methods(analysis)
    recommended = analysis.get("recommended") or min(rms, key=rms.get)
    nis = [[k, _fmt(v["mean"]), f"{_fmt(v['lower'])}..{_fmt(v['upper'])}", "yes" if v.get("consistent") else "no",
            "yes" if v.get("diverged") else "no"] for k, v in analysis["nis"].items()]
    return {"alignment": _alignment_text(results.get("fusion.alignment", {})),
            "tuning": _tuning_part(results.get("fusion.tuning"), folder),
            "recommendation": f"Recommended: {_label(recommended)} — {analysis.get('recommendation_rule', '')}.",
            "settings": _settings_text(analysis),
            "errors_png": errors_figure(analysis, folder / "angular_errors.png"),
            "methods": _method_rows(analysis, methods, recommended),
            "method_classes": ["best" if m == recommended else "" for m in methods],
            "tones": _per_tone_tables(analysis, methods), "nis": nis,
            "claims": [[c, "holds" if ok else "does not hold", ev] for c, ok, ev in claims(analysis)],
            "time_png": None if aligned is None else time_figure(aligned, folder / "angular_time.png", recommended),
            "notes": analysis.get("notes") or []}


def write_angular_report(results: dict, folder: Path, context: dict, aligned: dict | None = None, *,
                         pdf: bool = True) -> Path:
    """Write the report (module docstring) from a run's results; returns the HTML path.

    ``context`` heads the report: the run it reports (``run`` + ``digest``: the stored run's
    digest goes to the page's foot; ``operator`` also fills the approval block's "tested by")."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    frf, fusion = _frf_part(results, folder), _fusion_part(results, folder, aligned)
    (folder / "angular_report.json").write_text(json.dumps(
        {k: results[k] for k in ("frf.points", "frf.fits", "fusion.tuning", "fusion.analysis", "fusion.alignment")
         if k in results},
        indent=1, allow_nan=False, default=float), encoding="utf-8")
    header = context_header("Angular rig — Document B", context, numbers="angular_report.json")
    return write_report(folder / "angular_report.html", "angular.html.j2", header, pdf=pdf, frf=frf, fusion=fusion)
