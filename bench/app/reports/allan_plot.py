"""Allan plot and report, built only from an :class:`~bench.analysis.allan._adev.AllanResult`.

* :func:`plot_allan` draws onto any matplotlib ``Axes`` (other reports — acceptance,
  vibration — place it in their own figures): log-log ADEV with confidence bars, the
  fitted model, one dashed line per fitted term (its slope), and the slope-line
  read-offs — a dotted line through the curve point each was read from and a marker
  where it is read (τ = √3, 1, 3, √2 s; B at the minimum).
* :func:`write_allan_report` writes ``allan_report.html`` (``templates/allan.html.j2`` on the
  shared layout), its PDF, ``allan_plot.png`` and ``allan_result.json`` into a directory.

Figures use the object API (``Figure`` + Agg canvas): no pyplot state, no GUI backend.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from bench.analysis.allan import B_FACTOR, CHECK_CONFIDENCE, AllanResult, term_adev
from bench.app.reports.layout import context_header, write_report

_COLOURS = {"Q": "C4", "N": "C2", "B": "C1", "K": "C5", "R": "C6"}
_SLOPE_TEXT = {"Q": "−1", "N": "−1/2", "B": "0", "K": "+1/2", "R": "+1"}


def _g(x: float | None, digits: int = 4) -> str:
    return "—" if x is None else f"{x:.{digits}g}"


def _span(result: AllanResult) -> np.ndarray:
    """τ grid for lines: the data range widened to every read-off τ."""
    taus = [float(result.tau_s[0]), float(result.tau_s[-1])]
    for c in result.coefficients.values():
        taus += [t for t in (c.read_at_tau_s, c.read_off_tau_s) if t is not None and c.read_off_input is not None]
    return np.geomspace(min(taus), max(taus), 200)


def model_segments(result: AllanResult) -> list[tuple[float, float]]:
    """The τ ranges where the fitted model lies within the measured curve's intervals: runs of
    two or more consecutive τ whose interval holds the model. A plot draws the model there only
    — outside them the model is not what the data show (e.g. a fitted random walk above points
    that keep falling), and a line through them would read as a finding."""
    ok = result.adev > 0
    if not np.any(ok) or not any(c.fit_input for c in result.coefficients.values()):
        return []
    tau, ci = result.tau_s[ok], result.adev_ci[ok]
    model = result.model_adev(tau)
    inside = (model >= ci[:, 0]) & (model <= ci[:, 1]) & (model > 0)
    edges = np.flatnonzero(np.diff(np.r_[0, inside.astype(np.int8), 0]))  # each run's [start, stop)
    return [(float(tau[a]), float(tau[b - 1])) for a, b in zip(edges[::2], edges[1::2]) if b - a >= 2]


def model_spans_text(result: AllanResult) -> str:
    """The τ spans :func:`model_segments` draws the model over, as a caption names them
    (``τ 0.1–51.2 s, …``); empty when there are none."""
    return ", ".join(f"τ {lo:.3g}–{hi:.3g} s" for lo, hi in model_segments(result))


def plot_allan(ax: Axes, result: AllanResult, title: str | None = None, *, fit_values: bool = True) -> Axes:
    """Draw the Allan plot of ``result`` onto ``ax`` and return it.

    The fitted model is drawn only over :func:`model_segments`; each fitted term as a dashed line
    of its slope, labelled with its value when ``fit_values`` (a page whose table gives the
    read-off values passes False, so one value of each coefficient shows on the page)."""
    unit = result.units["adev"]
    ok = result.adev > 0
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set(xlabel="τ (s)", ylabel=f"Allan deviation ({unit})",
           title=title or f"Overlapping Allan deviation ({result.confidence:.1%} intervals)")
    if not np.any(ok):
        ax.text(0.5, 0.5, "every ADEV is zero (constant record)", transform=ax.transAxes, ha="center")
        return ax
    tau, dev, ci = result.tau_s[ok], result.adev[ok], result.adev_ci[ok]
    ax.errorbar(tau, dev, yerr=[dev - ci[:, 0], ci[:, 1] - dev], fmt="o", ms=4, color="C0",
                ecolor="C0", elinewidth=0.8, capsize=2, label="ADEV", zorder=3)
    grid = _span(result)
    for k, (lo, hi) in enumerate(model_segments(result)):
        span = np.geomspace(lo, hi, 60)
        ax.plot(span, result.model_adev(span), color="C3", lw=1.4, zorder=2,
                label="fitted model (where within the intervals)" if k == 0 else None)
    for name, c in result.coefficients.items():
        colour = _COLOURS[name]
        if c.fit_input:  # the fitted term alone: a line of its slope
            value = f" = {_g(c.fit)} {c.unit}" if fit_values else " (fitted)"
            ax.plot(grid, term_adev(name, c.fit_input, grid), "--", color=colour, lw=1.0,
                    label=f"{name}{value}, slope {_SLOPE_TEXT[name]}")
        if c.read_off_input is None or c.read_off_tau_s is None:  # both None: no part of the curve has the slope
            continue
        if c.read_at_tau_s is None:  # B: read at the curve's minimum, not at a fixed τ
            level = c.read_off_input * B_FACTOR
            ax.axhline(level, ls=":", color=colour, lw=0.9)
            ax.plot([c.read_off_tau_s], [level], "D", color=colour, ms=6, mfc="none",
                    label=f"read-off B = {_g(c.read_off)} {c.unit} (minimum / 0.664)")
            continue
        through = dev[np.argmin(np.abs(np.log(tau / c.read_off_tau_s)))]
        ax.plot(grid, through * (grid / c.read_off_tau_s) ** c.slope, ":", color=colour, lw=0.9)
        ax.plot([c.read_at_tau_s], [c.read_off_input], "D", color=colour, ms=6, mfc="none",
                label=f"read-off {name} = {_g(c.read_off)} {c.unit} at τ = {c.read_at_tau_s:.3g} s")
    low, high = float(np.min(ci[:, 0][ci[:, 0] > 0], initial=dev.min())), float(dev.max())
    ax.set_ylim(low / 3.0, high * 3.0)  # keep lines from stretching the axis by decades
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="best", fontsize=7)
    return ax


def write_allan_report(result: AllanResult, directory: str | Path, context: dict | None = None,
                       title: str | None = None, *, pdf: bool = True) -> Path:
    """Write the report files into ``directory`` (created if missing); return the HTML path.

    ``context`` (optional) heads the report: where the record came from (``input`` names the
    file whose SHA-256 goes to the page's foot; ``run`` + ``digest`` a stored run).
    """
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    fig = Figure(figsize=(9, 6))
    plot_allan(fig.add_subplot(), result, title)
    fig.tight_layout()
    fig.savefig(out / "allan_plot.png", dpi=110)
    (out / "allan_result.json").write_text(json.dumps(result.to_dict(), indent=2, allow_nan=False))

    coef_rows = []
    for name, c in result.coefficients.items():
        d = c.to_dict()
        fit = "not fitted" if c.fit_input is None else f"{_g(c.fit)} ± {_g(c.fit_std, 2)}"
        coef_rows.append([name, c.label, fit, _g(c.read_off), c.unit,
                          f"{_g(d['alt']['value'])} / {_g(d['alt']['read_off'])} {c.alt_unit}",
                          _g(c.read_off_tau_s)])
    curve_rows = [[_g(t, 6), _g(a), _g(lo), _g(hi), f"{e:.1f}", int(al), int(nt)]
                  for t, a, (lo, hi), e, al, nt in zip(result.tau_s, result.adev, result.adev_ci, result.edf,
                                                        result.noise_alpha, result.n_terms)]
    check_rows = []
    for name, ch in result.checks.items():
        f = result.coefficients[name].factor
        iv = ch.read_off_interval_input
        check_rows.append([name, ch.status, "—" if ch.curve_slope is None else
                           f"{ch.curve_slope:+.2f} ± {ch.curve_slope_sd:.2f} ({ch.shows})",
                           "—" if ch.read_off_input is None or iv is None else
                           f"{_g(ch.read_off_input * f)} [{_g(iv[0] * f)}, {_g(iv[1] * f)}]",
                           ch.message or ""])
    screen = result.outliers
    robust_text = ("robust estimate: flagged outliers replaced by their neighbour median" if result.robust
                   else "plain estimate (no outlier replacement)")
    if screen is not None:
        robust_text += (f"; {screen.n_flagged} samples ({screen.fraction:.2%}) flagged at false-alarm probability "
                        f"{screen.false_alarm:g} per record")
    spans = model_spans_text(result)
    model_caption = (f"The fitted model (red) is drawn where it lies within the intervals: {spans}." if spans else
                     "The fitted model lies outside the intervals everywhere; it is not drawn.")
    header = context_header(title or "Allan deviation (IEEE Std 952)", context, numbers="allan_result.json")
    return write_report(out / "allan_report.html", "allan.html.j2", header, pdf=pdf, r=result,
                        duration=result.n_samples / result.sample_rate_hz, model_caption=model_caption,
                        coefficients=coef_rows, checks=check_rows, robust_text=robust_text,
                        check_confidence=CHECK_CONFIDENCE, curve=curve_rows)
