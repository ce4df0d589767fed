"""What a simulated instrument does when its power goes and comes back, and which faults of
its own it has — the hooks fault injection (``sim.faults``) drives, so it never reaches
inside a device.

A device declares ``fault_kinds``, the faults that act on the device itself; the wire it is
served over adds the faults that act on the wire (``sim.server.Transport.wire_fault_kinds``:
drop, stall, and for SCPI slow, garble, error).  By kind, the device offers:

========== ======================================= ==========================================
kind       hooks                                   what the instrument does
========== ======================================= ==========================================
power      ``power_off()``, ``power_on()``         outputs to zero / comes back in its
                                                   power-on state (every device has it)
interlock  ``trip_interlock()``                    drives cut, latched until its reset
overload   ``overload(volts)``, ``end_overload()``, the input forced to ``volts`` from now
           ``overloaded``                          until ended
frame      (its frames go out through              each frame corrupted or lost on the line
           ``SerialLink.write_frames``)
limit      ``trip_limit()``                        an over-temperature limit trips: heating
                                                   and cooling cut, latched until its reset
alarm      ``raise_alarm()``                       a controller alarm goes active, latched
                                                   until cleared
========== ======================================= ==========================================

A contract test (``tests/sim/test_station_table.py``) checks that every instrument of the
station table has the hooks of the kinds it claims.
"""

from __future__ import annotations

from typing import Protocol

from sim.scpi import ScpiDevice

#: IEEE 488.2 ESR bit 7, power on: set by a device that has just been powered up
ESR_POWER_ON = 0x80


class SimDevice(Protocol):
    """Every simulated instrument: its own fault kinds and its power."""

    fault_kinds: tuple[str, ...]

    def power_off(self) -> None:
        """Power lost now: outputs to zero, anything in progress lost."""

    def power_on(self) -> None:
        """Power back now: the instrument's power-on state."""


class InterlockedDevice(SimDevice, Protocol):
    """A controller with a safety interlock (``"interlock"`` in its fault kinds)."""

    def trip_interlock(self) -> None:
        """The interlock trips now: drives cut, latched until the interlock is reset."""


class OverloadableDevice(SimDevice, Protocol):
    """A meter whose input can be forced (``"overload"`` in its fault kinds)."""

    @property
    def overloaded(self) -> bool:
        """An overload is in force now."""

    def overload(self, volts: float) -> None:
        """The input forced to ``volts`` from now (ending any earlier overload)."""

    def end_overload(self) -> None:
        """The forced input ends now (no-op without one)."""


class LimitDevice(SimDevice, Protocol):
    """A controller with an over-temperature limit (``"limit"`` in its fault kinds)."""

    def trip_limit(self) -> None:
        """The limit trips now: heating and cooling cut, latched until the limit is reset."""


class AlarmingDevice(SimDevice, Protocol):
    """A controller with alarms (``"alarm"`` in its fault kinds)."""

    def raise_alarm(self) -> None:
        """An alarm goes active now, latched until it is cleared."""


def scpi_power_on(device: ScpiDevice) -> None:
    """The power-on state of an IEEE 488.2 instrument: ``*RST`` settings, an empty error
    queue, and only PON in the event status register — in every I/O session, and PON for
    the next session to open (``ScpiDevice.power_on_status``)."""
    device.reset()
    device.clear_status()  # the device's own status hook (shared event registers)
    device.power_on_status()


__all__ = ["ESR_POWER_ON", "AlarmingDevice", "InterlockedDevice", "LimitDevice", "OverloadableDevice",
           "SimDevice", "scpi_power_on"]
