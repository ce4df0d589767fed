"""Physics models of the simulated bench world: pure numpy/scipy, no I/O, no clock.

State changes happen at given simulated times; continuous quantities are evaluated,
vectorised, for arrays of times at or after the last change. Every random draw comes
from a ``numpy.random.Generator`` handed in by the caller (the World).
"""

from sim.physics.accelerometer import AccelerometerParams, QuartzAccelerometer, indicated_acceleration_g
from sim.physics.gravity import STANDARD_GRAVITY_MPS2, earth_rate_enu_rps, local_gravity_mps2
from sim.physics.motion import Axis, DualAxisTable, move_phases, trapezoid_time_s, wrap_deg
from sim.physics.noise import GaussMarkov, RandomWalk, WhiteNoise
from sim.physics.thermal_unit import TwoNodeBody, TwoNodeParams

__all__ = [
    "STANDARD_GRAVITY_MPS2", "AccelerometerParams", "Axis", "DualAxisTable", "GaussMarkov",
    "QuartzAccelerometer", "RandomWalk", "TwoNodeBody", "TwoNodeParams", "WhiteNoise", "earth_rate_enu_rps",
    "indicated_acceleration_g", "local_gravity_mps2", "move_phases", "trapezoid_time_s", "wrap_deg",
]
