"""Shared IEEE 488.2 / SCPI-1999 engine for the simulated instruments.

Typical use::

    dev = ScpiDevice(("Keysight Technologies", "34465A", "SIM0001", "A.03.01"))
    dev.command("[SENSe:]VOLTage[:DC]:NPLCycles",
                set=lambda a: setattr(state, "nplc", a.number(0, min=0.001, max=100, default=10)),
                query=lambda a: format_number(state.nplc))
    reply = dev.feed(b"VOLT:NPLC 1;NPLC?\\n")   # -> b"+1.00000000E+00\\n"

See :mod:`sim.scpi.engine` for the path rules and status model, :mod:`sim.scpi.params`
for parameter parsing and :mod:`sim.scpi.framing` for stream framing.
"""

from .engine import ScpiDevice
from .errors import ERROR_MESSAGES, ScpiError, error_text, format_error_entry
from .formatting import format_block, format_bool, format_int, format_number, format_numbers, format_string
from .framing import MessageFramer, Oversize
from .params import Args
from .session import Session

__all__ = [
    "ScpiDevice", "Session", "ScpiError", "Args", "MessageFramer", "Oversize",
    "ERROR_MESSAGES", "error_text", "format_error_entry",
    "format_block", "format_number", "format_numbers", "format_int", "format_bool",
    "format_string",
]
