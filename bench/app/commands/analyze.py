"""``bench analyze startup --input FILE.csv`` and ``bench analyze run ID|latest``: Document A's start-up model.

Both print a text summary (or ``--json``: the numbers of ``StartupAnalysis.to_dict()``)
and with ``--report DIR`` write the HTML report there.  Handlers return 0 on success
and 2 on a usage or input error, after one line ``bench: error: …`` on stderr.
"""

from __future__ import annotations

import argparse
import csv
import importlib
import json
import pkgutil
import sys
import tempfile
from pathlib import Path

import numpy as np

import bench.app.commands
from bench.analysis.startup import analyze_startup
from bench.analysis.timeseries import AR_METHODS
from bench.app.commands.common import attach_folder, require_store, resolve_run_id
from bench.app.verdict import record_digest
from bench.core.store import DEFAULT_PATH, RunStore

RUN_STREAM, RUN_TIME_COL, RUN_VALUE_COL = "output", "t_s", "voltage_v"
ATTACHED = "analysis/startup/"  # where a stored run's start-up model and report are attached


def _analysis_modules() -> list[str]:
    """``bench.app.commands.analyze_<kind>`` modules; each adds ``bench analyze <kind>``."""
    return sorted(f"bench.app.commands.{m.name}" for m in pkgutil.iter_modules(bench.app.commands.__path__)
                  if m.name.startswith("analyze_"))


def configure(analyze: argparse.ArgumentParser) -> None:
    """Add ``analyze startup`` and ``analyze run`` to an argparse subparsers object."""
    kinds = analyze.add_subparsers(dest="analysis", metavar="ANALYSIS")
    kinds.required = True

    p = kinds.add_parser("startup", help="start-up model (Document A) of a CSV trace")
    p.add_argument("--input", required=True, metavar="FILE.csv", help="CSV with a header row; time in s")
    p.add_argument("--time-col", default="t", help="time column (s) [t]")
    p.add_argument("--value-col", default="y", help="output column, any unit [y]")
    _common(p)
    p.set_defaults(func=analyze_startup_csv)

    r = kinds.add_parser("run", help="start-up model of a stored start-up run (samples from power-on)")
    r.add_argument("run_id", metavar="ID", help="run id or 'latest'")
    r.add_argument("--stream", default=RUN_STREAM, help=f"stream to analyse [{RUN_STREAM}]")
    r.add_argument("--time-col", default=RUN_TIME_COL, help=f"time column (s since power-on) [{RUN_TIME_COL}]")
    r.add_argument("--value-col", default=RUN_VALUE_COL, help=f"output column [{RUN_VALUE_COL}]")
    r.add_argument("--store", default=argparse.SUPPRESS, help="run store path (overrides bench --store)")
    _common(r)
    r.set_defaults(func=analyze_stored_run)

    # Further analyses live in their own modules, each with ``register_analysis(kinds)``.
    for name in _analysis_modules():
        importlib.import_module(name).register_analysis(kinds)


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--json", action="store_true", help="print the results as JSON")
    p.add_argument("--report", metavar="DIR", default=None, help="write the HTML report into DIR")
    p.add_argument("--noise-source", choices=("raw", "denoised"), default="raw",
                   help="series the ARMA model describes: raw − trend, or denoised − trend as Document A "
                        "literally does [raw]")
    p.add_argument("--trend-source", choices=("raw", "denoised"), default="raw",
                   help="series the trend is fitted to: raw (unbiased) or denoised (Document A's literal "
                        "order; τ biased by the soft threshold) [raw]")
    p.add_argument("--criterion", choices=("bic", "aic"), default="bic", help="order criterion [bic]")
    p.add_argument("--ar-method", choices=AR_METHODS, default="ulrych-clayton", help="AR estimator [ulrych-clayton]")
    p.add_argument("--max-ar-order", type=int, default=None, help="largest AR order in the grid [10]")
    p.add_argument("--max-arma-order", type=int, default=None, help="largest p and q in MA/ARMA grids [2]")
    p.add_argument("--outlier-z", type=float, default=3.0,
                   help="outlier threshold in standard deviations [3, Document A]")


def read_csv_table(path: str | Path, required: tuple, optional: tuple = (), *,
                   finite: bool = True) -> dict:
    """Numeric columns of a CSV with a header row: every ``required`` one and each ``optional``
    one present.  ``ValueError`` naming the file, line and column of the first fault (with
    ``finite``, a NaN or infinite value is one)."""
    path = Path(path)
    try:
        with path.open(newline="", encoding="utf-8-sig") as fh:
            reader = csv.reader(fh)
            header = next(reader, None)
            if not header:
                raise ValueError(f"{path}: empty file, expected a header row")
            header = [h.strip() for h in header]
            for name in required:
                if name not in header:
                    raise ValueError(f"{path}: no column {name!r}; columns are {', '.join(header)}")
            names = list(required) + [n for n in optional if n in header]
            cols = {n: header.index(n) for n in names}
            out: dict[str, list[float]] = {n: [] for n in names}
            for row_no, row in enumerate(reader, start=2):
                if not row or all(not c.strip() for c in row):
                    continue  # blank line
                for name, idx in cols.items():
                    try:
                        out[name].append(float(row[idx]))
                    except (IndexError, ValueError):
                        cell = row[idx] if idx < len(row) else "<missing>"
                        raise ValueError(f"{path} line {row_no}, column {name!r}: {cell!r} is not a number") from None
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise ValueError(f"cannot read {path}: {exc}") from None
    result = {n: np.asarray(v, dtype=float) for n, v in out.items()}
    for name, v in result.items() if finite else ():
        bad = np.flatnonzero(~np.isfinite(v))
        if bad.size:
            raise ValueError(f"{path} line {bad[0] + 2}, column {name!r}: {v[bad[0]]!r} is not finite")
    return result


def read_csv_columns(path: str | Path, time_col: str, value_col: str) -> tuple[np.ndarray, np.ndarray]:
    """Two numeric columns of a CSV with a header row; ``ValueError`` naming file, row and column.
    Non-finite values pass: each analysis names them in its own terms."""
    table = read_csv_table(path, (time_col, value_col), finite=False)
    return table[time_col], table[value_col]


def _options(args) -> dict:
    return {"noise_source": args.noise_source, "trend_source": args.trend_source, "criterion": args.criterion,
            "ar_method": args.ar_method, "max_ar_order": args.max_ar_order, "max_arma_order": args.max_arma_order,
            "outlier_z": args.outlier_z}


def _fail(message: str) -> int:
    print(f"bench: error: {' '.join(str(message).split())}", file=sys.stderr)
    return 2


def _analyse_and_print(t: np.ndarray, y: np.ndarray, args, report_dir: Path | None, label: str) -> int:
    analysis = analyze_startup(t, y, **_options(args))
    report = None
    if report_dir is not None:
        # lazy: matplotlib only when a report is drawn (every `bench analyze` imports this module)
        from bench.app.reports.startup_report import write_startup_report  # noqa: PLC0415 — lazy, see above

        report = write_startup_report(analysis, report_dir, {"input": label, "time column": args.time_col,
                                                             "value column": args.value_col})
    if args.json:
        print(json.dumps(analysis_document(analysis, label, report), indent=2, allow_nan=False))
    else:
        print_analysis(analysis, label, report)
    return 0


def analysis_document(analysis, label: str, report: Path | None, run_id: str | None = None) -> dict:
    """The ``--json`` form of an analysis: its numbers, where it came from, where its report is."""
    doc = analysis.to_dict()
    doc["source"] = label
    if run_id is not None:
        doc["attached"] = ATTACHED
    if report is not None:
        doc["report"] = str(report)
    return doc


def analysis_lines(analysis, label: str, report: Path | None, run_id: str | None = None) -> list[str]:
    """The text form: summary, where the report was attached and written."""
    lines = _summary(analysis, label).split("\n")
    if run_id is not None:
        lines.append(f"report attached to run {run_id} as {ATTACHED}startup_report.html")
    if report is not None:
        lines.append(f"report: {report}")
    return lines


def print_analysis(analysis, label: str, report: Path | None, run_id: str | None = None) -> None:
    print("\n".join(analysis_lines(analysis, label, report, run_id)))


def _summary(a, label: str) -> str:
    m, dn, sel = a.model, a.denoise, a.order_selection
    lines = [f"start-up model of {label}: {a.raw.size} samples every {m.sample_interval_s:.6g} s",
             m.equation(),
             f"denoise: {dn.wavelet} level {dn.level}, σ = {dn.sigma:.4g}, λ = {dn.threshold:.4g}",
             f"identified {a.identification.kind} ({a.identification.reason}); "
             f"best AIC {sel.best_aic}, best BIC {sel.best_bic}",
             f"outliers: {a.outliers.count}; Ljung–Box p = {a.ljung_box.p_value:.4g} ({a.ljung_box.dof} dof)"]
    lines += [f"note: {n}" for n in a.notes]
    return "\n".join(lines)


def analyze_startup_csv(args) -> int:
    """Handler of ``bench analyze startup``."""
    try:
        t, y = read_csv_columns(args.input, args.time_col, args.value_col)
        return _analyse_and_print(t, y, args, None if args.report is None else Path(args.report), args.input)
    except (ValueError, OSError) as exc:
        return _fail(str(exc))


def analyse_run(store_path, run_id: str, report_root: Path | None, *, stream: str = RUN_STREAM,
                time_col: str = RUN_TIME_COL, value_col: str = RUN_VALUE_COL, **options):
    """Analyse a stored start-up run (samples from power-on), write the report and attach it
    to the run under ``analysis/startup/``.  Returns ``(analysis, report_html_path)``; the
    report lives in ``report_root/<run_id>/`` (a temporary folder when ``report_root`` is None,
    in which case only the attached copy remains)."""
    # lazy: matplotlib only when a report is drawn (every `bench analyze` imports this module)
    from bench.app.reports.startup_report import write_startup_report  # noqa: PLC0415 — lazy, see above

    require_store(store_path)
    with RunStore(store_path) as store, tempfile.TemporaryDirectory() as tmp:
        run_id = resolve_run_id(store, run_id)
        data = store.load(run_id, stream)
        info = store.get_run(run_id)
        for col in (time_col, value_col):
            if col not in data:
                raise ValueError(f"stream {stream!r} of run {run_id} has no column {col!r}; "
                                 f"columns are {', '.join(data)}")
        t, y = np.asarray(data[time_col], float), np.asarray(data[value_col], float)
        keep = t >= 0.0  # Document A models the trace from power-on; the record starts before it
        analysis = analyze_startup(t[keep], y[keep], **options)
        context = {"run": run_id, "unit": info.unit_serial, "procedure": info.procedure,
                   "station": (info.station or {}).get("name"), "status": info.status,
                   "started (UTC)": info.started_utc, "seed": info.seed,
                   "run's code version": info.code_version, "stream": f"{stream}.{value_col}",
                   "digest": record_digest(store, run_id)}
        folder = Path(report_root) / run_id if report_root is not None else Path(tmp)
        report = write_startup_report(analysis, folder, context)
        attach_folder(store, run_id, report.parent, ATTACHED)  # the report and model travel with the run
    return run_id, analysis, (report if report_root is not None else None)


def analyze_stored_run(args) -> int:
    """Handler of ``bench analyze run``: the samples from power-on (t ≥ 0) of a stored run."""
    try:
        run_id, analysis, report = analyse_run(
            getattr(args, "store", DEFAULT_PATH), args.run_id,
            None if args.report is None else Path(args.report), stream=args.stream,
            time_col=args.time_col, value_col=args.value_col, **_options(args))
        label = f"run {run_id}"
        if args.json:
            print(json.dumps(analysis_document(analysis, label, report, run_id), indent=2,
                             allow_nan=False))
        else:
            print_analysis(analysis, label, report, run_id)
        return 0
    except (ValueError, OSError, LookupError) as exc:
        return _fail(str(exc))
