"""The simulated start-up station: one World, its models, and the instruments that view it.

Wiring (what a lab would do with cables):

* supply CH2 → accelerometer +15 V rail, supply CH3 → −15 V rail (inverted at the fixture);
  the unit is powered while both rails sit inside its supply range;
* accelerometer output current → sampling resistor → ``dmm`` input;
* the internal AD590-type temperature sensor (1 µA/K) → ``temp_resistor`` → ``dmm_temp``;
* the accelerometer is fixed to the turntable platform with its input axis along platform z;
* the fibre-optic gyro sits on the platform too (IA along z), powered from
  ``gyro_supply_channel``, its frames on a serial line (``sim/station_gyro.py``);
* the turntable with both units stands inside a temperature chamber (``chamber``, a Watlow
  F4T over Modbus TCP, ``sim/devices/chamber.py``): the chamber air is the units' ambient
  (``sim/physics/thermal_chamber.py``); stopped, it rests at the lab's ambient.  The angular
  rig stands outside it;
* the shaker (``shaker``, a random-vibration controller) moves the same fixture along
  ``shaker_axis`` (platform frame; default z, the gyro's input axis).  The station has one
  fixture position: the platform is the shaker's fixture, so the controller refuses
  ``:STARt`` while the turntable moves (the table does not check back: a procedure keeps
  it still while shaking).  The vibration drives the gyro's vibration terms; the
  accelerometer does not see it.

The instruments are listed once, in :data:`INSTRUMENTS` (the station table): name, kind,
the wire it is served over, the bench driver that speaks to it (a key of
``instruments.registry``, as text: ``sim`` imports nothing of the bench) and where its device
is on the station.  The server, sim-control's ``SIM:INST:LIST?``, the fault targets, ``bench
sim serve``, ``bench doctor`` and the bench's embedded station are all derived from it.

Only this module (and ``bench.app.station`` which starts it) knows both the physics and the
instruments; procedures see TCP addresses.
"""

from __future__ import annotations

from collections.abc import Callable, Collection
from dataclasses import dataclass, field

import numpy as np

from sim.devices.chamber import WatlowF4T
from sim.devices.dmm import Multimeter
from sim.devices.dmm_model import LinePickup
from sim.devices.lifecycle import SimDevice
from sim.devices.shaker import ShakerController
from sim.devices.sim_control import SimControl
from sim.devices.supply import PowerSupply
from sim.devices.turntable import TurntableController
from sim.faults import FaultInjector
from sim.hislip import HISLIP
from sim.physics.accelerometer import QuartzAccelerometer, draw_accelerometer
from sim.physics.gravity import STANDARD_GRAVITY_MPS2, local_gravity_mps2
from sim.physics.motion import DualAxisTable
from sim.physics.shaker import Shaker
from sim.physics.thermal_chamber import ChamberAir, ChamberParams
from sim.server import MODBUS, SCPI, SERIAL, Endpoint, InstrumentServer, Transport
from sim.station_angular import AngularRig, draw_rig
from sim.station_fixture import Fixture, check_fixture
from sim.station_gyro import StationGyro, check_gyro_serial, station_gyro_params
from sim.world import World, check_pace


@dataclass
class SimStationConfig:
    """Everything the simulated station needs; all fields have lab-realistic defaults."""

    seed: int = 0
    unit_serial: str = "QA-SIM-0001"
    latitude_deg: float = 32.06      # Nanjing, where Document A's lab is
    height_m: float = 10.0
    g_mps2: float | None = None      # override local gravity
    sampling_resistor_ohm: float = 5000.0
    temp_resistor_ohm: float = 10000.0
    positive_rail_channel: int = 2
    negative_rail_channel: int = 3
    line_hz: float = 50.0
    line_pickup_v: float = 3e-6
    #: meters without reading noise or zero offset (set line_pickup_v = 0 too): a station on
    #: which a noiseless unit's calibration must come out exact — a check of the arithmetic
    ideal_meters: bool = False
    #: accelerometer IA, PA, OA as unit vectors in the platform frame (rows)
    mount: tuple[tuple[float, float, float], ...] = ((0, 0, 1), (1, 0, 0), (0, 1, 0))
    accelerometer: dict = field(default_factory=dict)  # overrides of the unit drawn by serial
    gyro_serial: str = "FOG-SIM-0001"
    gyro_grade: str = "tactical"     # tactical | navigation
    gyro: dict = field(default_factory=dict)  # GyroParams overrides of the drawn unit
    gyro_supply_channel: int = 1
    #: shaker motion axis as a unit vector in the platform frame
    shaker_axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    #: the angular rig's sensor pair (``sim.station_angular``): serial, overrides of the drawn units
    mhd_serial: str = "MHD-SIM-0001"
    mhd: dict = field(default_factory=dict)        # MhdParams overrides
    lf_sensor: dict = field(default_factory=dict)  # LfRateParams overrides
    dmm_timebase_ppm: float = 0.0                  # the MHD DMM's sample timer, slow by this much
    #: the temperature chamber's figures (``ChamberParams`` overrides: lab_ambient_c, rates, loop)
    chamber: dict = field(default_factory=dict)
    #: the batch fixture (``sim.station_fixture``): socket (1..8) → unit serial, read by ``daq``
    fixture: dict = field(default_factory=dict)
    fixture_units: dict = field(default_factory=dict)   # socket → overrides of its drawn unit
    fixture_open: list = field(default_factory=list)    # sockets whose output lead is open
    fixture_settling_tau_s: float = 1e-4                # the fixture's input filter, s
    fixture_first_channel: int = 101                    # socket n on DAQ channel first + n − 1
    host: str = "127.0.0.1"
    #: simulated time: None = event-driven (moves only when a client waits; same seed, same
    #: bytes); a number = it also follows the wall clock at that many simulated seconds per
    #: wall second (``sim.world.MIN_PACE..MAX_PACE``; 1 = realtime)
    pace: float | None = None

    def validate(self) -> None:
        for name in ("latitude_deg", "height_m", "sampling_resistor_ohm", "temp_resistor_ohm",
                     "line_hz", "line_pickup_v"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ValueError(f"{name} = {value!r} must be a number")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or not 0 <= self.seed < 2**63:
            raise ValueError(f"seed = {self.seed!r} not in 0..2**63-1")
        if not isinstance(self.unit_serial, str) or not 0 < len(self.unit_serial) <= 64:
            raise ValueError(f"unit_serial = {self.unit_serial!r} must be text of 1..64 characters")
        if not isinstance(self.ideal_meters, bool):
            raise ValueError(f"ideal_meters = {self.ideal_meters!r} must be true or false")
        if not isinstance(self.accelerometer, dict):
            raise ValueError(f"accelerometer = {self.accelerometer!r} must be a table of parameters")
        if not -90 <= self.latitude_deg <= 90:
            raise ValueError(f"latitude_deg {self.latitude_deg} not in -90..90")
        if not 10 <= self.sampling_resistor_ohm <= 1e6:
            raise ValueError(f"sampling_resistor_ohm {self.sampling_resistor_ohm} not in 10..1e6")
        if self.line_hz not in (50.0, 60.0):
            raise ValueError(f"line_hz {self.line_hz} not in 50|60")
        m = np.asarray(self.mount, float)
        if m.shape != (3, 3) or not np.allclose(m @ m.T, np.eye(3), atol=1e-6):
            raise ValueError("mount must be three orthonormal rows (IA, PA, OA)")
        ch = self.gyro_supply_channel
        if isinstance(ch, bool) or ch not in (1, 2, 3):
            raise ValueError(f"gyro_supply_channel = {ch!r} not in 1..3")
        if ch in (self.positive_rail_channel, self.negative_rail_channel):
            raise ValueError(f"gyro_supply_channel = {ch} is an accelerometer rail")
        axis = np.asarray(self.shaker_axis, float) if isinstance(self.shaker_axis, (list, tuple)) else None
        if axis is None or axis.shape != (3,) or not np.all(np.isfinite(axis)) \
                or abs(float(np.linalg.norm(axis)) - 1.0) > 1e-6:
            raise ValueError(f"shaker_axis = {self.shaker_axis!r} must be a unit vector [x, y, z] "
                             "in the platform frame")
        check_gyro_serial(self.gyro_serial)
        station_gyro_params(self.gyro_serial, self.gyro_grade, self.gyro)
        draw_rig(self.mhd_serial, self.mhd, self.lf_sensor)
        check_fixture(self.fixture, self.fixture_units, self.fixture_open, self.fixture_settling_tau_s)
        ppm = self.dmm_timebase_ppm
        if isinstance(ppm, bool) or not isinstance(ppm, (int, float)) or not abs(ppm) <= 1000:
            raise ValueError(f"dmm_timebase_ppm = {ppm!r} not in -1000..1000 ppm")
        check_pace(self.pace)
        self.chamber_params()

    def chamber_params(self) -> ChamberParams:
        if not isinstance(self.chamber, dict):
            raise ValueError(f"chamber = {self.chamber!r} must be a table of chamber figures")
        known = set(ChamberParams.__dataclass_fields__)
        unknown = sorted(set(self.chamber) - known)
        if unknown:
            raise ValueError(f"chamber parameter(s) {unknown} unknown; allowed: {sorted(known)}")
        return ChamberParams(**self.chamber)


class SimulatedStation:
    """Builds the world and serves its instruments on loopback TCP ports."""

    def __init__(self, config: SimStationConfig | None = None,
                 only: Collection[str] | None = None) -> None:
        """``only``: serve just these instruments (and the sim-control endpoint); the world
        and every model are built all the same, so a seed gives the same bytes either way."""
        cfg = config or SimStationConfig()
        cfg.validate()
        self.config = cfg
        self.world = World(cfg.seed, pace=cfg.pace)
        self.g_mps2 = cfg.g_mps2 or local_gravity_mps2(cfg.latitude_deg, cfg.height_m)
        self.table = DualAxisTable()
        #: the chamber air around the table and both units (at the lab's ambient while stopped)
        self.chamber_air = ChamberAir(self.world, cfg.chamber_params())
        self.chamber = WatlowF4T(self.world, self.chamber_air)
        self.accel = QuartzAccelerometer(draw_accelerometer(cfg.unit_serial, cfg.accelerometer),
                                         self.world.rng(f"accelerometer:{cfg.unit_serial}"),
                                         ambient=self.chamber_air,
                                         turn_on_rng=self.world.rng(f"accelerometer-turn-on:{cfg.unit_serial}"))
        self._mount = np.asarray(cfg.mount, float)
        pickup = LinePickup(amplitude_v=cfg.line_pickup_v, nominal_hz=cfg.line_hz)
        self.supply = PowerSupply(self.world)
        self.dmm = Multimeter(self.world, "dmm", self._accel_volts, serial="MY59001234",
                              line_pickup=pickup, ideal=cfg.ideal_meters)
        self.dmm_temp = Multimeter(self.world, "dmm_temp", self._temp_volts, serial="MY59001235",
                                   line_pickup=LinePickup(amplitude_v=cfg.line_pickup_v,
                                                          nominal_hz=cfg.line_hz, phase_rad=1.1),
                                   ideal=cfg.ideal_meters)
        self.turntable = TurntableController(self.world, self.table)
        self.shaker = Shaker(self.world.rng("shaker"), cfg.shaker_axis)
        self.shaker_controller = ShakerController(self.world, self.shaker,
                                                  table_at_rest=self._table_at_rest)
        self._gyro = StationGyro(self.world, self.table, self.supply, serial=cfg.gyro_serial,
                                 grade=cfg.gyro_grade, overrides=cfg.gyro,
                                 channel=cfg.gyro_supply_channel,
                                 latitude_deg=cfg.latitude_deg, g_mps2=self.g_mps2,
                                 shaker=self.shaker, ambient=self.chamber_air)
        self.gyro, self.gyro_line = self._gyro.model, self._gyro.line
        self.angular = AngularRig(self.world, serial=cfg.mhd_serial, mhd=cfg.mhd, lf=cfg.lf_sensor,
                                  line_pickup_v=cfg.line_pickup_v, line_hz=cfg.line_hz,
                                  ideal_meters=cfg.ideal_meters, dmm_timebase_ppm=cfg.dmm_timebase_ppm)
        self.fixture = Fixture(
            self.world, check_fixture(cfg.fixture, cfg.fixture_units, cfg.fixture_open,
                                      cfg.fixture_settling_tau_s),
            overrides=cfg.fixture_units, open_sockets=cfg.fixture_open,
            specific_force=self.specific_force_iapo_g,
            sampling_resistor_ohm=cfg.sampling_resistor_ohm,
            line_pickup=LinePickup(amplitude_v=cfg.line_pickup_v, nominal_hz=cfg.line_hz, phase_rad=0.7),
            settling_tau_s=cfg.fixture_settling_tau_s, ideal_meters=cfg.ideal_meters,
            ambient=self.chamber_air, first_channel=cfg.fixture_first_channel)
        #: every instrument's device, by name, in table order (``INSTRUMENTS``)
        self.devices: dict[str, SimDevice] = {row.name: row.device(self) for row in INSTRUMENTS}
        self.server = InstrumentServer(cfg.host, world=self.world)
        #: fault injection (``sim.faults``): ``station.faults.inject("stall", "dmm", at_s=...)``
        self.faults = FaultInjector(
            self.world, {row.name: (self.devices[row.name], row.transport) for row in INSTRUMENTS},
            call=self.server.call)
        self.server.faults = self.faults
        self.sim_control = SimControl(self.world, list(self.devices), self.faults)
        self._wire_power()
        unknown = sorted(set(only or ()) - set(self.devices))
        if unknown:
            raise ValueError(f"instrument {', '.join(unknown)} not on the simulated station; "
                             f"allowed: {', '.join(self.devices)}")
        for row in INSTRUMENTS:
            if only is None or row.name in only:
                self.server.add(row.name, row.kind, self.devices[row.name], row.transport,
                                also=ALSO_SERVED.get(row.transport, ()))
        self.server.add("sim", "sim_control", self.sim_control, SCPI, also=ALSO_SERVED[SCPI])
        self.endpoints: list[Endpoint] = []

    # -- wiring ----------------------------------------------------------------------------
    def _wire_power(self) -> None:
        pos, neg = self.config.positive_rail_channel, self.config.negative_rail_channel
        rails = {pos: 0.0, neg: 0.0}

        def on_change(t: float, channel: int, volts: float) -> None:
            if channel in rails and rails[channel] != volts:
                rails[channel] = volts
                # CH3 is wired inverted at the fixture: it feeds the unit's negative rail.
                self.accel.set_supply(t, rails[pos], -rails[neg])
                self.fixture.set_rails(t, rails[pos], -rails[neg])

        def load(t: float, volts: float) -> float:
            # Quiescent draw of the unit's servo electronics while a rail is within its range.
            p = self.accel.params
            in_range = p.supply_min_v <= volts <= p.supply_max_v
            return (p.quiescent_current_a if in_range else 0.0) + self.fixture.quiescent_current_a(volts)

        self.supply.listeners.append(on_change)
        self.supply.attach_load(pos, load)
        self.supply.attach_load(neg, load)

    def _table_at_rest(self, t: float) -> bool:
        return not any(bool(axis.moving(t)) for axis in self.table.axes)

    def specific_force_iapo_g(self, t: np.ndarray) -> np.ndarray:
        f_platform = self.table.specific_force_platform_g(t, self.g_mps2)
        if f_platform.shape[0] > 1 and f_platform.strides[0] == 0:  # table at rest
            return np.broadcast_to(f_platform[0] @ self._mount.T, f_platform.shape)
        return f_platform @ self._mount.T

    def _eval_times(self, t_start: np.ndarray, aperture_s: float) -> np.ndarray:
        # A reading is evaluated at mid-aperture; one whose aperture straddles a power
        # change is evaluated just after the change (the unit's state is piecewise).
        return np.maximum(t_start + aperture_s / 2, self.accel.last_supply_change_s)

    def _accel_volts(self, t_start: np.ndarray, aperture_s: float) -> np.ndarray:
        t_mid = self._eval_times(t_start, aperture_s)
        current = self.accel.output_current_a(t_mid, self.specific_force_iapo_g(t_mid), aperture_s)
        return current * self.config.sampling_resistor_ohm

    def _temp_volts(self, t_start: np.ndarray, aperture_s: float) -> np.ndarray:
        t_mid = self._eval_times(t_start, aperture_s)
        return self.accel.temp_sensor_current_a(t_mid) * self.config.temp_resistor_ohm

    # -- lifecycle ---------------------------------------------------------------------------
    def start(self) -> list[Endpoint]:
        self.endpoints = self.server.start()
        return self.endpoints

    def stop(self) -> None:
        self.server.stop()

    def __enter__(self) -> SimulatedStation:
        self.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

    def resources(self, transport: str | None = None) -> dict[str, str]:
        """Each served instrument's address by name: the one of its table wire (raw socket,
        ``socket://``, ``modbus://``), or with ``transport`` (``"hislip"``, ``"scpi"``, ...)
        its address on that wire, for the instruments that have one."""
        if transport is None:
            return {e.name: e.resource for e in self.endpoints}
        on = ({e.name: e for e in self.endpoints if e.transport.name == transport}
              | {e.name: e.also[transport] for e in self.endpoints if transport in e.also})
        return {name: e.resource for name, e in on.items()}

    def truth(self) -> dict:
        """The simulated unit's true parameters (for recovery tests, never for procedures)."""
        return {"g_mps2": self.g_mps2, "g_local_over_g0": self.g_mps2 / STANDARD_GRAVITY_MPS2,
                "sampling_resistor_ohm": self.config.sampling_resistor_ohm,
                **self.accel.truth()}

    def angular_truth(self) -> dict:
        """The angular rig's drawn sensors (for recovery tests, never for procedures)."""
        return self.angular.truth()

    def thermal_truth(self, t_s) -> dict:
        """Air, case and element temperatures (°C) at past times ``t_s`` (for tests, never for
        procedures): the chamber air and each unit's nodes, and the hysteresis memories."""
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        acc, fog = self.accel.body, self.gyro.body
        return {"air_c": self.chamber_air.air_c(t),
                "accelerometer_case_c": acc.case_c(t), "accelerometer_element_c": acc.element_c(t),
                "accelerometer_memory_c": acc.hysteresis_memory_c(t),
                "gyro_case_c": fog.case_c(t), "gyro_coil_c": fog.element_c(t),
                "gyro_memory_c": fog.hysteresis_memory_c(t)}
    def fixture_truth(self) -> dict[int, dict]:
        """Each fixture socket's true unit (for recovery tests, never for procedures)."""
        return self.fixture.truth()

    def gyro_truth(self) -> dict:
        """The simulated gyro's true parameters (for recovery tests, never for procedures)."""
        return {"latitude_deg": self.config.latitude_deg, **self.gyro.truth()}


@dataclass(frozen=True)
class StationInstrument:
    """One row of the station table: an instrument of the simulated station."""

    name: str                   # as procedures, station files and sim-control name it
    kind: str                   # what it is (multimeter, power_supply, ...), as ``bench sim serve`` lists it
    transport: Transport        # the wire it is served over (``sim.server``: SCPI, SERIAL)
    driver: str                 # the bench driver that speaks to it: a key of ``instruments.registry``
    #: its device on the built station (a ``sim.devices.lifecycle.SimDevice``): called once, in
    #: table order, after the world and its models are wired; may build the device or find it
    device: Callable[[SimulatedStation], SimDevice]


#: the wires an instrument answers on beside its table wire: a LAN SCPI instrument (a Keysight
#: meter, supply or DAQ) offers HiSLIP (``TCPIP::host::hislip0::INSTR``) as well as its raw socket
ALSO_SERVED: dict[Transport, tuple[Transport, ...]] = {SCPI: (HISLIP,)}

#: the simulated station's instruments, in the order they are served and listed
INSTRUMENTS: tuple[StationInstrument, ...] = (
    StationInstrument("dmm", "multimeter", SCPI, "keysight_34465a", lambda s: s.dmm),
    StationInstrument("dmm_temp", "multimeter", SCPI, "keysight_34465a", lambda s: s.dmm_temp),
    StationInstrument("supply", "power_supply", SCPI, "keysight_e36312a", lambda s: s.supply),
    StationInstrument("turntable", "turntable", SCPI, "acutrol_turntable", lambda s: s.turntable),
    StationInstrument("gyro", "gyro", SERIAL, "fog_serial", lambda s: s.gyro_line),
    StationInstrument("shaker", "shaker", SCPI, "vibration_controller", lambda s: s.shaker_controller),
    StationInstrument("angular_table", "angular_table", SCPI, "angular_vibration_table",
                      lambda s: s.angular.controller),
    StationInstrument("dmm_mhd", "multimeter", SCPI, "keysight_34465a", lambda s: s.angular.dmm),
    StationInstrument("lf_gyro", "gyro", SERIAL, "fog_serial", lambda s: s.angular.lf_line),
    StationInstrument("chamber", "thermal_chamber", MODBUS, "watlow_f4t", lambda s: s.chamber),
    StationInstrument("daq", "scanning_multimeter", SCPI, "keysight_daq970a", lambda s: s.fixture.daq),
)
