"""Out-of-catalogue structure for the open-world scorecard (issue 15): shapes no catalogue
effect has, hidden in a kind's experiment record. The workflow should name nothing for them
and report unexplained structure where it is.

Each shape is sized as the catalogue's own draws are: by the snr of what tells it from its
closest catalogue look-alike (a triangle wave from the sinusoid through its fundamental, a tanh
compression from K2 + K3 + asymmetry), log-uniform between 15 and 150 (3 to 30 times the
naming's size gate), so a shape is never a catalogue effect in disguise:

=============  ================================================================================
shape          structure (T the record's span)
=============  ================================================================================
triangle       a triangle wave of 8-30 cycles over T
square         a square wave of 8-30 cycles over T
chirp          a sine whose frequency sweeps linearly between 5/T and 40-80/T, up or down
bursts         three sine bursts (40-100 cycles/T), each 5 % of T
noise_bursts   white noise 2-4 × the floor in two windows of 8 % of T (a variance, not a mean)
supply         a gain on the logged supply voltage, stepped between 11-13 V levels 12-20 times
               (a supply-sensitivity test): a column no catalogue effect uses
tanh           the input compressed through L·tanh(u/L) (kinds with an input)
telegraph      random telegraph (popcorn) noise: the output steps between +A and −A at 10-100
               instants drawn uniformly over T; A log-uniform in 1-4 × the white sd (a step
               seen on the trace) — its spectrum is a Gauss–Markov's, its steps are not
am_line        a line of 20-200 cycles over T whose amplitude is modulated 50-90 % by a slow
               random envelope (three cosines of 1-3 cycles over T, random phases)
=============  ================================================================================

``hide(shape, kind, rec, rng, noise_sd)`` returns (the record with any new column, the
structure to add to the output, where it is: a dict the scorecard checks the unexplained
structure against; its ``allowed`` key, where present, the look-alikes the shape's size is
measured against — naming one states the part of the shape it is, so an honest answer may name
it, and must report the rest as unexplained structure).
"""

from __future__ import annotations

import math
import re

import numpy as np

from bench.discovery.data import Record
from bench.discovery.effects_linalg import base_regressors, project_out

SHAPES = ("triangle", "square", "chirp", "bursts", "noise_bursts", "supply", "tanh", "telegraph", "am_line")
SNR_RANGE = (15.0, 150.0)
#: the look-alikes the size rule measures a shape against: a line (the best single sinusoid) and
#: the input polynomial (K2 + K3 + asymmetry)
LINE = "sinusoidal_interference"
POLYNOMIAL = ("k2_nonlinearity", "k3_nonlinearity", "scale_factor_asymmetry")


def _triangle(phase: np.ndarray) -> np.ndarray:
    x = (phase / (2 * np.pi)) % 1.0
    return 4 * np.abs(x - 0.5) - 1.0


def telegraph_levels(at: np.ndarray, n: int) -> np.ndarray:
    """±1 over ``n`` samples, +1 at the first and changing sign at each sample index in ``at``
    (sorted): random telegraph noise of unit amplitude, its steps where they were drawn."""
    return 1.0 - 2.0 * (np.searchsorted(at, np.arange(n), side="right") % 2)


def _best_sine_left(d: np.ndarray, rec: Record) -> np.ndarray:
    """What the best single sinusoid (FFT peak, refined on a fine grid around it) leaves of d."""
    d = project_out(d, base_regressors(rec))
    tt = rec.t_s - rec.t_s[0]
    spec = np.abs(np.fft.rfft(d * np.hanning(rec.n)))
    f = np.fft.rfftfreq(rec.n, rec.dt_s)
    k = int(np.argmax(spec[1:])) + 1
    best = d
    for fr in np.linspace(f[max(k - 1, 1)], f[min(k + 1, f.size - 1)], 41):
        m = np.column_stack([np.sin(2 * np.pi * fr * tt), np.cos(2 * np.pi * fr * tt)])
        coef, *_ = np.linalg.lstsq(m, d, rcond=None)
        left = d - m @ coef
        if left @ left < best @ best:
            best = left
    return best


def _poly_left(d: np.ndarray, rec: Record) -> np.ndarray:
    u = rec.column("input")
    m = np.column_stack([base_regressors(rec), u * u, u ** 3, np.abs(u)])
    coef, *_ = np.linalg.lstsq(m, d, rcond=None)
    return d - m @ coef


def _size(unit: np.ndarray, left_of_unit: np.ndarray, rng: np.random.Generator, noise_sd: float) -> float:
    """Amplitude giving the departure from the look-alike an snr log-uniform in SNR_RANGE."""
    target = math.exp(rng.uniform(*np.log(SNR_RANGE)))
    norm = float(np.sqrt(left_of_unit @ left_of_unit))
    return target * noise_sd / norm if norm > 0 else 0.0


def hide(shape: str, kind: str, rec: Record, rng: np.random.Generator,
         noise_sd: float) -> tuple[Record, np.ndarray, dict]:
    """(record, structure to add to y, where it is) — see the module docstring."""
    t = rec.t_s - rec.t_s[0]
    span = float(t[-1])
    if shape in ("triangle", "square"):
        cycles = rng.uniform(8, 30)
        f0 = cycles / span
        ph = 2 * np.pi * f0 * t + rng.uniform(0, 2 * np.pi)
        unit = _triangle(ph) if shape == "triangle" else np.sign(np.sin(ph))
        amp = _size(unit, _best_sine_left(unit, rec), rng, noise_sd)
        return rec, amp * unit, {"freq_hz": (f0, 7 * f0), "allowed": (LINE,)}
    if shape == "chirp":
        f_lo, f_hi = 5 / span, rng.uniform(40, 80) / span
        tc = t if rng.random() < 0.5 else span - t  # sweeping up or down
        ph = 2 * np.pi * (f_lo * tc + 0.5 * (f_hi - f_lo) * tc * tc / span) + rng.uniform(0, 2 * np.pi)
        unit = np.sin(ph)
        amp = _size(unit, _best_sine_left(unit, rec), rng, noise_sd)
        return rec, amp * unit, {"freq_hz": (f_lo, f_hi), "allowed": (LINE,)}
    if shape == "bursts":
        f0 = rng.uniform(40, 100) / span
        width = 0.05 * span
        starts = np.sort(rng.choice(np.linspace(0.05, 0.85, 17), 3, replace=False)) * span
        env = np.zeros(rec.n)
        for s in starts:
            env[(t >= s) & (t < s + width)] = 1.0
        unit = env * np.sin(2 * np.pi * f0 * t + rng.uniform(0, 2 * np.pi))
        amp = _size(unit, _best_sine_left(unit, rec), rng, noise_sd)
        return rec, amp * unit, {"windows_s": [(rec.t_s[0] + s, rec.t_s[0] + s + width) for s in starts],
                                 "freq_hz": (0.8 * f0, 1.2 * f0), "allowed": (LINE,)}
    if shape == "noise_bursts":
        width = 0.08 * span
        starts = np.sort(rng.choice(np.linspace(0.05, 0.85, 17), 2, replace=False)) * span
        factor = rng.uniform(2.0, 4.0)
        extra = np.zeros(rec.n)
        for s in starts:
            sel = (t >= s) & (t < s + width)
            extra[sel] = noise_sd * math.sqrt(factor ** 2 - 1) * rng.standard_normal(int(sel.sum()))
        return rec, extra, {"windows_s": [(rec.t_s[0] + s, rec.t_s[0] + s + width) for s in starts]}
    if shape == "supply":
        switches = int(rng.integers(12, 21))
        at = np.sort(rng.uniform(rec.t_s[0], rec.t_s[-1], switches))
        levels = rng.choice([11.0, 11.5, 12.0, 12.5, 13.0], switches + 1)
        volts = levels[np.searchsorted(at, rec.t_s)]
        rec = rec.replace(supply_v=volts)
        unit = volts - 12.0
        amp = _size(unit, project_out(unit, base_regressors(rec)), rng, noise_sd)
        return rec, amp * unit * (1 if rng.random() < 0.5 else -1), {"column": "supply"}
    if shape == "tanh":
        if not rec.varies("input"):
            raise ValueError("tanh needs a varying input")
        u = rec.column("input")
        peak = float(np.max(np.abs(u)))
        lim = peak * rng.uniform(0.8, 2.0)
        unit = lim * np.tanh(u / lim) - u
        amp = _size(unit, _poly_left(unit, rec), rng, noise_sd)
        # the compression's depth is set by lim; amp scales it onto the size rule
        return rec, amp * unit, {"column": "input", "allowed": POLYNOMIAL}
    if shape == "telegraph":
        at = np.sort(rng.choice(np.arange(1, rec.n), int(rng.integers(10, 101)), replace=False))
        level = telegraph_levels(at, rec.n)
        amp = noise_sd * math.exp(rng.uniform(0.0, math.log(4.0)))
        return rec, amp * level * rng.choice([-1.0, 1.0]), {"levels": True}
    if shape == "am_line":
        f0 = rng.uniform(20, 200) / span
        env = np.zeros(rec.n)
        for _ in range(3):
            env += np.cos(2 * np.pi * rng.uniform(1, 3) / span * t + rng.uniform(0, 2 * np.pi))
        env /= float(np.max(np.abs(env)))
        unit = (1.0 + rng.uniform(0.5, 0.9) * env) * np.sin(2 * np.pi * f0 * t + rng.uniform(0, 2 * np.pi))
        amp = _size(unit, _best_sine_left(unit, rec), rng, noise_sd)
        return rec, amp * unit, {"freq_hz": (0.8 * f0, 1.2 * f0), "allowed": (LINE,)}
    raise ValueError(f"unknown shape {shape!r}; allowed: {list(SHAPES)}")


def found_where(where: dict, unexplained: list[str]) -> bool:
    """True when some unexplained finding sits where the hidden structure is: a spectral line or
    band inside its frequencies, a segment or jump inside one of its windows, a correlation with
    its column."""
    if "column" in where:
        return any(f"correlation with {where['column']}" in u for u in unexplained)
    if "levels" in where:  # steps between levels: a process doubted for its jumps, or the jumps themselves
        return any("it jumps" in u or "jump at t" in u for u in unexplained)
    ok = False
    if "windows_s" in where:
        for u in unexplained:
            for seg in _times(u):
                ok |= any(a - 1e-9 <= seg[1] and seg[0] <= b + 1e-9 for a, b in where["windows_s"])
    if "freq_hz" in where:
        lo, hi = where["freq_hz"]
        for u in unexplained:
            for fa, fb in _freqs(u):
                ok |= fa <= 1.15 * hi and fb >= 0.85 * lo
    return ok


def _times(text: str) -> list[tuple[float, float]]:
    out = []
    m = re.search(r"segment ([-\d.e+]+)–([-\d.e+]+) s", text)
    if m:
        out.append((float(m.group(1)), float(m.group(2))))
    m = re.search(r"jump at t = ([-\d.e+]+) s", text)
    if m:
        out.append((float(m.group(1)), float(m.group(1))))
    return out


def _freqs(text: str) -> list[tuple[float, float]]:
    m = re.search(r"spectral (?:line|band) at ([\d.e+-]+)–([\d.e+-]+) Hz", text)
    if m:
        return [(float(m.group(1)), float(m.group(2)))]
    m = re.search(r"spectral line at ([\d.e+-]+) Hz", text)
    if m:
        return [(float(m.group(1)), float(m.group(1)))]
    return []
