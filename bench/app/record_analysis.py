"""A record made elsewhere analysed as the station's step would analyse it.

:func:`analyze_record` takes a checked :class:`~bench.app.records.Record` and runs the fit its
kind's station step runs, on the same kind of numbers:

* **tumble** — the rows of one table position are averaged (their standard error from the
  given ``output_se``, else from their spread); the IEEE 1293 fit (:func:`fit_tumble`) with σ
  from the residuals when the plan leaves degrees of freedom, as the station does;
* **ratetable** — the rows of one input rate are averaged; the IEEE 952/647 line with one
  common σ (the rms of the per-rate errors), as the station does;
* **turn-on** — each cycle's bias is the mean over its settled window (the last
  ``settled_window_s``) with the within-run σ from ten block means, as the station's gyro
  step; the repeatability with the within-run noise removed (:func:`turn_on_repeatability`),
  split by day when the record has a ``day`` column; each cycle's turn-on time when a
  settling ``band`` is given;
* **thermal** — the chamber record fit with the element's temperature lagging the logged
  one (:func:`analyze_thermal_record`): bias and scale-factor polynomials of temperature,
  their coefficients at the reference, the lag, and the compensation file.

Each gives its measurements (name, value, σ, unit, what), the analysis's own JSON and a text
summary; :func:`write_report` writes one self-contained HTML report (figures inline) on the
reports' shared layout, with its PDF beside it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bench.analysis.ratetable import fit_rate_table
from bench.analysis.thermal import analyze_thermal_record, compensation_to_toml, verify_thermal_record
from bench.analysis.tumble import fit_tumble, specific_force_iapo_g
from bench.analysis.turn_on import turn_on_metrics, turn_on_repeatability
from bench.app.records import Record, RecordError, parameter

#: blocks the within-run σ of a static record's mean is read from (the station's gyro step)
BIAS_BLOCKS = 10
#: tumble measurements: IEEE 1293 symbol -> (the fit's parameter, unit, what)
TUMBLE_TERMS = {"k0": ("k0_g", "g", "bias K0"), "k1": ("k1_ma_per_g", "mA/g", "scale factor K1"),
                "k2": ("k2_g_per_g2", "g/g^2", "second-order non-linearity K2"),
                "k3": ("k3_g_per_g3", "g/g^3", "third-order non-linearity K3"),
                "delta_o": ("delta_o_rad", "rad", "input-axis misalignment δo (toward PA)"),
                "delta_p": ("delta_p_rad", "rad", "input-axis misalignment δp (toward OA)"),
                "kip": ("kip_g_per_g2", "g/g^2", "cross-coupling Kip"),
                "kio": ("kio_g_per_g2", "g/g^2", "cross-coupling Kio")}


def json_safe(value: Any) -> Any:
    """``value`` with non-finite floats as None and numpy values as Python's: a result that is
    valid JSON wherever it goes (``--json``, the run store)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    if isinstance(value, np.generic):
        return json_safe(value.item())
    if isinstance(value, np.ndarray):
        return json_safe(value.tolist())
    return value


@dataclass
class RecordAnalysis:
    """What the analysis of one record gives: measurements, the fit's JSON, a summary, figures."""

    kind: str
    measurements: list[dict[str, Any]]
    result: dict[str, Any]
    summary: list[str]
    notes: list[str] = field(default_factory=list)
    figures: list[tuple[str, Any]] = field(default_factory=list)  # (caption, matplotlib Figure)
    attachments: dict[str, tuple[bytes, str]] = field(default_factory=dict)  # name -> (bytes, mime)

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "measurements": self.measurements, "result": self.result,
                "notes": self.notes}


def _m(name: str, value: float | None, std: float | None, unit: str, what: str) -> dict[str, Any]:
    def clean(x):
        return None if x is None or not math.isfinite(float(x)) else float(x)
    return {"name": name, "value": clean(value), "uncertainty": clean(std), "unit": unit, "description": what,
            "low": None, "high": None, "outcome": "measured"}


def _groups(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unique rows of ``keys`` (n, k) in order of first appearance, and each row's group index."""
    rounded = np.round(keys, 9)
    _, first, inverse = np.unique(rounded, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    return keys[np.sort(first)], rank[inverse.ravel()]


def _group_means(y: np.ndarray, se: np.ndarray | None, index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard error per group: from the given standard errors (combined), else the
    rows' spread (None-as-NaN where a group has one row and no error was given)."""
    k = int(index.max()) + 1
    means, errors = np.empty(k), np.full(k, np.nan)
    for g in range(k):
        rows = index == g
        means[g] = y[rows].mean()
        if se is not None:
            errors[g] = math.sqrt(float(np.sum(se[rows] ** 2))) / rows.sum()
        elif rows.sum() > 1:
            errors[g] = y[rows].std(ddof=1) / math.sqrt(rows.sum())
    return means, errors


def analyze_tumble(record: Record, *, g_over_g0: float | None = None,
                   output_unit_per_ma: float | None = None) -> RecordAnalysis:
    d = record.data
    g0 = parameter(record, "g_over_g0", 1.0, 0.95, 1.05, g_over_g0)
    per_ma = parameter(record, "output_unit_per_ma", 1e-3, -1e6, 1e6, output_unit_per_ma)
    if per_ma == 0:
        raise RecordError("parameter output_unit_per_ma = 0; give the output units per mA (non-zero)")
    positions, index = _groups(np.column_stack([d["inner_deg"], d["outer_deg"]]))
    if len(positions) < 4:
        raise RecordError(f"{record.source}: {len(positions)} distinct table positions; a tumble needs at least 4")
    means, errors = _group_means(d["output"], d.get("output_se"), index)
    forces = specific_force_iapo_g(positions[:, 0], positions[:, 1], g0)
    fit = fit_tumble(forces, means, None, output_unit_per_ma=per_ma)
    if fit.dof == 0 and np.all(np.isfinite(errors)) and np.all(errors > 0):
        fit = fit_tumble(forces, means, errors, output_unit_per_ma=per_ma)
    out = [_m(name, fit.params[key].value, fit.params[key].std, unit, what)
           for name, (key, unit, what) in TUMBLE_TERMS.items() if key in fit.params]
    out.append(_m("fit_residual_rms", fit.rms_g, None, "g", "rms residual of the fit"))
    notes = [f"{name}: {fit.not_identifiable[key]}" for name, (key, _, _) in TUMBLE_TERMS.items()
             if key in fit.not_identifiable]
    summary = [f"tumble record {record.source}: {record.n_rows} rows, {len(positions)} positions, "
               f"g/g0 = {g0:g}, {per_ma:g} output units per mA"]
    fig = _figure()
    ax = fig.add_subplot()
    ax.plot(np.arange(len(positions)), np.asarray(fit.residuals_g) * 1e6, "o")
    ax.set_xlabel("position (in the record's order)")
    ax.set_ylabel("fit residual (µg)")
    ax.grid(True, alpha=0.3)
    return RecordAnalysis("tumble", out, {**fit.to_dict(), "positions_deg": positions.tolist(),
                                          "g_over_g0": g0}, summary, notes,
                          [("Residual of the IEEE 1293 fit per position", fig)])


def analyze_ratetable(record: Record, *, full_scale_dps: float | None = None,
                      nominal_scale_factor: float | None = None) -> RecordAnalysis:
    d = record.data
    rates, index = _groups(d["input_rate_dps"][:, None])
    rates = rates[:, 0]
    if len(rates) < 3:
        raise RecordError(f"{record.source}: {len(rates)} distinct input rates; a rate-table fit needs at least 3")
    fs = parameter(record, "full_scale_dps", float(np.max(np.abs(rates))), 1e-6, 1e5, full_scale_dps)
    sf = parameter(record, "nominal_scale_factor", 1.0, -1e9, 1e9, nominal_scale_factor)
    means, errors = _group_means(d["output"], d.get("output_se"), index)
    if not np.any(np.isfinite(errors)):
        raise RecordError(f"{record.source}: one row per rate and no output_se column: the standard error of each "
                          "rate's mean is unknown; give output_se or every reading")
    # IEEE 952's line is unweighted: one common σ (the rms of the per-rate errors), as the station
    common = np.full(rates.size, float(np.sqrt(np.nanmean(errors**2))))
    fit = fit_rate_table(rates, means, common, full_scale_dps=fs, nominal_scale_factor=sf)
    out = [_m("scale_factor_error", fit.scale_factor_error_ppm.value, fit.scale_factor_error_ppm.std, "ppm",
              "scale-factor error against the nominal"),
           _m("scale_factor", fit.scale_factor.value, fit.scale_factor.std, f"{record.units['output']}/(deg/s)",
              "scale factor"),
           _m("bias", fit.bias_dph.value, fit.bias_dph.std, "deg/h", "bias"),
           _m("nonlinearity", fit.nonlinearity_ppm.value, fit.nonlinearity_ppm.std, "ppm FS", "nonlinearity"),
           _m("asymmetry", fit.asymmetry_ppm.value, fit.asymmetry_ppm.std, "ppm", "asymmetry")]
    summary = [f"rate-table record {record.source}: {record.n_rows} rows, {rates.size} rates, full scale {fs:g} °/s"]
    fig = _figure()
    ax = fig.add_subplot()
    ax.plot(fit.input_rate_dps, fit.residuals_ppm_fs, "o")
    ax.set_xlabel("input rate (°/s)")
    ax.set_ylabel("residual (ppm of full scale)")
    ax.grid(True, alpha=0.3)
    return RecordAnalysis("ratetable", out, fit.to_dict(), summary, [],
                          [("Residual of the rate-table line", fig)])


def analyze_turn_on(record: Record, *, settled_window_s: float | None = None,
                    band: float | None = None) -> RecordAnalysis:
    d = record.data
    cycles = np.unique(d["cycle"])
    if cycles.size < 2:
        raise RecordError(f"{record.source}: {cycles.size} power cycle(s); turn-on repeatability needs at least 2")
    shortest = min(float(np.ptp(d["t_s"][d["cycle"] == c])) for c in cycles)
    window = parameter(record, "settled_window_s", min(300.0, shortest / 2), 1e-3, shortest, settled_window_s)
    band = parameter(record, "band", None, 0.0, math.inf, band)
    biases, stds, days, rows, notes = [], [], [], [], []
    for c in cycles:
        sel = d["cycle"] == c
        t, y = d["t_s"][sel], d["output"][sel]
        tail = y[t >= t[-1] - window]
        if tail.size < 2 * BIAS_BLOCKS:
            raise RecordError(f"{record.source}: cycle {c:g} has {tail.size} samples in its last {window:g} s; "
                              f"at least {2 * BIAS_BLOCKS} are needed")
        m = tail.size // BIAS_BLOCKS
        blocks = tail[: m * BIAS_BLOCKS].reshape(BIAS_BLOCKS, m).mean(axis=1)
        biases.append(float(tail.mean()))
        stds.append(max(float(blocks.std(ddof=1) / math.sqrt(BIAS_BLOCKS)), np.finfo(float).tiny))
        days.append(int(d["day"][sel][0]) if "day" in d else 0)
        row = {"cycle": int(c), "bias": biases[-1], "bias_std": stds[-1], "samples": int(sel.sum())}
        if band is not None:
            try:
                r = turn_on_metrics(t, y, band=band, settled_window_s=window)
                row["turn_on_time_s"] = r.turn_on_time_s
            except ValueError as exc:
                notes.append(f"cycle {c:g}: no turn-on time ({exc})")
        rows.append(row)
    split = "day" in d and len(set(days)) >= 2
    rr = turn_on_repeatability(np.array(biases), np.array(stds), day=days if split else None)
    unit = record.units["output"]
    rep, raw = rr.repeatability, rr.raw_sd
    out = [_m("turn_on_repeatability", rep.sd, (rep.high - rep.low) / (2 * 1.96), unit,
              "turn-on to turn-on bias repeatability (1σ, within-run noise removed)"),
           _m("turn_on_raw_sd", raw.sd, (raw.high - raw.low) / (2 * 1.96), unit, "standard deviation of the biases")]
    if rr.days is not None:
        for name, comp in (("day_to_day", rr.days.day_to_day), ("within_day", rr.days.within_day)):
            out.append(_m(name, comp.sd, (comp.high - comp.low) / (2 * 1.96), unit, name.replace("_", " ")))
    times = [row["turn_on_time_s"] for row in rows if row.get("turn_on_time_s") is not None]
    if times:
        out.append(_m("turn_on_time_max", max(times), None, "s", f"longest turn-on time (band ±{band:g} {unit})"))
    summary = [f"turn-on record {record.source}: {cycles.size} cycles, bias over the last {window:g} s of each"]
    fig = _figure()
    ax = fig.add_subplot()
    ax.errorbar(np.arange(1, cycles.size + 1), biases, yerr=stds, fmt="o", capsize=3)
    ax.set_xlabel("power cycle")
    ax.set_ylabel(f"bias ({unit})")
    ax.grid(True, alpha=0.3)
    return RecordAnalysis("turn-on", out, {**rr.to_dict(), "cycles": rows, "settled_window_s": window},
                          summary, notes, [("Bias of each power cycle (±1σ within run)", fig)])


def analyze_thermal(record: Record, *, reference_c: float | None = None, lag: str | None = None,
                    hysteresis: bool | None = None) -> RecordAnalysis:
    d = record.data
    ref = parameter(record, "reference_c", 25.0, -70.0, 150.0, reference_c)
    lag_text = str(lag if lag is not None else record.meta.parameters.get("lag", "fit"))
    lag_s = None if lag_text == "fit" else parameter(record, "lag", None, 0.0, 86400.0, lag_text)
    with_play = bool(hysteresis if hysteresis is not None else record.meta.parameters.get("hysteresis", False))
    r = analyze_thermal_record(d["t_s"], d["output"], d["temperature_c"], d.get("applied"), reference_c=ref,
                               lag_s=lag_s, hysteresis=with_play)
    out_unit = record.units["output"]
    in_unit = record.units.get("applied", out_unit) if "applied" in d else out_unit
    out = [_m("bias_tc", r.bias_tc.value, r.bias_tc.std, f"{in_unit}/degC",
              f"bias temperature coefficient at {ref:g} °C")]
    if r.scale_factor_tc_ppm_per_c is not None:
        e = r.scale_factor_tc_ppm_per_c
        out.append(_m("sf_tc", e.value, e.std, "ppm/degC", f"scale-factor temperature coefficient at {ref:g} °C"))
    out.append(_m("lag_s", r.lag_s.value, r.lag_s.std, "s", "the element's lag behind the logged temperature"))
    if r.hysteresis is not None:
        out.append(_m("hysteresis", r.hysteresis.value, r.hysteresis.std, out_unit, "thermal hysteresis (up − down)"))
    if r.hysteresis_width_c is not None:
        w = r.hysteresis_width_c
        out.append(_m("hysteresis_width", w.value, w.std, "degC", "travel to switch the hysteresis branch"))
    check = verify_thermal_record(r, d["t_s"], d["output"], d["temperature_c"], d.get("applied"))
    out.append(_m("compensated_rms", check.compensated_rms, None, in_unit, "rms error after compensation, this record"))
    out.append(_m("uncompensated_rms", check.uncompensated_rms, None, in_unit, "rms error without compensation"))
    notes = [f"{term}: {why}" for term, why in r.not_separable.items()] + list(r.warnings)
    model = r.compensation_model(unit_serial=record.meta.unit_serial or "unknown",
                                 unit_model=record.meta.model or "unknown", input_unit=in_unit, output_unit=out_unit,
                                 notes=f"from {Path(record.source).name} (sha256 {record.sha256[:12]}…)")
    summary = [f"thermal record {record.source}: {record.n_rows} samples over {np.ptp(d['t_s']) / 3600:.3g} h, "
               f"{d['temperature_c'].min():.3g} … {d['temperature_c'].max():.3g} °C logged"
               + (", applied input given: scale factor fitted" if "applied" in d else "")]
    fig = _figure()
    ax1, ax2 = fig.subplots(1, 2)
    used = r.block_used
    ax1.plot(r.block_element_c[used], r.block_output[used], ".", ms=3, label="block means")
    grid = np.linspace(float(np.min(r.block_element_c[used])), float(np.max(r.block_element_c[used])), 100)
    ax1.plot(grid, r.output_bias_curve.evaluate(grid), "-", label="fitted bias")
    ax1.set_xlabel("element temperature (°C)")
    ax1.set_ylabel(f"output ({out_unit})")
    ax1.legend()
    ax2.plot(r.block_t_s[used] / 3600.0, r.block_residual[used], ".", ms=3)
    ax2.set_xlabel("time (h)")
    ax2.set_ylabel(f"residual ({out_unit})")
    for ax in (ax1, ax2):
        ax.grid(True, alpha=0.3)
    return RecordAnalysis("thermal", out, {**r.to_dict(), "verification": check.to_dict()}, summary, notes,
                          [("Output over the element's temperature with the fitted bias; the residual over time", fig)],
                          {"compensation.toml": (compensation_to_toml(model).encode(), "application/toml")})


def _figure():
    from matplotlib.figure import Figure  # noqa: PLC0415 — lazy: matplotlib only when a figure is drawn

    return Figure(figsize=(8, 4))


ANALYSES: dict[str, Callable[..., RecordAnalysis]] = {
    "tumble": analyze_tumble, "ratetable": analyze_ratetable, "turn-on": analyze_turn_on, "thermal": analyze_thermal}


def analyze_record(record: Record, **options: Any) -> RecordAnalysis:
    """The analysis of ``record``'s kind (options: that kind's parameters; None = the metadata's or
    the default); RecordError for a kind with no file analysis (static, startup: ``bench analyze
    allan|startup`` and ``bench discover`` read those)."""
    if record.kind.name not in ANALYSES:
        raise RecordError(f"kind {record.kind.name!r} has no analysis of its own here; analysable kinds: "
                          f"{', '.join(ANALYSES)}")
    return ANALYSES[record.kind.name](record, **options)


def write_report(analysis: RecordAnalysis, record: Record, directory: str | Path,
                 context: dict[str, Any] | None = None, *, pdf: bool = True) -> Path:
    """Write ``<kind>_report.html`` (one file, figures inline; ``templates/record.html.j2`` on the
    shared layout), its PDF beside it (with ``pdf``), the figures as PNG files and the analysis's
    attachments into ``directory``; return the HTML path. ``context`` (optional) adds rows to the
    header: how the record was read (metadata file, options). The page's foot is the file's
    SHA-256, the one the analysis read."""
    # lazy: the page's libraries (Jinja2, matplotlib) only when a report is written
    from bench.app.reports import layout  # noqa: PLC0415 — lazy
    from bench.app.reports.common import save_figure  # noqa: PLC0415 — lazy

    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    stem = analysis.kind.replace("-", "_")
    name = Path(record.source).name
    meta = record.meta
    subject = [("record", record.source), ("kind", record.kind.name), ("unit", meta.unit_serial or "—"),
               ("model", meta.model or "—"), ("sensor", meta.sensor or "—"), ("started (UTC)", meta.started_utc),
               *((k.replace("_", " "), v) for k, v in meta.labels.items()),
               ("columns", "; ".join(f"{k} [{record.units.get(k, '—')}] ← {v}"
                                     for k, v in record.conversions.items())),
               *((k, v) for k, v in (context or {}).items() if v is not None)]
    figures = [{"png": save_figure(fig, out / f"{stem}_figure{i}.png"), "caption": caption}
               for i, (caption, fig) in enumerate(analysis.figures, 1)]

    def num(x, unc=False):
        return "—" if x is None else (f"{x:.2g}" if unc else f"{x:.6g}")
    rows = [[m["description"], m["name"], num(m["value"]), num(m["uncertainty"], True), m["unit"]]
            for m in analysis.measurements]
    header = layout.Header(title=f"{analysis.kind} analysis of {name}", subject=subject,
                           identity=layout.digest_identity([(name, record.sha256)]),
                           tested_by=meta.labels.get("operator", ""))
    path = layout.write_report(out / f"{stem}_report.html", "record.html.j2", header, pdf=pdf,
                               summary=analysis.summary, measurements=rows, figures=figures, notes=analysis.notes,
                               attachments=list(analysis.attachments))
    for attachment, (payload, _) in analysis.attachments.items():
        (out / attachment).write_bytes(payload)
    return path
