"""HTML report of discovery: the search's story step by step, with before/after plots.

For each named effect: what the localization flagged, the candidates' table (deviance saved,
the penalty it must beat, χ² p, that p times the criterion's multiplicity), the named one with
parameters ± std, look-alikes within the criterion's noise and the experiment that separates
them, the gap table before/after and one figure: the residual against time before and after in two
panels sharing the time axis (each with its mean over short runs), and below them the Welch
PSD with the white floor and the Allan deviation with the white expectation, before in grey,
after in colour; a random process whose driving noise is not the model's says so instead of
"named". Then what remains: "unexplained structure" (where) or "nothing significant".
The page is ``templates/discovery.html.j2`` on the shared layout, its PDF beside it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import NullFormatter
from scipy import signal

from bench.analysis.allan import overlapping_adev
from bench.app.reports.common import save_figure
from bench.app.reports.layout import context_header, write_report


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
#: bins of the mean line drawn over a residual trace: slow structure the min/max band hides
MEAN_BINS = 200


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


def bin_means(t: np.ndarray, y: np.ndarray, bins: int = MEAN_BINS) -> tuple[np.ndarray, np.ndarray]:
    """The mean of each of ``bins`` equal runs of samples at the run's middle time (the trace
    itself when it is shorter than ``2·bins``)."""
    if y.size <= 2 * bins:
        return t, y
    edges = np.linspace(0, y.size, bins + 1).astype(int)
    return t[(edges[:-1] + edges[1:]) // 2], np.add.reduceat(y, edges[:-1]) / np.diff(edges)


def _plots(t: np.ndarray, before: np.ndarray, after: np.ndarray, noise_sd: float, rate_hz: float,
           path: Path, title: str) -> str:
    """Residual against time, before and after, in two panels sharing both axes (their sizes
    compare; neither hides the other), each with its mean over short runs; below them the Welch
    PSD and the Allan deviation, before in grey and after in colour."""
    fig = Figure(figsize=(10, 7.2))
    grid = fig.add_gridspec(3, 2, height_ratios=[1, 1, 1.9])
    ax_b = fig.add_subplot(grid[0, :])
    ax_a = fig.add_subplot(grid[1, :], sharex=ax_b, sharey=ax_b)
    ax_psd, ax_adev = fig.add_subplot(grid[2, 0]), fig.add_subplot(grid[2, 1])
    trace = "min–max of each run of samples" if before.size > 2 * TRACE_BINS else "every sample"
    per = before.size // MEAN_BINS if before.size > 2 * MEAN_BINS else 1
    for ax, r, colour, mean_colour, name in ((ax_b, before, "0.7", "k", "before"),
                                              (ax_a, after, "#9ecae1", "C0", "after")):
        ax.plot(*envelope(t, r), color=colour, lw=0.6, label=f"{name} ({trace})")
        ax.plot(*bin_means(t, r), color=mean_colour, lw=1.0, label=f"mean of each {per} samples")
        ax.set_ylabel(f"residual {name}")
        ax.legend(fontsize=7, loc="upper right")
        ax.grid(alpha=0.3)
    ax_b.set_title(f"{title}: residual vs time")
    ax_b.tick_params(labelbottom=False)
    ax_a.set_xlabel("t (s)")
    for r, c, lab in ((before, "0.6", "before"), (after, "C0", "after")):
        f, p = _welch(r - r.mean(), rate_hz)
        ax_psd.loglog(f[1:], p[1:], color=c, lw=0.8, label=lab)
    ax_psd.axhline(2 * noise_sd ** 2 / rate_hz, color="k", ls="--", lw=0.8, label="white floor")
    ax_psd.set(xlabel="f (Hz)", ylabel="PSD (unit²/Hz)", title="Welch PSD")
    ax_psd.xaxis.set_minor_formatter(NullFormatter())
    ax_psd.legend(fontsize=8)
    for r, c, lab in ((before, "0.6", "before"), (after, "C0", "after")):
        if r.size >= 16:
            a = overlapping_adev(r, rate_hz, "octave", unit=None)
            ax_adev.loglog(a.tau_s, a.adev, "o-", ms=3, color=c, lw=0.8, label=lab)
    if before.size >= 16:
        tau = overlapping_adev(before, rate_hz, "octave", unit=None).tau_s
        ax_adev.loglog(tau, noise_sd / np.sqrt(tau * rate_hz), "k--", lw=0.8, label="white expectation")
    ax_adev.set(xlabel="τ (s)", ylabel="ADEV", title="Allan deviation")
    ax_adev.legend(fontsize=8)
    return save_figure(fig, path)


def _gap_rows(before, after) -> list[list[object]]:
    return [["residual rms / model noise", _fmt(before.rms_ratio), _fmt(after.rms_ratio)],
            ["Allan distance (decades, rms)", _fmt(before.allan_distance), _fmt(after.allan_distance)],
            ["spectral distance (dB, rms)", _fmt(before.spectral_distance_db), _fmt(after.spectral_distance_db)],
            ["whiteness (Ljung–Box p)", _fmt(before.whiteness_p, 3), _fmt(after.whiteness_p, 3)]]


def _candidates(naming) -> dict[str, list]:
    """The candidates' table: rows, and the named one's row class ``best``."""
    rows: list[list[object]] = []
    classes = []
    for c in naming.candidates:
        classes.append("best" if naming.best is not None and c.id == naming.best.id else "")
        main = ", ".join(f"{k}={_fmt(v, 3)}" for k, v in c.params.items())
        rows.append([c.id, _fmt(c.score, 3), _fmt(c.score_se, 3), _fmt(c.p_value, 3), _fmt(c.q_value, 3),
                     "yes" if c.big_enough else "no", "yes" if c.named else "", main])
    return {"rows": rows, "classes": classes}


def _model_rows(model) -> list[list[object]]:
    b = model.base
    rows: list[list[object]] = [["base", "bias", _fmt(b.bias, 6)], ["base", "scale_factor", _fmt(b.scale_factor, 8)],
                                ["base", "noise_sd (white, per sample)", _fmt(b.noise_sd, 4)]]
    return rows + [[eid, k, _fmt(v, 6)] for eid, p in model.effects for k, v in p.items()]


def _step(i: int, s, rec, result, out: Path) -> dict:
    """One named effect as the template tells it."""
    # a long record's step is told on what its search saw (block means or a window)
    t = s.t_s if s.t_s.size == s.residual_after.size else rec.t_s
    model_sd = s.noise_floor if np.isfinite(s.noise_floor) else result.final_model.base.noise_sd
    rate = (t.size - 1) / (t[-1] - t[0])
    png = _plots(t, s.residual_before, s.residual_after, model_sd, rate, out / f"discovery_step{i}.png",
                 f"step {i}" + (f" ({s.scale})" if s.scale else ""))
    return {"i": i, "effect": s.effect_id, "scale": s.scale, "where": s.localization.descriptions(),
            "candidates": _candidates(s.naming), "p": _fmt(s.p_value, 3),
            "params": ", ".join(f"{k} = {_fmt(v)} ± {_fmt(s.params_std.get(k))}" for k, v in s.params.items()),
            "competitors": ", ".join(s.naming.competitors), "separating": list(s.naming.separating),
            "gap": _gap_rows(s.gap_before, s.gap_after), "png": png, "doubt": s.doubt}


def write_discovery_report(result, rec, out_dir, label: str, context: dict | None = None, *,
                           pdf: bool = True) -> Path:
    """Write ``discovery_report.html`` (its PDF beside it, with ``pdf``) and its PNGs into
    ``out_dir``; return the HTML path.

    ``label`` names the record; ``context`` (optional) heads the report beside it: where the
    record came from (``input`` names the file whose SHA-256 goes to the page's foot; ``run`` +
    ``digest`` a stored run; ``operator`` also fills the approval block's "tested by")."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    m0 = result.initial_model.base
    steps = [_step(i, s, rec, result, out) for i, s in enumerate(result.steps, 1)]
    overall = None
    if result.steps:
        overall = _plots(rec.t_s, result.residual_initial, result.residual_final, result.final_model.base.noise_sd,
                         rec.rate_hz, out / "discovery_overall.png", "initial vs final")
    final_naming = result.final_naming
    context = context or {}
    if "input" not in context:  # a file's name heads the page as its input
        context = {"record": label, **context}
    header = context_header("Discrepancy workflow: model against measurement", context)
    return write_report(
        out / "discovery_report.html", "discovery.html.j2", header, pdf=pdf, fmt=_fmt, rec=rec, m0=m0,
        result=result, logged=", ".join(rec.to_columns()), steps=steps,
        start_effects=", ".join(e for e, _ in result.initial_model.effects) or "none",
        last_round=_candidates(final_naming) if final_naming is not None and final_naming.candidates else None,
        final_gap=_gap_rows(result.gap_initial, result.gap_final), final_model=_model_rows(result.final_model),
        overall=overall)
