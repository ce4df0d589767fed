"""The station's health check: is every configured instrument there, healthy and as expected?
``bench doctor`` prints it; the operator page shows it (``GET /api/doctor``).

For each instrument of the station, one at a time (so one unreachable instrument does
not hide the others): open it with its driver, ask its identity (``*IDN?``; the gyro
line's ``$ID?``), read its error queue (``SYST:ERR?`` until ``+0``), compare ``*OPT?``
with the ``options = [...]`` the station file states for it, and time one identity
round trip.  The sim-control clock of a simulated station is checked the same way.

How an instrument is checked follows from its driver's connection kind
(``instruments.registry``): SCPI over VISA as above, a serial line by its identity command,
a Modbus TCP chamber controller by its identification registers, its limit and its alarms
(a tripped limit or an active alarm is a FAIL).
VISA instruments are checked first, so the supply's outputs are known before the lines it
powers are opened.

Status per instrument: ``OK``; ``FAIL`` with the reason (cannot open, no or malformed
identity, errors queued, options missing); ``OFF`` for an instrument the station's supply
powers (``bench.app.station.SUPPLY_FED``: the gyro, from ``[wiring] gyro_supply_channel``)
when that output reads off — an unpowered unit is silent by design, so it is reported and
not asked.  A station that cannot be opened at all (a bad station file, an embedded
simulation that does not start, no instruments configured) raises ``StationError``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from contextlib import ExitStack
from dataclasses import asdict, dataclass, field
from typing import Any

from bench.app.station import SUPPLY_FED, InstrumentConfig, Station, StationConfig, StationError
from instruments.base import Identity, open_resource, parse_error_reply
from instruments.protocols import PowerSupply
from instruments.registry import DRIVERS, MODBUS, SERIAL, VISA

#: at most this many ``SYST:ERR?`` reads (an error queue is 20..100 deep on real meters)
MAX_ERROR_READS = 200


@dataclass
class Health:
    """One instrument's check: what it said and whether it passed."""

    name: str
    driver: str
    address: str
    status: str = "FAIL"          # OK | FAIL | OFF
    reason: str = ""
    identity: str = ""
    errors: list[str] = field(default_factory=list)
    options: list[str] | None = None           # *OPT? as read (None: not asked)
    expected_options: list[str] | None = None  # from the station file
    round_trip_ms: float | None = None


def expected_options(inst: InstrumentConfig) -> list[str] | None:
    """The ``options = [...]`` list of an instrument's station table, upper-cased."""
    wanted = inst.options.get("options")
    if wanted is None:
        return None
    if not isinstance(wanted, list) or not all(isinstance(o, str) and o for o in wanted):
        raise StationError(f"[instruments.{inst.name}] options = {wanted!r} must be a list of "
                           "option codes, e.g. [\"DIG\", \"MEM\"]")
    return [o.upper() for o in wanted]


def diagnose(config: StationConfig) -> list[Health]:
    """Check every instrument of ``config`` (starting its embedded simulation if any)."""
    for inst in config.instruments.values():
        expected_options(inst)  # a malformed expectation is a station-file error: exit 2
    with ExitStack() as stack:
        if config.simulation is not None:
            holder = Station(config)
            stack.callback(holder.__exit__, None, None, None)
            try:
                config = holder.start_simulation(config)
            except (StationError, ValueError):
                raise
            except Exception as exc:
                raise StationError(f"the embedded simulation did not start: {exc}") from exc
        if not config.instruments:
            raise StationError(f"station {config.name!r} configures no instruments")
        powered: dict[int, bool] = {}  # supply channel -> output on, read from the supply
        results = [CHECKS[transport](inst, config, powered) for transport in CHECKS
                   for inst in config.instruments.values() if DRIVERS[inst.driver].transport == transport]
        if config.clock != "wall":
            results.append(_check_clock(config))
        order = list(config.instruments) + ["clock"]
        return sorted(results, key=lambda r: order.index(r.name) if r.name in order else 0)


def _single(config: StationConfig, inst: InstrumentConfig) -> StationConfig:
    return StationConfig(config.name, {inst.name: inst}, "wall", "@py", config.wiring, None)


def _read_errors(query) -> tuple[list[str], str]:
    """Drain ``SYST:ERR?``; returns the entries and a reason if the queue never emptied."""
    errors: list[str] = []
    for _ in range(MAX_ERROR_READS):
        reply = query("SYST:ERR?")
        code, _message = parse_error_reply(reply)
        if code == 0:
            return errors, ""
        errors.append(reply.strip())
    return errors, f"SYST:ERR? still not +0 after {MAX_ERROR_READS} reads"


def _timed(fn) -> tuple[Any, float]:
    t0 = time.perf_counter()
    value = fn()
    return value, (time.perf_counter() - t0) * 1e3


def _check_scpi(inst: InstrumentConfig, config: StationConfig, powered: dict) -> Health:
    h = Health(inst.name, inst.driver, inst.address, expected_options=expected_options(inst))
    try:
        with Station(_single(config, inst)) as station:
            driver = station.instruments[inst.name]
            h.identity = ",".join(asdict(driver.idn).values())
            _, h.round_trip_ms = _timed(lambda: driver.query("*IDN?"))
            h.errors, overflow = _read_errors(driver.query)
            if h.expected_options is not None:
                h.options = list(driver.options)
            if DRIVERS[inst.driver].protocol is PowerSupply:
                for n, out in driver.ch.items():
                    powered[n] = bool(out.output_enabled)
                _read_errors(driver.query)  # output reads must not leave errors behind
    except Exception as exc:  # any failure to open or talk is this instrument's FAIL
        h.reason = _short(exc)
        return h
    problems = []
    if h.errors:
        problems.append(f"{len(h.errors)} error(s) queued: {h.errors[0]}")
    if overflow:
        problems.append(overflow)
    if h.expected_options is not None:
        missing = [o for o in h.expected_options if o not in (h.options or [])]
        if missing:
            problems.append(f"options {missing} missing (has {h.options or 'none'})")
    h.status, h.reason = ("FAIL", "; ".join(problems)) if problems else ("OK", "")
    return h


def _check_serial(inst: InstrumentConfig, config: StationConfig, powered: dict) -> Health:
    h = Health(inst.name, inst.driver, inst.address)
    fed_by = SUPPLY_FED.get(inst.name)
    channel = config.wiring.get(fed_by) if fed_by else None
    try:
        with Station(_single(config, inst)) as station:
            driver = station.instruments[inst.name]
            # only units fed by the station's supply can be found unpowered; others (the angular
            # rig's LF sensor) have their own power: always asked
            if channel is not None and powered.get(channel) is False:
                h.status = "OFF"
                h.reason = f"unpowered: supply output CH{channel} is off (line opened, not asked)"
                return h
            identity, h.round_trip_ms = _timed(driver.identify)
            h.identity = ",".join(asdict(identity).values())
    except Exception as exc:
        h.reason = _short(exc)
        return h
    h.status = "OK"
    return h


def _check_modbus(inst: InstrumentConfig, config: StationConfig, powered: dict) -> Health:
    """A chamber controller: identification registers, limit and alarm states."""
    h = Health(inst.name, inst.driver, inst.address)
    try:
        with Station(_single(config, inst)) as station:
            driver = station.instruments[inst.name]
            identity, h.round_trip_ms = _timed(driver.identify)
            h.identity = ",".join(str(v) for v in asdict(identity).values())
            status = driver.status()
    except Exception as exc:
        h.reason = _short(exc)
        return h
    h.errors = ([f"limit tripped ({status.limit})"] if status.limit_tripped else []) + \
        [f"alarm {a.number} {a.state}" for a in status.alarms if a.active]
    h.status, h.reason = ("FAIL", "; ".join(h.errors)) if h.errors else ("OK", "")
    return h


def _check_clock(config: StationConfig) -> Health:
    """The sim-control endpoint that serves a simulated station's clock."""
    h = Health("clock", "sim_control", config.clock)
    try:
        res = open_resource(config.clock, backend=config.clock_backend, timeout_ms=10000)
        try:
            reply, h.round_trip_ms = _timed(lambda: res.query("*IDN?"))
            h.identity = ",".join(asdict(Identity.parse(reply)).values())
            h.errors, overflow = _read_errors(res.query)
        finally:
            res.close()
    except Exception as exc:
        h.reason = _short(exc)
        return h
    problems = ([f"{len(h.errors)} error(s) queued: {h.errors[0]}"] if h.errors else []) \
        + ([overflow] if overflow else [])
    h.status, h.reason = ("FAIL", "; ".join(problems)) if problems else ("OK", "")
    return h


#: how an instrument is checked, by its driver's connection kind, in this order (the supply,
#: a VISA instrument, is read before the serial lines it may power)
CHECKS: dict[str, Callable[[InstrumentConfig, StationConfig, dict[int, bool]], Health]] = {
    VISA: _check_scpi, SERIAL: _check_serial, MODBUS: _check_modbus}


def _short(exc: BaseException) -> str:
    text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    return text if len(text) <= 160 else text[:157] + "..."
