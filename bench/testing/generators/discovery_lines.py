"""Records holding a few spectral lines in white noise, drawn and realised apart from the
discovery catalogue: the grade of how ``bench discover`` names several lines at once.

A line here is ``A·cos(2π·f·t + θ)`` on the record's own clock ``t`` (which need not start at 0);
the catalogue's ``sinusoidal_interference`` writes the same line as
``A·sin(2π·f·(t − t₀) + φ)`` from the first sample ``t₀``, so ``φ = θ + 2π·f·t₀ + π/2`` (wrapped),
which :class:`DrawnLine` also gives, for comparison only.

Draws (:func:`draw_lines_record`):

* the white noise's sd ``sd`` (given) and the record: ``n`` samples at ``rate_hz`` from a start
  time uniform in 0 … 1000 s;
* each line's frequency log-uniform between 20 cycles over the record and 0.4 × the sample rate,
  the lines at least ``min_separation`` Fourier bins (1/T) apart (drawn again until they are);
* each line's snr — ``A·√(n/2)/sd``, the line's norm over the record against the noise's —
  log-uniform in ``snr``, its amplitude from it; its phase uniform in one turn.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bench.discovery.data import Record


@dataclass(frozen=True)
class DrawnLine:
    """One drawn line: amplitude (the record's unit), frequency (Hz), phase θ (rad) of
    ``A·cos(2πft + θ)`` on the record's clock, its snr, and ``phase_from_start_rad``: the phase φ
    of ``A·sin(2πf(t − t₀) + φ)`` (wrapped to ±π)."""

    amplitude: float
    freq_hz: float
    phase_rad: float
    snr: float
    phase_from_start_rad: float


def draw_lines_record(rng: np.random.Generator, *, count: int = 2, n: int = 600, rate_hz: float = 10.0,
                      sd: float = 3e-3, snr: tuple[float, float] = (15.0, 60.0),
                      min_separation: float = 3.0) -> tuple[Record, tuple[DrawnLine, ...]]:
    """(record, its lines, strongest first): ``count`` lines in Gaussian white noise of sd ``sd``
    (module docstring). ValueError for a count, length, rate, sd or snr range outside what a
    line can be drawn in, or lines that cannot be ``min_separation`` bins apart."""
    if isinstance(count, bool) or not isinstance(count, int) or count < 0:
        raise ValueError(f"count = {count!r}; allowed: an integer ≥ 0")
    if not (n >= 64 and rate_hz > 0 and sd > 0):
        raise ValueError(f"n = {n!r}, rate_hz = {rate_hz!r}, sd = {sd!r}; allowed: n ≥ 64, rate_hz > 0, sd > 0")
    if not 0 < snr[0] <= snr[1]:
        raise ValueError(f"snr = {snr!r}; allowed: 0 < low ≤ high")
    span = n / rate_hz
    f_lo, f_hi = 20.0 / span, 0.4 * rate_hz
    if count * min_separation > (f_hi - f_lo) * span:
        raise ValueError(f"{count} lines {min_separation} bins apart do not fit between {f_lo:.4g} and "
                         f"{f_hi:.4g} Hz on {n} samples")
    t = float(rng.uniform(0.0, 1000.0)) + np.arange(n) / rate_hz
    while True:
        freqs = np.exp(rng.uniform(math.log(f_lo), math.log(f_hi), count))
        if count < 2 or np.min(np.diff(np.sort(freqs))) * span >= min_separation:
            break
    y = np.zeros(n)
    lines = []
    for f in freqs:
        s = math.exp(rng.uniform(math.log(snr[0]), math.log(snr[1])))
        amp = s * sd / math.sqrt(n / 2.0)
        theta = float(rng.uniform(-math.pi, math.pi))
        y += amp * np.cos(2 * math.pi * f * t + theta)
        phi = (theta + 2 * math.pi * f * t[0] + 0.5 * math.pi + math.pi) % (2 * math.pi) - math.pi
        lines.append(DrawnLine(float(amp), float(f), theta, float(s), float(phi)))
    y += rng.normal(0.0, sd, n)  # drawn last: the same noise whatever the lines took of the stream
    lines.sort(key=lambda ln: -ln.amplitude)
    return Record(t_s=t, y=y), tuple(lines)
