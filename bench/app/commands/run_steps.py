"""``bench run tumble | ratetable | accelerometer_noise | gyro_noise | gyro_startup``: one calibration or test
step as its own run — every produced measurement recorded with its uncertainty, no limits
(``bench acceptance`` judges them against a unit spec).

Each step's parameters become options (``--positions 12 --planes 2 …``), defaults from the
step's parameter dataclass.
"""

from __future__ import annotations

import dataclasses
import json
import sys

from bench.app.commands.common import open_store, print_outcome, progress_bar, seed_of, unit_of

#: step name → (module, class, help)
STEP_COMMANDS = {
    "tumble": ("procedures.tumble", "TumbleCalibration",
               "accelerometer multi-position calibration (IEEE 1293) on the turntable"),
    "ratetable": ("procedures.ratetable", "RateTableCalibration",
                  "gyro rate-table calibration (IEEE 952): scale factor, bias, nonlinearity, asymmetry"),
    "accelerometer_noise": ("procedures.noise", "AccelerometerNoise",
                            "accelerometer static record → Allan deviation: noise density, bias instability"),
    "gyro_noise": ("procedures.noise", "GyroNoise",
                   "gyro static record → Allan deviation: ARW, bias instability"),
    "gyro_startup": ("procedures.turn_on", "GyroTurnOnTest",
                     "gyro cold start from its frames: turn-on time, warm-up drift"),
}
def load_step(name: str, commands: dict | None = None):
    """The step class and its parameter dataclass of command ``name`` in ``commands``
    (name → (module, class, help); default :data:`STEP_COMMANDS`)."""
    import importlib

    module, cls, _ = (STEP_COMMANDS if commands is None else commands)[name]
    step = getattr(importlib.import_module(module), cls)
    return step, step.Parameters


def add_parameter_options(p, params) -> None:
    """One ``--option`` per field of a step's parameter dataclass, defaults from it."""
    for f in dataclasses.fields(params):
        kind = int if f.type in (int, "int") else float
        default = "the station's" if f.default is None else f.default
        p.add_argument(f"--{f.name.replace('_', '-')}", dest=f"param_{f.name}", type=kind,
                       default=f.default, metavar=kind.__name__.upper(), help=f"[{default}]")


def step_from_args(args, cls, params_cls):
    """The step built (and validated) from its ``--options``, before any station opens."""
    values = {f.name: getattr(args, f"param_{f.name}") for f in dataclasses.fields(params_cls)}
    return cls(params_cls(**values))


def register_procedure(procs, common) -> None:
    for name, (_, _, help_text) in STEP_COMMANDS.items():
        p = procs.add_parser(name, help=help_text)
        common(p)
        add_parameter_options(p, load_step(name)[1])
        p.set_defaults(func=run_step, step_name=name)


def execute_step(args, step):
    """Run one step as its own procedure on the station ``--station``; returns the outcome."""
    from bench.app.station import Station, resolve_station
    from bench.core.procedure import execute
    from procedures.steps import StepProcedure

    config = resolve_station(args.station)
    kind = step.kinds[0]
    unit, seed = unit_of(args, config, kind), seed_of(args, config)
    store = open_store(args)
    with Station(config, seed=seed, unit_serial=unit, unit_kind=kind) as station, \
            progress_bar(not args.no_progress and not args.json) as progress:
        return execute(StepProcedure(step), station, store, unit_serial=unit, seed=seed,
                       progress=progress)


def exit_code(outcome) -> int:
    return {"passed": 0, "failed": 1}.get(outcome.status, 2)


def run_step(args) -> int:
    outcome = execute_step(args, step_from_args(args, *load_step(args.step_name)))
    if args.json:
        json.dump(outcome.to_dict(), sys.stdout, indent=2, allow_nan=False)  # NaN → null in to_dict
        print()
    else:
        print_outcome(outcome)
    return exit_code(outcome)
