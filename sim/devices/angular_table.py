"""Simulated controller of an angular vibration table (SCPI over TCP).

The language is written down in docs/ARCHITECTURE.md ("Angular vibration table
language"); the motion is ``sim.physics.angular_table``, the reference capture
``sim.devices.angular_reference``.  Every command applies at ``world.now``.  The language
speaks degrees (°, °/s, °/s²); the physics radians.

Demands are *staged*: the oscillator table (``:OSC<n>:...``), the sweep settings and
``:SYNT:MODE`` only change what the next ``:STARt`` runs.  ``:STARt`` while IDLE ramps the
staged demand up; while RAMP or RUN it ramps the running demand down, then the staged one
up.  Errors go to the IEEE 488.2 queue: a value outside its range or a demand beyond the
table's limits is -222 naming the value and the allowed range; a command the present state
forbids (start while ABORT or with the interlock open, SINE with other than one enabled
oscillator, no oscillator enabled) is -221.

The interlock is the shaker's (``interlock_closed``; ``:INT:OPEN`` cuts the motion and
latches ABORT, ``:INT:RES`` clears it once at rest), so fault injection can treat both
alike: a power loss cuts the drive (:meth:`AngularTableController.power_off`), an interlock
fault opens the interlock (:meth:`AngularTableController.trip_interlock`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from sim.devices.angular_reference import (
    COUNT_RANGE,
    DEFAULT_REF_COUNT,
    DEFAULT_REF_RATE_HZ,
    ENCODER_COUNTS,
    RATE_NOISE_DPS,
    RATE_RANGE_HZ,
    ReferenceCapture,
)
from sim.devices.lifecycle import scpi_power_on
from sim.physics.angular_demand import SWEEP_TIME_RANGE_S, Sweep, Tone, describe
from sim.physics.angular_table import DEFAULT_RAMP_S, RAMP_RANGE_S, AngularMotion
from sim.scpi import Args, ScpiDevice, ScpiError, format_block, format_int, format_number

DEG = 180.0 / math.pi
#: SI units of the limit messages in the controller's degrees
TO_DEG = {"rad": ("deg", DEG), "rad/s": ("deg/s", DEG), "rad/s^2": ("deg/s^2", DEG)}
MODES = ("SINE", "MULTI", "SWEep")
PHASE_RANGE_DEG = (-360.0, 360.0)


def _exact(x: float) -> str:
    """A demand value as it was set (shortest round-trip text)."""
    return repr(float(x))


@dataclass
class Oscillator:
    magnitude_dps: float = 0.0
    freq_hz: float = 1.0
    phase_deg: float = 0.0
    enabled: bool = False


@dataclass
class SweepSettings:
    start_hz: float = 1.0
    stop_hz: float = 100.0
    time_s: float = 10.0
    spacing: str = "LOG"
    magnitude_dps: float = 10.0


class AngularTableController(ScpiDevice):
    fault_kinds: tuple[str, ...] = ("power", "interlock")

    def __init__(self, world, motion: AngularMotion, *, serial: str = "AVT-0001") -> None:
        super().__init__(("BENCHSIM", "ANGVIB-1", serial, "1.0"), options="0")
        self.world, self.motion = world, motion
        self.reference = ReferenceCapture(motion, world.rng(f"angular_table:{serial}:reference"))
        self.interlock_closed = True
        self._clear_demands()
        self._register()

    def _clear_demands(self) -> None:
        self.oscillators = [Oscillator() for _ in range(self.motion.limits.max_tones)]
        self.mode = "SINE"
        self.sweep = SweepSettings()

    def reset(self) -> None:
        # *RST: motion ramped down, demands cleared, default ramp, capture stopped and cleared
        self.motion.stop(self.world.now)
        self.motion.set_ramp(DEFAULT_RAMP_S)
        self._clear_demands()
        self.reference.clear()
        self.reference.set_rate(DEFAULT_REF_RATE_HZ)
        self.reference.set_count(DEFAULT_REF_COUNT)

    def open_interlock(self) -> None:
        """The interlock opens (``:INT:OPEN``, or a fault): a moving table is cut, ABORT latches."""
        self.interlock_closed = False
        if not self.motion.at_rest(self.world.now):
            self.motion.abort(self.world.now)
            self.world.note("angular table interlock open: drive cut")

    # -- lifecycle (sim.devices.lifecycle) ------------------------------------------------
    def power_off(self) -> None:
        """Power lost: the motion cut now, ABORT latched."""
        self.motion.abort(self.world.now)

    def power_on(self) -> None:
        scpi_power_on(self)

    def trip_interlock(self) -> None:
        """The interlock trips: the motion cut, ABORT latched until ``:INT:RES``."""
        self.open_interlock()

    # -- demands -------------------------------------------------------------------------
    def staged_tones(self) -> list[Tone]:
        return [Tone(o.magnitude_dps / DEG, o.freq_hz, o.phase_deg / DEG) for o in self.oscillators if o.enabled]

    def _limit_error(self, amps_rad_s, freqs_hz, what: str = "") -> None:
        problem = describe(self.motion.limits.excess(amps_rad_s, freqs_hz), self.motion.limits, TO_DEG)
        if problem:
            raise ScpiError(-222, what + problem)

    def _start(self) -> None:
        now, m = self.world.now, self.motion
        if not self.interlock_closed or m.aborted:
            raise ScpiError(-221, "interlock open or tripped: :INTerlock:CLOSe and :INTerlock:RESet first")
        if self.mode == "SWEEP":
            s = self.sweep
            if s.start_hz == s.stop_hz:
                raise ScpiError(-221, f"sweep start equals stop ({s.start_hz:g} Hz): use SINE for a dwell")
            for f in (s.start_hz, s.stop_hz):
                self._limit_error([s.magnitude_dps / DEG], [f], "sweep: ")
            m.start_sweep(now, Sweep(s.start_hz, s.stop_hz, s.time_s, s.magnitude_dps / DEG, s.spacing))
            self.world.note(f"angular table sweep {s.start_hz:g}..{s.stop_hz:g} Hz {s.spacing} "
                            f"over {s.time_s:g} s at {s.magnitude_dps:g} dps")
            return
        tones = self.staged_tones()
        n = len(tones)
        if n == 0:
            raise ScpiError(-221, "no oscillator enabled: :OSCillator<n>:STATe ON first")
        if self.mode == "SINE" and n != 1:
            raise ScpiError(-221, f"SINE runs exactly one oscillator, {n} enabled; use :SYNThesis:MODE MULTI")
        self._limit_error([t.rate_amplitude_rad_s for t in tones], [t.freq_hz for t in tones])
        m.start_tones(now, tones)
        self.world.note(f"angular table start {self.mode} {n} tone(s)")

    # -- vocabulary ----------------------------------------------------------------------
    def _register(self) -> None:
        c, lim = self.command, self.motion.limits
        n_osc = lim.max_tones
        rate_max_dps = lim.max_rate_rad_s * DEG
        now = lambda: self.world.now

        def osc(a: Args) -> Oscillator:
            return self.oscillators[a.suffixes[0] - 1]

        def osc_number(field: str, lo: float, hi: float, default: float):
            def set_(a: Args) -> None:
                a.require_count(1, 1)
                setattr(osc(a), field, a.number(0, min=lo, max=hi, default=default))
            return set_, (lambda a: _exact(getattr(osc(a), field)))

        for name, field, lo, hi, default in (("MAGNitude", "magnitude_dps", 0.0, rate_max_dps, 0.0),
                                             ("FREQuency", "freq_hz", lim.f_min_hz, lim.f_max_hz, 1.0),
                                             ("PHASe", "phase_deg", *PHASE_RANGE_DEG, 0.0)):
            set_, query = osc_number(field, lo, hi, default)
            c(f":OSCillator#:{name}", set=set_, query=query, max_suffix=n_osc)

        def osc_state(a: Args) -> None:
            a.require_count(1, 1)
            osc(a).enabled = a.boolean(0)

        c(":OSCillator#:STATe", set=osc_state, query=lambda a: "1" if osc(a).enabled else "0", max_suffix=n_osc)
        c(":OSCillator#:CLEar", set=lambda a: setattr(self, "oscillators", [Oscillator() for _ in range(n_osc)]),
          max_suffix=n_osc)

        def mode(a: Args) -> None:
            a.require_count(1, 1)
            self.mode = a.choice(0, list(MODES)).upper()

        c(":SYNThesis:MODE", set=mode, query=lambda a: self.mode)
        c(":SYNThesis:TONes", query=lambda a: format_int(sum(o.enabled for o in self.oscillators)))

        def sweep_number(field: str, lo: float, hi: float, default: float):
            def set_(a: Args) -> None:
                a.require_count(1, 1)
                setattr(self.sweep, field, a.number(0, min=lo, max=hi, default=default))
            return set_, (lambda a: _exact(getattr(self.sweep, field)))

        for name, field, lo, hi, default in (("STARt", "start_hz", lim.f_min_hz, lim.f_max_hz, 1.0),
                                             ("STOP", "stop_hz", lim.f_min_hz, lim.f_max_hz, 100.0),
                                             ("TIME", "time_s", *SWEEP_TIME_RANGE_S, 10.0),
                                             ("MAGNitude", "magnitude_dps", 0.0, rate_max_dps, 10.0)):
            set_, query = sweep_number(field, lo, hi, default)
            c(f":SWEep:{name}", set=set_, query=query)

        def spacing(a: Args) -> None:
            a.require_count(1, 1)
            self.sweep.spacing = a.choice(0, ["LINear", "LOGarithmic"])[:3].upper()

        c(":SWEep:SPACing", set=spacing, query=lambda a: self.sweep.spacing)
        c(":SWEep:INTerval", query=lambda a: format_number(self.motion.update_s))

        def ramp(a: Args) -> None:
            a.require_count(1, 1)
            self.motion.set_ramp(a.number(0, min=RAMP_RANGE_S[0], max=RAMP_RANGE_S[1], default=DEFAULT_RAMP_S))

        c(":RAMP[:TIME]", set=ramp, query=lambda a: format_number(self.motion.ramp_s))
        c(":STARt", set=lambda a: self._start())

        def stop(a: Args) -> None:
            self.motion.stop(now())
            self.world.note("angular table stop")

        def abort(a: Args) -> None:
            self.motion.abort(now())
            self.world.note("angular table abort")

        c(":STOP", set=stop)
        c(":ABORt", set=abort)
        c(":STATe", query=lambda a: self.motion.state(now()))


        def il_reset(a: Args) -> None:
            if not self.motion.aborted:
                return
            try:
                self.motion.reset_abort(now())
            except RuntimeError as exc:
                raise ScpiError(-221, str(exc)) from None

        c(":INTerlock:OPEN", set=lambda a: self.open_interlock())
        c(":INTerlock:CLOSe", set=lambda a: setattr(self, "interlock_closed", True))
        c(":INTerlock:RESet", set=il_reset)
        c(":INTerlock", query=lambda a: "1" if self.interlock_closed and not self.motion.aborted else "0")

        def limit_q(value: float) -> Callable[[Args], str]:
            return lambda a: _exact(value)  # in full: the driver checks demands against these

        c(":LIMit:ANGLe", query=limit_q(lim.max_angle_rad * DEG))
        c(":LIMit:RATE", query=limit_q(lim.max_rate_rad_s * DEG))
        c(":LIMit:ACCeleration", query=limit_q(lim.max_accel_rad_s2 * DEG))
        c(":LIMit:FREQuency", query=lambda a: f"{format_number(lim.f_min_hz)},{format_number(lim.f_max_hz)}")
        c(":LIMit:TONes", query=lambda a: format_int(lim.max_tones))
        c(":LIMit:DISTortion", query=lambda a: ",".join(format_number(d) for d in self.motion.distortion))
        self._register_reference()

    def _register_reference(self) -> None:
        c = self.command
        now = lambda: self.world.now

        def rate(a: Args) -> None:
            a.require_count(1, 1)
            self._ref_idle("rate")
            self.reference.set_rate(a.number(0, min=RATE_RANGE_HZ[0], max=RATE_RANGE_HZ[1],
                                             default=DEFAULT_REF_RATE_HZ))

        def count(a: Args) -> None:
            a.require_count(1, 1)
            self._ref_idle("count")
            self.reference.set_count(a.integer(0, min=COUNT_RANGE[0], max=COUNT_RANGE[1], default=DEFAULT_REF_COUNT))

        def remove(a: Args) -> bytes:
            a.require_count(1, 1)
            n = a.integer(0, min=1, max=self.reference.memory)
            return format_block(self.reference.remove(now(), n).astype("<f8").tobytes())

        c(":REFerence:RATE", set=rate, query=lambda a: format_number(self.reference.rate_hz))
        c(":REFerence:COUNt", set=count, query=lambda a: format_int(self.reference.count))
        c(":REFerence:INITiate", set=lambda a: self.reference.initiate(now()))
        c(":REFerence:ABORt", set=lambda a: self.reference.abort(now()))
        c(":REFerence:RUNNing", query=lambda a: "1" if self.reference.is_running(now()) else "0")
        c(":REFerence:POINts", query=lambda a: format_int(self.reference.points(now())))
        c(":REFerence:OVERflow", query=lambda a: "1" if self.reference.overflow else "0")
        c(":REFerence:DATA:REMove", query=remove)
        c(":REFerence:RESolution", query=lambda a: format_number(360.0 / ENCODER_COUNTS))
        c(":REFerence:NOISe", query=lambda a: format_number(RATE_NOISE_DPS))

    def _ref_idle(self, what: str) -> None:
        if self.reference.is_running(self.world.now):
            raise ScpiError(-221, f"reference {what} change refused while capturing; :REFerence:ABORt first")


__all__ = ["AngularTableController", "Oscillator", "SweepSettings"]
