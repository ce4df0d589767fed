"""The catalogue of steps: every test the bench can run, by name — the one list.

``bench run <step>`` (its options from the step's parameter dataclass, its help from the
step's docstring, ``--analyze`` / ``--report`` from its follow-up), the procedures a unit
spec may name (``bench.core.spec``) and the acceptance sequence (``procedures.acceptance``)
are all derived from it.  A new step is its module (a :class:`~bench.core.step.Step`
subclass), one line here, and its tests.

``renamed``: names that changed (old → new), so that a spec or a command line using an old
name is told the new one.  ``startup`` and ``gyro_startup`` were the turn-on tests' names in
unit specs while ``bench run startup`` was Document A's start-up acquisition: ``startup`` is
now the acquisition only (a spec cannot name it: it produces nothing to judge), the turn-on
tests are ``turn_on`` and ``gyro_turn_on``.
"""

from __future__ import annotations

from bench.core.step import Catalogue
from procedures.frf import FrfTest
from procedures.fusion import FusionTest
from procedures.noise import AccelerometerNoise, GyroNoise
from procedures.ratetable import RateTableCalibration
from procedures.startup import StartupAcquisition
from procedures.thermal_ramp import GyroThermalRamp, ThermalRamp
from procedures.thermal_sweep import GyroThermalSweep, ThermalSweep
from procedures.tumble import TumbleCalibration
from procedures.turn_on import GyroTurnOnTest, TurnOnTest
from procedures.turn_on_repeatability import GyroTurnOnRepeatabilityTest, TurnOnRepeatabilityTest
from procedures.vibration import VibrationTest

CATALOGUE = Catalogue.of(
    StartupAcquisition,      # startup: Document A's start-up acquisition
    TurnOnTest,              # turn_on
    GyroTurnOnTest,          # gyro_turn_on
    TumbleCalibration,       # tumble
    RateTableCalibration,    # ratetable
    AccelerometerNoise,      # accelerometer_noise
    GyroNoise,               # gyro_noise
    VibrationTest,           # vibration: Document C's test
    FrfTest,                 # frf: the angular rig (Document B)
    FusionTest,              # fusion: the angular rig (Document B)
    ThermalSweep,            # thermal_sweep: calibration over temperature (chamber)
    GyroThermalSweep,        # gyro_thermal_sweep
    ThermalRamp,             # thermal_ramp: hysteresis and rate sensitivity (chamber)
    GyroThermalRamp,         # gyro_thermal_ramp
    TurnOnRepeatabilityTest,      # turn_on_repeatability: power cycles in the chamber
    GyroTurnOnRepeatabilityTest,  # gyro_turn_on_repeatability
    renamed={"startup": "turn_on", "gyro_startup": "gyro_turn_on"},
)

__all__ = ["CATALOGUE"]
