"""Small value types shared by the library and the framework.

This module sits at the very bottom of the bench: it imports nothing but the standard
library, so the framework (run store, steps, specs) can carry a fitted value and its
uncertainty without importing an analysis method and its heavy dependencies.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Estimate"]


@dataclass(frozen=True)
class Estimate:
    """A fitted value and its standard error, in the parameter's units.

    Parameters
    ----------
    value : float
        The estimate, in the unit of the quantity it estimates.
    std : float or None
        Its standard uncertainty (one standard deviation), same unit; None when unknown.

    Examples
    --------
    >>> from bench.values import Estimate
    >>> k1 = Estimate(1.3142, 3.8e-6)
    >>> k1.to_dict()
    {'value': 1.3142, 'std': 3.8e-06}
    """

    value: float
    std: float | None

    def to_dict(self) -> dict[str, float | None]:
        """The estimate as a JSON-ready mapping ``{"value": ..., "std": ...}``."""
        return {"value": float(self.value), "std": None if self.std is None else float(self.std)}
