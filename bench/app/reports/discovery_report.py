"""HTML report of discovery: the search's story step by step, with before/after plots.

For each named effect: what the localization flagged, the candidates' table (deviance saved,
the penalty it must beat, χ² p, that p times the criterion's multiplicity), the named one with
parameters ± std, look-alikes within the criterion's noise and the experiment that separates
them, the gap table before/after and three plots (residual vs time, Welch PSD with the white
floor, Allan deviation with the white expectation), before in grey, after in colour. Then what
remains: "unexplained structure" (where) or "nothing significant".
"""

from __future__ import annotations

import html
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import NullFormatter
from scipy import signal

from bench.analysis.allan import overlapping_adev
from bench.app.reports.common import html_table, save_figure, write_page

CSS = ("body{font-family:sans-serif;max-width:1100px;margin:2em auto;line-height:1.4}"
       "table{border-collapse:collapse;margin:0.5em 0}td,th{border:1px solid #bbb;padding:2px 6px;"
       "font-size:90%}tr.best{font-weight:bold;background:#eef}img{max-width:100%}")


def _fmt(x, digits: int = 4) -> str:
    try:
        v = float(x)
    except (TypeError, ValueError):
        return str(x)
    return "—" if not np.isfinite(v) else f"{v:.{digits}g}"


def _welch(r: np.ndarray, rate_hz: float):
    # finer than the localization's Welch (a quarter of the record per segment): lines show
    nperseg = min(r.size, max(64, 2 ** int(np.log2(max(r.size // 4, 64)))))
    return signal.welch(r, fs=rate_hz, window="hann", nperseg=nperseg, detrend="constant")


#: bins of a residual-vs-time trace: each drawn as its minimum and maximum (spikes kept)
TRACE_BINS = 1500


def envelope(t: np.ndarray, y: np.ndarray, bins: int = TRACE_BINS) -> tuple[np.ndarray, np.ndarray]:
    """The trace as the minimum and maximum of each of ``bins`` equal runs of samples, in time
    order (2·bins points): what a line of every sample would show at screen resolution, at a
    fraction of the drawing time of a 180 000-sample line."""
    if y.size <= 2 * bins:
        return t, y
    edges = np.linspace(0, y.size, bins + 1).astype(int)
    lo = np.minimum.reduceat(y, edges[:-1])
    hi = np.maximum.reduceat(y, edges[:-1])
    mid = t[(edges[:-1] + edges[1:]) // 2]
    return np.repeat(mid, 2), np.column_stack([lo, hi]).ravel()


def _plots(t: np.ndarray, before: np.ndarray, after: np.ndarray, noise_sd: float, rate_hz: float,
           path: Path, title: str) -> str:
    fig = Figure(figsize=(12, 3.4))
    ax = fig.subplots(1, 3)
    ax[0].plot(*envelope(t, before), color="0.6", lw=0.6, label="before")
    ax[0].plot(*envelope(t, after), color="C0", lw=0.6, label="after")
    ax[0].set(xlabel="t (s)", ylabel="residual", title=f"{title}: residual vs time")
    ax[0].legend(fontsize=8)
    for r, c, lab in ((before, "0.6", "before"), (after, "C0", "after")):
        f, p = _welch(r - r.mean(), rate_hz)
        ax[1].loglog(f[1:], p[1:], color=c, lw=0.8, label=lab)
    ax[1].axhline(2 * noise_sd ** 2 / rate_hz, color="k", ls="--", lw=0.8, label="white floor")
    ax[1].set(xlabel="f (Hz)", ylabel="PSD (unit²/Hz)", title="Welch PSD")
    ax[1].xaxis.set_minor_formatter(NullFormatter())
    ax[1].legend(fontsize=8)
    for r, c, lab in ((before, "0.6", "before"), (after, "C0", "after")):
        if r.size >= 16:
            a = overlapping_adev(r, rate_hz, "octave", unit=None)
            ax[2].loglog(a.tau_s, a.adev, "o-", ms=3, color=c, lw=0.8, label=lab)
    if before.size >= 16:
        tau = overlapping_adev(before, rate_hz, "octave", unit=None).tau_s
        ax[2].loglog(tau, noise_sd / np.sqrt(tau * rate_hz), "k--", lw=0.8, label="white expectation")
    ax[2].set(xlabel="τ (s)", ylabel="ADEV", title="Allan deviation")
    ax[2].legend(fontsize=8)
    return save_figure(fig, path)


def _gap_table(before, after) -> str:
    rows: list[list[object]] = [
        ["residual rms / model noise", _fmt(before.rms_ratio), _fmt(after.rms_ratio)],
        ["Allan distance (decades, rms)", _fmt(before.allan_distance), _fmt(after.allan_distance)],
        ["spectral distance (dB, rms)", _fmt(before.spectral_distance_db), _fmt(after.spectral_distance_db)],
        ["whiteness (Ljung–Box p)", _fmt(before.whiteness_p, 3), _fmt(after.whiteness_p, 3)]]
    return html_table(["gap", "before", "after"], rows)


def _candidates_table(naming) -> str:
    rows: list[list[object]] = []
    bold = set()
    for i, c in enumerate(naming.candidates):
        if naming.best is not None and c.id == naming.best.id:
            bold.add(i)
        main = ", ".join(f"{k}={_fmt(v, 3)}" for k, v in c.params.items())
        rows.append([c.id, _fmt(c.score, 3), _fmt(c.score_se, 3), _fmt(c.p_value, 3), _fmt(c.q_value, 3),
                     "yes" if c.big_enough else "no", "yes" if c.named else "", main])
    return html_table(["candidate", "deviance saved", "penalty", "p", "p × multiplicity", "lowers the criterion",
                       "named", "parameters"], rows, bold)


def _model_table(model) -> str:
    b = model.base
    rows: list[list[object]] = [["base", "bias", _fmt(b.bias, 6)], ["base", "scale_factor", _fmt(b.scale_factor, 8)],
                                ["base", "noise_sd (white, per sample)", _fmt(b.noise_sd, 4)]]
    rows += [[eid, k, _fmt(v, 6)] for eid, p in model.effects for k, v in p.items()]
    return html_table(["part", "parameter", "value"], rows)


def write_discovery_report(result, rec, out_dir, label: str) -> Path:
    """Write ``discovery_report.html`` (and its PNGs) into ``out_dir``; return the HTML path."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    m0 = result.initial_model.base
    parts = [f"<h1>Discrepancy workflow — {html.escape(label)}</h1>",
             f"<p>{rec.n} samples at {_fmt(rec.rate_hz)} Hz over {_fmt(rec.duration_s)} s; sensor kind "
             f"{html.escape(m0.kind)}. Logged: {html.escape(', '.join(rec.to_columns()))}.</p>",
             "<h2>a. Calibrated starting model</h2>",
             f"<p>bias {_fmt(m0.bias)}, scale factor {_fmt(m0.scale_factor)}, white noise σ {_fmt(m0.noise_sd)} "
             f"(from the residual's high-frequency floor); effects: "
             f"{html.escape(', '.join(e for e, _ in result.initial_model.effects) or 'none')}.</p>",
             f"<p>Residual rms {_fmt(result.rms_initial)} against a noise floor of {_fmt(m0.noise_sd)}.</p>"]
    for i, s in enumerate(result.steps, 1):
        # a long record's step is told on what its search saw (block means or a window)
        t = s.t_s if s.t_s.size == s.residual_after.size else rec.t_s
        model_sd = s.noise_floor if np.isfinite(s.noise_floor) else result.final_model.base.noise_sd
        rate = (t.size - 1) / (t[-1] - t[0])
        img = _plots(t, s.residual_before, s.residual_after, model_sd, rate,
                     out / f"discovery_step{i}.png", f"step {i}" + (f" ({s.scale})" if s.scale else ""))
        ps = ", ".join(f"{html.escape(k)} = {_fmt(v)} ± {_fmt(s.params_std.get(k))}" for k, v in s.params.items())
        seen_on = f" (on the record's {html.escape(s.scale)})" if s.scale else ""
        parts += [f"<h2>Step {i}: {html.escape(s.effect_id)}{seen_on}</h2>",
                  "<h3>b. Where the residual departs from the floor</h3>",
                  "<ul>" + "".join(f"<li>{html.escape(d)}</li>" for d in s.localization.descriptions())
                  + "</ul>" if s.localization.descriptions() else "<p>no single test flags it on its own.</p>",
                  "<h3>c. Candidates (exact likelihood; named when the deviance saved beats the penalty "
                  "χ²_k.isf(α / (C·M)))</h3>", _candidates_table(s.naming),
                  f"<p><b>Named: {html.escape(s.effect_id)}</b> — {ps}; p = {_fmt(s.p_value, 3)}.</p>"]
        if s.naming.competitors:
            parts.append("<p>Look-alikes within the criterion's noise (weight ≥ α of the named one's): "
                         + html.escape(", ".join(s.naming.competitors)) + ".</p><ul>"
                         + "".join(f"<li>{html.escape(x)}</li>" for x in s.naming.separating) + "</ul>")
        parts += ["<h3>d. Added, re-calibrated: the gap before and after</h3>",
                  _gap_table(s.gap_before, s.gap_after), f"<img src='{img}' alt='step {i} plots'>"]
    parts.append("<h2>e. What remains</h2>")
    if result.withdrawn:
        parts.append("<p><b>Withdrawn</b> — added on the way, then dropped or swapped out by a move that lowered "
                     "the criterion:</p><ul>"
                     + "".join(f"<li>{html.escape(w)}</li>" for w in result.withdrawn) + "</ul>")
    if result.set_aside:
        parts.append("<p><b>Set aside</b> — catch-alls (random processes, a drift) that would have been chosen last, "
                     "but whose own signature does not hold:</p><ul>"
                     + "".join(f"<li>{html.escape(w)}</li>" for w in result.set_aside) + "</ul>")
    if result.unexplained:
        parts.append("<p><b>Unexplained structure</b> (no catalogue effect lowers the criterion for it):</p><ul>"
                     + "".join(f"<li>{html.escape(u)}</li>" for u in result.unexplained) + "</ul>")
    elif not result.steps:
        parts.append("<p>Nothing significant: the residual is at the model's noise floor; nothing named.</p>")
    else:
        parts.append("<p>No further candidate is significant; the residual shows no structure the tests flag.</p>")
    if result.final_naming is not None and result.final_naming.candidates:
        parts += ["<h3>Last round of candidates</h3>", _candidates_table(result.final_naming)]
    parts += [f"<p>Final residual rms {_fmt(result.rms_final)}; model noise floor {_fmt(result.noise_floor)} "
              f"(ratio {_fmt(result.rms_final / result.noise_floor, 3)}).</p>",
              _gap_table(result.gap_initial, result.gap_final)]
    parts += ["<h3>Final model (written to the model file)</h3>", _model_table(result.final_model)]
    parts += [f"<p>note: {html.escape(n)}</p>" for n in result.notes]
    if result.steps:
        img = _plots(rec.t_s, result.residual_initial, result.residual_final, result.final_model.base.noise_sd,
                     rec.rate_hz, out / "discovery_overall.png", "initial vs final")
        parts.append(f"<img src='{img}' alt='initial vs final'>")
    path = out / "discovery_report.html"
    write_page(path, f"<!doctype html><html><head><meta charset='utf-8'><title>discover</title>"
                     f"<style>{CSS}</style></head><body>{''.join(parts)}</body></html>")
    return path
