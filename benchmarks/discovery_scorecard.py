"""Scorecard of the discrepancy workflow (issues 7 and 15) on records with hidden structure.

Rows (each kind's experiment, :func:`bench.discovery.experiments.make_experiment`, ``--n``
samples; the workflow starts from the bare base model):

* **singles** — every catalogue effect of the kind, ``--seeds`` records each, parameters drawn by
  ``Effect.draw`` (physical range, detectable) and simulated by the catalogue's own
  ``Model.simulate``: named first (target ≥ 90 %), nothing else named, main parameter within 2
  stated standard errors, final gap ≤ 1.1;
* **independent** — the same draws realised by :mod:`bench.testing.generators.discovery_effects`,
  a second generator written apart from the catalogue (the simulator's FOG and accelerometer
  physics where it has the effect): the rates should be within 5 points of the catalogue
  draws' (issue 15);
* **pairs** / **triples** — two / three effects at once (triples mix deterministic and
  stochastic): all named and nothing else (target ≥ 80 %); each effect at snr ≥ 15 inside its
  mixture (:func:`bench.testing.discovery_cases.hidden_case`; ``--white-draws``: against white
  noise only, stop 27's rule);
* **clean** — nothing hidden: nothing named (target ≥ 95 %), for both generators;
* **out-of-catalogue** — shapes no effect has (:mod:`bench.testing.generators.discovery_shapes`:
  triangle and square waves, a chirp, bursts, noise bursts, a dependence on the supply column,
  a tanh compression, random telegraph noise, an amplitude-modulated line): nothing named but the
  look-alike the shape's size is measured against (a line for the periodic and tonal shapes, the
  input polynomial for the tanh: naming it states the part of the shape it is), and unexplained
  structure reported (target ≥ 95 %), and found where it is. A random process in the model for
  its spectrum whose driving noise is not the model's (``Step.doubt``) is not a name here,
  as it is not in ``bench discover``'s answer (``Discovery.named``);
* the confusion matrix (hidden → first named).

``--power 0.5,1,2``: instead, the power curve of the naming near its minimum effect size — each
effect drawn with its main parameter exactly at snr = ratio × MIN_SNR (``Effect.draw(at_snr=)``;
the normal draw starts at 3 × MIN_SNR) and the rate at which it is named first, per effect and
ratio, with wrong first names counted apart (and among them its look-alike, ``CATALOGUE.look_alikes``).
The workflow's size gate is snr ≥ MIN_SNR on the *fitted* parameters, so ≈ 50 % is expected at
ratio 1; below it the effect is, by design, too small to name. For an effect with a look-alike
(time_delay ↔ lowpass_bandwidth, k2_nonlinearity ↔ scale_factor_asymmetry) the snr is that of
what tells the two apart: the effect itself can be far larger, so at low ratios it is named —
often as its look-alike, which the report then gives as a close competitor.
``--report FILE`` / ``--report-power FILE``: print the tables again from a ``--json`` file.

Run: ``.venv/bin/python benchmarks/discovery_scorecard.py [--kinds accelerometer,gyro,mhd]
[--seeds 5] [--independent-seeds 5] [--pairs 10] [--triples 10] [--clean 20] [--open 5]
[--n 3000] [--jobs 2] [--first N] [--json FILE]``. There is no peer library that names effects, so the
figures stand alone (targets from the issues beside them).
"""

from __future__ import annotations

import argparse
import json
import os
import sys

# one BLAS thread: the fits are tiny and a threaded BLAS spins on a shared two-core machine
# (measured: a case takes 6.1 s with the default threads, 3.3 s with one)
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
import time
from collections import Counter, defaultdict
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from bench.discovery.effects import CATALOGUE
from bench.discovery.effects_base import MIN_SNR
from bench.discovery.experiments import make_experiment
from bench.discovery.model import Model, base_model
from bench.discovery.workflow import discover
from bench.testing.discovery_cases import hidden_case, truth_base
from bench.testing.generators.discovery_shapes import SHAPES, found_where, hide

#: issue 15's new effects (their named-first rate is a row of its own)
NEW_EFFECTS = ("flicker_noise", "bias_jump", "angle_quantization", "thermal_two_node", "temperature_rate",
               "thermal_hysteresis")


def run_case(kind: str, effects: tuple[str, ...], seed: int, n: int, at_snr: float | None = None,
             generator: str = "catalogue", mix_rule: bool = True) -> dict | None:
    case = hidden_case(kind, effects, seed, n, at_snr, generator, mix_rule)
    if case is None:
        return None
    rec, truth, snrs, redraws = case
    t0 = time.perf_counter()
    d = discover(rec, Model(base_model(kind)), max_effects=max(2, len(effects) + 1), seed=seed)
    named = list(d.named)
    out = {"row": "single" if len(effects) == 1 else {0: "clean", 2: "pair", 3: "triple"}[len(effects)],
           "generator": generator, "kind": kind, "hidden": list(effects), "seed": seed, "named": named,
           "first": named[0] if named else None, "doubted": [s.effect_id for s in d.steps if s.doubt],
           "gap_final": d.gap_final.rms_ratio,
           "unexplained": list(d.unexplained), "withdrawn": list(d.withdrawn),
           "seconds": time.perf_counter() - t0, "recovered": None, "snr_ratio": [x / MIN_SNR for x in snrs],
           "ratio": None if at_snr is None else at_snr / MIN_SNR, "redraws": redraws,
           "mix_snr_ratio": [truth.effect_snr(rec, i) / MIN_SNR for i in range(len(effects))] if len(effects) > 1
           else None}
    if effects and named and named[0] == effects[0]:
        main = CATALOGUE[effects[0]].main_param
        true_v = truth.effects[0][1][main]
        got, sd = d.steps[0].params[main], d.steps[0].params_std[main]
        out.update(true=true_v, fit=got, fit_std=sd,
                   recovered=bool(np.isfinite(sd) and abs(got - true_v) <= 2 * sd))
    return out


def run_open_case(kind: str, shape: str, seed: int, n: int) -> dict | None:
    """An out-of-catalogue shape hidden in a clean record of the kind
    (:mod:`bench.testing.generators.discovery_shapes`)."""
    rng = np.random.default_rng([seed, 15, SHAPES.index(shape)])
    rec = make_experiment(kind, rng, n=n)
    truth = truth_base(kind, rng)
    try:
        rec, extra, where = hide(shape, kind, rec, rng, truth.base.noise_sd)
    except ValueError:
        return None
    rec = rec.replace(y=truth.simulate(rec, rng) + extra)
    t0 = time.perf_counter()
    d = discover(rec, Model(base_model(kind)), max_effects=3, seed=seed)
    named = list(d.named)
    return {"row": "open", "generator": "shapes", "kind": kind, "shape": shape, "hidden": [], "seed": seed,
            "named": named, "first": named[0] if named else None, "unexplained": list(d.unexplained),
            "allowed": list(where.get("allowed", ())),
            "doubted": [s.effect_id for s in d.steps if s.doubt],
            "withdrawn": list(d.withdrawn), "found_where": found_where(where, list(d.unexplained)),
            "seconds": time.perf_counter() - t0}


def _pct(k: int, n: int) -> str:
    return f"{100 * k / n:5.1f} % ({k}/{n})" if n else "   —"


def _call(job: tuple) -> dict | None:
    fn, args = job
    return run_open_case(*args) if fn == "open" else run_case(*args)


def _mark(c: dict) -> str:
    if c["row"] == "open":
        return f"{'ok ' if _open_ok(c) else 'MISS'} named {c['named']} doubted {c.get('doubted', [])} where " \
               f"{c['found_where']} withdrawn {[w.split(':')[0] for w in c['withdrawn']]}"
    hid = c["hidden"]
    if not hid:
        return f"named {c['named']} unexplained {len(c['unexplained'])}"
    ok = set(c["named"]) == set(hid) and len(c["named"]) == len(hid)
    mark = "ok " if ok else "xtra" if c["first"] == hid[0] and set(hid) <= set(c["named"]) else "MISS"
    return f"{mark} named {c['named']} doubted {c.get('doubted', [])} gap {c['gap_final']:.3f} " \
           f"recovered {c['recovered']}"


def run_jobs(jobs: list[tuple], n_jobs: int, json_path: str | None = None) -> list[dict]:
    """Run the cases (in ``n_jobs`` processes), printing each as it finishes, in job order, and
    rewriting ``json_path`` (when given) after each: a run stopped early can still be reported
    (``--report FILE``)."""
    out: list[dict] = []

    def show(job, c):
        fn, args = job
        label = f"{args[0]:13s} " + (f"{args[1]:12s}" if fn == "open" else
                                     f"{'+'.join(args[1]) or 'clean':40s} {args[5] if len(args) > 5 else ''}")
        if c is None:
            print(f"{label} seed {args[2]}: not drawable on this record (skipped)", flush=True)
            return
        print(f"[{len(out) + 1}/{len(jobs)}] {label} seed {args[2]}: {_mark(c)} ({c['seconds']:.1f} s)", flush=True)
        out.append(c)
        if json_path:
            Path(json_path).write_text(json.dumps(out, indent=1, default=float))

    if n_jobs <= 1:
        for job in jobs:
            show(job, _call(job))
        return out
    with ProcessPoolExecutor(n_jobs) as pool:
        for job, c in zip(jobs, pool.map(_call, jobs, chunksize=1)):
            show(job, c)
    return out


def effect_ids(kind: str, subset: str | None) -> list[str]:
    """Catalogue effects of ``kind``, restricted to the comma-separated ``subset`` if given."""
    return [e for e, eff in CATALOGUE.items() if kind in eff.kinds
            and (subset is None or e in subset.split(","))]


#: order of the rows within a round: the open-world rows first, singles of both generators side
#: by side (issue 15's new effects first), pairs last
ROW_ORDER = ("open", "triple", "clean", "single-new", "single", "pair")


def scorecard_jobs(args) -> list[tuple]:
    """Every case, in rounds: each row's first records (every kind, effect and shape; three
    triples and clean records, two pairs) before any row's next, so a run stopped early is a
    balanced sample; within a round the rows in ROW_ORDER, the kinds interleaved, and each
    effect's catalogue and independent records side by side (a cut leaves both generators on the
    same effects)."""
    jobs: list[tuple[tuple[int, int, int, int], tuple]] = []
    kinds = args.kinds.split(",")

    def add(round_: int, row: str, kind: str, k: int, job: tuple) -> None:
        jobs.append(((round_, ROW_ORDER.index(row), k, kinds.index(kind)), job))
    for kind in kinds:
        ids = effect_ids(kind, args.effects)
        for gen, seeds in (("catalogue", args.seeds), ("independent", args.independent_seeds)):
            for i, eid in enumerate(ids):
                for seed in range(seeds):
                    add(seed, "single-new" if eid in NEW_EFFECTS else "single", kind, 2 * i + (gen != "catalogue"),
                        ("single", (kind, (eid,), seed, args.n, None, gen)))
        rng = np.random.default_rng(12345)
        det = [e for e in ids if not CATALOGUE[e].stochastic]
        for k in range(args.pairs if len(det) >= 2 else 0):
            pair = tuple(str(e) for e in rng.choice(det, 2, replace=False))
            add(k // 2, "pair", kind, k, ("single", (kind, pair, 1000 + k, args.n, None, "catalogue",
                                                     not args.white_draws)))
        for k in range(args.triples):
            add(k // 3, "triple", kind, k, ("single", (kind, draw_triple(kind, ids, rng), 3000 + k, args.n, None,
                                                       "catalogue", not args.white_draws)))
        for j, gen in enumerate(("catalogue", "independent")):
            for k in range(args.clean):
                add(k // 3, "clean", kind, 2 * k + j, ("single", (kind, (), 2000 + k, args.n, None, gen)))
        for i, shape in enumerate(SHAPES):
            for seed in range(args.open):
                add(seed, "open", kind, i, ("open", (kind, shape, seed, args.n)))
    return [job for _, job in sorted(jobs, key=lambda kj: kj[0])]


def draw_triple(kind: str, ids: list[str], rng: np.random.Generator) -> tuple[str, ...]:
    """Three effects of the kind: two or three deterministic and at most one random process, no
    two look-alikes (their naming is a coin toss by design) and at most one output transform."""
    det = [e for e in ids if not CATALOGUE[e].stochastic]
    sto = [e for e in ids if CATALOGUE[e].stochastic]
    while True:
        k_sto = int(rng.random() < 0.5 and bool(sto))
        pick = [str(e) for e in rng.choice(det, 3 - k_sto, replace=False)]
        pick += [str(e) for e in rng.choice(sto, k_sto, replace=False)]
        if any(b in CATALOGUE.look_alikes(a) for a in pick for b in pick):
            continue
        if sum(CATALOGUE[e].stage == "output" for e in pick) > 1:
            continue
        return tuple(pick)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kinds", default="accelerometer,gyro,mhd")
    ap.add_argument("--seeds", type=int, default=5, help="catalogue-draw records per effect")
    ap.add_argument("--independent-seeds", type=int, default=5, help="independent-generator records per effect")
    ap.add_argument("--pairs", type=int, default=10, help="pair cases per kind")
    ap.add_argument("--triples", type=int, default=10, help="triple cases per kind")
    ap.add_argument("--clean", type=int, default=20, help="clean cases per kind and generator")
    ap.add_argument("--open", type=int, default=5, help="out-of-catalogue records per shape and kind")
    ap.add_argument("--n", type=int, default=3000, help="samples per record")
    ap.add_argument("--white-draws", action="store_true",
                    help="mixtures drawn with each effect at snr >= 15 against white noise only (stop 27's rule), "
                         "not inside its mixture")
    ap.add_argument("--jobs", type=int, default=1, help="worker processes")
    ap.add_argument("--effects", default=None, help="comma-separated subset of effect ids")
    ap.add_argument("--first", type=int, default=None, metavar="N",
                    help="only the first N cases in round order (a balanced sample; e.g. --pairs 6 --triples 10 "
                         "--first 23 with the other rows at 0: the first 17 triples and 6 pairs)")
    ap.add_argument("--json", default=None, help="write every case's outcome here")
    ap.add_argument("--power", default=None,
                    help="comma-separated snr ratios (× MIN_SNR): the power curve instead of the scorecard")
    ap.add_argument("--report", default=None, metavar="FILE", help="print the scorecard from a --json file")
    ap.add_argument("--report-power", default=None, metavar="FILE",
                    help="print the power-curve table from a --power --json file and stop")
    args = ap.parse_args(argv)
    if args.report_power is not None:
        cases = json.loads(Path(args.report_power).read_text())
        report_power(cases, sorted({c["ratio"] for c in cases}))
        return 0
    if args.report is not None:
        report(json.loads(Path(args.report).read_text()))
        return 0
    t_start = time.perf_counter()
    if args.power is not None:
        try:
            ratios = [float(v) for v in args.power.split(",")]
        except ValueError:
            ap.error(f"--power {args.power!r}: expected comma-separated positive numbers, e.g. 0.5,1,2")
        if not all(np.isfinite(r) and r > 0 for r in ratios):
            ap.error(f"--power {args.power!r}: every ratio must be > 0")
        jobs = [("single", (kind, (eid,), seed, args.n, ratio * MIN_SNR, "catalogue"))
                for kind in args.kinds.split(",") for eid in effect_ids(kind, args.effects)
                for ratio in ratios for seed in range(args.seeds)]
        cases = run_jobs(jobs, args.jobs, args.json)
        report_power(cases, ratios)
        print(f"total {time.perf_counter() - t_start:.0f} s; records of {args.n} samples")
        if args.json:
            Path(args.json).write_text(json.dumps(cases, indent=1, default=float))
        return 0
    jobs = scorecard_jobs(args)
    cases = run_jobs(jobs if args.first is None else jobs[:args.first], args.jobs, args.json)
    report(cases)
    print(f"total {time.perf_counter() - t_start:.0f} s; records of {args.n} samples, {args.jobs} process(es)")
    if args.json:
        Path(args.json).write_text(json.dumps(cases, indent=1, default=float))
    return 0


def report_power(cases: list[dict], ratios: list[float]) -> None:
    """Named-first rate per effect and snr ratio; a wrong first name counted apart."""
    print("\npower curve: hidden effect named first [another effect named first, + nL: its look-alike], "
          "by snr / MIN_SNR")
    print(f"  {'':13s} {'effect':26s} " + " ".join(f"{'× ' + format(r, 'g'):>14s}" for r in ratios))
    by = defaultdict(list)
    for c in cases:
        by[(c["kind"], c["hidden"][0])].append(c)

    def cell(cs):
        if not cs:
            return f"{'—':>14s}"
        eid = cs[0]["hidden"][0]
        k = sum(c["first"] == eid for c in cs)
        look = sum(c["first"] in CATALOGUE.look_alikes(eid) for c in cs)
        wrong = sum(c["first"] not in (None, eid) for c in cs) - look
        return f"{f'{k}/{len(cs)} [{wrong}' + (f'+{look}L' if look else '') + ']':>14s}"
    for (kind, eid), cs in by.items():
        print(f"  {kind:13s} {eid:26s} " + " ".join(cell([c for c in cs if c["ratio"] == r]) for r in ratios))

    def named_first(r: float) -> str:
        sel = [c for c in cases if c["ratio"] == r]
        return _pct(sum(c["first"] == c["hidden"][0] for c in sel), len(sel))
    print(f"  {'all':13s} {'':26s} " + " ".join(f"{named_first(r):>14s}" for r in ratios))
    for r in ratios:
        sel = [c for c in cases if c["ratio"] == r]
        wrong = [c for c in sel if c["first"] not in (None, c["hidden"][0])]
        look = sum(c["first"] in CATALOGUE.look_alikes(c["hidden"][0]) for c in wrong)
        print(f"  × {r:g}: named first {_pct(sum(c['first'] == c['hidden'][0] for c in sel), len(sel))}, "
              f"a wrong first name {_pct(len(wrong), len(sel))} (its look-alike in {look})")


def _singles_table(singles: list[dict], title: str) -> None:
    print(f"\n{title} (kind: named first | main parameter within 2 std | final gap ≤ 1.1 | only it named)")
    by = defaultdict(list)
    for c in singles:
        by[(c["kind"], c["hidden"][0])].append(c)
    for (kind, eid), cs in by.items():
        first = sum(c["first"] == eid for c in cs)
        rec = sum(bool(c["recovered"]) for c in cs)
        gap = sum(c["gap_final"] <= 1.1 for c in cs)
        only = sum(c["named"] == [eid] for c in cs)
        print(f"  {kind:13s} {eid:26s} {_pct(first, len(cs))}  {_pct(rec, first)}  {_pct(gap, len(cs))}"
              f"  {_pct(only, len(cs))}")


def _open_ok(c: dict) -> bool:
    """An out-of-catalogue record answered honestly: nothing named but the look-alikes the shape is
    sized against (``allowed``: the part of the shape they are), and unexplained structure reported."""
    return set(c["named"]) <= set(c.get("allowed", ())) and bool(c["unexplained"])


def report(cases: list[dict]) -> None:
    def rows(row: str, gen: str | None = None) -> list[dict]:
        return [c for c in cases if c["row"] == row and (gen is None or c["generator"] == gen)]
    singles, ind = rows("single", "catalogue"), rows("single", "independent")
    pairs, triples, opens = rows("pair"), rows("triple"), rows("open")
    clean, clean_ind = rows("clean", "catalogue"), rows("clean", "independent")
    _singles_table(singles, "per effect, catalogue draws")
    _singles_table(ind, "per effect, independent generator")
    print("\nout-of-catalogue (kind, shape: nothing named and unexplained structure | found where it is)")
    by = defaultdict(list)
    for c in opens:
        by[(c["kind"], c["shape"])].append(c)
    for (kind, shape), cs in by.items():
        ok = sum(_open_ok(c) for c in cs)
        print(f"  {kind:13s} {shape:14s} {_pct(ok, len(cs))}  {_pct(sum(c['found_where'] for c in cs), len(cs))}"
              f"  named: {dict(Counter(e for c in cs for e in c['named']))}"
              f"  doubted: {dict(Counter(e for c in cs for e in c.get('doubted', ())))}")

    def first_rate(cs: list[dict]) -> tuple[int, int]:
        return sum(c["first"] == c["hidden"][0] for c in cs), len(cs)

    def all_named(cs: list[dict]) -> tuple[int, int]:
        return sum(set(c["hidden"]) == set(c["named"]) and len(c["named"]) == len(c["hidden"]) for c in cs), len(cs)
    f1, n1 = first_rate(singles)
    fi, ni = first_rate(ind)
    new1 = first_rate([c for c in singles if c["hidden"][0] in NEW_EFFECTS])
    newi = first_rate([c for c in ind if c["hidden"][0] in NEW_EFFECTS])
    only1 = sum(c["named"] == c["hidden"] for c in singles)
    rec1 = sum(bool(c["recovered"]) for c in singles)
    gap1 = sum(c["gap_final"] <= 1.1 for c in singles if c["first"] == c["hidden"][0])
    open_ok = sum(_open_ok(c) for c in opens)
    open_where = sum(c["found_where"] for c in opens)
    clean_ok = sum(not c["named"] for c in clean)
    clean_ind_ok = sum(not c["named"] for c in clean_ind)
    table = [
        ("hidden effect named first (catalogue draws)", _pct(f1, n1), "≥ 90 %"),
        ("… of issue 15's new effects", _pct(*new1), "≥ 90 %"),
        ("… and nothing else named", _pct(only1, n1), ""),
        ("its main parameter within 2 stated standard errors", _pct(rec1, f1), ""),
        ("final gap within 10 % of the noise floor", _pct(gap1, f1), ""),
        ("independent generator: named first", _pct(fi, ni), "within 5 points of the draws'"),
        ("… of issue 15's new effects", _pct(*newi), ""),
        ("both effects of a hidden pair named, nothing else", _pct(*all_named(pairs)), "≥ 80 %"),
        ("all three of a hidden triple named, nothing else", _pct(*all_named(triples)), "≥ 80 %"),
        ("clean record: nothing named (catalogue noise)", _pct(clean_ok, len(clean)), "≥ 95 %"),
        ("clean record: nothing named (independent generator)", _pct(clean_ind_ok, len(clean_ind)), "≥ 95 %"),
        ("out of catalogue: nothing named but its look-alike, unexplained structure reported",
         _pct(open_ok, len(opens)), "≥ 95 %"),
        ("… and found where it is", _pct(open_where, len(opens)), ""),
    ]
    print("\n| | measured | target |\n|---|---|---|")
    for name, got, target in table:
        print(f"| {name} | {got} | {target} |")
    if n1 and ni:
        print(f"\nindependent − catalogue named-first: {100 * (fi / ni - f1 / n1):+.1f} points")
    for label, cs in (("triples", triples), ("pairs", pairs)):
        bad = [c for c in cs if not (set(c["hidden"]) == set(c["named"]) and len(c["named"]) == len(c["hidden"]))]
        for c in bad:
            print(f"  {label} miss: {c['kind']} {'+'.join(c['hidden'])} → {c['named']}")
    print("\nconfusion (hidden → first named: count), catalogue draws | independent generator")
    for gen_cases in (singles, ind):
        conf: defaultdict[str, Counter[str]] = defaultdict(Counter)
        for c in gen_cases:
            conf[c["hidden"][0]][c["first"] or "nothing"] += 1
        for eid, cnt in conf.items():
            if cnt.get(eid, 0) != sum(cnt.values()):
                print(f"  {eid:26s} " + ", ".join(f"{k}: {v}" for k, v in cnt.most_common()))
        print("  --")


if __name__ == "__main__":
    sys.exit(main())
