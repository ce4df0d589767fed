"""``bench run <step>``: one step of the catalogue on a station, stored as its own run.

Every subcommand is derived from the step catalogue (``procedures.catalogue``): its help
from the step's docstring, one ``--option`` per field of its parameter dataclass (type,
default and help from the field), ``--analyze`` / ``--report DIR`` from the step's
follow-up.  Every produced value is recorded with its uncertainty, no limits (``bench
acceptance`` judges them against a unit spec); a step's own guards (the start-up
acquisition's level check) are judged.  The ending is the one every run command shares
(:func:`bench.app.commands.common.conclude`): exit 0 passed, 1 failed, 2 aborted or error.
"""

from __future__ import annotations

import argparse
import dataclasses
import inspect
import typing
from pathlib import Path
from typing import Any

from bench.app import session
from bench.app.commands.common import conclude, label_options, labels_of, open_store, progress_bar, seed_of
from bench.app.commands.follow_ups import ANALYSES, follow_up
from bench.core.step import Step
from procedures.catalogue import CATALOGUE


def configure(run: argparse.ArgumentParser) -> None:
    steps = run.add_subparsers(dest="procedure", metavar="STEP")
    steps.required = True
    for name, step in CATALOGUE.steps.items():
        p = steps.add_parser(name, help=step.summary(), description=inspect.cleandoc(step.__doc__ or ""),
                             formatter_class=argparse.RawDescriptionHelpFormatter)
        station_options(p)
        parameter_options(p, step.Parameters)
        if step.follow_up is not None and step.follow_up.on_request:
            p.add_argument("--analyze", action="store_true", help=step.follow_up.summary)
            p.add_argument("--report", metavar="DIR", default=None,
                           help="with --analyze: also write the report into DIR/<run id>/")
        elif step.follow_up is not None:
            p.add_argument("--report", metavar="DIR", default=None,
                           help=f"{step.follow_up.summary}; also written into DIR/<run id>/")
        p.set_defaults(func=run_step, step_name=name)
    for old, new in CATALOGUE.renamed.items():
        if old not in CATALOGUE:  # a name that went away: say the new one (not listed in the help)
            steps.add_parser(old).set_defaults(func=_renamed, old=old, new=new, ignores_arguments=True)


def station_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--station", default="sim", help="'sim' (built-in simulated station) or a "
                   "station TOML file [sim]")
    p.add_argument("--unit", default=None, help="unit serial number")
    p.add_argument("--seed", type=int, default=None, help="seed of the simulated world")
    p.add_argument("--json", action="store_true", help="print the outcome as JSON")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    label_options(p)


def _option_type(annotation: Any) -> type:
    """int or float (``float | None`` is a float left to the station when not given)."""
    kinds = {a for a in typing.get_args(annotation) if a is not type(None)} or {annotation}
    if kinds == {int}:
        return int
    if kinds <= {float, int}:
        return float
    raise TypeError(f"no command-line option type for a parameter of type {annotation!r}")


def _shown(default: Any) -> str:
    if default is None:
        return "the station's"
    return f"{default:g}" if isinstance(default, float) else str(default)


def parameter_options(p: argparse.ArgumentParser, params: type) -> None:
    """One ``--option`` per field of a step's parameter dataclass: type and default from the
    field, help from its ``parameter(..., help)`` metadata."""
    hints = typing.get_type_hints(params)
    for f in dataclasses.fields(params):
        kind = _option_type(hints[f.name])
        names = [f"--{f.name.replace('_', '-')}"] + [f"--{a}" for a in f.metadata.get("aliases", ())]
        p.add_argument(*names, dest=f"param_{f.name}", type=kind, default=f.default,
                       metavar=kind.__name__.upper(),
                       help=f"{f.metadata.get('help', '')} [{_shown(f.default)}]".strip())


def step_from_args(args: argparse.Namespace) -> Step[Any]:
    """The step built (and validated) from its ``--options``, before any station opens."""
    step = CATALOGUE.step(args.step_name)
    return session.make_step(args.step_name, **{f.name: getattr(args, f"param_{f.name}")
                                        for f in dataclasses.fields(step.Parameters)})


def _report_root(args: argparse.Namespace, step: Step[Any]) -> Path | None:
    """``--report DIR``, refused before the station opens when it cannot be used."""
    report = getattr(args, "report", None)
    if report is None:
        return None
    declared = step.follow_up
    if declared is not None and declared.on_request and not args.analyze:
        raise ValueError(f"--report DIR needs --analyze (the report is the "
                         f"{ANALYSES[declared.analysis].title}'s)")
    root = Path(report)
    if root.exists() and not root.is_dir():
        raise ValueError(f"--report {report!r} exists and is not a folder")
    return root


def run_step(args: argparse.Namespace) -> int:
    """Handler of ``bench run <step>``."""
    step = step_from_args(args)  # validated before any instrument is touched
    report_root = _report_root(args, step)
    config = session.station_config(args.station)
    seed = seed_of(args, config)  # --seed named in the error, before any instrument is touched
    store = open_store(args)
    with progress_bar(not args.no_progress and not args.json) as progress:
        outcome = session.run_step(step, station=config, unit=args.unit, seed=seed, store=store,
                                   labels=labels_of(args, config), progress=progress)
    declared, follow_ups = step.follow_up, []
    if declared is not None and (not declared.on_request or args.analyze) and outcome.status == "passed":
        follow_ups.append(follow_up(declared, store.path, outcome.run_id, report_root))
    return conclude(outcome, as_json=args.json, follow_ups=follow_ups)


def _renamed(args: argparse.Namespace) -> int:
    raise ValueError(f"bench run {args.old} is now bench run {args.new} (the step was renamed)")
