"""Step a of the discrepancy workflow: calibrate every parameter the model has on the record.

:func:`calibrate` — bounded least squares of all the model's parameters (bias, scale factor
when the input is logged and varies, and every parameter of the waveform effects already in it,
from their current values; random processes and histogram-judged effects keep theirs,
``Effect.waveform``); the white-noise sd is re-estimated from the residual's high-frequency
floor (median of the Welch PSD over the upper half of the band, median-bias corrected), so the
floor is the data's, not a default's. An output transform whose mean reading depends on the
noise before it (``Effect.mean_depends_on_noise``: the quantizer's dither) makes that noise sd a
parameter of the prediction, fitted with the rest.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from scipy import optimize

from bench.discovery.data import Record
from bench.discovery.effects_base import Param
from bench.discovery.effects_noise import Processes
from bench.discovery.model import BASE_RANGES, Model
from bench.discovery.significance import white_floor


@dataclass(frozen=True)
class _Slot:
    """One fitted coordinate: a base field (``what`` "base"), a parameter ``param`` of effect
    ``index`` ("effect"), or the noise sd before an output transform ("noise", started from the
    measured ``floor``)."""

    what: str
    name: str
    index: int = -1
    param: Param | None = None
    floor: float = 0.0


def _sf_free(rec: Record) -> bool:
    """Scale factor is fitted only when the input is logged and varies: with a constant input
    bias and scale factor are one offset (not separable)."""
    return rec.varies("input")


def _slots(model: Model, rec: Record, frozen: frozenset[str] = frozenset()) -> list[_Slot]:
    """Every coordinate calibrate fits (it appends the noise slot for a model whose mean
    reading depends on the noise); the effects in ``frozen`` keep their values."""
    slots = [_Slot("base", "bias")]
    if _sf_free(rec):
        slots.append(_Slot("base", "scale_factor"))
    for i, (eff, p) in enumerate(model.entries()):
        if not eff.waveform or eff.id in frozen:
            continue
        for q in eff.free_params(p, model.base.kind, rec):
            slots.append(_Slot("effect", q.name, i, q))
    return slots


def _coords(model: Model, slots: list[_Slot], rec: Record) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(x, lower, upper, scale): optimiser coordinates (log parameters in log) and bounds."""
    x, lo, hi, sc = [], [], [], []
    for s in slots:
        if s.what == "noise":  # log sd, from a thousandth of the measured floor up to it
            x.append(np.log(max(float(model.base.noise_sd), 1e-3 * s.floor)))
            lo.append(np.log(1e-3 * s.floor))
            hi.append(np.log(s.floor))
            sc.append(0.3)
            continue
        if s.what == "base":
            a, b = BASE_RANGES[model.base.kind][s.name]
            x.append(float(getattr(model.base, s.name)))
            lo.append(a)
            hi.append(b)
            sc.append(max(float(model.base.noise_sd), 1e-12) if s.name == "bias" else 1e-4)
            continue
        q = s.param
        assert q is not None  # an effect slot carries its parameter
        v = float(model.effects[s.index][1][q.name])
        if q.log:
            x.append(np.log(v))
            lo.append(np.log(q.low))
            hi.append(np.log(q.high))
            sc.append(0.3)
        elif q.periodic:  # a phase wraps: no wall at ±π for the optimiser
            x.append(v)
            lo.append(-8 * np.pi)
            hi.append(8 * np.pi)
            sc.append(0.1)
        else:
            own = model.entries()[s.index][0].coordinate_scale(q, rec)
            x.append(v)
            lo.append(q.low)
            hi.append(q.high)
            sc.append(own if own is not None else max(abs(v), (q.high - q.low) * 1e-4, 1e-300))
    return np.array(x), np.array(lo), np.array(hi), np.array(sc)


def _at(model: Model, slots: list[_Slot], x: np.ndarray) -> Model:
    """The model with the optimiser coordinates ``x`` (effect values clipped to their ranges)."""
    base: dict[str, Any] = {}
    effects = [(eid, dict(p)) for eid, p in model.effects]
    for s, v in zip(slots, x):
        if s.what == "noise":
            base[s.name] = float(np.exp(v))
            continue
        if s.what == "base":
            base[s.name] = float(v)
            continue
        q = s.param
        assert q is not None  # an effect slot carries its parameter
        val = float(np.exp(v)) if q.log else float(v)
        if q.periodic:
            val = (val + np.pi) % (2 * np.pi) - np.pi
        effects[s.index][1][q.name] = float(np.clip(val, q.low, q.high))
    return Model(replace(model.base, **base), tuple(effects))


def white_floor_sd(residual: np.ndarray, rate_hz: float, stochastic_effects: Processes = ()) -> float:
    """White-noise sd from the upper half of the residual's Welch PSD (median, bias-corrected):
    immune to slow structure (drift, warm-up, temperature) and to a few spectral lines; beside
    the model's random processes, whose spectrum there is theirs, not white (white angle noise
    lives at the top of the band) (:func:`bench.discovery.significance.white_floor`)."""
    return float(white_floor(np.asarray(residual, float), rate_hz, stochastic_effects)[0])


def _check_base(model: Model, bias: float, sf: float) -> None:
    """ValueError when an unconstrained base fit lands outside its range (never a silent clip)."""
    rng = BASE_RANGES[model.base.kind]
    for name, v in (("bias", bias), ("scale_factor", sf)):
        lo, hi = rng[name]
        if not (lo <= v <= hi) or not np.isfinite(v):
            raise ValueError(f"calibrated {name} = {v:.6g} outside the allowed range [{lo}, {hi}] for a "
                             f"{model.base.kind}: wrong unit or missing input column?")


def calibrate(model: Model, rec: Record, *, noise: bool = True, max_nfev: int = 200,
              frozen: frozenset[str] = frozenset()) -> Model:
    """The model with ALL its parameters fitted to ``rec`` by bounded least squares (issue 7,
    step a: bias, scale factor when the input is logged and varies, and every parameter of the
    waveform effects already in it — time constants, frequencies, delays too, so a frozen
    shape misfit does not linger in the residual as colour), starting from the current values,
    each bounded by its range; with ``noise``, the white-noise sd is set to the residual's
    high-frequency floor. Random processes and histogram-judged effects keep their values (the
    workflow re-estimates the processes on the new residual); so do the effects named in
    ``frozen`` (a long record's slow effects while its full-rate window is searched).

    Bias and scale factor are first solved linearly (unconstrained); outside the kind's range
    that is a ValueError naming the value (a wrong unit or a missing input column), never a clip."""
    sf_free = _sf_free(rec)
    u = rec.column("input") if sf_free else None
    rest = model.predict(rec) - model.base.bias - (model.base.scale_factor * u if u is not None else 0.0)
    cols = [np.ones(rec.n)] + ([u] if u is not None else [])
    coef, *_ = np.linalg.lstsq(np.column_stack(cols), rec.y - rest, rcond=None)
    bias = float(coef[0])
    sf = float(coef[1]) if sf_free else float(model.base.scale_factor)
    _check_base(model, bias, sf)
    model = model.with_base(bias=bias, scale_factor=sf)
    slots = _slots(model, rec, frozen)
    # through a quantizer the prediction E[Q(x + n)] depends on the noise before it: that sd is
    # a parameter of the prediction, fitted with the rest (the conditional mean minimises the
    # squared error, so least squares finds it), starting from the measured floor's inversion
    dithered = noise and any(e.mean_depends_on_noise for e, _ in model.entries())
    if dithered:
        floor = white_floor_sd(rec.y - model.predict(rec), rec.rate_hz, model.stochastic_effects())
        floor = float(min(floor, BASE_RANGES[model.base.kind]["noise_sd"][1]))
        if floor > 0 and np.isfinite(floor):
            model = model.with_noise_floor(floor)
            slots.append(_Slot("noise", "noise_sd", floor=floor))
    if len(slots) > (2 if sf_free else 1):  # effects with parameters: the joint nonlinear fit
        x0, lo, hi, sc = _coords(model, slots, rec)
        x0 = np.clip(x0, lo, hi)
        y = rec.y
        start = model

        def fun(x: np.ndarray) -> np.ndarray:
            return y - _at(start, slots, x).predict(rec)

        try:
            res = optimize.least_squares(fun, x0, bounds=(lo, hi), x_scale=sc, max_nfev=max_nfev, method="trf")
            if np.sum(res.fun ** 2) < np.sum(fun(x0) ** 2):
                model = _at(start, slots, res.x)
        except (ValueError, np.linalg.LinAlgError):
            pass  # keep the linear calibration
        b = model.base
        for name in ("bias", "scale_factor"):
            lo_b, hi_b = BASE_RANGES[b.kind][name]
            v = getattr(b, name)
            if min(v - lo_b, hi_b - v) <= 1e-9 * (hi_b - lo_b):
                raise ValueError(f"calibrated {name} = {v:.6g} at the edge of the allowed range [{lo_b}, {hi_b}] "
                                 f"for a {b.kind}: wrong unit or missing input column?")
    if noise and not any(s.what == "noise" for s in slots):
        sd = white_floor_sd(rec.y - model.predict(rec), rec.rate_hz, model.stochastic_effects())
        sd = float(min(sd, BASE_RANGES[model.base.kind]["noise_sd"][1]))
        if sd > 0 and np.isfinite(sd):
            # the measured floor holds a quantizer's rounding too: the noise before it is less
            model = model.with_noise_floor(sd)
    return model
