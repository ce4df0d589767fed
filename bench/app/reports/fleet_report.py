"""The fleet views as reports on the shared layout (``templates/fleet.html.j2``): yield by group
with its Wilson intervals, a measurement's control charts with the flagged points, a unit's runs.

Each view is a :class:`FleetPage` — the page's header and body as data — that renders to one
self-contained HTML file (plots inline) and writes its PDF beside it. The page's foot carries
the SHA-256 of the view's ``--json`` document (the numbers the page shows), so a printed chart
can be matched to the data it was drawn from; the approval block is there, as a quality
engineer signs control charts too.
"""

from __future__ import annotations

import base64
import hashlib
import io
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from bench.analysis.quality import RULES, ControlChart
from bench.app.reports.layout import Header, Identity, render, subject_rows, write_report


@dataclass(frozen=True)
class FleetPage:
    """One fleet view as a page: its header and the body's data (``fleet.html.j2``)."""

    header: Header
    body: dict[str, Any]

    def html(self) -> str:
        """The page as one self-contained HTML document."""
        return render("fleet.html.j2", self.header, **self.body)

    def write(self, path: str | Path, *, pdf: bool = True) -> Path:
        """Write the page to ``path`` and, with ``pdf``, its PDF beside it (``.pdf``)."""
        return write_report(path, "fleet.html.j2", self.header, pdf=pdf, **self.body)


def view_identity(doc: dict[str, Any]) -> Identity:
    """The foot of a fleet page: the SHA-256 of the view's ``--json`` document as ``bench fleet``
    prints it (so ``bench fleet … --json | sha256sum`` prints the same while the store is unchanged)."""
    text = json.dumps(doc, indent=2, allow_nan=False, default=str) + "\n"
    return Identity("View SHA-256", hashlib.sha256(text.encode()).hexdigest(),
                    "of the view's --json document; the same command with --json piped to sha256sum prints it "
                    "while the central store holds the same runs")


def _png(fig: Figure) -> str:
    """``fig`` as a data URI (the page is one file; nothing is written beside it but its PDF)."""
    buffer = io.BytesIO()
    fig.tight_layout()
    fig.savefig(buffer, format="png", dpi=100)
    return f"data:image/png;base64,{base64.b64encode(buffer.getvalue()).decode()}"


def _page(title: str, doc: dict[str, Any], context: dict[str, Any] | None, **body: Any) -> FleetPage:
    header = Header(title=title, subject=subject_rows(context), identity=view_identity(doc))
    return FleetPage(header, {"figure": None, "paragraphs": [], "rules": None, "table": None, "empty": None, **body})


def yield_page(doc: dict[str, Any], context: dict[str, Any] | None = None) -> FleetPage:
    """Acceptance yield by group (``bench fleet yield``'s document); ``context`` heads the page."""
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
    return _page(f"Yield by {doc['by']}" + (f" — {doc['model']}" if doc.get("model") else ""), doc, context,
                 figure={"png": _png(fig), "alt": "yield by group"},
                 paragraphs=["Yield = passed / (passed + failed) over acceptance runs; aborted runs are no verdict "
                             "and are counted apart. A unit tested twice counts twice."],
                 table={"header": [doc["by"], "passed", "failed", "aborted", "yield", "95 % interval"],
                        "rows": rows, "classes": None, "num_from": 1, "widths": [30, 11, 11, 11, 13, 24]})


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
             rng: ControlChart | None, context: dict[str, Any] | None = None) -> FleetPage:
    """Control charts of one measurement (``bench fleet spc``'s document and charts)."""
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
    return _page(f"Control charts — {doc['param']}" + (f" ({doc['model']})" if doc.get("model") else ""), doc, context,
                 figure={"png": _png(fig), "alt": "control charts"},
                 paragraphs=[f"{doc['n']} values; centre {chart.centre:.6g} {unit}, control limits "
                             f"{chart.lcl:.6g} … {chart.ucl:.6g}."],
                 rules=[f"{r}: {t}" for r, t in RULES.items()],
                 table={"header": ["#", "started (UTC)", "unit", "station", "value", "rule"], "rows": rows,
                        "classes": None, "num_from": None, "widths": [6, 19, 15, 14, 11, 35]} if rows else None,
                 empty="No point breaks a rule: the process is in statistical control.")


def trace_page(doc: dict[str, Any], context: dict[str, Any] | None = None) -> FleetPage:
    """Every run of one unit (``bench fleet trace``'s document)."""
    runs = doc["runs"]
    names = sorted({m["name"] for r in runs for m in r["measurements"] if m["value"] is not None})
    figure = None
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
        figure = {"png": _png(fig), "alt": "measurements of every run"}
    rows = [[r["started_utc"][:19], r["station_id"], r["socket"] or "-", r["lot"] or "-",
             r["procedure"], r["status"], r["n_samples"], r["uuid"]] for r in runs]
    return _page(f"Unit {doc['serial']}: every run", doc, context, figure=figure,
                 table={"header": ["started (UTC)", "station", "socket", "lot", "procedure", "status", "samples",
                                   "uuid"], "rows": rows,
                        "classes": ["" if r["status"] == "passed" else "fail" for r in runs], "num_from": None,
                        "widths": [18, 11, 6, 6, 11, 8, 8, 32]})
