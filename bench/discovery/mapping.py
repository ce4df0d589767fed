"""How the naming step's candidates' fits are mapped over the candidates: the caller's choice
of ``map`` (:class:`MapFn`) — the builtin one, or an executor's running them side by side in
worker processes. A fit draws no random number (the p-values are drawn afterwards, in turn, on
the step's generator), so the answer does not depend on the choice."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from typing import Protocol, TypeVar

T = TypeVar("T")
R = TypeVar("R")


class MapFn(Protocol):
    """``map_fn(fn, items)``: ``fn`` of each item, in the items' order (``map``,
    ``ProcessPoolExecutor.map``)."""

    def __call__(self, fn: Callable[[T], R], items: Iterable[T], /) -> Iterator[R]: ...
