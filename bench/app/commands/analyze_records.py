"""``bench analyze thermal|tumble|ratetable|turn-on --input FILE``: a record made elsewhere,
analysed as the station's step analyses its own (``bench.app.record_analysis``).

The file follows the column convention of its kind (``bench.app.records``; a metadata TOML
``--meta`` or ``--col NAME=COLUMN[:UNIT]`` maps other names and units). Prints a table (or
``--json``), and with ``--report DIR`` writes one self-contained HTML report there (plus the
thermal compensation file). Exit 0, or 2 after one line ``bench: error: …`` naming the file,
column and row of a bad input.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from bench.app.record_analysis import ANALYSES, RecordAnalysis, analyze_record, write_report
from bench.app.records import KINDS, SENSORS, Meta, parse_column_option, read_meta, read_record

#: kind -> its options: (flag, dest, type, help)
OPTIONS: dict[str, list[tuple[str, str, Any, str]]] = {
    "tumble": [("--g-over-g0", "g_over_g0", float, "local gravity over standard gravity, 0.95..1.05 [1]"),
               ("--output-unit-per-ma", "output_unit_per_ma", float,
                "output units per mA (1e-3: output in A; a resistor R read in V: R·1e-3) [1e-3]")],
    "ratetable": [("--full-scale-dps", "full_scale_dps", float, "the gyro's full scale, °/s [largest |rate|]"),
                  ("--nominal-scale-factor", "nominal_scale_factor", float, "output units per °/s [1]")],
    "turn-on": [("--settled-window-s", "settled_window_s", float,
                 "each cycle's bias is its mean over this last part, s [300, at most half the shortest cycle]"),
                ("--band", "band", float, "settling band ± in the output's unit: also each cycle's turn-on time")],
    "thermal": [("--reference-c", "reference_c", float, "temperature the coefficients are read at, °C [25]"),
                ("--lag", "lag", str, "the element's lag behind the logged temperature: 'fit' or seconds [fit]")],
}


def add_record_options(p: argparse.ArgumentParser) -> None:
    """The options that say what a record file is (shared with ``bench runs import``)."""
    p.add_argument("--meta", metavar="FILE.toml", default=None, help="metadata file (kind, unit, columns, parameters)")
    p.add_argument("--col", action="append", default=[], metavar="NAME=COLUMN[:UNIT]",
                   help="the file's column for a bench column, and its unit (repeatable), e.g. t_s=Time:ms")
    p.add_argument("--output-unit", default=None, help="unit of the output column (e.g. deg/s, V, g) [1]")
    p.add_argument("--serial", default=None, help="the unit's serial number")
    p.add_argument("--sensor", default=None, choices=SENSORS, help="what the unit is")
    p.add_argument("--unit-model", dest="unit_model", default=None, help="the unit's model")
    p.add_argument("--station-id", dest="station_id", default=None, help="the rig the record was made on")
    p.add_argument("--lot", default=None, help="the unit's lot")
    p.add_argument("--operator", default=None, help="who made the record")


def meta_of(args: argparse.Namespace, kind: str | None) -> Meta:
    """The record's metadata: ``--meta`` with the command line's fields on top."""
    columns = dict(parse_column_option(c) for c in args.col)
    return read_meta(args.meta, kind=kind, overrides={
        "output_unit": args.output_unit, "unit_serial": args.serial, "sensor": args.sensor,
        "model": args.unit_model, "station_id": args.station_id, "lot": args.lot, "operator": args.operator,
        "columns": columns})


def register_analysis(kinds: argparse._SubParsersAction) -> None:
    for kind in ANALYSES:
        p = kinds.add_parser(kind, help=f"{KINDS[kind].what}, from a file (CSV or HDF5)")
        p.add_argument("--input", required=True, metavar="FILE", help="the record: CSV with a header row, or HDF5")
        add_record_options(p)
        for flag, dest, typ, text in OPTIONS[kind]:
            p.add_argument(flag, dest=dest, type=typ, default=None, help=text)
        p.add_argument("--json", action="store_true", help="print the results as JSON")
        p.add_argument("--report", metavar="DIR", default=None, help="write the HTML report (one file) into DIR")
        p.set_defaults(func=analyze_file, record_kind=kind)


def options_of(args: argparse.Namespace, kind: str) -> dict[str, Any]:
    return {dest: getattr(args, dest, None) for _, dest, _, _ in OPTIONS.get(kind, [])}


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
    report = write_report(analysis, record, args.report) if args.report else None
    if args.json:
        doc = {**analysis.to_dict(), "source": record.source, "sha256": record.sha256,
               "columns": record.conversions, "units": record.units}
        if report is not None:
            doc["report"] = str(report)
        print(json.dumps(doc, indent=2, default=float))
    else:
        print_analysis(analysis)
        if report is not None:
            print(f"report: {report}")
    return 0
