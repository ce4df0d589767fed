"""Simulated dual-axis turntable controller (ACUTROL-style language, see docs/ARCHITECTURE.md).

The motion physics (trapezoids, rate ramps, settling) lives in ``sim.physics.motion``; this
module is only the controller's command language and its interlock, evaluated at
``world.now``.  Axis numbers come first in every command's parameters.
"""

from __future__ import annotations

from sim.devices.lifecycle import scpi_power_on
from sim.physics.motion import DualAxisTable
from sim.scpi import Args, ScpiDevice, ScpiError, format_number
from sim.world import World

STATUS_IN_POSITION, STATUS_MOVING, STATUS_AT_RATE = 1, 2, 4
STATUS_LIMIT, STATUS_INTERLOCK_OPEN, STATUS_FAULT = 8, 16, 32


class TurntableController(ScpiDevice):
    fault_kinds: tuple[str, ...] = ("power", "interlock")

    def __init__(self, world: World, table: DualAxisTable, serial: str = "0001") -> None:
        super().__init__(("BENCHSIM", "TURNTABLE-2AX", serial, "1.0"), options="0")
        self.world, self.table = world, table
        self.interlock_closed = True
        self.tripped = False
        self._register()

    def _axis(self, args: Args):
        args.require_count(1, 99)
        n = args.integer(0, min=1, max=len(self.table.axes))
        return n, self.table.axes[n - 1]

    def _need_drive(self) -> None:
        if not self.interlock_closed or self.tripped:
            raise ScpiError(-221, "interlock open: close (and reset a trip) before commanding motion")

    def reset(self) -> None:
        for axis in self.table.axes:
            axis.stop(self.world.now)

    # -- lifecycle (sim.devices.lifecycle) ------------------------------------------------
    def _drives_off(self) -> None:
        for axis in self.table.axes:  # drives disabled: the axes coast to rest
            axis.command_off(self.world.now)

    def power_off(self) -> None:
        """Power lost: both drives off, the axes coast to rest."""
        self._drives_off()

    def power_on(self) -> None:
        scpi_power_on(self)

    def trip_interlock(self) -> None:
        """The interlock trips: drives off (the axes coast to rest), status bits 16 and 32,
        motion refused until ``:INT:RES``."""
        self.tripped = True
        self._drives_off()

    def status_bits(self, axis) -> int:
        t = self.world.now
        bits = 0
        bits |= STATUS_IN_POSITION if axis.mode == "POS" and bool(axis.in_position(t)) else 0
        bits |= STATUS_MOVING if bool(axis.moving(t)) else 0
        bits |= STATUS_AT_RATE if axis.mode == "RATE" and bool(axis.at_rate(t)) else 0
        bits |= STATUS_LIMIT if bool(axis.limit_reached(t)) else 0
        # a trip opens the interlock chain until :INT:RES (bit 16 with the fault bit 32)
        bits |= STATUS_INTERLOCK_OPEN if not self.interlock_closed or self.tripped else 0
        bits |= STATUS_FAULT if self.tripped else 0
        return bits

    def _register(self) -> None:
        c, now = self.command, lambda: self.world.now

        def mode(kind: str):
            def handler(args: Args) -> None:
                _, axis = self._axis(args)
                args.require_count(1, 1)
                if kind != "OFF":
                    self._need_drive()
                {"POS": axis.command_hold, "RATE": axis.command_rate_mode,
                 "OFF": axis.command_off}[kind](now())
            return handler

        def demand_pos(args: Args) -> None:
            _, axis = self._axis(args)
            args.require_count(2, 2)
            self._need_drive()
            if axis.mode != "POS":
                raise ScpiError(-221, "axis not in position mode (:MODE:POS <axis> first)")
            lo, hi = axis.position_limits_deg
            target = args.number(1, min=lo if lo is not None else -1e6,
                                 max=hi if hi is not None else 1e6)
            axis.command_position(now(), target)

        def demand_rate(args: Args) -> None:
            _, axis = self._axis(args)
            args.require_count(2, 2)
            self._need_drive()
            if axis.mode != "RATE":
                raise ScpiError(-221, "axis not in rate mode (:MODE:RATE <axis> first)")
            lim = axis.rate_limit_dps
            axis.command_rate(now(), args.number(1, min=-lim, max=lim))

        def limit(attr: str, hw_attr: str):
            def handler(args: Args) -> None:
                _, axis = self._axis(args)
                args.require_count(2, 2)
                value = args.number(1, min=1e-3, max=getattr(axis, hw_attr))
                getattr(axis, f"set_{attr}")(now(), value)
            return handler

        def read(fn: str):
            return lambda args: format_number(float(getattr(self._axis(args)[1], fn)(now())))

        c(":MODE:POSition", set=mode("POS"))
        c(":MODE:RATE", set=mode("RATE"))
        c(":MODE:OFF", set=mode("OFF"))
        c(":MODE", query=lambda a: self._axis(a)[1].mode)
        c(":DEMand:POSition", set=demand_pos,
          query=lambda a: format_number(self._axis(a)[1].position_demand_deg))
        c(":DEMand:RATE", set=demand_rate,
          query=lambda a: format_number(self._axis(a)[1].rate_demand_dps))
        c(":READ:POSition", query=read("position_deg"))
        c(":READ:RATE", query=read("rate_dps"))
        c(":READ:ACCeleration", query=read("accel_dps2"))
        def limit_q(attr: str, hw_attr: str):
            def handler(args: Args) -> str:
                _, axis = self._axis(args)
                if args.count > 1:
                    word = args.keyword(1)
                    if word not in ("MIN", "MAX"):
                        raise ScpiError(-224, f"{args.raw[1]!r} not in MIN|MAX")
                    return format_number(1e-3 if word == "MIN" else getattr(axis, hw_attr))
                return format_number(getattr(axis, attr))
            return handler

        c(":LIMit:RATE", set=limit("rate_limit", "rate_max_dps"),
          query=limit_q("rate_limit_dps", "rate_max_dps"))
        c(":LIMit:ACCeleration", set=limit("accel_limit", "accel_max_dps2"),
          query=limit_q("accel_limit_dps2", "accel_max_dps2"))
        c(":STATus", query=lambda a: str(self.status_bits(self._axis(a)[1])))
        c(":STOP", set=lambda a: self._axis(a)[1].stop(now()))

        def il_open(args: Args) -> None:
            self.interlock_closed = False
            for axis in self.table.axes:  # drives disabled: everything coasts to rest
                axis.command_off(now())

        c(":INTerlock:OPEN", set=il_open)
        c(":INTerlock:CLOSe", set=lambda a: setattr(self, "interlock_closed", True))
        c(":INTerlock:RESet", set=lambda a: setattr(self, "tripped", False))
        c(":INTerlock", query=lambda a: "1" if self.interlock_closed and not self.tripped else "0")
