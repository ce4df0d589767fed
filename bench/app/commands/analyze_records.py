"""``bench analyze thermal|tumble|ratetable|turn-on --input FILE``: a record made elsewhere,
analysed as the station's step analyses its own (``bench.app.record_analysis``).

The file follows the column convention of its kind (``bench.app.records``; a metadata TOML
``--meta`` or ``--col NAME=COLUMN[:UNIT]`` maps other names and units). Prints a table (or
``--json``), and with ``--report DIR`` writes one self-contained HTML report there, its PDF beside
it (plus the thermal compensation file). Exit 0, or 2 after one line ``bench: error: …`` naming the file,
column and row of a bad input.
"""

from __future__ import annotations

import argparse
import json
import sys

from bench.app.commands.record_options import OPTIONS, add_kind_option, add_record_options, meta_of, options_of
from bench.app.record_analysis import ANALYSES, RecordAnalysis, analyze_record, json_safe, write_report
from bench.app.records import KINDS, read_record


def register_analysis(kinds: argparse._SubParsersAction) -> None:
    for kind in ANALYSES:
        p = kinds.add_parser(kind, help=f"{KINDS[kind].what}, from a file (CSV or HDF5)")
        p.add_argument("--input", required=True, metavar="FILE", help="the record: CSV with a header row, or HDF5")
        add_record_options(p)
        for flag, dest, typ, text in OPTIONS[kind]:
            add_kind_option(p, flag, dest, typ, text)
        p.add_argument("--json", action="store_true", help="print the results as JSON")
        p.add_argument("--report", metavar="DIR", default=None,
                       help="write the HTML report (one file) and its PDF into DIR")
        p.set_defaults(func=analyze_file, record_kind=kind)


def print_analysis(a: RecordAnalysis) -> None:
    for line in a.summary:
        print(line)
    print(f"  {'measurement':<24} {'value':>14} {'± 1σ':>10}  unit")
    for m in a.measurements:
        value = "—" if m["value"] is None else f"{m['value']:.6g}"
        unc = "" if m["uncertainty"] is None else f"{m['uncertainty']:.2g}"
        print(f"  {m['name']:<24} {value:>14} {unc:>10}  {m['unit']}")
    for note in a.notes:
        print(f"note: {note}")


def analyze_file(args: argparse.Namespace) -> int:
    """Handler of ``bench analyze <kind> --input FILE``."""
    kind = args.record_kind
    record = read_record(args.input, meta_of(args, kind))
    print(f"analysing {record.n_rows} rows of {args.input} ({kind})", file=sys.stderr, flush=True)
    analysis = analyze_record(record, **options_of(args, kind))
    given = {flag: getattr(args, dest) for flag, dest, _, _ in OPTIONS[kind] if getattr(args, dest, None) is not None}
    report = (write_report(analysis, record, args.report, {"metadata file": args.meta, **given})
              if args.report else None)
    if args.json:
        doc = {**analysis.to_dict(), "source": record.source, "sha256": record.sha256,
               "columns": record.conversions, "units": record.units}
        if report is not None:
            doc["report"] = str(report)
        print(json.dumps(json_safe(doc), indent=2, allow_nan=False))
    else:
        print_analysis(analysis)
        if report is not None:
            print(f"report: {report}")
    return 0
