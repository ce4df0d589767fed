"""A simulated Watlow F4T temperature-chamber controller, served over Modbus TCP.

One control loop (the chamber air), its ramp-to-set-point, six alarms, a separate
over-temperature limit controller and a real-time clock, as registers
(``sim.devices.chamber_map``; the table is docs/CHAMBER.md).  The plant is
``sim.physics.thermal_chamber.ChamberAir``, a view of the World: the controller's loop runs
(conditioning on) while its control mode is Auto, the limit is not tripped and it has power;
otherwise the air drifts to the lab's ambient.

* Control mode (2730): Auto (10) runs the chamber, Off (62) is standby; Manual (54, open-loop
  power) is not simulated and refused with exception 03.
* Ramp (2794 action, 2796 scale, 2798 rate): with action Set Point (85) or Both (13) a set
  point change ramps at the rate; with Startup (88) or Both the switch from standby ramps from
  the air temperature.  The plant's own heating and cooling rates bound every move.  The
  working set point (2810) is the demand the loop follows: the ramp while ramping, else the
  set point.
* Alarm 1 is a deviation alarm (from the working set point, ±3 °C by default, non-latching),
  blocked while the demand ramps and for two loop periods after it arrives (the F4T's
  blocking of a deviation alarm until the process first settles).  Alarm 2 is a process alarm
  (−75 / +185 °C, latching).  Alarms 3–6 have the same registers (block n at 1330 + 100·(n − 1))
  and the F4T's defaults: Off, 0 / 148.9 °C, non-latching.  A latched alarm clears on Clear (129)
  to its clear register once its condition is gone.  States are evaluated when read.
* Loop power (2808, read-only): the loop's output, −100 % (full cooling) … +100 % (full heat),
  0 while not conditioning.  Manual power (2784) is kept, −100 … 100 %, and drives nothing
  (Manual mode is not simulated).
* Clock (14664 hour … 14674 year): a calendar that runs with the World's clock from
  ``CLOCK_AT_WORLD_START``; writing a field sets it (a day past the month's end: 03; a month or
  year write moves a day past the new month's end back to its last day).  Battery-backed: a
  power loss does not stop it.
* The limit controller watches the air with its own sensor: crossing its high or low set
  point trips it (found in closed form on the air's segment and scheduled on the World), which
  cuts heating and cooling until Clear (129) is written to 11256 with the air back inside the
  limits by 2 °C.
* Bad requests: an address outside the map, a write to a read-only register or a write that
  does not cover a whole 32-bit parameter → exception 02 (illegal data address); a value
  outside its range or not one of its options, a non-finite float → 03 (illegal data value);
  a function other than 03/04/06/16 → 01.  Nothing a client sends raises out of the device.
* Faults (``fault_kinds``): ``power`` (silent; back in standby with its settings kept, as the
  F4T keeps them in non-volatile memory), ``limit`` (the limit trips now, latched), ``alarm``
  (alarm 2 goes to Alarm High, latched until cleared).
"""

from __future__ import annotations

import calendar
import datetime
import math
from collections.abc import Callable
from typing import Any, cast

from pymodbus.constants import ExcCodes
from pymodbus.simulator import DataType, SimData, SimDevice

from sim.devices import chamber_map as cm
from sim.physics.thermal_chamber import ChamberAir
from sim.world import World

#: hysteresis of the limit's clear (°C inside the limit)
LIMIT_CLEAR_MARGIN_C = 2.0
#: Modbus functions served: read holding (03) and input (04) registers, write single (06) / multiple (16)
FUNCTIONS = (3, 4, 6, 16)
#: the identity the controller reports (hardware id as the F4T guide's table gives it)
HARDWARE_ID, SOFTWARE_RELEASE = 124, 7
#: digit 7 'A': no profiles, six alarms; digit 12 '1': one control loop, no cascade — as ESPEC's
#: ChamberConnectLibrary decodes the part number (``process_controller``)
PART_NUMBER = "F4T1L0AA1A11AA1"
#: the clock's reading at the World's t = 0 (assumed: the World keeps no calendar)
CLOCK_AT_WORLD_START = datetime.datetime(2025, 1, 1, 0, 0, 0)
#: the clock's fields (registers ``clock_<field>``) and the values a write may set (the year's: assumed)
CLOCK_FIELDS = {"hour": (0, 23), "minute": (0, 59), "second": (0, 59), "month": (1, 12),
                "day": (1, 31), "year": (2000, 2099)}
#: manual power, %: −100 full cooling … +100 full heating (F4T function reference, PWR)
POWER_RANGE_PCT = (-100.0, 100.0)
_FLOAT_RANGE = 99_999.0


class WatlowF4T:
    """The controller's registers over the chamber air of one World."""

    fault_kinds: tuple[str, ...] = ("power", "limit", "alarm")

    def __init__(self, world: World, air: ChamberAir, serial_number: int = 1_234_567) -> None:
        self.world = world
        self.air = air
        self.serial_number = int(serial_number)
        p = air.params
        self.powered = True
        self.mode = cm.OFF
        self.set_point_c = p.lab_ambient_c
        self.set_point_range_c = (p.min_c, p.max_c)
        self.ramp_action = cm.RAMP_OFF
        self.ramp_scale = cm.PER_MINUTE
        self.ramp_rate = 1.0
        self._ramping = False
        self.alarms = [_Alarm(cm.ALARM_DEVIATION, -3.0, 3.0, cm.NON_LATCHING),
                       _Alarm(cm.ALARM_PROCESS, -75.0, 185.0, cm.LATCHING)]
        # alarms 3..n at the F4T guide's defaults: Off, low 0.0 °C, high 148.9 °C, non-latching
        self.alarms += [_Alarm(cm.ALARM_OFF, 0.0, 148.9, cm.NON_LATCHING) for _ in range(cm.ALARMS - 2)]
        self.manual_power_pct = 0.0
        self._clock_offset_s = 0  # what clock writes have moved the calendar by, whole seconds
        self.limit_low_c, self.limit_high_c = p.min_c - 10.0, p.max_c + 10.0
        self.limit_tripped = cm.LIMIT_NONE
        self._limit_event: Any = None
        air.listeners.append(self._air_changed)
        self._getters: dict[str, Callable[[], float | int | str]] = {
            "hardware_id": lambda: HARDWARE_ID, "software_release": lambda: SOFTWARE_RELEASE,
            "serial_number": lambda: self.serial_number, "part_number": lambda: PART_NUMBER,
            "device_status": lambda: cm.DEVICE_OK, "display_units": lambda: cm.UNITS_C,
            "control_mode": lambda: self.mode, "set_point_low_c": lambda: self.set_point_range_c[0],
            "set_point_high_c": lambda: self.set_point_range_c[1], "set_point_c": lambda: self.set_point_c,
            "ramp_action": lambda: self.ramp_action, "ramp_scale": lambda: self.ramp_scale,
            "ramp_rate": lambda: self.ramp_rate, "working_set_point_c": self.working_set_point_c,
            "control_mode_active": lambda: self.mode, "process_value_c": self.process_value_c,
            "chamber_temperature_c": self.process_value_c, "limit_state": lambda: self.limit_tripped,
            "limit_low_c": lambda: self.limit_low_c, "limit_high_c": lambda: self.limit_high_c,
            "limit_status": lambda: cm.DEVICE_OK if self.limit_tripped == cm.LIMIT_NONE else cm.DEVICE_FAIL,
            "limit_error": lambda: cm.ALARM_NONE, "limit_clear": lambda: cm.IGNORE,
            "manual_power_pct": lambda: self.manual_power_pct, "loop_power_pct": self.loop_power_pct,
        }
        for field in CLOCK_FIELDS:
            self._getters[f"clock_{field}"] = self._clock_getter(field)
        for n, alarm in enumerate(self.alarms, start=1):
            self._getters.update(self._alarm_getters(n, alarm))

    def _alarm_getters(self, n: int, alarm: _Alarm) -> dict[str, Callable[[], float | int | str]]:
        return {f"alarm{n}_type": lambda: alarm.kind, f"alarm{n}_sides": lambda: cm.SIDES_BOTH,
                f"alarm{n}_high_c": lambda: alarm.high_c, f"alarm{n}_low_c": lambda: alarm.low_c,
                f"alarm{n}_hysteresis_c": lambda: alarm.hysteresis_c,
                f"alarm{n}_latching": lambda: alarm.latching, f"alarm{n}_clear": lambda: cm.IGNORE,
                f"alarm{n}_state": lambda: self._alarm_state(alarm)}

    # -- what the controller computes -------------------------------------------------------
    @property
    def conditioning(self) -> bool:
        return self.powered and self.mode == cm.AUTO and self.limit_tripped == cm.LIMIT_NONE

    def process_value_c(self) -> float:
        return float(self.air.air_c(self.world.now)[0])

    def working_set_point_c(self) -> float:
        if self.conditioning and self._ramping and self.world.now < self.air.ramp_end_s:
            return self.air.reference_c(self.world.now)
        return self.set_point_c

    def loop_power_pct(self) -> float:
        """The loop's output now, % (−100 full cooling … +100 full heating; 0 while not
        conditioning).  The plant has no heater model: the output is the heat flow the air needs —
        its rate of change plus its loss to the lab (the standby time constant) — as a share of
        the plant's heating (cooling) rate, so a hold at the lab's temperature needs 0 %, a hold
        at 180 °C about 87 % and a full-rate ramp 100 %."""
        if not self.conditioning:
            return 0.0
        p = self.air.params
        t = self.world.now
        need_c_per_s = (float(self.air.air_rate_c_per_s(t)[0])
                        + (self.process_value_c() - p.lab_ambient_c) / p.standby_tau_s)
        capacity_c_per_s = (p.heat_rate_c_per_min if need_c_per_s >= 0 else p.cool_rate_c_per_min) / 60.0
        return max(-100.0, min(100.0, 100.0 * need_c_per_s / capacity_c_per_s))

    def clock(self) -> datetime.datetime:
        """The controller's calendar now (whole seconds)."""
        return CLOCK_AT_WORLD_START + datetime.timedelta(
            seconds=math.floor(self.world.now) + self._clock_offset_s)

    def _set_clock(self, field: str, value: int) -> bool | None:
        lo, hi = CLOCK_FIELDS[field]
        if not lo <= value <= hi:
            return False
        now = self.clock()
        parts = {"year": now.year, "month": now.month, "day": now.day,
                 "hour": now.hour, "minute": now.minute, "second": now.second, field: value}
        last_day = calendar.monthrange(parts["year"], parts["month"])[1]
        if field == "day" and value > last_day:
            return False
        parts["day"] = min(parts["day"], last_day)  # a month or year write: into the new month
        new = datetime.datetime(parts["year"], parts["month"], parts["day"],
                                parts["hour"], parts["minute"], parts["second"])
        self._clock_offset_s += int((new - now).total_seconds())
        return None

    def _clock_getter(self, field: str) -> Callable[[], float | int | str]:
        return lambda: int(getattr(self.clock(), field))

    def _clock_setter(self, field: str) -> Callable[[Any], bool | None]:
        return lambda v: self._set_clock(field, int(v))

    def _ramp_c_per_min(self, for_set_point: bool) -> float | None:
        applies = self.ramp_action in ((cm.RAMP_SET_POINT, cm.RAMP_BOTH) if for_set_point
                                       else (cm.RAMP_STARTUP, cm.RAMP_BOTH))
        if not applies:
            return None
        return self.ramp_rate if self.ramp_scale == cm.PER_MINUTE else self.ramp_rate / 60.0

    def _apply(self, for_set_point: bool = True) -> None:
        """Tell the plant what the controller now demands."""
        ramp = self._ramp_c_per_min(for_set_point) if self.conditioning else None
        self._ramping = ramp is not None
        self.air.command(self.conditioning, self.set_point_c, ramp)

    def _alarm_state(self, alarm: _Alarm) -> int:
        if alarm.kind == cm.ALARM_OFF or not self.powered:
            return cm.ALARM_NONE
        pv = self.process_value_c()
        if alarm.kind == cm.ALARM_DEVIATION:
            settled = self.world.now >= self.air.ramp_end_s + 2.0 * self.air.params.loop_period_s
            if not self.conditioning:
                return alarm.latched or cm.ALARM_NONE
            if not settled:
                return alarm.latched or cm.ALARM_BLOCKED
            centre = self.working_set_point_c()
        else:
            centre = 0.0
        now = (cm.ALARM_HIGH if pv - centre > alarm.high_c
               else cm.ALARM_LOW if pv - centre < alarm.low_c else cm.ALARM_NONE)
        if now != cm.ALARM_NONE and alarm.latching == cm.LATCHING:
            alarm.latched = now
        return alarm.latched or now

    def _clear_alarm(self, alarm: _Alarm) -> None:
        alarm.latched = 0
        self._alarm_state(alarm)  # still in alarm: latches again

    # -- the limit controller ---------------------------------------------------------------
    def _air_changed(self, t: float) -> None:
        """A new air segment: find where it first leaves the limits (if it does) and trip there."""
        if self._limit_event is not None:
            self.world.cancel(self._limit_event)
            self._limit_event = None
        if self.limit_tripped != cm.LIMIT_NONE:
            return
        p = self.air.params
        horizon = 10.0 * max(p.loop_period_s, p.standby_tau_s)
        hits = [(tc, side) for tc, side in (
            (self.air.first_crossing(self.limit_high_c, True, t, horizon), cm.LIMIT_HIGH),
            (self.air.first_crossing(self.limit_low_c, False, t, horizon), cm.LIMIT_LOW)) if tc is not None]
        if hits:
            tc, side = min(hits)
            self._limit_event = self.world.schedule(max(tc, self.world.now), lambda: self._trip(side),
                                                    name="chamber limit trip")

    def _trip(self, side: int) -> None:
        self._limit_event = None
        if self.limit_tripped == cm.LIMIT_NONE:
            self.limit_tripped = side
            self.world.note(f"chamber limit tripped ({'high' if side == cm.LIMIT_HIGH else 'low'})")
            self._apply()

    def _clear_limit(self) -> None:
        pv = self.process_value_c()
        inside = self.limit_low_c + LIMIT_CLEAR_MARGIN_C <= pv <= self.limit_high_c - LIMIT_CLEAR_MARGIN_C
        if self.limit_tripped != cm.LIMIT_NONE and inside:
            self.limit_tripped = cm.LIMIT_NONE
            self._apply(for_set_point=False)
            self._air_changed(self.world.now)

    # -- lifecycle hooks (sim.devices.lifecycle) --------------------------------------------
    def power_off(self) -> None:
        self.powered = False
        self._apply()

    def power_on(self) -> None:
        self.powered = True
        self.mode = cm.OFF  # back in standby; the settings are kept
        self._apply()

    def trip_limit(self) -> None:
        """The over-temperature limit trips now (latched until cleared over Modbus)."""
        self._trip(cm.LIMIT_HIGH)

    def raise_alarm(self) -> None:
        """Alarm 2 goes to Alarm High now, latched until cleared."""
        self.alarms[1].latched = cm.ALARM_HIGH

    # -- registers --------------------------------------------------------------------------
    def read(self, name: str) -> list[int]:
        """The words of one parameter as served."""
        reg = cm.BY_NAME[name]
        value = self._getters[name]()
        if reg.kind == "float":
            return cm.float_to_words(float(value))
        if reg.kind == "int32":
            return cm.int32_to_words(int(value))
        if reg.kind == "string":
            return cm.string_to_words(str(value), reg.words)
        return [int(value) & 0xFFFF]

    def write(self, name: str, words: list[int]) -> int | None:
        """Apply a write of one whole parameter; an exception code, or None when accepted."""
        reg = cm.BY_NAME[name]
        value: float = cm.words_to_float(words) if reg.kind == "float" else words[0]
        if reg.kind == "float" and not (math.isfinite(value) and abs(value) <= _FLOAT_RANGE):
            return ExcCodes.ILLEGAL_VALUE
        setter = self._setters().get(name)
        if setter is None:
            return ExcCodes.ILLEGAL_ADDRESS
        return ExcCodes.ILLEGAL_VALUE if setter(value) is False else None

    def _setters(self) -> dict[str, Callable[[Any], bool | None]]:
        def choice(attr: str, allowed: tuple[int, ...], then: Callable[[], None] | None = None):
            def set_(v: int) -> bool | None:
                if v not in allowed:
                    return False
                setattr(self, attr, v)
                if then is not None:
                    then()
                return None
            return set_

        def set_point(v: float) -> bool | None:
            lo, hi = self.set_point_range_c
            if not lo <= v <= hi:
                return False
            self.set_point_c = float(v)
            if self.conditioning:
                self._apply(for_set_point=True)
            return None

        def sp_range(index: int) -> Callable[[float], bool | None]:
            def set_(v: float) -> bool | None:
                p = self.air.params
                new = list(self.set_point_range_c)
                new[index] = float(v)
                if not p.min_c <= new[0] < new[1] <= p.max_c:
                    return False
                self.set_point_range_c = (new[0], new[1])
                return None
            return set_

        def ramp_rate(v: float) -> bool | None:
            if not 0.0 < v <= _FLOAT_RANGE:
                return False
            self.ramp_rate = float(v)
            return None

        def mode(v: int) -> bool | None:
            if v not in (cm.AUTO, cm.OFF):
                return False
            was = self.conditioning
            self.mode = v
            if self.conditioning != was:
                self._apply(for_set_point=False)
            return None

        def limit(attr: str) -> Callable[[float], bool | None]:
            def set_(v: float) -> bool | None:
                old = getattr(self, attr)
                setattr(self, attr, float(v))
                if self.limit_low_c >= self.limit_high_c:
                    setattr(self, attr, old)
                    return False
                self._air_changed(self.world.now)
                return None
            return set_

        def manual_power(v: float) -> bool | None:
            lo, hi = POWER_RANGE_PCT
            if not lo <= v <= hi:
                return False
            self.manual_power_pct = float(v)
            return None

        def clear_limit(v: int) -> bool | None:
            if v not in (cm.CLEAR, cm.IGNORE):
                return False
            if v == cm.CLEAR:
                self._clear_limit()
            return None

        out: dict[str, Callable[[Any], bool | None]] = {
            "display_units": lambda v: None if v == cm.UNITS_C else False,  # °C only
            "control_mode": mode, "set_point_c": set_point,
            "set_point_low_c": sp_range(0), "set_point_high_c": sp_range(1),
            "ramp_action": choice("ramp_action", (cm.RAMP_OFF, cm.RAMP_STARTUP, cm.RAMP_SET_POINT, cm.RAMP_BOTH)),
            "ramp_scale": choice("ramp_scale", (cm.PER_MINUTE, cm.PER_HOUR)),
            "ramp_rate": ramp_rate, "limit_low_c": limit("limit_low_c"), "limit_high_c": limit("limit_high_c"),
            "limit_clear": clear_limit,
            "manual_power_pct": manual_power,
        }
        for field in CLOCK_FIELDS:
            out[f"clock_{field}"] = self._clock_setter(field)
        for n, alarm in enumerate(self.alarms, start=1):
            out.update({
                f"alarm{n}_type": _alarm_setter(alarm, "kind", (cm.ALARM_OFF, cm.ALARM_PROCESS, cm.ALARM_DEVIATION)),
                f"alarm{n}_sides": lambda v: None if v == cm.SIDES_BOTH else False,
                f"alarm{n}_high_c": _alarm_setter(alarm, "high_c", None),
                f"alarm{n}_low_c": _alarm_setter(alarm, "low_c", None),
                f"alarm{n}_hysteresis_c": _alarm_setter(alarm, "hysteresis_c", None),
                f"alarm{n}_latching": _alarm_setter(alarm, "latching", (cm.LATCHING, cm.NON_LATCHING)),
                f"alarm{n}_clear": self._alarm_clearer(alarm),
            })
        return out

    def _alarm_clearer(self, alarm: _Alarm) -> Callable[[Any], bool | None]:
        def clear(v: int) -> bool | None:
            if v not in (cm.CLEAR, cm.IGNORE):
                return False
            if v == cm.CLEAR:
                self._clear_alarm(alarm)
            return None
        return clear

    # -- the Modbus view --------------------------------------------------------------------
    def simdevice(self) -> SimDevice:
        """The register block pymodbus serves, every access passed to :meth:`_access`."""
        data = [SimData(r.address, count=r.words, datatype=DataType.REGISTERS, readonly=r.access == "R")
                for r in cm.REGISTERS]
        data += [SimData(a, count=1, datatype=DataType.REGISTERS, readonly=True) for a in cm.CLOCK_PADDING]
        return SimDevice(0, simdata=data, action=self._access)

    async def _access(self, function_code: int, start_address: int, address: int, count: int,
                      registers: list[int], values: list[int] | list[bool] | None) -> ExcCodes | None:
        try:
            return self.access(function_code, start_address, address, count, registers, values)
        except Exception:  # a bug here must answer 04, never take the connection down
            return ExcCodes.DEVICE_FAILURE

    def access(self, function_code: int, start_address: int, address: int, count: int,
               registers: list[int], values: list[int] | list[bool] | None) -> ExcCodes | None:
        """Fill ``registers`` for a read, apply a write (pymodbus then stores ``values``)."""
        if function_code not in FUNCTIONS:
            return ExcCodes.ILLEGAL_FUNCTION
        covered = [r for r in cm.REGISTERS if r.address < address + count and address < r.address + r.words]
        if values is None:
            for reg in covered:
                words = self.read(reg.name)
                off = reg.address - start_address
                registers[off:off + reg.words] = words
            return None
        for reg in covered:  # a write covers whole parameters
            if reg.address < address or reg.address + reg.words > address + count:
                return ExcCodes.ILLEGAL_ADDRESS
        for reg in covered:
            words = [int(v) for v in values[reg.address - address:reg.address - address + reg.words]]
            code = self.write(reg.name, words)
            if code is not None:
                return ExcCodes(code)
        for reg in covered:  # what the client reads back is what the controller holds
            off = reg.address - start_address
            registers[off:off + reg.words] = self.read(reg.name)
            cast(list[int], values)[reg.address - address:reg.address - address + reg.words] = \
                registers[off:off + reg.words]
        return None


class _Alarm:
    """One alarm block's settings and its latched state (0: none latched)."""

    def __init__(self, kind: int, low_c: float, high_c: float, latching: int) -> None:
        self.kind, self.low_c, self.high_c, self.latching = kind, low_c, high_c, latching
        self.hysteresis_c = 0.6
        self.latched = 0


def _alarm_setter(alarm: _Alarm, attr: str, allowed: tuple[int, ...] | None) -> Callable[[Any], bool | None]:
    def set_(v: Any) -> bool | None:
        if allowed is not None and v not in allowed:
            return False
        setattr(alarm, attr, float(v) if allowed is None else v)
        return None
    return set_
