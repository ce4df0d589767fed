"""The acceptance test's own decision risk: the real acceptance procedure on N units drawn
from the manufacturing spread, each on its own simulated station, on Dask.

One task per unit (:func:`run_unit`), the same code path as ``bench acceptance``
(``AcceptanceTest(spec)`` run by ``bench.core.procedure.execute`` on a ``Station``, stored
in the run store).  Unit ``i`` of seed ``S`` is fixed by ``SeedSequence(S, spawn_key=(i,))``:
its first word seeds the simulated world, its second names the unit (the serial
``<pattern>`` with ``*`` → ``MC<hex>``, and a serial draws the unit's parameters from the
population).  So a unit's verdict depends on (spec, S, i) alone — not on the worker, the
order or how many times it ran: serial, 2-worker and cluster runs agree, and a unit whose
worker died is run again elsewhere with the same result.

Truth: the simulated station knows each drawn unit (``truth()`` / ``gyro_truth()``); the
spec's measurements are mapped to true values by :data:`TRUTH` (measurement → truth key and
its unit).  Where a measurement has no true value in the model it is judged but not scored
(:data:`UNDEFINED` says why).
"""

from __future__ import annotations

import math
import os
import socket
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from distributed import Client, LocalCluster, as_completed

from bench.analysis.quality import DecisionRisk, Proportion, decision_risk, inside, overall_risk, wilson_interval
from bench.app.station import Station, builtin_sim_config
from bench.core.procedure import execute
from bench.core.spec import UnitSpec, convert, load_spec
from bench.core.store import RunStore
from procedures.acceptance import AcceptanceTest
from procedures.catalogue import CATALOGUE

#: spec kind → measurement → (key of the station's truth dict, unit of that value)
TRUTH: dict[str, dict[str, tuple[str, str]]] = {
    "accelerometer": {
        "k0": ("k0_g", "g"),
        "k1": ("k1_ma_per_g", "mA/g"),
        "k2": ("k2_g_per_g2", "g/g^2"),
        "delta_o": ("delta_o_rad", "rad"),
        "delta_p": ("delta_p_rad", "rad"),
        "noise_density": ("white_density_g_per_rthz", "g/rtHz"),  # one-sided N, as measured
    },
    "gyro": {
        "bias": ("bias_dph", "deg/h"),          # the unit's turn-on bias (the run's differs by
        "scale_factor_error": ("scale_factor_error_ppm", "ppm"),  # the repeatability: a risk)
        "asymmetry": ("asymmetry_ppm", "ppm"),
        "arw": ("arw_deg_per_rh", "deg/rth"),
        "bias_instability": ("bias_instability_dph", "deg/h"),  # IEEE 952 B, as measured
    },
}
#: measurements judged but without a true value in the simulated unit, and why
UNDEFINED: dict[str, str] = {
    "fit_residual_rms": "model adequacy of the tumble fit: a property of the record, not the unit",
    "turn_on_time": "defined by the record (settling into a band), not a parameter of the unit",
    "warmup_drift": "defined by the record's smoothing window, not a parameter of the unit",
    "bias_instability@accelerometer": "the unit's coloured noise is Gauss-Markov terms: no flicker "
                                      "floor B to compare with",
    "nonlinearity": "the spec judges the LS-line residual over the rate plan; the unit has a cubic "
                    "coefficient (the map between them depends on the plan)",
    "vibration_bias_shift": "rectification at the achieved level, a function of the record",
    "vibration_level": "the shaker's achieved level: judges the station, not the unit",
    "level_check_g": "a guard of the station (table level), not the unit",
    "readings_lost": "a guard of the acquisition, not the unit",
}


def unit_seeds(root_seed: int, index: int) -> tuple[int, str]:
    """(world seed, serial tag) of unit ``index``: from ``SeedSequence(root_seed, spawn_key=(index,))``."""
    if not 0 <= root_seed < 2**63 or not 0 <= index < 2**32:
        raise ValueError(f"seed {root_seed} not in 0..2**63-1 or index {index} not in 0..2**32-1")
    words = np.random.SeedSequence(root_seed, spawn_key=(index,)).generate_state(2, np.uint64)
    return int(words[0]) >> 1, f"MC{int(words[1]):016X}"


def truth_key(kind: str, name: str) -> tuple[str, str] | None:
    return TRUTH.get(kind, {}).get(name)


def run_unit(spec_path: str, index: int, root_seed: int, store_path: str) -> dict[str, Any]:
    """Draw unit ``index``, run the acceptance procedure on its own simulated station, store
    the run; return its verdict, measurements and true values (spec units).  A Dask task."""
    spec = load_spec(spec_path, CATALOGUE)
    world_seed, tag = unit_seeds(root_seed, index)
    serial = (spec.serial_pattern or "UNIT-*").replace("*", tag)
    labels = {"station_id": f"risk:{socket.gethostname()}:{os.getpid()}", "lot": f"MC{root_seed}"}
    with RunStore(store_path) as store, \
            Station(builtin_sim_config(), seed=world_seed, unit_serial=serial,
                    unit_kind=spec.kind) as station:
        outcome = execute(AcceptanceTest(spec), station, store, unit_serial=serial, seed=world_seed,
                          labels=labels)
        assert station.sim is not None  # the built-in station is simulated
        truth = station.sim.gyro_truth() if spec.kind == "gyro" else station.sim.truth()
    true_values = {}
    for m in spec.measurements:
        key = truth_key(spec.kind, m.name)
        if key is not None:
            true_values[m.name] = convert(float(truth[key[0]]), key[1], m.unit)
    return {"index": index, "serial": serial, "seed": world_seed, "run_id": outcome.run_id,
            "status": outcome.status, "reason": outcome.reason,
            "measurements": {m.name: {"value": m.value if math.isfinite(m.value) else None,
                                      "outcome": m.outcome} for m in outcome.measurements},
            "truth": true_values}


@dataclass(frozen=True)
class RiskReport:
    """What ``bench risk`` reports: the yield, each scored measurement's decision risk, the
    whole test's false accept / reject, and which measurements could not be scored."""

    spec: str
    model: str
    units: int
    root_seed: int
    yield_: Proportion
    aborted: int
    per_measurement: dict[str, DecisionRisk]
    overall_false_accept: Proportion
    overall_false_reject: Proportion
    unscored: dict[str, str]
    verdicts: tuple[str, ...]
    rejected_unscored: int = 0      # units rejected on a measurement with no true value

    def to_dict(self) -> dict[str, Any]:
        return {"spec": self.spec, "model": self.model, "units": self.units, "seed": self.root_seed,
                "yield": self.yield_.to_dict(), "aborted": self.aborted,
                "measurements": {k: v.to_dict() for k, v in self.per_measurement.items()},
                "overall": {"false_accept": self.overall_false_accept.to_dict(),
                            "false_reject": self.overall_false_reject.to_dict(),
                            "rejected_on_unscored": self.rejected_unscored},
                "unscored": self.unscored, "verdicts": list(self.verdicts)}


def assess(spec: UnitSpec, root_seed: int, units: Sequence[dict[str, Any]],
           target: float = 0.02) -> RiskReport:
    """The decision risk from the units' results (:func:`run_unit`, any order)."""
    results = sorted(units, key=lambda u: u["index"])
    judged = [u for u in results if u["status"] in ("passed", "failed")]
    if len(judged) < 2:
        raise ValueError(f"only {len(judged)} unit(s) finished the acceptance test; need >= 2")
    per: dict[str, DecisionRisk] = {}
    unscored: dict[str, str] = {}
    conforming = np.ones(len(judged), bool)
    for m in spec.measurements:
        if truth_key(spec.kind, m.name) is None:
            unscored[m.name] = UNDEFINED.get(f"{m.name}@{spec.kind}", UNDEFINED.get(
                m.name, "no true value mapped"))
            continue
        measured = np.array([np.nan if u["measurements"].get(m.name, {}).get("value") is None
                             else u["measurements"][m.name]["value"] for u in judged])
        true = np.array([u["truth"][m.name] for u in judged])
        per[m.name] = decision_risk(measured, true, m.low, m.high, target=target)
        conforming &= inside(true, m.low, m.high)
    accepted = np.array([u["status"] == "passed" for u in judged])
    # rejected on a measurement with no true value (or a station guard): not scoreable
    undecidable = np.array([any(m.get("outcome") == "fail" for name, m in u["measurements"].items()
                                if name not in per) for u in judged])
    fa, fr = overall_risk(accepted, conforming, undecidable)
    return RiskReport(spec.source, spec.model, len(results), root_seed,
                      wilson_interval(int(accepted.sum()), len(judged)),
                      len(results) - len(judged), per, fa, fr, unscored,
                      tuple(u["status"] for u in results), int(undecidable.sum()))


def run_on_dask(spec_path: str, units: int, root_seed: int, store_path: str, *,
                workers: int | None = None, scheduler: str | None = None,
                on_done: Callable[[int, int], None] | None = None) -> list[dict[str, Any]]:
    """Every unit as a Dask task on a new ``LocalCluster`` of ``workers`` single-threaded
    processes, or on the cluster whose scheduler is at ``scheduler``; results in any order."""
    if scheduler is not None:
        client = Client(scheduler, timeout="30s")
        cluster = None
    else:
        cluster = LocalCluster(n_workers=workers or 1, threads_per_worker=1, processes=True,
                               dashboard_address=None, silence_logs=40)
        client = Client(cluster)
    try:
        futures = [client.submit(run_unit, spec_path, i, root_seed, store_path,
                                 key=f"risk-unit-{root_seed}-{i}", pure=False, retries=2)
                   for i in range(units)]
        out = []
        for n, future in enumerate(as_completed(futures), start=1):
            out.append(future.result())
            if on_done is not None:
                on_done(n, units)
        return out
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
