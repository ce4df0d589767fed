"""Records with hidden effects, drawn as the discovery scorecard draws them.

:func:`hidden_case` is one case of ``benchmarks/discovery_scorecard.py``: a kind's experiment
record (``bench.discovery.experiments.make_experiment``), a truth model with the hidden effects'
parameters drawn by the catalogue (``Effect.draw``: physical range, detectable), and the
readings realised either by the catalogue's own ``Model.simulate`` or by the independent
generator (:mod:`bench.testing.generators.discovery_effects`). The tests that pin a scorecard
case take it from here, so they draw the record the scorecard reported.
"""

from __future__ import annotations

import numpy as np

from bench.discovery.data import Record
from bench.discovery.effects import CATALOGUE
from bench.discovery.effects_base import DEFAULT_NOISE_SD, DRAW_SNR_FACTOR, MIN_SNR
from bench.discovery.experiments import make_experiment
from bench.discovery.model import BaseModel, Model
from bench.testing.generators.discovery_effects import realise

#: the truth's base bias is drawn uniform within ± this, per kind (the base model's units)
BASE_BIAS = {"accelerometer": 2e-3, "gyro": 0.05, "mhd": 0.5}
#: redraws of a mixture whose rest hides one of its effects before the case counts as not drawable
MIX_REDRAWS = 12


def truth_base(kind: str, rng: np.random.Generator) -> Model:
    """The truth's base model of ``kind``: a drawn bias and scale factor, the kind's noise."""
    sd = DEFAULT_NOISE_SD[kind]
    return Model(BaseModel(kind=kind, bias=BASE_BIAS[kind] * rng.uniform(-1, 1),
                           scale_factor=1.0 + rng.normal(0, 2e-3), noise_sd=sd))


def hidden_case(kind: str, effects: tuple[str, ...], seed: int, n: int, at_snr: float | None = None,
                generator: str = "catalogue",
                mix_rule: bool = True) -> tuple[Record, Model, list[float], int] | None:
    """(record, truth model, snr of each effect, redraws) or None when an effect cannot be drawn
    on this record (not detectable; with ``at_snr``: that snr outside its physical range).
    ``generator``: "catalogue" (``Model.simulate``) or "independent"
    (:mod:`bench.testing.generators.discovery_effects`); the same seed draws the same record and
    parameters for both.

    A mixture (two or three effects) is held to the draw rule of a single inside its mixture: each
    effect's ``Model.effect_snr`` at least DRAW_SNR_FACTOR·MIN_SNR (15), as a single's snr is
    against white noise — for a term what tells it from the rest of the mixture (the other
    effects' directions out) against the mixture's whole noise (white + its random process), for
    a random process its excess Allan variance over the readings' floor (a quantizer's rounding
    included, as in the naming's size gate); an output transform as drawn. A draw that
    breaks it (a 19-sigma temperature bias drawn beside a random walk holding 1.8 sigma of it) is
    drawn again with the next sub-seed, up to MIX_REDRAWS times; ``redraws`` counts them.
    ``mix_rule=False``: each effect drawn against white noise only, as a single (stop 27's rule,
    ``--white-draws``; the first draw of every mixture — the same record)."""
    floor = DRAW_SNR_FACTOR * MIN_SNR
    for attempt in range(MIX_REDRAWS + 1 if len(effects) > 1 and mix_rule else 1):
        drawn = _draw_case(kind, effects, seed, n, at_snr, attempt)
        if drawn is None:
            if attempt == 0:
                return None
            continue  # this redraw's record cannot hold an effect: the next one
        rec, truth, snrs, rng = drawn
        if len(effects) == 1 or not mix_rule or all(not truth.effect_snr(rec, i) < floor
                                                    for i in range(len(effects))):
            y = truth.simulate(rec, rng) if generator == "catalogue" else realise(kind, rec, truth, rng)
            return rec.replace(y=y), truth, snrs, attempt
    return None


def _draw_case(kind: str, effects: tuple[str, ...], seed: int, n: int, at_snr: float | None,
               attempt: int) -> tuple[Record, Model, list[float], np.random.Generator] | None:
    """(record without readings, truth model, snr of each effect, the rng to simulate with) —
    each effect drawn by ``Effect.draw`` — or None when one cannot be drawn on the record."""
    salt = ([] if at_snr is None else [int(round(1000 * at_snr))]) + ([10_000 + attempt] if attempt else [])
    rng = np.random.default_rng([seed, len(effects), *[list(CATALOGUE).index(e) for e in effects], *salt])
    rec = make_experiment(kind, rng, n=n)
    sd = DEFAULT_NOISE_SD[kind]
    truth = truth_base(kind, rng)
    snrs = []
    # an output-stage effect (clipping, rounding) acts on bias + SF·input: drawn and sized there
    on_output = rec.replace(input=truth.base.bias + truth.base.scale_factor * rec.column("input"))
    for eid in effects:
        eff = CATALOGUE[eid]
        where = on_output if eff.stage == "output" else rec
        try:
            p = eff.draw(rng, where, kind=kind, noise_sd=sd, at_snr=at_snr)
        except ValueError:
            return None
        snrs.append(float(eff.snr(p, where, sd)))
        truth = truth.with_effect(eid, p)
    return rec, truth, snrs, rng
