"""HTML report of an acceptance run, built from the run store alone.

What a quality engineer signs: a header naming the unit (model, serial, lot), where and by
whom it was tested (station, socket, operator), the spec (file name, version, SHA-256 of its
content), the code version, the seed and the run's start and end; the verdict, each
measurement against its limits, one figure per step, the station snapshot, the events; a
signature block (tested by, reviewed by, date); and at the foot the **record's digest** — the
SHA-256 of the stored run's acquired content, the one the central store checks — so a printed
copy can be matched to the stored run (``bench runs show ID`` prints the same digest). Files go
into one directory (``acceptance_report.html``, self-contained, its PDF ``acceptance_report.pdf``,
the PNGs and ``acceptance.json``); the page is ``templates/acceptance.html.j2`` on the shared layout.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from bench.app.reports.acceptance_plots import SECTIONS
from bench.app.reports.layout import Header, run_identity, write_report
from bench.app.verdict import measurements_of, record_digest, verdict_of
from bench.app.wording import bound_text, measurement_label, unit_text
from bench.core.store.central import spec_identity

_OUTCOMES = ("pass", "marginal", "fail")


def _num(x: Any) -> str:
    return "" if x is None else f"{x:.6g}"


def _identity(entry: dict[str, Any]) -> str:
    """The instrument's identity as it reported it, or why it did not."""
    idn = entry.get("idn") or entry.get("identity")
    if isinstance(idn, dict):
        return " ".join(str(v) for v in idn.values() if v is not None)
    if idn:
        return str(idn)
    return f"not read: {entry['error']}" if entry.get("error") else "not reported by its interface"


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


def write_acceptance_report(store, run_id: str, directory: str | Path, *, pdf: bool = True) -> Path:
    """``acceptance_report.html`` (and its PDF, with ``pdf``), the figures and ``acceptance.json``
    in ``directory``; return the HTML's path."""
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    info = store.get_run(run_id)
    results = store.results(run_id)
    doc = acceptance_document(store, run_id)
    (out / "acceptance.json").write_text(json.dumps(doc, indent=2, default=str))
    labels = {e["name"]: e.get("label") or e["name"]
              for e in (results.get("acceptance.spec") or {}).get("measurements", [])}
    rows, outcomes = [], []
    for m in doc["measurements"]:
        value = "not produced" if m["value"] is None else bound_text(m) + _num(m["value"])
        value += "" if m.get("uncertainty") is None else f" ± {m['uncertainty']:.2g}"
        label = measurement_label(m, labels)
        described = m["description"] if label == m["name"] else f"{m['description']} [{m['name']}]"
        rows.append([label, described, value, unit_text(m["unit"]), _num(m["low"]), _num(m["high"]),
                     _num(m["marginal"]) if m["marginal"] else "", m["outcome"].upper()])
        outcomes.append(m["outcome"] if m["outcome"] in _OUTCOMES else "")
    sections = []
    for step in (results.get("acceptance.spec") or {}).get("procedures", {}):
        builder = SECTIONS.get(step)
        built = builder(store, run_id, results, out) if builder else None
        if built:
            title, png, caption = built
            sections.append({"title": title, "png": png, "step": step, "caption": caption})
    station = info.station or {}
    instruments = [[name, e.get("driver", ""), e.get("address", ""), _identity(e)]
                   for name, e in (station.get("instruments") or {}).items()]
    events = [[f"{e.t_s:.3f}", e.kind, e.message] for e in store.events(run_id)[:200]]
    spec = results.get("acceptance.spec") or {}
    sha, version = spec_identity(spec) if spec else ("", "")
    labels = info.labels or {}
    subject = (
        ("model", doc["model"] or "—"), ("serial", info.unit_serial or "—"), ("lot", labels.get("lot", "—")),
        ("station", labels.get("station_id") or station.get("name", "—")), ("socket", labels.get("socket", "—")),
        ("operator", labels.get("operator", "—")),
        ("spec", f"{Path(str(doc['spec'] or '—')).name}, version {spec.get('version', version) or '—'}"),
        ("spec SHA-256", sha or "—"), ("seed", info.seed),
        ("started (UTC)", info.started_utc), ("ended (UTC)", info.ended_utc or "—"), ("run", run_id))
    header = Header(title=f"Acceptance test — {doc['model']} s/n {info.unit_serial}", subject=subject,
                    identity=run_identity(record_digest(store, run_id), run_id), verdict=doc["verdict"],
                    reason=info.reason, tested_by=labels.get("operator", ""), numbers="acceptance.json")
    return write_report(out / "acceptance_report.html", "acceptance.html.j2", header, pdf=pdf,
                        measurements=rows, outcomes=outcomes, sections=sections, instruments=instruments,
                        events=events)
