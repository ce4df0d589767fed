"""Consistency checks that gate a fusion method where there is no reference to judge it.

Without a reference no method's error can be measured, but a method can be caught being wrong:
its output, read back through each sensor's model, must agree with that sensor's reading in the
band that sensor passes, to within the sensor's noise.

**Why that bound.**  Two sensors read the rate ``ω`` through ``G_h``, ``G_l`` with independent
noise ``n_h``, ``n_l`` (PSDs ``S_h``, ``S_l``); on the rate scale their noises are
``N_s = S_s/|G_s|²``.  The best linear estimate weights the sensors' inverted readings by
``N_l/(N_h+N_l)`` and ``N_h/(N_h+N_l)``, and its *read-back residual* ``r_s = y_s − G_s·ω̂``
has the PSD ``S_s·N_s/(N_h+N_l) ≤ S_s`` at every frequency — for both sensors.  A method that
leans on the wrong sensor (a smoother whose noise model was fitted to motion it did not model,
which then follows the LF sensor's inverse far above its corner) or that diverges leaves a
residual far above its sensor's noise where that sensor reads well.

:func:`check_method`: for each sensor, in each octave band where its model passes at least half
its gain, the ratio of the residual's mean PSD to the sensor's white-noise level must stay below
the F quantile at ``1 − alpha/m`` (``m`` the number of bands tested over both sensors:
Bonferroni), the degrees of freedom counting each Welch bin of each segment once (adjacent bins
of half-overlapped Hann segments are correlated: a conservative count).  The noise level is the
reading's own mean PSD between ``NOISE_BAND`` of the sample rate, where the motion has gone and
the reading is its white noise (motion there makes the check lenient, never strict).  The output
must also be finite.  Under the stated noise model a method at least as good as the best linear
one fails with probability at most ``alpha``; a sensor whose noise is not white (flicker below
the band) makes the check strict, and then the plain complementary filter is what is left.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.signal import bilinear, csd, lfilter, lfilter_zi, welch
from scipy.stats import f as f_dist

from bench.analysis.fusion._models import SensorModel

GATE_ALPHA = 0.01  # chance that a method as good as the best linear estimate fails its checks
NOISE_BAND = (0.38, 0.48)  # fractions of the sample rate where a reading is its white noise
MIN_SEGMENTS = 16  # Welch segments (half overlap) the record holds at least
PASSBAND = 0.5  # a sensor is tested in the octaves where its model's gain is at least this of its passband's
EDGE_TIME_CONSTANTS = 5.0  # the slowest corner's time constants left out at each end (start-up)


@dataclass(frozen=True)
class BandCheck:
    """One sensor's read-back residual in one octave: band (Hz), residual PSD ÷ the sensor's
    white-noise PSD, and the bound it must stay below."""

    sensor: str
    band_hz: tuple
    ratio: float
    bound: float

    @property
    def passed(self) -> bool:
        return bool(math.isfinite(self.ratio) and self.ratio <= self.bound)

    def to_dict(self) -> dict:
        return {"sensor": self.sensor, "band_hz": [float(v) for v in self.band_hz],
                "ratio": float(self.ratio) if math.isfinite(self.ratio) else None, "bound": float(self.bound),
                "passed": self.passed}


@dataclass(frozen=True)
class MethodCheck:
    """A method's consistency checks without a reference (module docstring).

    Attributes
    ----------
    passed : bool
        Whether every band passed and the output is finite.
    reason : str
        Why it failed (the worst band), or what it passed, in words.
    bands : tuple of BandCheck
        Every band tested: sensor, band (Hz), residual PSD ÷ the sensor's noise PSD, bound.
    """

    passed: bool
    reason: str
    bands: tuple = ()

    def to_dict(self) -> dict:
        return {"passed": bool(self.passed), "reason": self.reason, "bands": [b.to_dict() for b in self.bands]}


def sensor_filter(model: SensorModel, rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """The sensor's model as a digital filter (bilinear transform, corner prewarped)."""
    wc = 2 * rate_hz * math.tan(math.pi * min(model.corner_hz, 0.45 * rate_hz) / rate_hz)
    den = [1 / wc, 1.0] if model.order == 1 else [1 / wc ** 2, 2 * model.zeta / wc, 1.0]
    if model.kind == "lowpass":
        num = [model.gain]
    else:
        num = list(model.gain * np.array([1 / wc, 0.0] if model.order == 1 else [1 / wc ** 2, 0.0, 0.0]))
    return bilinear(num, den, rate_hz)


def read_back(rate, model: SensorModel, rate_hz: float) -> np.ndarray:
    """What a sensor of ``model`` would read of ``rate`` (started in steady state at its first value)."""
    b, a = sensor_filter(model, rate_hz)
    x = np.asarray(rate, dtype=float)
    return lfilter(b, a, x, zi=lfilter_zi(b, a) * x[0])[0]


@dataclass(frozen=True)
class SensorNoise:
    """A sensor reading's white-noise PSD (reading unit²/Hz, one-sided) from its noise band, with
    the degrees of freedom of that estimate, and the Welch segment used."""

    psd: float
    dof: float
    nperseg: int


def welch_segment(n: int) -> int:
    """Welch segment: the longest power of two that leaves ``MIN_SEGMENTS`` half-overlapped segments."""
    return int(2 ** max(5, math.floor(math.log2(max(2 * n / (MIN_SEGMENTS + 1), 32)))))


def _edge(n: int, rate_hz: float, models: tuple) -> int:
    slowest = max(1 / (2 * math.pi * m.corner_hz) for m in models)
    return min(n // 10, int(EDGE_TIME_CONSTANTS * slowest * rate_hz))


def sensor_noise(y, rate_hz: float, nperseg: int) -> SensorNoise:
    """White-noise PSD of a reading from its mean Welch PSD over ``NOISE_BAND`` of the sample rate."""
    f, p = welch(np.asarray(y, dtype=float), fs=rate_hz, nperseg=nperseg, noverlap=nperseg // 2)
    use = (f >= NOISE_BAND[0] * rate_hz) & (f <= NOISE_BAND[1] * rate_hz)
    segments = max((len(y) - nperseg) // (nperseg // 2) + 1, 1)
    return SensorNoise(float(np.mean(p[use])), float(use.sum() * segments), nperseg)


def band_ratios(rate, y, model: SensorModel, rate_hz: float, level: SensorNoise, edge: int) -> list:
    """``(band_hz, ratio, dof)`` per octave where ``model`` passes at least ``PASSBAND`` of its gain:
    the read-back residual's mean Welch PSD over the octave ÷ the sensor's white-noise PSD."""
    resid = (np.asarray(y, dtype=float) - read_back(rate, model, rate_hz))[edge:len(y) - edge]
    nper = min(level.nperseg, welch_segment(resid.size))
    f, p = welch(resid, fs=rate_hz, nperseg=nper, noverlap=nper // 2)
    segments = max((resid.size - nper) // (nper // 2) + 1, 1)
    out = []
    lo = 4 * rate_hz / nper
    while lo < NOISE_BAND[0] * rate_hz:
        hi = min(2 * lo, NOISE_BAND[0] * rate_hz)
        use = (f >= lo) & (f < hi)
        if use.any() and abs(model.response(math.sqrt(lo * hi))) >= PASSBAND * abs(model.gain):
            out.append(((lo, hi), float(np.mean(p[use])) / level.psd, float(use.sum() * segments)))
        lo = hi
    return out


def _analog(model: SensorModel) -> tuple[np.ndarray, np.ndarray]:
    wc = 2 * math.pi * model.corner_hz
    den = np.array([1 / wc, 1.0] if model.order == 1 else [1 / wc ** 2, 2 * model.zeta / wc, 1.0])
    num = np.array([model.gain]) if model.kind == "lowpass" else \
        model.gain * np.array([1 / wc, 0.0] if model.order == 1 else [1 / wc ** 2, 0.0, 0.0])
    return num, den


def difference_noise(hf, lf, hf_model: SensorModel, lf_model: SensorModel, rate_hz: float) -> tuple[float, float]:
    """Upper bounds of the sensors' white-noise PSDs (their units²/Hz) from their *difference*, in
    which the motion cancels (the models' error aside):

    * HF: ``d_h = P·y_h − P·(G_h/G_l)·y_l`` (``P`` a low-pass of the LF order at a quarter of the
      sample rate, which makes ``G_h/G_l`` proper; digital by the bilinear transform) is the HF
      noise where ``|G_h/G_l|`` is small — below the HF corner;
    * LF: ``D = Y_l − (G_l/G_h)·Y_h`` (from the Welch spectra) is the LF noise where
      ``|G_l/G_h|`` is small — above the LF corner.

    Each bound is the least, over the octaves from the record's resolution to the noise band,
    of the difference's mean PSD (the HF one divided by ``|P|²``); Welch segments long enough
    for eight bins below the HF corner (at most a quarter of the record).  Model error and motion
    the models do not cancel only add.  NaN where no octave holds two bins."""
    n = len(hf)
    nperseg = int(2 ** math.ceil(math.log2(max(8 * rate_hz / hf_model.corner_hz, 64))))
    nperseg = min(nperseg, int(2 ** math.floor(math.log2(max(n // 4, 64)))))
    kw = {"fs": rate_hz, "nperseg": nperseg, "noverlap": nperseg // 2}
    # HF: the LF reading through G_h/G_l, both through P, in the time domain (no leakage of the motion)
    (nh, dh), (nl, dl) = _analog(hf_model), _analog(lf_model)
    wp = 2 * math.pi * 0.25 * rate_hz
    pole = np.array([1.0])
    for _ in range(lf_model.order):
        pole = np.polymul(pole, [1 / wp, 1.0])
    b1, a1 = bilinear([1.0], pole, rate_hz)
    b2, a2 = bilinear(np.polymul(nh, dl), np.polymul(np.polymul(dh, nl), pole), rate_hz)
    d_h = lfilter(b1, a1, np.asarray(hf, dtype=float)) - lfilter(b2, a2, np.asarray(lf, dtype=float))
    skip = min(n // 4, nperseg)  # the filters' start
    f, p_dh = welch(d_h[skip:], **{**kw, "nperseg": min(nperseg, max(64, (n - skip) // 4))})
    p_dh = p_dh * np.abs(1 + 1j * f / (0.25 * rate_hz)) ** (2 * lf_model.order)
    # LF: from the spectra, where the HF term is small
    f2, p_hh = welch(hf, **kw)
    p_ll = welch(lf, **kw)[1]
    p_hl = csd(hf, lf, **kw)[1]  # conj(Y_h)·Y_l
    keep = f2 > 0
    f2, p_hh, p_ll, p_hl = f2[keep], p_hh[keep], p_ll[keep], p_hl[keep]
    r = lf_model.response(f2) / hf_model.response(f2)
    p_d = p_ll + np.abs(r) ** 2 * p_hh - 2 * np.real(r * np.conj(p_hl))

    def least(freq: np.ndarray, psd: np.ndarray, step: float) -> float:
        out, lo = math.inf, 2 * step
        while lo < NOISE_BAND[0] * rate_hz:
            band = (freq >= lo) & (freq < 2 * lo)
            if band.sum() >= 2:
                out = min(out, float(np.mean(psd[band])))
            lo *= 2
        return out if math.isfinite(out) and out > 0 else math.nan

    return least(f, p_dh, f[1] - f[0]), least(f2, p_d, f2[1] - f2[0] if f2.size > 1 else rate_hz)


def check_method(rate, hf, lf, hf_model: SensorModel, lf_model: SensorModel, rate_hz: float,
                 alpha: float = GATE_ALPHA, noise: tuple | None = None, yardstick=None) -> MethodCheck:
    """A method's output checked against both sensors' readings (module docstring).

    Parameters
    ----------
    rate : array_like, shape (n,)
        The method's output, rate units.
    hf, lf : array_like, shape (n,)
        The readings it was made from (spikes replaced, on one clock), their units.
    hf_model, lf_model : SensorModel
        The sensors' models (the method's own).
    rate_hz : float
        Sample rate, in Hz.
    alpha : float, default 0.01
        Chance that a method as good as the best linear estimate fails, in (0, 1).
    noise : tuple of SensorNoise, optional
        The HF and LF white-noise levels (:func:`sensor_noise`); default measured here.
    yardstick : array_like, shape (n,), optional
        The plain complementary filter's output on the same readings: a band passes also where
        the method's residual is no larger than the yardstick's (module docstring).

    Returns
    -------
    MethodCheck
        Passed or not, the reason, every band tested.

    Raises
    ------
    ValueError
        If ``alpha`` is outside (0, 1).

    Examples
    --------
    Broadband motion read by a 1 Hz high-pass and a 40 Hz low-pass; a complementary filter that
    crosses over at 600 Hz (it trusts the LF sensor's inverse far above its corner, as a smoother
    with a wrong noise model does) fails; one that crosses over between the corners passes:

    >>> import numpy as np
    >>> from bench.analysis.fusion import FusionModel, SensorModel, check_method, complementary_filter
    >>> from bench.analysis.fusion._consistency import read_back
    >>> fs, n = 2000.0, 40000
    >>> rng = np.random.default_rng(2)
    >>> hf_m, lf_m = SensorModel("highpass", 1, 1.0), SensorModel("lowpass", 1, 40.0)
    >>> rate = np.convolve(rng.standard_normal(n + 99), np.ones(100) / 10, mode="valid")
    >>> hf = read_back(rate, hf_m, fs) + 1e-3 * rng.standard_normal(n)
    >>> lf = read_back(rate, lf_m, fs) + 1e-3 * rng.standard_normal(n)
    >>> blend = complementary_filter(hf, lf, fs, FusionModel(hf_m, lf_m, 1.0), 6.3)
    >>> lf_only = complementary_filter(hf, lf, fs, FusionModel(hf_m, lf_m, 1.0), 600.0)
    >>> check_method(blend, hf, lf, hf_m, lf_m, fs).passed, check_method(lf_only, hf, lf, hf_m, lf_m, fs).passed
    (True, False)
    """
    if not 0 < alpha < 1:
        raise ValueError(f"alpha {alpha} must be in (0, 1)")
    x = np.asarray(rate, dtype=float)
    if not np.all(np.isfinite(x)):
        return MethodCheck(False, "its output is not finite")
    n = x.size
    nper = welch_segment(n)
    if noise is None:
        noise = (sensor_noise(hf, rate_hz, nper), sensor_noise(lf, rate_hz, nper))
    edge = _edge(n, rate_hz, (hf_model, lf_model))
    tests = []
    for name, y, model, level in (("hf", hf, hf_model, noise[0]), ("lf", lf, lf_model, noise[1])):
        mine = band_ratios(x, y, model, rate_hz, level, edge)
        yard = (band_ratios(yardstick, y, model, rate_hz, level, edge) if yardstick is not None
                else [(b, 1.0, d) for b, _, d in mine])
        tests += [(name, band, ratio, max(1.0, other), dof, level.dof)
                  for (band, ratio, dof), (_, other, _) in zip(mine, yard)]
    if not tests:
        return MethodCheck(True, "no band to test")
    bands = tuple(BandCheck(name, band, ratio, scale * float(f_dist.isf(alpha / len(tests), dof, dof_noise)))
                  for name, band, ratio, scale, dof, dof_noise in tests)
    failed = [b for b in bands if not b.passed]
    if failed:
        worst = max(failed, key=lambda b: b.ratio / b.bound if math.isfinite(b.ratio) else math.inf)
        return MethodCheck(False, f"its read-back residual of the {worst.sensor.upper()} sensor at "
                                  f"{worst.band_hz[0]:.3g}–{worst.band_hz[1]:.3g} Hz is {worst.ratio:.3g}× that "
                                  f"sensor's noise (bound {worst.bound:.3g})", bands)
    return MethodCheck(True, f"agrees with each sensor within its noise or as well as the complementary filter "
                             f"in {len(bands)} bands", bands)
