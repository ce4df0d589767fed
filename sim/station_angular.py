"""The angular vibration rig on the simulated station (Document B): the table, the MHD and
low-frequency rate sensors on it, and the instruments reading them.

Wiring (what a lab would do with cables):

* the angular vibration table (``angular_table``, its own controller on its own port)
  carries both sensors coaxially on its rotor: they see the same angular rate;
* MHD sensor output → ``dmm_mhd`` input: a 34465A with the DIG option (digitizing);
* low-frequency sensor → its serial line (``lf_gyro``, ``socket://``), the frame format
  of docs/FOG_SERIAL.md;
* both sensors are powered by the rig (not the station's E36312A): the LF unit is on from
  the start, the MHD sensor is passive.

Each unit is drawn from a manufacturing spread seeded by ``mhd_serial`` (:func:`draw_rig`):
the MHD corner and sensitivity, the LF corner, damping, latency and frame-clock error
differ from unit to unit, as they do on a real shelf; ``mhd`` / ``lf_sensor`` overrides
replace any drawn figure.

Clocks: the table's reference capture runs on the world clock (the reference); the LF
frames on the unit's clock, ``frame_clock_error_ppm`` fast; the DMM's sample timer on its
timebase, ``dmm_timebase_ppm`` slow (default 0).  The procedures measure both rate errors
against the reference and remove them.  The LF
unit reports the motion ``latency_s`` late.
"""

from __future__ import annotations

import math
import zlib

import numpy as np

from sim.devices.angular_table import AngularTableController
from sim.devices.dmm import Multimeter
from sim.devices.dmm_model import LinePickup
from sim.devices.fog_serial import FogSerialDevice, GyroInputs
from sim.physics.angular_table import AngularMotion
from sim.physics.rate_sensors import LF_PRESET, MHD_PRESET, LfGyroUnit, LfRateParams, MhdParams, mhd_sensor
from sim.world import World

#: relative (or absolute, where marked) 1σ spread of the drawn figures
SPREAD = {"mhd.highpass_corner_hz": 0.08, "mhd.sensitivity_v_per_rad_s": 0.02,
          "lf.corner_hz": 0.05, "lf.zeta": 0.05, "lf.latency_s": 0.15,
          "lf.frame_clock_error_ppm": 15.0}  # ppm absolute
LF_SUPPLY_V = 24.0


def _check_serial(serial: object) -> None:
    if (not isinstance(serial, str) or not 0 < len(serial) <= 64 or not serial.isascii()
            or not serial.isprintable() or any(c in serial for c in ",$")):
        raise ValueError(f"mhd_serial = {serial!r} must be printable ASCII of 1..64 characters without ',' or '$'")


def draw_rig(serial: str, mhd: dict | None = None, lf: dict | None = None) -> tuple[MhdParams, LfRateParams]:
    """The rig's sensor pair as drawn for ``serial`` (same serial → same units), then overrides."""
    _check_serial(serial)
    for name, value in (("mhd", mhd), ("lf_sensor", lf)):
        if value is not None and not isinstance(value, dict):
            raise ValueError(f"{name} = {value!r} must be a table of parameter overrides")
    rng = np.random.default_rng([zlib.crc32(serial.encode()), 0xA1])
    z = rng.standard_normal(6)
    drawn_mhd = {"highpass_corner_hz": MHD_PRESET.highpass_corner_hz * (1 + SPREAD["mhd.highpass_corner_hz"] * z[0]),
                 "sensitivity_v_per_rad_s": MHD_PRESET.sensitivity_v_per_rad_s
                 * (1 + SPREAD["mhd.sensitivity_v_per_rad_s"] * z[1])}
    drawn_lf = {"corner_hz": LF_PRESET.corner_hz * (1 + SPREAD["lf.corner_hz"] * z[2]),
                "zeta": LF_PRESET.zeta * (1 + SPREAD["lf.zeta"] * z[3]),
                "latency_s": LF_PRESET.latency_s * (1 + SPREAD["lf.latency_s"] * z[4]),
                "frame_clock_error_ppm": LF_PRESET.frame_clock_error_ppm + SPREAD["lf.frame_clock_error_ppm"] * z[5]}
    drawn_mhd = {k: float(v) for k, v in drawn_mhd.items()}
    drawn_lf = {k: float(v) for k, v in drawn_lf.items()}
    try:
        return (MHD_PRESET.replace(**{**drawn_mhd, **(mhd or {})}),
                LF_PRESET.replace(**{**drawn_lf, **(lf or {})}))
    except TypeError as exc:  # an unknown override key
        raise ValueError(f"angular rig overrides: {exc}") from None


class AngularRig:
    """The table, both sensors and their instruments, as views of one world."""

    def __init__(self, world: World, *, serial: str, mhd: dict, lf: dict, line_pickup_v: float,
                 line_hz: float, ideal_meters: bool, dmm_timebase_ppm: float) -> None:
        if not (isinstance(dmm_timebase_ppm, (int, float)) and math.isfinite(dmm_timebase_ppm)
                and abs(dmm_timebase_ppm) <= 1000):
            raise ValueError(f"dmm_timebase_ppm = {dmm_timebase_ppm!r} not in -1000..1000 ppm")
        self.mhd_params, self.lf_params = draw_rig(serial, mhd, lf)
        self.serial = serial
        self.motion = AngularMotion(rng=world.rng("angular_table"))
        self.controller = AngularTableController(world, self.motion, serial="AVT-0001")
        self.mhd = mhd_sensor(self.motion.pieces, world.rng(f"mhd:{serial}"), self.mhd_params,
                              t_origin_s=world.now)
        self.dmm = Multimeter(world, "dmm_mhd", self.mhd_volts, serial="MY59001236",
                              line_pickup=LinePickup(amplitude_v=line_pickup_v, nominal_hz=line_hz, phase_rad=2.3),
                              ideal=ideal_meters, timebase_ppm=dmm_timebase_ppm)
        self.lf_unit = LfGyroUnit(self.motion.pieces, world.rng(f"lf:{serial}"), self.lf_params,
                                  t_origin_s=world.now)
        self.lf_unit.set_supply(world.now, LF_SUPPLY_V)
        self.lf_line = FogSerialDevice(
            world, self.lf_unit, self._no_table_inputs, serial=f"{serial}-LF", model="LFRS-1",
            scale_factor_pulses_per_arcsec=self.lf_params.scale_factor_pulses_per_arcsec,
            full_scale_dps=self.lf_params.full_scale_dps, clock_ppm=self.lf_params.frame_clock_error_ppm,
            supply_volts=self.supply_volts)

    def mhd_volts(self, t_start: np.ndarray, aperture_s: float) -> np.ndarray:
        return self.mhd.mean_output(t_start, aperture_s)

    @staticmethod
    def _no_table_inputs(t_edges_s: np.ndarray) -> GyroInputs:
        # the LF unit reads the angular table's motion itself (LfGyroUnit); the turntable's
        # rate and specific force do not reach it
        n = t_edges_s.size - 1
        return GyroInputs(np.zeros((n, 3)), np.zeros((n, 3)), 0.0)

    def supply_volts(self) -> float:
        return LF_SUPPLY_V

    def truth(self) -> dict:
        """The drawn units (for recovery tests, never for procedures)."""
        m, lf = self.mhd_params, self.lf_params
        return {"serial": self.serial,
                "mhd": {k: getattr(m, k) for k in m.__dataclass_fields__},
                "lf": {k: getattr(lf, k) for k in lf.__dataclass_fields__}}
