"""``bench discover``: find where the model and a measurement disagree, name the missing effect.

``bench discover (--run ID | --measured FILE.csv) [--sensor accelerometer|gyro|mhd]
[--model FILE.toml] [--out DIR] [--json]``

CSV columns (header row): ``t`` (s) and ``y`` (g or deg/s) required; optional ``input``,
``cross_input``, ``temp`` (degC), ``t_on`` (s since power-on), ``vib`` (g rms), ``accel`` (g)
— see :mod:`bench.discovery.data`.

Stored runs: the streams :mod:`bench.app.commands.discover_runs` maps (start-up, static noise
and vibration records of both sensors; ``--stream`` picks one when a run holds several).

Writes ``discovered_model.toml`` and ``discovery_report.html`` into ``--out`` (default
``bench-data/discover``). Bad input: one line ``bench: error: …`` and exit 2 (ValueError /
LookupError / OSError are turned into that by :mod:`bench.app.cli`).
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import json
import multiprocessing
import os
import sys
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.markup import escape

from bench.app.blas import blas_threads, set_blas_threads
from bench.app.commands.analyze import read_csv_table
from bench.app.commands.common import require_store, resolve_run_id
from bench.app.commands.discover_runs import read_run
from bench.app.files import read_model, write_model
from bench.app.reports.discovery_report import write_discovery_report
from bench.app.verdict import record_digest
from bench.core.store import RunStore
from bench.discovery.data import CSV_COLUMNS, Record
from bench.discovery.effects import CATALOGUE
from bench.discovery.model import Model, base_model
from bench.discovery.workflow import discover

SENSORS = ("accelerometer", "gyro", "mhd")
DEFAULT_OUT = "bench-data/discover"


def configure(p: argparse.ArgumentParser) -> None:
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--run", metavar="ID",
                     help="stored run id or 'latest' (start-up, noise, vibration and thermal-ramp runs)")
    src.add_argument("--measured", metavar="FILE.csv",
                     help=f"CSV with a header row; columns {', '.join(CSV_COLUMNS)} (t, y required)")
    p.add_argument("--stream", metavar="NAME", default=None,
                   help="which stream of the run (default: the first mappable; see discover_runs)")
    p.add_argument("--sensor", choices=SENSORS, default=None,
                   help="base model kind when no --model (default: from the run, else accelerometer)")
    p.add_argument("--model", metavar="FILE.toml", default=None, help="starting model file")
    p.add_argument("--out", metavar="DIR", default=DEFAULT_OUT, help=f"output folder [{DEFAULT_OUT}]")
    p.add_argument("--max-effects", type=int, default=4, help="most effects to add [4]")
    p.add_argument("--alpha", type=float, default=0.05,
                   help="false-name rate: the chance of naming an effect on a record that holds none, and of "
                        "doubting a random process that is what it is named [0.05]")
    p.add_argument("--seed", type=int, default=0, help="seed of the model-noise realisations of the gap table [0]")
    p.add_argument("--jobs", type=int, default=default_jobs(),
                   help=f"worker processes fitting the add moves side by side (same answer) [{default_jobs()}]")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.add_argument("--no-progress", action="store_true", help="no progress line on stderr")
    p.set_defaults(func=discover_command)


def read_measured(path: str) -> Record:
    """A CSV with a header into a Record (ValueError naming the file and the fault). Header
    names are matched case-insensitively after stripping blanks; a repeated or unknown name
    is refused."""
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            raw = next(csv.reader(fh), [])
    except (UnicodeDecodeError, csv.Error) as exc:
        raise ValueError(f"cannot read {path}: {exc}") from None
    header = [h.strip().lower() for h in raw]
    unknown = [h for h, r in zip(header, raw) if h and h not in CSV_COLUMNS]
    if unknown:
        raise ValueError(f"{path}: unknown column(s) {unknown}; allowed: {list(CSV_COLUMNS)}")
    repeated = sorted({h for h in header if h and header.count(h) > 1})
    if repeated:
        raise ValueError(f"{path}: column(s) {repeated} appear more than once in the header")
    original = {h: r.strip() for h, r in zip(header, raw) if h}
    for name in ("t", "y"):
        if name not in original:
            raise ValueError(f"{path}: no column {name!r}; columns are {', '.join(original.values()) or '(none)'}")
    optional = tuple(original[c] for c in CSV_COLUMNS if c not in ("t", "y") and c in original)
    table = read_csv_table(path, (original["t"], original["y"]), optional)
    lower = {v: k for k, v in original.items()}
    try:
        return Record.from_columns({lower[k]: v for k, v in table.items()})
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None


def discover_command(args) -> int:
    if args.run is not None:
        run_id, source = run_context(args.store, args.run)
        rec, run_kind, label = read_run(args.store, run_id, args.stream)
    else:
        if args.stream is not None:
            raise ValueError("--stream applies to --run only")
        rec, run_kind, label = read_measured(args.measured), None, args.measured
        source = {"input": args.measured}
    if args.model is not None:
        model = read_model(args.model, rate_hz=rec.rate_hz)  # noise_sd carried to this record's rate
        if args.sensor is not None and args.sensor != model.base.kind:
            raise ValueError(f"--sensor {args.sensor} contradicts the model file's kind {model.base.kind!r}")
    else:
        model = Model(base_model(args.sensor or run_kind or "accelerometer"))
    if not 0 <= args.max_effects <= len(CATALOGUE):
        raise ValueError(f"--max-effects {args.max_effects}; allowed: 0..{len(CATALOGUE)} (the catalogue's size)")
    if rec.n < 64:
        raise ValueError(f"{label}: {rec.n} samples; discover needs at least 64")
    if not rec.is_uniform(rtol=0.05):
        raise ValueError(f"{label}: sample intervals vary by more than 5 %; discover needs a uniform record")
    if not 0 < args.alpha < 1:
        raise ValueError(f"--alpha {args.alpha}; allowed: a rate in (0, 1)")
    with status_line(not args.no_progress, plain=args.json) as say, candidate_map(args.jobs) as map_fn:
        say(f"{label}: {rec.n} samples at {rec.rate_hz:.6g} Hz; calibrating the {model.base.kind} model")
        result = discover(rec, model, max_effects=args.max_effects, alpha=args.alpha, seed=args.seed,
                          progress=say, map_fn=map_fn)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    model_file = out / "discovered_model.toml"
    write_model(result.final_model, model_file, rate_hz=rec.rate_hz)
    context = {**source, "sensor model": model.base.kind, "starting model": args.model or "the built-in base model",
               "false-name rate α": args.alpha, "most effects": args.max_effects, "gap-table seed": args.seed}
    report = write_discovery_report(result, rec, out, label, context)
    doc = result.to_dict(str(model_file))
    doc["report"] = str(report)
    doc["source"] = label
    if args.json:
        print(json.dumps(clean_json(doc), indent=2, allow_nan=False))
    else:
        print(summary(result, label, model_file, report))
    return 0


def run_context(store_path, run_id: str) -> tuple[str, dict]:
    """The run ``run_id`` names ('latest' resolved) and what the report's header says of it (its
    digest goes to the report's foot)."""
    require_store(store_path)
    with RunStore(store_path) as store:
        run_id = resolve_run_id(store, run_id)
        info = store.get_run(run_id)
        labels = info.labels or {}
        return run_id, {"run": run_id, "unit": info.unit_serial, "procedure": info.procedure,
                        "station": labels.get("station_id") or (info.station or {}).get("name"),
                        "operator": labels.get("operator"), "started (UTC)": info.started_utc,
                        "run's seed": info.seed, "digest": record_digest(store, run_id)}


def default_jobs() -> int:
    """Worker processes for the candidates' fits: one per core this process may run on."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def check_jobs(jobs: int) -> None:
    """``--jobs``: an integer >= 1 (ValueError naming the value otherwise)."""
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise ValueError(f"--jobs {jobs!r}; allowed: an integer >= 1")


@contextlib.contextmanager
def candidate_map(jobs: int) -> Iterator:
    """The ``map`` each round of the search fits its add moves with (``workflow.discover``'s
    ``map_fn``): the builtin one for ``jobs`` = 1, else that of ``jobs`` worker processes,
    forked from a server that has imported the discovery library (never from this process,
    whose status line runs a thread). The fits draw no random numbers: the same answer.
    BLAS runs one thread a process, here and in the workers (:mod:`bench.app.blas`: on these
    tall, narrow matrices a second thread doubled the CPU time and saved no wall time), so
    every ``jobs`` computes with the same BLAS and gives the same numbers."""
    check_jobs(jobs)
    with blas_threads(1):
        if jobs == 1:
            yield map
            return
        context = multiprocessing.get_context("forkserver")
        context.set_forkserver_preload(["bench.discovery.search"])
        with ProcessPoolExecutor(max_workers=jobs, mp_context=context, initializer=set_blas_threads,
                                 initargs=(1,)) as pool:
            for _ in range(jobs):  # start the server and the workers now, while this process calibrates
                pool.submit(int)
            yield pool.map


@contextlib.contextmanager
def status_line(enabled: bool, plain: bool = False):
    """A spinner with the search's current step on stderr (rich); each finished step's message
    stays printed. ``plain`` (``--json``: stdout is the document): one line per message on
    stderr instead, no spinner. Yields ``say(message)``."""
    if not enabled:
        yield lambda _msg: None
        return
    if plain:
        def say_plain(msg: str) -> None:
            print(f"discover: {msg}", file=sys.stderr, flush=True)

        yield say_plain
        return
    console = Console(file=sys.stderr)
    with console.status("discover: starting") as status:
        def say(msg: str) -> None:
            if msg.startswith(("named ", "done", "unexplained")) or "outliers" in msg:
                console.print(escape(msg))
            status.update(escape(f"discover — {msg}"))

        yield say


def clean_json(x):
    """numpy scalars to Python, NaN/inf to None, recursively (JSON without NaN)."""
    if isinstance(x, dict):
        return {str(k): clean_json(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [clean_json(v) for v in x]
    if isinstance(x, (np.floating, float)):
        return float(x) if np.isfinite(x) else None
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def summary(result, label: str, model_file: Path, report: Path) -> str:
    lines = [f"discrepancy workflow on {label}: residual rms {result.rms_initial:.4g} → {result.rms_final:.4g} "
             f"(noise floor {result.noise_floor:.4g})"]
    if not result.steps:
        lines.append("nothing named: no catalogue effect lowers the criterion")
    elif not result.named:
        lines.append("nothing named: what lowers the criterion is not the process it looks like (below)")
    for i, s in enumerate(result.steps, 1):
        ps = ", ".join(f"{k} = {v:.4g} ± {s.params_std.get(k, float('nan')):.2g}" for k, v in s.params.items())
        pv = "p < 1e-300" if s.p_value < 1e-300 else f"p = {s.p_value:.3g}"  # below a double's range: a bound
        seen_on = f" [{s.scale}]" if s.scale else ""  # a long record: block means or the full-rate window
        doubted = " — in the model for its spectrum, not named (doubted: see unexplained structure)" if s.doubt else ""
        lines.append(f"{i}. {s.effect_id}{seen_on} ({ps}); {pv}; rms {s.rms_before:.4g} → {s.rms_after:.4g}"
                     f"{doubted}")
        for sep in s.naming.separating:
            lines.append(f"   look-alike within the criterion's noise — {sep}")
    for u in result.unexplained:
        lines.append(f"unexplained structure: {u}")
    lines += [f"note: {n}" for n in result.notes]
    lines += [f"model: {model_file}", f"report: {report}"]
    return "\n".join(lines)
