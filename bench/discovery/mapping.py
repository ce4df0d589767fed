"""How the workflow's independent pieces of work are mapped over their inputs: the caller's
choice of ``map`` (:class:`MapFn`) — the builtin one, or an executor's running them side by
side in worker processes. Only work that draws no random number from a shared generator is
mapped (a candidate's fit; a null's realisations, each from the seed its turn on the caller's
generator gave it), so the answer does not depend on the choice."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Sequence
from typing import Protocol, TypeVar

T = TypeVar("T")
R = TypeVar("R")
T_contra = TypeVar("T_contra", contravariant=True)


class MapFn(Protocol):
    """``map_fn(fn, items)``: ``fn`` of each item, in the items' order (``map``,
    ``ProcessPoolExecutor.map``)."""

    def __call__(self, fn: Callable[[T], R], items: Iterable[T], /) -> Iterator[R]: ...


#: A null's realisations are handed out in this many batches (each worker then builds its share
#: of the replicates in one array; the builtin map pays only the batches' concatenation).
BATCHES = 4


def batches(items: Sequence[T], k: int = BATCHES) -> list[Sequence[T]]:
    """``items`` cut into at most ``k`` contiguous, nearly equal, non-empty slices (in order)."""
    if isinstance(k, bool) or not isinstance(k, int) or k < 1:
        raise ValueError(f"k = {k!r}; allowed: an integer >= 1")
    n = len(items)
    k = min(k, n)
    edges = [n * i // k for i in range(k + 1)] if k else [0]
    return [items[a:b] for a, b in zip(edges[:-1], edges[1:])]
