"""The sim-control endpoint: what real instruments lack — simulated time, the seed, faults.

The bench clock of a simulated station talks to it (see docs/ARCHITECTURE.md).
"""

from __future__ import annotations

from collections.abc import Callable

from sim.faults import FaultInjector, FaultTargetError
from sim.scpi import Args, ScpiDevice, ScpiError, format_number
from sim.world import MAX_ADVANCE_S, World


class SimControl(ScpiDevice):
    def __init__(self, world: World, instrument_names: list[str],
                 faults: FaultInjector | None = None) -> None:
        super().__init__(("BENCHSIM", "WORLD", str(world.seed), "1.0"), options="0")
        self.world, self.names = world, instrument_names

        def advance(args: Args) -> None:
            self.world.advance(args.number(0, min=0.0, max=MAX_ADVANCE_S))

        def until(args: Args) -> None:
            # paced, the clock runs on by itself: a time it has passed is nothing left to wait for
            earliest = self.world.now if self.world.pace is None else 0.0
            t_s = args.number(0, min=earliest, max=self.world.now + MAX_ADVANCE_S)
            self.world.advance_to(max(t_s, self.world.now))

        self.command("SIMulation:TIME", query=lambda a: f"{self.world.now:.9f}")
        self.command("SIMulation:TIME:ADVance", set=advance)
        self.command("SIMulation:TIME:UNTil", set=until)
        self.command("SIMulation:SEED", query=lambda a: str(self.world.seed))
        self.command("SIMulation:INSTrument:LIST",
                     query=lambda a: ",".join(f'"{n}"' for n in self.names))
        self.command("SIMulation:LOG", query=lambda a: format_number(len(self.world.log)))
        if faults is not None:
            register_fault_commands(self, faults)


def register_fault_commands(device: ScpiDevice, injector: FaultInjector) -> None:
    """``SIMulation:FAULt:<kind> "<instrument>",<args>``, ``:CLEar``, ``SIMulation:FAULt?``
    on the sim-control endpoint (docs/ARCHITECTURE.md).  Bad values: -222 naming the range;
    an unknown instrument or a kind it does not have: -224 naming the allowed ones."""
    layouts = {"DROP": ("drop", ("refuse_s",)), "STALl": ("stall", ("duration_s",)),
               "SLOW": ("slow", ("delay_ms",)), "GARBle": ("garble", ("probability",)),
               "ERRor": ("error", ("count", "code")), "FRAMe": ("frame", ("corrupt", "loss")),
               "POWer": ("power", ()), "INTerlock": ("interlock", ()),
               "OVERload": ("overload", ("volts",)), "LIMit": ("limit", ()), "ALARm": ("alarm", ())}

    def handler(kind: str, names: tuple[str, ...]) -> Callable[[Args], None]:
        def apply(args: Args) -> None:
            args.require_count(1, 1 + len(names))
            params = {n: args.number(i + 1, min=None, max=None)
                      for i, n in enumerate(names) if i + 1 < args.count}
            try:
                action = injector.prepare(kind, args.string(0), params)
            except ValueError as exc:
                raise ScpiError(-224 if isinstance(exc, FaultTargetError) else -222,
                                str(exc)) from None
            action()
        return apply

    for header, (kind, names) in layouts.items():
        device.command(f"SIMulation:FAULt:{header}", set=handler(kind, names))

    def clear(args: Args) -> None:
        args.require_count(1, 1)
        target = args.raw[0].strip().strip('"').strip("'")
        try:
            action = injector.prepare_clear(target)
        except ValueError as exc:
            raise ScpiError(-224, f"{exc} (or ALL)") from None
        action()

    def query(args: Args) -> str:
        entries = [f'"{name}:{kind.upper()}"' for name, kinds in injector.active().items()
                   for kind in kinds]
        return ",".join(entries) if entries else '""'

    device.command("SIMulation:FAULt:CLEar", set=clear)
    device.command("SIMulation:FAULt", query=query)
