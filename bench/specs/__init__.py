"""Unit specs shipped with the bench (TOML): one per simulated sensor model.

``builtin_specs()`` lists them; ``spec_for_serial(serial)`` picks the one whose
``serial_pattern`` matches.
"""

from __future__ import annotations

from pathlib import Path

HERE = Path(__file__).resolve().parent


def builtin_specs() -> list[Path]:
    return sorted(HERE.glob("*.toml"))
