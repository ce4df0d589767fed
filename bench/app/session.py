"""The bench from Python: open a station, run a step or an acceptance, read the run back.

What ``bench run``, ``bench acceptance`` and ``bench runs`` do, as functions a script or a
notebook calls (the CLI calls the same ones)::

    from bench.app.session import run_step, read_run

    outcome = run_step("tumble", station="sim", unit="QA-SIM-0003", seed=1, store="runs.sqlite")
    k1 = outcome.measurement("k1")
    print(f"K1 = {k1.value:.6f} ± {k1.uncertainty:.1g} {k1.unit}")
    run = read_run(outcome.run_id, store="runs.sqlite")
    table = run.frame("tumble")          # the mean output per position, a pandas DataFrame

``station`` is ``"sim"`` (the built-in simulated station, started and stopped around the run),
the path of a station TOML file (real instruments at their VISA addresses, or a simulated
station with options), or a parsed :class:`~bench.app.station.StationConfig`. Every run is
stored with every sample, as from the command line, and read back with :func:`read_run`.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from bench.app import labels as run_labels
from bench.app.labels import world_seed
from bench.app.station import Station, StationConfig, resolve_station
from bench.core.operator import Operator
from bench.core.procedure import RunOutcome, execute
from bench.core.spec import UnitSpec, load_spec
from bench.core.step import Progress, Step, no_progress
from bench.core.store import RunStore
from bench.core.store.model import RunInfo
from bench.specs import builtin_specs
from bench.values import Estimate
from procedures.acceptance import AcceptanceTest
from procedures.catalogue import CATALOGUE
from procedures.running import alone

if TYPE_CHECKING:
    import pandas

#: where runs go when no store is named (the CLI's default too; ``BENCH_STORE`` overrides)
DEFAULT_STORE = "bench-data/bench.sqlite"

#: the simulated unit a step gets when neither the caller nor the station file names one
SIM_DEFAULT_UNIT = {"accelerometer": ("unit_serial", "QA-SIM-0001"),
                    "gyro": ("gyro_serial", "FOG-SIM-0001"),
                    "angular": ("mhd_serial", "MHD-SIM-0001")}

__all__ = ["DEFAULT_STORE", "StoredRun", "choose_spec", "make_step", "open_station", "read_run",
           "run_acceptance", "run_step", "station_config", "station_labels", "station_seed",
           "station_unit"]


def station_config(station: str | os.PathLike[str] | StationConfig = "sim") -> StationConfig:
    """The station a run uses: ``"sim"``, a station TOML file, or a parsed configuration.

    Raises ValueError (naming the file and the key) when a station file is invalid.
    """
    if isinstance(station, StationConfig):
        return station
    return resolve_station(os.fspath(station))


def station_seed(config: StationConfig, seed: int | None = None) -> int | None:
    """The seed of the simulated world: ``seed``, else the station file's ``[simulation] seed``
    (0 when it names none); None on a real station."""
    return world_seed(config.simulation, seed)


def station_unit(config: StationConfig, kind: str, unit: str | None = None) -> str | None:
    """The unit's serial: ``unit``, else the station file's simulated unit of that ``kind``,
    else the simulated default (None on a real station: the caller decides)."""
    if kind not in SIM_DEFAULT_UNIT:
        raise ValueError(f"unit kind {kind!r} not in {'|'.join(SIM_DEFAULT_UNIT)}")
    key, default = SIM_DEFAULT_UNIT[kind]
    return unit or (config.simulation or {}).get(key) or (default if config.simulated else None)


def station_labels(config: StationConfig, *, station_id: str | None = None, socket_name: str | None = None,
                   lot: str | None = None) -> dict[str, str]:
    """A run's labels: the station id (given, else ``$BENCH_STATION_ID``, else ``host:station``),
    and the test socket and production lot when given."""
    return run_labels.station_labels(config.name, station_id=station_id, socket_name=socket_name, lot=lot)


@contextmanager
def open_station(station: str | os.PathLike[str] | StationConfig = "sim", *, seed: int | None = None,
                 unit: str | None = None, kind: str = "accelerometer") -> Iterator[Station]:
    """An open station for a script of its own: drivers in ``.instruments``, the bench clock
    in ``.clock``; everything (and an embedded simulated station) closed on exit.

    >>> with open_station("sim", seed=1) as station:                     # doctest: +SKIP
    ...     dmm = station.instruments["dmm"]
    """
    config = station_config(station)
    with Station(config, seed=station_seed(config, seed), unit_serial=station_unit(config, kind, unit),
                 unit_kind=kind) as opened:
        yield opened


def make_step(name: str, **parameters: Any) -> Step[Any]:
    """The catalogue's step ``name`` with its parameters (the fields of its ``Parameters``
    dataclass, e.g. ``make_step("tumble", positions=24, planes=2)``), validated before any
    instrument is touched."""
    step = CATALOGUE.step(name)
    fields = {f.name for f in dataclasses.fields(step.Parameters)}
    unknown = sorted(set(parameters) - fields)
    if unknown:
        raise ValueError(f"step {name!r} has no parameter {', '.join(unknown)} "
                         f"(its parameters: {', '.join(sorted(fields))})")
    return step(step.Parameters(**parameters))


def _store_path(store: str | os.PathLike[str] | None) -> Path:
    """The named store, else ``$BENCH_STORE``, else the default (the CLI's rule)."""
    return Path(os.fspath(store) if store is not None else os.environ.get("BENCH_STORE") or DEFAULT_STORE)


def _store(store: str | os.PathLike[str] | RunStore | None) -> RunStore:
    return store if isinstance(store, RunStore) else RunStore(_store_path(store))


def run_step(step: str | Step[Any], *, station: str | os.PathLike[str] | StationConfig = "sim",
             unit: str | None = None, seed: int | None = None,
             store: str | os.PathLike[str] | RunStore | None = None, labels: Mapping[str, str] | None = None,
             progress: Progress = no_progress, **parameters: Any) -> RunOutcome:
    """Run one step of the catalogue on a station and store it as its own run (``bench run``).

    ``step`` is a step name (its parameters as keyword arguments) or a built step
    (:func:`make_step`). Returns the run's outcome: ``run_id``, ``status`` (``passed``,
    ``failed`` or ``aborted`` with ``reason``) and its measurements, each with its standard
    uncertainty (``outcome.measurement("k1")``). The run, with every sample, is in ``store``.
    """
    built = make_step(step, **parameters) if isinstance(step, str) else step
    if parameters and not isinstance(step, str):
        raise ValueError("give the parameters to make_step, not beside a built step")
    config = station_config(station)
    run_store = _store(store)
    with open_station(config, seed=seed, unit=unit, kind=built.kinds[0]) as opened:
        return execute(alone(built), opened, run_store, unit_serial=opened.unit_serial, seed=opened.seed,
                       progress=progress, labels=dict(labels) if labels is not None else station_labels(config))


def choose_spec(spec: str | os.PathLike[str] | None, unit: str | None) -> UnitSpec:
    """The unit spec of an acceptance: the file ``spec``, else the built-in spec whose serial
    pattern matches ``unit`` (ValueError naming the patterns when none does)."""
    if spec is not None:
        return load_spec(os.fspath(spec), CATALOGUE)
    specs = [load_spec(p, CATALOGUE) for p in builtin_specs()]
    patterned = [s for s in specs if s.serial_pattern]  # a spec without one is chosen by file only
    if unit is None:
        raise ValueError("give a spec file or a unit serial (built-in specs match serials: "
                         + ", ".join(f"{s.serial_pattern} → {s.model}" for s in patterned) + ")")
    matching = [s for s in patterned if s.applies_to(unit)]
    if not matching:
        raise ValueError(f"no built-in spec matches unit {unit!r} (serials it knows: "
                         + ", ".join(f"{s.serial_pattern} → {s.model}" for s in patterned) + "); give a spec file")
    return matching[0]


def acceptance_unit(spec: UnitSpec, config: StationConfig, unit: str | None) -> str:
    """The serial an acceptance runs on: ``unit``, else (simulated station) the spec's pattern
    with ``*`` = 0001."""
    if unit is not None:
        return unit
    if not config.simulated or not spec.serial_pattern:
        raise ValueError("a unit serial is required on a real station")
    return spec.serial_pattern.replace("*", "0001")


def run_acceptance(unit: str | None = None, *, spec: str | os.PathLike[str] | UnitSpec | None = None,
                   station: str | os.PathLike[str] | StationConfig = "sim", seed: int | None = None,
                   store: str | os.PathLike[str] | RunStore | None = None,
                   labels: Mapping[str, str] | None = None, operator: Operator | None = None,
                   progress: Progress = no_progress) -> RunOutcome:
    """The factory acceptance test of one unit against its spec (``bench acceptance``).

    ``spec`` is a unit-spec TOML file or a loaded spec; without it the built-in spec whose
    serial pattern matches ``unit``. Every step's parameters are validated before the station
    opens. Returns the outcome with each measurement judged against its limits.
    """
    unit_spec = spec if isinstance(spec, UnitSpec) else choose_spec(spec, unit)
    procedure = AcceptanceTest(unit_spec)
    config = station_config(station)
    serial = acceptance_unit(unit_spec, config, unit)
    run_store = _store(store)
    with open_station(config, seed=seed, unit=serial, kind=unit_spec.kind) as opened:
        return execute(procedure, opened, run_store, unit_serial=opened.unit_serial, seed=opened.seed,
                       progress=progress, labels=dict(labels) if labels is not None else station_labels(config),
                       operator=operator)


@dataclass(frozen=True)
class StoredRun:
    """A stored run, read back: its record, measurements and sample streams.

    Attributes
    ----------
    info : RunInfo
        The run's record: id, procedure, parameters, station snapshot, unit serial, seed,
        code version, status and reason, start and end times, labels.
    store : RunStore
        The store it was read from.
    """

    info: RunInfo
    store: RunStore

    @property
    def run_id(self) -> str:
        return self.info.id

    @property
    def streams(self) -> list[str]:
        """The names of the run's sample streams."""
        return list(self.store.streams(self.info.id))

    def measurements(self) -> dict[str, dict[str, Any]]:
        """Every measurement: name → ``{value, uncertainty, unit, low, high, outcome, ...}``."""
        return {k.removeprefix("measurement."): v for k, v in self.info.results.items()
                if k.startswith("measurement.")}

    def measurement(self, name: str) -> Estimate:
        """One measurement as a value with its standard uncertainty (in its unit)."""
        found = self.measurements()
        if name not in found:
            raise LookupError(f"run {self.run_id} has no measurement {name!r} "
                              f"(it has: {', '.join(found) or 'none'})")
        m = found[name]
        value = float("nan") if m["value"] is None else float(m["value"])
        return Estimate(value, m.get("uncertainty"))

    def arrays(self, stream: str) -> dict[str, np.ndarray]:
        """A stream's columns as numpy arrays (column name → array, units in the stream's info)."""
        return self.store.load(self.info.id, stream)

    def frame(self, stream: str) -> pandas.DataFrame:
        """A stream as a pandas DataFrame, one column per stored column."""
        # lazy: pandas (~0.3 s of imports) only for the caller who asks for a DataFrame
        import pandas  # noqa: PLC0415 — lazy, see above

        return pandas.DataFrame(self.arrays(stream))


def read_run(run_id: str = "latest", *, store: str | os.PathLike[str] | RunStore | None = None) -> StoredRun:
    """A stored run by id (``"latest"``: the newest) from the station's store (never created
    here: a missing store is a LookupError naming it)."""
    if not isinstance(store, RunStore) and not _store_path(store).is_file():
        raise LookupError(f"no run store at {_store_path(store)}")
    run_store = _store(store)
    if run_id == "latest":
        runs = run_store.list_runs(limit=1)
        if not runs:
            raise LookupError(f"no runs stored yet in {run_store.location}")
        run_id = runs[0].id
    return StoredRun(run_store.get_run(run_id), run_store)
