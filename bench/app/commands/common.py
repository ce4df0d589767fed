"""Helpers shared by CLI commands: the store, progress display, printing outcomes."""

from __future__ import annotations

import contextlib
import math
import sys

from bench.core.store import RunStore


def require_store(path) -> None:
    """Reading commands never create a store: a missing one is named (LookupError)."""
    from pathlib import Path

    if not Path(path).is_file():
        raise LookupError(f"no run store at {path} (run a procedure first, or --store PATH)")


def open_store(args, *, create: bool = True) -> RunStore:
    """The run store; reading commands pass ``create=False``."""
    if not create:
        require_store(args.store)
    return RunStore(args.store)


def resolve_run_id(store: RunStore, run_id: str) -> str:
    """``latest`` names the newest run; anything else must be a stored id."""
    if run_id == "latest":
        runs = store.list_runs(limit=1)
        if not runs:
            raise LookupError(f"no runs stored yet in {store.path}")
        return runs[0].id
    store.get_run(run_id)  # raises LookupError naming the id
    return run_id


#: the simulated unit a procedure gets when neither --unit nor the station file names one
SIM_DEFAULT_UNIT = {"accelerometer": ("unit_serial", "QA-SIM-0001"),
                    "gyro": ("gyro_serial", "FOG-SIM-0001"),
                    "angular": ("mhd_serial", "MHD-SIM-0001")}


def seed_of(args, config) -> int | None:
    """``--seed``, else the station file's ``[simulation] seed`` (0 if it has none); None for
    a real station."""
    if args.seed is not None and not 0 <= args.seed < 2**63:
        raise ValueError(f"--seed {args.seed} not in 0..2**63-1")
    if args.seed is not None:
        return args.seed
    return (config.simulation or {}).get("seed", 0) if config.simulation is not None else None


def unit_of(args, config, kind: str) -> str | None:
    """``--unit``, else the station file's simulated unit of that kind, else the simulated
    default serial (None on a real station: the caller decides whether that is allowed)."""
    key, default = SIM_DEFAULT_UNIT[kind]
    return args.unit or (config.simulation or {}).get(key) or (default if config.simulated else None)


@contextlib.contextmanager
def progress_bar(enabled: bool):
    """A rich progress bar on stderr; yields a ``progress(done, total, message)`` callable."""
    if not enabled:
        yield lambda done, total, message="": None
        return
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    with Progress(TextColumn("{task.description}"), BarColumn(),
                  TextColumn("{task.percentage:>5.1f} %"), TimeElapsedColumn(),
                  console=_stderr_console(), transient=False) as bar:
        task = bar.add_task("starting", total=1.0)

        def update(done: float, total: float, message: str = "") -> None:
            bar.update(task, completed=done, total=total, description=message or "working")

        yield update


def _stderr_console():
    from rich.console import Console

    return Console(file=sys.stderr)


def print_outcome(outcome) -> None:
    print(f"run {outcome.run_id}: {outcome.status.upper()}"
          + (f" — {outcome.reason}" if outcome.reason else ""))
    for m in outcome.measurements:
        lim = f"[{'' if m.limit.low is None else f'{m.limit.low:g}'} .. " \
              f"{'' if m.limit.high is None else f'{m.limit.high:g}'}]"
        unc = "" if m.uncertainty is None else f"± {m.uncertainty:.2g}"
        value = f"{m.value:.6g}" if math.isfinite(m.value) else "—"  # not produced
        print(f"  {m.name:<22} {value:>14} {unc:<11} {m.unit:<9} {lim:<18} {m.outcome}")
    print(f"stored in {outcome.store_path} (bench runs show {outcome.run_id})")
