"""The common machinery of catalogue effects: parameters, detectability, drawing, fit starts, and
the hooks through which the workflow asks an effect about itself.

Conventions
-----------
* ``u`` is the sensor's unit: g for accelerometers, deg/s for gyros and the MHD sensor;
  parameter names carry the kind-independent part of the unit (``_s``, ``_hz``, ``_per_c``)
  and ``Param.unit`` spells the full unit for the kind.
* An effect acts at one *stage* of the signal path (``Model.predict`` composes them so):
  ``"input"`` transforms the applied input before the scale factor (time_delay,
  lowpass_bandwidth, highpass_rolloff, dead_zone); ``"additive"`` adds a term to the output;
  ``"output"`` transforms the whole output (saturation, then quantization: the ADC comes last).
  ``Effect.apply(p, rec, y_ideal)`` applies the effect on its own: for input-stage effects it
  adds ``F[input] - input`` (unit scale factor; ``Model`` uses the exact ``SF·F[input]``).
* Detectability: the signature's signal-to-noise ratio ``snr(p, rec, noise_sd)``. For a
  deterministic effect it is ``||P⊥ Δ|| / noise_sd``: Δ the change the effect makes to the
  reference output (``y = input``, or 0 without an input) and P⊥ the projection away from the
  base model's calibration regressors (1 and the input), so what a recalibration of bias and
  scale factor absorbs does not count — and, for an effect with look-alikes (``competitors``),
  away from the best-matching signature of each, so it measures how well the effect can be told
  from them. Stochastic and quantization effects override it.
  ``min_effect`` is the main parameter's magnitude at ``snr = MIN_SNR`` (5), never below the
  physically meaningful floor of the kind; ``draw`` picks the main parameter so that
  ``snr`` is between ``DRAW_SNR_FACTOR * MIN_SNR`` (15; for effects linear in their main
  parameter that is ``|main| >= 3 * min_effect``) and ``DRAW_SPAN`` (30) times that, inside the
  kind's physical range (log-uniform in the main parameter between the two). Other parameters
  are drawn where the record can resolve them.

Families (how the naming step judges a candidate): an :class:`Effect` is a *waveform* — its
prediction is fitted by least squares, and calibration refits its parameters;
``bench.discovery.effects_noise.StochasticEffect`` is a random process judged on the residual's
spectral shape; :class:`HistogramEffect` is judged on the histogram of the readings.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from bench.discovery.data import Record
from bench.discovery.effects_linalg import base_regressors, orthonormal, project_out, project_q, vdot

KINDS = ("accelerometer", "gyro", "mhd")
UNIT = {"accelerometer": "g", "gyro": "deg/s", "mhd": "deg/s"}
#: White-noise sd per sample assumed when none is given and the record cannot tell (u).
DEFAULT_NOISE_SD = {"accelerometer": 5e-6, "gyro": 3e-3, "mhd": 0.06}
MIN_SNR = 5.0
DRAW_SNR_FACTOR = 3.0
DRAW_SPAN = 30.0
#: Starting points a grid search keeps for a nonlinear fit (:func:`grid_starts`).
N_STARTS = 3

#: Golden-section steps and bracket (log units) at which ``direction_matching`` stops on a
#: main parameter.
MATCH_STEPS = 80
MATCH_XTOL = 1e-9

#: An effect's parameter values by name (in the kind's units).
Params = dict[str, float]


@dataclass(frozen=True)
class Param:
    """One parameter: physical range ``[low, high]`` (inclusive) in ``unit``.

    ``log``: positive and drawn/gridded on a log scale; ``linear``: the effect's output is
    linear in it (a least-squares parameter); ``floor``: smallest physically meaningful
    magnitude (a coefficient below it is indistinguishable from zero for this sensor class).
    ``[fit_low, fit_high]``: what a fit may return and a model may hold (default, and never
    narrower than, ``[low, high]``) — wider where the fit range comes from the record for any
    sensor grade (a random process, a quantizer: :meth:`Effect.fit_range`) while draws keep to
    the physical envelope ``[low, high]`` of the grades the kind was set for."""

    name: str
    unit: str
    low: float
    high: float
    log: bool = False
    linear: bool = False
    floor: float = 0.0
    fit_low: float = math.nan
    fit_high: float = math.nan

    def __post_init__(self) -> None:
        for name in ("low", "high", "floor"):
            object.__setattr__(self, name, float(getattr(self, name)))
        # never narrower than the physical range: a drawn value is always one a model may hold
        object.__setattr__(self, "fit_low", min(float(self.fit_low), self.low)
                           if not math.isnan(self.fit_low) else self.low)
        object.__setattr__(self, "fit_high", max(float(self.fit_high), self.high)
                           if not math.isnan(self.fit_high) else self.high)

    @property
    def periodic(self) -> bool:
        """A phase spanning one full turn: it wraps, so an optimiser must not meet a wall at ±π."""
        return self.unit == "rad" and "phase" in self.name and self.high - self.low >= 2 * math.pi - 1e-9

    def check(self, value: Any, effect_id: str = "") -> float:
        """The value as float, or ValueError naming it and the allowed range."""
        where = f"{effect_id}.{self.name}" if effect_id else self.name
        try:
            v = float(value)
        except (TypeError, ValueError):
            raise ValueError(f"{where} = {value!r} is not a number; "
                             f"allowed: [{self.fit_low}, {self.fit_high}] {self.unit}") from None
        if not (self.fit_low <= v <= self.fit_high and math.isfinite(v)):
            raise ValueError(f"{where} = {v!r} outside the allowed range [{self.fit_low}, {self.fit_high}] "
                             f"{self.unit}")
        return v

    def edge(self, value: float) -> str:
        """``"lower"`` or ``"upper"`` when ``value`` lies within :data:`EDGE_FRACTION` of this
        range (of its log-range for a log parameter) of that bound, or beyond it; else ``""``.
        Meant for a fit range (:meth:`Effect.fit_params`), where it says a fit stopped at a bound.

        A phase that wraps has no bound. A magnitude whose range starts at 0 (0: the effect absent)
        with a ``floor`` is judged on its log range from the floor: its scale, not its distance
        from 0 in units of the whole range, says whether a bound set it (a 3 mdeg/s line in a
        range of 0 … 1 deg/s is well inside it, a 2 µdeg/s one is at the floor)."""
        if self.periodic:
            return ""
        v, lo, hi = float(value), self.low, self.high
        if not self.log and lo == 0.0 and self.floor > 0.0:
            if abs(v) <= self.floor:
                return "lower"
            v, lo, hi = math.log(abs(v)), math.log(self.floor), math.log(hi)
        elif self.log and lo > 0 and v > 0:
            v, lo, hi = math.log(v), math.log(lo), math.log(hi)
        tol = EDGE_FRACTION * (hi - lo)
        if not math.isfinite(tol):
            return ""
        if v <= lo + tol:
            return "lower"
        return "upper" if v >= hi - tol else ""


#: A fitted value within this fraction of its fit range (of its log-range for a log parameter)
#: of a bound is at that bound: the data-derived ranges span 4-12 decades, so 1 % is a factor
#: 1.1-1.3 in the value — inside the spread of a fitted level or correlation time, so the bound,
#: not the record, may have set it (an estimate that would leave the range is clipped there).
EDGE_FRACTION = 0.01


def at_edge(effect: Effect, params: Mapping[str, float], rec: Record, kind: str) -> tuple[str, ...]:
    """Names of ``effect``'s parameters whose value in ``params`` lies at (within
    :data:`EDGE_FRACTION` of) or beyond a bound of its fit range on rec (:meth:`Effect.fit_params`):
    a report then says the range, not the record, stopped the fit. Only the parameters a fit
    moves (:meth:`Effect.free_params`: not an unused jump slot's time) count, each in the fit
    range narrowed by the bounds the fit keeps it in (a jump's time: inside the record)."""
    free = {q.name: q for q in effect.free_params(params, kind, rec)}
    physical = {q.name: q for q in effect.params_for(kind)}
    out = []
    for q in effect.fit_params(rec, kind):
        f = free.get(q.name)
        if f is None or q.name not in params:
            continue
        # the fit keeps the parameter inside the free bounds only where they narrow its range
        narrowed = (f.low, f.high) != (physical[q.name].low, physical[q.name].high)
        lo, hi = (max(q.low, f.low), min(q.high, f.high)) if narrowed else (q.low, q.high)
        if (replace(q, low=lo, high=hi) if lo < hi else q).edge(params[q.name]):
            out.append(q.name)
    return tuple(out)


def edge_notes(effect_id: str, params: Mapping[str, float], bounds: Sequence[Param]) -> tuple[str, ...]:
    """One line per parameter of ``params`` at a bound of its fit range ``bounds`` (Params of
    :meth:`Effect.fit_params`): ``"gauss_markov.tau_s at its upper bound 3600 s"``."""
    out = []
    for q in bounds:
        side = q.edge(params[q.name]) if q.name in params else ""
        if side:
            out.append(f"{effect_id}.{q.name} at its {side} bound {q.low if side == 'lower' else q.high:.4g} {q.unit}")
    return tuple(out)


def guess_kind(rec: Record) -> str:
    """Sensor kind from the record alone: inputs beyond 5 (a rate in deg/s) mean a gyro,
    otherwise an accelerometer (g). Pass ``kind`` explicitly when it is known."""
    if rec.input is not None and float(np.max(np.abs(rec.input))) > 5.0:
        return "gyro"
    return "accelerometer"


def noise_sd_of(rec: Record, kind: str) -> float:
    """Robust white-noise sd of ``rec.y`` from first differences (MAD), else the kind's default."""
    d = np.diff(rec.y)
    s = float(1.4826 * np.median(np.abs(d - np.median(d))) / math.sqrt(2.0))
    return s if s > 0 else DEFAULT_NOISE_SD[kind]


def reference_input(rec: Record) -> np.ndarray:
    """The applied input, or zeros when none was logged (the output then is bias alone)."""
    return rec.input.copy() if rec.input is not None else np.zeros(rec.n)


class Effect:
    """One catalogue entry: a *waveform* effect (its prediction fitted by least squares).
    Subclasses set the class attributes and implement the hook of their stage (``term``,
    ``transform_input`` or ``transform``); the rest have defaults to override where the effect
    differs.

    Declaration: ``id``, ``description``, ``form``, ``inputs`` (logged columns needed),
    ``main_param``, ``signature``, ``stage``, ``kinds`` (sensor kinds it applies to),
    ``identity`` (main-parameter value that leaves the output unchanged), ``increasing`` (a
    larger main parameter is a larger effect; False for a bandwidth or a saturation limit),
    ``ranges`` (kind -> tuple of Param), ``needs_uniform`` (a sampled filter: the record must be
    uniform to 0.1 %).

    Relations to other entries, by id (the catalogue makes both symmetric, so they are declared
    once, on either effect of a pair): ``competitors`` — effects whose signature this one
    resembles on typical records (its snr counts only what they cannot absorb; the instances
    arrive as ``look_alikes`` when the catalogue builds it); ``separating`` — id -> the
    experiment that tells the two apart.

    Family (how the workflow treats it): ``stochastic`` (a random process), ``waveform``
    (calibration refits its parameters; False for random processes and histogram-judged effects,
    whose residual floor the gap then simulates), ``mean_depends_on_noise`` (an output transform
    whose mean reading depends on the noise before it: calibration fits the noise sd with it).

    Hooks the search and the criterion ask: ``applies_to`` (does the record carry what it needs:
    its logged columns, varying), ``identifiable`` (can the record resolve these parameters at
    all: a fit it cannot is no model), ``search_cells`` (how many positions its fit searched —
    the criterion's multiplicity M), ``components`` (the parts the criterion charges one by one:
    each line of a sinusoid, as if it were added alone; ``joined`` puts parts together),
    ``prefixes`` (shorter versions of a fit, each scored: a jump's fewer change points, a
    sinusoid's fewer lines), ``fit_params`` (the range a fit may move in on a record, any sensor
    grade), ``per_sample`` (judged on each reading: not on a long record's block means),
    ``aliases`` (what a fit on block means could stand for) and ``time_shifted`` (the same term
    on a record starting earlier). The fit asks ``free_params`` (which parameters a fit moves; a
    jump's unused slots stay put) and ``coordinate_scale`` (the optimiser's scale of a parameter
    on rec)."""

    id: str = ""
    description: str = ""
    form: str = ""
    inputs: tuple[str, ...] = ()
    main_param: str = ""
    signature: str = ""
    stochastic: bool = False
    waveform: bool = True
    mean_depends_on_noise: bool = False
    stage: str = "additive"
    kinds: tuple[str, ...] = KINDS
    identity: float = 0.0
    increasing: bool = True
    ranges: Mapping[str, tuple[Param, ...]] = {}
    competitors: tuple[str, ...] = ()
    separating: Mapping[str, str] = {}
    draw_span_main: float = DRAW_SPAN
    threshold_log_tol: float = 1e-3  # bisection width (log of the main parameter) of a threshold
    needs_uniform: bool = False  # a sampled filter: every interval within 0.1 % of the median

    @property
    def per_sample(self) -> bool:
        """Judged on the record's own readings — an output stage acts on each reading (a
        quantizer's lattice, a clip), which block means of them do not keep (the means of
        readings on a lattice of step q lie on one of step q/m): a long record's block means are
        not searched for it."""
        return self.stage == "output"

    def __init__(self, look_alikes: Sequence[Effect] = ()) -> None:
        """``look_alikes``: the competitor effects themselves (the catalogue passes them); an
        effect built without them judges its snr plainly."""
        self.look_alikes: tuple[Effect, ...] = tuple(look_alikes)

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"

    # ---- parameters -------------------------------------------------------------------
    @property
    def params(self) -> tuple[Param, ...]:
        """Envelope of the physical ranges over the kinds (unit: each kind's unit listed)."""
        per = [self.ranges[k] for k in self.kinds]
        out = []
        for i, p in enumerate(per[0]):
            lo = min(q[i].low for q in per)
            hi = max(q[i].high for q in per)
            fl = min(q[i].floor for q in per)
            units = [q[i].unit for q in per]
            unit = units[0] if len(set(units)) == 1 else " | ".join(f"{u} ({k})" for u, k in zip(units, self.kinds))
            out.append(replace(p, low=lo, high=hi, floor=fl, unit=unit, fit_low=min(q[i].fit_low for q in per),
                               fit_high=max(q[i].fit_high for q in per)))
        return tuple(out)

    def params_for(self, kind: str) -> tuple[Param, ...]:
        """The physical ranges for one sensor kind (ValueError for a kind it does not apply to)."""
        if kind not in self.ranges:
            raise ValueError(f"effect {self.id!r} does not apply to kind {kind!r}; allowed: {list(self.kinds)}")
        return self.ranges[kind]

    def fit_params(self, rec: Record, kind: str) -> tuple[Param, ...]:
        """The kind's parameters with the ranges a fit on rec uses (``fit_range``) as ``[low,
        high]``, kept inside what a model may hold (``[fit_low, fit_high]``: the physical range
        unless the effect's parameters reach beyond it): e.g. a warm-up tau longer than half the
        record is a linear drift on it, a line above the Nyquist frequency an alias; a random
        process's levels and times come from the record alone, for any sensor grade. Same names
        and order as ``params_for(kind)``; a parameter whose range on rec is empty keeps its own."""
        out = []
        for q in self.params_for(kind):
            lo, hi = self.fit_range(q, rec, kind)
            lo, hi = max(lo, q.fit_low), min(hi, q.fit_high)
            out.append(replace(q, low=lo, high=hi) if lo < hi else q)
        return tuple(out)

    def fit_range(self, q: Param, rec: Record, kind: str) -> tuple[float, float]:
        """The range of one parameter a fit on rec uses (override per effect; default: the
        physical range; :meth:`fit_params` keeps it within ``[q.fit_low, q.fit_high]``)."""
        return q.low, q.high

    def param(self, name: str, kind: str | None = None) -> Param:
        for p in (self.params_for(kind) if kind else self.params):
            if p.name == name:
                return p
        raise ValueError(f"effect {self.id!r} has no parameter {name!r}; allowed: {self.param_names}")

    @property
    def param_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.ranges[self.kinds[0]])

    def check_params(self, p: Mapping[str, object], kind: str | None = None) -> Params:
        """Validated copy of p (floats): every parameter present, none unknown, each in range."""
        names = self.param_names
        unknown = sorted(set(p) - set(names))
        if unknown:
            raise ValueError(f"effect {self.id!r}: unknown parameter(s) {unknown}; allowed: {list(names)}")
        missing = [n for n in names if n not in p]
        if missing:
            raise ValueError(f"effect {self.id!r}: missing parameter(s) {missing}; required: {list(names)}")
        return {q.name: q.check(p[q.name], self.id) for q in (self.params_for(kind) if kind else self.params)}

    def aliases(self, p: Mapping[str, float], block_rate_hz: float, rate_hz: float,
                shift_s: float = 0.0) -> list[Params]:
        """The parameters whose term, seen through block means at ``block_rate_hz`` of a record
        at ``rate_hz`` whose first mean is ``shift_s`` after its first sample (``p`` referenced to
        that sample: :meth:`time_shifted`), could have made what a fit on the means found at
        ``p`` (a line above the means' Nyquist frequency folds into their band): ``p`` first.
        Default: ``p`` alone."""
        return [dict(p)]

    def time_shifted(self, p: Mapping[str, float], shift_s: float) -> Params:
        """The parameters that give the same term on a record starting ``shift_s`` seconds
        earlier (negative: later; a term timed from the record's first sample — a line's phase —
        fitted on a window of a longer record, moved to the whole record). Default: the same values (terms
        on absolute time or on the time since power-on; a drift's level is the bias's)."""
        return dict(p)

    def free_params(self, p: Mapping[str, float], kind: str, rec: Record,
                    rows: np.ndarray | None = None) -> tuple[Param, ...]:
        """The parameters a fit on rec moves from the values ``p``, with the bounds it keeps them
        in (default: all of the kind's, in their physical ranges); ``rows``: the samples the fit
        sees when not all (a fold's training blocks), where a range the rows cannot resolve may
        be narrowed (a transient's fast node: :class:`.effects_thermal.ThermalTwoNode`)."""
        return self.params_for(kind)

    def coordinate_scale(self, q: Param, rec: Record) -> float | None:
        """The optimiser's scale of parameter ``q`` on rec (None: the fitter's default, a
        thousandth of the range; a jump's time has the sample interval)."""
        return None

    def applies_to(self, rec: Record) -> bool:
        """True when rec carries what the effect needs: every logged column of ``inputs`` present
        and varying (an input held constant is one with the bias; ``t``/``t_on`` always are)."""
        return all(n in ("t", "t_on") or rec.varies(n) for n in self.inputs)

    def check_inputs(self, rec: Record) -> None:
        for name in self.inputs:
            if not rec.has(name):
                raise ValueError(f"effect {self.id!r} needs the logged column {name!r}, absent from this record")

    # ---- the effect -------------------------------------------------------------------
    def apply(self, p: Params, rec: Record, y_ideal: np.ndarray,
              rng: np.random.Generator | None = None) -> np.ndarray:
        """``y_ideal`` with this effect applied (see the module docstring for stages; ``rng``
        draws a random process's realisation)."""
        self.check_inputs(rec)
        y = np.asarray(y_ideal, dtype=float)
        if y.shape != (rec.n,):
            raise ValueError(f"y_ideal has shape {y.shape}; allowed: ({rec.n},) like the record")
        return self._applied(p, rec, y, rng)

    def _applied(self, p: Params, rec: Record, y: np.ndarray, rng: np.random.Generator | None) -> np.ndarray:
        if self.stage == "input":
            u = rec.column("input")
            return y + (self.transform_input(p, rec, u) - u)
        if self.stage == "output":
            return self.transform(p, rec, y)
        return y + self.term(p, rec)

    def term(self, p: Params, rec: Record) -> np.ndarray:
        """Additive effects: the term added to the output (sensor unit)."""
        raise NotImplementedError(f"{self.id} is not an additive effect")

    def term_gradient(self, p: Mapping[str, float], rec: Record, names: Sequence[str]) -> list[np.ndarray] | None:
        """Additive effects: ∂term/∂p of each parameter in ``names`` at ``p`` (the least-squares
        fit's analytic Jacobian, :mod:`.fitting`); None (the default): not given, the fit
        differences its prediction numerically."""
        return None

    def transform_input(self, p: Params, rec: Record, u: np.ndarray) -> np.ndarray:
        """Input-stage effects: the transformed input (same unit)."""
        raise NotImplementedError(f"{self.id} is not an input-stage effect")

    def transform(self, p: Params, rec: Record, y: np.ndarray) -> np.ndarray:
        """Output-stage effects: the transformed output (what a reading of ``y`` becomes)."""
        raise NotImplementedError(f"{self.id} is not an output-stage effect")

    def expected_transform(self, p: Params, rec: Record, y: np.ndarray, noise_sd: float) -> np.ndarray:
        """Output stage: mean of ``transform(y + n)``, n white Gaussian of sd ``noise_sd`` (what
        ``Model.predict`` returns; readings are transformed noisy signals). Default: ``transform(y)``."""
        return self.transform(p, rec, y)

    def observes_noise(self, p: Params, y: np.ndarray) -> np.ndarray:
        """Output stage: where a reading of the signal ``y`` (the mean before this transform)
        still carries the noise added before it — False where the transform censors it (a
        saturation's clipped stretches read the limit, whatever the noise). Default: all True
        (a quantizer's flips between levels carry it)."""
        return np.ones(np.shape(y), bool)

    def pre_transform_sd(self, p: Params, floor_sd: float) -> float:
        """Output stage: white sd before this transform given the floor of a model without it."""
        return floor_sd

    def residual_var(self, p: Params, noise_sd: float) -> float:
        """Output stage: variance of a reading about the model's mean (default noise_sd²)."""
        return noise_sd ** 2

    def residual_moments_at(self, p: Params, rec: Record, y: np.ndarray, noise_sd: float,
                            wander_sd: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Output stage: (variance, fourth central moment) of a reading about its mean per
        sample, at the signal ``y`` before the transform, with a slow unpredicted offset of sd
        ``wander_sd`` (the model's random processes) moving the signal. Default:
        ``residual_var`` everywhere, Gaussian (a homoscedastic transform)."""
        v = np.full(np.shape(y), self.residual_var(p, noise_sd))
        return v, 3 * v * v

    # ---- detectability ----------------------------------------------------------------
    def reference_output(self, rec: Record) -> np.ndarray:
        """The output the detectability rule perturbs: ``input`` (unit SF, zero bias) or 0."""
        return reference_input(rec)

    def plain_snr(self, p: Params, rec: Record, noise_sd: float) -> float:
        """The signature's snr without taking out what its look-alikes could absorb: the size
        of the effect, not how well it can be told from them (the naming's size gate)."""
        if not self.look_alikes:
            return self.snr(p, rec, noise_sd)
        y0 = self.reference_output(rec)
        delta = project_q(self.apply(p, rec, y0) - y0, orthonormal(base_regressors(rec)))
        return math.sqrt(vdot(delta, delta)) / noise_sd

    def snr(self, p: Params, rec: Record, noise_sd: float) -> float:
        """Signal-to-noise ratio of the effect's signature on rec (see module docstring): the
        part its look-alikes cannot absorb, i.e. how well it can be told from them."""
        y0 = self.reference_output(rec)
        q = orthonormal(base_regressors(rec))
        delta = project_q(self.apply(p, rec, y0) - y0, q)
        if self.look_alikes and np.any(delta):
            dirs = [c.direction_matching(delta, rec, q, guess_kind(rec)) for c in self.look_alikes]
            delta = project_q(delta, orthonormal(np.column_stack(dirs)))
        return math.sqrt(vdot(delta, delta)) / noise_sd

    def direction_matching(self, delta: np.ndarray, rec: Record, q: np.ndarray, kind: str) -> np.ndarray:
        """This effect's signature (projected away from the orthonormal columns ``q``, unit norm)
        that best matches ``delta`` (already orthogonal to q) up to a scale — what it could absorb
        of another effect's: all-linear effects have one direction; otherwise a 13-point grid of
        its shape parameter (the main parameter when nonlinear, else its one nonlinear
        parameter) over its resolvable range, then 8 golden-section steps. The main parameter
        is searched over its whole physical range, 25 points then golden section to
        convergence: a look-alike may match beyond the range a fit starts from (a sub-sample
        delay of 0.02 s on a 1-Hz record is a low-pass at 8 Hz, above the low-pass's grid that
        stops at the sampling rate — matched only up to 1 Hz, such a delay read as snr 17 from
        its look-alike and was drawn as distinguishable when no record can tell them apart),
        and a large effect's match is narrow (8 steps leave a bracket of 3 %)."""
        if kind not in self.ranges:
            kind = self.kinds[0]
        y0 = self.reference_output(rec)
        base = self.reference_params(rec, kind)
        if self.param(self.main_param, kind).linear:
            base[self.main_param] = 1.0  # the direction is scale-free; the reference may be 0
        shape = self.shape_param(kind)

        def direction(v: float | None) -> np.ndarray:
            p = dict(base)
            if shape is not None and v is not None:
                p[shape.name] = v
            d = project_q(self.apply(p, rec, y0) - y0, q)
            nrm = math.sqrt(vdot(d, d))
            return d / nrm if nrm > 0 else d

        if shape is None or shape.linear:
            return direction(None)
        main = shape.name == self.main_param
        lo, hi = ((max(shape.low, 1e-300), shape.high) if main and shape.log
                  else self.main_grid_range(rec, kind) if main else self.drawable_range(shape, rec, kind))
        to_v, from_v = ((math.exp, math.log) if shape.log or main else (float, float))

        def fit(c: float) -> float:  # captured fraction of delta (maximise)
            return abs(vdot(direction(to_v(c)), delta))

        grid = np.linspace(from_v(lo), from_v(hi), 25 if main and shape.log else 13)
        vals = [fit(g) for g in grid]
        i = int(np.argmax(vals))
        x0, x1 = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
        g = (math.sqrt(5) - 1) / 2
        c, d = x1 - g * (x1 - x0), x0 + g * (x1 - x0)
        fc, fd = fit(c), fit(d)
        for _ in range(MATCH_STEPS if main and shape.log else 8):
            if x1 - x0 <= MATCH_XTOL * max(1.0, abs(x0)):
                break
            if fc > fd:
                x1, d, fd = d, c, fc
                c = x1 - g * (x1 - x0)
                fc = fit(c)
            else:
                x0, c, fc = c, d, fd
                d = x0 + g * (x1 - x0)
                fd = fit(d)
        return direction(to_v(0.5 * (x0 + x1)))

    def shape_param(self, kind: str) -> Param | None:
        """The parameter whose value sets the shape of the signature (searched when matching
        another effect's): the main parameter when it is nonlinear, else the one nonlinear
        parameter; None when several or none are (the reference values are used)."""
        qs = self.params_for(kind)
        main = self.param(self.main_param, kind)
        if not main.linear:
            return main
        nonlinear = [q for q in qs if not q.linear]
        if len(nonlinear) == 1:
            return nonlinear[0]
        return main if not nonlinear else None

    def reference_params(self, rec: Record, kind: str) -> Params:
        """Typical values of every parameter for judging detectability on rec: geometric mean
        of the resolvable range (log parameters), 0 for signed linear ones, else the midpoint."""
        out = {}
        for q in self.params_for(kind):
            lo, hi = self.drawable_range(q, rec, kind)
            out[q.name] = math.sqrt(lo * hi) if q.log else (0.0 if lo <= 0 <= hi and q.linear else 0.5 * (lo + hi))
        return out

    def drawable_range(self, q: Param, rec: Record, kind: str) -> tuple[float, float]:
        """The part of a non-main parameter's range the record can resolve (override per effect)."""
        return q.low, q.high

    def identity_params(self, p: Params) -> Params:
        """p with the effect switched off: main parameter at ``identity`` (and, for effects with a
        second amplitude such as temperature_bias's quadratic term, that one at 0 too)."""
        return self.with_main(p, self.identity)

    def with_main(self, others: Mapping[str, float], value: float) -> Params:
        """``others`` with the main parameter set to ``value``."""
        d = dict(others)
        d[self.main_param] = value
        return d

    def _threshold(self, others: Params, rec: Record, noise_sd: float, target: float, kind: str,
                   distinct: bool = True) -> float:
        """Main-parameter magnitude where snr == target (bisection on a log scale); ``distinct``
        False: the plain snr (:meth:`plain_snr`)."""
        q = self.param(self.main_param, kind)
        hi_mag = max(abs(q.low), abs(q.high))
        lo_mag = max(q.floor, hi_mag * 1e-12, 1e-300) if not q.log else q.low
        sgn = 1.0 if q.high > 0 else -1.0
        snr = self.snr if distinct else self.plain_snr

        def f(m: float) -> float:
            return snr(self.with_main(others, sgn * m), rec, noise_sd) - target

        a, b = math.log(lo_mag), math.log(hi_mag)
        fa, fb = f(lo_mag), f(hi_mag)
        if self.increasing:
            if fb < 0:
                return math.inf
            if fa >= 0:
                return lo_mag
        else:
            if fa < 0:
                return 0.0
            if fb >= 0:
                return hi_mag
        for _ in range(64):
            m = 0.5 * (a + b)
            if (f(math.exp(m)) >= 0) == self.increasing:
                b = m
            else:
                a = m
            if b - a < self.threshold_log_tol:
                break
        return math.exp(b if self.increasing else a)

    def min_effect(self, rec: Record, noise_sd: float, *, kind: str | None = None,
                   params: Mapping[str, float] | None = None, distinct: bool = True) -> float:
        """Smallest main-parameter magnitude that matters on rec with white noise ``noise_sd``
        (the largest for a decreasing effect, e.g. a bandwidth): ``snr = MIN_SNR`` with the other
        parameters at ``params`` (default: reference values), and never finer than the physical
        floor. ``math.inf`` (0 for decreasing) when even the range's end is undetectable.
        ``distinct`` (default): the snr of what tells it from its look-alikes (the scorecard's
        draws); False: the plain snr — the naming's size gate, which asks whether the effect
        matters, not whether it can be told from a look-alike (that is the competitors' report)."""
        if not noise_sd > 0:
            raise ValueError(f"noise_sd = {noise_sd!r}; allowed: > 0")
        kind = kind or guess_kind(rec)
        others = self.reference_params(rec, kind)
        if params:
            others.update({k: v for k, v in params.items() if k in others})
        thr = self._threshold(others, rec, noise_sd, MIN_SNR, kind, distinct)
        floor = self.param(self.main_param, kind).floor
        return max(thr, floor) if self.increasing else thr

    def detectable(self, p: Params, rec: Record, noise_sd: float) -> bool:
        """True when snr(p) >= MIN_SNR."""
        return self.snr(p, rec, noise_sd) >= MIN_SNR

    def identifiable(self, p: Mapping[str, float], rec: Record) -> bool:
        """False when rec cannot resolve these parameters (e.g. a correlation time beyond a fifth
        of the record), however significant the fit: it is then not named."""
        return True

    # ---- drawing ----------------------------------------------------------------------
    def draw(self, rng: np.random.Generator, rec: Record, *, kind: str | None = None,
             noise_sd: float | None = None, at_snr: float | None = None) -> Params:
        """Parameters inside the kind's physical ranges, resolvable on rec, with the main
        parameter log-uniform between the values giving ``snr = DRAW_SNR_FACTOR·MIN_SNR`` (15)
        and ``DRAW_SPAN`` times that snr (450) — or, with ``at_snr``, exactly at that snr (a
        power curve); random sign for signed parameters. ValueError when the physical range
        cannot reach that on this record (the record is too short/quiet for it)."""
        kind = kind or guess_kind(rec)
        self.params_for(kind)
        self.check_inputs(rec)
        sd = noise_sd if noise_sd is not None else noise_sd_of(rec, kind)
        others = self.draw_others(rng, rec, kind)
        q = self.param(self.main_param, kind)
        if at_snr is not None:
            if not (math.isfinite(at_snr) and at_snr > 0):
                raise ValueError(f"at_snr = {at_snr!r}; allowed: > 0")
            thr = far = self._threshold(others, rec, sd, at_snr, kind)
        else:
            lo_snr = DRAW_SNR_FACTOR * MIN_SNR
            thr = self._threshold(others, rec, sd, lo_snr, kind)
            far = self._threshold(others, rec, sd, lo_snr * DRAW_SPAN, kind)
            # never more than draw_span_main times the threshold in the parameter itself (an snr
            # that saturates, as quantization's does, would otherwise open the whole range)
            far = min(far, thr * self.draw_span_main) if self.increasing else max(far, thr / self.draw_span_main)
        hi_mag = max(abs(q.low), abs(q.high))
        lo_mag = q.low if q.log else max(q.floor, 0.0)
        if self.increasing:
            a, b = max(thr, lo_mag), min(hi_mag, far)
        else:
            a, b = max(lo_mag, far), min(thr, hi_mag)
        c_lo, c_hi = self.main_draw_clip(rec, kind, sd)
        a, b = max(a, c_lo), min(b, c_hi)
        if not (0 < a <= b):
            raise ValueError(f"{self.id}: no {self.main_param} inside [{q.low}, {q.high}] {q.unit} is "
                             f"detectable on this record (needs {'>=' if self.increasing else '<='} {thr:.3g})")
        mag = math.exp(rng.uniform(math.log(a), math.log(b)))
        sign = 1.0 if (q.low >= 0 or rng.random() < 0.5) else -1.0
        p = self.with_main(others, sign * mag)
        if at_snr is not None:  # the threshold stops at the range's end: was the snr reached?
            got = self.snr(p, rec, sd)
            if not abs(got / at_snr - 1) <= 0.02:
                raise ValueError(f"{self.id}: no {self.main_param} inside [{q.low}, {q.high}] {q.unit} "
                                 f"gives snr {at_snr:.3g} on this record (the range ends at snr {got:.3g})")
        return self.finish_draw(rng, rec, kind, p)

    def draw_others(self, rng: np.random.Generator, rec: Record, kind: str) -> Params:
        """Non-main parameters: uniform (log-uniform for log params) over the drawable range."""
        out = {}
        for q in self.params_for(kind):
            if q.name == self.main_param:
                continue
            lo, hi = self.drawable_range(q, rec, kind)
            out[q.name] = math.exp(rng.uniform(math.log(lo), math.log(hi))) if q.log else rng.uniform(lo, hi)
        return out

    def main_draw_clip(self, rec: Record, kind: str, noise_sd: float) -> tuple[float, float]:
        """Extra limits on the drawn main magnitude on rec with white ``noise_sd`` (override: e.g.
        an angle quantizer whose readings would sit on a visible lattice)."""
        return 0.0, math.inf

    def finish_draw(self, rng: np.random.Generator, rec: Record, kind: str, p: Params) -> Params:
        """Hook for parameters drawn relative to the main one."""
        return p

    # ---- fit starts -------------------------------------------------------------------
    def fit_starts(self, rec: Record, residual: np.ndarray, *, kind: str | None = None,
                   rows: np.ndarray | None = None, held_out: np.ndarray | None = None) -> list[Params]:
        """Initial guesses for a nonlinear fit of this effect to ``residual`` (best first) on the
        samples ``rows`` (default all; the others are not looked at): the :data:`N_STARTS` best
        points of a grid over its nonlinear parameters (:func:`grid_starts`). ``held_out``: the
        samples a fold holds out, when ``rows`` is a fold's training blocks (None: no fold) —
        ``rows`` may miss more (samples a clip hides), and a start that reads the fold's own
        pattern (:class:`SinusoidalInterference`'s alias lines) reads it here."""
        r = np.asarray(residual, float) if rows is None else np.where(rows, residual, 0.0)
        return grid_starts(self, rec, r, kind or guess_kind(rec))

    def searched(self, p: Mapping[str, float]) -> int:
        """How many of the free parameters at ``p`` a search over the whole record placed (a
        jump's times): a likelihood maximised over a location gains more than a parameter's
        ln(n/2), and a BIC that weighs such a term against a random process charges each twice (as
        the modified BIC of change points does); 0 by default."""
        return 0

    def prefixes(self, p: Mapping[str, float]) -> list[Params]:
        """Smaller versions of the fitted ``p`` for the criterion to weigh too (a jump fit's
        first j change points, j below its count); [] by default."""
        return []

    def components(self, p: Mapping[str, float]) -> list[Params]:
        """The parts of the effect at ``p`` that the criterion charges one by one, each its own
        penalty (:func:`.criterion.penalty`), as the parameters of the effect holding that part
        alone: ``[p]`` by default (one charge for the whole effect); a sinusoid's lines, each a
        line the search could have added by itself."""
        return [dict(p)]

    def joined(self, p: Mapping[str, float], parts: Sequence[Mapping[str, float]]) -> Params:
        """The effect holding ``parts`` (each as :meth:`components` gives one) together, its other
        parameters from ``p``: the one part itself by default."""
        return dict(parts[0]) if parts else dict(p)

    def search_cells(self, p: Mapping[str, float], rec: Record) -> float:
        """How many distinct positions the fit of this effect at ``p`` chose among (the
        criterion's multiplicity, :func:`.criterion.penalty`): 1 for a fit that searches no
        location (default); a jump's time is one of the n samples per jump, a line's frequency
        one of the n/2 Fourier bins."""
        return float(rec.n) ** self.searched(p) if self.searched(p) else 1.0

    def reduced(self, p: Mapping[str, float], nested: str, kind: str) -> list[Params]:
        """Starts for the effect ``nested`` (one of :attr:`nests`) standing alone for this effect at
        ``p`` — the workflow tries the model with it in this one's place when a random process
        named after this one may hold what the richer shape's extra parameters took; [] by
        default."""
        return []

    def main_grid_range(self, rec: Record, kind: str) -> tuple[float, float]:
        q = self.param(self.main_param, kind)
        return self.drawable_range(q, rec, kind)


class HistogramEffect(Effect):
    """An effect judged on the histogram of the readings, not on a waveform (a quantizer whose
    step is below the noise leaves no waveform of its own): the naming step asks
    :meth:`fit_histogram` for its parameters, held-out score and p-value; calibration keeps its
    parameters."""

    waveform = False

    def fit_histogram(self, y: np.ndarray, noise_sd: float, folds: np.ndarray, kind: str) -> HistogramFit:
        """Fit to the readings ``y`` with calibrated white noise ``noise_sd``; held-out score on
        the blocks of ``folds`` (fitted on the others), as comparable with the other candidates'."""
        raise NotImplementedError(f"{self.id} does not say how its histogram is judged")


@dataclass(frozen=True)
class HistogramFit:
    """A histogram-judged effect's fit: parameters ± std, held-out score and p-value."""

    params: Params
    params_std: Params
    score: float
    p_value: float


def product_grid(grids: Sequence[tuple[str, np.ndarray]]) -> Iterator[Params]:
    """Every combination of the named grids, as parameter dicts (the first name varies slowest)."""
    if not grids:
        yield {}
        return
    (name, pts), rest = grids[0], grids[1:]
    for v in pts:
        for tail in product_grid(rest):
            yield {name: float(v)} | tail


def grid_starts(effect: Effect, rec: Record, residual: np.ndarray, kind: str) -> list[Params]:
    """The :data:`N_STARTS` best points of a grid over ``effect``'s nonlinear parameters (their
    resolvable ranges: 9 log-spaced points for a log parameter, 5 linear ones otherwise), the
    linear parameters solved by least squares at each grid point after projecting the base
    model's calibration regressors out of both sides; lowest residual sum of squares first."""
    r = np.asarray(residual, dtype=float)
    qs = effect.params_for(kind)
    lin = [q for q in qs if q.linear]
    grids = []
    for q in qs:
        if q.linear:
            continue
        lo, hi = (effect.drawable_range(q, rec, kind) if q.name != effect.main_param
                  else effect.main_grid_range(rec, kind))
        pts = np.geomspace(lo, hi, 9) if q.log else np.linspace(lo, hi, 5)
        grids.append((q.name, pts))
    a = base_regressors(rec)
    r_perp = project_out(r, a)
    y0 = effect.reference_output(rec)
    cands = []
    for combo in product_grid(grids):
        p = {q.name: 0.0 for q in lin} | combo
        if lin:
            cols = []
            for q in lin:
                pu = dict(p)
                pu[q.name] = 1.0
                cols.append(project_out(effect.apply(pu, rec, y0) - y0, a))
            coef, *_ = np.linalg.lstsq(np.column_stack(cols), r_perp, rcond=None)
            for q, c in zip(lin, coef):
                p[q.name] = float(np.clip(c, q.low, q.high))
        d = project_out(effect.apply(p, rec, y0) - y0, a)
        cands.append((float(np.sum((r_perp - d) ** 2)), p))
    cands.sort(key=lambda c: c[0])
    return [c[1] for c in cands[:N_STARTS]]
