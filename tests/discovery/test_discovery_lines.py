"""Several lines in one ``sinusoidal_interference``: each line a slot (amplitude, frequency,
phase), each charged by the criterion as a line added alone, their number the criterion's.

Graded on records drawn and realised apart from the catalogue
(:mod:`bench.testing.generators.discovery_lines`: lines as cosines on the record's own clock,
frequencies log-uniform from 20 cycles to 0.4 × the sample rate, each line's snr log-uniform
in 15–60): two-line records name both lines with every parameter within 3 stated standard
errors; one-line records name one line; white-noise records name none — each a count over
fixed seeds against a stated rate (:func:`bench.testing.discovery_nulls.binomial_allowance`: a
correct method fails it with probability ≤ 0.1 %), or a recovery share against the 80 % the
method is held to. The figures behind them over more records:
``python -m tests.discovery.test_discovery_lines [RECORDS] [catalogue]`` (``catalogue``: every
search over the whole catalogue).
"""

from __future__ import annotations

import math
from typing import cast

import numpy as np
import pytest
from scipy.stats import chi2

from bench.discovery.criterion import FALSE_NAME_RATE, n_free, penalty
from bench.discovery.data import Record
from bench.discovery.effects import CATALOGUE
from bench.discovery.effects_base import DRAW_SNR_FACTOR, MIN_SNR
from bench.discovery.effects_terms import MAX_LINES, SinusoidalInterference, line_names
from bench.discovery.model import BaseModel, Model, model_from_toml, model_to_toml
from bench.discovery.workflow import Discovery, discover
from bench.testing.discovery_nulls import binomial_allowance
from bench.testing.generators.discovery_lines import DrawnLine, draw_lines_record

LINE = cast(SinusoidalInterference, CATALOGUE["sinusoidal_interference"])
KIND = "gyro"
SD = 3e-3
#: samples per record (10 Hz: a minute): a search of the panel below takes about a second
N = 600
#: each drawn line's snr: from the catalogue's draw floor (3 × the naming's size gate) to 4 × it
SNR = (DRAW_SNR_FACTOR * MIN_SNR, 4 * DRAW_SNR_FACTOR * MIN_SNR)
#: the catalogue the two-line searches may add: the line, and the random processes a second line
#: is otherwise taken for (a short Gauss–Markov, angle quantization). Naming from the rest of
#: the catalogue is the null tests' property (``test_discovery_search.py``).
PANEL = ("sinusoidal_interference", "gauss_markov", "angle_quantization")
#: share of records a recovery property must hold in
RECOVERY_SHARE = 0.8


def _start() -> Model:
    return Model(BaseModel(KIND, noise_sd=SD))


def _record(seed: int, count: int):
    return draw_lines_record(np.random.default_rng([36, count, seed]), count=count, n=N, sd=SD, snr=SNR)


def _lines(d: Discovery) -> list[tuple[dict, dict]]:
    """Each line the discovery named: {amplitude, freq_hz, phase_rad} and their std."""
    step = next((s for s in d.steps if s.effect_id == LINE.id), None)
    if step is None:
        return []
    out = []
    for k in range(1, MAX_LINES + 1):
        names = line_names(k)
        if step.params[names[0]] != 0.0:
            out.append(({r: step.params[m] for r, m in zip(line_names(1), names)},
                        {r: step.params_std.get(m, math.nan) for r, m in zip(line_names(1), names)}))
    return out


def _z(found: tuple[dict, dict], truth: DrawnLine) -> float:
    """The largest |error| / stated std of a named line's three parameters against a drawn one."""
    p, sd = found
    dphi = (p["phase_rad"] - truth.phase_from_start_rad + math.pi) % (2 * math.pi) - math.pi
    errs = (abs(p["amplitude"] - truth.amplitude), abs(p["freq_hz"] - truth.freq_hz), abs(dphi))
    stds = (sd["amplitude"], sd["freq_hz"], sd["phase_rad"])
    return max(e / s if s > 0 else math.inf for e, s in zip(errs, stds))


def recovered(d: Discovery, truth: tuple[DrawnLine, ...]) -> tuple[bool, str]:
    """(every drawn line named — the named line nearest its frequency — with its amplitude,
    frequency and phase within 3 stated std, a description)."""
    lines = _lines(d)
    zs = []
    for t in truth:
        if not lines:
            return False, "no line named"
        nearest = min(lines, key=lambda ln: abs(ln[0]["freq_hz"] - t.freq_hz))
        zs.append(_z(nearest, t))
    desc = (f"named {[s.effect_id for s in d.steps]}, lines at {[round(p['freq_hz'], 4) for p, _ in lines]} Hz, "
            f"true {[round(t.freq_hz, 4) for t in truth]} Hz (snr {[round(t.snr, 1) for t in truth]}), "
            f"max |z| {[round(z, 2) for z in zs]}")
    return all(z <= 3.0 for z in zs), desc


# ---- the effect's slots and the criterion's charge -------------------------------------------

def _two() -> dict:
    return LINE.with_lines({}, [(0.01, 0.7, 0.3), (0.004, 2.9, -1.2)])


def test_each_line_is_charged_as_a_line_added_alone():
    """A line's frequency was searched among n/2 bins: each line costs χ²_3.isf(α/(C·n/2)), the
    cost of a line added by itself; an unused slot moves nothing and costs nothing."""
    rec, _ = _record(0, 0)
    two = _two()
    one = LINE.with_lines({}, LINE.lines(two)[:1])
    each = chi2.isf(FALSE_NAME_RATE / (20 * rec.n / 2), 3)
    assert n_free(LINE, one, rec, KIND) == 3 and n_free(LINE, two, rec, KIND) == 6
    assert penalty(LINE, one, rec, KIND, 20) == pytest.approx(each, rel=1e-10)
    assert penalty(LINE, two, rec, KIND, 20) == pytest.approx(2 * each, rel=1e-10)
    assert [q.name for q in LINE.free_params(two, KIND, rec)] == [*line_names(1), *line_names(2)]


def test_lines_add_up_and_the_prefixes_keep_the_strongest():
    """The term is the sum of the lines; the shorter fits the criterion weighs hold the strongest
    lines, strongest first; with none the effect is its identity."""
    rec, _ = _record(0, 0)
    two = _two()
    tt = rec.t_s - rec.t_s[0]
    want = 0.01 * np.sin(2 * np.pi * 0.7 * tt + 0.3) + 0.004 * np.sin(2 * np.pi * 2.9 * tt - 1.2)
    np.testing.assert_allclose(LINE.term(two, rec), want, atol=1e-15)
    weak_first = LINE.with_lines({}, LINE.lines(two)[::-1])
    assert [LINE.lines(p) for p in LINE.prefixes(weak_first)] == [[(0.01, 0.7, 0.3)]]
    assert not np.any(LINE.term(LINE.identity_params(two), rec))
    # moved to a record starting 12.5 s earlier, the lines predict there what they did here
    earlier = Record(t_s=np.r_[rec.t_s[0] - 12.5, rec.t_s], y=np.zeros(rec.n + 1))
    np.testing.assert_allclose(LINE.term(LINE.time_shifted(two, 12.5), earlier)[1:], want, atol=1e-12)


def test_a_model_file_with_one_line_reads_and_a_partial_line_is_refused():
    """A model file written with the first line's parameters alone reads as that line (the
    others unused) and round-trips; a line with some of its parameters missing names them."""
    one = {"amplitude": 0.01, "freq_hz": 0.7, "phase_rad": 0.3}
    m = _start().with_effect(LINE.id, one)
    assert LINE.lines(m.effects[0][1]) == [(0.01, 0.7, 0.3)]
    assert model_from_toml(model_to_toml(m)) == m
    with pytest.raises(ValueError, match="phase_2_rad"):
        _start().with_effect(LINE.id, one | {"amplitude_2": 0.01, "freq_2_hz": 2.0})


@pytest.mark.parametrize(("f_true", "phase"), [(16.08, 0.7), (27.3, -2.1), (43.1, 2.9), (31.9, -0.4)])
def test_an_aliased_line_is_proposed_at_its_own_frequency_and_phase(f_true, phase):
    """A line above the block means' Nyquist frequency (means of 5 samples at 100 Hz): fitted on
    the means at its alias and moved to a window's first sample, the alias proposal at its own
    frequency carries its own phase there (within 0.01 rad: the block average's gain and the
    means' time offset accounted for)."""
    rate, n = 100.0, 4000
    t = 3.0 + np.arange(n) / rate
    rec = Record(t_s=t, y=np.sin(2 * np.pi * f_true * (t - t[0]) + phase))
    means = rec.block_means(5)
    fb = means.rate_hz
    f_alias = abs(f_true - round(f_true / fb) * fb)
    tm = means.t_s - means.t_s[0]
    cols = np.column_stack([np.sin(2 * np.pi * f_alias * tm), np.cos(2 * np.pi * f_alias * tm)])
    (a, b), *_ = np.linalg.lstsq(cols, means.y, rcond=None)
    on_means = LINE.with_lines({}, [(math.hypot(a, b), f_alias, math.atan2(b, a))])
    w0 = float(t[1234])
    shift = float(means.t_s[0] - w0)
    cands = [c for c in LINE.aliases(LINE.time_shifted(on_means, shift), fb, rate, shift)
             if abs(c["freq_hz"] - f_true) < 1e-6]
    assert len(cands) == 1
    want = phase + 2 * np.pi * f_true * (w0 - t[0])
    assert abs((cands[0]["phase_rad"] - want + np.pi) % (2 * np.pi) - np.pi) < 0.01


# ---- recovery and nulls ------------------------------------------------------------------

def test_two_lines_are_both_named_within_three_sigma():
    """Two-line records (6, drawn apart from the catalogue): both lines named with amplitude,
    frequency and phase within 3 stated std in ≥ 80 %; any other name in no more records than the
    binomial allowance at α."""
    seeds = range(6)
    ok, other, rows, harmonic = 0, [], [], 0
    for seed in seeds:
        rec, truth = _record(seed, 2)
        d = discover(rec, _start(), only=PANEL)
        good, desc = recovered(d, truth)
        ok += good
        rows.append(f"{seed}: {desc}")
        if any(s.effect_id != LINE.id for s in d.steps):
            other.append(rows[-1])
        harmonic += any("at a multiple of" in n for n in d.notes)
    assert ok >= RECOVERY_SHARE * len(seeds), rows
    assert len(other) <= binomial_allowance(len(seeds), FALSE_NAME_RATE), other
    # unrelated lines are not said to be harmonics (≈ 0.3 % a pair by chance at the stated errors)
    assert harmonic <= binomial_allowance(len(seeds), 0.003)


@pytest.mark.parametrize("seed", range(3))
def test_a_square_wave_named_as_lines_is_said_to_be_one_periodic_source(seed):
    """A square wave's fundamental and 3rd harmonic (amplitudes 1 and 1/3 of 40 noise sd, drawn
    frequency and phase): named as two lines, the note says the higher one sits at
    3× the lower within its errors — one periodic source that is not a sine."""
    rng = np.random.default_rng([36, 3, seed])
    t = np.arange(N) / 10.0
    f = rng.uniform(0.2, 1.0)
    phase = rng.uniform(-math.pi, math.pi)
    amp = 40 * SD  # a pick-up well above the noise: the lines' errors are small, the test is the ratio
    y = (amp * (np.sin(2 * np.pi * f * t + phase) + np.sin(3 * (2 * np.pi * f * t + phase)) / 3)
         + SD * rng.standard_normal(N))
    d = discover(Record(t_s=t, y=y), _start(), only=(LINE.id,))
    assert len(_lines(d)) >= 2, d.steps
    note = next((n for n in d.notes if "at a multiple of" in n), None)
    assert note is not None and "(3×)" in note, d.notes


def test_one_line_records_name_one_line():
    """One-line records (8): the line named within 3 stated std in ≥ 80 %; a second line named
    in no more records than the binomial allowance at α (a line beside it is charged as a line
    added alone)."""
    seeds = range(8)
    ok, extra, rows = 0, [], []
    for seed in seeds:
        rec, truth = _record(seed, 1)
        d = discover(rec, _start(), only=(LINE.id,))
        good, desc = recovered(d, truth)
        ok += good
        rows.append(f"{seed}: {desc}")
        if len(_lines(d)) > 1:
            extra.append(rows[-1])
    assert ok >= RECOVERY_SHARE * len(seeds), rows
    assert len(extra) <= binomial_allowance(len(seeds), FALSE_NAME_RATE), extra


def test_white_noise_names_no_line():
    """White-noise records (20, the same generator with no line): a line named in no more records
    than the binomial allowance at the false-name rate α."""
    named = []
    for seed in range(20):
        rec, _ = _record(seed, 0)
        d = discover(rec, _start(), only=(LINE.id,))
        if d.steps:
            named.append(f"{seed}: {[p['freq_hz'] for p, _ in _lines(d)]}")
    assert len(named) <= binomial_allowance(20, FALSE_NAME_RATE), named


if __name__ == "__main__":  # the figures: python -m tests.discovery.test_discovery_lines [RECORDS] [catalogue]
    import sys
    import time

    records = int(sys.argv[1]) if len(sys.argv) > 1 else 100
    whole = len(sys.argv) > 2 and sys.argv[2] == "catalogue"  # every effect the records allow
    t0 = time.perf_counter()
    for count, only in ((2, None if whole else PANEL), (1, None if whole else (LINE.id,)),
                        (0, None if whole else (LINE.id,))):
        good = exact = other = 0
        for seed in range(1000, 1000 + records):
            rec, truth = _record(seed, count)
            d = discover(rec, _start(), only=only)
            good += recovered(d, truth)[0] if count else not d.steps
            exact += len(_lines(d)) == count
            other += any(s.effect_id != LINE.id for s in d.steps)
        what = "all lines within 3 std" if count else "nothing named"
        print(f"{count} line(s), {records} records of {N} samples, snr {SNR[0]:g}-{SNR[1]:g}, "
              f"search over {only or 'the whole catalogue'}: "
              f"{what} {good}/{records}; exactly {count} line(s) named {exact}/{records}; "
              f"another effect named {other}/{records}")
    print(f"{time.perf_counter() - t0:.0f} s")
