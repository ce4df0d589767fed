"""Simulated random-vibration controller driving an electrodynamic shaker (SCPI over TCP).

The language is written down in docs/ARCHITECTURE.md ("Vibration controller language");
the physics (profiles, limits, envelope, control signal) is ``sim.physics.shaker``.  Every
command applies at ``world.now``.  Errors go to the IEEE 488.2 queue: a value outside its
range or a profile beyond the shaker's limits is -222 naming the value and the allowed
range; a command the present state forbids is -221.

The station has one fixture position (the turntable platform): ``table_at_rest(t)``
tells whether the table is still, and ``:STARt`` is refused (-221) while it moves.
"""

from __future__ import annotations

from collections.abc import Callable

from sim.devices.lifecycle import scpi_power_on
from sim.physics.shaker import DEFAULT_RAMP_S, LEVEL_RANGE_DB, RAMP_RANGE_S, Shaker
from sim.physics.shaker_profile import MAX_BREAKPOINTS, RandomProfile, SineProfile
from sim.scpi import Args, ScpiDevice, ScpiError, format_number

#: averaging time of the control level readback (s)
CONTROL_WINDOW_S = 1.0


def _exact(x: float) -> str:
    """A profile value as it was set (shortest round-trip text, not NR3's 9 digits)."""
    return repr(float(x))


class ShakerController(ScpiDevice):
    fault_kinds: tuple[str, ...] = ("power",)

    def __init__(self, world, shaker: Shaker, *, serial: str = "VC-0001",
                 table_at_rest: Callable[[float], bool] | None = None) -> None:
        super().__init__(("BENCHSIM", "VIBCTRL-1", serial, "1.0"), options="0")
        self.world, self.shaker = world, shaker
        self.table_at_rest = table_at_rest
        self.interlock_closed = True
        self._register()

    def reset(self) -> None:
        # *RST: drive stopped (ramped down), level 0 dB, default ramp; the profile is kept
        now = self.world.now
        self.shaker.stop(now)
        self.shaker.set_ramp(DEFAULT_RAMP_S)
        try:
            self.shaker.set_level(now, 0.0)  # not driving any more: only the setting changes
        except ValueError:  # the profile at 0 dB exceeds a limit: keep the level
            pass

    # -- lifecycle (sim.devices.lifecycle) ------------------------------------------------
    def power_off(self) -> None:
        """Power lost: the drive cut now (ABORT latched)."""
        self.shaker.abort(self.world.now)

    def power_on(self) -> None:
        scpi_power_on(self)

    # -- helpers -------------------------------------------------------------------------
    def _profile(self, profile_fn) -> None:
        now = self.world.now
        try:
            profile = profile_fn()
        except ValueError as exc:
            raise ScpiError(-222, str(exc)) from None
        state = self.shaker.state(now)
        if state != "IDLE":
            raise ScpiError(-221, f"profile change refused while {state}; "
                                  f"{':STOP' if state != 'ABORT' else ':INTerlock:RESet'} first")
        try:
            self.shaker.set_profile(now, profile)
        except ValueError as exc:
            raise ScpiError(-222, str(exc)) from None

    def _register(self) -> None:
        c, lim = self.command, self.shaker.limits

        def random(args: Args) -> None:
            n = args.count
            if n < 4 or n % 2 or n > 2 * MAX_BREAKPOINTS:
                raise ScpiError(-109 if n < 4 else -108,
                                f"RANDom takes 2..{MAX_BREAKPOINTS} pairs <Hz>,<g2/Hz>, got {n} values")
            values = [args.number(i, min=None, max=None) for i in range(n)]
            freqs, psd = values[0::2], values[1::2]
            for f in freqs:
                if not lim.f_min_hz <= f <= lim.f_max_hz:
                    raise ScpiError(-222, f"frequency {f:g} Hz not in {lim.f_min_hz:g}..{lim.f_max_hz:g} Hz")
            for p in psd:
                if not 0 < p <= lim.max_psd_g2hz:
                    raise ScpiError(-222, f"ASD {p:g} g2/Hz not in (0, {lim.max_psd_g2hz:g}] g2/Hz")
            self._profile(lambda: RandomProfile(tuple(freqs), tuple(psd)))

        def flat(args: Args) -> None:
            args.require_count(3, 3)
            psd = args.number(0, min=1e-9, max=lim.max_psd_g2hz)
            f_lo = args.number(1, min=lim.f_min_hz, max=lim.f_max_hz)
            f_hi = args.number(2, min=lim.f_min_hz, max=lim.f_max_hz)
            if not f_hi > f_lo:
                raise ScpiError(-222, f"upper frequency {f_hi:g} Hz not in ({f_lo:g}, {lim.f_max_hz:g}] Hz")
            self._profile(lambda: RandomProfile.flat(psd, f_lo, f_hi))

        def sine(args: Args) -> None:
            args.require_count(2, 2)
            f = args.number(0, min=lim.f_min_hz, max=lim.f_max_hz)
            g = args.number(1, min=1e-6, max=lim.max_sine_peak_g)
            self._profile(lambda: SineProfile(f, g))

        def profile_q(args: Args) -> str:
            p = self.shaker.profile
            if p is None:
                return "NONE"
            if isinstance(p, SineProfile):
                return f"SINE,{_exact(p.freq_hz)},{_exact(p.peak_g)}"
            pairs = (f"{_exact(f)},{_exact(g)}" for f, g in zip(p.freqs_hz, p.psd_g2hz))
            return "RAND," + ",".join(pairs)

        def level(args: Args) -> None:
            args.require_count(1, 1)
            lo, hi = LEVEL_RANGE_DB
            db = args.number(0, min=lo, max=hi, default=0.0)
            if self.shaker.aborted:
                raise ScpiError(-221, "level change refused while ABORT; :INTerlock:RESet first")
            try:
                self.shaker.set_level(self.world.now, db)
            except ValueError as exc:
                raise ScpiError(-222, str(exc)) from None

        def ramp(args: Args) -> None:
            args.require_count(1, 1)
            lo, hi = RAMP_RANGE_S
            self.shaker.set_ramp(args.number(0, min=lo, max=hi, default=DEFAULT_RAMP_S))

        def start(args: Args) -> None:
            now, sh = self.world.now, self.shaker
            if not self.interlock_closed or sh.aborted:
                raise ScpiError(-221, "interlock open or tripped: :INTerlock:CLOSe and :INTerlock:RESet first")
            if sh.profile is None:
                raise ScpiError(-221, "no profile: :PROFile:RANDom or :PROFile:SINE first")
            if self.table_at_rest is not None and not self.table_at_rest(now):
                raise ScpiError(-221, "turntable moving: the fixture must be at rest to shake")
            problem = sh.limits.violation(sh.profile, sh.level_db)
            if problem:
                raise ScpiError(-222, problem)
            sh.start(now)
            self.world.note(f"shaker start {sh.target_grms():.4g} g rms")

        def stop(args: Args) -> None:
            self.shaker.stop(self.world.now)
            self.world.note("shaker stop")

        def abort(args: Args) -> None:
            self.shaker.abort(self.world.now)
            self.world.note("shaker abort")

        def il_open(args: Args) -> None:
            self.interlock_closed = False
            if self.shaker.driving or self.shaker.envelope_grms(self.world.now) > 0:
                self.shaker.abort(self.world.now)  # an opened interlock cuts the drive
                self.world.note("shaker interlock open: drive cut")

        def il_reset(args: Args) -> None:
            if not self.shaker.aborted:
                return
            try:
                self.shaker.reset_abort(self.world.now)
            except RuntimeError as exc:
                raise ScpiError(-221, str(exc)) from None

        def limit_q(value: float) -> Callable[[Args], str]:
            return lambda a: format_number(value)

        now = lambda: self.world.now
        c(":PROFile:RANDom", set=random)
        c(":PROFile:RANDom:FLAT", set=flat)
        c(":PROFile:SINE", set=sine)
        c(":PROFile", query=profile_q)
        c(":PROFile:GRMS", query=lambda a: format_number(
            0.0 if self.shaker.profile is None else self.shaker.profile.grms))
        c(":LEVel", set=level, query=lambda a: format_number(self.shaker.level_db))
        c(":RAMP[:TIME]", set=ramp, query=lambda a: format_number(self.shaker.ramp_s))
        c(":STARt", set=start)
        c(":STOP", set=stop)
        c(":ABORt", set=abort)
        c(":STATe", query=lambda a: self.shaker.state(now()))
        c(":READ:GRMS", query=lambda a: format_number(
            self.shaker.measured_grms(now(), CONTROL_WINDOW_S)))
        c(":TARGet:GRMS", query=lambda a: format_number(self.shaker.target_grms()))
        c(":AXIS", query=lambda a: ",".join(format_number(float(x)) for x in self.shaker.axis_platform))
        c(":LIMit:GRMS", query=limit_q(lim.max_grms))
        c(":LIMit:SINE", query=limit_q(lim.max_sine_peak_g))
        c(":LIMit:VELocity", query=limit_q(lim.max_velocity_mps))
        c(":LIMit:DISPlacement", query=limit_q(lim.max_displacement_m))
        c(":LIMit:FREQuency", query=lambda a: f"{format_number(lim.f_min_hz)},{format_number(lim.f_max_hz)}")
        c(":INTerlock:OPEN", set=il_open)
        c(":INTerlock:CLOSe", set=lambda a: setattr(self, "interlock_closed", True))
        c(":INTerlock:RESet", set=il_reset)
        c(":INTerlock", query=lambda a: "1" if self.interlock_closed and not self.shaker.aborted else "0")
