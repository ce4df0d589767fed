"""The BLAS thread count of this process, set while it runs (OpenBLAS, through its own setter).

numpy and scipy each load an OpenBLAS of their own, threaded by default over every core. The
discovery workflow's linear algebra is on tall, narrow matrices (180 000 × 5 Jacobians, a few
columns of regressors) where a second BLAS thread mostly waits for the first: on the start-up
run ``bench discover`` took 117 s of CPU with two BLAS threads and 54 s with one, for the same
wall time. Its work is parallel by candidate instead (:mod:`bench.discovery.mapping`).

The libraries are found among those this process has mapped (``/proc/self/maps``) and set with
the setter each exports (numpy's 64-bit-integer build suffixes ``64_``); on a platform without
that file, or with a BLAS that is not OpenBLAS, nothing is changed.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
from collections.abc import Iterator
from typing import Any

#: (setter, getter) symbol pairs of the OpenBLAS builds numpy and scipy ship, and of a plain one
_SYMBOLS = (("scipy_openblas_set_num_threads64_", "scipy_openblas_get_num_threads64_"),
            ("scipy_openblas_set_num_threads", "scipy_openblas_get_num_threads"),
            ("openblas_set_num_threads64_", "openblas_get_num_threads64_"),
            ("openblas_set_num_threads", "openblas_get_num_threads"))


def loaded_openblas() -> list[tuple[Any, Any]]:
    """(setter, getter) of each OpenBLAS this process has loaded."""
    try:
        with open("/proc/self/maps", encoding="utf-8", errors="replace") as fh:
            paths = sorted({line.split()[-1] for line in fh
                            if "/" in line and "openblas" in os.path.basename(line.split()[-1]).lower()})
    except OSError:
        return []
    found = []
    for path in paths:
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for set_name, get_name in _SYMBOLS:
            if hasattr(lib, set_name) and hasattr(lib, get_name):
                found.append((getattr(lib, set_name), getattr(lib, get_name)))
                break
    return found


def set_blas_threads(n: int) -> None:
    """Set every loaded OpenBLAS to ``n`` threads (a worker process's initializer)."""
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ValueError(f"BLAS threads {n!r}; allowed: an integer >= 1")
    for setter, _ in loaded_openblas():
        setter(n)


@contextlib.contextmanager
def blas_threads(n: int) -> Iterator[None]:
    """Every loaded OpenBLAS at ``n`` threads for the duration of the block, then as before."""
    before = [(setter, int(getter())) for setter, getter in loaded_openblas()]
    set_blas_threads(n)
    try:
        yield
    finally:
        for setter, k in before:
            setter(k)
