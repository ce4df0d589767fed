"""Bias jumps: steps of the output's level at unknown times (a FOG mode hop, a relay, a connector
that moved), found by a change-point search and fitted as a localized waveform.

Up to :data:`MAX_JUMPS` jumps, each a size and a time; a slot whose size is 0 is unused (its time
is not fitted: ``free_params``), so the count is the number of non-zero sizes. A jump is a ramp
across the one sample interval it falls in, so its time is a continuous parameter a least-squares
fit can refine below a sample once a start has found the right sample.

Starts (:meth:`BiasJump.fit_starts`): binary segmentation of the residual (base regressors
projected out, on the training rows only): the split with the largest CUSUM statistic
``(S_k − k·S/m)²·m/(k·(m − k))/σ²`` of any segment is taken while it exceeds ``MIN_SNR²`` (a
step of snr 5, the size gate), at most :data:`MAX_JUMPS`, at least one; σ from the MAD of the
first differences (immune to the steps themselves).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import replace

import numpy as np

from bench.discovery.data import Record
from bench.discovery.effects_base import MIN_SNR, Effect, Param, Params
from bench.discovery.effects_linalg import base_regressors, project_out

#: Most jumps one bias_jump effect holds.
MAX_JUMPS = 3
#: Drawn jumps lie in the middle of the record, at least this share of it apart.
DRAW_SPREAD = (0.1, 0.9)
DRAW_SEPARATION = 0.1


def _slots(unit: str, limit: float, floor: float, time_high_s: float = 1e9) -> tuple[Param, ...]:
    """size_k (±limit, the first with a physical floor) and time_k_s (0 … time_high_s) per slot."""
    lo, hi = -limit, limit
    out: list[Param] = []
    for k in range(1, MAX_JUMPS + 1):
        out += [Param(f"size_{k}", unit, lo, hi, linear=True, floor=floor if k == 1 else 0.0),
                Param(f"time_{k}_s", "s", 0.0, time_high_s)]
    return tuple(out)


def ramp(t_s: np.ndarray, time_s: float, dt_s: float) -> np.ndarray:
    """0 before ``time_s − dt/2``, 1 after ``time_s + dt/2``, linear between: a step placed to a
    fraction of a sample."""
    return np.clip((t_s - time_s) / dt_s + 0.5, 0.0, 1.0)


def change_points(r: np.ndarray, sd: float, max_count: int, min_z2: float) -> list[int]:
    """Indices where the level of ``r`` changes (a step between i − 1 and i), by binary
    segmentation: at each round the best split of any segment (largest CUSUM statistic in units
    of ``sd``²) is taken while it exceeds ``min_z2``; the first split is always taken."""
    n = r.size
    segments = [(0, n)]
    found: list[int] = []
    while len(found) < max_count:
        best = (0.0, -1, -1)
        for a, b in segments:
            m = b - a
            if m < 4:
                continue
            s = np.cumsum(r[a:b])
            k = np.arange(1, m)
            stat = (s[:-1] - k * s[-1] / m) ** 2 * m / (k * (m - k))
            i = int(np.argmax(stat))
            if stat[i] > best[0]:
                best = (float(stat[i]), a, a + i + 1)
        z2, a, cut = best
        if cut < 0 or (found and z2 / sd ** 2 < min_z2):
            break
        found.append(cut)
        b = next(e for s0, e in segments if s0 == a)
        segments.remove((a, b))
        segments += [(a, cut), (cut, b)]
    return sorted(found)


class BiasJump(Effect):
    id = "bias_jump"
    description = ("steps of the bias at unknown times (a FOG mode hop, an intermittent connection, a range "
                   f"change): up to {MAX_JUMPS} jumps, each a size and a time")
    form = "y += Σ_k size_k · ramp(t − time_k_s) (a step across the sample it falls in); size_k = 0: no jump"
    inputs = ("t",)
    main_param = "size_1"
    signature = ("time: the level shifts at each jump and stays (CUSUM kinks, segment means); innovations: a "
                 "burst at each jump time; spectrum 1/f² at low frequency")
    separating = {"rate_random_walk": "repeat the record: a jump is one event at one time (often with an event "
                                      "in the log), a random walk wanders everywhere"}
    ranges = {  # FOG mode hops ~0.01-1 deg/h up to a degraded unit's deg/s; µg-mg accelerometer shifts
        "accelerometer": _slots("g", 1e-2, 1e-7),
        "gyro": _slots("deg/s", 1.0, 1e-6),
        "mhd": _slots("deg/s", 10.0, 1e-4),
    }

    def term(self, p: Mapping[str, float], rec: Record) -> np.ndarray:
        out = np.zeros(rec.n)
        for k in range(1, MAX_JUMPS + 1):
            size = p[f"size_{k}"]
            if size != 0.0:
                out += size * ramp(rec.t_s, p[f"time_{k}_s"], rec.dt_s)
        return out

    def count(self, p: Mapping[str, float]) -> int:
        """Number of jumps (non-zero sizes)."""
        return sum(p[f"size_{k}"] != 0.0 for k in range(1, MAX_JUMPS + 1))

    def searched(self, p: Mapping[str, float]) -> int:
        """Each jump's time was found by a change-point search."""
        return self.count(p)

    def identity_params(self, p: Params) -> Params:
        return dict(p) | {f"size_{k}": 0.0 for k in range(1, MAX_JUMPS + 1)}

    def prefixes(self, p: Mapping[str, float]) -> list[Params]:
        """The j largest jumps of ``p`` (j = 1 … count − 1), in time order in the first slots:
        the number of jumps is the criterion's to choose."""
        used = [(p[f"size_{k}"], p[f"time_{k}_s"]) for k in range(1, MAX_JUMPS + 1) if p[f"size_{k}"] != 0.0]
        by_size = sorted(used, key=lambda st: -abs(st[0]))
        out = []
        for j in range(1, len(used)):
            q = dict(p) | {f"size_{k}": 0.0 for k in range(1, MAX_JUMPS + 1)}
            for k, (size, time) in enumerate(sorted(by_size[:j], key=lambda st: st[1]), start=1):
                q[f"size_{k}"], q[f"time_{k}_s"] = size, time
            out.append(q)
        return out

    def free_params(self, p: Mapping[str, float], kind: str, rec: Record,
                    rows: np.ndarray | None = None) -> tuple[Param, ...]:
        """Size and time of each used slot (the first always), times inside the record."""
        used = {1} | {k for k in range(2, MAX_JUMPS + 1) if p.get(f"size_{k}", 0.0) != 0.0}
        t0, t1 = float(rec.t_s[0]), float(rec.t_s[-1])
        return tuple(replace(q, low=max(q.low, t0), high=min(q.high, t1)) if q.name.startswith("time_") else q
                     for q in self.params_for(kind) if int(q.name.split("_")[1]) in used)

    def coordinate_scale(self, q: Param, rec: Record) -> float | None:
        return rec.dt_s if q.name.startswith("time_") else None

    def drawable_range(self, q: Param, rec: Record, kind: str) -> tuple[float, float]:
        if q.name.startswith("time_"):
            t0, span = float(rec.t_s[0]), rec.duration_s
            return t0 + DRAW_SPREAD[0] * span, t0 + DRAW_SPREAD[1] * span
        return q.low, q.high

    def draw_others(self, rng: np.random.Generator, rec: Record, kind: str) -> Params:
        """1-3 jumps (probabilities 0.5, 0.3, 0.2) at times in the middle of the record at least
        a tenth of it apart; the sizes of the second and third set after the first is drawn."""
        count = int(rng.choice([1, 2, 3], p=[0.5, 0.3, 0.2]))
        lo, hi = self.drawable_range(self.params_for(kind)[1], rec, kind)
        while True:
            times = np.sort(rng.uniform(lo, hi, count))
            if count == 1 or np.min(np.diff(times)) >= DRAW_SEPARATION * rec.duration_s:
                break
        out: Params = {}
        for k in range(1, MAX_JUMPS + 1):
            # an unused slot has time 0; the sizes of the used ones follow the first (finish_draw),
            # so the first is drawn at its snr alone
            out[f"time_{k}_s"] = float(times[k - 1]) if k <= count else 0.0
            if k > 1:
                out[f"size_{k}"] = 0.0
        return out

    def draw(self, rng: np.random.Generator, rec: Record, *, kind: str | None = None,
             noise_sd: float | None = None, at_snr: float | None = None) -> Params:
        """As every effect draws; with ``at_snr`` (a power curve) one jump only, so the snr is
        the one asked for."""
        p = super().draw(rng, rec, kind=kind, noise_sd=noise_sd, at_snr=at_snr)
        if at_snr is not None:
            p |= {f"{v}_{k}{u}": 0.0 for k in range(2, MAX_JUMPS + 1) for v, u in (("size", ""), ("time", "_s"))}
        return p

    def finish_draw(self, rng: np.random.Generator, rec: Record, kind: str, p: Params) -> Params:
        """The further jumps (slots with a time) 0.6-1.2 times the first's size, of either sign."""
        out = dict(p)
        main = abs(float(p["size_1"]))
        for k in range(2, MAX_JUMPS + 1):
            if out[f"time_{k}_s"] != 0.0:
                out[f"size_{k}"] = float(main * rng.uniform(0.6, 1.2) * (1 if rng.random() < 0.5 else -1))
        return out

    def reference_params(self, rec: Record, kind: str) -> Params:
        """One jump in the middle of the record."""
        out = {q.name: 0.0 for q in self.params_for(kind)}
        out["time_1_s"] = float(rec.t_s[0] + 0.5 * rec.duration_s)
        return out

    def fit_starts(self, rec: Record, residual: np.ndarray, *, kind: str | None = None,
                   rows: np.ndarray | None = None, held_out: np.ndarray | None = None) -> list[Params]:
        """Change points of the residual on ``rows`` (module docstring), sizes by least squares
        with the base regressors; one start (the count is the search's)."""
        return self._starts(rec, residual, kind or "accelerometer", rows, MAX_JUMPS)

    def _starts(self, rec: Record, residual: np.ndarray, kind: str, rows: np.ndarray | None,
                max_count: int) -> list[Params]:
        rows = np.ones(rec.n, bool) if rows is None else np.asarray(rows, bool)
        a = base_regressors(rec)[rows]
        r = project_out(np.asarray(residual, float)[rows], a)
        d = np.diff(r)
        sd = float(1.4826 * np.median(np.abs(d - np.median(d))) / math.sqrt(2.0)) or float(np.std(r)) or 1.0
        cuts = change_points(r, sd, max_count, MIN_SNR ** 2)
        t = rec.t_s[rows]
        times = [0.5 * (t[c - 1] + t[c]) for c in cuts]
        p: Params = {q.name: 0.0 for q in self.params_for(kind)}
        cols = [ramp(rec.t_s, tj, rec.dt_s)[rows] for tj in times]
        if cols:
            sizes, *_ = np.linalg.lstsq(np.column_stack([project_out(c, a) for c in cols]), r, rcond=None)
        else:
            sizes = np.zeros(0)
        lo, hi = self.param("size_1", kind).low, self.param("size_1", kind).high
        for k, (tj, sk) in enumerate(zip(times, sizes), start=1):
            p[f"time_{k}_s"] = float(tj)
            # a used slot keeps a non-zero size: zero would switch it off
            p[f"size_{k}"] = float(np.clip(sk, lo, hi)) or float(sd * 1e-3)
        if not times:
            p["time_1_s"] = float(rec.t_s[0] + 0.5 * rec.duration_s)
            p["size_1"] = float(sd * 1e-3)
        return [p]

