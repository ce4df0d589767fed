"""Argument checks the library's methods share: each raises ValueError naming the argument,
the value and the allowed range (private to the library: a method's own checks use these)."""

from __future__ import annotations

import math
import numbers

import numpy as np

__all__ = ["as_array", "check_choice", "check_int", "check_real", "is_real"]


def is_real(value) -> bool:
    """A finite real number (bool excluded)."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool) and math.isfinite(value)


def check_real(name: str, value, low: float, high: float, *, low_open: bool = False) -> float:
    """``value`` as a float when finite and in [low, high] ((low, high] with ``low_open``).

    Otherwise ValueError naming the value and the allowed range: the argument check the
    thermal (and turn-on) analyses share.

    Parameters
    ----------
    name : str
        The argument's name, for the message.
    value : float
        The value to check (a real number; bool is refused).
    low : float
        Lower end of the allowed range, in the value's unit.
    high : float
        Upper end (inclusive), same unit.
    low_open : bool, default False
        Exclude ``low`` itself: the range is (low, high].

    Returns
    -------
    float
        ``value`` as a float.

    Raises
    ------
    ValueError
        If ``value`` is not a finite real number within the range; the message names
        ``name``, the value and the allowed range.

    Examples
    --------
    >>> from bench.analysis._checks import check_real
    >>> check_real("reference_c", 25, -100.0, 200.0)
    25.0
    >>> check_real("confidence", 1.5, 0.5, 0.999)
    Traceback (most recent call last):
    ...
    ValueError: confidence = 1.5 outside the allowed range [0.5, 0.999]
    """
    ok = is_real(value) and (low < value if low_open else low <= value) and value <= high
    if not ok:
        bracket = "(" if low_open else "["
        raise ValueError(f"{name} = {value!r} outside the allowed range {bracket}{low:g}, {high:g}]")
    return float(value)


def check_int(name: str, value, low: int, high: int) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or not low <= int(value) <= high:
        raise ValueError(f"{name} = {value!r} must be an integer in [{low}, {high}]")
    return int(value)


def check_choice(name: str, value, allowed: tuple[str, ...]) -> str:
    if value not in allowed:
        raise ValueError(f"{name} = {value!r} must be one of {', '.join(map(repr, allowed))}")
    return str(value)


def as_array(name: str, values, *, size: int | None = None, min_size: int = 1,
             positive: bool = False, limits: tuple[float, float] | None = None) -> np.ndarray:
    """1-D finite float array (a copy), checked for length, sign and range.

    The array check the thermal (and turn-on) analyses share.

    Parameters
    ----------
    name : str
        The argument's name, for the message.
    values : array_like
        The values, any unit.
    size : int, optional
        Required length; default any length ≥ ``min_size``.
    min_size : int, default 1
        Shortest allowed length (when ``size`` is None).
    positive : bool, default False
        Require every value > 0.
    limits : tuple of float, optional
        ``(low, high)``: require every value within [low, high], in the values' unit.

    Returns
    -------
    ndarray of float, shape (n,)
        A copy of ``values``.

    Raises
    ------
    ValueError
        If ``values`` is not 1-D of the required length, or a value is not finite, not > 0
        (with ``positive``) or outside ``limits``; the message names the first bad element
        and the allowed range.

    Examples
    --------
    >>> from bench.analysis._checks import as_array
    >>> as_array("temperature_c", [-40, 25, 70], limits=(-100.0, 200.0)).tolist()
    [-40.0, 25.0, 70.0]
    >>> as_array("std", [0.1, 0.0], positive=True)
    Traceback (most recent call last):
    ...
    ValueError: std[1] = 0.0 outside the allowed range (0, ∞)
    """
    arr = np.array(values, dtype=float)
    if arr.ndim != 1 or arr.size < min_size or (size is not None and arr.size != size):
        want = f"length {size}" if size is not None else f"length ≥ {min_size}"
        raise ValueError(f"{name} must be a 1-D array of {want}, got shape {arr.shape}")
    bad = ~np.isfinite(arr)
    if positive:
        bad |= ~(arr > 0)
    if limits is not None:
        bad |= (arr < limits[0]) | (arr > limits[1])
    if np.any(bad):
        i = int(np.flatnonzero(bad)[0])
        allowed = (f"[{limits[0]:g}, {limits[1]:g}]" if limits is not None
                   else "(0, ∞)" if positive else "finite numbers")
        raise ValueError(f"{name}[{i}] = {float(arr[i])!r} outside the allowed range {allowed}")
    return arr
