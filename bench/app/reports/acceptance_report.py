"""HTML report of an acceptance run, built from the run store alone.

What a quality engineer signs: a header naming the unit (model, serial, lot), where and by
whom it was tested (station, socket, operator), the spec (file name, version, SHA-256 of its
content), the code version, the seed and the run's start and end; the verdict, each
measurement against its limits, one figure per step, the station snapshot, the events; a
signature block (tested by, reviewed by, date); and at the foot the **record's digest** — the
SHA-256 of the stored run's acquired content, the one the central store checks — so a printed
copy can be matched to the stored run (``bench runs show ID`` prints the same digest). Files go
into one directory (``acceptance_report.html``, self-contained, + PNGs + ``acceptance.json``).
"""

from __future__ import annotations

import html
import json
from pathlib import Path
from typing import Any

from bench.app.reports.acceptance_plots import SECTIONS
from bench.app.reports.common import write_page
from bench.app.verdict import measurements_of, record_digest, verdict_of
from bench.core.store.central import spec_identity

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
    spec = results.get("acceptance.spec") or {}
    sha, version = spec_identity(spec) if spec else ("", "")
    labels = info.labels or {}
    digest = record_digest(store, run_id)
    header = "".join(_row([k, v]) for k, v in (
        ("model", doc["model"] or "—"), ("serial", info.unit_serial or "—"), ("lot", labels.get("lot", "—")),
        ("station", labels.get("station_id") or station.get("name", "—")), ("socket", labels.get("socket", "—")),
        ("operator", labels.get("operator", "—")),
        ("spec", f"{Path(str(doc['spec'] or '—')).name}, version {spec.get('version', version) or '—'}"),
        ("spec SHA-256", sha or "—"), ("code version", info.code_version), ("seed", info.seed),
        ("started (UTC)", info.started_utc), ("ended (UTC)", info.ended_utc or "—"), ("run", run_id)))
    signatures = ("<table class='sign'><tr><th></th><th>name</th><th>signature</th><th>date</th></tr>"
                  "<tr><th>tested by</th><td>" + html.escape(labels.get("operator", ""))
                  + "</td><td></td><td></td></tr>"
                  "<tr><th>reviewed by</th><td></td><td></td><td></td></tr></table>")
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>Acceptance {html.escape(str(info.unit_serial))}</title>
<style>body{{font-family:sans-serif;max-width:1000px;margin:auto}} table{{border-collapse:collapse;margin:0.5em 0}}
td,th{{border:1px solid #bbb;padding:2px 8px}} img{{max-width:100%}}
.verdict{{font-size:2em;font-weight:bold;color:{colour}}} table.sign td{{min-width:12em;height:2.2em}}
.digest{{font-size:0.85em;word-break:break-all}}</style></head><body>
<h1>Acceptance test — {html.escape(str(doc["model"]))} s/n {html.escape(str(info.unit_serial))}</h1>
<p class="verdict">{html.escape(doc["verdict"])}</p>
{"<p>" + html.escape(str(info.reason)) + "</p>" if info.reason else ""}
<table>{header}</table>
<h2>Measurements</h2>
<table><tr><th>measurement</th><th>description</th><th>value ± std. unc.</th><th>unit</th>
<th>low</th><th>high</th><th>marginal band</th><th>outcome</th></tr>{"".join(rows)}</table>
{"".join(sections)}
<h2>Station</h2><table><tr><th>instrument</th><th>driver</th><th>address</th><th>identity</th></tr>
{"".join(inst_rows)}</table>
<h2>Events</h2><table><tr><th>t (s)</th><th>event</th><th>message</th></tr>{"".join(events)}</table>
<h2>Approval</h2>{signatures}
<p>Numbers: <a href="acceptance.json">acceptance.json</a></p>
<p class="digest">Record digest (SHA-256 of the stored run's acquired content; <code>bench runs show
{html.escape(run_id)}</code> prints it): <code>{html.escape(digest)}</code></p>
</body></html>
"""
    path = out / "acceptance_report.html"
    write_page(path, page)
    return path
