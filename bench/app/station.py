"""Station configuration and opening a station (simulated or real) for a procedure.

A station is a TOML file::

    [station]
    name = "lab-3 start-up rig"
    clock = "wall"                       # or the VISA address of a sim-control endpoint

    [instruments.dmm]                    # name -> driver kind, address, options
    driver = "keysight_34465a"
    address = "TCPIP::192.168.1.20::5025::SOCKET"
    visa_backend = "@py"                 # any VISA backend: "@py", "@ivi", a pyvisa-sim YAML "@sim"

    [instruments.gyro]                   # a serial-line instrument, opened with pyserial
    driver = "fog_serial"
    address = "/dev/ttyUSB0"             # or "socket://host:port" (a serial server)
    baudrate = 921600

    [wiring]
    sampling_resistor_ohm = 5000.0
    positive_rail_channel = 2
    negative_rail_channel = 3

    [site]                               # latitude, height, optional measured local_g_mps2
    latitude_deg = 32.06
    height_m = 10.0

The built-in station ``sim`` starts the simulated world in-process on free loopback ports
and fills in the addresses; a ``[simulation]`` table in a station file does the same with
its own settings (seed, latitude, resistor, accelerometer overrides).  The same procedure
runs on either.

Drivers are looked up in ``instruments.registry`` (class, connection kind, options); the
simulated station's instruments come from its table (``sim.station.INSTRUMENTS``: name,
driver key, address once served).  This module joins the two and opens each connection
with the opener of its kind (:data:`OPENERS`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pyvisa
import serial

from bench.core.clock import Clock, SimulatedClock, WallClock
from bench.core.site import DEFAULT_SITE
from bench.core.toml_file import read_toml
from instruments.base import open_resource
from instruments.registry import DRIVERS, MODBUS, SERIAL, VISA, Option

if TYPE_CHECKING:  # the simulator is imported when a station starts one (it is slow to import)
    from sim.station import SimulatedStation

DEFAULT_WIRING = {
    "sampling_resistor_ohm": 5000.0,
    "temp_resistor_ohm": 10000.0,
    "positive_rail_channel": 2,
    "negative_rail_channel": 3,
    "rail_voltage_v": 15.0,
    "rail_current_limit_a": 0.1,
    "gyro_supply_channel": 1,
    "gyro_supply_voltage_v": 5.0,
    "gyro_current_limit_a": 1.0,
    "fixture_first_channel": 101,   # the batch fixture: socket n on scanner channel first + n − 1
}
#: instruments the station's supply powers: name -> the [wiring] key of the output feeding it
SUPPLY_FED = {"gyro": "gyro_supply_channel"}


SITE_RANGES = {"latitude_deg": (-90.0, 90.0), "height_m": (-1000.0, 10000.0),
               "local_g_mps2": (9.7, 9.9)}


class StationError(ValueError):
    """A station file or address that cannot be used (message names the value)."""


@dataclass
class InstrumentConfig:
    name: str
    driver: str
    address: str
    visa_backend: str = "@py"
    timeout_ms: int = 10000
    options: dict[str, Any] = field(default_factory=dict)


@dataclass
class StationConfig:
    name: str
    instruments: dict[str, InstrumentConfig]
    clock: str = "wall"  # "wall" or the VISA address of a sim-control endpoint
    clock_backend: str = "@py"
    wiring: dict[str, Any] = field(default_factory=lambda: dict(DEFAULT_WIRING))
    simulation: dict[str, Any] | None = None  # present → start an embedded simulated world
    #: where the bench is: latitude_deg, height_m (gravity and Earth rate follow), optional
    #: local_g_mps2 (measured gravity, overrides the normal-gravity formula)
    site: dict[str, Any] = field(default_factory=lambda: dict(DEFAULT_SITE))

    @property
    def simulated(self) -> bool:
        return self.simulation is not None or self.clock != "wall"


def _require(table: dict, key: str, kind: type, where: str):
    if key not in table:
        raise StationError(f"{where}: missing '{key}'")
    value = table[key]
    if not isinstance(value, kind):
        raise StationError(f"{where}: '{key}' = {value!r} must be a {kind.__name__}")
    return value


#: wiring key -> (allowed range, must be a whole number)
WIRING_RANGES = {
    "sampling_resistor_ohm": ((10.0, 1e6), False),
    "temp_resistor_ohm": ((10.0, 1e6), False),
    "positive_rail_channel": ((1, 3), True),
    "negative_rail_channel": ((1, 3), True),
    "rail_voltage_v": ((0.0, 25.0), False),
    "rail_current_limit_a": ((0.0, 1.0), False),
    "gyro_supply_channel": ((1, 3), True),
    "gyro_supply_voltage_v": ((0.0, 25.0), False),
    "gyro_current_limit_a": ((0.0, 5.0), False),
    "fixture_first_channel": ((101, 113), True),
}


def _table(data: dict, key: str, source: str) -> dict:
    value = data.get(key, {})
    if not isinstance(value, dict):
        raise StationError(f"{source}: '{key}' = {value!r} must be a table ([{key}])")
    return value


def parse_station(data: dict, source: str = "<station>") -> StationConfig:
    """Validate a station table (as read from TOML) into a :class:`StationConfig`."""
    top = _table(data, "station", source)
    unknown = set(data) - {"station", "instruments", "wiring", "simulation", "site"}
    if unknown:
        raise StationError(f"{source}: unknown table(s) {sorted(unknown)}; allowed: "
                           "station, instruments, wiring, simulation, site")
    instruments: dict[str, InstrumentConfig] = {}
    for name, table in _table(data, "instruments", source).items():
        where = f"{source}: [instruments.{name}]"
        if not isinstance(table, dict):
            raise StationError(f"{where} must be a table with driver and address")
        driver = _require(table, "driver", str, where)
        if driver not in DRIVERS:
            raise StationError(f"{where}: driver {driver!r} not in {sorted(DRIVERS)}")
        address = table.get("address", "")
        if not isinstance(address, str):
            raise StationError(f"{where}: address {address!r} must be a VISA resource string")
        timeout = table.get("timeout_ms", 10000)
        if not isinstance(timeout, int) or not 100 <= timeout <= 600000:
            raise StationError(f"{where}: timeout_ms {timeout!r} not in 100..600000")
        if DRIVERS[driver].options:
            _check_options(table, DRIVERS[driver].options, where)
        instruments[name] = InstrumentConfig(
            name, driver, address, table.get("visa_backend", "@py"), timeout,
            {k: v for k, v in table.items()
             if k not in ("driver", "address", "visa_backend", "timeout_ms")})
    wiring = dict(DEFAULT_WIRING)
    for key, value in _table(data, "wiring", source).items():
        if key not in DEFAULT_WIRING:
            raise StationError(f"{source}: [wiring] {key!r} not in {sorted(DEFAULT_WIRING)}")
        (lo, hi), whole = WIRING_RANGES[key]
        if (isinstance(value, bool) or not isinstance(value, (int, float))
                or (whole and value != int(value)) or not lo <= value <= hi):
            kind = "a whole number" if whole else "a number"
            raise StationError(f"{source}: [wiring] {key} = {value!r} must be {kind} in {lo:g}..{hi:g}")
        wiring[key] = int(value) if whole else float(value)
    if wiring["positive_rail_channel"] == wiring["negative_rail_channel"]:
        raise StationError(f"{source}: [wiring] positive and negative rails are both channel "
                           f"{wiring['positive_rail_channel']}")
    if wiring["gyro_supply_channel"] in (wiring["positive_rail_channel"],
                                         wiring["negative_rail_channel"]):
        raise StationError(f"{source}: [wiring] gyro_supply_channel = "
                           f"{wiring['gyro_supply_channel']} is an accelerometer rail")
    simulation = data.get("simulation")
    if simulation is not None:
        if not isinstance(simulation, dict):
            raise StationError(f"{source}: [simulation] must be a table")
        check_simulation(simulation, source)
    clock = top.get("clock", "wall")
    if not isinstance(clock, str):
        raise StationError(f"{source}: [station] clock {clock!r} must be 'wall' or a VISA address")
    site = _parse_site(data, simulation, source)
    return StationConfig(top.get("name", Path(source).stem), instruments, clock,
                         top.get("clock_backend", "@py"), wiring, simulation, site)


def _parse_site(data: dict, simulation: dict | None, source: str) -> dict[str, Any]:
    """[site], else the simulated world's own latitude and height, else the default site."""
    table = _table(data, "site", source)
    for key, value in table.items():
        if key not in SITE_RANGES:
            raise StationError(f"{source}: [site] {key!r} not in {sorted(SITE_RANGES)}")
        lo, hi = SITE_RANGES[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not lo <= value <= hi:
            raise StationError(f"{source}: [site] {key} = {value!r} must be a number in {lo:g}..{hi:g}")
    site = dict(DEFAULT_SITE)
    if simulation is not None:
        site.update({k: float(simulation[k]) for k in ("latitude_deg", "height_m") if k in simulation})
        if simulation.get("g_mps2"):
            site["local_g_mps2"] = float(simulation["g_mps2"])
    site.update({k: float(v) for k, v in table.items()})
    return site


def _check_options(table: dict, spec: Mapping[str, Option], where: str) -> None:
    """A driver's options (``instruments.registry``): each known, and in its set or range."""
    for key, value in table.items():
        if key in ("driver", "address", "timeout_ms"):
            continue
        if key not in spec:
            raise StationError(f"{where}: option {key!r} not in {sorted(spec)}")
        problem = spec[key].problem(key, value)
        if problem:
            raise StationError(f"{where}: {problem}")


#: ``opener(instrument, connection options, VISA resource manager by backend)`` -> an open
#: connection (anything with ``close()``) of one transport kind of ``instruments.registry``
Opener = Callable[[InstrumentConfig, dict[str, Any], Callable[[str], Any]], Any]


def _open_visa(inst: InstrumentConfig, options: dict[str, Any], manager: Callable[[str], Any]) -> Any:
    """A pyvisa message-based resource (``TCPIP::host::port::SOCKET``, GPIB, ...)."""
    return open_resource(inst.address, backend=inst.visa_backend, timeout_ms=inst.timeout_ms,
                         resource_manager=manager(inst.visa_backend), **options)


def _open_serial(inst: InstrumentConfig, options: dict[str, Any], manager: Callable[[str], Any]) -> Any:
    """A pyserial port for ``socket://host:port`` or a device path."""
    return serial.serial_for_url(inst.address, timeout=inst.timeout_ms / 1000.0, **options)


def _open_modbus(inst: InstrumentConfig, options: dict[str, Any], manager: Callable[[str], Any]) -> Any:
    """A connected pymodbus ``ModbusTcpClient`` for ``modbus://host[:port]`` (port 502 by default)."""
    # lazy: pymodbus (~30 ms) only for a station with a Modbus TCP instrument (the thermal chamber)
    from pymodbus.client import ModbusTcpClient  # noqa: PLC0415 — lazy, see above

    host, port = parse_modbus_address(inst.address)
    # retries=0: the driver re-sends what may be re-sent itself (instruments/chamber.py)
    client = ModbusTcpClient(host, port=port, timeout=inst.timeout_ms / 1000.0, retries=0)
    if not client.connect():
        raise ConnectionError(f"no Modbus TCP server at {host}:{port}")
    return client


def parse_modbus_address(address: str) -> tuple[str, int]:
    """``modbus://host[:port]`` → (host, port); ValueError naming the expected form."""
    rest = address[len("modbus://"):] if address.startswith("modbus://") else None
    host, _, port = (rest or "").rpartition(":") if rest and ":" in rest else (rest, "", "502")
    if not rest or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise ValueError(f"address {address!r} must be modbus://host[:port] (port 1..65535, default 502)")
    return host, int(port)


#: how a station opens each kind of connection a driver is driven over
OPENERS: dict[str, Opener] = {VISA: _open_visa, SERIAL: _open_serial, MODBUS: _open_modbus}


def check_simulation(options: dict, source: str = "<station>") -> None:
    """Validate a [simulation] table now, before any run is created."""
    # lazy: the simulator (~1 s of imports) only for a station file with a [simulation] table
    from sim.physics.accelerometer import AccelerometerParams  # noqa: PLC0415 — lazy, see above
    from sim.station import SimStationConfig  # noqa: PLC0415 — lazy: the simulator, as above

    try:
        SimStationConfig(**options).validate()
        AccelerometerParams(**options.get("accelerometer", {}))
    except TypeError as exc:
        raise StationError(f"{source}: [simulation]: {exc}") from None
    except ValueError as exc:
        raise StationError(f"{source}: [simulation] {exc}") from None


def load_station(path: str | Path) -> StationConfig:
    return parse_station(read_toml(path, "station file", StationError, " (or use --station sim)"), str(path))


#: sensor kind → the simulated station's option naming that unit's serial
UNIT_KEYS = {"accelerometer": "unit_serial", "gyro": "gyro_serial", "angular": "mhd_serial"}


class Station:
    """Open drivers and clock of a station; closes everything (and the embedded sim) on exit."""

    def __init__(self, config: StationConfig, *, seed: int | None = None,
                 unit_serial: str | None = None, unit_kind: str = "accelerometer",
                 fixture: Mapping[int, str] | None = None) -> None:
        """``fixture``: the units in the batch fixture's sockets (socket → serial); on a
        simulated station they are the fixture's simulated units."""
        if unit_kind not in UNIT_KEYS:
            raise ValueError(f"unit_kind {unit_kind!r} not in {'|'.join(UNIT_KEYS)}")
        self.config = config
        self.seed = seed
        self.unit_serial = unit_serial
        self.unit_kind = unit_kind  # which simulated sensor the serial number names
        self.fixture = dict(fixture or {})
        self.instruments: dict[str, Any] = {}
        self.clock: Clock = WallClock()
        self.sim: SimulatedStation | None = None  # the embedded simulated station, if any
        self._stack = ExitStack()

    def __enter__(self) -> Station:
        try:
            self._open()
        except BaseException:
            self._stack.close()
            raise
        return self

    def __exit__(self, *exc) -> None:
        self._stack.close()

    def _open(self) -> None:
        cfg = self.config
        if cfg.simulation is not None:
            cfg = self.start_simulation(cfg)
        managers: dict[str, Any] = {}

        def manager(backend: str) -> Any:
            if backend not in managers:
                managers[backend] = pyvisa.ResourceManager(backend)
                self._stack.callback(managers[backend].close)
            return managers[backend]

        for name, inst in cfg.instruments.items():
            driver = DRIVERS[inst.driver]
            try:
                connection = OPENERS[driver.transport](inst, driver.connection_options(inst.options), manager)
                self._stack.callback(connection.close)
                self.instruments[name] = driver.cls(connection, name=name,
                                                    **driver.driver_options(inst.options))
            except Exception as exc:
                raise StationError(f"cannot open instrument {name!r} ({inst.driver}) at "
                                   f"{inst.address!r}: {exc}") from exc
        if cfg.clock != "wall":
            try:
                res = open_resource(cfg.clock, backend=cfg.clock_backend, timeout_ms=600000,
                                    resource_manager=manager(cfg.clock_backend))
            except Exception as exc:
                raise StationError(f"cannot open the sim-control clock at {cfg.clock!r}: {exc}") from exc
            self._stack.callback(res.close)
            self.clock = SimulatedClock(res)
        self.config = cfg

    def start_simulation(self, cfg: StationConfig) -> StationConfig:
        """Start ``cfg``'s embedded simulated station (stopped when this station closes);
        return the station config with its instruments and clock at the served addresses."""
        # lazy: the simulator (~1 s of imports) only when a station simulates (not a real one)
        from sim.station import INSTRUMENTS, SimStationConfig, SimulatedStation  # noqa: PLC0415 — lazy, see above

        sim_opts = dict(cfg.simulation or {})
        if self.seed is not None:
            sim_opts["seed"] = self.seed
        if self.unit_serial is not None:
            sim_opts[UNIT_KEYS[self.unit_kind]] = self.unit_serial
        if self.fixture:
            sim_opts["fixture"] = {str(n): serial for n, serial in self.fixture.items()}
        for key in ("sampling_resistor_ohm", "temp_resistor_ohm", "positive_rail_channel",
                    "negative_rail_channel", "gyro_supply_channel", "fixture_first_channel"):
            sim_opts.setdefault(key, cfg.wiring[key])
        try:
            sim_cfg = SimStationConfig(**sim_opts)
        except TypeError as exc:
            raise StationError(f"[simulation]: {exc}") from None
        sim = self.sim = SimulatedStation(sim_cfg)
        sim.start()
        self._stack.callback(sim.stop)
        res = sim.resources()
        instruments = {row.name: InstrumentConfig(row.name, row.driver, res[row.name]) for row in INSTRUMENTS}
        return StationConfig("sim", instruments, res["sim"], "@py", cfg.wiring, cfg.simulation,
                             cfg.site)

    def snapshot(self) -> dict[str, Any]:
        """Each instrument's identity and settings, for the run record."""
        snap: dict[str, Any] = {"name": self.config.name, "simulated": self.config.simulated,
                                "wiring": self.config.wiring, "site": self.config.site,
                                "instruments": {}}
        for name, driver in self.instruments.items():
            entry: dict[str, Any] = {"address": self.config.instruments[name].address,
                                     "driver": self.config.instruments[name].driver}
            try:
                entry.update(driver.snapshot())
            except Exception as exc:  # a snapshot must never stop a run from being recorded
                entry["error"] = str(exc)
            snap["instruments"][name] = entry
        if self.sim is not None:
            snap["simulation"] = {"seed": self.sim.config.seed,
                                  "unit_serial": self.sim.config.unit_serial}
        return snap


def builtin_sim_config() -> StationConfig:
    return StationConfig("sim", {}, "wall", "@py", dict(DEFAULT_WIRING), simulation={})


def resolve_station(spec: str) -> StationConfig:
    """``sim`` → the built-in simulated station; anything else is a station TOML file."""
    return builtin_sim_config() if spec == "sim" else load_station(spec)
