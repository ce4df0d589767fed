"""The fibre-optic gyro on the simulated station: the drawn unit, its mount, power and line.

Wiring (what a lab would do with cables):

* the FOG is fixed to the turntable platform with its input axis (IA) along platform z;
  its sensor axes (IA, second, third) are the rows of :data:`GYRO_MOUNT`;
* supply channel ``gyro_supply_channel`` (CH1, the E36312A's 6 V / 5 A output) feeds it:
  the station's unit is the 5 V variant of the drawn unit (:data:`FIVE_VOLT_VARIANT`, same
  power as at 12 V), since the presets' 9-36 V range cannot be reached from CH1;
* its RS-422 line is served as a raw byte stream (``socket://``), docs/FOG_SERIAL.md.

Each frame's input is the interval mean of the platform's inertial rate and specific
force (Simpson's rule on the frame edges and midpoints: exact for rates linear or
quadratic in time within a frame, e.g. a constant-acceleration ramp).

With a shaker (``sim.physics.shaker.Shaker``) the gyro sits on its fixture: each frame's
vibration input is the shaker's level along each sensor axis, the rms over the frame
(Simpson on g², exact for the envelope's linear ramps).  The vibration reaches the model
only through its vibration terms; the frame mean of the oscillating acceleration (zero
on average) is not added to the specific force.
"""

from __future__ import annotations

import numpy as np

from sim.devices.fog_serial import FogSerialDevice, GyroInputs
from sim.devices.supply import PowerSupply
from sim.physics.gyro import GRADES, FiberOpticGyro, GyroParams, draw_gyro
from sim.physics.motion import DualAxisTable
from sim.world import World

#: IA, second and third sensor axes as unit vectors in the platform frame (rows)
GYRO_MOUNT = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
#: supply figures of the 5 V variant; the current keeps the drawn unit's power at 12 V
FIVE_VOLT_VARIANT = {"supply_min_v": 4.75, "supply_max_v": 5.25}
_PRESET_SUPPLY_V = 12.0


def station_gyro_params(serial: str, grade: str, overrides: dict) -> GyroParams:
    """The drawn unit as the station has it (5 V variant), then the user's overrides."""
    if grade not in GRADES:
        raise ValueError(f"gyro_grade = {grade!r} not in {'|'.join(sorted(GRADES))}")
    if not isinstance(overrides, dict):
        raise ValueError(f"gyro = {overrides!r} must be a table of GyroParams overrides")
    drawn = draw_gyro(serial, grade)
    variant = dict(FIVE_VOLT_VARIANT,
                   supply_current_a=drawn.supply_current_a * _PRESET_SUPPLY_V / 5.0)
    return drawn.replace(**{**variant, **overrides})


def check_gyro_serial(serial: object) -> None:
    if (not isinstance(serial, str) or not 0 < len(serial) <= 64 or not serial.isascii()
            or not serial.isprintable() or any(c in serial for c in ",$")):
        raise ValueError(f"gyro_serial = {serial!r} must be printable ASCII of 1..64 characters "
                         "without ',' or '$'")


class StationGyro:
    """The gyro model, its serial line device and their wiring to table and supply."""

    def __init__(self, world: World, table: DualAxisTable, supply: PowerSupply, *,
                 serial: str, grade: str, overrides: dict, channel: int,
                 latitude_deg: float, g_mps2: float, shaker=None, ambient=None) -> None:
        check_gyro_serial(serial)
        self.params = station_gyro_params(serial, grade, overrides)
        self.model = FiberOpticGyro(self.params, world.rng(f"gyro:{serial}"), ambient=ambient)
        self.table, self.latitude_deg, self.g_mps2 = table, latitude_deg, g_mps2
        self.shaker = shaker
        self.line = FogSerialDevice(
            world, self.model, self.inputs, serial=serial,
            scale_factor_pulses_per_arcsec=self.params.scale_factor_pulses_per_arcsec,
            full_scale_dps=self.params.full_scale_dps,
            supply_volts=lambda: supply.read(channel).voltage_v)
        self._wire_power(supply, channel)

    def _wire_power(self, supply: PowerSupply, channel: int) -> None:
        last = {"volts": 0.0}

        def on_change(t: float, ch: int, volts: float) -> None:
            if ch == channel and volts != last["volts"]:
                last["volts"] = volts
                self.model.set_supply(t, volts)
                self.line.power_changed(t)

        def load(t: float, volts: float) -> float:
            return self.params.supply_current_a if self.model.supply_in_range(volts) else 0.0

        supply.listeners.append(on_change)
        supply.attach_load(channel, load)

    def inputs(self, t_edges_s: np.ndarray) -> GyroInputs:
        """Interval means of inertial rate (°/s) and specific force (g) in sensor axes."""
        n = t_edges_s.size - 1
        t = np.empty(2 * n + 1)
        t[0::2] = t_edges_s
        t[1::2] = 0.5 * (t_edges_s[:-1] + t_edges_s[1:])
        omega = self.table.angular_rate_platform_dps(t, self.latitude_deg) @ GYRO_MOUNT.T
        force = self.table.specific_force_platform_g(t, self.g_mps2) @ GYRO_MOUNT.T

        def simpson(x: np.ndarray) -> np.ndarray:
            return (x[0:-1:2] + 4.0 * x[1::2] + x[2::2]) / 6.0

        vibration = 0.0
        if self.shaker is not None and not self.shaker.quiet_between(t[0], t[-1]):
            g = self.shaker.envelope_grms(t)
            along = np.abs(GYRO_MOUNT @ self.shaker.axis_platform)  # |cos| to each sensor axis
            vibration = np.sqrt(simpson(g * g))[:, None] * along[None, :]
        return GyroInputs(simpson(omega), simpson(force), vibration)
