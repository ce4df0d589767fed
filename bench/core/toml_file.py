"""Reading a configuration file (a station, a unit spec, the operator station's users): its
TOML table, or an error naming the file and what is wrong with it."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any


def read_toml(path: str | Path, what: str, error: type[Exception] = ValueError,
              hint: str = "") -> dict[str, Any]:
    """The TOML table of the file at ``path``; ``error`` naming it (``what``: "spec file")
    when it is missing (``hint`` appended: how to make one) or is not UTF-8 TOML."""
    path = Path(path)
    if not path.is_file():
        raise error(f"{what} {str(path)!r} not found{hint}")
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise error(f"{what} {str(path)!r} is not valid TOML: {exc}") from None


__all__ = ["read_toml"]
