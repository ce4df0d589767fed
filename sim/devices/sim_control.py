"""The sim-control endpoint: what real instruments lack — simulated time and the seed.

The bench clock of a simulated station talks to it (see docs/ARCHITECTURE.md).
"""

from __future__ import annotations

from sim.scpi import Args, ScpiDevice, format_number
from sim.world import MAX_ADVANCE_S, World


class SimControl(ScpiDevice):
    def __init__(self, world: World, instrument_names: list[str]) -> None:
        super().__init__(("BENCHSIM", "WORLD", str(world.seed), "1.0"), options="0")
        self.world, self.names = world, instrument_names

        def advance(args: Args) -> None:
            self.world.advance(args.number(0, min=0.0, max=MAX_ADVANCE_S))

        def until(args: Args) -> None:
            self.world.advance_to(args.number(0, min=self.world.now,
                                              max=self.world.now + MAX_ADVANCE_S))

        self.command("SIMulation:TIME", query=lambda a: f"{self.world.now:.9f}")
        self.command("SIMulation:TIME:ADVance", set=advance)
        self.command("SIMulation:TIME:UNTil", set=until)
        self.command("SIMulation:SEED", query=lambda a: str(self.world.seed))
        self.command("SIMulation:INSTrument:LIST",
                     query=lambda a: ",".join(f'"{n}"' for n in self.names))
        self.command("SIMulation:LOG", query=lambda a: format_number(len(self.world.log)))
