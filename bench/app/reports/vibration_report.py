"""HTML report of Document C's random-vibration error model, built only from a
:class:`~bench.analysis.vibration._pipeline.VibrationAnalysis`.

:func:`write_vibration_report` writes into one directory:

* ``vibration_report.html`` (``templates/vibration.html.j2`` on the shared layout; its PDF
  beside it) — summary, the non-random terms and why, the per-IMF table (tests, orders,
  coefficients, Kalman gain), the error-statistics table beside Document C's published one,
  notes;
* ``vibration_imfs.png`` — the record, every IMF (labelled random / periodic / trend)
  and the residue;
* ``vibration_orders.png`` — AIC and BIC against the AR order for every modelled IMF,
  the chosen order marked;
* ``vibration_fit.png`` — the record with the AR fit and the AR + Kalman fit, whole
  record (thinned) and a short zoom;
* ``vibration_error_hist.png`` — histograms of the two fit errors;
* ``vibration_analysis.json`` — ``analysis.to_dict()``.

Figures use matplotlib's object API (``Figure`` + Agg), no pyplot state.  Long records
are thinned to ≤ 20 000 plotted points.
"""

from __future__ import annotations

import functools
import json
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from bench.analysis.vibration import VibrationAnalysis
from bench.app.reports.common import MAX_POINTS, save_figure
from bench.app.reports.common import thin as _thin
from bench.app.reports.layout import context_header, write_report

_ZOOM_SAMPLES = 400
_KIND_COLOUR = {"random": "C0", "periodic": "C3", "trend": "C2"}
_save = functools.partial(save_figure, dpi=100)
DOCUMENT_C = (("AR model fit", 7.3677e-6, 0.0041), ("AR + Kalman fit", 3.9332e-6, 0.0018))  # °/s


def _imf_figure(a: VibrationAnalysis, path: Path) -> str:
    dec = a.decomposition
    rows = [("record", a.y, "k")]
    for c in a.terms.components:
        data = dec.residue if c.index == 0 else dec.imfs[c.index - 1]
        rows.append((f"{c.label} ({c.kind})", data, _KIND_COLOUR[c.kind]))
    fig = Figure(figsize=(9, 1.0 + 0.75 * len(rows)))
    axes = fig.subplots(len(rows), 1, sharex=True, squeeze=False)[:, 0]
    for ax, (label, data, colour) in zip(axes, rows):
        t, d = _thin(a.time_s, data)
        ax.plot(t, d, lw=0.5, color=colour)
        ax.set_ylabel(label, rotation=0, ha="right", va="center", fontsize=7)
        ax.tick_params(labelsize=6)
    axes[0].set_title(f"EMD: {dec.n_imfs} IMFs + residue (stop rule {dec.stop})")
    axes[-1].set_xlabel("time (s)")
    return _save(fig, path)


def _order_figure(a: VibrationAnalysis, path: Path) -> str:
    k = max(1, len(a.models))
    cols = min(4, k)
    nrow = -(-k // cols)
    fig = Figure(figsize=(9, 2.2 * nrow))
    axes = fig.subplots(nrow, cols, squeeze=False).ravel()
    for ax, m in zip(axes, a.models):
        orders = np.asarray(m.orders)
        aic, bic = np.asarray(m.aic), np.asarray(m.bic)
        ax.plot(orders, aic - aic.min(), "o-", ms=3, lw=1, color="C0", label="AIC − min")
        ax.plot(orders, bic - bic.min(), "s-", ms=3, lw=1, color="C1", label="BIC − min")
        ax.axvline(m.p, color="k", lw=0.8, ls="--")
        ax.set_yscale("symlog", linthresh=10)
        ax.set_title(f"IMF{m.index}: AIC {m.aic_order}, BIC {m.bic_order} → p = {m.p}", fontsize=8)
        ax.tick_params(labelsize=6)
        ax.set_xlabel("AR order p", fontsize=7)
    for ax in axes[len(a.models):]:
        ax.set_visible(False)
    if a.models:
        axes[0].legend(fontsize=6)
    else:
        axes[0].set_visible(True)
        axes[0].text(0.5, 0.5, "no random IMF to model", ha="center", transform=axes[0].transAxes)
    return _save(fig, path)


def _fit_figure(a: VibrationAnalysis, path: Path) -> str:
    fig = Figure(figsize=(9, 6))
    ax1, ax2 = fig.subplots(2, 1)
    t, y, far, fk = _thin(a.time_s, a.y, a.fit_ar, a.fit_ar_kalman)
    ax1.plot(t, y, lw=0.5, color="0.6", label="record")
    ax1.plot(t, a.terms.signal[:: max(1, a.y.size // MAX_POINTS)], lw=1.0, color="C2", label="non-random terms")
    ax1.set(xlabel="time (s)", ylabel="y", title="Record and its non-random terms (trend + periodic)")
    ax1.legend(fontsize=7, loc="upper right")
    s = slice(a.compared_from, min(a.y.size, a.compared_from + _ZOOM_SAMPLES))
    ax2.plot(a.time_s[s], a.y[s], "o", ms=2, color="0.4", label="record")
    ax2.plot(a.time_s[s], a.fit_ar[s], lw=0.9, color="C1", label="AR fit (one-step prediction)")
    ax2.plot(a.time_s[s], a.fit_ar_kalman[s], lw=0.9, color="C0", label="AR + Kalman fit (filtered)")
    ax2.set(xlabel="time (s)", ylabel="y", title=f"Zoom: first {s.stop - s.start} compared samples")
    ax2.legend(fontsize=7, loc="upper right")
    return _save(fig, path)


def _error_figure(a: VibrationAnalysis, path: Path) -> str:
    s = slice(a.compared_from, None)
    e_ar, e_k = a.y[s] - a.fit_ar[s], a.y[s] - a.fit_ar_kalman[s]
    fig = Figure(figsize=(9, 3.5))
    ax = fig.add_subplot()
    lim = float(np.percentile(np.abs(e_ar), 99.9)) or 1.0
    bins = np.linspace(-lim, lim, 121).tolist()  # a list: the bin edges as matplotlib's stubs type them
    ax.hist(e_ar, bins=bins, histtype="step", color="C1", label=f"AR fit, std {a.error_ar.std:.3g}")
    ax.hist(e_k, bins=bins, histtype="step", color="C0", label=f"AR + Kalman fit, std {a.error_ar_kalman.std:.3g}")
    ax.set(xlabel="fit error y − fit", ylabel="samples", title="Fit error distribution")
    ax.legend(fontsize=8)
    return _save(fig, path)


def _g(x: float, digits: int = 4) -> str:
    return f"{x:.{digits}g}"


def write_vibration_report(analysis: VibrationAnalysis, directory: str | Path, context: dict | None = None,
                           *, pdf: bool = True) -> Path:
    """Write the report files into ``directory`` (created if missing); return the HTML path.

    ``context`` (optional) heads the report: where the record came from (``input`` names the
    file whose SHA-256 goes to the page's foot; ``run`` + ``digest`` a stored run; ``operator``
    also fills the approval block's "tested by").
    """
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    a = analysis
    figs = {"imfs": _imf_figure(a, out / "vibration_imfs.png"),
            "orders": _order_figure(a, out / "vibration_orders.png"),
            "fit": _fit_figure(a, out / "vibration_fit.png"),
            "hist": _error_figure(a, out / "vibration_error_hist.png")}
    (out / "vibration_analysis.json").write_text(json.dumps(a.to_dict(), indent=2, allow_nan=False))
    comp_rows = [[c.label, c.kind, _g(c.frequency_hz), _g(c.amplitude), _g(c.rms), _g(c.cycles), c.reason]
                 for c in a.terms.components]
    model_rows = [[f"IMF{m.index}", m.p, m.aic_order, m.bic_order, ", ".join(f"{v:.4f}" for v in m.ar), _g(m.sigma2),
                   _g(m.residual_white.ljung_box_p, 3), _g(m.adf.p_value, 3), _g(m.kpss.p_value, 3),
                   _g(m.imf_white.ljung_box_p, 3), m.identified, _g(k.gain[0], 3)]
                  for m, k in zip(a.models, a.kalman)]
    err_rows: list[list[object]] = [
        ["AR model fit", _g(a.error_ar.mean), _g(a.error_ar.std), DOCUMENT_C[0][1], DOCUMENT_C[0][2]],
        ["AR + Kalman fit", _g(a.error_ar_kalman.mean), _g(a.error_ar_kalman.std), DOCUMENT_C[1][1], DOCUMENT_C[1][2]],
        ["std ratio (Kalman / AR)", "", _g(a.std_ratio, 3), "", _g(DOCUMENT_C[1][2] / DOCUMENT_C[0][2], 3)],
    ]
    header = context_header("Random-vibration error model (Document C)", context, numbers="vibration_analysis.json")
    return write_report(out / "vibration_report.html", "vibration.html.j2", header, pdf=pdf, a=a,
                        dec=a.decomposition, figs=figs, errors=err_rows, components=comp_rows, models=model_rows,
                        r_ratio=_g(a.settings["r_ratio"]))
