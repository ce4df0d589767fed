"""A random process is named only if it is that process (:mod:`bench.discovery.adequacy`).

Properties, each a count over fixed seeds against a stated rate
(:func:`bench.testing.discovery_nulls.binomial_allowance`: a correct method fails it with
probability ≤ 0.1 %) or a share the method is held to:

- the smoother's disturbances are the model's: under the catalogue's own processes at their
  values they have unit spread once standardized by the smoother's own variance — checked
  against a dense reference implementation of the same recursions;
- **size**: records realised from the catalogue's processes (Gauss–Markov, flicker, rate random
  walk, angle noise; Gaussian and Student-t white) doubt the process that made them at most at
  the stated rate α;
- **power**: random telegraph noise with steps seen on the trace, and tone bursts, fitted by the
  Gauss–Markov of the best exact likelihood, are doubted in ≥ 80 % of records;
- the workflow carries a doubt through: the process stays in the model, is not named, and the
  reason is unexplained structure (``Discovery.named``, ``Step.doubt``, the CLI summary).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import cast

import numpy as np
import pytest

from bench.app.commands.discover import summary
from bench.app.reports.discovery_report import write_discovery_report
from bench.discovery import stochastic as sto
from bench.discovery.adequacy import N_STATISTICS, process_doubts, reps_for
from bench.discovery.criterion import FALSE_NAME_RATE
from bench.discovery.data import Record
from bench.discovery.effects import CATALOGUE
from bench.discovery.effects_base import DEFAULT_NOISE_SD
from bench.discovery.effects_noise import StochasticEffect
from bench.discovery.experiments import make_experiment
from bench.discovery.model import Model, base_model
from bench.discovery.whiten import state_space
from bench.discovery.workflow import discover
from bench.testing.discovery_nulls import binomial_allowance
from bench.testing.generators.discovery_shapes import telegraph_levels

KIND = "gyro"
SD = DEFAULT_NOISE_SD[KIND]
#: samples per record (10 Hz: 2.5 minutes)
N = 1500
GM = CATALOGUE["gauss_markov"]
LEVEL = FALSE_NAME_RATE / N_STATISTICS
#: share of records a power property must hold in
RECOVERY_SHARE = 0.8


def _record(rng: np.random.Generator) -> Record:
    return make_experiment(KIND, rng, n=N)


def _start() -> Model:
    return Model(base_model(KIND)).with_base(noise_sd=SD)


def _dense_disturbances(y: np.ndarray, f, q, h, p0, r_var) -> tuple[np.ndarray, np.ndarray]:
    """The same smoother written with whole matrices: (h·Q·r_k, h·Q·N_k·Q·hᵀ) per sample; a NaN
    reading is not observed."""
    n, m = y.size, h.size
    x, p = np.zeros(m), p0.copy()
    v, s, gain = np.zeros(n), np.ones(n), np.zeros((n, m))
    for k in range(n):
        if k:
            x, p = f @ x, f @ p @ f.T + q
        s[k] = h @ p @ h + r_var
        if np.isnan(y[k]):  # not observed: no update, no term below
            s[k] = np.inf
            continue
        gain[k] = p @ h / s[k]
        v[k] = y[k] - h @ x
        x, p = x + gain[k] * v[k], p - np.outer(gain[k], h @ p)
    r, nn = np.zeros(m), np.zeros((m, m))
    out, var = np.zeros(n), np.zeros(n)
    for k in range(n - 1, -1, -1):
        ell = np.eye(m) - np.outer(gain[k], h)
        rk = h * v[k] / s[k] + ell.T @ r
        nk = np.outer(h, h) / s[k] + ell.T @ nn @ ell
        out[k], var[k] = h @ q @ rk, h @ q @ nk @ q @ h
        r, nn = f.T @ rk, f.T @ nk @ f
    return out, var


@pytest.mark.parametrize("eid", ["gauss_markov", "flicker_noise", "rate_random_walk"])
def test_the_smoothed_disturbances_are_the_dense_recursions_and_have_unit_standardized_spread(eid):
    rng = np.random.default_rng([36, 7, list(CATALOGUE).index(eid)])
    rec = _record(rng)
    p = CATALOGUE[eid].draw(rng, rec, kind=KIND, noise_sd=SD)
    ss = state_space(rec.rate_hz, N, [(CATALOGUE[eid], p)])
    y = ss.simulate(rng, N) + SD * rng.standard_normal(N)
    y[rng.choice(N, 15, replace=False)] = np.nan  # samples set aside: missing to the filter
    fast = ss.smoothed_disturbances(y, SD * SD)[:, 0]
    slow, var = _dense_disturbances(y, ss.f, ss.q, ss.h, ss.p0, SD * SD)
    assert np.allclose(fast, slow, rtol=1e-9, atol=1e-12 * float(np.max(np.abs(slow))))
    z = slow[1:] / np.sqrt(var[1:])
    # unit variance within what its autocorrelated samples allow (4 standard errors at N/10)
    assert abs(float(np.mean(z * z)) - 1.0) < 4 * math.sqrt(2 / (N / 10))


def test_reps_make_the_least_p_value_half_the_level():
    for level in (0.05, 0.0125, 0.003):
        r = reps_for(level)
        assert 1 / (r + 1) <= level / 2 < 1 / r
    with pytest.raises(ValueError, match="level"):
        reps_for(0.0)


NULL_PROCESSES = ("gauss_markov", "flicker_noise", "rate_random_walk", "angle_quantization")
#: records per null process (Gaussian white) and for a Gauss–Markov under Student-t white (ν = 4)
NULL_RECORDS = 12


def doubted_nulls(records: int, first_seed: int = 0) -> tuple[list[tuple], int]:
    """Records realised from each null case's process at its drawn values, ``records`` per case:
    (the doubted ones as (effect, ν, seed, description), the records tested)."""
    doubted, total = [], 0
    cases = [(eid, None) for eid in NULL_PROCESSES] + [("gauss_markov", 4.0)]
    for i, (eid, nu) in enumerate(cases):
        for seed in range(first_seed, first_seed + records):
            rng = np.random.default_rng([36, 11, i, seed])
            rec = _record(rng)
            eff = cast(StochasticEffect, CATALOGUE[eid])
            p = eff.draw(rng, rec, kind=KIND, noise_sd=SD)
            model = _start().with_effect(eid, p)
            ss = state_space(rec.rate_hz, N, [(eff, p)])
            w = rng.standard_normal(N) if nu is None else rng.standard_t(nu, N) * math.sqrt((nu - 2) / nu)
            rec = rec.replace(y=model.predict(rec) + ss.simulate(rng, N) + SD * w)
            got = process_doubts(model, rec, None, (eid,), level=LEVEL, nu=math.inf if nu is None else nu,
                                 seed=seed)
            total += 1
            if got:
                doubted.append((eid, nu, seed, got[eid].describe()))
    return doubted, total


def test_a_process_that_is_what_it_is_named_is_doubted_at_most_at_the_stated_rate():
    doubted, total = doubted_nulls(NULL_RECORDS)
    assert len(doubted) <= binomial_allowance(total, FALSE_NAME_RATE), doubted


def _fitted_gm(rec: Record, extra: np.ndarray, rng: np.random.Generator) -> tuple[Model, np.ndarray]:
    """The record with ``extra`` in white noise, and the Gauss–Markov of the best exact likelihood
    for it (what the search would weigh)."""
    y = extra + SD * rng.standard_normal(N)
    lag1 = float(np.corrcoef(extra[:-1], extra[1:])[0, 1])
    start = {"sigma": float(np.std(extra)), "tau_s": -rec.dt_s / math.log(min(max(lag1, 0.05), 0.999))}
    p, white, _ = sto.exact_fit(y - y.mean(), rec.dt_s, GM, start, SD)
    return _start().with_base(noise_sd=white).with_effect(GM.id, p), y


def _telegraph(rng: np.random.Generator) -> np.ndarray:
    """Steps between ±A (A 2–4 white sd: seen on the trace) at 20–60 instants drawn uniformly."""
    at = np.sort(rng.choice(np.arange(1, N), int(rng.integers(20, 61)), replace=False))
    level = telegraph_levels(at, N)
    return SD * rng.uniform(2.0, 4.0) * level


def _bursts(rng: np.random.Generator, rec: Record) -> np.ndarray:
    """Three bursts of a tone (40–100 cycles over the record), each 5 % of it, amplitude 2–4 sd."""
    t = rec.t_s - rec.t_s[0]
    span = float(t[-1])
    env = np.zeros(N)
    for s in rng.choice(np.linspace(0.05, 0.85, 17), 3, replace=False) * span:
        env[(t >= s) & (t < s + 0.05 * span)] = 1.0
    return SD * rng.uniform(2.0, 4.0) * env * np.sin(2 * np.pi * rng.uniform(40, 100) / span * t)


POWER_RECORDS = 10


def doubted_shapes(shape: str, records: int, first_seed: int = 0) -> int:
    """Records of ``shape`` in white noise, each fitted by its best Gauss–Markov, that doubt it."""
    doubted = 0
    for seed in range(first_seed, first_seed + records):
        rng = np.random.default_rng([36, 12, seed])
        rec = _record(rng)
        extra = _telegraph(rng) if shape == "telegraph" else _bursts(rng, rec)
        model, y = _fitted_gm(rec, extra, rng)
        rec = rec.replace(y=model.predict(rec) - model.predict(rec).mean() + y)
        doubted += bool(process_doubts(model, rec, None, (GM.id,), level=LEVEL, seed=seed))
    return doubted


@pytest.mark.parametrize("shape", ["telegraph", "bursts"])
def test_structure_with_a_gauss_markov_spectrum_that_is_not_one_is_doubted(shape):
    assert doubted_shapes(shape, POWER_RECORDS) >= RECOVERY_SHARE * POWER_RECORDS


#: records of the workflow test: telegraph noise of 30 steps of ±3 white sd (doubted in ≥ 80 %)
WORKFLOW_RECORDS = 2


def test_the_workflow_keeps_a_doubted_process_in_the_model_and_does_not_name_it(tmp_path):
    doubted = 0
    for seed in range(WORKFLOW_RECORDS):
        rng = np.random.default_rng([36, 13, seed])
        rec = _record(rng)
        at = np.sort(rng.choice(np.arange(1, N), 30, replace=False))
        steps = 3 * SD * telegraph_levels(at, N)
        rec = rec.replace(y=_start().predict(rec) + steps + SD * rng.standard_normal(N))
        d = discover(rec, _start(), max_effects=2, only=("gauss_markov", "flicker_noise", "rate_random_walk"))
        assert d.steps  # the structure lowers the criterion: some process stands for its spectrum
        assert {s.effect_id for s in d.steps} <= set(d.final_model.effect_ids)
        assert d.named == tuple(s.effect_id for s in d.steps if not s.doubt)
        for s in d.steps:
            if s.doubt:
                assert s.doubt in d.unexplained and "it jumps" in s.doubt
        js = d.to_dict()
        assert js["named"] == list(d.named)
        assert [bool(e["doubt"]) for e in js["effects"]] == [bool(s.doubt) for s in d.steps]
        text = summary(d, "telegraph", tmp_path / "m.toml", tmp_path / "r.html")
        assert ("nothing named" in text) == (not d.named)
        assert text.count("not named (doubted") == sum(bool(s.doubt) for s in d.steps)
        # a p-value below a double's range is printed as the bound it is
        floored = replace(d, steps=tuple(replace(s, p_value=0.0) for s in d.steps))
        assert summary(floored, "t", tmp_path / "m.toml", tmp_path / "r.html").count("p < 1e-300") == len(d.steps)
        page = write_discovery_report(d, rec, tmp_path / f"report{seed}", "telegraph", pdf=False).read_text("utf-8")
        assert page.count("In the model for its spectrum, not named: ") == sum(bool(s.doubt) for s in d.steps)
        assert page.count("<b>Named: ") == len(d.named)
        doubted += not d.named
    assert doubted >= 1


if __name__ == "__main__":  # the figures: python -m tests.discovery.test_discovery_adequacy [RECORDS]
    import sys
    import time

    records = int(sys.argv[1]) if len(sys.argv) > 1 else 100
    t0 = time.perf_counter()
    bad, total = doubted_nulls(records, first_seed=1000)
    by = {f"{e}{'' if nu is None else f' (Student-t ν = {nu:g})'}": 0 for e, nu in
          [(eid, None) for eid in NULL_PROCESSES] + [("gauss_markov", 4.0)]}
    for e, nu, _, _ in bad:
        by[f"{e}{'' if nu is None else f' (Student-t ν = {nu:g})'}"] += 1
    print(f"size: {len(bad)}/{total} records of the model's own process doubted (stated ≤ {FALSE_NAME_RATE:g}); "
          + ", ".join(f"{k} {v}/{records}" for k, v in by.items()))
    for shape in ("telegraph", "bursts"):
        print(f"power, {shape}: doubted {doubted_shapes(shape, records, first_seed=1000)}/{records}")
    print(f"{time.perf_counter() - t0:.0f} s ({N} samples a record)")
