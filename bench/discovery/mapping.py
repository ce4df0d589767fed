"""How the workflow's independent pieces of work are mapped: the caller's choice of ``map``
(:class:`MapFn`) — the builtin one, or an executor's running them side by side. Two uses: the
naming step's candidates' fits (``map_fn``, worker processes: a fit draws no random number, the
p-values are drawn afterwards, in turn, on the step's generator) and a null's noise realisations
(``fill_map``, threads: each from its own root, drawn first — :meth:`.Model.simulate_noise_many`).
Either way the answer does not depend on the choice."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from typing import Protocol, TypeVar

T = TypeVar("T")
R = TypeVar("R")


class MapFn(Protocol):
    """``map_fn(fn, items)``: ``fn`` of each item, in the items' order (``map``,
    ``ProcessPoolExecutor.map``)."""

    def __call__(self, fn: Callable[[T], R], items: Iterable[T], /) -> Iterator[R]: ...
