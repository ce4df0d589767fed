"""Unit specs shipped with the bench (TOML): one per simulated sensor model.

``builtin_specs()`` lists them; ``bench acceptance --unit SN`` uses the one whose
``serial_pattern`` matches (``bench.app.session.choose_spec``).
"""

from __future__ import annotations

from pathlib import Path

HERE = Path(__file__).resolve().parent


def builtin_specs() -> list[Path]:
    """The shipped spec files, by name."""
    return sorted(HERE.glob("*.toml"))
