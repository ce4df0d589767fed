"""``bench analyze vibration --input FILE.csv``: Document C's EMD → AR → AR-Kalman error model
(and :func:`analyse_vibration_run`, the same model of a stored ``bench run vibration`` run).

Reads a time column (s) and a rate column from a CSV with a header row; the sampling
must be uniform (every interval within 1 % of the median — a gap or restart is refused,
not bridged: EMD and the AR models need a uniform time base).  Prints a summary (or
``--json``: ``VibrationAnalysis.to_dict()`` plus ``source``) and with ``--report DIR``
writes the HTML report there.  Bad input raises ``ValueError``; ``bench`` prints it as
one line ``bench: error: …`` and exits 2.
"""

from __future__ import annotations

import json
import tempfile
from pathlib import Path

import numpy as np

from bench.analysis.emd import STOP_RULES
from bench.analysis.vibration import analyze_vibration
from bench.app.commands.analyze import analysis_document, read_csv_columns
from bench.app.commands.common import attach_folder
from bench.app.verdict import record_digest
from bench.core.store import RunStore

DOCUMENT_C = {"ar": (7.3677e-6, 0.0041), "ar_kalman": (3.9332e-6, 0.0018)}  # °/s, published table
ATTACHED = "analysis/vibration/"  # where a stored run's vibration model and report are attached


def register_analysis(kinds) -> None:
    """Add ``vibration`` to the ``bench analyze`` subparsers."""
    p = kinds.add_parser("vibration", help="EMD → AR → AR-Kalman random-vibration error model (Document C)")
    p.add_argument("--input", required=True, metavar="FILE.csv", help="CSV with a header row; time in s")
    p.add_argument("--time-col", default="t", help="time column (s) [t]")
    p.add_argument("--value-col", default="y", help="rate column, any unit (e.g. deg/s) [y]")
    p.add_argument("--json", action="store_true", help="print the results as JSON")
    p.add_argument("--report", metavar="DIR", default=None, help="write the HTML report into DIR")
    p.add_argument("--stop", choices=STOP_RULES, default="sd", help="EMD sifting stop criterion [sd]")
    p.add_argument("--max-imfs", type=int, default=None, help="most IMFs to extract [no limit]")
    p.add_argument("--max-sifts", type=int, default=1000, help="most siftings per IMF [1000]")
    p.add_argument("--p-max", type=int, default=15, help="largest AR order tried per IMF [15]")
    p.add_argument("--criterion", choices=("bic", "aic"), default="bic", help="AR order criterion [bic]")
    p.add_argument("--r-ratio", type=float, default=1.0,
                   help="Kalman measurement noise R as a multiple of the AR innovation variance [1]")
    p.add_argument("--min-cycles", type=float, default=8.0,
                   help="IMFs with fewer oscillations in the record count as trend [8]")
    p.set_defaults(func=analyze_vibration_csv)


def summary(a, label: str) -> str:
    """The text form of a :class:`~bench.analysis.vibration._pipeline.VibrationAnalysis`."""
    dec = a.decomposition
    lines = [f"random-vibration error model of {label}: {a.y.size} samples at {a.rate_hz:.6g} Hz "
             f"({a.y.size / a.rate_hz:.6g} s)",
             f"EMD ({dec.stop}): {dec.n_imfs} IMFs + residue, siftings {list(dec.sifts)}"]
    for c in a.terms.nonrandom:
        lines.append(f"non-random {c.label}: {c.kind}, {c.frequency_hz:.4g} Hz, amplitude {c.amplitude:.4g} "
                     f"— {c.reason}")
    lines.append(f"{'IMF':>4} {'p':>3} {'AIC':>4} {'BIC':>4} {'resid LB p':>11} {'ADF p':>9} {'KPSS p':>7} "
                 f"{'ident':>5} {'K1':>6}")
    for m, k in zip(a.models, a.kalman):
        lines.append(f"{m.index:>4} {m.p:>3} {m.aic_order:>4} {m.bic_order:>4} {m.residual_white.ljung_box_p:>11.3g} "
                     f"{m.adf.p_value:>9.3g} {m.kpss.p_value:>7.3g} {m.identified:>5} {k.gain[0]:>6.3f}")
    ea, ek = a.error_ar, a.error_ar_kalman
    lines += [f"fit error (y − fit, from sample {a.compared_from}):      mean          std",
              f"  AR model fit               {ea.mean:>14.5g} {ea.std:>12.5g}",
              f"  AR + Kalman fit            {ek.mean:>14.5g} {ek.std:>12.5g}",
              f"  std ratio AR+Kalman / AR   {a.std_ratio:>27.3f}  (Document C: "
              f"{DOCUMENT_C['ar_kalman'][1] / DOCUMENT_C['ar'][1]:.2f})"]
    lines += [f"note: {n}" for n in a.notes]
    return "\n".join(lines)


def analyze_vibration_csv(args) -> int:
    """Handler of ``bench analyze vibration``."""
    t, y = read_csv_columns(args.input, args.time_col, args.value_col)
    analysis = analyze_vibration(t, y, stop=args.stop, max_imfs=args.max_imfs, max_sifts=args.max_sifts,
                                 p_max=args.p_max, criterion=args.criterion, r_ratio=args.r_ratio,
                                 min_cycles=args.min_cycles)
    report = None
    if args.report is not None:
        # lazy: matplotlib only when --report asks for a report (every `bench analyze` imports this module)
        from bench.app.reports.vibration_report import write_vibration_report  # noqa: PLC0415 — lazy, see above

        report = write_vibration_report(analysis, Path(args.report),
                                        {"input": args.input, "time column": f"{args.time_col} (s)",
                                         "rate column": args.value_col})
    if args.json:
        print(json.dumps(analysis_document(analysis, args.input, report), indent=2, allow_nan=False))
    else:
        print(summary(analysis, args.input))
        if report is not None:
            print(f"report: {report}")
    return 0


def analyse_vibration_run(store_path, run_id: str, report_root: Path | None):
    """Document C's model of a stored vibration run's steady vibration segment; the report is
    attached to the run under ``analysis/vibration/``.  Returns ``(analysis, report path or
    None)``; the report is also written to ``report_root/<run id>/`` when one is given."""
    # lazy: matplotlib only when a report is drawn (every `bench analyze` imports this module)
    from bench.app.reports.vibration_report import write_vibration_report  # noqa: PLC0415 — lazy, see above

    with RunStore(store_path) as store, tempfile.TemporaryDirectory() as tmp:
        frames = store.load(run_id, "gyro_frames")
        keep = (frames["segment"] == 1) & frames["steady"].astype(bool)
        if not np.any(keep):
            raise ValueError(f"run {run_id} has no steady vibration frames to analyse")
        analysis = analyze_vibration(frames["t_s"][keep], frames["rate_dps"][keep])
        info = store.get_run(run_id)
        labels = info.labels or {}
        context = {"run": run_id, "unit": info.unit_serial, "procedure": info.procedure,
                   "station": labels.get("station_id") or (info.station or {}).get("name"),
                   "operator": labels.get("operator"), "started (UTC)": info.started_utc, "seed": info.seed,
                   "run's code version": info.code_version,
                   "record": "gyro_frames.rate_dps, steady vibration segment (deg/s)",
                   "digest": record_digest(store, run_id)}
        folder = Path(report_root) / run_id if report_root is not None else Path(tmp)
        report = write_vibration_report(analysis, folder, context)
        attach_folder(store, run_id, report.parent, ATTACHED)
    return analysis, (report if report_root is not None else None)
