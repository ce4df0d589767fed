"""The command-line options that say what a record file is and how its kind is analysed: shared
by ``bench analyze <kind> --input`` and ``bench runs import`` (light: ``bench runs list`` imports
this module, so nothing here imports the analyses)."""

from __future__ import annotations

import argparse
from typing import Any

from bench.app.records import SENSORS, Meta, parse_column_option, read_meta

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
                ("--lag", "lag", str, "the element's lag behind the logged temperature: 'fit' or seconds [fit]"),
                ("--hysteresis", "hysteresis", "flag",
                 "also fit thermal hysteresis with its switching width (a record that reverses)")],
}


def add_kind_option(p: argparse.ArgumentParser, flag: str, dest: str, typ: Any, text: str) -> None:
    """One of :data:`OPTIONS` (``typ`` "flag": a switch)."""
    if typ == "flag":
        p.add_argument(flag, dest=dest, action="store_const", const=True, default=None, help=text)
    else:
        p.add_argument(flag, dest=dest, type=typ, default=None, help=text)


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


def options_of(args: argparse.Namespace, kind: str) -> dict[str, Any]:
    return {dest: getattr(args, dest, None) for _, dest, _, _ in OPTIONS.get(kind, [])}
