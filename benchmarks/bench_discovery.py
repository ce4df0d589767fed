"""Wall time of `bench discover`'s hot functions on a 180k-sample record, old code vs new; and
with ``--startup``, of the whole workflow on the station's 30-min start-up run (issue 15's goal:
≤ 30 s wall on 2 cores).

    .venv/bin/python benchmarks/bench_discovery.py [--n 180100] [--reps 999]
    .venv/bin/python benchmarks/bench_discovery.py --startup [--jobs N] [--reference]
    .venv/bin/python benchmarks/bench_discovery.py --static [--hours 3]

``--startup`` runs ``bench run startup`` (the simulated station, 180 000 samples) into a
temporary store, reads the run as ``bench discover --run latest`` does and times
``workflow.discover`` on it (calibration, every step, the audit; not the HTML report) with the
candidates fitted by ``--jobs`` worker processes as ``bench discover --jobs`` does (default: the
cores; BLAS one thread a process), printing each step's time, the effects named, the wall time,
the CPU time of this process and its workers, and the load average before and after.

``--reference`` times the same start-up record searched whole at full rate (the route before
long records were searched on two scales: block means and a full-rate window) beside the
two-scale route, and prints the ratio and both named models.

``--static`` writes a static MEMS-gyro record of ``--hours`` at 100 Hz (3 h: 1.08 M samples;
white 0.01 °/s, a Gauss–Markov 2e-3 °/s / 30 s, a rate random walk 2e-5 °/s/√s, readings on a
0.005 °/s lattice — drawn here with numpy, apart from the catalogue) to a CSV and runs the
command a user types, ``bench discover --measured FILE --sensor gyro --json``, at ``--jobs 1``
and ``--jobs 2``: wall time, CPU, the largest resident set of the command and its workers, the
progress lines on stderr, the JSON on stdout, and whether both named the same model (goal:
≤ 60 s wall and ≤ 2 GB).

Measured for issue 15 item 4 (2-core machine, load 0.4–1.4, four runs on 2026-11-27 13:19):
``--jobs 2`` 24.1–25.1 s wall, 41.5–43.4 s CPU in all (22.7–23.3 s at the previous stop, before
its naming changes); before the item 105 s wall and 127 s CPU at load 2.2.
Same steps (thermal_two_node, then gauss_markov, then nothing) and parameters before and after.
The ≤ 30 s wall goal is met; the README ("Where its time goes") says what remains.

The audit (issue 7, #11) profiled `bench discover` on a default start-up run (180,100 samples,
150 s wall): lattice.visibility 34 s in 3 quantization fits, LinearScorer.scores 32 s and
block_bootstrap 9 s in the bootstrap p-values. This times, on a record of that size,
``lattice.fit_lattice`` + ``lattice.heldout_score`` (the quantization candidate) and
``significance.bootstrap_p_value`` (one deterministic candidate's null, up to ``--reps``
replicates) with the current code and with the straightforward implementations they replaced
(``bench.testing.references.discovery``, the tests' references too), checks both give the same
numbers, and prints the times and the ratio. The reference "peer" here is our own old code.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np
from scipy.signal import lfilter

from bench.app.commands.discover import candidate_map, default_jobs
from bench.app.commands.discover_runs import read_run
from bench.discovery import lattice as lat
from bench.discovery import significance as sig
from bench.discovery import workflow as wf
from bench.discovery.model import Model, base_model
from bench.discovery.workflow import Discovery, discover
from bench.testing.references import discovery as ref


@contextmanager
def old_code():
    """Swap the reference implementations in for the duration of the block."""
    saved = lat.visibility, sig.LinearScorer, sig.block_bootstrap

    def visibility(y: np.ndarray, s: np.ndarray | float, *, cf: lat.CharFun | None = None) -> np.ndarray:
        return ref.visibility_reference(y, s)

    lat.visibility = visibility
    sig.LinearScorer = ref.LinearScorerReference
    sig.block_bootstrap = ref.block_bootstrap_reference
    try:
        yield
    finally:
        lat.visibility, sig.LinearScorer, sig.block_bootstrap = saved


def workload(n: int, reps: int) -> dict:
    rng = np.random.default_rng(7)
    rate_hz = 100.0
    t = np.arange(n) / rate_hz
    sd = 5e-6
    warm = 7e-5 * np.exp(-t / 160.0)
    y = 1e-3 + warm + sd * rng.standard_normal(n)  # a start-up record: bias, warm-up, white noise
    folds = sig.block_folds(n)
    out: dict[str, tuple[float, tuple[float, ...]]] = {}
    t0 = time.perf_counter()
    fit = lat.fit_lattice(y, sd, 1e-7, 1e-3)
    score = lat.heldout_score(y, sd, folds, 1e-7, 1e-3)
    out["quantization candidate"] = (time.perf_counter() - t0, (fit.step, fit.visibility, score))
    x_nuis = np.ones((n, 1))
    g = np.exp(-t / 150.0)
    x_cand = [np.column_stack([g, t * g / 150.0]), np.column_stack([g, t * g / 152.0])]
    r = y - y.mean()
    t0 = time.perf_counter()
    obs = float(sig.heldout_linear_scores(r, x_nuis, x_cand, folds)[0])
    # observed → 1e9 so every replicate is drawn: the full-length null of a significant candidate
    p = sig.bootstrap_p_value(r, x_nuis, x_cand, folds, 1e9, n_rep=reps, rng=np.random.default_rng(1))
    out["bootstrap p-value"] = (time.perf_counter() - t0, (obs, p))
    return out


def _tree_cpu_s() -> float:
    """CPU seconds (user + system) of this process and of every live process descended from it
    (the worker pool and its fork server), from /proc; this process's alone elsewhere."""
    own = time.process_time()
    proc = Path("/proc")
    if not proc.is_dir():
        return own
    parent, ticks = {}, {}
    for d in proc.iterdir():
        if not d.name.isdigit():
            continue
        try:
            fields = (d / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        parent[int(d.name)] = int(fields[1])
        ticks[int(d.name)] = int(fields[11]) + int(fields[12])
    me, total = os.getpid(), 0
    for pid in ticks:
        p = pid
        while p in parent and p != me and p > 1:
            p = parent[p]
        if p == me and pid != me:
            total += ticks[pid]
    return own + total / os.sysconf("SC_CLK_TCK")


def _timed(rec, kind: str, jobs: int) -> tuple[float, float, float, Discovery, list[tuple[float, str]]]:
    """(wall, CPU of this process, CPU in all, the Discovery, the progress marks) of one discover."""
    marks: list[tuple[float, str]] = []
    with candidate_map(jobs) as map_fn:
        t0, c0, cpu0 = time.perf_counter(), time.process_time(), _tree_cpu_s()

        def progress(msg: str) -> None:
            marks.append((time.perf_counter() - t0, msg))

        d = discover(rec, Model(base_model(kind)), progress=progress, map_fn=map_fn)
        return time.perf_counter() - t0, time.process_time() - c0, _tree_cpu_s() - cpu0, d, marks


def startup_run(jobs: int, reference: bool = False) -> int:
    """Time ``discover`` on a fresh 30-min start-up run of the simulated station, the candidates
    fitted by ``jobs`` worker processes (as ``bench discover --jobs``); with ``reference`` the
    same record searched whole at full rate too."""
    with tempfile.TemporaryDirectory() as tmp:
        store = str(Path(tmp) / "bench.sqlite")
        bench = Path(sys.executable).with_name("bench")
        t0 = time.perf_counter()
        subprocess.run([str(bench), "--store", store, "run", "startup"], check=True, stdout=subprocess.DEVNULL)
        t_run = time.perf_counter() - t0
        rec, kind, label = read_run(store, "latest", None)
    print(f"start-up run: {rec.n} samples at {rec.rate_hz:g} Hz ({kind}); `bench run startup` {t_run:.1f} s")
    routes = [("two scales", wf.SEARCH_POINTS)] + ([("whole record at full rate", rec.n)] if reference else [])
    walls = []
    for name, points in routes:
        saved, wf.SEARCH_POINTS = wf.SEARCH_POINTS, points
        load0 = os.getloadavg()[0]
        try:
            wall, cpu, cpu_all, d, marks = _timed(rec, kind, jobs)
        finally:
            wf.SEARCH_POINTS = saved
        walls.append(wall)
        print(f"{name}:")
        for t, msg in marks:
            if msg.startswith(("named", "done", "round")):
                print(f"  {t:7.1f} s  {msg}")
        for s in d.steps:
            print(f"  {s.effect_id}: "
                  + ", ".join(f"{k} = {v:.4g} ± {s.params_std[k]:.2g}" for k, v in s.params.items()))
        print(f"  named: {[s.effect_id for s in d.steps]}; unexplained: {len(d.unexplained)}")
        load = os.getloadavg()[0]
        print(f"  discover wall time {wall:.1f} s with --jobs {jobs}; CPU time {cpu_all:.1f} s in all ({cpu:.1f} s in "
              f"this process, the rest in the workers), on {os.cpu_count()} core(s) at load {load0:.1f} → {load:.1f} "
              "(1-min averages, this run included; goal ≤ 20 s wall on 2 cores; on a loaded machine the CPU time is "
              "the fairer figure)")
    if reference:
        print(f"whole record at full rate / two scales: {walls[1] / walls[0]:.1f}× the wall time")
    return 0


def static_record(path: Path, hours: float) -> int:
    """Write the ``--static`` record (module docstring) as CSV; its number of samples."""
    rate = 100.0
    n = int(round(hours * 3600 * rate))
    rng = np.random.default_rng(3)
    phi = np.exp(-1 / (rate * 30.0))
    gm = lfilter([1.0], [1.0, -phi], rng.standard_normal(n) * 2e-3 * np.sqrt(1 - phi ** 2))
    rrw = np.cumsum(rng.standard_normal(n)) * 2e-5 / np.sqrt(rate)
    y = 0.005 * np.round((0.3 + 0.01 * rng.standard_normal(n) + gm + rrw) / 0.005)
    np.savetxt(path, np.column_stack([np.arange(n) / rate, y]), fmt=["%.2f", "%.3f"], delimiter=",",
               header="t,y", comments="")
    return n


def static_run(hours: float) -> int:
    """Time ``bench discover --json`` on the ``--static`` record at --jobs 1 and 2."""
    bench = Path(sys.executable).with_name("bench")
    named = {}
    with tempfile.TemporaryDirectory() as tmp:
        csv = Path(tmp) / "static.csv"
        n = static_record(csv, hours)
        print(f"static MEMS-gyro record: {n} samples at 100 Hz ({hours:g} h), {csv.stat().st_size / 1e6:.0f} MB of CSV")
        for jobs in (1, 2):
            load0 = os.getloadavg()[0]
            r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
            t0 = time.perf_counter()
            done = subprocess.run([str(bench), "discover", "--measured", str(csv), "--sensor", "gyro", "--json",
                                   "--jobs", str(jobs), "--out", str(Path(tmp) / f"out{jobs}")],
                                  capture_output=True, text=True, env={**os.environ, "OPENBLAS_NUM_THREADS": "1"})
            wall = time.perf_counter() - t0
            r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
            if done.returncode != 0:
                print(done.stderr[-2000:])
                return 1
            result = json.loads(done.stdout)
            named[jobs] = [(e["id"], {k: round(v, 6) for k, v in e["params"].items()}) for e in result["effects"]]
            progress = [ln for ln in done.stderr.splitlines() if ln.strip()]
            cpu = (r1.ru_utime + r1.ru_stime) - (r0.ru_utime + r0.ru_stime)
            print(f"--jobs {jobs}: wall {wall:.1f} s (goal ≤ 60 s), CPU {cpu:.1f} s, largest resident set "
                  f"{r1.ru_maxrss / 1024:.0f} MB (goal ≤ 2048 MB; the command and its workers), load "
                  f"{load0:.1f} → {os.getloadavg()[0]:.1f}; {len(progress)} progress lines on stderr, JSON on stdout")
            for e in result["effects"]:
                print(f"    {e['id']} ({e.get('scale', 'record')}): "
                      + ", ".join(f"{k} = {v:.4g}" for k, v in e["params"].items()))
    print(f"same named model at --jobs 1 and 2: {named[1] == named[2]}")
    return 0 if named[1] == named[2] else 1


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=180100)
    ap.add_argument("--reps", type=int, default=999)
    ap.add_argument("--startup", action="store_true", help="time the whole workflow on a 30-min start-up run")
    ap.add_argument("--reference", action="store_true",
                    help="with --startup: also the record searched whole at full rate, and the ratio")
    ap.add_argument("--static", action="store_true",
                    help="time `bench discover --json` on a long static MEMS-gyro record (1 and 2 jobs)")
    ap.add_argument("--hours", type=float, default=3.0, help="with --static: the record's length [3]")
    ap.add_argument("--jobs", type=int, default=None,
                    help="with --startup: worker processes fitting the candidates [as bench discover: the cores]")
    a = ap.parse_args(argv)
    if a.static:
        return static_run(a.hours)
    if a.startup:
        return startup_run(default_jobs() if a.jobs is None else a.jobs, reference=a.reference)
    new = workload(a.n, a.reps)
    with old_code():
        old = workload(a.n, a.reps)
    print(f"n = {a.n} samples, {a.reps} bootstrap replicates")
    print(f"{'function':26s} {'old (s)':>9s} {'new (s)':>9s} {'ratio':>7s}  same result")
    tot_old = tot_new = 0.0
    for k in new:
        (to, ro), (tn, rn) = old[k], new[k]
        same = np.allclose(ro, rn, rtol=1e-9, atol=1e-12)
        print(f"{k:26s} {to:9.2f} {tn:9.2f} {to / tn:7.1f}  {same}  {rn}")
        tot_old, tot_new = tot_old + to, tot_new + tn
    print(f"{'total':26s} {tot_old:9.2f} {tot_new:9.2f} {tot_old / tot_new:7.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
