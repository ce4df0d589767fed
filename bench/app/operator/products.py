"""The products an operator station tests, and the spec of a batch from its serials — with
the refusal in the operator's words (what to do at the station, never a command-line flag).

A station served with ``--spec FILE`` tests that spec's product (serials matching its
``serial_pattern``, any serial when it has none); otherwise every shipped spec with a serial
pattern.  The specs are read once, when the station starts: a broken one stops the start.
"""

from __future__ import annotations

from collections.abc import Mapping

from bench.core.spec import UnitSpec, load_spec
from bench.specs import builtin_specs
from procedures.catalogue import CATALOGUE

ASK = "Check the label, or ask the test engineer to add the product."


class Products:
    """The specs this station tests (``spec_path``'s alone, else the shipped ones chosen by
    serial pattern)."""

    def __init__(self, spec_path: str | None = None) -> None:
        if spec_path is not None:
            self.specs = [load_spec(spec_path, CATALOGUE)]
        else:
            self.specs = [s for s in (load_spec(p, CATALOGUE) for p in builtin_specs())
                          if s.serial_pattern]
        if not self.specs:
            raise ValueError("no shipped spec has a serial pattern: serve the station with a spec file")

    def known(self) -> str:
        """The products and their serial patterns, as the operator reads them."""
        return "; ".join(f"{s.model}: serials {s.serial_pattern}" if s.serial_pattern
                         else f"{s.model}: any serial" for s in self.specs)

    def spec_of(self, socket: int, serial: str) -> UnitSpec:
        """The spec testing ``serial``; ValueError saying what to do when none does."""
        for spec in self.specs:
            if spec.serial_pattern is None or spec.applies_to(serial):
                return spec
        raise ValueError(f"Serial {serial} (socket {socket}) matches no product this station "
                         f"tests ({self.known()}). {ASK}")

    def spec_for(self, sockets: Mapping[int, str]) -> UnitSpec:
        """The one spec of a batch: every socket's serial a unit of the same product;
        ValueError in the operator's words naming the socket that is not."""
        if not sockets:
            raise ValueError("Scan or type at least one serial.")
        specs = {n: self.spec_of(n, serial) for n, serial in sorted(sockets.items())}
        first, spec = next(iter(specs.items()))
        for n, other in specs.items():
            if other is not spec:
                raise ValueError(f"Socket {n} holds a {other.model} (serial {sockets[n]}) but "
                                 f"socket {first} a {spec.model}: test one product per batch — "
                                 f"take the unit out of socket {n} and test it in a batch of its own.")
        return spec


__all__ = ["Products", "ASK"]
