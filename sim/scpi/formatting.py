"""Response formatting in the style of Keysight instruments (IEEE 488.2 §8.7).

* reals (NR3): ``+1.00000000E+00`` — sign, one digit, 8 decimals, signed exponent;
* integers (NR1): ``+100``;
* booleans: ``1`` / ``0``;
* strings: ``"text"`` with embedded double quotes doubled;
* definite-length arbitrary blocks: ``#<n><len><payload>``.

Non-finite reals use the SCPI-1999 §7.2.1.5 sentinels: +INF = 9.9E37, -INF = -9.9E37,
NaN = 9.91E37.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

__all__ = ["format_block", "format_number", "format_int", "format_bool",
           "format_string", "format_numbers", "SCPI_INF", "SCPI_NINF", "SCPI_NAN"]

SCPI_INF = 9.9e37
SCPI_NINF = -9.9e37
SCPI_NAN = 9.91e37

#: Largest payload a definite-length block header can describe (9 length digits).
MAX_BLOCK_BYTES = 10**9 - 1


def format_block(payload: bytes) -> bytes:
    """Definite-length arbitrary block ``#<n><len><payload>`` (IEEE 488.2 §8.7.9).

    Raises:
        ValueError: if the payload is longer than 999 999 999 bytes.
    """
    payload = bytes(payload)
    size = len(payload)
    if size > MAX_BLOCK_BYTES:
        raise ValueError(f"block payload of {size} bytes exceeds the {MAX_BLOCK_BYTES}-byte maximum")
    digits = str(size)
    return b"#" + str(len(digits)).encode("ascii") + digits.encode("ascii") + payload


def format_number(x: float) -> str:
    """NR3 real with an 8-decimal mantissa: ``1`` -> ``+1.00000000E+00``."""
    x = float(x)
    if math.isnan(x):
        x = SCPI_NAN
    elif math.isinf(x):
        x = SCPI_INF if x > 0 else SCPI_NINF
    return f"{x:+.8E}"


def format_int(n: int) -> str:
    """NR1 integer with explicit sign: ``100`` -> ``+100``."""
    return f"{int(n):+d}"


def format_bool(b: bool) -> str:
    """Boolean response: ``1`` or ``0``."""
    return "1" if b else "0"


def format_string(s: str) -> str:
    """String response data ``"..."`` with internal double quotes doubled."""
    return '"' + str(s).replace('"', '""') + '"'


def format_numbers(values: Iterable[float]) -> str:
    """Comma-separated NR3 reals, as a DMM returns a reading list."""
    return ",".join(format_number(v) for v in values)
