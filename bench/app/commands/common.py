"""Helpers shared by CLI commands: the store, the unit and seed, progress display, and the one
ending of every command that runs something (:func:`conclude`: table or JSON, exit code, and
with ``BENCH_CENTRAL`` set the store's queue forwarded to the central store,
:func:`forward_after_run`).

Every command imports this module (``bench runs list`` too): what only one path needs (psycopg,
rich) is imported by that path."""

from __future__ import annotations

import contextlib
import json
import math
import os
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bench.app.labels import station_labels, world_seed
from bench.core.operator import Unattended
from bench.core.procedure import RunOutcome
from bench.core.store import RunStore
from bench.core.store.reader import RunReader, is_central_url, masked


def require_store(path) -> None:
    """Reading commands never create a store: a missing one is named (LookupError)."""
    if not Path(path).is_file():
        raise LookupError(f"no run store at {path} (run a procedure first, or --store PATH)")


def open_store(args, *, create: bool = True) -> RunStore:
    """The station's run store; reading commands pass ``create=False``.  A central store URL
    is refused here: runs are written locally and forwarded (``bench sync``)."""
    if is_central_url(args.store):
        raise ValueError(f"--store {masked(args.store)} is a central store: runs are written to "
                         "the station's SQLite store and forwarded by `bench sync`")
    if not create:
        require_store(args.store)
    return RunStore(args.store)


def open_reader(args) -> RunReader:
    """A store to read runs from: the station's SQLite file or the central store
    (``--store postgresql://…``)."""
    if is_central_url(args.store):
        # lazy: psycopg only when a central store URL is given
        from bench.core.store.central import CentralStore  # noqa: PLC0415 — lazy, see above

        return CentralStore(args.store)
    return open_store(args, create=False)


def resolve_run_id(store: RunReader, run_id: str) -> str:
    """``latest`` names the newest run; anything else must be a stored id."""
    if run_id == "latest":
        runs = store.list_runs(limit=1)
        if not runs:
            raise LookupError(f"no runs stored yet in {store.location}")
        return runs[0].id
    return store.get_run(run_id).id  # raises LookupError naming the id


def label_options(p) -> None:
    """The options naming where and what a run is in the factory (its labels)."""
    p.add_argument("--station-id", default=None, help="this station's name in the fleet "
                   "[$BENCH_STATION_ID, else host:station]")
    p.add_argument("--socket", default=None, help="test socket (fixture position) of the unit")
    p.add_argument("--lot", default=None, help="production lot of the unit")
    p.add_argument("--operator", dest="operator_name", default=None, metavar="NAME",
                   help="who runs the test (printed as 'tested by' on the report)")


def labels_of(args, config) -> dict[str, str]:
    """The run's labels from :func:`label_options` (station id always; socket, lot and operator if
    given)."""
    labels = station_labels(config.name, station_id=getattr(args, "station_id", None),
                            socket_name=getattr(args, "socket", None), lot=getattr(args, "lot", None))
    name = getattr(args, "operator_name", None)
    if name is not None:
        if not name.strip() or len(name) > 80 or not name.isprintable():
            raise ValueError(f"--operator {name!r} must be a printable name of 1 to 80 characters")
        labels["operator"] = name.strip()
    return labels


def seed_of(args, config) -> int | None:
    """``--seed``, else the station file's ``[simulation] seed`` (0 if it has none); None for
    a real station."""
    return world_seed(config.simulation, args.seed, name="--seed")


class TerminalOperator:
    """The operator at a console (``bench.core.operator.Operator``): a prompt on stderr, Enter
    continues, ``a`` aborts; end of input aborts (nobody can answer)."""

    name = "terminal"

    def ask(self, text: str) -> bool:
        print(f"\n>>> operator: {text}\n    Enter = continue, a = abort: ", end="", file=sys.stderr,
              flush=True)
        line = sys.stdin.readline()
        if not line:  # end of input: nobody can answer
            return False
        return line.strip().lower() not in ("a", "abort")


def operator_options(p) -> None:
    p.add_argument("--unattended", action="store_true",
                   help="answer every operator prompt of the spec Continue (scripts); without it "
                   "a console is asked, and a run with no console continues unattended")


def operator_of(args):
    """Who answers a run's prompts: the console when there is one and ``--unattended`` is not
    given, else nobody (every prompt continues; the record says unattended)."""
    if getattr(args, "unattended", False) or getattr(args, "json", False) or not sys.stdin.isatty():
        return Unattended()
    return TerminalOperator()


@contextlib.contextmanager
def progress_bar(enabled: bool):
    """A rich progress bar on stderr; yields a ``progress(done, total, message)`` callable.

    The bar appears at the first report of progress, so an error raised before the work
    starts (a bad seed, a station that does not open) is the only line on stderr."""
    if not enabled:
        yield lambda done, total, message="": None
        return
    # lazy: rich (~40 ms) only when a bar is drawn; reading commands (runs list) import this module
    from rich.console import Console  # noqa: PLC0415 — lazy, see above
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn  # noqa: PLC0415 — lazy: rich, as above

    bar = Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.percentage:>5.1f} %"),
                   TimeElapsedColumn(), console=Console(file=sys.stderr), transient=False)
    task = None

    def update(done: float, total: float, message: str = "") -> None:
        nonlocal task
        if task is None:
            bar.start()
            task = bar.add_task("starting", total=1.0)
        bar.update(task, completed=done, total=total, description=message or "working")

    try:
        yield update
    finally:
        if task is not None:
            bar.stop()


#: exit code of a finished run: 0 passed, 1 failed (a measurement outside its limits), 2 aborted
EXIT_CODES = {"passed": 0, "failed": 1}
#: what the bench attaches of a report folder
REPORT_MIME = {".html": "text/html", ".png": "image/png", ".json": "application/json"}


def attach_folder(store: RunStore, run_id: str, folder: Path, prefix: str) -> None:
    """Every report file of ``folder`` attached to the run as ``<prefix><file name>``."""
    for f in sorted(folder.iterdir()):
        if f.is_file() and f.suffix in REPORT_MIME:
            store.attach_analysis(run_id, prefix + f.name, f.read_bytes(), REPORT_MIME[f.suffix])


@dataclass
class FollowUpResult:
    """What an analysis after a run had to say: its part of the ``--json`` document (under
    ``key``), its lines of text, or the error that stopped it (``<key>_error``; exit 2)."""

    key: str
    document: Any = None
    lines: list[str] = field(default_factory=list)
    error: str | None = None


def outcome_lines(outcome: RunOutcome) -> list[str]:
    """A run's verdict and measurement table, as ``bench run`` prints them."""
    lines = [f"run {outcome.run_id}: {outcome.status.upper()}"
             + (f" — {outcome.reason}" if outcome.reason else "")]
    for m in outcome.measurements:
        lim = f"[{'' if m.limit.low is None else f'{m.limit.low:g}'} .. " \
              f"{'' if m.limit.high is None else f'{m.limit.high:g}'}]"
        unc = "" if m.uncertainty is None else f"± {m.uncertainty:.2g}"
        value = f"{m.value:.6g}" if math.isfinite(m.value) else "—"  # not produced
        lines.append(f"  {m.name:<22} {value:>14} {unc:<11} {m.unit:<9} {lim:<18} {m.outcome}")
    lines.append(f"stored in {outcome.store_path} (bench runs show {outcome.run_id})")
    return lines


def conclude(outcome: RunOutcome, *, as_json: bool, document: dict[str, Any] | None = None,
             table: list[str] | None = None, follow_ups: Sequence[FollowUpResult] = ()) -> int:
    """The one ending of every command that runs something: print the outcome — the table
    (``table``, default :func:`outcome_lines`) and each follow-up's lines, or the ``--json``
    document (``document``, default ``outcome.to_dict()``) with each follow-up's part under its
    key — then each follow-up's error on stderr; return the exit code: 0 passed, 1 failed,
    2 aborted or a follow-up failed (the run is stored whatever happened)."""
    doc = dict(outcome.to_dict() if document is None else document)
    errors = []
    for f in follow_ups:
        if f.error is not None:
            doc[f"{f.key}_error"] = f.error
            errors.append(f.error)
        elif f.document is not None:
            doc[f.key] = f.document
    if as_json:
        json.dump(doc, sys.stdout, indent=2, allow_nan=False, default=str)  # NaN → null in to_dict
        print()
    else:
        for line in (outcome_lines(outcome) if table is None else table):
            print(line)
        for f in follow_ups:
            for line in f.lines if f.error is None else ():
                print(line)
    for error in errors:
        print(f"bench: error: {error}", file=sys.stderr)
    forward_after_run(outcome.store_path)  # with $BENCH_CENTRAL: the queue goes to the central store
    return 2 if errors else EXIT_CODES.get(outcome.status, 2)


#: the environment variable naming the central store (``bench sync --central``'s default)
CENTRAL_ENV = "BENCH_CENTRAL"


def forward_after_run(store_path: str) -> None:
    """With ``BENCH_CENTRAL`` set: forward the queue of the store at ``store_path`` once (a
    server that cannot be reached leaves it queued); one line on stderr either way.  The
    run's outcome and exit code do not depend on it.  Every command that stores runs ends
    with it (:func:`conclude` does)."""
    url = os.environ.get(CENTRAL_ENV)
    if not url:
        return
    if not is_central_url(url):
        print(f"bench: warning: {CENTRAL_ENV}={url!r} is not a postgresql:// URL; runs stay "
              "queued", file=sys.stderr)
        return
    # lazy: psycopg only when $BENCH_CENTRAL names a central store
    from bench.core.store.forward import sync  # noqa: PLC0415 — lazy, see above

    try:
        with RunStore(store_path) as store:
            report = sync(store, url, connect_timeout_s=5.0)
    except Exception as exc:  # forwarding never turns a stored run into an error
        print(f"bench: warning: runs stay queued for the central store: {exc}", file=sys.stderr)
        return
    if report.complete:
        print(f"forwarded {len(report.stored)} run(s) to {report.central}", file=sys.stderr)
    else:
        print(f"bench: warning: {len(report.pending) + len(report.conflicts)} run(s) stay queued "
              f"for {report.central} ({report.error}); `bench sync` sends them", file=sys.stderr)
