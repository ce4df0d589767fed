"""The discrepancy workflow (issue 7, section 2): calibrate, localize, name, add, repeat.

:func:`discover` runs, on a :class:`~bench.discovery.data.Record` and a starting model:

a. :func:`calibrate` — least squares of the model's linear parameters (bias, scale factor when
   the input is logged, and every ``Param.linear`` parameter of the effects already in it),
   Gauss–Newton on the model's own prediction (exact in two steps for an affine model); the
   white-noise sd is re-estimated from the residual's high-frequency floor (median of the
   Welch PSD over the upper half of the band, median-bias corrected), so the floor is the
   data's, not a default's;
b. :func:`bench.discovery.localize.localize` of the residual;
c. :func:`bench.discovery.naming.name_effect` over the catalogue;
d. add the named effect with its fitted parameters, re-calibrate, and measure the gap before
   and after (:class:`bench.discovery.significance.Gap`: rms / model-noise rms, Allan distance,
   spectral distance, Ljung–Box whiteness p) against a simulation of the model's own noise;
e. repeat until nothing is named (or ``max_effects``). Structure left that no candidate
   explains is reported as "unexplained structure" with where it is; nothing significant
   names nothing.

Pure: record and model in, a :class:`Discovery` out (no files; the CLI writes the model file).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy import signal, stats

from bench.discovery.data import Record
from bench.discovery.localize import Localization, localize
from bench.discovery.naming import Naming, name_effect
from bench.discovery.significance import Gap, gap_metrics


def _effect(eid: str):
    from bench.discovery.effects import CATALOGUE  # noqa: PLC0415

    return CATALOGUE[eid]


def _linear_slots(model, rec: Record) -> list[tuple[str, int | None, str]]:
    """(what, effect index or None, name) of every linear parameter to calibrate."""
    slots = [("base", None, "bias")]
    if rec.logged("input"):
        slots.append(("base", None, "scale_factor"))
    for i, (eid, p) in enumerate(model.effects):
        eff = _effect(eid)
        if eff.stochastic:
            continue
        for q in eff.params_for(model.base.kind):
            if q.linear:
                slots.append(("effect", i, q.name))
    return slots


def _get(model, slot) -> float:
    what, i, name = slot
    return float(getattr(model.base, name)) if what == "base" else float(model.effects[i][1][name])


def _set(model, slot, value: float):
    what, i, name = slot
    if what == "base":
        from bench.discovery.model import BASE_RANGES  # noqa: PLC0415

        lo, hi = BASE_RANGES[model.base.kind][name]
        return replace(model, base=replace(model.base, **{name: float(np.clip(value, lo, hi))}))
    effects = list(model.effects)
    eid, p = effects[i]
    q = _effect(eid).param(name, model.base.kind)
    p = dict(p)
    p[name] = float(np.clip(value, q.low, q.high))
    effects[i] = (eid, p)
    return replace(model, effects=tuple(effects))


def _range(model, slot) -> tuple[float, float]:
    from bench.discovery.model import BASE_RANGES  # noqa: PLC0415

    what, i, name = slot
    if what == "base":
        return BASE_RANGES[model.base.kind][name]
    q = _effect(model.effects[i][0]).param(name, model.base.kind)
    return q.low, q.high


def white_floor_sd(residual: np.ndarray, rate_hz: float) -> float:
    """White-noise sd from the upper half of the residual's Welch PSD (median, bias-corrected):
    immune to slow structure (drift, warm-up, temperature) and to a few spectral lines."""
    r = np.asarray(residual, float)
    nperseg = min(r.size, max(64, 2 ** int(np.log2(max(r.size // 16, 64)))))
    f, p = signal.welch(r, fs=rate_hz, window="hann", nperseg=nperseg, detrend="constant")
    upper = p[f >= 0.5 * f[-1]][:-1] if f.size > 4 else p
    k = max(1, 2 * (r.size - nperseg) // nperseg + 1)
    nu = 2.0 * k * 0.9
    med_bias = stats.chi2.median(nu) / nu
    return float(np.sqrt(np.median(upper) / med_bias * rate_hz / 2.0))


def calibrate(model, rec: Record, *, noise: bool = True, iterations: int = 3):
    """The model with its linear parameters fitted to ``rec`` by least squares (and, with
    ``noise``, the white-noise sd set to the residual's high-frequency floor)."""
    slots = _linear_slots(model, rec)
    for _ in range(iterations):
        f0 = model.predict(rec)
        r = rec.y - f0
        cols = []
        for s in slots:
            v = _get(model, s)
            lo, hi = _range(model, s)
            h = 1e-3 * (hi - lo)
            moved = _set(model, s, v + h if v + h <= hi else v - h)
            cols.append((moved.predict(rec) - f0) / (_get(moved, s) - v))
        jac = np.column_stack(cols)
        scale = np.where(np.linalg.norm(jac, axis=0) > 0, np.linalg.norm(jac, axis=0), 1.0)
        step, *_ = np.linalg.lstsq(jac / scale, r, rcond=None)
        step = step / scale
        for s, d in zip(slots, step):
            model = _set(model, s, _get(model, s) + d)
        if np.all(np.abs(step) <= 1e-10 * (np.abs([_get(model, s) for s in slots]) + 1e-300)):
            break
    if noise:
        sd = white_floor_sd(rec.y - model.predict(rec), rec.rate_hz)
        from bench.discovery.model import BASE_RANGES  # noqa: PLC0415

        sd = float(min(sd, BASE_RANGES[model.base.kind]["noise_sd"][1]))
        if sd > 0 and np.isfinite(sd):
            model = replace(model, base=replace(model.base, noise_sd=sd))
    return model


@dataclass(frozen=True)
class Step:
    """One named effect: what, its parameters ± std, p-value, the gap before and after, the
    naming (all candidates) and the localization that motivated it; residuals for the plots."""

    effect_id: str
    params: dict
    params_std: dict
    p_value: float
    gap_before: Gap
    gap_after: Gap
    rms_before: float
    rms_after: float
    naming: Naming
    localization: Localization
    residual_before: np.ndarray = field(repr=False)
    residual_after: np.ndarray = field(repr=False)

    def to_dict(self) -> dict:
        return {"id": self.effect_id, "params": self.params, "params_std": self.params_std,
                "gap_before": self.gap_before.rms_ratio, "gap_after": self.gap_after.rms_ratio,
                "p_value": self.p_value, "rms_before": self.rms_before, "rms_after": self.rms_after,
                "gap_table": {"before": self.gap_before.to_dict(), "after": self.gap_after.to_dict()},
                "competitors": list(self.naming.competitors),
                "separating_experiments": list(self.naming.separating),
                "localization": self.localization.descriptions()}


@dataclass(frozen=True)
class Discovery:
    """The loop's story: the calibrated starting model, each step, the final model and gaps.

    Gap figures in JSON: ``gap.initial`` / ``gap.final`` (and each effect's ``gap_before`` /
    ``gap_after``) are residual rms relative to the model's noise rms (1 = at the floor);
    ``gap.noise_floor`` the final model's noise rms in the sensor unit, ``rms_initial`` /
    ``rms_final`` the residual rms in that unit; the full before/after table (Allan, spectral,
    whiteness) of each step is under ``effects[i].gap_table``."""

    initial_model: object
    final_model: object
    steps: tuple[Step, ...]
    unexplained: tuple[str, ...]
    gap_initial: Gap
    gap_final: Gap
    rms_initial: float
    rms_final: float
    noise_floor: float
    final_localization: Localization
    final_naming: Naming
    residual_initial: np.ndarray = field(repr=False)
    residual_final: np.ndarray = field(repr=False)
    notes: tuple[str, ...] = ()

    def to_dict(self, model_file: str | None = None) -> dict:
        return {"effects": [s.to_dict() for s in self.steps],
                "gap": {"initial": self.gap_initial.rms_ratio, "final": self.gap_final.rms_ratio,
                        "noise_floor": self.noise_floor, "rms_initial": self.rms_initial,
                        "rms_final": self.rms_final,
                        "initial_table": self.gap_initial.to_dict(), "final_table": self.gap_final.to_dict()},
                "unexplained": list(self.unexplained), "model_file": model_file, "notes": list(self.notes),
                "last_naming": self.final_naming.to_dict()}


def model_noise(model, rec: Record, seed: int) -> np.ndarray:
    """One realisation of the model's own noise (white + its stochastic effects) on rec's grid."""
    return model.simulate(rec, np.random.default_rng(seed)) - model.predict(rec)


def gap_of(model, rec: Record, seed: int) -> tuple[Gap, float, float, np.ndarray]:
    """(gap table, residual rms, model-noise rms, residual) of ``model`` on ``rec``."""
    r = rec.y - model.predict(rec)
    stoch = any(_effect(eid).stochastic for eid, _ in model.effects)
    if stoch:  # a random process's rms varies between realisations: average several
        noises = [model_noise(model, rec, seed + k) for k in range(8)]
        floor = float(np.sqrt(np.mean([np.mean(x ** 2) for x in noises])))
        g = gap_metrics(r, model.base.noise_sd, rec.rate_hz, noises[0], floor)
    else:
        floor = float(model.base.noise_sd)
        g = gap_metrics(r, model.base.noise_sd, rec.rate_hz)
    return g, float(np.sqrt(np.mean(r ** 2))), floor, r


def _structure(model, rec: Record, r: np.ndarray) -> Localization:
    return localize(rec, r - r.mean(), model.base.noise_sd)


def _unexplained(model, loc: Localization) -> tuple[str, ...]:
    # with stochastic effects in the model its residual is coloured by design: every
    # localization test is calibrated on white noise and would flag the model's own noise
    # (a random walk correlates with any slow input); the workflow notes it instead
    if any(_effect(eid).stochastic for eid, _ in model.effects):
        return ()
    return tuple(loc.descriptions())


def discover(rec: Record, model, *, max_effects: int = 4, alpha: float = 0.05, seed: int = 0,
             n_rep: int = 999, only: tuple[str, ...] | None = None) -> Discovery:
    """Run the loop a..e on ``rec`` from ``model``; see the module docstring."""
    if not isinstance(max_effects, int) or not 0 <= max_effects <= 19:
        raise ValueError(f"max_effects = {max_effects!r}; allowed: an integer in [0, 19]")
    if not 0 < alpha < 1:
        raise ValueError(f"alpha = {alpha!r}; allowed: (0, 1)")
    model = calibrate(model, rec)
    initial = model
    g0, rms0, _, r0 = gap_of(model, rec, seed)
    steps = []
    notes = []
    gap_cur, rms_cur, r_cur = g0, rms0, r0
    naming = None
    for it in range(max_effects + 1):
        loc = _structure(model, rec, r_cur)
        naming = name_effect(model, rec, alpha=alpha, seed=seed + it, n_rep=n_rep, only=only)
        if naming.best is None:
            break
        if it == max_effects:
            notes.append(f"stopped after max_effects = {max_effects}; {naming.best.id} was still significant")
            break
        best = naming.best
        new = calibrate(model.with_effect(best.id, best.params), rec)
        g1, rms1, _, r1 = gap_of(new, rec, seed)
        steps.append(Step(best.id, dict(new.effects[-1][1]), best.params_std, best.p_value,
                          gap_cur, g1, rms_cur, rms1, naming, loc, r_cur, r1))
        model, gap_cur, rms_cur, r_cur = new, g1, rms1, r1
    loc = _structure(model, rec, r_cur)
    unexplained = _unexplained(model, loc) if naming is None or naming.best is None or notes else ()
    if any(_effect(eid).stochastic for eid, _ in model.effects):
        notes.append("the model has stochastic effects: the white-noise localization tests do not apply "
                     "to its residual, so unexplained structure is not assessed")
    _, _, floor, _ = gap_of(model, rec, seed)
    return Discovery(initial, model, tuple(steps), unexplained, g0, gap_cur, rms0, rms_cur, floor, loc,
                     naming, r0, r_cur, tuple(notes))
