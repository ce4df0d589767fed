"""HTML report of an acceptance run, built from the run store alone.

Unit, spec, verdict, each measurement against its limits, one figure per step, the station
snapshot, the events, code version — what a quality engineer signs.  Files go into one
directory (``acceptance_report.html`` + PNGs + ``acceptance.json``).
"""

from __future__ import annotations

import html
import json
from pathlib import Path
from typing import Any

from bench.app.reports.acceptance_plots import SECTIONS
from bench.app.reports.common import write_page
from bench.app.verdict import measurements_of, verdict_of

_COLOURS = {"pass": "#d8f0d8", "marginal": "#fff2c0", "fail": "#f8d0d0"}


def _num(x: Any) -> str:
    return "" if x is None else f"{x:.6g}"


def _row(cells: list[Any], style: str = "") -> str:
    tds = "".join(f"<td>{html.escape(str(c))}</td>" for c in cells)
    return f"<tr style='{style}'>{tds}</tr>"


def _identity(entry: dict[str, Any]) -> str:
    idn = entry.get("idn", entry.get("error", ""))
    return " ".join(str(v) for v in idn.values()) if isinstance(idn, dict) else str(idn)


def acceptance_document(store, run_id: str) -> dict[str, Any]:
    """The run's verdict and measurements as data (``--json`` and acceptance.json)."""
    info = store.get_run(run_id)
    results = store.results(run_id)
    ms = measurements_of(results)
    spec = results.get("acceptance.spec") or {}
    return {"run_id": run_id, "unit": info.unit_serial, "model": spec.get("model"),
            "kind": spec.get("kind"), "spec": spec.get("source"), "status": info.status,
            "reason": info.reason, "verdict": verdict_of(info.status, ms),
            "started_utc": info.started_utc, "ended_utc": info.ended_utc, "seed": info.seed,
            "code_version": info.code_version, "measurements": ms}


def write_acceptance_report(store, run_id: str, directory: str | Path) -> Path:
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    info = store.get_run(run_id)
    results = store.results(run_id)
    doc = acceptance_document(store, run_id)
    (out / "acceptance.json").write_text(json.dumps(doc, indent=2, default=str))
    rows = []
    for m in doc["measurements"]:
        value = ("not produced" if m["value"] is None else _num(m["value"])) + ("" if m.get("uncertainty") is None
                                    else f" ± {m['uncertainty']:.2g}")
        rows.append(_row([m["name"], m["description"], value, m["unit"], _num(m["low"]),
                          _num(m["high"]), _num(m["marginal"]) if m["marginal"] else "",
                          m["outcome"].upper()],
                         f"background:{_COLOURS.get(m['outcome'], '#fff')}"))
    sections = []
    for step in (results.get("acceptance.spec") or {}).get("procedures", {}):
        builder = SECTIONS.get(step)
        built = builder(store, run_id, results, out) if builder else None
        if built:
            title, png, caption = built
            sections.append(f"<h2>{html.escape(title)}</h2><img src='{html.escape(png)}' "
                            f"alt='{html.escape(step)}'><p>{html.escape(caption)}</p>")
    station = info.station or {}
    inst_rows = [_row([name, e.get("driver", ""), e.get("address", ""), _identity(e)])
                 for name, e in (station.get("instruments") or {}).items()]
    events = [_row([f"{e.t_s:.3f}", e.kind, e.message]) for e in store.events(run_id)[:200]]
    colour = {"PASS": "#2a7a2a", "FAIL": "#b02020", "ABORTED": "#b02020"}.get(
        doc["verdict"], "#a07000")
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>Acceptance {html.escape(str(info.unit_serial))}</title>
<style>body{{font-family:sans-serif;max-width:1000px;margin:auto}} table{{border-collapse:collapse;margin:0.5em 0}}
td,th{{border:1px solid #bbb;padding:2px 8px}} img{{max-width:100%}}
.verdict{{font-size:2em;font-weight:bold;color:{colour}}}</style></head><body>
<h1>Acceptance test — {html.escape(str(doc["model"]))} s/n {html.escape(str(info.unit_serial))}</h1>
<p class="verdict">{html.escape(doc["verdict"])}</p>
{"<p>" + html.escape(str(info.reason)) + "</p>" if info.reason else ""}
<table>{_row(["run", run_id])}{_row(["spec", doc["spec"]])}{_row(["station", station.get("name", "")])}
{_row(["started (UTC)", info.started_utc])}{_row(["ended (UTC)", info.ended_utc])}
{_row(["seed", info.seed])}{_row(["code version", info.code_version])}</table>
<h2>Measurements</h2>
<table><tr><th>measurement</th><th>description</th><th>value ± std. unc.</th><th>unit</th>
<th>low</th><th>high</th><th>marginal band</th><th>outcome</th></tr>{"".join(rows)}</table>
{"".join(sections)}
<h2>Station</h2><table><tr><th>instrument</th><th>driver</th><th>address</th><th>identity</th></tr>
{"".join(inst_rows)}</table>
<h2>Events</h2><table><tr><th>t (s)</th><th>event</th><th>message</th></tr>{"".join(events)}</table>
<p>Numbers: <a href="acceptance.json">acceptance.json</a></p>
</body></html>
"""
    path = out / "acceptance_report.html"
    write_page(path, page)
    return path
