"""Declarative SCPI settings: the :class:`Setting` descriptor and its constructors.

This module holds the PyMeasure-style property layer of the drivers: a :class:`Setting`
is declared once on a driver or channel class with its SCPI get/set commands, validator,
allowed values and docstring (via :func:`control` for read/write settings and
:func:`measurement` for read-only values); reading it sends an idempotent query, setting
it validates first and then hands one command to the owner's ``configure_command``.
:func:`read_settings` reads a list of such settings for the run record without letting
one failed read lose the others.  :mod:`instruments.base` re-exports every name here.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from typing import Any

from .validate import format_number, parse_float

Validator = Callable[[str, Any, Any], Any]


class Setting:
    """A data descriptor for one SCPI setting or reading, declared once.

    ``get_cmd``/``set_cmd`` are format strings; ``{value}`` is the formatted value and the
    owner's ``command_fields()`` (e.g. ``{ch}``, ``{axis}``) fill the rest.  ``values`` is a
    constant or a callable ``owner -> values`` for allowed values that depend on the
    instrument (a channel's range, an installed option).
    """

    def __init__(
        self,
        get_cmd: str | None,
        set_cmd: str | None,
        doc: str,
        *,
        validator: Validator | None = None,
        values: Any = None,
        set_map: Mapping[Any, str] | None = None,
        fmt: Callable[[Any], str] = format_number,
        parse: Callable[[str], Any] = parse_float,
    ) -> None:
        if set_cmd is not None and validator is None:
            raise TypeError("a settable Setting needs a validator")
        self.get_cmd, self.set_cmd = get_cmd, set_cmd
        self.validator, self.values, self.set_map = validator, values, set_map
        self.fmt, self.parse = fmt, parse
        self.__doc__ = doc
        self.name = "?"

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def allowed(self, owner: Any) -> Any:
        """The allowed values for this setting on ``owner``."""
        return self.values(owner) if callable(self.values) else self.values

    def __get__(self, owner: Any, owner_type: type | None = None) -> Any:
        if owner is None:
            return self
        if self.get_cmd is None:
            raise AttributeError(f"{self.name} is write-only")
        command = self.get_cmd.format(**owner.command_fields())
        # a setting's readback has no side effect: safe to ask again after a failure
        return owner.query_value(command, self.parse, retry=True)

    def __set__(self, owner: Any, value: Any) -> None:
        if self.set_cmd is None:
            raise AttributeError(f"{self.name} is read-only")
        assert self.validator is not None
        canonical = self.validator(owner.label(self.name), value, self.allowed(owner))
        wire = self.set_map[canonical] if self.set_map is not None else self.fmt(canonical)
        owner.configure_command(self.set_cmd.format(value=wire, **owner.command_fields()))


def control(get_cmd: str | None, set_cmd: str, doc: str, **kwargs: Any) -> Setting:
    """A readable and settable setting (see :class:`Setting`)."""
    return Setting(get_cmd, set_cmd, doc, **kwargs)


def measurement(get_cmd: str, doc: str, parse: Callable[[str], Any] = parse_float) -> Setting:
    """A read-only value (see :class:`Setting`)."""
    return Setting(get_cmd, None, doc, parse=parse)


def read_settings(owner: Any, names: Iterable[str]) -> dict[str, Any]:
    """``{name: getattr(owner, name)}``, with a failed read recorded as ``"error: ..."``."""
    values: dict[str, Any] = {}
    for name in names:
        try:
            values[name] = getattr(owner, name)
        except Exception as exc:  # one unreadable setting must not lose the others
            values[name] = f"error: {exc}"
    return values
