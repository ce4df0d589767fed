"""An operator station (its page, API and live stream) served on a free loopback port.

:func:`serve` runs the simulated station's operator page in a thread for the length of a
``with`` block; the browser tests and the operator-page benchmark drive it with Playwright and
Debian's chromium (:data:`CHROMIUM`, ``make chromium``).
"""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import uvicorn

from bench.app.operator.auth import Users
from bench.app.operator.server import OperatorStation, create_app
from bench.app.station import builtin_sim_config

#: Debian's chromium, which Playwright drives (it cannot download a browser of its own here)
CHROMIUM = Path("/usr/bin/chromium")


def free_port() -> int:
    """A TCP port free on loopback now (the OS picks it)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@contextmanager
def serve(folder: Path, *, spec_path: str | None = None, simulation: dict[str, Any] | None = None,
          seed: int = 3, users: Users | None = None) -> Iterator[tuple[str, OperatorStation]]:
    """``(base URL, station)`` of a station served in a thread until the block ends."""
    config = builtin_sim_config()
    config.simulation = dict(simulation or {})
    station = OperatorStation(config, folder / "bench.sqlite", folder / "reports", seed=seed,
                              spec_path=spec_path, labels={"station_id": "test-line"})
    port = free_port()
    server = uvicorn.Server(uvicorn.Config(create_app(station, users), host="127.0.0.1", port=port,
                                           log_level="warning"))
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    deadline = time.monotonic() + 30
    while not server.started:
        if time.monotonic() > deadline or not thread.is_alive():
            raise RuntimeError("the operator station did not start")
        time.sleep(0.05)
    try:
        yield f"http://127.0.0.1:{port}", station
    finally:
        station.live.request_abort()
        if station.thread is not None:
            station.thread.join(timeout=60)
        server.should_exit = True
        thread.join(timeout=10)
