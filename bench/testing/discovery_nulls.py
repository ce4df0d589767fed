"""Null and contaminated records for grading discovery's criterion and search as a method.

A **null** record holds nothing the catalogue could name: a kind's experiment stimulus
(``bench.discovery.experiments.make_experiment``), the kind's default base model, and white
observation noise of the kind's default sd — Gaussian, or Student-t with ν degrees of freedom
scaled to the same sd (a t variable has variance ν/(ν − 2)). Discovery's stated false-name rate
is the probability that such a record gets any name. :func:`with_spikes` adds isolated spikes
(a bad frame, an EMI hit) to readings. :func:`binomial_allowance` is the count a stated rate may
reach over N independent records before a test calls it exceeded.
"""

from __future__ import annotations

import numpy as np
from scipy.stats import binom

from bench.discovery.data import Record
from bench.discovery.effects_base import DEFAULT_NOISE_SD
from bench.discovery.experiments import make_experiment
from bench.discovery.model import Model, base_model

#: Quantile of the binomial count a test allows at a stated rate: a correct method fails such a
#: test with probability ≤ 0.1 % per assertion.
ALLOWANCE_QUANTILE = 0.999


def binomial_allowance(n: int, rate: float, q: float = ALLOWANCE_QUANTILE) -> int:
    """The largest count of events, each at ``rate``, that ``n`` independent trials reach with
    probability ≥ 1 − ``q``: ``binom.ppf(q, n, rate)``."""
    return int(binom.ppf(q, n, rate))


def white(kind: str, rng: np.random.Generator, n: int, nu: float | None = None) -> np.ndarray:
    """``n`` samples of white noise of the kind's default sd: Gaussian (``nu`` None) or
    Student-t with ``nu`` > 2 degrees of freedom, scaled to that sd."""
    sd = DEFAULT_NOISE_SD[kind]
    if nu is None:
        return rng.normal(0.0, sd, n)
    if not nu > 2:
        raise ValueError(f"nu = {nu!r}; allowed: > 2 (a finite variance)")
    return sd * np.sqrt((nu - 2.0) / nu) * rng.standard_t(nu, n)


def null_record(kind: str, seed: int, n: int, nu: float | None = None) -> tuple[Record, Model]:
    """(record, starting model): ``kind``'s experiment of ``n`` samples holding only white noise
    (:func:`white`) about the default base model's prediction; the same seed, the same record."""
    rng = np.random.default_rng([seed, n, 0 if nu is None else int(round(1000 * nu))])
    rec = make_experiment(kind, rng, n=n)
    model = Model(base_model(kind))
    return rec.replace(y=model.predict(rec) + white(kind, rng, n, nu)), model


def with_spikes(y: np.ndarray, rng: np.random.Generator, fraction: float, sd: float,
                size_sd: tuple[float, float] = (10.0, 50.0)) -> tuple[np.ndarray, np.ndarray]:
    """(readings with spikes, their indices): ``fraction`` of the samples, isolated (at least two
    clean samples between two spikes, none at either end), each of random sign and a size
    uniform in ``size_sd`` times ``sd``."""
    y = np.asarray(y, float)
    count = int(round(fraction * y.size))
    # one spike per cell of three samples keeps them isolated: at the cell's middle
    cells = rng.choice(np.arange(1, (y.size - 1) // 3), size=count, replace=False)
    at = np.sort(3 * cells + 1)
    out = y.copy()
    out[at] += rng.choice([-1.0, 1.0], size=count) * rng.uniform(*size_sd, size=count) * sd
    return out, at
