"""The angular vibration table's reference capture: encoder angle and reference rate on the
table's own clock (the World's, exact).

Sample k of a capture started (``:REF:INIT``) at t₀ is taken at t₀ + k/rate for k < count.
Its three values are (k/rate s since the capture start, encoder angle in degrees,
reference rate in °/s):

* encoder angle: the table's angle quantized by a 2²⁴-count-per-revolution encoder
  (floor to the count below; resolution 360/2²⁴ ≈ 2.1·10⁻⁵ °);
* reference rate: the true rate plus white noise of 2·10⁻⁴ °/s rms.

Samples are computed when read (all those due at or before ``now``): the motion is
analytic and never changes its past, so a late computation is exact.  The noise is
counter-based — block b of 2¹⁶ samples of capture c comes from its own Philox stream (counter
(b, c), key one draw of the device's generator) — so the bytes do not depend on how often the capture is polled,
and samples that overflow the memory are skipped without being computed.  The memory is a
FIFO of :data:`MEMORY_SAMPLES`; when it is full the oldest samples are dropped and the
overflow flag is set (cleared by the next ``:REF:INIT``).
"""

from __future__ import annotations

import math

import numpy as np

MEMORY_SAMPLES = 4_000_000
ENCODER_COUNTS = 1 << 24
RATE_NOISE_DPS = 2e-4
RATE_RANGE_HZ = (1.0, 50_000.0)
COUNT_RANGE = (1, 1_000_000_000)
DEFAULT_REF_RATE_HZ = 1000.0
DEFAULT_REF_COUNT = 1000
_NOISE_BLOCK = 1 << 16
_CHUNK = 1 << 16


class ReferenceCapture:
    """Capture settings, the acquisition in progress and its FIFO memory."""

    def __init__(self, motion, rng: np.random.Generator, memory: int = MEMORY_SAMPLES) -> None:
        self.motion = motion
        self.memory = int(memory)
        self._key = [int(x) for x in rng.integers(0, 2**63, size=2)]
        self.rate_hz = DEFAULT_REF_RATE_HZ
        self.count = DEFAULT_REF_COUNT
        self._t0: float | None = None
        self._next_k = 0      # next sample to compute
        self._end_k = 0       # samples this capture takes
        self._chunks: list[np.ndarray] = []
        self._head = 0        # rows of _chunks[0] already read
        self._stored = 0
        self.overflow = False
        self._block = (-1, np.zeros(0))
        self._capture_no = 0  # each capture its own noise streams

    # ---- control -----------------------------------------------------------------------
    def set_rate(self, rate_hz: float) -> None:
        lo, hi = RATE_RANGE_HZ
        if not lo <= rate_hz <= hi:
            raise ValueError(f"reference rate {rate_hz!r} Hz not in {lo:g}..{hi:g} Hz")
        self.rate_hz = float(rate_hz)

    def set_count(self, count: int) -> None:
        lo, hi = COUNT_RANGE
        if not lo <= count <= hi:
            raise ValueError(f"reference count {count!r} not in {lo}..{hi}")
        self.count = int(count)

    def initiate(self, now: float) -> None:
        """Start a capture at ``now`` (the memory is cleared, the overflow flag too)."""
        self.clear()
        self._capture_no += 1
        self._block = (-1, np.zeros(0))
        self._t0, self._next_k, self._end_k = float(now), 0, self.count

    def abort(self, now: float) -> None:
        """End the capture: samples due up to ``now`` stay readable, no more are taken."""
        if self._t0 is not None:
            self._fill(now)
            self._end_k = self._next_k

    def clear(self) -> None:
        self._chunks, self._head, self._stored, self.overflow = [], 0, 0, False
        self._t0, self._next_k, self._end_k = None, 0, 0

    @property
    def running(self) -> bool:
        return self._t0 is not None and self._next_k < self._end_k

    def is_running(self, now: float) -> bool:
        self._fill(now)
        return self.running

    # ---- data --------------------------------------------------------------------------
    def points(self, now: float) -> int:
        """Samples captured and not yet read."""
        self._fill(now)
        return self._stored

    def remove(self, now: float, max_points: int) -> np.ndarray:
        """Up to ``max_points`` oldest samples, (n, 3): t_s, angle_deg, rate_dps; removed."""
        self._fill(now)
        out, need = [], min(int(max_points), self._stored)
        while need:
            c = self._chunks[0]
            take = min(need, c.shape[0] - self._head)
            out.append(c[self._head:self._head + take])
            self._head += take
            need -= take
            self._stored -= take
            if self._head == c.shape[0]:
                self._chunks.pop(0)
                self._head = 0
        return np.concatenate(out) if out else np.zeros((0, 3))

    def _fill(self, now: float) -> None:
        if self._t0 is None or self._next_k >= self._end_k:
            return
        # samples at t0 + k/rate ≤ now (a hair of slack for the float division)
        due = min(self._end_k, math.floor((now - self._t0) * self.rate_hz + 1e-7) + 1)
        if due <= self._next_k:
            return
        new = due - self._next_k
        if new >= self.memory:  # everything stored and the oldest new ones are lost
            self._chunks, self._head, self._stored = [], 0, 0
            self._next_k = due - self.memory
            self.overflow = True
            new = self.memory
        elif self._stored + new > self.memory:
            self._drop(self._stored + new - self.memory)
            self.overflow = True
        for k0 in range(self._next_k, due, _CHUNK):
            k = np.arange(k0, min(k0 + _CHUNK, due))
            self._chunks.append(self._samples(k))
        self._stored += new
        self._next_k = due

    def _drop(self, n: int) -> None:
        while n:
            c = self._chunks[0]
            take = min(n, c.shape[0] - self._head)
            self._head += take
            self._stored -= take
            n -= take
            if self._head == c.shape[0]:
                self._chunks.pop(0)
                self._head = 0

    def _samples(self, k: np.ndarray) -> np.ndarray:
        assert self._t0 is not None, "samples exist only while capturing"
        t_rel = k / self.rate_hz
        t = self._t0 + t_rel
        rate, angle, _ = self.motion.motion(t)
        counts = np.floor(angle / (2 * math.pi) * ENCODER_COUNTS)
        angle_deg = counts * (360.0 / ENCODER_COUNTS)
        rate_dps = np.degrees(rate) + RATE_NOISE_DPS * self._noise(k)
        return np.column_stack([t_rel, angle_deg, rate_dps])

    def _noise(self, k: np.ndarray) -> np.ndarray:
        """Unit normal noise of samples ``k`` (consecutive), block by block."""
        out = np.empty(k.size)
        blocks = k // _NOISE_BLOCK
        for b in np.unique(blocks):
            sel = blocks == b
            out[sel] = self._noise_block(int(b))[k[sel] % _NOISE_BLOCK]
        return out

    def _noise_block(self, b: int) -> np.ndarray:
        if self._block[0] != b:
            gen = np.random.Generator(np.random.Philox(key=self._key, counter=[0, b, self._capture_no, 0]))
            self._block = (b, gen.standard_normal(_NOISE_BLOCK))
        return self._block[1]


__all__ = ["COUNT_RANGE", "DEFAULT_REF_COUNT", "DEFAULT_REF_RATE_HZ", "ENCODER_COUNTS", "MEMORY_SAMPLES",
           "RATE_NOISE_DPS", "RATE_RANGE_HZ", "ReferenceCapture"]
