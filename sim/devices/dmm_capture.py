"""Level-triggered and pretrigger acquisition of the simulated 34465A (DIG option).

With ``TRIG:SOUR INT`` (a trigger when the input crosses ``TRIG:LEV`` in the direction of
``TRIG:SLOP``) or ``SAMP:COUN:PRET`` > 0, the meter samples continuously from ``INIT`` on,
one reading every sample interval, while it waits for the trigger.  What the guide says,
and how it is modelled here, on one time grid ``t_arm + i·interval`` (reading i starts
there and integrates over the aperture):

* Pretrigger readings are kept in a ring of ``SAMP:COUN:PRET`` readings: the most recent
  ones are saved; fewer when the trigger comes early.  A reading in progress when the
  trigger arrives is a pretrigger reading.
* After the trigger, ``SAMP:COUN`` − ``SAMP:COUN:PRET`` readings are taken (memory was
  reserved for the pretrigger count even when fewer were taken).  Here they continue on
  the same grid, from the first grid point at least ``TRIG:DEL`` after the end of the
  last pretrigger reading (assumption: the real meter's post-trigger timing is not
  specified more closely).
* The level trigger fires on the first reading that reaches the level from the other
  side: for POS a reading ≥ level after one below it, for NEG ≤ level after one above.
  The reading's noise takes part, as on the meter; no hysteresis is modelled.  The first
  reading is compared with the input as it stood at ``INIT``.
* ``IMMediate`` triggers at ``INIT`` (no pretrigger readings), ``BUS`` on ``*TRG``,
  ``EXTernal`` never (nothing drives the Ext Trig input on the station).

This class is only the bookkeeping of that grid: which readings are due, which are kept;
the meter takes the readings (``sim.devices.dmm``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass
class CaptureGrid:
    """One continuous acquisition from ``t_arm`` (one trigger)."""

    t_arm: float
    interval_s: float
    aperture_s: float
    delay_s: float
    pretrigger: int          # SAMP:COUN:PRET: readings kept before the trigger (ring)
    post_count: int          # SAMP:COUN − SAMP:COUN:PRET readings after it
    level_v: float | None    # TRIG:LEV when level-triggered, else None
    slope: str = "POS"       # POS | NEG
    next_index: int = 0      # next reading to take
    trigger_index: int | None = None  # last pretrigger reading (−1: none), once triggered
    previous_v: float = math.nan      # the last reading taken (the level trigger compares)

    def t_start(self, i: np.ndarray) -> np.ndarray:
        return self.t_arm + i * self.interval_s

    def due(self, t: float) -> int:
        """Readings (from index 0) whose aperture has ended by ``t``."""
        eps = 1e-9 * self.interval_s
        return max(0, math.floor((t - self.t_arm - self.aperture_s + eps) / self.interval_s) + 1)

    @property
    def first_post_index(self) -> int:
        """First reading after the trigger (valid once triggered)."""
        assert self.trigger_index is not None
        k = self.trigger_index
        earliest = (self.t_arm if k < 0 else self.t_arm + k * self.interval_s + self.aperture_s) + self.delay_s
        return max(k + 1, math.ceil((earliest - self.t_arm) / self.interval_s - 1e-9))

    @property
    def end_index(self) -> int | None:
        """One past the last reading of the acquisition, once triggered."""
        return None if self.trigger_index is None else self.first_post_index + self.post_count

    def trigger_at_arm(self) -> None:
        """``TRIG:SOUR IMM``: triggered at ``INIT``, before any pretrigger reading."""
        self.trigger_index = -1

    def trigger_now(self, t: float) -> None:
        """A trigger at ``t`` (``*TRG``): the reading started by then is the last pretrigger one."""
        if self.trigger_index is None:
            self.trigger_index = max(-1, math.floor((t - self.t_arm) / self.interval_s + 1e-9))

    def crossing(self, values: np.ndarray) -> int | None:
        """Index in ``values`` (the next readings) of the first that fires the level trigger."""
        if self.level_v is None or values.size == 0:
            return None
        x = np.concatenate(([self.previous_v], values))
        if self.slope == "POS":
            hit = (x[:-1] < self.level_v) & (x[1:] >= self.level_v)
        else:
            hit = (x[:-1] > self.level_v) & (x[1:] <= self.level_v)
        found = np.flatnonzero(hit)
        return int(found[0]) if found.size else None

    def completion_time(self) -> float | None:
        """End of the last reading, or None while the trigger has not come."""
        end = self.end_index
        if end is None:
            return None
        return self.t_arm + (end - 1) * self.interval_s + self.aperture_s

    def time_of_reading(self, i: int) -> float:
        """End of the aperture of reading ``i``."""
        return self.t_arm + i * self.interval_s + self.aperture_s


__all__ = ["CaptureGrid"]
