"""Which EMD components are non-random (Document C's trend ``u`` and periodic term ``s``).

:func:`nonrandom_terms` labels the residue and every IMF as ``"trend"``, ``"periodic"``
or ``"random"`` by this rule, in this order:

1. **The residue is the trend** (fewer than three extrema: a monotone or one-bend curve).
2. **Too slow to be stationary → trend.**  An IMF that completes fewer than
   ``min_cycles`` oscillations (zero crossings / 2) over the record cannot be told from a
   trend: its mean over the record is not estimable and stationarity tests have no
   power at that scale.
3. **Dominated by a spectral line → periodic.**  The IMF's Hann-windowed periodogram
   has its highest ordinate ``line_ratio`` times above the median of the ordinates
   around it (±``BACKGROUND_BINS`` bins, the main lobe excluded), more than noise would
   reach with false-alarm probability ``line_alpha`` over all bins (periodogram
   ordinates of noise are exponential, so the threshold is ``ln(bins / α) / ln 2``
   medians), **and** a sinusoid fitted by least squares at the refined peak frequency
   carries at least ``line_dominance`` (default half) of the IMF's variance.  The
   whole IMF is then the periodic term: its small amplitude modulation belongs to the
   tone, not to the noise model.
4. Everything else is **random** — the stationary part that the AR models describe.

A line that is significant but not dominant is reported (``line_ratio``,
``line_fraction``) and left in the random part, whose AR model then carries it.
Frequencies are in Hz (``rate_hz`` is the sampling rate); amplitudes in the signal's
units: the fitted sinusoid's amplitude for periodic terms, half the peak-to-peak
range for trends and ``√2 × rms`` for random IMFs.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from scipy import fft as sp_fft

from bench.analysis.emd._kernel import count_zero_crossings

BACKGROUND_BINS = 50  # each side of a peak, for the local noise level
MAIN_LOBE_BINS = 3  # Hann main lobe half-width (2 bins) plus one


@dataclass(frozen=True)
class Component:
    """One EMD component described; ``index`` is the IMF number (1 = fastest) or 0 for the residue.

    Attributes
    ----------
    index : int
        IMF number (1 = fastest), or 0 for the residue.
    kind : {"trend", "periodic", "random"}
        Label given by the rule of :func:`nonrandom_terms`.
    frequency_hz : float
        Line frequency in Hz (periodic), mean zero-crossing frequency in Hz (others), 0 (residue).
    amplitude : float
        In the signal's unit: the fitted sinusoid's amplitude (periodic), half the
        peak-to-peak range (trend), ``√2 × rms`` (random).
    rms : float
        RMS of the mean-removed component, in the signal's unit.
    cycles : float
        Oscillations over the record (zero crossings / 2).
    line_ratio : float
        Highest Hann-windowed periodogram ordinate over the local median (dimensionless).
    line_fraction : float
        Share of the component's variance carried by the fitted sinusoid, in [0, 1].
    reason : str
        Why the component got its label, in words.
    label : str
        Property: ``"IMF<k>"`` or ``"residue"``.
    """

    index: int
    kind: str  # "trend" | "periodic" | "random"
    frequency_hz: float  # line frequency (periodic), mean zero-crossing frequency (others), 0 (residue)
    amplitude: float
    rms: float  # of the mean-removed component
    cycles: float  # oscillations over the record
    line_ratio: float  # highest periodogram ordinate / local median
    line_fraction: float  # variance share of the fitted sinusoid
    reason: str

    @property
    def label(self) -> str:
        """``"IMF<index>"``, or ``"residue"`` for index 0."""
        return "residue" if self.index == 0 else f"IMF{self.index}"

    def to_dict(self) -> dict:
        """JSON-ready fields plus ``"component"`` (the label)."""
        d = asdict(self)
        d["component"] = self.label
        return d


@dataclass(frozen=True, eq=False)
class NonRandomTerms:
    """The classification of every component and the sum of the non-random ones.

    Returned by :func:`nonrandom_terms`.

    Attributes
    ----------
    components : tuple of Component
        IMF1..IMFk, then the residue.
    signal : ndarray of float, shape (n,)
        Sum of the trend and periodic components (Document C's ``u + s``), in the signal's unit.
    random_indices : tuple of int
        IMF numbers labelled random: the stationary part left to the AR models.
    settings : dict
        The rule's options and derived threshold (``line_threshold_medians``, ``background_bins``).
    nonrandom : tuple of Component
        Property: the components labelled trend or periodic.
    """

    components: tuple[Component, ...]  # IMF1..IMFk then the residue
    signal: np.ndarray  # trend + periodic terms, in the signal's units
    random_indices: tuple[int, ...]  # IMF numbers left to the AR models
    settings: dict

    @property
    def nonrandom(self) -> tuple[Component, ...]:
        """The components labelled trend or periodic."""
        return tuple(c for c in self.components if c.kind != "random")

    def to_dict(self) -> dict:
        """JSON-ready non-random components, random IMF numbers and the rule's settings."""
        return {"components": [c.to_dict() for c in self.nonrandom], "random_imfs": list(self.random_indices),
                "rule": dict(self.settings)}


def _fit_line(x: np.ndarray, rate_hz: float) -> tuple[float, float, float, float]:
    """Strongest spectral line of the mean-removed ``x``: (frequency_hz, amplitude, ratio, fraction)."""
    n = x.size
    xd = x - x.mean()
    var = float(xd @ xd) / n
    if var <= 0:
        return 0.0, 0.0, 0.0, 0.0
    w = np.hanning(n)
    power = np.abs(sp_fft.rfft(xd * w)) ** 2
    power[0] = 0.0  # DC is the mean, removed
    k = int(np.argmax(power))
    lo, hi = max(1, k - BACKGROUND_BINS), min(power.size, k + BACKGROUND_BINS + 1)
    around = np.r_[power[lo : max(lo, k - MAIN_LOBE_BINS)], power[min(hi, k + MAIN_LOBE_BINS + 1) : hi]]
    ratio = float(power[k] / np.median(around)) if around.size and np.median(around) > 0 else np.inf
    # refine the peak between bins (parabola through the log-power of the Hann lobe)
    if 1 <= k < power.size - 1 and power[k - 1] > 0 and power[k + 1] > 0:
        l0, l1, l2 = np.log(power[k - 1 : k + 2])
        den = l0 - 2 * l1 + l2
        shift = 0.5 * (l0 - l2) / den if den < 0 else 0.0
    else:
        shift = 0.0
    f_hz = (k + float(np.clip(shift, -0.5, 0.5))) * rate_hz / n
    ph = 2 * np.pi * f_hz / rate_hz * np.arange(n)
    basis = np.column_stack([np.cos(ph), np.sin(ph)])
    coef, *_ = np.linalg.lstsq(basis, xd, rcond=None)
    amp = float(np.hypot(*coef))
    return f_hz, amp, ratio, min(1.0, 0.5 * amp**2 / var)


def nonrandom_terms(imfs: np.ndarray, residue: np.ndarray, rate_hz: float, *, min_cycles: float = 8.0,
                    line_alpha: float = 1e-3, line_dominance: float = 0.5) -> NonRandomTerms:
    """Label the residue and each IMF (rows of ``imfs``, fastest first) by the module's rule.

    In this order: the residue is the trend; an IMF with fewer than ``min_cycles``
    oscillations is trend; an IMF whose periodogram line exceeds the local median by the
    false-alarm threshold ``ln(bins / line_alpha) / ln 2`` **and** whose fitted sinusoid
    carries at least ``line_dominance`` of its variance is periodic; the rest is random.

    Parameters
    ----------
    imfs : array_like of float, shape (k, n)
        IMFs, fastest first (e.g. ``EmdResult.imfs``), in the signal's unit.
    residue : array_like of float, shape (n,)
        The EMD residue, same unit.
    rate_hz : float
        Sampling rate in Hz, > 0.
    min_cycles : float, default 8.0
        Fewest oscillations over the record for an IMF not to count as trend; ≥ 0.
    line_alpha : float, default 1e-3
        False-alarm probability of the spectral-line test over all bins, in (0, 1).
    line_dominance : float, default 0.5
        Least share of an IMF's variance its fitted sinusoid must carry to be periodic, in (0, 1].

    Returns
    -------
    NonRandomTerms
        Every component's label, frequency (Hz) and amplitude (signal unit), the sum of the
        non-random ones and the numbers of the random IMFs.

    Raises
    ------
    ValueError
        If ``imfs`` and ``residue`` do not share the sample count (or ``residue`` is not 1-D),
        ``rate_hz`` is not > 0, ``min_cycles`` < 0, ``line_alpha`` is outside (0, 1) or
        ``line_dominance`` outside (0, 1].

    Examples
    --------
    Hand-made components at 100 Hz: white noise, a 5 Hz tone, a wave too slow to tell from a
    trend, and a ramp as the residue:

    >>> import numpy as np
    >>> from bench.analysis.emd import nonrandom_terms
    >>> t = np.arange(2000) / 100.0
    >>> noise = 0.2 * np.random.default_rng(0).normal(size=t.size)
    >>> imfs = np.array([noise, np.sin(2 * np.pi * 5.0 * t), 0.3 * np.sin(2 * np.pi * 0.2 * t)])
    >>> terms = nonrandom_terms(imfs, 0.05 * t, 100.0)
    >>> [(c.label, c.kind) for c in terms.components]
    [('IMF1', 'random'), ('IMF2', 'periodic'), ('IMF3', 'trend'), ('residue', 'trend')]
    >>> tone = terms.components[1]
    >>> round(tone.frequency_hz, 2), round(tone.amplitude, 2)
    (5.0, 1.0)
    >>> terms.random_indices, bool(np.allclose(terms.signal, imfs[1] + imfs[2] + 0.05 * t))
    ((1,), True)
    """
    imfs = np.atleast_2d(np.asarray(imfs, dtype=float))
    residue = np.asarray(residue, dtype=float)
    if residue.ndim != 1 or imfs.shape[1] != residue.size:
        raise ValueError(f"imfs {imfs.shape} and residue {residue.shape} must share the sample count")
    if not rate_hz > 0:
        raise ValueError(f"rate_hz = {rate_hz!r} must be > 0")
    if not min_cycles >= 0:
        raise ValueError(f"min_cycles = {min_cycles!r} must be ≥ 0")
    if not 0 < line_alpha < 1:
        raise ValueError(f"line_alpha = {line_alpha!r} must be in (0, 1)")
    if not 0 < line_dominance <= 1:
        raise ValueError(f"line_dominance = {line_dominance!r} must be in (0, 1]")
    n = residue.size
    duration_s = n / rate_hz
    bins = n // 2
    threshold = np.log(bins / line_alpha) / np.log(2.0)  # medians a noise ordinate exceeds w.p. α/bins
    comps: list[Component] = []
    signal = residue.copy()
    random_idx: list[int] = []
    for i, imf in enumerate(imfs, start=1):
        rms = float(np.std(imf))
        cycles = count_zero_crossings(imf - imf.mean()) / 2.0
        f_mean = cycles / duration_s
        f_line, amp, ratio, frac = _fit_line(imf, rate_hz)
        if cycles < min_cycles:
            kind, freq, a = "trend", f_mean, 0.5 * float(np.ptp(imf))
            why = f"{cycles:g} oscillations in the record (< {min_cycles:g}): indistinguishable from a trend"
        elif ratio > threshold and frac >= line_dominance:
            kind, freq, a = "periodic", f_line, amp
            why = (f"spectral line at {f_line:.6g} Hz, {ratio:.3g}× the local median (threshold "
                   f"{threshold:.3g}), carrying {frac:.0%} of the variance")
        else:
            kind, freq, a = "random", f_mean, np.sqrt(2.0) * rms
            why = ("no spectral line" if ratio <= threshold else
                   f"line at {f_line:.6g} Hz carries only {frac:.0%} of the variance") + "; stationary part"
        comps.append(Component(i, kind, float(freq), float(a), rms, float(cycles), float(ratio), float(frac), why))
        if kind == "random":
            random_idx.append(i)
        else:
            signal += imf
    comps.append(Component(0, "trend", 0.0, 0.5 * float(np.ptp(residue)), float(np.std(residue)),
                           count_zero_crossings(residue - residue.mean()) / 2.0, 0.0, 0.0,
                           "EMD residue: the trend"))
    settings = {"min_cycles": min_cycles, "line_alpha": line_alpha, "line_dominance": line_dominance,
                "line_threshold_medians": float(threshold), "background_bins": BACKGROUND_BINS}
    return NonRandomTerms(tuple(comps), signal, tuple(random_idx), settings)
