"""Small value types shared by the library and the framework.

This module sits at the very bottom of the bench: it imports nothing but the standard
library, so the framework (run store, steps, specs) can carry a fitted value and its
uncertainty without importing an analysis method and its heavy dependencies.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["BOUNDS", "Estimate"]

#: what an estimate's value is: measured (None), or only an upper or a lower bound of the quantity
BOUNDS = (None, "upper", "lower")


@dataclass(frozen=True)
class Estimate:
    """A fitted value and its standard error, in the parameter's units.

    Parameters
    ----------
    value : float
        The estimate, in the unit of the quantity it estimates.
    std : float or None
        Its standard uncertainty (one standard deviation), same unit; None when unknown.
    bound : {None, "upper", "lower"}
        None for a measured value; "upper" when the data only show the quantity is at most
        ``value`` (e.g. a turn-on time shorter than the averaging window can resolve), "lower"
        when at least.

    Examples
    --------
    >>> from bench.values import Estimate
    >>> k1 = Estimate(1.3142, 3.8e-6)
    >>> k1.to_dict()
    {'value': 1.3142, 'std': 3.8e-06}
    >>> Estimate(125.0, None, bound="upper").to_dict()
    {'value': 125.0, 'std': None, 'bound': 'upper'}
    """

    value: float
    std: float | None
    bound: str | None = None

    def __post_init__(self) -> None:
        if self.bound not in BOUNDS:
            raise ValueError(f"bound = {self.bound!r} must be one of {BOUNDS}")

    def to_dict(self) -> dict[str, float | str | None]:
        """The estimate as a JSON-ready mapping ``{"value": ..., "std": ...}`` (and ``"bound"``
        when it is one)."""
        out: dict[str, float | str | None] = {"value": float(self.value),
                                              "std": None if self.std is None else float(self.std)}
        if self.bound is not None:
            out["bound"] = self.bound
        return out
