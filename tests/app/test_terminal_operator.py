"""The operator at a console (``bench acceptance`` on a terminal): a spec's prompt on stderr,
Enter continues, ``a`` aborts, and end of input (nobody there) aborts."""

from __future__ import annotations

import io

from bench.app.commands.common import TerminalOperator


def test_a_console_operator_continues_on_enter_and_aborts_on_a_or_end_of_input(monkeypatch, capsys):
    for typed, expected in (("\n", True), ("c\n", True), ("a\n", False), ("Abort\n", False), ("", False)):
        monkeypatch.setattr("sys.stdin", io.StringIO(typed))
        assert TerminalOperator().ask("Close the cover") is expected
        assert "Close the cover" in capsys.readouterr().err
