"""What the shaker controller and the angular vibration table share: ``:STAR``, ``:STOP``,
``:ABOR``, the interlock commands, a ``:STAT?`` of IDLE | RAMP | RUN | ABORT, and waiting
for RUN or IDLE on the bench clock (never sleeping) — :func:`poll_until`, the polling loop the
turntable's axes wait with too."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

from .base import SCPIInstrument
from .protocols import SafeOrder, Wait
from .validate import in_range

T = TypeVar("T")


class Interlocked(SCPIInstrument):
    """Base of a driver of a controller with a safety interlock (``:INT:OPEN|CLOS|RES``):
    the turntable, the shaker, the angular vibration table."""

    def interlock_close(self) -> None:
        """``:INT:CLOS``: close the interlock (drives enabled)."""
        self.configure_command(":INT:CLOS")

    def interlock_open(self) -> None:
        """``:INT:OPEN``: open the interlock (drives cut)."""
        self.configure_command(":INT:OPEN")

    def interlock_reset(self) -> None:
        """``:INT:RES``: clear a latched trip (ABORT) once at rest."""
        self.configure_command(":INT:RES")


class RampedController(Interlocked):
    """Base of a driver with a ``state`` setting (IDLE, RAMP, RUN, ABORT), declared by the
    driver; ``aborted_error`` is the exception raised when the controller reports ABORT.
    Made safe by ``:STOP`` (ramped down to rest)."""

    aborted_error: type[Exception] = RuntimeError
    #: ``:STAT?``: IDLE, RAMP, RUN or ABORT (a ``measurement`` of the driver)
    state: Any
    safe_order = SafeOrder.MOTION
    safe_action = "stop"

    def make_safe(self) -> None:
        """``:STOP``: ramp down to rest (sent again over a reopened connection if lost)."""
        self.stop()

    def start(self) -> None:
        """``:STAR``: ramp the demand up and run (while running: the old one down first)."""
        self.configure_command(":STAR")

    def stop(self) -> None:
        """``:STOP``: ramp down to rest (does not wait)."""
        self.configure_command(":STOP")

    def abort(self) -> None:
        """``:ABOR``: cut the drive now; the controller latches ABORT."""
        self.configure_command(":ABOR")

    def wait_running(self, wait: Wait, timeout_s: float, poll_s: float = 0.1) -> str:
        """Poll ``:STAT?`` until RUN; :attr:`aborted_error` on ABORT, RuntimeError on IDLE
        (nothing is starting), TimeoutError after ``timeout_s``."""
        return self._wait_for("RUN", wait, timeout_s, poll_s)

    def wait_idle(self, wait: Wait, timeout_s: float, poll_s: float = 0.1) -> str:
        """Poll ``:STAT?`` until IDLE (ramp-down finished); otherwise as :meth:`wait_running`."""
        return self._wait_for("IDLE", wait, timeout_s, poll_s)

    def _wait_for(self, goal: str, wait: Wait, timeout_s: float, poll_s: float) -> str:
        def reached(state: str) -> bool:
            if state == goal:
                return True
            if state == "ABORT":
                raise self.aborted_error(f"{self.name}: ABORT while waiting for {goal}")
            if goal == "RUN" and state == "IDLE":
                raise RuntimeError(f"{self.name}: IDLE while waiting for RUN (not started?)")
            return False

        return poll_until(lambda: self.state, reached, wait, timeout_s, poll_s,
                          lambda state, waited: f"{self.name}: not {goal} after {waited:g} s (state {state})")


def poll_until(read: Callable[[], T], reached: Callable[[T], bool], wait: Wait, timeout_s: float,
               poll_s: float, timed_out: Callable[[T, float], str]) -> T:
    """Read until ``reached(value)`` (which may raise on a fault), letting ``poll_s`` of bench
    time pass between reads through ``wait``; ``TimeoutError(timed_out(value, waited_s))``
    once ``timeout_s`` has passed. The shared loop of every driver's wait-for-state."""
    timeout = in_range("timeout_s", timeout_s, (0.0, float("inf")))
    poll = in_range("poll_s", poll_s, (1e-6, float("inf")))
    if not callable(wait):
        raise ValueError(f"wait={wait!r} is not callable; pass the bench clock's wait")
    waited = 0.0
    while True:
        value = read()
        if reached(value):
            return value
        remaining = timeout - waited
        if remaining <= 1e-9:  # tolerance: summed float steps fall just short of timeout
            raise TimeoutError(timed_out(value, waited))
        step = min(poll, remaining)
        wait(step)
        waited += step
