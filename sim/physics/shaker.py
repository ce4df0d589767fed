"""Linear electrodynamic shaker as the unit on its fixture sees it.

The shaker moves the fixture along one axis (``axis_platform``, a unit vector in the
platform frame; the station has one fixture position, the turntable platform's).  What
the gyro model needs is the vibration level along each of its sensor axes at any time,
g rms (``grms_sensor``); a control accelerometer readback needs the instantaneous
acceleration (``acceleration_g``).

Level over time (the *envelope*, g rms along the axis): piecewise linear between knots.
``start`` ramps linearly from the present level to the profile's level (× 10^(dB/20))
over ``ramp_s``; ``set_level`` while running ramps to the new level over ``ramp_s``;
``stop`` ramps down to zero over ``ramp_s``; ``abort`` cuts the drive (to zero in
:data:`ABORT_DECAY_S`).  Commands apply at their time and never change the past, so the
gyro's frames, computed up to the command's time, stay consistent with the envelope.

Acceleration time series: the profile's shape at 0 dB from
:class:`sim.physics.shaker_signal.ShapedNoise` (random) or a sine of random phase, times
envelope / profile g rms.  The profile can only change while the shaker is idle (level
zero), so a series is consistent within each run.
"""

from __future__ import annotations

import math

import numpy as np

from sim.physics.shaker_profile import Profile, RandomProfile, ShakerLimits, SineProfile
from sim.physics.shaker_signal import CONTROL_RATE_HZ, ShapedNoise

#: time for the drive to die away after an abort (s)
ABORT_DECAY_S = 0.01
DEFAULT_RAMP_S = 2.0
RAMP_RANGE_S = (0.01, 60.0)
LEVEL_RANGE_DB = (-30.0, 6.0)

IDLE, RAMP, RUN, ABORT = "IDLE", "RAMP", "RUN", "ABORT"


class Shaker:
    """Profile, level, ramps and state of one shaker; envelope and signals over time.

    ``rng`` seeds the control signal (one draw at construction, plus a phase per sine
    profile), so the same world seed gives the same acceleration samples.  Commands come
    at non-decreasing times (the World's ``now``).
    """

    def __init__(self, rng: np.random.Generator, axis_platform=(0.0, 0.0, 1.0),
                 limits: ShakerLimits | None = None) -> None:
        axis = np.asarray(axis_platform, dtype=float)
        if axis.shape != (3,) or not np.all(np.isfinite(axis)) or abs(np.linalg.norm(axis) - 1) > 1e-6:
            raise ValueError(f"axis_platform = {axis_platform!r} must be a unit 3-vector")
        self.axis_platform = axis / np.linalg.norm(axis)
        self.limits = limits or ShakerLimits()
        self._rng = rng
        self._noise_seed = int(rng.integers(0, 2**63))
        self.profile: Profile | None = None
        self.level_db = 0.0
        self.ramp_s = DEFAULT_RAMP_S
        self._signal: ShapedNoise | None = None
        self._sine_phase = 0.0
        self._knot_t = np.array([0.0])
        self._knot_g = np.array([0.0])  # envelope knots (g rms along the axis)
        self._aborted = False
        self._t_last = 0.0

    # ---- commands ---------------------------------------------------------------------
    def _at(self, t_s: float) -> float:
        t = float(t_s)
        if not (math.isfinite(t) and t >= self._t_last):
            raise ValueError(f"t_s = {t_s!r} must be finite and ≥ the last command's time {self._t_last!r} s")
        self._t_last = t
        return t

    def _ramp_to(self, t: float, target_grms: float, duration_s: float) -> None:
        """From the level at ``t``, linearly to ``target_grms`` over ``duration_s``."""
        now = float(self.envelope_grms(t))
        keep = self._knot_t < t
        # already there: hold (no ramp of zero height, which would read RAMP for a while)
        times, levels = ([t], [now]) if now == target_grms else ([t, t + duration_s], [now, target_grms])
        self._knot_t = np.concatenate([self._knot_t[keep], times])
        self._knot_g = np.concatenate([self._knot_g[keep], levels])

    def set_profile(self, t_s: float, profile: Profile) -> None:
        """A new profile (idle only); ValueError naming a limit the profile × level exceeds."""
        t = self._at(t_s)
        if self.state(t) != IDLE:
            raise RuntimeError(f"profile change refused while {self.state(t)}; stop first")
        problem = self.limits.violation(profile, self.level_db)
        if problem:
            raise ValueError(problem)
        self.profile = profile
        if isinstance(profile, RandomProfile):
            self._signal = ShapedNoise(profile, self._noise_seed)
        else:
            self._signal = None
            self._sine_phase = float(self._rng.uniform(0.0, 2 * math.pi))

    def target_grms(self, level_db: float | None = None) -> float:
        """g rms the profile gives at ``level_db`` (default: the set level); 0 without one."""
        if self.profile is None:
            return 0.0
        return self.profile.grms * 10.0 ** ((self.level_db if level_db is None else level_db) / 20.0)

    def set_level(self, t_s: float, level_db: float) -> None:
        """Level in dB re the profile; while running the level ramps to it over ``ramp_s``."""
        lo, hi = LEVEL_RANGE_DB
        if not (isinstance(level_db, (int, float)) and lo <= level_db <= hi):
            raise ValueError(f"level {level_db!r} dB not in {lo:g}..{hi:g} dB")
        t = self._at(t_s)
        if self.profile is not None:
            problem = self.limits.violation(self.profile, level_db)
            if problem:
                raise ValueError(problem)
        self.level_db = float(level_db)
        if self.driving:
            self._ramp_to(t, self.target_grms(), self.ramp_s)

    def set_ramp(self, ramp_s: float) -> None:
        lo, hi = RAMP_RANGE_S
        if not (isinstance(ramp_s, (int, float)) and lo <= ramp_s <= hi):
            raise ValueError(f"ramp {ramp_s!r} s not in {lo:g}..{hi:g} s")
        self.ramp_s = float(ramp_s)

    def start(self, t_s: float) -> None:
        t = self._at(t_s)
        if self.profile is None:
            raise RuntimeError("no profile: set a random or sine profile first")
        if self._aborted:
            raise RuntimeError("aborted: reset the interlock first")
        if self.driving:
            return  # already going up or running: nothing to do
        self._ramp_to(t, self.target_grms(), self.ramp_s)

    def stop(self, t_s: float) -> None:
        """Ramp down to rest over ``ramp_s`` (nothing to do when idle or aborted)."""
        t = self._at(t_s)
        if self.driving:
            self._ramp_to(t, 0.0, self.ramp_s)

    def abort(self, t_s: float) -> None:
        """Cut the drive now; the state stays ABORT until :meth:`reset_abort`."""
        t = self._at(t_s)
        self._ramp_to(t, 0.0, ABORT_DECAY_S)
        self._aborted = True

    def reset_abort(self, t_s: float) -> None:
        t = self._at(t_s)
        if self.envelope_grms(t) > 0.0:  # still decaying: let it reach rest first
            raise RuntimeError("drive still decaying; reset after it reached rest")
        self._aborted = False

    # ---- state ------------------------------------------------------------------------
    @property
    def driving(self) -> bool:
        """The envelope heads for (or holds) a level above zero: started and not stopped."""
        return bool(self._knot_g[-1] > 0.0)

    def state(self, t_s: float) -> str:
        """IDLE (at rest), RAMP (level changing), RUN (at the goal level) or ABORT."""
        if self._aborted:
            return ABORT
        t = float(t_s)
        if t < self._knot_t[-1]:
            return RAMP
        return RUN if self._knot_g[-1] > 0.0 else IDLE

    @property
    def aborted(self) -> bool:
        return self._aborted

    # ---- what the unit sees -----------------------------------------------------------
    def envelope_grms(self, t_s):
        """Vibration level along the shaker axis at ``t_s``, g rms (scalar or array)."""
        t = np.asarray(t_s, dtype=float)
        out = np.interp(t, self._knot_t, self._knot_g, left=0.0)
        return float(out) if out.ndim == 0 else out

    def quiet_between(self, t0_s: float, t1_s: float) -> bool:
        """True when the level is zero over all of [t0, t1] (the envelope is piecewise linear)."""
        inside = (self._knot_t > t0_s) & (self._knot_t < t1_s)
        ends = self.envelope_grms(np.array([t0_s, t1_s]))
        return not (np.any(ends > 0) or np.any(self._knot_g[inside] > 0))

    def grms_sensor(self, t_s, mount: np.ndarray) -> np.ndarray:
        """g rms along each sensor axis (rows of ``mount`` in the platform frame), (n, 3):
        a one-axis motion projects with |cos| of the angle to each axis."""
        g = np.atleast_1d(np.asarray(self.envelope_grms(t_s), dtype=float))
        return g[:, None] * np.abs(np.asarray(mount, float) @ self.axis_platform)[None, :]

    def acceleration_g(self, t0_s: float, t1_s: float,
                       rate_hz: float = CONTROL_RATE_HZ) -> tuple[np.ndarray, np.ndarray]:
        """Control-accelerometer samples on the grid k/rate_hz in [t0, t1): (times s, g).

        Random profiles are sampled at :data:`CONTROL_RATE_HZ` only (the kernel's rate).
        """
        if not (0.0 <= t0_s <= t1_s and math.isfinite(t1_s)):
            raise ValueError(f"window [{t0_s!r}, {t1_s!r}) s must satisfy 0 ≤ t0 ≤ t1 < inf")
        if self._signal is not None and rate_hz != CONTROL_RATE_HZ:
            raise ValueError(f"rate_hz = {rate_hz!r}: random signals are sampled at {CONTROL_RATE_HZ} Hz")
        k0, k1 = math.ceil(t0_s * rate_hz), math.ceil(t1_s * rate_hz)
        t = np.arange(k0, k1) / rate_hz
        if self.profile is None or t.size == 0:
            return t, np.zeros(t.size)
        scale = self.envelope_grms(t) / self.profile.grms
        p = self.profile
        if isinstance(p, SineProfile):
            return t, scale * p.peak_g * np.sin(2 * math.pi * p.freq_hz * t + self._sine_phase)
        if self._signal is None:  # set_profile builds the shaped noise with every random profile
            raise RuntimeError(f"random profile {p!r} has no shaped-noise signal")
        return t, scale * self._signal.samples(k0, k1 - k0)

    def measured_grms(self, t_s: float, window_s: float = 1.0) -> float:
        """What the controller reads back: rms of the control signal over the last
        ``window_s`` before ``t_s`` (estimation noise of a finite average included)."""
        t0 = max(0.0, t_s - window_s)
        _, a = self.acceleration_g(t0, t_s)
        return float(np.sqrt(np.mean(a * a))) if a.size else 0.0


__all__ = ["ABORT", "ABORT_DECAY_S", "IDLE", "LEVEL_RANGE_DB", "RAMP", "RAMP_RANGE_S", "RUN",
           "RandomProfile", "Shaker", "ShakerLimits", "SineProfile"]
