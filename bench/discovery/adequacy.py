"""Is a named random process the process it is named? Its driving noise, tested against the model.

A random process is named on its spectrum: the exact Gaussian likelihood weighs a record's
second moments and nothing more, so random telegraph (popcorn) noise, bursts of a tone, a sweep,
or steps in an unlogged input can win as a Gauss–Markov (a flicker, a walk, angle noise) whose
spectrum matches. What tells them apart is the process's own driving noise. Under the model its
smoothed disturbances — E[e_k | the whole record] of the block's state noise as it moves the
output (:meth:`.whiten.StateSpace.smoothed_disturbances`; the auxiliary residuals of Harvey &
Koopman 1992) — are a Gaussian series whose spectrum is the model's and whose spread does not
change along the record. Four statistics of that series are tested, each one-sided:

============== ========================================================================
kurtosis high  jumps between levels (telegraph noise) or steps: a few large disturbances
kurtosis low   a drive bounded like a waveform's (a triangle's constant slope)
segments       the dispersion of its mean square over :data:`SEGMENTS` stretches of the
               record: structure that comes and goes (bursts, a sweep's rising frequency)
peak           its largest periodogram ordinate over the model's mean periodogram there:
               a periodic drive
============== ========================================================================

Each statistic's distribution is the fitted model's own, by Monte Carlo: the model's white
noise (Student-t where the record's is heavy-tailed) and its processes realised on the record's
samples (the same samples missing), smoothed alike; the p-value is the rank of the record's
statistic among ``R`` realisations, (1 + #{null ≥ observed}) / (R + 1), exact for any R.
A process is doubted when a statistic's p-value is at most α / (4·P) (P the processes tested,
four statistics each: Bonferroni), so a process that is what it is named is doubted with
probability at most α. R is the smallest count whose least p-value is half that level
(:func:`reps_for`), so a departure beyond every realisation is always seen.

A doubted process stays in the model (its spectrum is what the record shows) but is not a name:
the structure is reported as unexplained, with what its driving noise showed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bench.discovery import stochastic as sto
from bench.discovery.data import Record
from bench.discovery.model import Model
from bench.discovery.whiten import seen_only, state_space

#: stretches of the record the segments statistic compares (as :func:`.localize.time_segments`)
SEGMENTS = 16
#: one-sided statistics per tested process
N_STATISTICS = 4


def reps_for(level: float) -> int:
    """Monte Carlo realisations R whose least p-value 1/(R + 1) is half ``level``."""
    if not 0 < level < 1:
        raise ValueError(f"level = {level!r}; allowed: (0, 1)")
    return math.ceil(2.0 / level) - 1


@dataclass(frozen=True)
class Doubt:
    """What a named process's smoothed driving noise showed against the model's own: each
    failed statistic as (name, observed, the model's median, p-value); ``peak_hz`` where the
    peak statistic's line sits."""

    effect_id: str
    failed: tuple[tuple[str, float, float, float], ...]
    peak_hz: float = math.nan

    def reasons(self) -> list[str]:
        out = []
        for name, obs, med, p in self.failed:
            if name == "kurtosis_high":
                out.append(f"it jumps — kurtosis {obs:.3g} against the model's {med:.3g} (p = {p:.3g}): steps "
                           "between levels, as random telegraph (popcorn) noise or an unlogged input makes")
            elif name == "kurtosis_low":
                out.append(f"it is bounded like a waveform's — kurtosis {obs:.3g} against the model's {med:.3g} "
                           f"(p = {p:.3g})")
            elif name == "segments":
                out.append(f"it comes and goes along the record — its mean square over {SEGMENTS} stretches "
                           f"disperses {obs:.3g} against the model's {med:.3g} (p = {p:.3g})")
            else:
                out.append(f"it holds a line at {self.peak_hz:.4g} Hz — {obs:.3g}× the model's spectrum there "
                           f"against {med:.3g} typically (p = {p:.3g})")
        return out

    def describe(self) -> str:
        return (f"{self.effect_id} fits the record's spectrum but is not that process — its driving noise "
                f"(smoothed) departs from the model's: {'; '.join(self.reasons())}. Not named: structure with "
                "that spectrum which no catalogue process makes")

    def to_dict(self) -> dict:
        return {"effect": self.effect_id, "peak_hz": None if math.isnan(self.peak_hz) else self.peak_hz,
                "failed": [{"statistic": n, "observed": o, "model_median": m, "p_value": p}
                           for n, o, m, p in self.failed]}


def _statistics(d: np.ndarray) -> tuple[float, float, np.ndarray]:
    """(kurtosis, dispersion of the mean square over SEGMENTS stretches, periodogram) of one
    block's disturbances."""
    u = d - d.mean()
    m2 = float(np.mean(u * u))
    if not m2 > 0:
        return 3.0, 0.0, np.zeros(max(u.size // 2, 1))
    kurt = float(np.mean(u ** 4)) / (m2 * m2)
    seg = np.array([float(np.mean(x * x)) for x in np.array_split(u, SEGMENTS)])
    return kurt, float(np.std(seg) / np.mean(seg)), np.abs(np.fft.rfft(u))[1:] ** 2


def process_doubts(model: Model, rec: Record, seen: np.ndarray | None, ids: tuple[str, ...], *,
                   level: float, nu: float = math.inf, seed: int = 0) -> dict[str, Doubt]:
    """The processes of ``model`` named in ``ids`` whose smoothed disturbances on ``rec`` depart
    from the model's (module docstring), each statistic tested at ``level``: {id: Doubt}.
    ``seen``: the samples the likelihood counted (None: all); ``nu``: the white noise's Student-t
    degrees of freedom (inf: Gaussian); ``seed``: the Monte Carlo's."""
    procs = list(model.stochastic_effects())
    order = [e.id for e, _ in procs]
    unknown = sorted(set(ids) - set(order))
    if unknown:
        raise ValueError(f"ids = {unknown}; allowed: the model's random processes {order}")
    if not ids:
        return {}
    reps = reps_for(level)
    x = seen_only(rec.y - model.predict(rec), seen)
    # the white level at the exact likelihood with the processes as fitted (an output stage's
    # per-sample spread is not the model's white level)
    white = sto.exact_white(x, rec.dt_s, procs, float(model.residual_sd()))
    ss = state_space(rec.rate_hz, rec.n, procs)
    which = [order.index(i) for i in ids]
    observed = [_statistics(col) for col in ss.smoothed_disturbances(x, white * white)[:, which].T]
    rng = np.random.default_rng([int(seed), 36, 4])
    null_k = np.zeros((reps, len(which)))
    null_s = np.zeros((reps, len(which)))
    null_p = [np.zeros((reps, observed[0][2].size)) for _ in which]
    missing = np.isnan(x)
    for r in range(reps):
        w = rng.standard_normal(rec.n) if not math.isfinite(nu) else \
            rng.standard_t(nu, rec.n) * math.sqrt((nu - 2.0) / nu)
        y = ss.simulate(rng, rec.n) + white * w
        y = np.where(missing, np.nan, y - float(np.mean(y[~missing])))
        for j, col in enumerate(ss.smoothed_disturbances(y, white * white)[:, which].T):
            null_k[r, j], null_s[r, j], null_p[j][r] = _statistics(col)
    out: dict[str, Doubt] = {}
    for j, eid in enumerate(ids):
        kurt, seg, pg = observed[j]
        # the model's mean periodogram over all R + 1 series, the record's among them: each is then
        # normalised alike, and the rank test stays exact
        mean_pg = np.maximum((null_p[j].sum(axis=0) + pg) / (reps + 1), np.finfo(float).tiny)
        peaks = np.max(null_p[j] / mean_pg, axis=1)
        ratio = pg / mean_pg
        at = int(np.argmax(ratio))
        tests = (("kurtosis_high", kurt, null_k[:, j], 1), ("kurtosis_low", kurt, null_k[:, j], -1),
                 ("segments", seg, null_s[:, j], 1), ("peak", float(ratio[at]), peaks, 1))
        failed = []
        for name, obs, null, sign in tests:
            p = (1 + int(np.sum(sign * null >= sign * obs))) / (reps + 1)
            if p <= level:
                failed.append((name, float(obs), float(np.median(null)), p))
        if failed:
            out[eid] = Doubt(eid, tuple(failed), (at + 1) / (rec.n * rec.dt_s))
    return out
