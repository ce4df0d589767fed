"""``bench runs list | show ID | export ID --format csv|hdf5 | attachment ID NAME | import FILE``, on the station's
store or on the central store (``--store postgresql://…``: every station's runs, named by UUID).

``import`` stores a bench export exactly as it was exported, or a record made elsewhere (CSV or
HDF5 following ``bench.app.records``' convention) as a run of its kind, analysed as the
station's step would analyse it (``bench.app.importing``)."""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import asdict
from pathlib import Path
from typing import Any

from bench.app.commands.common import open_reader, open_store, resolve_run_id
from bench.app.commands.record_options import OPTIONS, add_kind_option, add_record_options, meta_of, options_of
from bench.app.export import export_csv, export_hdf5
from bench.app.records import KINDS, read_record
from bench.app.verdict import measurements_of, record_digest, verdict_of
from bench.app.wording import bound_text
from bench.core.store.reader import is_central_url

#: where ``bench runs export`` writes unless told (beside the default store)
EXPORTS = "bench-data/exports"


def configure(runs: argparse.ArgumentParser) -> None:
    cmds = runs.add_subparsers(dest="runs_command", metavar="SUBCOMMAND")
    cmds.required = True
    ls = cmds.add_parser("list", help="stored runs, newest first")
    ls.add_argument("--limit", type=int, default=20)
    ls.add_argument("--json", action="store_true")
    ls.set_defaults(func=list_runs)
    show = cmds.add_parser("show", help="one run: metadata, streams, events, measurements")
    show.add_argument("run_id", help="run id, or 'latest'")
    show.add_argument("--json", action="store_true")
    show.set_defaults(func=show_run)
    exp = cmds.add_parser("export", help="export a run's data")
    exp.add_argument("run_id")
    exp.add_argument("--format", choices=("csv", "hdf5"), default="csv")
    exp.add_argument("--out", default=None,
                     help=f"output folder (csv) or file (hdf5) [{EXPORTS}/ID/ or {EXPORTS}/ID.h5]")
    exp.set_defaults(func=export_run)
    att = cmds.add_parser("attachment", help="write one of a run's attachments (a report, a compensation file) "
                          "to a file")
    att.add_argument("run_id", metavar="ID", help="run id, or 'latest'")
    att.add_argument("name", nargs="?", default=None, metavar="NAME",
                     help="the attachment (as `bench runs show` lists it); none: list them")
    att.add_argument("--out", default=None, metavar="FILE",
                     help="where to write it [the attachment's file name in the current folder]; - for stdout")
    att.set_defaults(func=attachment_of_run)
    imp = cmds.add_parser("import", help="store a record made elsewhere (CSV, HDF5) or a bench export as a run")
    imp.add_argument("file", metavar="FILE", help="a record (CSV with a header row, HDF5) or a bench export "
                     "(its .json sidecar or .h5 file)")
    imp.add_argument("--kind", choices=tuple(KINDS), default=None,
                     help="what the record is (or the metadata's kind); not needed for a bench export")
    add_record_options(imp)
    for kind, options in OPTIONS.items():
        for flag, dest, typ, text in options:
            add_kind_option(imp, flag, dest, typ, f"{kind}: {text}")
    imp.add_argument("--no-analysis", action="store_true",
                     help="store the record only (by default a tumble, rate-table, turn-on or thermal record is "
                     "also analysed and its measurements stored with it)")
    imp.add_argument("--json", action="store_true")
    imp.set_defaults(func=import_run)


def list_runs(args) -> int:
    if args.limit < 1:
        raise ValueError(f"--limit {args.limit} must be ≥ 1")
    central = is_central_url(args.store)
    runs = open_reader(args).list_runs(limit=args.limit)  # a store that is not there is named
    if args.json:
        json.dump([_info(r) for r in runs], sys.stdout, indent=2, default=str)
        print()
        return 0
    if not runs:
        print("no runs stored yet (try: bench run startup)")
        return 0
    width = 36 if central else 22  # the central store names runs by UUID
    pw = max([11] + [len(r.procedure) for r in runs])
    print(f"{'id':<{width}} {'procedure':<{pw}} {'unit':<14} {'status':<9} {'started (UTC)':<20} "
          + ("station  " if central else "") + "reason")
    for r in runs:
        print(f"{r.id:<{width}} {r.procedure:<{pw}} {str(r.unit_serial or '-'):<14} {r.status:<9} "
              f"{str(r.started_utc)[:19]:<20} "
              + (f"{r.labels.get('station_id', '-')}  " if central else "") + f"{r.reason or ''}")
    return 0


def _info(r) -> dict:
    d = asdict(r)
    return d


def show_run(args) -> int:
    store = open_reader(args)
    args.run_id = resolve_run_id(store, args.run_id)
    info = store.get_run(args.run_id)
    streams = store.streams(args.run_id)
    events = store.events(args.run_id)
    measurements = measurements_of(info.results or {})
    verdict = None
    if info.procedure == "acceptance" and info.status != "running":
        verdict = verdict_of(info.status, measurements)
    if args.json:
        doc = _info(info)
        doc["verdict"] = verdict
        doc["measurements"] = measurements
        doc["streams"] = {k: asdict(v) if hasattr(v, "__dataclass_fields__") else v
                          for k, v in streams.items()}
        doc["events"] = events  # (t_s, kind, message, data) each
        doc["attachments"] = [asdict(a) if hasattr(a, "__dataclass_fields__") else a
                              for a in store.attachments(args.run_id)]
        doc["digest"] = record_digest(store, args.run_id)
        json.dump(doc, sys.stdout, indent=2, default=str)
        print()
        return 0
    print(f"run        {info.id}\nuuid       {info.uuid}\nprocedure  {info.procedure}\n"
          f"unit       {info.unit_serial}\n"
          + "".join(f"{k:<11}{v}\n" for k, v in info.labels.items()) +
          f"status     {info.status}" + (f" — {info.reason}" if info.reason else "") +
          (f"\nverdict    {verdict}" if verdict else "") +
          f"\nstarted    {info.started_utc}\nended      {info.ended_utc}\nseed       {info.seed}\n"
          f"code       {info.code_version}\nlast good sample at t = {info.last_sample_t_s} s\n"
          f"digest     {record_digest(store, args.run_id)}")
    print("streams:")
    for name, s in streams.items():
        print(f"  {name:<14} {getattr(s, 'n_rows', '?'):>10} rows  "
              f"{', '.join(f'{c} [{u}]' for c, u in getattr(s, 'columns', {}).items())}")
    if measurements:
        print(f"measurements:\n  {'name':<22} {'value':>14} {'± unc.':>9} {'unit':<9} {'low':>10} "
              f"{'high':>10}  outcome")
        for m in measurements:
            unc = "" if m.get("uncertainty") is None else f"{m['uncertainty']:.2g}"
            low = "" if m.get("low") is None else f"{m['low']:g}"
            high = "" if m.get("high") is None else f"{m['high']:g}"
            value = "—" if m["value"] is None else f"{bound_text(m)}{m['value']:.6g}"
            print(f"  {m['name']:<22} {value:>14} {unc:>9} {m['unit']:<9} {low:>10} "
                  f"{high:>10}  {m['outcome']}")
    attachments = store.attachments(args.run_id)
    if attachments:
        print("attachments:")
        for a in attachments:
            print(f"  {a.name:<40} {a.mime:<18} {a.size_bytes:>9} bytes")
    print(f"events: {len(events)}")
    for e in events[:20]:
        print(f"  t={e.t_s:>10.3f} s  {e.kind:<14} {e.message}")
    return 0


def export_run(args) -> int:
    store = open_reader(args)
    args.run_id = resolve_run_id(store, args.run_id)
    if args.format == "csv":
        paths = export_csv(store, args.run_id, Path(args.out or f"{EXPORTS}/{args.run_id}"))
    else:
        paths = [export_hdf5(store, args.run_id, Path(args.out or f"{EXPORTS}/{args.run_id}.h5"))]
    for p in paths:
        print(p)
    return 0


def attachment_of_run(args) -> int:
    """Handler of ``bench runs attachment ID [NAME]``."""
    store = open_reader(args)
    args.run_id = resolve_run_id(store, args.run_id)
    if args.name is None:
        attachments = store.attachments(args.run_id)
        if not attachments:
            print(f"run {args.run_id} has no attachments")
        for a in attachments:
            print(f"{a.name:<48} {a.mime:<24} {a.size_bytes:>9} bytes")
        return 0
    payload = store.attachment(args.run_id, args.name)  # LookupError naming the ones it has
    if args.out == "-":
        sys.stdout.buffer.write(payload)
        sys.stdout.flush()
        return 0
    out = Path(args.out or Path(args.name).name)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_bytes(payload)
    print(out)
    return 0


def import_run(args) -> int:
    """Handler of ``bench runs import FILE``."""
    # lazy: the analyses (scipy) only for an import; `bench runs list` imports this module
    from bench.app.commands.analyze_records import print_analysis  # noqa: PLC0415 — lazy, see above
    from bench.app.importing import bench_export, import_file  # noqa: PLC0415 — lazy, see above

    store = open_store(args)
    record = None
    if bench_export(args.file) is None:
        record = read_record(args.file, meta_of(args, args.kind))
        print(f"importing {record.n_rows} rows of {args.file} as a {record.kind.name} record",
              file=sys.stderr, flush=True)
    run_id, analysis = import_file(store, args.file, record, analyse=not args.no_analysis,
                                   options=options_of(args, record.kind.name) if record else None)
    info = store.get_run(run_id)
    if args.json:
        doc: dict[str, Any] = {"run_id": run_id, "uuid": info.uuid, "procedure": info.procedure,
                               "store": str(args.store)}
        if analysis is not None:
            doc["analysis"] = analysis.to_dict()
        json.dump(doc, sys.stdout, indent=2, default=str)
        print()
        return 0
    print(f"imported as run {run_id} ({info.procedure}, unit {info.unit_serial or '-'}) into {args.store}")
    if analysis is not None:
        print_analysis(analysis)
    print(f"bench runs show {run_id}")
    return 0
