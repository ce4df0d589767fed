"""The fleet views as single-file HTML pages (plots embedded as PNG): yield by group with its
Wilson intervals, a measurement's control charts with the flagged points, a unit's runs."""

from __future__ import annotations

import base64
import html
import io
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from bench.analysis.quality import RULES, ControlChart
from bench.app.reports.common import html_table

STYLE = ("body{font-family:sans-serif;margin:2em;max-width:1100px}table{border-collapse:collapse}"
         "td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}th{background:#eee}"
         "tr.best td{background:#fdd}")


def _png(fig: Figure) -> str:
    buffer = io.BytesIO()
    fig.tight_layout()
    fig.savefig(buffer, format="png", dpi=100)
    return f"<img alt='plot' src='data:image/png;base64,{base64.b64encode(buffer.getvalue()).decode()}'>"


def _page(title: str, body: str) -> str:
    return (f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
            f"<style>{STYLE}</style></head><body><h1>{html.escape(title)}</h1>{body}</body></html>")


def yield_page(doc: dict[str, Any]) -> str:
    groups = doc["groups"]
    fig = Figure(figsize=(9, 0.5 + 0.4 * max(len(groups), 3)))
    ax = fig.add_subplot()
    y = np.arange(len(groups))
    p = np.array([np.nan if g["yield"]["p"] is None else 100 * g["yield"]["p"] for g in groups])
    lo = np.array([100 * g["yield"]["low"] for g in groups])
    hi = np.array([100 * g["yield"]["high"] for g in groups])
    ax.errorbar(np.nan_to_num(p, nan=50.0), y, xerr=[np.nan_to_num(p - lo), np.nan_to_num(hi - p)],
                fmt="o", capsize=3)
    ax.set_yticks(y, [g["group"] for g in groups])
    ax.set_xlabel("yield, % (95 % Wilson interval)")
    ax.set_xlim(0, 100)
    ax.grid(alpha=0.3)
    rows = [[g["group"], g["passed"], g["failed"], g["aborted"],
             "—" if g["yield"]["p"] is None else f"{100 * g['yield']['p']:.1f} %",
             f"{100 * g['yield']['low']:.1f} – {100 * g['yield']['high']:.1f} %"] for g in groups]
    table = html_table([doc["by"], "passed", "failed", "aborted", "yield", "95 % interval"], rows)
    note = ("<p>Yield = passed / (passed + failed) over acceptance runs; aborted runs are no verdict "
            "and are counted apart. A unit tested twice counts twice.</p>")
    return _page(f"Yield by {doc['by']}" + (f" — {doc['model']}" if doc.get("model") else ""),
                 _png(fig) + note + table)


def _draw(ax, chart: ControlChart, label: str, low: float | None = None,
          high: float | None = None) -> None:
    """Points, centre line, control limits, the rule zones (±1σ, ±2σ; not for ranges), the
    spec limits and the flagged points."""
    x = np.arange(chart.values.size)
    ax.plot(x, chart.values, "o-", ms=3, lw=0.8, label=label)
    for level, style in ((chart.centre, "-"), (chart.lcl, "--"), (chart.ucl, "--")):
        ax.axhline(level, color="k", ls=style, lw=0.8)
    for k in (1, 2) if chart.kind != "range" else ():
        for sign in (-1, 1):
            ax.axhline(chart.centre + sign * k * chart.sigma, color="0.6", ls=":", lw=0.6)
    ax.xaxis.get_major_locator().set_params(integer=True)
    for limit in (low, high):
        if limit is not None:
            ax.axhline(limit, color="tab:red", lw=1.0)
    flagged = chart.flagged
    if flagged.size:
        ax.plot(flagged, chart.values[flagged], "o", ms=8, mfc="none", mec="tab:red",
                label="Western Electric rule broken")
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)


def spc_page(doc: dict[str, Any], chart: ControlChart, xbar: ControlChart | None,
             rng: ControlChart | None) -> str:
    unit = doc["unit"]
    n_axes = 1 if xbar is None else 3
    fig = Figure(figsize=(10, 3.2 * n_axes))
    ax = fig.add_subplot(n_axes, 1, 1)
    _draw(ax, chart, f"{doc['param']} [{unit}]", doc.get("low"), doc.get("high"))
    ax.set_title("individuals (limits ±3σ̂ from the moving range; red: spec limits)")
    if xbar is not None and rng is not None:
        ax2 = fig.add_subplot(n_axes, 1, 2)
        _draw(ax2, xbar, f"subgroup mean, n = {doc['xbar']['subgroup']}")
        ax2.set_title("X̄ chart")
        ax3 = fig.add_subplot(n_axes, 1, 3)
        _draw(ax3, rng, "subgroup range")
        ax3.set_title("R chart")
        ax3.set_xlabel("subgroup, oldest first")
    else:
        ax.set_xlabel("run, oldest first")
    rows = []
    for v in doc["individuals"]["violations"]:
        p = doc["points"][v["index"]]
        rows.append([v["index"], p["started_utc"][:19], p["unit_serial"] or "-", p["station_id"],
                     f"{p['value']:.6g}", f"{v['rule']}: {v['rule_text']}"])
    rules = "".join(f"<li>{r}: {html.escape(t)}</li>" for r, t in RULES.items())
    summary = (f"<p>{doc['n']} values; centre {chart.centre:.6g} {html.escape(unit)}, control "
               f"limits {chart.lcl:.6g} … {chart.ucl:.6g}.</p><p>Western Electric rules:</p><ul>{rules}</ul>")
    table = html_table(["#", "started (UTC)", "unit", "station", "value", "rule"], rows) if rows \
        else "<p>No point breaks a rule: the process is in statistical control.</p>"
    return _page(f"Control charts — {doc['param']}" + (f" ({doc['model']})" if doc.get("model") else ""),
                 _png(fig) + summary + table)


def trace_page(doc: dict[str, Any]) -> str:
    runs = doc["runs"]
    names = sorted({m["name"] for r in runs for m in r["measurements"] if m["value"] is not None})
    body = ""
    if names:
        fig = Figure(figsize=(10, 2.2 * min(len(names), 6)))
        for i, name in enumerate(names[:6]):
            ax = fig.add_subplot(min(len(names), 6), 1, i + 1)
            pts = [(j, m["value"], m["low"], m["high"], m["unit"]) for j, r in enumerate(runs)
                   for m in r["measurements"] if m["name"] == name and m["value"] is not None]
            ax.plot([p[0] for p in pts], [p[1] for p in pts], "o-")
            for limit in (pts[0][2], pts[0][3]):
                if limit is not None:
                    ax.axhline(limit, color="tab:red", lw=1.0)
            ax.set_ylabel(f"{name}\n[{pts[0][4]}]")
            ax.set_xticks(range(len(runs)), [r["station_id"] for r in runs], fontsize=7)
            ax.grid(alpha=0.3)
        body += _png(fig)
    rows = [[r["started_utc"][:19], r["station_id"], r["socket"] or "-", r["lot"] or "-",
             r["procedure"], r["status"], r["n_samples"], r["uuid"]] for r in runs]
    body += html_table(["started (UTC)", "station", "socket", "lot", "procedure", "status", "samples",
                        "uuid"], rows, bold_rows={i for i, r in enumerate(runs) if r["status"] != "passed"})
    return _page(f"Unit {doc['serial']}: every run", body)
