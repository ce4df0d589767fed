"""What a person reads — on the operator page and in the reports: measurement names from the
spec's labels, units as a person writes them, numbers to the digits they carry, limits on one
line, the time left, and a stored run's procedure and result.

Plain data in, text out; the page or the report only places the text.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from bench.core.spec import UNITS, plain_unit

#: significant digits of a value shown (fewer when its uncertainty says the last is noise): the
#: shipped limits carry at most three, and a fourth places the value inside a marginal band a
#: tenth of the limit — more is for the report, not the operator
DEFAULT_DIGITS = 4
#: digits of a limit, written as the spec gives it (trailing zeros dropped)
MAX_DIGITS = 6
#: written in fixed point inside this range of magnitudes, as a power of ten outside it
FIXED_RANGE = (1e-4, 1e6)
_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def unit_text(unit: str | None) -> str:
    """A unit as a person reads it (``bench.core.spec.plain_unit``); an unknown one as given."""
    if not unit:
        return ""
    return plain_unit(unit) if unit in UNITS else unit


def _significant(value: float, digits: int) -> str:
    exponent = math.floor(math.log10(abs(value)))
    rounded = round(value, digits - 1 - exponent)
    if rounded != 0 and math.floor(math.log10(abs(rounded))) != exponent:  # 9.9996 → 10.00
        exponent += 1
    if FIXED_RANGE[0] <= abs(rounded) < FIXED_RANGE[1]:
        return f"{rounded:.{max(digits - 1 - exponent, 0)}f}".replace("-", "−")
    mantissa = rounded / 10.0**exponent
    return f"{mantissa:.{digits - 1}f}×10{str(exponent).translate(_SUPERSCRIPT)}".replace("-", "−", 1)


def number_text(value: float | None, unit: str | None = None, uncertainty: float | None = None) -> str:
    """``value`` to the digits it carries: a count as a whole number; otherwise
    :data:`DEFAULT_DIGITS` significant digits, or fewer when a standard ``uncertainty`` puts its
    second significant digit higher (GUM 7.2.6: the value rounded where its uncertainty is).
    A missing value is a dash."""
    if value is None or not math.isfinite(value):
        return "—"
    if unit in UNITS and UNITS[unit][0] == "count":
        return f"{round(value):d}".replace("-", "−")
    if value == 0:
        return "0"
    digits = DEFAULT_DIGITS
    if uncertainty is not None and math.isfinite(uncertainty) and uncertainty > 0:
        decimals = 1 - math.floor(math.log10(uncertainty))
        digits = math.floor(math.log10(abs(value))) + 1 + decimals
        rounded = round(value, decimals)
        if 1 <= digits <= DEFAULT_DIGITS and FIXED_RANGE[0] <= abs(rounded) < FIXED_RANGE[1]:
            return f"{rounded:.{max(decimals, 0)}f}".replace("-", "−")
    return _significant(value, min(max(digits, 1), DEFAULT_DIGITS))


def _limit(value: float) -> str:
    """A limit as the spec wrote it (up to :data:`MAX_DIGITS` digits, no trailing zeros)."""
    if value == 0:
        return "0"
    number, times, power = _significant(value, MAX_DIGITS).partition("×")
    if "." in number:
        number = number.rstrip("0").rstrip(".")
    return number + times + power


def limits_text(low: float | None, high: float | None) -> str:
    """Limits on one line: ``−4 … 4``, ``≤ 2.2``, ``≥ 1.2``, ``= 0``; empty when none."""
    if low is not None and high is not None:
        return f"= {_limit(low)}" if low == high else f"{_limit(low)} … {_limit(high)}"
    if high is not None:
        return f"≤ {_limit(high)}"
    if low is not None:
        return f"≥ {_limit(low)}"
    return ""


def plain_name(name: str) -> str:
    """An identifier in words: ``readings_lost`` → ``Readings lost``, ``level_check_g`` →
    ``Level check`` (a trailing unit, as names carry them, dropped), ``turn_on`` → ``Turn on``."""
    words = [w for w in name.split("_") if w]
    if len(words) > 1 and words[-1] in UNITS:
        words = words[:-1]
    text = " ".join(words)
    return text[:1].upper() + text[1:]


def measurement_label(measurement: Mapping[str, Any], labels: Mapping[str, str]) -> str:
    """What the operator reads for a measurement: the spec's label (its name where the spec
    gives none); one the procedure takes beside the spec's (a guard such as
    ``readings_lost``) by its name in words."""
    name = str(measurement.get("name", ""))
    return labels[name] if name in labels else plain_name(name)


#: how a value that only bounds its quantity is written before it
BOUND_SIGN = {"upper": "≤ ", "lower": "≥ "}


def bound_text(measurement: Mapping[str, Any]) -> str:
    """``≤ `` before a value that is an upper bound of its quantity, ``≥ `` a lower, else nothing."""
    return BOUND_SIGN.get(str(measurement.get("bound")), "")


def measurement_row(measurement: Mapping[str, Any], labels: Mapping[str, str]) -> dict[str, Any]:
    """A judged measurement (``Measurement.to_dict``) with the text the page shows."""
    unit = measurement.get("unit")
    unc = measurement.get("uncertainty")
    return {**measurement, "label": measurement_label(measurement, labels),
            "value_text": bound_text(measurement) + number_text(measurement.get("value"), unit, unc),
            "unit_text": unit_text(unit),
            "uncertainty_text": "" if unc is None else f"± {number_text(unc, unit)} {unit_text(unit)}",
            "limits_text": limits_text(measurement.get("low"), measurement.get("high"))}


def time_left_text(seconds: float | None) -> str:
    """``about 40 s left``, ``about 12 min left``, ``about 1 h 52 min left``; ``finishing``
    under a second; empty while there is no estimate yet."""
    if seconds is None:
        return ""
    if seconds < 1:
        return "finishing"
    if seconds < 90:
        return f"about {math.ceil(seconds)} s left"
    minutes = math.ceil(seconds / 60)
    if minutes < 90:
        return f"about {minutes} min left"
    return f"about {minutes // 60} h {minutes % 60} min left"


def procedure_text(procedure: str, parameters: Mapping[str, Any]) -> str:
    """A stored run's procedure: ``acceptance QA-2000-SIM`` (with its spec's model), or the
    procedure's own name (``startup`` for ``bench run startup``)."""
    spec = parameters.get("spec") if isinstance(parameters, Mapping) else None
    model = spec.get("model") if isinstance(spec, Mapping) else None
    if procedure == "acceptance" and isinstance(model, str) and model:
        return f"acceptance {model}"
    return procedure


__all__ = ["DEFAULT_DIGITS", "MAX_DIGITS", "unit_text", "number_text", "limits_text", "plain_name",
           "measurement_label", "measurement_row", "time_left_text", "procedure_text"]
