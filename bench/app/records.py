"""Records made elsewhere: the column and metadata convention per kind of record, read and checked.

A lab's own rigs (LabVIEW, a turntable vendor's software, a chamber logger) write CSV or HDF5
tables. :func:`read_record` reads one, finds the columns a **kind** of record needs, converts
their units to the bench's, and checks the values as strictly as a station run would be: every
error names the file, the column and the row (the line of a CSV, counting the header as line
1) and the allowed range. The same reading serves ``bench runs import`` (the record becomes a
stored run) and ``bench analyze thermal|tumble|ratetable|turn-on --input`` (the record is
analysed as the station's step would analyse it).

Kinds (:data:`KINDS`), their columns (the bench's name, the unit stored, what it is):

=============  ===========================================================================
kind           columns (``?``: optional)
=============  ===========================================================================
``static``     ``t_s`` time (s), ``output``, ``temperature_c``? (°C)
``startup``    ``t_s`` time from power-on (s, ≥ 0), ``output``, ``temperature_c``? (°C)
``thermal``    ``t_s`` (s), ``output``, ``temperature_c`` the logged sensor (°C),
               ``applied``? the applied input (rate-table rate or g) for the scale factor
``tumble``     ``inner_deg``, ``outer_deg`` table angles (°), ``output``, ``output_se``? the
               standard error of each mean; rows of one position are averaged
``ratetable``  ``input_rate_dps`` input rate, Earth rate included (°/s), ``output``,
               ``output_se``?; rows of one rate are averaged
``turn-on``    ``cycle`` power cycle (integer), ``t_s`` time from that cycle's power-on (s),
               ``output``, ``day``? (integer)
=============  ===========================================================================

A file's column is found by the bench's name (``t_s``), by a common name with its unit in
brackets (``Time [ms]``, ``Temp (K)``, ``Inner [rad]``, ``Rate [deg/h]``, ``y [V]``), or by a
mapping the user gives (``--col t_s=Time:ms`` or the
metadata file's ``[columns]`` table). Units of time (s, ms, min, h), temperature (degC, K,
degF), angle (deg, rad) and rate (deg/s, deg/h, rad/s) are converted; ``output`` keeps the
unit the metadata names (``output_unit``, default ``1``).

Metadata (a TOML file, ``--meta``; command-line fields override it)::

    kind = "thermal"
    sensor = "gyro"                    # or "accelerometer"
    unit_serial = "FOG-0042"
    model = "FOG-200"
    output_unit = "deg/s"
    station_id = "rig-3"               # lot, operator, socket likewise
    started_utc = "2025-03-01T08:00:00Z"
    [columns]
    t_s = "Time"                       # or { column = "Time", unit = "ms" }
    temperature_c = { column = "Case T", unit = "K" }
    [parameters]                       # what the analysis of the kind needs
    full_scale_dps = 500
"""

from __future__ import annotations

import csv
import datetime as _dt
import hashlib
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bench.core.store.model import LABELS
from bench.core.toml_file import read_toml

#: dimension -> unit -> (scale, offset) to the bench's unit (value·scale + offset)
UNITS: dict[str, dict[str, tuple[float, float]]] = {
    "time": {"s": (1.0, 0.0), "ms": (1e-3, 0.0), "min": (60.0, 0.0), "h": (3600.0, 0.0)},
    "temperature": {"degC": (1.0, 0.0), "°C": (1.0, 0.0), "C": (1.0, 0.0), "K": (1.0, -273.15),
                    "degF": (5.0 / 9.0, -32.0 * 5.0 / 9.0), "°F": (5.0 / 9.0, -32.0 * 5.0 / 9.0)},
    "angle": {"deg": (1.0, 0.0), "°": (1.0, 0.0), "rad": (180.0 / math.pi, 0.0)},
    "rate": {"deg/s": (1.0, 0.0), "°/s": (1.0, 0.0), "dps": (1.0, 0.0), "deg/h": (1.0 / 3600.0, 0.0),
             "°/h": (1.0 / 3600.0, 0.0), "rad/s": (180.0 / math.pi, 0.0)},
    "acceleration": {"g": (1.0, 0.0), "mg": (1e-3, 0.0), "ug": (1e-6, 0.0), "µg": (1e-6, 0.0),
                     "m/s^2": (1.0 / 9.80665, 0.0), "m/s2": (1.0 / 9.80665, 0.0)},
    "count": {"1": (1.0, 0.0)},
    "free": {},
}
BENCH_UNIT = {"time": "s", "temperature": "degC", "angle": "deg", "rate": "deg/s", "acceleration": "g", "count": "1"}
#: physical range of each dimension in the bench's unit: beyond it a value is a wrong unit or a fault
RANGES = {"temperature": (-100.0, 250.0), "angle": (-3600.0, 3600.0), "rate": (-1e5, 1e5),
          "time": (-1e9, 1e9), "count": (0.0, 1e9)}
SENSORS = ("gyro", "accelerometer")
#: how many rows a kind needs at least (the analyses ask for more; they say so themselves)
MIN_ROWS = {"static": 64, "startup": 64, "thermal": 64, "tumble": 4, "ratetable": 3, "turn-on": 128}


@dataclass(frozen=True)
class Column:
    """One column a kind of record has: the bench's name, its dimension, whether required."""

    name: str
    dimension: str
    what: str
    required: bool = True
    aliases: tuple[str, ...] = ()  # other bare names it is found by (case-insensitive), unit in brackets


@dataclass(frozen=True)
class Kind:
    """A kind of record: its columns, the procedure and stream a stored import is named by."""

    name: str
    columns: tuple[Column, ...]
    procedure: str
    what: str
    time: str | None = "t_s"  # the column that must increase (within a cycle for turn-on)
    group: str | None = None  # turn-on: the column time restarts with

    def column(self, name: str) -> Column:
        return next(c for c in self.columns if c.name == name)


_TIME = ("t", "time")
_TEMPS = ("temperature", "temp")
_T = Column("t_s", "time", "time", aliases=_TIME)
_OUT = Column("output", "free", "the sensor's output", aliases=("y",))
_TEMP = Column("temperature_c", "temperature", "the logged temperature", required=False, aliases=_TEMPS)
KINDS: dict[str, Kind] = {k.name: k for k in (
    Kind("static", (_T, _OUT, _TEMP), "static_record", "a static record (noise, drift, discovery)"),
    Kind("startup", (Column("t_s", "time", "time from power-on", aliases=_TIME), _OUT, _TEMP), "startup_record",
         "a start-up record from power-on (Document A's model)"),
    Kind("thermal", (_T, _OUT, Column("temperature_c", "temperature", "the logged temperature", aliases=_TEMPS),
                     Column("applied", "free", "the applied input (rate or g)", required=False)),
         "thermal_record", "a chamber record of soaks and ramps"),
    Kind("tumble", (Column("inner_deg", "angle", "inner-axis angle", aliases=("inner",)),
                    Column("outer_deg", "angle", "outer-axis angle", aliases=("outer",)),
                    _OUT, Column("output_se", "free", "standard error of the output", required=False)),
         "tumble_record", "an accelerometer's multi-position table (IEEE 1293)", time=None),
    Kind("ratetable", (Column("input_rate_dps", "rate", "input rate, Earth rate included",
                              aliases=("input_rate", "rate")), _OUT,
                       Column("output_se", "free", "standard error of the output", required=False)),
         "ratetable_record", "a gyro's rate-table sequence (IEEE 952/647)", time=None),
    Kind("turn-on", (Column("cycle", "count", "power cycle"),
                     Column("t_s", "time", "time from the cycle's power-on", aliases=_TIME),
                     _OUT, Column("day", "count", "day of the cycle", required=False)),
         "turn_on_record", "start-up records of several power cycles", group="cycle"),
)}

_BRACKET = re.compile(r"^\s*(.*?)\s*[\[(]\s*([^\])]+?)\s*[\])]\s*$")


class RecordError(ValueError):
    """A record file that does not follow the convention: the message names file, column, row."""


@dataclass(frozen=True)
class Meta:
    """What a record is: its kind, the unit and station, and how its columns are named."""

    kind: str
    sensor: str | None = None
    unit_serial: str | None = None
    model: str | None = None
    output_unit: str = "1"
    started_utc: str | None = None
    labels: dict[str, str] = field(default_factory=dict)
    columns: dict[str, tuple[str, str | None]] = field(default_factory=dict)  # bench name -> (file column, unit)
    parameters: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Record:
    """A record read and checked: the bench's columns in the bench's units, and where from."""

    kind: Kind
    meta: Meta
    data: dict[str, np.ndarray]
    units: dict[str, str]
    source: str
    sha256: str
    conversions: dict[str, str]  # bench column -> "file column [unit]" it came from

    @property
    def n_rows(self) -> int:
        return len(next(iter(self.data.values())))


def parse_column_option(text: str) -> tuple[str, tuple[str, str | None]]:
    """``NAME=COLUMN[:UNIT]`` (``--col``) as (bench name, (file column, unit or None))."""
    name, sep, rest = text.partition("=")
    if not sep or not name.strip() or not rest.strip():
        raise RecordError(f"--col {text!r}: give NAME=COLUMN or NAME=COLUMN:UNIT (e.g. t_s=Time:ms)")
    column, _, unit = rest.rpartition(":") if ":" in rest else (rest, "", "")
    return name.strip(), (column.strip(), unit.strip() or None)


def read_meta(path: str | os.PathLike[str] | None, *, kind: str | None = None,
              overrides: dict[str, Any] | None = None) -> Meta:
    """The metadata of a record: the TOML file at ``path`` (if any) with ``overrides`` (the
    command line's fields, None ones ignored) on top; RecordError naming a bad field."""
    doc: dict[str, Any] = dict(read_toml(Path(path), "metadata file", RecordError)) if path else {}
    where = f"metadata file {os.fspath(path)!r}" if path else "metadata"
    for key, value in (overrides or {}).items():
        if value is not None and value != {}:
            doc[key] = {**doc.get(key, {}), **value} if isinstance(value, dict) else value
    if kind is not None:
        if doc.get("kind") not in (None, kind):
            raise RecordError(f"{where}: kind = {doc['kind']!r}, but this is `{kind}`: the file describes "
                              f"a {doc['kind']} record")
        doc["kind"] = kind
    known = {"kind", "sensor", "unit_serial", "model", "output_unit", "started_utc", "columns",
             "parameters", *LABELS}
    unknown = sorted(set(doc) - known)
    if unknown:
        raise RecordError(f"{where}: unknown field(s) {unknown}; allowed: {', '.join(sorted(known))}")
    k = doc.get("kind")
    if k is None:
        raise RecordError(f"{where}: no kind given; give one of {', '.join(KINDS)} (--kind or kind = …)")
    if k not in KINDS:
        raise RecordError(f"{where}: kind {k!r}; give one of {', '.join(KINDS)} (--kind or kind = …)")
    sensor = doc.get("sensor")
    if sensor is not None and sensor not in SENSORS:
        raise RecordError(f"{where}: sensor {sensor!r}; allowed: {', '.join(SENSORS)}")
    for key in ("unit_serial", "model", "output_unit", "started_utc", *LABELS):
        value = doc.get(key)
        if value is not None and (not isinstance(value, str) or not value.strip() or len(value) > 128
                                  or not value.isprintable()):
            raise RecordError(f"{where}: {key} = {value!r} must be printable text of 1..128 characters")
    started = doc.get("started_utc")
    if started is not None:
        try:
            _dt.datetime.fromisoformat(started.replace("Z", "+00:00"))
        except ValueError:
            raise RecordError(f"{where}: started_utc = {started!r} is not an ISO 8601 time "
                              "(e.g. 2025-03-01T08:00:00Z)") from None
    columns: dict[str, tuple[str, str | None]] = {}
    raw_columns = doc.get("columns", {})
    if not isinstance(raw_columns, dict):
        raise RecordError(f"{where}: [columns] must be a table of NAME = \"COLUMN\" or {{column, unit}}")
    names = [c.name for c in KINDS[k].columns]
    for name, value in raw_columns.items():
        if name not in names:
            raise RecordError(f"{where}: {name!r} is not a column of a {k} record; its columns: {', '.join(names)}")
        if isinstance(value, str):
            columns[name] = (value, None)
        elif isinstance(value, dict) and isinstance(value.get("column"), str) and set(value) <= {"column", "unit"}:
            columns[name] = (value["column"], value.get("unit"))
        elif isinstance(value, tuple) and len(value) == 2:
            columns[name] = value
        else:
            raise RecordError(f"{where}: columns.{name} = {value!r}; "
                              "give \"COLUMN\" or { column = \"…\", unit = \"…\" }")
    parameters = doc.get("parameters", {})
    if not isinstance(parameters, dict):
        raise RecordError(f"{where}: [parameters] must be a table")
    return Meta(kind=k, sensor=sensor, unit_serial=doc.get("unit_serial"), model=doc.get("model"),
                output_unit=doc.get("output_unit") or "1", started_utc=started,
                labels={key: doc[key] for key in LABELS if doc.get(key)}, columns=columns,
                parameters=dict(parameters))


def _split_header(name: str) -> tuple[str, str | None]:
    m = _BRACKET.match(name)
    return (m.group(1), m.group(2)) if m else (name.strip(), None)


def _implied_unit(column: Column) -> str | None:
    """The unit a bench column name implies (``t_s`` → s, ``inner_deg`` → deg), else None."""
    if column.dimension in BENCH_UNIT:
        return BENCH_UNIT[column.dimension]
    return None


def _read_table(path: Path) -> tuple[list[str], list[np.ndarray], list[int]]:
    """Header, columns as float arrays, and the file line of each row (CSV) or its index."""
    if path.suffix.lower() in (".h5", ".hdf5"):
        import h5py  # noqa: PLC0415 — lazy: h5py (~80 ms) only for HDF5 records

        with h5py.File(path, "r") as f:
            names = [n for n, d in f.items() if isinstance(d, h5py.Dataset) and d.ndim == 1]
            if not names:
                raise RecordError(f"{path}: no 1-D datasets at the file's root (one per column)")
            header, cols = [], []
            for n in names:
                unit = f[n].attrs.get("unit", f[n].attrs.get("units"))
                unit = unit.decode() if isinstance(unit, bytes) else unit
                header.append(f"{n} [{unit}]" if unit else n)
                try:
                    cols.append(np.asarray(f[n][()], dtype=float))
                except (TypeError, ValueError):
                    raise RecordError(f"{path}: dataset {n!r} is not numeric") from None
            lengths = {len(c) for c in cols}
            if len(lengths) != 1:
                raise RecordError(f"{path}: datasets have different lengths "
                                  f"{dict(zip(names, (len(c) for c in cols)))}")
            return header, cols, list(range(len(cols[0])))
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise RecordError(f"cannot read record {os.fspath(path)!r}: {reason}") from None
    lines = text.splitlines()
    if not lines or not lines[0].strip():
        raise RecordError(f"{path}: empty, or no header row on line 1")
    dialect = csv.Sniffer().sniff(lines[0], delimiters=",;\t") if any(d in lines[0] for d in ",;\t") else csv.excel
    reader = csv.reader(lines, dialect)
    header = [h.strip() for h in next(reader)]
    rows, line_numbers = [], []
    for line_no, row in enumerate(reader, start=2):
        if not row or all(not x.strip() for x in row):
            continue
        if len(row) != len(header):
            raise RecordError(f"{path}: line {line_no} has {len(row)} fields, the header {len(header)}")
        rows.append(row)
        line_numbers.append(line_no)
    cols = []
    for j, name in enumerate(header):
        values = np.empty(len(rows))
        for i, row in enumerate(rows):
            try:
                values[i] = float(row[j])
            except ValueError:
                raise RecordError(f"{path}: column {name!r}, line {line_numbers[i]}: {row[j]!r} "
                                  "is not a number") from None
        cols.append(values)
    return header, cols, line_numbers


def _row(path: Path, lines: list[int], i: int) -> str:
    return f"line {lines[i]}" if path.suffix.lower() not in (".h5", ".hdf5") else f"row {i}"


def read_record(path: str | os.PathLike[str], meta: Meta) -> Record:
    """Read and check the record at ``path`` (CSV with a header row, or HDF5 with one 1-D
    dataset per column) as a record of ``meta.kind``; RecordError naming what is wrong."""
    path = Path(path)
    if not path.is_file():
        raise RecordError(f"record {os.fspath(path)!r} not found")
    kind = KINDS[meta.kind]
    header, cols, lines = _read_table(path)
    by_bare: dict[str, list[int]] = {}  # bench names match whatever their case
    for j, h in enumerate(header):
        by_bare.setdefault(_split_header(h)[0].lower(), []).append(j)
    by_alias: dict[str, list[int]] = {}
    for j, h in enumerate(header):
        bare, unit_given = _split_header(h)
        if unit_given is not None:  # an alias needs its unit said: "Time [ms]", not "Time"
            by_alias.setdefault(bare.lower(), []).append(j)
    data: dict[str, np.ndarray] = {}
    units: dict[str, str] = {}
    conversions: dict[str, str] = {}
    for column in kind.columns:
        if column.name in meta.columns:
            file_name, unit = meta.columns[column.name]
            matches = [j for j, h in enumerate(header) if h == file_name] or by_bare.get(file_name.lower(), [])
            if not matches:
                raise RecordError(f"{path}: column {file_name!r} (given for {column.name}) is not in the "
                                  f"header {header}")
        else:
            file_name, unit = column.name, None
            matches = by_bare.get(column.name.lower(), [])
            for alias in column.aliases:
                if not matches and by_alias.get(alias):
                    file_name, matches = alias, by_alias[alias]
            if not matches:
                if column.required:
                    raise RecordError(
                        f"{path}: no column {column.name!r} ({column.what}) in the header {header}; name it so, "
                        f"or map one with --col {column.name}=COLUMN[:UNIT]")
                continue
        if len(matches) > 1:
            raise RecordError(f"{path}: {len(matches)} columns named {file_name!r} in the header")
        j = matches[0]
        unit = unit or _split_header(header[j])[1] or _implied_unit(column)
        values = cols[j]
        if column.dimension == "free":
            unit = unit or meta.output_unit
        else:
            table = UNITS[column.dimension]
            if unit not in table:
                raise RecordError(
                    f"{path}: column {header[j]!r} ({column.name}, a {column.dimension}) in {unit!r}; "
                    f"allowed units: {', '.join(table)}")
            scale, offset = table[unit]
            values = values * scale + offset
            unit = BENCH_UNIT[column.dimension]
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            raise RecordError(f"{path}: column {header[j]!r}, {_row(path, lines, int(bad[0]))}: "
                              f"{cols[j][bad[0]]} is not a finite number ({bad.size} such rows)")
        if column.dimension in RANGES:
            lo, hi = RANGES[column.dimension]
            out = np.flatnonzero((values < lo) | (values > hi))
            if out.size:
                raise RecordError(
                    f"{path}: column {header[j]!r}, {_row(path, lines, int(out[0]))}: {values[out[0]]:.6g} "
                    f"{BENCH_UNIT[column.dimension]} outside [{lo:g}, {hi:g}] (a wrong unit?)")
        if column.dimension == "count" and np.any(values != np.round(values)):
            i = int(np.flatnonzero(values != np.round(values))[0])
            raise RecordError(f"{path}: column {header[j]!r}, {_row(path, lines, i)}: {values[i]} is not an integer")
        data[column.name] = values
        units[column.name] = unit
        conversions[column.name] = header[j]
    n = len(lines)
    if n < MIN_ROWS[kind.name]:
        raise RecordError(f"{path}: {n} rows; a {kind.name} record needs at least {MIN_ROWS[kind.name]}")
    if kind.time is not None:
        _check_time(path, lines, data, kind, conversions)
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    return Record(kind, meta, data, units, os.fspath(path), digest, conversions)


def _check_time(path: Path, lines: list[int], data: dict[str, np.ndarray], kind: Kind,
                conversions: dict[str, str]) -> None:
    t = data["t_s"]
    same = np.ones(t.size - 1, dtype=bool) if kind.group is None else data[kind.group][1:] == data[kind.group][:-1]
    back = np.flatnonzero(same & (np.diff(t) <= 0))
    if back.size:
        i = int(back[0]) + 1
        raise RecordError(f"{path}: column {conversions['t_s']!r}, {_row(path, lines, i)}: time {t[i]:.9g} s does "
                          f"not increase (previous {t[i - 1]:.9g} s)" +
                          (f" within {kind.group} {data[kind.group][i]:g}" if kind.group else ""))
    if kind.group is not None:
        g = data[kind.group]
        if np.any(np.diff(g) < 0):
            i = int(np.flatnonzero(np.diff(g) < 0)[0]) + 1
            raise RecordError(f"{path}: column {conversions[kind.group]!r}, {_row(path, lines, i)}: {kind.group} "
                              f"{g[i]:g} after {g[i - 1]:g}; give the cycles in order")
    if kind.name in ("startup", "turn-on") and t.min() < 0:
        i = int(np.argmin(t))
        raise RecordError(f"{path}: column {conversions['t_s']!r}, {_row(path, lines, i)}: {t[i]:g} s; time "
                          "counts from power-on (≥ 0)")


#: what a sensor's output is measured in, as discover reads it: the dimension and the bench's unit
SENSOR_OUTPUT = {"gyro": "rate", "accelerometer": "acceleration"}


def to_sensor_unit(values: np.ndarray, unit: str | None, sensor: str) -> np.ndarray:
    """A stored output in ``unit`` converted to the sensor's bench unit (deg/s, g); ValueError
    naming the unit when it is not one of the sensor's."""
    table = UNITS[SENSOR_OUTPUT[sensor]]
    if unit not in table:
        raise ValueError(f"the output is in {unit!r}, not a {SENSOR_OUTPUT[sensor]} a {sensor} gives; "
                         f"import it with --output-unit one of {', '.join(table)}")
    scale, offset = table[unit]
    return np.asarray(values, float) * scale + offset


def parameter(record: Record, name: str, default: Any, lo: float | None = None, hi: float | None = None,
              given: Any = None) -> Any:
    """A kind's parameter: the command line's ``given``, else the metadata's, else ``default``;
    RecordError when outside [lo, hi]."""
    value = given if given is not None else record.meta.parameters.get(name, default)
    if value is None:
        return None
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise RecordError(f"parameter {name} = {value!r} is not a number") from None
    if not math.isfinite(x) or (lo is not None and x < lo) or (hi is not None and x > hi):
        span = f"[{'-inf' if lo is None else f'{lo:g}'}, {'inf' if hi is None else f'{hi:g}'}]"
        raise RecordError(f"parameter {name} = {value!r} outside {span}")
    return x
