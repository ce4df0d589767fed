"""What names a run beyond its unit: the station's labels and the simulated world's seed.

One rule for the command line (``--station-id``, ``--socket``, ``--lot``, ``--seed``) and for
scripts (:mod:`bench.app.session`); standard library only, so every command may import it.
"""

from __future__ import annotations

import os
import socket
from collections.abc import Mapping
from typing import Any

#: the seeds a simulated world takes
SEED_RANGE = (0, 2**63)


def station_labels(station_name: str, *, station_id: str | None = None, socket_name: str | None = None,
                   lot: str | None = None) -> dict[str, str]:
    """A run's labels: the station id (given, else ``$BENCH_STATION_ID``, else
    ``host:station``), and the test socket and production lot when given."""
    labels = {"station_id": station_id or os.environ.get("BENCH_STATION_ID")
              or f"{socket.gethostname()}:{station_name}"}
    if socket_name:
        labels["socket"] = str(socket_name)
    if lot:
        labels["lot"] = str(lot)
    return labels


def world_seed(simulation: Mapping[str, Any] | None, seed: int | None, *, name: str = "seed") -> int | None:
    """The simulated world's seed: ``seed``, else the station's ``[simulation] seed`` (0 when it
    names none); None on a real station (``simulation`` None). ValueError naming ``name``
    when the seed is outside 0..2**63-1."""
    if seed is not None and not SEED_RANGE[0] <= seed < SEED_RANGE[1]:
        raise ValueError(f"{name} {seed} not in 0..2**63-1")
    if seed is not None:
        return seed
    return simulation.get("seed", 0) if simulation is not None else None
