"""The person at the station, as a run sees them: a prompt answered Continue or Abort.

A procedure asks through its context (``Context.ask``): "mount the units", "close the
fixture's cover".  Who answers is the application's business — the operator page (its
prompt box), a terminal (``bench acceptance`` on a console), or nobody (:class:`Unattended`:
a script, CI, a simulated station) — so every runner takes an :class:`Operator`.  The
prompt and its answer go into the run record as events; Abort raises :class:`OperatorAbort`,
which the runners treat as an interrupt: the teardown leaves the station safe and every
record says why it stopped.
"""

from __future__ import annotations

from typing import Protocol

#: longest prompt text a spec may give (a line on the operator's screen)
MAX_PROMPT_CHARS = 200


class OperatorAbort(KeyboardInterrupt):
    """The operator chose Abort: the runner's interrupt path (teardown: station safe); its
    message is the reason every record keeps."""


class Operator(Protocol):
    """Whoever answers the station's prompts; ``name`` is who the record says answered."""

    @property
    def name(self) -> str:
        """Who answers (an operator's name, ``terminal``, ``unattended``)."""
        ...

    def ask(self, text: str) -> bool:
        """Show ``text`` and wait: True on Continue, False on Abort."""
        ...


class Unattended:
    """Nobody to ask: every prompt is answered Continue (the record says it was unattended)."""

    name = "unattended"

    def ask(self, text: str) -> bool:
        return True


def check_prompt(text: object, where: str) -> str:
    """A prompt's text checked: ValueError naming it unless 1..MAX_PROMPT_CHARS printable."""
    if not isinstance(text, str) or not text.strip():
        raise ValueError(f"{where}: prompt text {text!r} must be non-empty text")
    if len(text) > MAX_PROMPT_CHARS or not text.isprintable():
        raise ValueError(f"{where}: prompt text must be 1..{MAX_PROMPT_CHARS} printable characters "
                         f"on one line, got {len(text)}")
    return text.strip()


__all__ = ["Operator", "OperatorAbort", "Unattended", "check_prompt", "MAX_PROMPT_CHARS"]
