"""A sensor model for the discrepancy workflow: base model + catalogue effects, and its TOML file.

Base model: ``y = bias + scale_factor · input`` (input absent → 0) plus white noise of sd
``noise_sd`` per sample, in the sensor unit (g or deg/s). Effects compose by stage, each stage
in the model's listed order: input-path transforms of ``input`` → base → additive terms
(stochastic ones and the white noise only in ``simulate``) → output transforms (saturation,
quantization), so the ADC's quantization sees the noisy signal as a real one does.

``predict`` is the expected reading: quantization acts on signal + noise, so its mean over the
white noise (sd ``noise_sd``, the noise *before* the quantizer) is predicted — the dithered
quantizer ``E[Q(x + n)]`` (``Effect.expected_transform``), never ``Q(x)``, whose staircase the
data do not have. A residual floor measured with quantization in the model includes the rounding
error: ``Model.with_noise_floor`` turns it into that noise sd. Saturation is predicted as the
noiseless clip: its mean bias ``E[clip(x + n)] − clip(x)`` lives only within a few noise sd of the
limit, readings beyond it sit exactly on the limit (as predicted), and while saturation is not
yet in the model the residual floor that would set the smoothing is inflated by the clipping
misfit itself (0.024 g for 5 µg true noise on the test experiment: the fitted limit was then
1.5e-4 g off instead of 1e-7 g). Slow stochastic effects (Gauss–Markov, random walk) move the
operating point rather than dither a reading, and are left out of the mean. Input-stage
transforms (dead zone, delay, filters) act on the applied input, which carries no sensor noise,
so their noiseless form is already the mean.
"""

from __future__ import annotations

import math
import tomllib
import zlib
from dataclasses import dataclass, field, replace

import numpy as np

from bench.discovery.data import Record
from bench.discovery.effects import CATALOGUE
from bench.discovery.effects_base import DEFAULT_NOISE_SD, KINDS, Effect, reference_input
from bench.discovery.effects_linalg import base_regressors, orthonormal, project_q
from bench.discovery.effects_noise import StochasticEffect
from bench.discovery.mapping import MapFn
from bench.discovery.whiten import innovations

#: Allowed base-parameter ranges per kind (sensor unit): a raw QA-2000 bias < 4 mg (allow 50 mg),
#: a FOG's ±1 deg/s (3600 deg/h), an MHD offset; scale factor normalised near 1; noise sd ≥ 0.
BASE_RANGES = {
    "accelerometer": {"bias": (-0.05, 0.05), "scale_factor": (0.5, 2.0), "noise_sd": (0.0, 0.1)},
    "gyro": {"bias": (-1.0, 1.0), "scale_factor": (0.5, 2.0), "noise_sd": (0.0, 10.0)},
    "mhd": {"bias": (-100.0, 100.0), "scale_factor": (0.5, 2.0), "noise_sd": (0.0, 10.0)},
}

#: Sample rates a model file may state (Hz).
RATE_RANGE_HZ = (1e-6, 1e9)


@dataclass(frozen=True)
class BaseModel:
    """Bias + scale factor + white noise (sensor unit; ``scale_factor`` output per input unit).

    ``noise_sd`` is per sample; ``rate_hz`` is the sample rate it was measured at (None: not
    recorded). The white-noise density ``noise_sd/√rate_hz`` (u/√Hz) is the physical constant:
    ``Model.at_rate`` carries the model to another rate."""

    kind: str
    bias: float = 0.0
    scale_factor: float = 1.0
    noise_sd: float = 0.0
    rate_hz: float | None = None

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"base.kind = {self.kind!r}; allowed: {list(KINDS)}")
        for name, (lo, hi) in BASE_RANGES[self.kind].items():
            v = getattr(self, name)
            if (isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating))
                    or not (lo <= float(v) <= hi)):
                raise ValueError(f"base.{name} = {v!r} outside the allowed range [{lo}, {hi}] for a {self.kind}")
            object.__setattr__(self, name, float(v))
        r = self.rate_hz
        if r is not None:
            if isinstance(r, bool) or not isinstance(r, (int, float, np.integer, np.floating)) \
                    or not (RATE_RANGE_HZ[0] <= float(r) <= RATE_RANGE_HZ[1]):
                raise ValueError(f"base.rate_hz = {r!r} outside the allowed range {list(RATE_RANGE_HZ)} Hz")
            object.__setattr__(self, "rate_hz", float(r))


def base_model(kind: str) -> BaseModel:
    """Default base model per kind: zero bias, unit scale factor, the kind's typical noise sd
    (accelerometer 5 µg at ~1 Hz readings, FOG 3e-3 deg/s at 10 Hz, MHD 0.06 deg/s at 1 kHz)."""
    if kind not in KINDS:
        raise ValueError(f"sensor kind {kind!r}; allowed: {list(KINDS)}")
    return BaseModel(kind=kind, bias=0.0, scale_factor=1.0, noise_sd=DEFAULT_NOISE_SD[kind])


@dataclass(frozen=True)
class Model:
    """Base model + effects ``((id, {param: value}), ...)`` in the order found/applied."""

    base: BaseModel
    effects: tuple[tuple[str, dict], ...] = field(default=())

    def __post_init__(self) -> None:
        checked = []
        seen: dict[str, int] = {}
        for i, item in enumerate(self.effects):
            if not (isinstance(item, (tuple, list)) and len(item) == 2 and isinstance(item[1], dict)):
                raise ValueError(f"effects[{i}] = {item!r}; allowed: (effect_id, {{param: value}})")
            eid, params = item
            e = CATALOGUE.effect(eid)
            if eid in seen:  # one entry per effect: a second copy would double its term
                raise ValueError(f"effects[{i}]: effect {eid!r} is listed twice (also effects[{seen[eid]}]); "
                                 f"allowed: each effect once, with all its parameters")
            seen[eid] = i
            if self.base.kind not in e.kinds:
                raise ValueError(f"effects[{i}]: {eid!r} does not apply to a {self.base.kind}; "
                                 f"it applies to {list(e.kinds)}")
            checked.append((eid, e.check_params(params, self.base.kind)))
        object.__setattr__(self, "effects", tuple(checked))

    @property
    def effect_ids(self) -> tuple[str, ...]:
        return tuple(eid for eid, _ in self.effects)

    def entries(self) -> list[tuple[Effect, dict]]:
        """Each effect of the model (the catalogue's entry) with its parameters, in order."""
        return [(CATALOGUE[eid], p) for eid, p in self.effects]

    def stochastic_effects(self) -> list[tuple[StochasticEffect, dict]]:
        """The model's random processes with their parameters, in order."""
        return [(e, p) for e, p in self.entries() if isinstance(e, StochasticEffect)]

    def with_effect(self, effect_id: str, params: dict) -> Model:
        """This model with one more effect (validated against the kind's ranges)."""
        return Model(self.base, self.effects + ((effect_id, dict(params)),))

    def with_params(self, index: int, params: dict) -> Model:
        """This model with effect ``index``'s parameters replaced."""
        if not 0 <= index < len(self.effects):
            raise ValueError(f"effect index {index!r}; allowed: 0..{len(self.effects) - 1}")
        eff = list(self.effects)
        eff[index] = (eff[index][0], dict(params))
        return Model(self.base, tuple(eff))

    def with_base(self, **changes) -> Model:
        """This model with base fields replaced (e.g. ``bias=``, ``scale_factor=``)."""
        return Model(replace(self.base, **changes), self.effects)

    def at_rate(self, rate_hz: float) -> Model:
        """This model for records sampled at ``rate_hz``: the white-noise sd per sample scaled by
        ``√(rate_hz / base.rate_hz)`` (constant density); with no recorded rate, the rate is
        recorded and noise_sd kept (it is taken to be per sample at ``rate_hz``)."""
        b = self.base
        new = replace(b, rate_hz=rate_hz)  # validates the rate
        if b.rate_hz is None or b.rate_hz == new.rate_hz:
            return Model(new, self.effects)
        sd = b.noise_sd * math.sqrt(float(rate_hz) / b.rate_hz)
        return Model(replace(new, noise_sd=sd), self.effects)

    def residual_sd(self) -> float:
        """White sd of ``y − predict`` this model expects (its noise floor, sensor unit):
        ``noise_sd`` passed through the output transforms' ``residual_var`` (quantization adds
        its rounding share); the inverse of ``with_noise_floor``."""
        v = self.base.noise_sd ** 2
        for e, p in self.entries():
            if e.stage == "output":
                v = e.residual_var(p, math.sqrt(v))
        return math.sqrt(v)

    def residual_profile(self, rec: Record, wander_sd: float = 0.0,
                         offset: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(variance, fourth central moment) of ``y − predict`` per sample on rec: ``noise_sd²``
        and Gaussian everywhere without an output stage; through a coarse quantizer or a clipping
        they follow where the signal sits (``Effect.residual_moments_at``) — a reading on a
        lattice level barely moves and then by a whole step, one between two levels flips.
        ``wander_sd``: sd of the slow offset the model's random processes add before the output
        stage (it moves the signal along the lattice); ``offset``: where they moved it, estimated
        on the record (sensor unit, per sample) — the wander is then that estimate's own error."""
        b = self.base
        var = np.full(rec.n, b.noise_sd ** 2)
        m4 = 3 * var * var
        if not self.has_output_stage():
            return var, m4
        u, add = self.stages(rec)
        y = b.bias + b.scale_factor * u + add + (0.0 if offset is None else np.asarray(offset, float))
        sd = b.noise_sd
        for e, p in self.entries():
            if e.stage == "output":
                var, m4 = e.residual_moments_at(p, rec, y, sd, wander_sd)
                y = e.expected_transform(p, rec, y, sd)
                sd = math.sqrt(float(np.mean(var)))
        return var, m4

    def effect_snr(self, rec: Record, index: int) -> float:
        """Signal-to-noise ratio on rec of effect ``index`` *inside this model*: what tells its
        term apart from everything else the model holds — its contribution to ``predict`` with
        the base regressors and every other deterministic effect's parameter directions (the
        model's Jacobian in the parameters a fit moves, ``Effect.free_params``: what a joint fit
        of them could absorb) projected out — against
        the model's whole noise, white ``noise_sd`` plus its random processes (both sides
        Kalman-whitened: generalised least squares). Alone in a model without processes this is
        the plain snr of ``Effect.snr`` (no look-alike taken out); beside a strong random walk
        or a thermal term that can bend into it, it can be a small fraction of that — a mixture
        of a 15-sigma temperature bias and a walk can hold too little of the bias for any
        method to name it. A random process: its own snr (``Effect.snr``, excess Allan variance)
        against the white floor of the readings without it (``residual_sd``: a coarse quantizer's
        rounding counts, as in the naming's size gate — a Gauss–Markov 39σ above white noise is
        7σ behind a quantizer of 8σ steps). NaN for an output-stage transform (its size is judged
        on the readings' own statistics, not on a waveform)."""
        if not 0 <= index < len(self.effects):
            raise ValueError(f"effect index {index!r}; allowed: 0..{len(self.effects) - 1}")
        entries = self.entries()
        eff, own = entries[index]
        without = Model(self.base, self.effects[:index] + self.effects[index + 1:])
        if eff.stage == "output":
            return math.nan
        if eff.stochastic:
            return float(eff.snr(own, rec, without.residual_sd()))
        here = self.predict(rec)
        cols = [base_regressors(rec)]
        for j, (other, p) in enumerate(entries):
            if j == index or other.stochastic or other.stage == "output":
                continue
            for name in (q.name for q in other.free_params(p, self.base.kind, rec)):  # not an unused slot's
                v = p[name]
                h = 1e-4 * abs(v) if v != 0 else 1e-9
                try:
                    d = (self.with_params(j, {**p, name: v + h}).predict(rec) - here) / h
                except ValueError:  # at the top of its range: the step the other way
                    d = (here - self.with_params(j, {**p, name: v - h}).predict(rec)) / h
                nrm = float(np.linalg.norm(d))
                if nrm > 0 and math.isfinite(nrm):
                    cols.append((d / nrm)[:, None])
        a = np.column_stack(cols)
        procs = self.stochastic_effects()
        sd = self.base.noise_sd

        def whiten(v: np.ndarray) -> np.ndarray:
            return innovations(v, rec.rate_hz, sd, procs) if procs else v / sd
        delta = whiten(here - without.predict(rec))
        w = np.column_stack([whiten(c) for c in a.T])
        return float(np.linalg.norm(project_q(delta, orthonormal(w))))

    def with_noise_floor(self, floor_sd: float) -> Model:
        """This model with ``noise_sd`` set so that its residual ``y − predict`` has white sd
        ``floor_sd`` (what a calibration measures): equal without output transforms; with
        quantization the floor holds the rounding error too, and the noise sd before the
        quantizer solves ``Effect.residual_var(σ) = floor_sd²`` (bisection; σ ≤ floor_sd)."""
        if not (floor_sd >= 0 and math.isfinite(floor_sd)):
            raise ValueError(f"floor_sd = {floor_sd!r}; allowed: a finite value >= 0")
        target = float(floor_sd)
        lo, hi = 0.0, target
        if self.with_base(noise_sd=hi).residual_sd() > target:
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                lo, hi = (mid, hi) if self.with_base(noise_sd=mid).residual_sd() < target else (lo, mid)
        return self.with_base(noise_sd=hi)

    def predict(self, rec: Record) -> np.ndarray:
        """Expected output on rec's stimulus: the deterministic signal, through quantization its
        mean over the white noise — readings are Q(signal + noise), whose mean is the dithered
        quantizer, not Q(signal) (module docstring)."""
        return self._run(rec, None)

    def simulate(self, rec: Record, rng) -> np.ndarray:
        """predict + stochastic effects + white noise. ``rng``: a numpy Generator or an int seed.
        One integer is drawn from rng; each stochastic component then gets its own stream
        seeded from (that integer, crc32 of its name), so same seed → same output and adding
        an effect never changes another component's noise."""
        return self._run(rec, _root(_generator(rng)))

    def has_output_stage(self) -> bool:
        """True when an effect of the model transforms the whole output (saturation, quantization)."""
        return any(e.stage == "output" for e, _ in self.entries())

    def follows_input(self, rec: Record) -> np.ndarray:
        """Samples where the output follows a small change of the signal before the output stage:
        the secant gain of ``predict`` over one white-noise sd added to the bias is above one
        half — False where a saturation clips or a dead zone swallows it (a missing term leaves
        no trace in the residual there); all True without an output stage (the dithered mean of
        a quantizer follows its input)."""
        if not self.has_output_stage():
            return np.ones(rec.n, bool)
        step = math.copysign(self.base.noise_sd or 1e-9, -self.base.bias)  # toward 0: inside the range
        moved = Model(replace(self.base, bias=self.base.bias + step), self.effects)
        return np.asarray((moved.predict(rec) - self.predict(rec)) / step > 0.5)

    def noise_seen(self, rec: Record) -> np.ndarray:
        """Samples whose readings carry the model's noise: False where an output stage censors it
        (``Effect.observes_noise``: a saturation's clipped stretches), judged on the mean signal
        before it; all True without such a stage. A random process is carried across the others
        by its dynamics (``whiten.innovations(seen=…)``), not read from their flat residual."""
        seen = np.ones(rec.n, bool)
        if not self.has_output_stage():
            return seen
        u, add = self.stages(rec)
        y = self.base.bias + self.base.scale_factor * u + add
        for e, p in self.entries():
            if e.stage == "output":
                seen &= e.observes_noise(p, y)
                y = e.expected_transform(p, rec, y, self.base.noise_sd)
        return seen

    def partly_seen(self, rec: Record) -> np.ndarray | None:
        """:meth:`noise_seen` when an output stage censors some of the samples but not all of
        them — the mask a likelihood or an innovation test leaves them out by — else None."""
        seen = self.noise_seen(rec)
        return seen if seen.any() and not seen.all() else None

    def stages(self, rec: Record) -> tuple[np.ndarray, np.ndarray]:
        """(input after the model's input-stage effects, sum of its deterministic additive terms)
        on rec: ``predict`` is ``bias + scale_factor·u + terms`` when the model has no output
        stage (a fit that varies only the base and one more effect reuses them)."""
        u = reference_input(rec)
        staged = self.entries()
        for e, p in staged:
            if e.stage == "input":
                e.check_inputs(rec)
                u = e.transform_input(p, rec, u)
        add = np.zeros(rec.n)
        for e, p in staged:
            if e.stage == "additive" and not isinstance(e, StochasticEffect):
                e.check_inputs(rec)
                add = add + e.term(p, rec)
        return u, add

    def simulate_noise(self, rec: Record, rng) -> np.ndarray:
        """``simulate(rec, rng) − predict(rec)``: one realisation of the model's own noise (white +
        its random processes), the same numbers for the same rng; without an output stage it is
        drawn alone, not as a difference of two full predictions (a null of many replicates)."""
        return self._noise_from_root(rec, _root(_generator(rng)))

    def simulate_noise_many(self, rec: Record, rng, m: int, *, fill_map: MapFn = map) -> np.ndarray:
        """(n, m): ``m`` successive :meth:`simulate_noise` draws from ``rng`` as columns (the same
        numbers), each realisation written in place into its row of an (m, n) array seen
        transposed — how a null's scorer reads replicates (no stacking, no copy). (Built in
        worker processes they cost more CPU in moving 1.4 MB a realisation than they saved.)
        Each realisation comes from its own root, drawn from ``rng`` first, so ``fill_map`` may
        fill them in any order or side by side — a thread pool's ``map``: numpy's normal draws and
        the compiled recursions release the GIL — with the same numbers."""
        rng = _generator(rng)
        if isinstance(m, bool) or int(m) != m or m < 0:
            raise ValueError(f"m = {m!r}; allowed: an integer >= 0")
        roots = [_root(rng) for _ in range(int(m))]
        out = np.empty((int(m), rec.n))

        def fill(j: int) -> None:
            self._noise_from_root(rec, roots[j], out[j])

        for _ in fill_map(fill, range(int(m))):
            pass
        return out.T

    def _noise_from_root(self, rec: Record, root: int, out: np.ndarray | None = None) -> np.ndarray:
        """One realisation of the model's noise from the streams seeded by ``root`` (into
        ``out`` when given: a row of a null, filled in place)."""
        y = np.empty(rec.n) if out is None else out
        if self.has_output_stage():
            np.subtract(self._run(rec, root), self.predict(rec), out=y)
            return y
        y[:] = 0.0
        for i, (e, p) in enumerate(self.entries()):
            if e.stage == "additive" and isinstance(e, StochasticEffect):
                e.check_inputs(rec)
                y += e.noise(p, rec, _stream(root, f"{i}:{e.id}"))
        if self.base.noise_sd > 0:
            white = _stream(root, "white").standard_normal(rec.n)
            white *= self.base.noise_sd
            y += white
        return y

    def _run(self, rec: Record, root: int | None) -> np.ndarray:
        b = self.base
        staged = self.entries()
        u, add = self.stages(rec)
        y = b.bias + b.scale_factor * u + add
        for i, (e, p) in enumerate(staged):
            if e.stage == "additive" and isinstance(e, StochasticEffect) and root is not None:
                e.check_inputs(rec)
                y = y + e.noise(p, rec, _stream(root, f"{i}:{e.id}"))
        if root is not None and b.noise_sd > 0:
            y = y + b.noise_sd * _stream(root, "white").standard_normal(rec.n)
        for e, p in staged:
            if e.stage == "output":
                # a reading is the transformed noisy signal: predict its mean, simulate it
                y = e.transform(p, rec, y) if root is not None else e.expected_transform(p, rec, y, b.noise_sd)
        return y


def _generator(rng) -> np.random.Generator:
    """``rng`` as a Generator: a Generator itself, or an int seed (ValueError otherwise)."""
    if isinstance(rng, (int, np.integer)):
        return np.random.default_rng(int(rng))
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng = {rng!r}; allowed: a numpy Generator or an int seed")
    return rng


def _root(rng: np.random.Generator) -> int:
    """The one integer a realisation draws from the caller's generator: its streams' seed."""
    return int(rng.integers(0, 2 ** 63))


def _stream(root: int, name: str) -> np.random.Generator:
    return np.random.default_rng([root, zlib.crc32(name.encode())])


# ---- the model file -------------------------------------------------------------------------

def model_to_dict(model: Model) -> dict:
    """Plain dict (the TOML document's structure)."""
    b = model.base
    base = {"kind": b.kind, "bias": b.bias, "scale_factor": b.scale_factor, "noise_sd": b.noise_sd}
    if b.rate_hz is not None:
        base["rate_hz"] = b.rate_hz
    return {"base": base,
            "effects": [{"id": eid, "params": dict(p)} for eid, p in model.effects]}


def model_from_dict(doc: dict) -> Model:
    """Inverse of model_to_dict, validating keys, types and ranges (ValueError naming them)."""
    if not isinstance(doc, dict):
        raise ValueError(f"model document is {type(doc).__name__}; allowed: a table with [base] and [[effects]]")
    extra = sorted(set(doc) - {"base", "effects"})
    if extra:
        raise ValueError(f"unknown top-level key(s) {extra}; allowed: ['base', 'effects']")
    base = doc.get("base")
    if not isinstance(base, dict):
        raise ValueError("missing [base] table; required keys: ['kind', 'bias', 'scale_factor', 'noise_sd']")
    keys = {"kind", "bias", "scale_factor", "noise_sd"}
    if not keys <= set(base) <= keys | {"rate_hz"}:
        raise ValueError(f"[base] keys {sorted(base)}; required: {sorted(keys)}, optional: ['rate_hz']")
    bm = BaseModel(**base)
    effects = doc.get("effects", [])
    if not isinstance(effects, list):
        raise ValueError(f"effects = {effects!r}; allowed: an array of tables [[effects]]")
    out = []
    for i, item in enumerate(effects):
        if not isinstance(item, dict) or set(item) - {"id", "params"} or "id" not in item:
            raise ValueError(f"effects[{i}] = {item!r}; allowed keys: id (string), params (table)")
        params = item.get("params", {})
        if not isinstance(params, dict):
            raise ValueError(f"effects[{i}].params = {params!r}; allowed: a table of numbers")
        for k, v in params.items():
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise ValueError(f"effects[{i}].params.{k} = {v!r} is not a number")
        out.append((str(item["id"]), dict(params)))
    return Model(bm, tuple(out))


def _fmt(v) -> str:
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    f = float(v)
    if math.isinf(f):
        return "inf" if f > 0 else "-inf"
    return repr(f)  # shortest repr: reads back bit for bit


def model_to_toml(model: Model) -> str:
    """The model file's text."""
    d = model_to_dict(model)
    lines = ["# inertial-bench discrepancy model: base (bias + scale factor + white noise) and effects",
             "[base]"]
    lines += [f"{k} = {_fmt(v)}" for k, v in d["base"].items()]
    for e in d["effects"]:
        lines += ["", "[[effects]]", f"id = {_fmt(e['id'])}", "[effects.params]"]
        lines += [f"{k} = {_fmt(v)}" for k, v in e["params"].items()]
    return "\n".join(lines) + "\n"


def model_from_toml(text: str) -> Model:
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"model file is not valid TOML: {exc}") from None
    return model_from_dict(doc)
