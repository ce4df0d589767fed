"""The straightforward code a fast path replaced, kept as its oracle.

A compiled or vectorised implementation is checked against the plain one it replaced (to
floating-point noise, or to the bit for a seeded draw), and the benchmarks time the two side by
side. A reference may borrow the graded module's small helpers (column scaling, a tolerance),
never the code it checks.

* :mod:`bench.testing.references.fusion` — the per-sample numpy loop of the sequential Kalman
  filter (``bench.analysis.fusion``'s ``sequential_kalman`` before its numba kernel);
* :mod:`bench.testing.references.discovery` — the lattice visibility, the held-out linear scorer
  and the block bootstrap of ``bench.discovery`` before their fast paths.
"""
