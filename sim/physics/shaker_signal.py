"""Random vibration as a time series: white Gaussian noise through an FIR filter shaped to
the profile's acceleration spectral density.

Design (frequency sampling): the filter's magnitude is |H(f)| = √(P(f)·fs/2) on a fine
grid (unit-variance white noise sampled at fs has a one-sided density of 2/fs per Hz, so
the output's density is P(f)); zero phase, inverse FFT, centred, truncated to
:data:`KERNEL_TAPS` taps under a Hann window.  The taps are then scaled so that Σh² = the
profile's g² exactly: the series' variance equals the profile's g rms² whatever the
window did to the band edges (the edges smear over ±2·fs/taps ≈ ±4 Hz).

Random access, deterministic: the white noise of sample block j (of
:data:`BLOCK_SAMPLES`) comes from its own generator seeded by ``(seed, j)``, so any
window of the series — e.g. the controller's last second, polled at arbitrary times — is
the same whatever was asked before.  Sample k is at t = k / :data:`CONTROL_RATE_HZ`.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import oaconvolve

#: control accelerometer sampling rate (Hz): Nyquist 4096 Hz above the 3000 Hz shaker limit
CONTROL_RATE_HZ = 8192
KERNEL_TAPS = 4097
BLOCK_SAMPLES = 8192
_DESIGN_GRID = 1 << 16  # frequency-sampling grid (0.125 Hz at 8192 Hz)
_CACHE_BLOCKS = 8


def design_kernel(profile, rate_hz: float = CONTROL_RATE_HZ, taps: int = KERNEL_TAPS) -> np.ndarray:
    """FIR taps whose output, for unit white noise, has the profile's ASD (g²/Hz)."""
    if profile.f_hi_hz >= rate_hz / 2:
        raise ValueError(f"profile up to {profile.f_hi_hz:g} Hz not below Nyquist {rate_hz / 2:g} Hz")
    if taps % 2 == 0 or taps < 3:
        raise ValueError(f"taps = {taps!r} must be odd and ≥ 3")
    f = np.fft.rfftfreq(_DESIGN_GRID, d=1.0 / rate_hz)
    magnitude = np.sqrt(profile.psd(f) * rate_hz / 2.0)
    impulse = np.fft.irfft(magnitude, _DESIGN_GRID)  # zero phase: symmetric about sample 0
    half = taps // 2
    h = np.concatenate([impulse[-half:], impulse[: half + 1]]) * np.hanning(taps + 2)[1:-1]
    h *= math.sqrt(profile.moment(0) / float(np.sum(h * h)))
    return h


class ShapedNoise:
    """The profile's acceleration (g) at CONTROL_RATE_HZ, sample k = k/rate s (k ≥ 0)."""

    def __init__(self, profile, seed: int) -> None:
        self.profile = profile
        self.kernel = design_kernel(profile)
        self._seed = int(seed)
        self._blocks: dict[int, np.ndarray] = {}

    def _white_block(self, j: int) -> np.ndarray:
        block = self._blocks.get(j)
        if block is None:
            block = np.random.default_rng([self._seed, j]).standard_normal(BLOCK_SAMPLES)
            if len(self._blocks) >= _CACHE_BLOCKS:
                self._blocks.pop(next(iter(self._blocks)))
            self._blocks[j] = block
        return block

    def white(self, k0: int, n: int) -> np.ndarray:
        """Unit white noise samples k0 .. k0+n−1 (zero before sample 0: the series starts at t = 0)."""
        out = np.zeros(n)
        lo, hi = max(k0, 0), k0 + n
        if hi <= lo:
            return out
        for j in range(lo // BLOCK_SAMPLES, (hi - 1) // BLOCK_SAMPLES + 1):
            a, b = max(lo, j * BLOCK_SAMPLES), min(hi, (j + 1) * BLOCK_SAMPLES)
            out[a - k0:b - k0] = self._white_block(j)[a - j * BLOCK_SAMPLES:b - j * BLOCK_SAMPLES]
        return out

    def samples(self, k0: int, n: int) -> np.ndarray:
        """Acceleration samples k0 .. k0+n−1 in g (causal filter of the white noise)."""
        if n <= 0:
            return np.zeros(0)
        taps = self.kernel.size
        w = self.white(k0 - (taps - 1), n + taps - 1)
        return oaconvolve(w, self.kernel, mode="valid")
