"""The discrepancy workflow (issue 7, section 2): calibrate, localize, name, add, repeat.

:func:`discover` runs, on a :class:`~bench.discovery.data.Record` and a starting model:

a. :func:`calibrate` — bounded least squares of all the model's parameters (bias, scale factor
   when the input is logged and varies, and every parameter of the deterministic effects
   already in it, from their current values); the white-noise sd is re-estimated from the residual's high-frequency floor (median of the
   Welch PSD over the upper half of the band, median-bias corrected), so the floor is the
   data's, not a default's;
b. :func:`bench.discovery.localize.localize` of the residual;
c. :func:`bench.discovery.naming.name_effect` over the catalogue;
d. add the named effect with its fitted parameters, re-calibrate, and measure the gap before
   and after (:class:`bench.discovery.significance.Gap`: rms / model-noise rms, Allan distance,
   spectral distance, Ljung–Box whiteness p) against a simulation of the model's own noise;
e. repeat until nothing is named (or ``max_effects``). Structure left that no candidate
   explains is reported as "unexplained structure" with where it is
   (:func:`bench.discovery.localize.unexplained_structure`: the residual, or its Kalman
   innovations when the model has stochastic effects, against the model's own noise,
   family-wise at ``alpha``); nothing significant names nothing.

Pure: record and model in, a :class:`Discovery` out (no files; the CLI writes the model file).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from bench.discovery.data import Record
from bench.discovery.localize import Localization, localize, unexplained_structure
from bench.discovery.naming import Naming, name_effect
from bench.discovery.significance import Gap, gap_metrics, white_floor


def _effect(eid: str):
    from bench.discovery.effects import CATALOGUE  # noqa: PLC0415

    return CATALOGUE[eid]


#: Effects whose parameters calibrate leaves as named: stochastic ones have no waveform, and a
#: quantizer's prediction is piecewise constant in its step (judged on the histogram instead).
_HISTOGRAM_JUDGED = ("quantization",)


def _sf_free(rec: Record) -> bool:
    """Scale factor is fitted only when the input is logged and varies: with a constant input
    bias and scale factor are one offset (not separable)."""
    return rec.varies("input")


def _slots(model, rec: Record) -> list[tuple[str, int | None, object]]:
    """(what, effect index or None, Param or base name) of every parameter calibrate fits
    (calibrate appends ("noise", measured floor, "noise_sd") for a quantized model)."""
    slots = [("base", None, "bias")]
    if _sf_free(rec):
        slots.append(("base", None, "scale_factor"))
    for i, (eid, _) in enumerate(model.effects):
        eff = _effect(eid)
        if eff.stochastic or eid in _HISTOGRAM_JUDGED:
            continue
        for q in eff.params_for(model.base.kind):
            slots.append(("effect", i, q))
    return slots


def _periodic(q) -> bool:
    return q.unit == "rad" and "phase" in q.name and q.high - q.low >= 2 * np.pi - 1e-9


def _coords(model, slots) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(x, lower, upper, scale): optimiser coordinates (log parameters in log) and bounds."""
    from bench.discovery.model import BASE_RANGES  # noqa: PLC0415

    x, lo, hi, sc = [], [], [], []
    for what, i, q in slots:
        if what == "noise":  # log sd, from a thousandth of the measured floor ``i`` up to it
            x.append(np.log(max(float(model.base.noise_sd), 1e-3 * i)))
            lo.append(np.log(1e-3 * i))
            hi.append(np.log(i))
            sc.append(0.3)
            continue
        if what == "base":
            a, b = BASE_RANGES[model.base.kind][q]
            x.append(float(getattr(model.base, q)))
            lo.append(a)
            hi.append(b)
            sc.append(max(float(model.base.noise_sd), 1e-12) if q == "bias" else 1e-4)
            continue
        v = float(model.effects[i][1][q.name])
        if q.log:
            x.append(np.log(v))
            lo.append(np.log(q.low))
            hi.append(np.log(q.high))
            sc.append(0.3)
        elif _periodic(q):  # a phase wraps: no wall at ±π for the optimiser
            x.append(v)
            lo.append(-8 * np.pi)
            hi.append(8 * np.pi)
            sc.append(0.1)
        else:
            x.append(v)
            lo.append(q.low)
            hi.append(q.high)
            sc.append(max(abs(v), (q.high - q.low) * 1e-4, 1e-300))
    return np.array(x), np.array(lo), np.array(hi), np.array(sc)


def _at(model, slots, x: np.ndarray):
    """The model with the optimiser coordinates ``x`` (effect values clipped to their ranges)."""
    base = {}
    effects = [(eid, dict(p)) for eid, p in model.effects]
    for (what, i, q), v in zip(slots, x):
        if what == "noise":
            base[q] = float(np.exp(v))
            continue
        if what == "base":
            base[q] = float(v)
            continue
        val = float(np.exp(v)) if q.log else float(v)
        if _periodic(q):
            val = (val + np.pi) % (2 * np.pi) - np.pi
        effects[i][1][q.name] = float(np.clip(val, q.low, q.high))
    from bench.discovery.model import Model  # noqa: PLC0415

    return Model(replace(model.base, **base), tuple(effects))


def white_floor_sd(residual: np.ndarray, rate_hz: float) -> float:
    """White-noise sd from the upper half of the residual's Welch PSD (median, bias-corrected):
    immune to slow structure (drift, warm-up, temperature) and to a few spectral lines
    (:func:`bench.discovery.significance.white_floor`)."""
    return float(white_floor(np.asarray(residual, float), rate_hz)[0])


def _check_base(model, rec: Record, bias: float, sf: float) -> None:
    """ValueError when an unconstrained base fit lands outside its range (never a silent clip)."""
    from bench.discovery.model import BASE_RANGES  # noqa: PLC0415

    rng = BASE_RANGES[model.base.kind]
    for name, v in (("bias", bias), ("scale_factor", sf)):
        lo, hi = rng[name]
        if not (lo <= v <= hi) or not np.isfinite(v):
            raise ValueError(f"calibrated {name} = {v:.6g} outside the allowed range [{lo}, {hi}] for a "
                             f"{model.base.kind}: wrong unit or missing input column?")


def calibrate(model, rec: Record, *, noise: bool = True, max_nfev: int = 200):
    """The model with ALL its parameters fitted to ``rec`` by bounded least squares (issue 7,
    step a: bias, scale factor when the input is logged and varies, and every parameter of the
    deterministic effects already in it — time constants, frequencies, delays too, so a frozen
    shape misfit does not linger in the residual as colour), starting from the current values,
    each bounded by its range; with ``noise``, the white-noise sd is set to the residual's
    high-frequency floor. Stochastic effects and the quantization step keep their values.

    Bias and scale factor are first solved linearly (unconstrained); outside the kind's range
    that is a ValueError naming the value (a wrong unit or a missing input column), never a clip."""
    from scipy import optimize  # noqa: PLC0415

    from bench.discovery.model import BASE_RANGES  # noqa: PLC0415

    sf_free = _sf_free(rec)
    rest = model.predict(rec) - model.base.bias - (model.base.scale_factor * rec.input if sf_free else 0.0)
    cols = [np.ones(rec.n)] + ([rec.input] if sf_free else [])
    coef, *_ = np.linalg.lstsq(np.column_stack(cols), rec.y - rest, rcond=None)
    bias = float(coef[0])
    sf = float(coef[1]) if sf_free else float(model.base.scale_factor)
    _check_base(model, rec, bias, sf)
    model = model.with_base(bias=bias, scale_factor=sf)
    slots = _slots(model, rec)
    # through a quantizer the prediction E[Q(x + n)] depends on the noise before it: that sd is
    # a parameter of the prediction, fitted with the rest (the conditional mean minimises the
    # squared error, so least squares finds it), starting from the measured floor's inversion
    quantized = noise and any(eid in _HISTOGRAM_JUDGED for eid, _ in model.effects)
    if quantized:
        floor = white_floor_sd(rec.y - model.predict(rec), rec.rate_hz)
        floor = float(min(floor, BASE_RANGES[model.base.kind]["noise_sd"][1]))
        if floor > 0 and np.isfinite(floor):
            model = model.with_noise_floor(floor)
            slots.append(("noise", floor, "noise_sd"))
    if len(slots) > (2 if sf_free else 1):  # effects with parameters: the joint nonlinear fit
        x0, lo, hi, sc = _coords(model, slots)
        x0 = np.clip(x0, lo, hi)
        y = rec.y
        fun = lambda x: y - _at(model, slots, x).predict(rec)
        try:
            res = optimize.least_squares(fun, x0, bounds=(lo, hi), x_scale=sc, max_nfev=max_nfev, method="trf")
            if np.sum(res.fun ** 2) < np.sum(fun(x0) ** 2):
                model = _at(model, slots, res.x)
        except (ValueError, np.linalg.LinAlgError):
            pass  # keep the linear calibration
        b = model.base
        for name in ("bias", "scale_factor"):
            lo_b, hi_b = BASE_RANGES[b.kind][name]
            v = getattr(b, name)
            if min(v - lo_b, hi_b - v) <= 1e-9 * (hi_b - lo_b):
                raise ValueError(f"calibrated {name} = {v:.6g} at the edge of the allowed range [{lo_b}, {hi_b}] "
                                 f"for a {b.kind}: wrong unit or missing input column?")
    if noise and not any(w == "noise" for w, _, _ in slots):
        sd = white_floor_sd(rec.y - model.predict(rec), rec.rate_hz)
        sd = float(min(sd, BASE_RANGES[model.base.kind]["noise_sd"][1]))
        if sd > 0 and np.isfinite(sd):
            # the measured floor holds a quantizer's rounding too: the noise before it is less
            model = model.with_noise_floor(sd)
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
    # a random process's rms varies between realisations, and a quantizer's rounding error
    # depends on where the signal sits between levels: both floors come from simulating the
    # model on this stimulus (several realisations), not from a formula
    stoch = any(_effect(eid).stochastic or eid in _HISTOGRAM_JUDGED for eid, _ in model.effects)
    if stoch:
        noises = [model_noise(model, rec, seed + k) for k in range(8)]
        floor = float(np.sqrt(np.mean([np.mean(x ** 2) for x in noises])))
        g = gap_metrics(r, model.residual_sd(), rec.rate_hz, noises[0], floor)
    else:
        floor = float(model.residual_sd())
        g = gap_metrics(r, floor, rec.rate_hz)
    return g, float(np.sqrt(np.mean(r ** 2))), floor, r


def _structure(model, rec: Record, r: np.ndarray) -> Localization:
    return localize(rec, r - r.mean(), model.residual_sd())


def _step_std(model, rec: Record, naming_std: dict) -> dict:
    """Std of the last effect's parameters at the re-calibrated model (the naming fit's std
    belonged to other values of the other parameters); the naming's for stochastic and
    histogram-judged effects."""
    from bench.discovery.fitting import CandidateFitter  # noqa: PLC0415
    from bench.discovery.model import Model  # noqa: PLC0415

    eid, p = model.effects[-1]
    eff = _effect(eid)
    if eff.stochastic or eid in _HISTOGRAM_JUDGED:
        return dict(naming_std)
    # the model's noise_sd is already the noise before any quantizer (with_noise_floor)
    f = CandidateFitter(Model(model.base, model.effects[:-1]), rec, eff, eid, noise_is_floor=False)
    x = f.pack(p, model.base.bias, model.base.scale_factor)
    return dict(f.fit([x], max_nfev=1).params_std)


def _fmt(v: float) -> str:
    return f"{v:.3g}"


def discover(rec: Record, model, *, max_effects: int = 4, alpha: float = 0.05, seed: int = 0,
             n_rep: int = 999, only: tuple[str, ...] | None = None,
             progress: Callable[[str], None] | None = None) -> Discovery:
    """Run the loop a..e on ``rec`` from ``model``; see the module docstring. ``progress``:
    called with a short human message before each candidate fit and after each step."""
    if not isinstance(max_effects, int) or not 0 <= max_effects <= 19:
        raise ValueError(f"max_effects = {max_effects!r}; allowed: an integer in [0, 19]")
    if not 0 < alpha < 1:
        raise ValueError(f"alpha = {alpha!r}; allowed: (0, 1)")
    say = progress or (lambda _msg: None)
    from bench.discovery.effects import CATALOGUE  # noqa: PLC0415

    skipped = [eid for eid, e in CATALOGUE.items() if e.needs_uniform and model.base.kind in e.kinds]
    if skipped and not rec.is_uniform():
        notes = [f"{', '.join(skipped)} not tried: the sample intervals vary by more than 0.1 % of the median "
                 "(a sampled filter needs a uniform record; resample to try them)"]
    else:
        notes = []
    model = calibrate(model, rec)
    initial = model
    g0, rms0, floor, r0 = gap_of(model, rec, seed)
    steps = []
    gap_cur, rms_cur, r_cur = g0, rms0, r0
    naming = None
    for it in range(max_effects + 1):  # always ends by a break, loc describing r_cur
        loc = _structure(model, rec, r_cur)
        step_say = (lambda msg, _it=it: say(f"step {_it + 1}: {msg}"))
        naming = name_effect(model, rec, alpha=alpha, seed=seed + it, n_rep=n_rep, only=only,
                             progress=step_say)
        if naming.best is None:
            say(f"step {it + 1}: nothing significant; stopping")
            break
        if it == max_effects:
            notes.append(f"stopped after max_effects = {max_effects}; {naming.best.id} was still significant")
            break
        best = naming.best
        new = calibrate(model.with_effect(best.id, best.params), rec)
        g1, rms1, floor, r1 = gap_of(new, rec, seed)
        steps.append(Step(best.id, dict(new.effects[-1][1]), _step_std(new, rec, best.params_std), best.p_value,
                          gap_cur, g1, rms_cur, rms1, naming, loc, r_cur, r1))
        say(f"step {it + 1}: named {best.id}, rms {_fmt(rms_cur)} → {_fmt(rms1)}")
        model, gap_cur, rms_cur, r_cur = new, g1, rms1, r1
    # what no catalogue effect explained: the residual (white model) or its Kalman innovations
    # (stochastic model) against the model's own noise, family-wise at alpha
    unexplained = unexplained_structure(rec, r_cur, model, alpha=alpha)
    if unexplained:
        say(f"unexplained structure: {len(unexplained)} finding(s)")
    return Discovery(initial, model, tuple(steps), unexplained, g0, gap_cur, rms0, rms_cur, floor, loc,
                     naming, r0, r_cur, tuple(notes))
