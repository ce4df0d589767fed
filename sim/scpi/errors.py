"""SCPI error numbers, their standard texts, and how they map onto the IEEE 488.2 ESR.

Error numbers follow SCPI-1999 Vol. 2 §21.8 (which re-uses IEEE 488.2 §11.5.1):

* ``-1xx`` command errors (parser)            → ESR bit 5, CME
* ``-2xx`` execution errors                   → ESR bit 4, EXE
* ``-3xx`` and positive device-specific codes → ESR bit 3, DDE
* ``-4xx`` query errors                       → ESR bit 2, QYE
* ``-5xx``/``-6xx``/``-7xx``/``-8xx`` events  → PON / URQ / RQC / OPC

An error-queue entry reads ``<code>,"<text>[;<detail>]"``, e.g.
``-222,"Data out of range;NPLC 7 not in 0.001..100"``; the code is written with an
explicit sign (``+0,"No error"``) as Keysight instruments do.
"""

from __future__ import annotations

__all__ = [
    "ERROR_MESSAGES",
    "ScpiError",
    "error_text",
    "esr_bit_for",
    "format_error_entry",
    "MAX_ERROR_ENTRY_CHARS",
]

#: Standard texts (SCPI-1999 Vol. 2 §21.8.9-21.8.13).
ERROR_MESSAGES: dict[int, str] = {
    0: "No error",
    -100: "Command error",
    -101: "Invalid character",
    -102: "Syntax error",
    -103: "Invalid separator",
    -104: "Data type error",
    -105: "GET not allowed",
    -108: "Parameter not allowed",
    -109: "Missing parameter",
    -110: "Command header error",
    -111: "Header separator error",
    -112: "Program mnemonic too long",
    -113: "Undefined header",
    -114: "Header suffix out of range",
    -120: "Numeric data error",
    -121: "Invalid character in number",
    -123: "Exponent too large",
    -124: "Too many digits",
    -128: "Numeric data not allowed",
    -130: "Suffix error",
    -131: "Invalid suffix",
    -134: "Suffix too long",
    -138: "Suffix not allowed",
    -140: "Character data error",
    -141: "Invalid character data",
    -144: "Character data too long",
    -148: "Character data not allowed",
    -150: "String data error",
    -151: "Invalid string data",
    -158: "String data not allowed",
    -160: "Block data error",
    -161: "Invalid block data",
    -168: "Block data not allowed",
    -170: "Expression error",
    -171: "Invalid expression",
    -178: "Expression data not allowed",
    -200: "Execution error",
    -210: "Trigger error",
    -211: "Trigger ignored",
    -212: "Arm ignored",
    -213: "Init ignored",
    -214: "Trigger deadlock",
    -220: "Parameter error",
    -221: "Settings conflict",
    -222: "Data out of range",
    -223: "Too much data",
    -224: "Illegal parameter value",
    -230: "Data corrupt or stale",
    -240: "Hardware error",
    -241: "Hardware missing",
    -300: "Device-specific error",
    -310: "System error",
    -311: "Memory error",
    -330: "Self-test failed",
    -350: "Queue overflow",
    -360: "Communication error",
    -400: "Query error",
    -410: "Query INTERRUPTED",
    -420: "Query UNTERMINATED",
    -430: "Query DEADLOCKED",
    -440: "Query UNTERMINATED after indefinite response",
    -500: "Power on",
    -600: "User request",
    -700: "Request control",
    -800: "Operation complete",
}

#: SCPI limits an error/event string (quotes excluded) to 255 characters.
MAX_ERROR_ENTRY_CHARS = 255

# Family fallback texts for codes missing from the table (e.g. -115 -> "Command error").
_FAMILY_TEXT = {-1: "Command error", -2: "Execution error", -3: "Device-specific error",
                -4: "Query error", -5: "Power on", -6: "User request",
                -7: "Request control", -8: "Operation complete"}

# ESR bit per hundreds-family (IEEE 488.2 §11.5.1.1).
_FAMILY_ESR = {-1: 0x20, -2: 0x10, -3: 0x08, -4: 0x04, -5: 0x80, -6: 0x40,
               -7: 0x02, -8: 0x01}


def _family(code: int) -> int:
    """Hundreds family of a negative code: -113 -> -1, -222 -> -2."""
    return -((-code) // 100)


def error_text(code: int, overrides: dict[int, str] | None = None) -> str:
    """Standard message text for ``code``; unknown codes get their family's text.

    Positive codes are device-specific; without an override they read
    "Device-specific error".
    """
    if overrides and code in overrides:
        return overrides[code]
    text = ERROR_MESSAGES.get(code)
    if text is not None:
        return text
    if code > 0:
        return "Device-specific error"
    return _FAMILY_TEXT.get(_family(code), "Device-specific error")


def esr_bit_for(code: int) -> int:
    """ESR bit mask set when an error with ``code`` occurs (0 for code 0)."""
    if code == 0:
        return 0
    if code > 0:
        return 0x08  # device-specific (DDE)
    return _FAMILY_ESR.get(_family(code), 0x08)


def _sanitize(text: str) -> str:
    """Make free text safe inside a SCPI string response: ASCII, one line, quotes doubled."""
    text = text.encode("ascii", "replace").decode("ascii")
    text = "".join(ch if " " <= ch <= "~" else " " for ch in text)
    return text.replace('"', '""')


def format_error_entry(code: int, detail: str | None = None,
                       overrides: dict[int, str] | None = None) -> str:
    """Format one error-queue entry: ``-222,"Data out of range;detail"``.

    The quoted part is truncated to :data:`MAX_ERROR_ENTRY_CHARS` characters.
    """
    body = error_text(code, overrides)
    if detail:
        body = f"{body};{detail}"
    body = _sanitize(body)
    if len(body) > MAX_ERROR_ENTRY_CHARS:
        body = body[:MAX_ERROR_ENTRY_CHARS]
        # never leave half of a doubled quote at the cut
        if (len(body) - len(body.rstrip('"'))) % 2:
            body = body[:-1]
    return f"{code:+d},\"{body}\""


class ScpiError(Exception):
    """An error destined for the instrument's error queue.

    Args:
        code: SCPI error number (negative standard codes, positive device codes).
        detail: optional device-dependent information appended after ``;``.
    """

    def __init__(self, code: int, detail: str | None = None):
        if not isinstance(code, int) or isinstance(code, bool):
            raise TypeError(f"SCPI error code must be an int, got {code!r}")
        self.code = code
        self.detail = detail
        super().__init__(self.entry)

    @property
    def text(self) -> str:
        """The standard message text for :attr:`code`."""
        return error_text(self.code)

    @property
    def entry(self) -> str:
        """Queue-entry form, e.g. ``-222,"Data out of range;NPLC 7 not in 0.001..100"``."""
        return format_error_entry(self.code, self.detail)
