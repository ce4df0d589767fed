"""IEEE 488.2 common commands and the SCPI-mandated SYSTem commands, as a mixin.

:class:`sim.scpi.engine.ScpiDevice` inherits these. A device customises behaviour by
overriding the hooks (:meth:`reset`, :meth:`wait_complete`, :meth:`trigger`,
:meth:`self_test`, :meth:`device_status_bits`, :meth:`clear_status`) or by registering
the same pattern again (e.g. ``*TST``), which replaces the built-in handler.

Responses follow Keysight practice: registers as signed NR1 (``*ESR?`` -> ``+32``),
``*OPC?`` -> ``1``, ``SYSTem:VERSion?`` -> ``1999.0``. ``*OPC`` sets ESR bit 0 once
:meth:`wait_complete` returns (operations are synchronous in the simulation), ``*SRE``
ignores bit 6 (IEEE 488.2 §11.3.2.3), ``*ESR?`` clears the ESR it reports.
``SYSTem:ERRor:ALL?`` (SCPI-1999 §21.8.5) returns and clears every entry.
The error queue, ESR, ESE and SRE these commands read and write are those of the session
whose message is being processed (``session``; see :mod:`sim.scpi.engine`).
"""

from __future__ import annotations

from abc import abstractmethod
from collections.abc import Callable

from .errors import ScpiError, format_error_entry
from .formatting import format_int
from .params import Args
from .session import Session

__all__ = ["CommonCommands"]


class CommonCommands:
    """``*IDN? *RST *CLS *ESR? *ESE[?] *SRE[?] *STB? *OPC[?] *WAI *TRG *TST? *OPT?`` and
    ``SYSTem:ERRor[:NEXT]? / :COUNt? / :ALL?``, ``SYSTem:VERSion?``.

    Expects the host class to provide ``command``, ``idn``, ``options``, ``esr``,
    ``ese``, ``sre``, ``stb``, ``errors``, ``session`` and ``pop_error`` (declared below).
    """

    idn: tuple[str, ...]
    options: str
    esr: int
    ese: int
    sre: int

    @abstractmethod
    def command(self, pattern: str, *, set: Callable[[Args], None] | None = None,
                query: Callable[[Args], str | bytes] | None = None,
                max_suffix: int | tuple[int | None, ...] | None = None) -> None:
        """Register handlers for a SCPI pattern."""

    @abstractmethod
    def pop_error(self) -> str:
        """Oldest error entry, removed from the queue."""

    @property
    @abstractmethod
    def stb(self) -> int:
        """Status byte."""

    @property
    @abstractmethod
    def errors(self) -> list[str]:
        """Queued error entries, oldest first."""

    @property
    @abstractmethod
    def session(self) -> Session:
        """The session whose message is being processed (else the default one)."""

    def _register_builtins(self) -> None:
        c = self.command
        c("*IDN", query=self._q_idn)
        c("*RST", set=self._c_rst)
        c("*CLS", set=self._c_cls)
        c("*ESR", query=self._q_esr)
        c("*ESE", set=self._c_ese, query=lambda a: self._q_reg(a, self.ese))
        c("*SRE", set=self._c_sre, query=lambda a: self._q_reg(a, self.sre))
        c("*STB", query=lambda a: self._q_reg(a, self.stb))
        c("*OPC", set=self._c_opc, query=self._q_opc)
        c("*WAI", set=self._c_wai)
        c("*TRG", set=self._c_trg)
        c("*TST", query=self._q_tst)
        c("*OPT", query=self._q_opt)
        c("SYSTem:ERRor[:NEXT]", query=self._q_err)
        c("SYSTem:ERRor:COUNt", query=lambda a: self._q_reg(a, self.session.count))
        c("SYSTem:ERRor:ALL", query=self._q_err_all)
        c("SYSTem:VERSion", query=self._q_version)

    # -- hooks a device overrides -----------------------------------------------------
    def reset(self) -> None:
        """Device part of ``*RST``: return settings to their reset values."""

    def wait_complete(self) -> None:
        """Block until pending operations are done (``*OPC``, ``*OPC?``, ``*WAI``)."""

    def trigger(self) -> None:
        """``*TRG``; the default device is not waiting for a bus trigger."""
        raise ScpiError(-211, "no trigger armed for BUS")

    def self_test(self) -> int:
        """``*TST?`` result: 0 = passed."""
        return 0

    def device_status_bits(self) -> int:
        """STB bits 0, 1, 3 and 7 (e.g. QUES/OPER summaries); 0 by default."""
        return 0

    def clear_status(self) -> None:
        """``*CLS``: clear this session's error queue and event status register (a device
        with shared event registers, e.g. SCPI QUES/OPER, clears those too)."""
        self.session.clear_status()

    # -- built-in handlers ---------------------------------------------------------------
    def _q_idn(self, a: Args) -> str:
        a.require_count(0)
        return ",".join(self.idn)

    def _c_rst(self, a: Args) -> None:
        a.require_count(0)
        self.reset()

    def _c_cls(self, a: Args) -> None:
        a.require_count(0)
        self.clear_status()

    def _q_esr(self, a: Args) -> str:
        a.require_count(0)
        value, self.esr = self.esr, 0
        return format_int(value)

    def _q_reg(self, a: Args, value: int) -> str:
        a.require_count(0)
        return format_int(value)

    def _c_ese(self, a: Args) -> None:
        a.require_count(1)
        self.ese = a.integer(0, min=0, max=255)

    def _c_sre(self, a: Args) -> None:
        a.require_count(1)
        self.sre = a.integer(0, min=0, max=255) & ~0x40  # bit 6 cannot be enabled

    def _c_opc(self, a: Args) -> None:
        a.require_count(0)
        self.wait_complete()
        self.esr |= 0x01

    def _q_opc(self, a: Args) -> str:
        a.require_count(0)
        self.wait_complete()
        return "1"

    def _c_wai(self, a: Args) -> None:
        a.require_count(0)
        self.wait_complete()

    def _c_trg(self, a: Args) -> None:
        a.require_count(0)
        self.trigger()

    def _q_tst(self, a: Args) -> str:
        a.require_count(0)
        return format_int(self.self_test())

    def _q_opt(self, a: Args) -> str:
        a.require_count(0)
        return self.options

    def _q_err(self, a: Args) -> str:
        a.require_count(0)
        return self.pop_error()

    def _q_err_all(self, a: Args) -> str:
        a.require_count(0)
        entries = self.errors or [format_error_entry(0)]
        self.session.clear_errors()
        return ",".join(entries)

    def _q_version(self, a: Args) -> str:
        a.require_count(0)
        return "1999.0"
