"""``bench analyze allan --input FILE.csv``: overlapping Allan deviation and IEEE 952 noise terms.

Reads a time column (s) and a value column from a CSV with a header row.  The sample
rate comes from the time column, which must be uniform (every interval within 1 % of
the mean interval — a dropped sample or a restart is refused, not bridged).  Prints a
table (or ``--json``: ``AllanResult.to_dict()`` plus ``source``) and with ``--report DIR``
writes the HTML report there.  ``--robust`` replaces isolated outliers first (at
``--false-alarm`` per record); the table, JSON and report show each term's check against
the curve and whether the estimate is robust.  Bad input raises ``ValueError``; ``bench`` prints it as
one line ``bench: error: …`` and exits 2.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from bench.analysis.allan import DEFAULT_FALSE_ALARM, ONE_SIGMA, TERMS, overlapping_adev
from bench.app.commands.analyze import read_csv_columns

SAMPLING_TOLERANCE = 0.01


def register_analysis(kinds) -> None:
    """Add ``allan`` to the ``bench analyze`` subparsers."""
    p = kinds.add_parser("allan", help="overlapping Allan deviation and IEEE 952 noise terms of a static record")
    p.add_argument("--input", required=True, metavar="FILE.csv", help="CSV with a header row; time in s")
    p.add_argument("--time-col", default="t", help="time column (s) [t]")
    p.add_argument("--value-col", default="y", help="rate column (or angle with --data-type phase) [y]")
    p.add_argument("--unit", default="dps",
                   help="rate unit of the value column: dps, dph, radps, g, mg, ug, mps2 or none [dps]")
    p.add_argument("--data-type", choices=("rate", "phase"), default="rate",
                   help="rate samples, or their integral (angle, velocity) [rate]")
    p.add_argument("--taus", default="octave", help="octave, log, or comma-separated τ in s [octave]")
    p.add_argument("--points-per-decade", type=int, default=10, help="τ per decade for --taus log [10]")
    p.add_argument("--confidence", type=float, default=ONE_SIGMA, help="interval confidence [0.683]")
    p.add_argument("--terms", default=",".join(TERMS), help="noise terms the fit may use [Q,N,B,K,R]")
    p.add_argument("--robust", action="store_true",
                   help="replace isolated outliers (spikes) before the Allan variance; says how many")
    p.add_argument("--false-alarm", type=float, default=DEFAULT_FALSE_ALARM,
                   help="probability that the outlier screen flags a clean record at all [0.01]")
    p.add_argument("--json", action="store_true", help="print the results as JSON")
    p.add_argument("--report", metavar="DIR", default=None, help="write the HTML report into DIR")
    p.set_defaults(func=analyze_allan_csv)


def sample_rate_hz(t_s: np.ndarray) -> float:
    """Sample rate of a uniformly sampled time column; ``ValueError`` naming the first fault."""
    t = np.asarray(t_s, dtype=float)
    if t.size < 2:
        raise ValueError(f"the time column has {t.size} values; at least 2 are needed for a sample rate")
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise ValueError(f"time has {bad.size} non-finite values (first at sample index {bad[0]}); all must be finite")
    dt = np.diff(t)
    if np.any(dt <= 0):
        k = int(np.flatnonzero(dt <= 0)[0])
        raise ValueError(f"time is not strictly increasing at sample index {k + 1} "
                         f"({t[k]:.9g} s then {t[k + 1]:.9g} s)")
    step = float(t[-1] - t[0]) / (t.size - 1)
    deviation = np.abs(dt / step - 1.0)
    k = int(np.argmax(deviation))
    if deviation[k] > SAMPLING_TOLERANCE:
        raise ValueError(f"sampling is not uniform: the interval after sample index {k} is {dt[k]:.6g} s, "
                         f"{deviation[k]:.2%} off the mean {step:.6g} s (allowed ≤ {SAMPLING_TOLERANCE:.0%}); "
                         "Allan deviation needs a uniform record without gaps")
    return 1.0 / step


def _taus(text: str):
    if text in ("octave", "log"):
        return text
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise ValueError(f"--taus {text!r} must be 'octave', 'log' or comma-separated τ in s") from None
    if not values:
        raise ValueError(f"--taus {text!r} must be 'octave', 'log' or comma-separated τ in s")
    return np.array(values)


def _table(result) -> str:
    units = result.units
    lines = [f"{'tau (s)':>12} {'ADEV':>12} {'CI low':>12} {'CI high':>12} {'EDF':>10}  ({units['adev']}, "
             f"{result.confidence:.1%})"]
    for t, a, (lo, hi), e in zip(result.tau_s, result.adev, result.adev_ci, result.edf):
        lines.append(f"{t:12.6g} {a:12.5g} {lo:12.5g} {hi:12.5g} {e:10.4g}")
    lines.append("noise terms: fit ± 1σ | slope-line read-off | check against the curve (slope shown there)")
    for name, c in result.coefficients.items():
        fit = "not fitted" if c.fit is None else f"{c.fit:.4g} ± {'—' if c.fit_std is None else f'{c.fit_std:.2g}'}"
        ro = "—" if c.read_off is None else f"{c.read_off:.4g}"
        check = result.checks[name]
        shown = "" if check.curve_slope is None else f" (slope {check.curve_slope:+.2f} ± {check.curve_slope_sd:.2f})"
        lines.append(f"  {name} {c.label:<26} {fit:>22} | {ro:>10}  {c.unit:<14} | {check.status}{shown}")
    screen = result.outliers
    if screen is not None:
        state = "robust: outliers replaced" if result.robust else "plain estimate (--robust replaces outliers)"
        lines.append(f"{state}; {screen.n_flagged} samples ({screen.fraction:.2%}) flagged at false-alarm "
                     f"probability {screen.false_alarm:g} per record")
    return "\n".join(lines)


def analyze_allan_csv(args) -> int:
    """Handler of ``bench analyze allan``."""
    t, y = read_csv_columns(args.input, args.time_col, args.value_col)
    rate = sample_rate_hz(t)
    unit = None if args.unit.lower() == "none" else args.unit
    terms = tuple(s.strip() for s in args.terms.split(",") if s.strip())
    result = overlapping_adev(y, rate, _taus(args.taus), data_type=args.data_type,
                              points_per_decade=args.points_per_decade, unit=unit,
                              confidence=args.confidence, terms=terms, robust=args.robust,
                              false_alarm=args.false_alarm)
    report = None
    if args.report is not None:
        # lazy: matplotlib only when --report asks for a report (every `bench analyze` imports this module)
        from bench.app.reports.allan_plot import write_allan_report  # noqa: PLC0415 — lazy, see above

        report = write_allan_report(result, Path(args.report), {"input": args.input, "column": args.value_col})
    if args.json:
        doc = result.to_dict()
        doc["source"] = args.input
        if report is not None:
            doc["report"] = str(report)
        print(json.dumps(doc, indent=2, allow_nan=False))
    else:
        print(f"Allan deviation of {args.input}: {t.size} samples at {rate:.6g} Hz "
              f"({(t[-1] - t[0]):.6g} s, {args.data_type})")
        print(_table(result))
        for note in result.notes:
            print(f"note: {note}")
        if report is not None:
            print(f"report: {report}")
    return 0
