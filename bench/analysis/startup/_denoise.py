"""Daubechies-wavelet denoising exactly as Document A, step 2.

1. Forward DWT of the trace with a Daubechies wavelet ``dbM`` to ``level`` L.
2. ``σ = median(|W1,n|) / 0.6745`` over the first-level (finest) detail coefficients
   ``W1,n`` — the median absolute deviation of Gaussian noise is ``0.6745 σ``.
3. ``λ = σ·sqrt(2 ln N)`` (Donoho–Johnstone universal threshold, N = trace length).
4. Soft thresholding ``w ← sign(w)·(|w| − λ)`` if ``|w| ≥ λ`` else 0, then the inverse DWT.

Which coefficients are thresholded: every detail level 1..L, never the level-L
approximation.  Why: the transform is orthonormal, so white measurement noise has the
same σ in every detail level and one λ serves all of them (σ is measured at level 1,
where the smooth start-up transient has almost no energy and the MAD sees only noise);
the approximation carries the slow start-up trend and drift, which thresholding would
only bias.

Boundary handling is PyWavelets' ``symmetric`` extension: a start-up trace begins at
its steepest point, and mirroring keeps it continuous there (``periodization`` would
splice the settled end onto the power-on transient).  With this mode level 1 holds
``floor((N + 2M - 1) / 2)`` coefficients rather than Document A's ``N/2``; the few extra
boundary coefficients change the median negligibly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pywt

MAD_TO_SIGMA = 0.6745  # median(|N(0, 1)|)
MIN_SAMPLES = 16
BOUNDARY_MODE = "symmetric"


@dataclass(frozen=True, eq=False)
class DenoiseResult:
    """Outcome of :func:`wavelet_denoise`; ``sigma`` and ``threshold`` are in the trace's units.

    Attributes
    ----------
    wavelet : str
        Daubechies wavelet used, ``"db1"`` … ``"db38"``.
    level : int
        Decomposition depth L (≥ 1).
    sigma : float
        Noise standard deviation ``median(|W1,n|) / 0.6745`` from the finest detail level,
        in the trace's units.
    threshold : float
        Universal threshold ``λ = σ·sqrt(2 ln N)``, in the trace's units.
    thresholded_levels : tuple of int
        Detail levels soft-thresholded, 1 = finest (always ``1..L``).
    denoised : ndarray of float, shape (N,)
        The denoised trace (read-only), in the trace's units.
    n : int
        Property: number of samples N.
    """

    wavelet: str
    level: int
    sigma: float
    threshold: float
    thresholded_levels: tuple[int, ...]  # detail levels, 1 = finest
    denoised: np.ndarray

    @property
    def n(self) -> int:
        """Number of samples of the trace."""
        return self.denoised.size


def choose_wavelet(n: int) -> str:
    """Daubechies wavelet for a trace of ``n`` samples: db8 from 2¹⁴, db6 from 2¹¹, db4 from 2⁸, else db2.

    More vanishing moments represent the smooth transient with fewer, larger
    coefficients (less of it is touched by the threshold); longer filters need longer
    records so that boundary-affected coefficients stay a small fraction.
    """
    if n < MIN_SAMPLES:
        raise ValueError(f"trace has {n} samples; wavelet denoising needs at least {MIN_SAMPLES}")
    for min_n, name in ((2**14, "db8"), (2**11, "db6"), (2**8, "db4")):
        if n >= min_n:
            return name
    return "db2"


def choose_level(n: int, wavelet: str) -> int:
    """Decomposition depth: ``floor(log2(n) / 2)``, capped by PyWavelets' maximum useful level.

    The approximation then keeps about ``sqrt(n)`` coefficients — fine enough to follow
    the start-up transient untouched — while the thresholded details span scales up to
    ``sqrt(n)`` samples.
    """
    max_level = pywt.dwt_max_level(n, pywt.Wavelet(wavelet).dec_len)
    return int(max(1, min(max_level, int(np.log2(n) // 2))))


def wavelet_denoise(x: np.ndarray, wavelet: str | None = None, level: int | None = None) -> DenoiseResult:
    """Denoise ``x`` (uniformly sampled, any units) per Document A; see the module docstring.

    ``wavelet`` must be a Daubechies name ``db1``..``db38``; ``wavelet`` and ``level``
    default to :func:`choose_wavelet` and :func:`choose_level`.

    Forward DWT (PyWavelets, ``symmetric`` boundary), ``σ = median(|W1,n|) / 0.6745`` from
    the finest details, universal threshold ``λ = σ·sqrt(2 ln N)``, soft thresholding of
    every detail level 1..L (never the approximation), inverse DWT.

    Parameters
    ----------
    x : array_like of float, shape (N,)
        The trace, uniformly sampled, in any unit (V, mA, g, …); finite, N ≥ 16.
    wavelet : str, optional
        Daubechies wavelet ``"db1"`` … ``"db38"``.  Default by length: db8 from 2¹⁴ samples,
        db6 from 2¹¹, db4 from 2⁸, else db2.
    level : int, optional
        Decomposition depth, an integer in ``[1, max]`` with ``max`` PyWavelets' maximum
        useful level for N and the wavelet.  Default ``floor(log2(N) / 2)``, capped at ``max``.

    Returns
    -------
    DenoiseResult
        The denoised trace (same unit as ``x``), wavelet, level, σ and λ.

    Raises
    ------
    ValueError
        If ``x`` is not 1-D, has fewer than 16 samples or a non-finite value, ``wavelet`` is
        not ``db1``..``db38``, or ``level`` is not an integer in ``[1, max]``.

    Examples
    --------
    >>> import numpy as np
    >>> from bench.analysis.startup import wavelet_denoise
    >>> t = np.arange(2000) * 0.1
    >>> clean = 1.0 + 0.05 * np.exp(-t / 20.0)
    >>> x = clean + np.random.default_rng(0).normal(0.0, 0.002, t.size)
    >>> d = wavelet_denoise(x)
    >>> d.wavelet, d.level, d.thresholded_levels
    ('db4', 5, (1, 2, 3, 4, 5))
    >>> round(d.sigma, 4)  # the white noise level, estimated
    0.002
    >>> bool(np.std(d.denoised - clean) < 0.25 * np.std(x - clean))
    True
    """
    arr = np.array(x, dtype=float)  # a copy: PyWavelets refuses read-only buffers
    if arr.ndim != 1:
        raise ValueError(f"trace must be one-dimensional, got shape {arr.shape}")
    n = arr.size
    if n < MIN_SAMPLES:
        raise ValueError(f"trace has {n} samples; wavelet denoising needs at least {MIN_SAMPLES}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"trace contains {int(np.sum(~np.isfinite(arr)))} non-finite values; all must be finite")
    wavelet = choose_wavelet(n) if wavelet is None else wavelet
    if wavelet not in pywt.wavelist("db"):
        raise ValueError(f"wavelet {wavelet!r} is not a Daubechies wavelet (allowed: db1..db38)")
    max_level = max(1, pywt.dwt_max_level(n, pywt.Wavelet(wavelet).dec_len))
    level = choose_level(n, wavelet) if level is None else level
    if int(level) != level or not 1 <= level <= max_level:
        raise ValueError(f"level = {level!r} must be an integer in [1, {max_level}] for {n} samples and {wavelet}")
    coeffs = pywt.wavedec(arr, wavelet, mode=BOUNDARY_MODE, level=int(level))
    # coeffs = [approximation_L, detail_L, ..., detail_1]
    sigma = float(np.median(np.abs(coeffs[-1])) / MAD_TO_SIGMA)
    threshold = sigma * float(np.sqrt(2.0 * np.log(n)))
    shrunk = [coeffs[0]] + [pywt.threshold(d, threshold, mode="soft") for d in coeffs[1:]]
    denoised = pywt.waverec(shrunk, wavelet, mode=BOUNDARY_MODE)[:n]  # odd n gains one sample
    denoised.flags.writeable = False
    return DenoiseResult(wavelet, int(level), sigma, threshold, tuple(range(1, int(level) + 1)), denoised)
