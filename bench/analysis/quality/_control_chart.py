"""Shewhart control charts (individuals and X̄-R) and the Western Electric run rules.

Individuals chart (one value per unit, in time order): the process sigma is estimated from the
average moving range of consecutive values, σ̂ = MR̄ / d₂ with d₂ = 1.128 (n = 2), so a slow
drift does not inflate the limits; limits at centre ± 3σ̂.  X̄-R chart (subgroups of n = 2..10
values, e.g. the units of one day or lot): X̄ limits X̿ ± A₂R̄, range limits D₃R̄ .. D₄R̄, with
σ̂ = R̄/d₂ (constants: ASTM STP 15D / Montgomery, *Introduction to Statistical Quality Control*,
Appendix VI).

Western Electric rules (Statistical Quality Control Handbook, 1956), judged on the plotted
points against zones of width σ̂ (σ̂/√n for X̄) about the centre:

1. one point beyond 3σ;
2. two of three consecutive points beyond 2σ on the same side;
3. four of five consecutive points beyond 1σ on the same side;
4. eight consecutive points on the same side of the centre.

A point is flagged with each rule whose window ends at it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

#: subgroup size -> (A2, D3, D4, d2)
XBAR_R_CONSTANTS: dict[int, tuple[float, float, float, float]] = {
    2: (1.880, 0.0, 3.267, 1.128), 3: (1.023, 0.0, 2.574, 1.693), 4: (0.729, 0.0, 2.282, 2.059),
    5: (0.577, 0.0, 2.114, 2.326), 6: (0.483, 0.0, 2.004, 2.534), 7: (0.419, 0.076, 1.924, 2.704),
    8: (0.373, 0.136, 1.864, 2.847), 9: (0.337, 0.184, 1.816, 2.970), 10: (0.308, 0.223, 1.777, 3.078),
}
D2_MOVING_RANGE = 1.128
RULES = {1: "1 point beyond 3σ", 2: "2 of 3 beyond 2σ, same side",
         3: "4 of 5 beyond 1σ, same side", 4: "8 in a row on one side"}


@dataclass(frozen=True)
class ControlChart:
    """A Shewhart control chart: points, centre line, control limits and rule violations.

    A chart of ``values`` (one point each) with its centre line, control limits and the
    sigma its zones use; ``violations`` are (point index, Western Electric rule number).

    All values, limits and sigma are in the unit of the charted quantity (a range chart's in
    that unit too).

    Attributes
    ----------
    kind : str
        ``"individuals"``, ``"xbar"`` (subgroup means) or ``"range"`` (subgroup ranges).
    values : ndarray, shape (k,)
        The plotted points, in time order.
    centre : float
        Centre line: the (baseline) mean, the grand mean X̿ or the mean range R̄.
    lcl : float
        Lower control limit.
    ucl : float
        Upper control limit.
    sigma : float
        The zone width the run rules use: σ̂ (individuals), σ̂/√n (X̄), R̄/d₂ (range);
        0 when the data do not vary.
    violations : tuple of (int, int)
        ``(point index, rule number)`` for every rule (1 … 4, :data:`RULES`) broken by a window
        ending at that point; for the range chart only rule 1 (a point beyond its limits).
    flagged : ndarray of int
        Property: indices of the points that break any rule, ascending.
    """

    kind: str                       # "individuals" | "xbar" | "range"
    values: np.ndarray
    centre: float
    lcl: float
    ucl: float
    sigma: float
    violations: tuple[tuple[int, int], ...]

    @property
    def flagged(self) -> np.ndarray:
        """Indices of the points that break any rule, ascending."""
        return np.array(sorted({i for i, _ in self.violations}), dtype=int)


def western_electric(values: npt.ArrayLike, centre: float, sigma: float) -> tuple[tuple[int, int], ...]:
    """(index, rule) for every point of ``values`` that ends a window breaking rule 1..4.

    The Western Electric rules of the module docstring, judged against zones of width
    ``sigma`` about ``centre``: 1 one point beyond 3σ; 2 two of three beyond 2σ, same side;
    3 four of five beyond 1σ, same side; 4 eight in a row on one side.

    Parameters
    ----------
    values : array_like, shape (k,)
        The plotted points in time order, in the charted quantity's unit.
    centre : float
        Centre line, same unit.
    sigma : float
        Zone width σ, same unit; > 0.

    Returns
    -------
    tuple of (int, int)
        ``(index, rule)`` pairs in index order; a point may appear once per rule it breaks.

    Raises
    ------
    ValueError
        If ``values`` is not 1-D or ``sigma`` is not > 0.

    Examples
    --------
    >>> from bench.analysis.quality import western_electric
    >>> western_electric([0.5, 2.5, 2.4, 0.1, 3.5], centre=0.0, sigma=1.0)
    ((2, 2), (4, 1), (4, 2))
    >>> western_electric([0.5] * 8, centre=0.0, sigma=1.0)  # eight on one side
    ((7, 4),)
    """
    x = np.asarray(values, dtype=float)
    if x.ndim != 1:
        raise ValueError(f"values must be 1-D, got shape {x.shape}")
    if not sigma > 0:
        raise ValueError(f"sigma={sigma!r} must be > 0")
    z = (x - centre) / sigma
    found: list[tuple[int, int]] = []
    for i in range(z.size):
        if abs(z[i]) > 3:
            found.append((i, 1))
        for rule, window, need, beyond in ((2, 3, 2, 2.0), (3, 5, 4, 1.0)):
            if i + 1 >= window:
                side = 1.0 if z[i] > 0 else -1.0  # the window's count on this point's side
                w = side * z[i + 1 - window:i + 1]
                if w[-1] > beyond and np.sum(w > beyond) >= need:
                    found.append((i, rule))
        if i + 1 >= 8:
            w = z[i - 7:i + 1]
            if np.all(w > 0) or np.all(w < 0):
                found.append((i, 4))
    return tuple(found)


def individuals_chart(values: npt.ArrayLike, baseline: int | None = None) -> ControlChart:
    """Individuals chart of ``values`` in time order (at least 2, finite).

    ``baseline``: the centre and sigma come from the first ``baseline`` values only (phase I:
    limits from a period known to be in control, every value judged against them); default
    all. σ̂ = MR̄/d₂ with d₂ = 1.128 (average moving range of consecutive values), limits at
    centre ± 3σ̂, and the Western Electric rules (:func:`western_electric`) on every value.

    Parameters
    ----------
    values : array_like, shape (k,)
        One value per unit in time order, any unit; finite, k ≥ 2.
    baseline : int, optional
        Number of leading values the centre and σ̂ come from, in [2, k]; default all.

    Returns
    -------
    ControlChart
        ``kind="individuals"``, limits and sigma in the values' unit, the rule violations
        (none, and every limit at the centre, when the baseline does not vary).

    Raises
    ------
    ValueError
        If ``values`` is not 1-D with at least 2 finite values, or ``baseline`` is outside
        [2, k].

    Examples
    --------
    >>> import numpy as np
    >>> from bench.analysis.quality import individuals_chart
    >>> x = np.r_[np.random.default_rng(0).normal(10.0, 0.1, 20), 10.5]  # a jump at the end
    >>> c = individuals_chart(x, baseline=20)
    >>> round(c.centre, 2), c.lcl < 10.0 < c.ucl
    (9.98, True)
    >>> c.violations, c.flagged.tolist()
    (((20, 1),), [20])
    """
    x = _finite_1d(values, "values", 2)
    if baseline is not None and not 2 <= baseline <= x.size:
        raise ValueError(f"baseline={baseline!r} not in 2..{x.size} (the number of values)")
    base = x[:baseline]
    moving_range = np.abs(np.diff(base)).mean()
    sigma = moving_range / D2_MOVING_RANGE
    centre = float(base.mean())
    if sigma == 0:
        return ControlChart("individuals", x, centre, centre, centre, 0.0, ())
    return ControlChart("individuals", x, centre, centre - 3 * sigma, centre + 3 * sigma, float(sigma),
                        western_electric(x, centre, sigma))


def xbar_r_charts(subgroups: npt.ArrayLike) -> tuple[ControlChart, ControlChart]:
    """X̄ and R charts of ``subgroups`` (k × n, k ≥ 2 subgroups of n = 2..10 values each).

    X̄ limits X̿ ± A₂R̄, range limits D₃R̄ … D₄R̄, σ̂ = R̄/d₂ (constants of the module
    docstring). The X̄ chart is judged by all four Western Electric rules with zones of
    σ̂/√n; the range chart by its limits only (rule 1).

    Parameters
    ----------
    subgroups : array_like, shape (k, n)
        k ≥ 2 subgroups (e.g. the units of one day or lot), one per row, of n in 2 … 10
        values each, any unit; finite.

    Returns
    -------
    xbar : ControlChart
        ``kind="xbar"``: the subgroup means, in the values' unit.
    r_chart : ControlChart
        ``kind="range"``: the subgroup ranges, same unit.

    Raises
    ------
    ValueError
        If ``subgroups`` is not k × n with k ≥ 2 and n in [2, 10], or is not finite.

    Examples
    --------
    >>> import numpy as np
    >>> from bench.analysis.quality import xbar_r_charts
    >>> g = np.random.default_rng(1).normal(5.0, 0.2, (20, 5))  # 20 lots of 5 units
    >>> xbar, r = xbar_r_charts(g)
    >>> xbar.kind, r.kind, xbar.values.shape
    ('xbar', 'range', (20,))
    >>> round(xbar.centre, 2), round(r.centre, 2), xbar.violations, r.violations
    (4.99, 0.4, (), ())
    """
    g = np.asarray(subgroups, dtype=float)
    if g.ndim != 2 or g.shape[0] < 2 or g.shape[1] not in XBAR_R_CONSTANTS:
        raise ValueError(f"subgroups must be k x n with k >= 2 and n in 2..10, got shape {g.shape}")
    if not np.all(np.isfinite(g)):
        raise ValueError("subgroups must be finite")
    a2, d3, d4, d2 = XBAR_R_CONSTANTS[g.shape[1]]
    means, ranges = g.mean(axis=1), np.ptp(g, axis=1)
    grand, r_bar = float(means.mean()), float(ranges.mean())
    sigma_mean = r_bar / d2 / np.sqrt(g.shape[1])
    xbar_rules = western_electric(means, grand, sigma_mean) if sigma_mean > 0 else ()
    xbar = ControlChart("xbar", means, grand, grand - a2 * r_bar, grand + a2 * r_bar,
                        float(sigma_mean), xbar_rules)
    beyond = tuple((int(i), 1) for i in np.flatnonzero((ranges > d4 * r_bar) | (ranges < d3 * r_bar)))
    r_chart = ControlChart("range", ranges, r_bar, d3 * r_bar, d4 * r_bar, float(r_bar / d2),
                           beyond if r_bar > 0 else ())
    return xbar, r_chart


def _finite_1d(values: npt.ArrayLike, name: str, minimum: int) -> np.ndarray:
    x = np.asarray(values, dtype=float)
    if x.ndim != 1 or x.size < minimum:
        raise ValueError(f"{name} must be 1-D with at least {minimum} points, got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{name} must be finite")
    return x
