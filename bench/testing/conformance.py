"""Does a driver have what an instrument kind's ``typing.Protocol`` declares?

A procedure asks for "a multimeter that can take a timed trace" (``instruments.protocols``),
not for a model number; a driver for a new instrument must offer every member of that
Protocol. ``isinstance`` against a ``runtime_checkable`` Protocol checks names only, and reads
properties; :func:`assert_conforms` checks names and method parameters without any I/O.
"""

from __future__ import annotations

import inspect
from typing import Any


def assert_conforms(instance: Any, protocol: type) -> None:
    """Raise unless ``instance`` has every member ``protocol`` declares, with its parameters.

    Members are those the Protocol declares itself or through the Protocols it extends
    (``SafeInstrument``: ``make_safe`` ...). They are looked up statically
    (``inspect.getattr_static``), so no property is read over the wire; a method must accept
    every parameter the Protocol's method names.

    Parameters
    ----------
    instance : object
        The driver (or channel) to check; built on a :class:`bench.testing.visa.FakeResource`.
    protocol : type
        The ``typing.Protocol`` class.

    Raises
    ------
    AttributeError
        A declared member is missing.
    AssertionError
        A method lacks a parameter the Protocol's method names.

    Examples
    --------
    >>> from typing import Protocol
    >>> class Dimmer(Protocol):
    ...     level: float
    ...     def ramp(self, level: float, rate_per_s: float) -> None: ...
    >>> class Lamp:
    ...     level = 0.0
    ...     def ramp(self, level, rate_per_s, wait=True): ...
    >>> assert_conforms(Lamp(), Dimmer)
    >>> class Bulb:
    ...     level = 0.0
    ...     def ramp(self, level): ...
    >>> assert_conforms(Bulb(), Dimmer)
    Traceback (most recent call last):
    ...
    AssertionError: ramp() lacks parameter 'rate_per_s'
    """
    declared: dict[str, Any] = {}
    for cls in reversed([c for c in protocol.__mro__ if c is not object and c.__module__ != "typing"]):
        declared |= dict.fromkeys(getattr(cls, "__annotations__", {}))
        declared |= {n: v for n, v in vars(cls).items()
                     if not n.startswith("_") and (callable(v) or isinstance(v, property))}
    for name in sorted(declared):
        member = inspect.getattr_static(instance, name)  # AttributeError if missing
        wanted = declared[name]
        if callable(wanted) and not isinstance(wanted, property):
            have = inspect.signature(member).parameters
            for param in list(inspect.signature(wanted).parameters)[1:]:
                assert param in have, f"{name}() lacks parameter {param!r}"
