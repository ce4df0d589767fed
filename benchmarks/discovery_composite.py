"""Composite gyro noise at three grades through `bench discover`'s noise model: what is recovered.

Each record is a static gyro's rate output drawn here: white noise + a Gauss–Markov + flicker
(bias instability B) + a rate random walk, and for the MEMS grade readings on the output's
16-bit lattice — the processes realised by the catalogue's own ``noise`` (its state-space
draws), the white noise and the rounding with numpy. Levels per grade, in the customary units:

==========  ==================  ===========  =======  ========  ===================  =========
grade       record              N (°/√h)     B (°/h)  K (°/h/√h) Gauss–Markov         lattice
==========  ==================  ===========  =======  ========  ===================  =========
MEMS        20 min at 100 Hz    0.3          10       21.6      0.01 °/s, 5 s         0.0076 °/s
tactical    1 h at 10 Hz        0.05         0.5      0.22      1e-4 °/s, 30 s        —
navigation  10 h at 1 Hz        0.003        0.005    0.022     5e-6 °/s, 300 s       —
==========  ==================  ===========  =======  ========  ===================  =========

Each record goes through ``bench analyze allan --model``'s estimator (``noise_model``: discover
over the random processes, the quantizer and a drift, at the false-name rate 0.05), and the
script prints per grade: the processes named (doubted ones marked), N against the truth, and
where the model's Allan deviation leaves the data's 95 % interval. The issue's goal is the
composite recovered as a whole; this measures how far from it the estimator is.

    .venv/bin/python benchmarks/discovery_composite.py [--seeds 2] [--json FILE]

No peer names noise processes on these records; the figures stand alone (docs/RESULTS.md).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from typing import cast

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

from bench.analysis.allan import overlapping_adev
from bench.app.commands.analyze_allan import noise_model
from bench.discovery.data import Record
from bench.discovery.effects import CATALOGUE
from bench.discovery.effects_noise import StochasticEffect

#: °/h → °/s and °/h/√h → °/s/√s
PER_H, PER_H_SQRT_H = 1.0 / 3600.0, 1.0 / (3600.0 * 60.0)
#: grade: (rate Hz, samples, N °/√h, B °/h, K °/h/√h, GM σ °/s, GM τ s, lattice °/s or 0)
GRADES = {
    "mems": (100.0, 120_000, 0.3, 10.0, 21.6, 0.01, 5.0, 250.0 / 32768),
    "tactical": (10.0, 36_000, 0.05, 0.5, 0.22, 1e-4, 30.0, 0.0),
    "navigation": (1.0, 36_000, 0.003, 0.005, 0.022, 5e-6, 300.0, 0.0),
}


def draw(grade: str, seed: int) -> tuple[np.ndarray, np.ndarray, dict]:
    """(t s, rate °/s, the truth) of one record of ``grade``."""
    rate, n, n_arw, b, k, sigma, tau, step = GRADES[grade]
    rng = np.random.default_rng([48, seed, list(GRADES).index(grade)])
    t = np.arange(n) / rate
    rec = Record(t_s=t, y=np.zeros(n))
    white = n_arw / 60.0 * math.sqrt(rate)  # °/√h → °/√s, per sample
    truth = {"gauss_markov": {"sigma": sigma, "tau_s": tau},
             "flicker_noise": {"b": b * PER_H, "tau_min_s": 1.0 / rate},
             "rate_random_walk": {"k_per_rs": k * PER_H_SQRT_H}}
    y = white * rng.standard_normal(n)
    for eid, p in truth.items():
        y = y + cast(StochasticEffect, CATALOGUE[eid]).noise(p, rec, rng)
    if step:
        y = np.round(y / step) * step
    return t, y, {"white_per_sample": white, "N": n_arw, "lattice": step, **truth}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=2, help="records per grade [2]")
    ap.add_argument("--json", default=None, help="write the rows to this file")
    args = ap.parse_args(argv)
    if args.seeds < 1:
        ap.error(f"--seeds {args.seeds}; allowed: ≥ 1")
    rows = []
    t_all = time.perf_counter()
    for grade, spec in GRADES.items():
        for seed in range(args.seeds):
            t, y, truth = draw(grade, seed)
            res = overlapping_adev(y, spec[0], data_type="rate", unit="dps", confidence=0.95)
            t0 = time.perf_counter()
            nm = noise_model(t, y, spec[0], "dps", res, 0.05,
                             progress=lambda m: print(f"  {m}", file=sys.stderr, flush=True))
            named = [e["id"] + (" (doubted)" if e.get("doubt") else "") for e in nm["effects"]]
            row = {"grade": grade, "seed": seed, "named": named, "N": nm["terms"]["N"]["value"],
                   "N_true": truth["N"], "inside": nm["within"], "taus": nm["taus"], "outside": nm["outside"],
                   "seconds": time.perf_counter() - t0}
            rows.append(row)
            outside = ("; outside at " + ", ".join(f"{a:.3g} s ({s})" for a, s in row["outside"])
                       if row["outside"] else "")
            print(f"{grade:10s} seed {seed}: named {', '.join(named) or 'nothing'}; N {row['N']:.4g} °/√h "
                  f"(true {truth['N']:g}); Allan deviation inside the 95 % interval at {row['inside']}/{row['taus']} "
                  f"τ{outside} ({row['seconds']:.1f} s)", flush=True)
    print(f"truth in every record: Gauss–Markov, flicker, rate random walk (and the lattice on MEMS); "
          f"{time.perf_counter() - t_all:.0f} s in all")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump(rows, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
