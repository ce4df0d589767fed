"""How the naming step tells random-process shapes apart (issue 15): at the step after the
deterministic effects of scorecard records with one hidden random process, which shape each rule
would name among the processes the step named.

Each record of the scorecard's triples with a random process (``--pairs`` values: the samples;
``--triples 30`` each, as the scorecard draws them) and of its single-process records
(``--singles`` seeds a process, catalogue and independent generator) is taken at the step where
its deterministic effects are in the model at their truth, calibrated; ``name_effect`` runs there
and the named random processes it hands :func:`bench.discovery.choosing.preferred` are read
(their Whittle BIC gain and, on a close call, the exact likelihood's, ``Trial.shape_bic``). The
rules, each naming one of them:

- ``whittle``: the best Whittle BIC gain;
- ``exact-any``: shapes within ``SHAPE_TIE`` of the best ranked by the exact likelihood when two
  or more are (stop 33's rule);
- ``exact-all``: the exact likelihood only when every named shape is within the tie (stop 34's
  rule, ``naming.shape_ranked``) — else the Whittle order.

Prints right/total per group and rule and the paired wins/losses against ``exact-any``.
``python benchmarks/discovery_shape_calls.py --pairs 0,1,2,3,4,5,6,7,8,9,10,11,12 --singles 5
--jobs 2`` (≈ 12 min on 2 cores: 434 triples and 72 singles with two or more shapes named) gave
exact-any 365 + 66, exact-all 372 + 71, whittle 367 + 71 (right of 434 triples + 72 singles)."""

from __future__ import annotations

import argparse
import json
import math
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import discovery_scorecard as sc  # its neighbour in this folder: the scorecard's case list

from bench.discovery import choosing, naming
from bench.discovery.calibration import calibrate
from bench.discovery.effects import CATALOGUE
from bench.discovery.model import Model
from bench.testing.discovery_cases import hidden_case

#: the catch-all processes whose shapes are told apart (an angle quantizer is white angle noise)
SHAPES = ("gauss_markov", "flicker_noise", "rate_random_walk")

_seen: list[list[dict]] = []
_preferred = choosing.preferred


def _reading(named, *args, **kwargs):
    """:func:`choosing.preferred`, recording the named processes of its first call."""
    if not _seen:
        _seen.append([{"id": t.id, "bic": float(t.bic_gain), "shape": float(t.shape_bic)}
                      for t in named if t.effect.stochastic and math.isfinite(t.bic_gain)])
    return _preferred(named, *args, **kwargs)


def shape_call(job: tuple) -> dict | None:
    """The named processes at the step after the deterministic effects of one record."""
    kind, effects, seed, generator = job
    case = hidden_case(kind, effects, seed, 3000, None, generator)
    if case is None:
        return None
    rec, truth, _, _ = case
    params = dict(truth.effects)
    known = [e for e in effects if not CATALOGUE[e].stochastic]
    model = calibrate(Model(truth.base, tuple((e, params[e]) for e in known)), rec)
    _seen.clear()
    choosing.preferred = _reading
    try:
        naming.name_effect(model, rec, seed=seed + len(known))
    finally:
        choosing.preferred = _preferred
    truth_id = next(e for e in effects if e in SHAPES)
    return {"kind": kind, "hidden": list(effects), "seed": seed, "generator": generator, "truth": truth_id,
            "named": _seen[0] if _seen else []}


def _whittle(named: list[dict]) -> str:
    return max(named, key=lambda t: t["bic"])["id"]


def _exact_any(named: list[dict]) -> str:
    close = [t for t in named if math.isfinite(t["shape"])]
    return max(close, key=lambda t: t["shape"])["id"] if len(close) > 1 else _whittle(named)


def _exact_all(named: list[dict]) -> str:
    close = [t for t in named if math.isfinite(t["shape"])]
    return max(close, key=lambda t: t["shape"])["id"] if len(close) == len(named) else _whittle(named)


RULES = {"whittle": _whittle, "exact-any": _exact_any, "exact-all": _exact_all}


def jobs_for(pairs: list[int], singles: int) -> list[tuple]:
    jobs: list[tuple] = []
    for kind in ("accelerometer", "gyro", "mhd"):
        for eid in SHAPES:
            if kind in CATALOGUE[eid].kinds:
                jobs += [(kind, (eid,), s, g) for s in range(singles) for g in ("catalogue", "independent")]
    for p in pairs:
        args = argparse.Namespace(kinds="accelerometer,gyro,mhd", seeds=0, independent_seeds=0, pairs=p,
                                  triples=30, clean=0, open=0, n=3000, effects=None, white_draws=False)
        for _, (kind, effects, seed, *_rest) in sc.scorecard_jobs(args):
            if len(effects) == 3 and set(effects) & set(SHAPES):
                jobs.append((kind, effects, seed, "catalogue"))
    return list(dict.fromkeys(jobs))


def check() -> int:
    """``--check``: each rule on a worked close call, and the job list, without naming any record.

    The close call is the independent-generator flicker record's (accelerometer, seed 1 of the
    singles): flicker and Gauss–Markov within the tie, the walk outside it. Prints a line per
    check; 0 when every one holds."""
    two_close = [{"id": "flicker_noise", "bic": 732.5, "shape": 69737.3},
                 {"id": "gauss_markov", "bic": 730.7, "shape": 69740.4},
                 {"id": "rate_random_walk", "bic": 703.4, "shape": math.nan}]
    all_close = [dict(t, shape=69730.0, bic=730.0) if t["id"] == "rate_random_walk" else t for t in two_close]
    jobs = jobs_for([0], 0)
    checks = {
        "exact-any: the exact likelihood decides when two shapes are in the tie":
            RULES["exact-any"](two_close) == "gauss_markov",
        "exact-all: the Whittle order unless every shape is in the tie":
            RULES["exact-all"](two_close) == RULES["whittle"](two_close) == "flicker_noise",
        "exact-all and exact-any agree when every shape is in the tie":
            RULES["exact-all"](all_close) == RULES["exact-any"](all_close) == "gauss_markov",
        "the jobs of --pairs 0 --singles 0 are triples holding a shape":
            bool(jobs) and all(len(j[1]) == 3 and set(j[1]) & set(SHAPES) for j in jobs),
    }
    for what, holds in checks.items():
        print(f"{'ok  ' if holds else 'FAIL'} {what}")
    return 0 if all(checks.values()) else 1


def report(calls: list[dict]) -> None:
    right: dict[str, Counter] = {}
    total: Counter = Counter()
    paired: Counter = Counter()
    for c in calls:
        named = c["named"]
        if len(named) < 2 or c["truth"] not in {t["id"] for t in named}:
            continue  # no call of shape to make
        group = "single" if len(c["hidden"]) == 1 else "triple"
        total[group] += 1
        ok = {name: rule(named) == c["truth"] for name, rule in RULES.items()}
        for name, hit in ok.items():
            right.setdefault(group, Counter())[name] += hit
        for name in RULES:
            paired[name, "+"] += ok[name] and not ok["exact-any"]
            paired[name, "-"] += ok["exact-any"] and not ok[name]
    print(f"{'group':8s} {'records':>8s} " + " ".join(f"{name:>10s}" for name in RULES))
    for group in sorted(total):
        print(f"{group:8s} {total[group]:8d} " + " ".join(f"{right[group][name]:10d}" for name in RULES))
    print("against exact-any: " + ", ".join(f"{name} +{paired[name, '+']} -{paired[name, '-']}" for name in RULES
                                            if name != "exact-any"))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", default="0", help="comma-separated --pairs values of the scorecard (its samples)")
    ap.add_argument("--singles", type=int, default=5, help="single-process records a shape, kind and generator")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--json", default=None, help="write every record's named processes here")
    ap.add_argument("--check", action="store_true", help="check the rules and the job list, name no record")
    args = ap.parse_args(argv)
    if args.check:
        return check()
    pairs = [int(p) for p in args.pairs.split(",") if p.strip()]
    jobs = jobs_for(pairs, args.singles)
    print(f"{len(jobs)} records", flush=True)
    with ProcessPoolExecutor(args.jobs) as pool:
        calls = [c for c in pool.map(shape_call, jobs, chunksize=1) if c is not None]
    if args.json:
        Path(args.json).write_text(json.dumps(calls, indent=1))
    report(calls)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
