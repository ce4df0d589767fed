"""Scorecard of the discrepancy workflow (issue 7) on data with hidden effects.

For each sensor kind and each catalogue effect that applies to it, ``--seeds`` records of the
kind's experiment (:func:`bench.discovery.experiments.make_experiment`, ``--n`` samples) are
simulated with a base model (bias, scale factor, the kind's white noise) plus the effect with
parameters drawn by ``Effect.draw`` (physical range, detectable on that record); the workflow
starts from the bare base model. Reported:

* named first: the first effect named is the hidden one (target ≥ 90 %); "named first and
  nothing else": it is the only effect named; spurious extras: effects named beyond the hidden one;
* recovered: its main parameter within 2 stated standard errors of the truth (≈ 95 % if the
  stated uncertainty is right);
* gap ≤ 1.1: final residual rms within 10 % of the model's noise rms (target: all);
* pairs: two effects hidden at once, both named AND nothing else named (target ≥ 80 %);
* clean: no effect hidden, nothing named (target ≥ 95 %);
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
``--report-power FILE``: print the power-curve table again from a ``--json`` file.

Run: ``.venv/bin/python benchmarks/discovery_scorecard.py [--kinds accelerometer,gyro,mhd]
[--seeds 5] [--pairs 10] [--clean 20] [--n 3000] [--json FILE]``. There is no peer library
that names effects, so the figures stand alone (targets from the issue beside them).
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
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.discovery.effects import CATALOGUE
from bench.discovery.effects_base import DEFAULT_NOISE_SD, MIN_SNR
from bench.discovery.experiments import make_experiment
from bench.discovery.model import BaseModel, Model, base_model
from bench.discovery.workflow import discover

BASE_BIAS = {"accelerometer": 2e-3, "gyro": 0.05, "mhd": 0.5}


def hidden_case(kind: str, effects: tuple[str, ...], seed: int, n: int, at_snr: float | None = None):
    """(record, truth model, snr of each effect) or None when an effect cannot be drawn on
    this record (not detectable; with ``at_snr``: that snr outside its physical range)."""
    salt = [] if at_snr is None else [int(round(1000 * at_snr))]
    rng = np.random.default_rng([seed, len(effects), *[list(CATALOGUE).index(e) for e in effects], *salt])
    rec = make_experiment(kind, rng, n=n)
    sd = DEFAULT_NOISE_SD[kind]
    truth = Model(BaseModel(kind=kind, bias=BASE_BIAS[kind] * rng.uniform(-1, 1),
                            scale_factor=1.0 + rng.normal(0, 2e-3), noise_sd=sd))
    snrs = []
    # an output-stage effect (clipping, rounding) acts on bias + SF·input: drawn and sized there
    on_output = rec.replace(input=truth.base.bias + truth.base.scale_factor * rec.column("input"))
    for eid in effects:
        eff = CATALOGUE[eid]
        where = on_output if eff.stage == "output" else rec
        try:
            p = eff.draw(rng, where, kind=kind, noise_sd=sd, at_snr=at_snr)
        except ValueError:
            return None
        snrs.append(float(eff.snr(p, where, sd)))
        truth = truth.with_effect(eid, p)
    return rec.replace(y=truth.simulate(rec, rng)), truth, snrs


def run_case(kind: str, effects: tuple[str, ...], seed: int, n: int,
             at_snr: float | None = None) -> dict | None:
    case = hidden_case(kind, effects, seed, n, at_snr)
    if case is None:
        return None
    rec, truth, snrs = case
    t0 = time.perf_counter()
    d = discover(rec, Model(base_model(kind)), max_effects=max(2, len(effects) + 1), seed=seed)
    named = [s.effect_id for s in d.steps]
    out = {"kind": kind, "hidden": list(effects), "seed": seed, "named": named,
           "first": named[0] if named else None, "gap_final": d.gap_final.rms_ratio,
           "unexplained": list(d.unexplained), "seconds": time.perf_counter() - t0, "recovered": None,
           "snr_ratio": [x / MIN_SNR for x in snrs]}
    if effects and named and named[0] == effects[0]:
        main = CATALOGUE[effects[0]].main_param
        true_v = truth.effects[0][1][main]
        got, sd = d.steps[0].params[main], d.steps[0].params_std[main]
        out.update(true=true_v, fit=got, fit_std=sd,
                   recovered=bool(np.isfinite(sd) and abs(got - true_v) <= 2 * sd))
    return out


def _pct(k: int, n: int) -> str:
    return f"{100 * k / n:5.1f} % ({k}/{n})" if n else "   —"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kinds", default="accelerometer,gyro,mhd")
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--pairs", type=int, default=10, help="pair cases per kind")
    ap.add_argument("--clean", type=int, default=20, help="clean cases per kind")
    ap.add_argument("--n", type=int, default=3000, help="samples per record")
    ap.add_argument("--effects", default=None, help="comma-separated subset of effect ids")
    ap.add_argument("--json", default=None, help="write every case's outcome here")
    ap.add_argument("--power", default=None,
                    help="comma-separated snr ratios (× MIN_SNR): the power curve instead of the scorecard")
    ap.add_argument("--report-power", default=None, metavar="FILE",
                    help="print the power-curve table from a --power --json file and stop")
    args = ap.parse_args(argv)
    if args.report_power is not None:
        cases = json.loads(Path(args.report_power).read_text())
        report_power(cases, sorted({c["ratio"] for c in cases}))
        return 0
    cases = []
    t_start = time.perf_counter()
    if args.power is not None:
        try:
            ratios = [float(v) for v in args.power.split(",")]
        except ValueError:
            ap.error(f"--power {args.power!r}: expected comma-separated positive numbers, e.g. 0.5,1,2")
        if not all(np.isfinite(r) and r > 0 for r in ratios):
            ap.error(f"--power {args.power!r}: every ratio must be > 0")
        cases = power_curve(args, ratios)
        report_power(cases, ratios)
        print(f"total {time.perf_counter() - t_start:.0f} s; records of {args.n} samples")
        if args.json:
            Path(args.json).write_text(json.dumps(cases, indent=1, default=float))
        return 0
    for kind in args.kinds.split(","):
        ids = effect_ids(kind, args.effects)
        for eid in ids:
            for seed in range(args.seeds):
                c = run_case(kind, (eid,), seed, args.n)
                if c is None:
                    print(f"{kind:13s} {eid:26s} seed {seed}: not detectable on this record (skipped)", flush=True)
                    continue
                cases.append(c)
                mark = "ok " if c["named"] == [eid] else "xtra" if c["first"] == eid else "MISS"
                print(f"{kind:13s} {eid:26s} seed {seed}: {mark} named {c['named']} gap {c['gap_final']:.3f} "
                      f"recovered {c['recovered']} ({c['seconds']:.1f} s)", flush=True)
        rng = np.random.default_rng(12345)
        det = [e for e in ids if not CATALOGUE[e].stochastic]
        for k in range(args.pairs if len(det) >= 2 else 0):
            pair = tuple(rng.choice(det, 2, replace=False))
            c = run_case(kind, pair, 1000 + k, args.n)
            if c is None:
                continue
            cases.append(c)
            mark = "ok " if set(c["named"]) == set(pair) and len(c["named"]) == 2 else "MISS"
            print(f"{kind:13s} pair {'+'.join(pair):40s}: {mark} named {c['named']}", flush=True)
        for k in range(args.clean):
            c = run_case(kind, (), 2000 + k, args.n)
            if c is None:  # nothing to draw: a clean case always runs
                continue
            cases.append(c)
            print(f"{kind:13s} clean seed {2000 + k}: named {c['named']} unexplained {len(c['unexplained'])}",
                  flush=True)
    report(cases)
    print(f"total {time.perf_counter() - t_start:.0f} s; records of {args.n} samples")
    if args.json:
        Path(args.json).write_text(json.dumps(cases, indent=1, default=float))
    return 0


def effect_ids(kind: str, subset: str | None) -> list[str]:
    """Catalogue effects of ``kind``, restricted to the comma-separated ``subset`` if given."""
    return [e for e, eff in CATALOGUE.items() if kind in eff.kinds
            and (subset is None or e in subset.split(","))]


def power_curve(args, ratios: list[float]) -> list[dict]:
    cases = []
    for kind in args.kinds.split(","):
        ids = effect_ids(kind, args.effects)
        for eid in ids:
            for ratio in ratios:
                for seed in range(args.seeds):
                    c = run_case(kind, (eid,), seed, args.n, at_snr=ratio * MIN_SNR)
                    if c is None:
                        print(f"{kind:13s} {eid:26s} × {ratio:g} seed {seed}: outside the physical range "
                              "(skipped)", flush=True)
                        continue
                    c["ratio"] = ratio
                    cases.append(c)
                    print(f"{kind:13s} {eid:26s} × {ratio:g} (snr {c['snr_ratio'][0]:.2f}×) seed {seed}: "
                          f"named {c['named']} ({c['seconds']:.1f} s)", flush=True)
    return cases


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


def report(cases: list[dict]) -> None:
    singles = [c for c in cases if len(c["hidden"]) == 1]
    pairs = [c for c in cases if len(c["hidden"]) == 2]
    clean = [c for c in cases if not c["hidden"]]
    print("\nper effect (kind: named first | main parameter within 2 std | final gap ≤ 1.1 | only it named)")
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
    n1 = len(singles)
    f1 = sum(c["first"] == c["hidden"][0] for c in singles)
    print(f"\nnamed first, all single-effect cases: {_pct(f1, n1)}   (target ≥ 90 %)")
    only = sum(c["named"] == c["hidden"] for c in singles)
    print(f"named first and nothing else: {_pct(only, n1)}")
    extra = [c for c in singles if len(c["named"]) > 1 or (c["named"] and c["named"][0] != c["hidden"][0])]
    n_extra = sum(len([e for e in c["named"] if e != c["hidden"][0]]) for c in singles)
    print(f"single-effect cases with spurious extra effects: {len(extra)}/{n1} ({n_extra} spurious effects named)")
    rc = sum(bool(c["recovered"]) for c in singles)
    print(f"main parameter within 2 std (of correctly named): {_pct(rc, f1)}")
    g = sum(c["gap_final"] <= 1.1 for c in singles if c["first"] == c["hidden"][0])
    print(f"final gap within 10 % of the noise floor (correctly named): {_pct(g, f1)}")
    both = sum(set(c["hidden"]) == set(c["named"]) and len(c["named"]) == 2 for c in pairs)
    print(f"pairs, both named and nothing else: {_pct(both, len(pairs))}   (target ≥ 80 %)")
    sub = sum(set(c["hidden"]) <= set(c["named"]) for c in pairs)
    print(f"pairs, both named (extras allowed): {_pct(sub, len(pairs))}; "
          f"with spurious extras: {sum(bool(set(c['named']) - set(c['hidden'])) for c in pairs)}/{len(pairs)}")
    none = sum(not c["named"] for c in clean)
    print(f"clean data, nothing named: {_pct(none, len(clean))}   (target ≥ 95 %)")
    print("\nconfusion (hidden → first named: count)")
    conf: defaultdict[str, Counter[str]] = defaultdict(Counter)
    for c in singles:
        conf[c["hidden"][0]][c["first"] or "nothing"] += 1
    for eid, cnt in conf.items():
        print(f"  {eid:26s} " + ", ".join(f"{k}: {v}" for k, v in cnt.most_common()))


if __name__ == "__main__":
    sys.exit(main())
