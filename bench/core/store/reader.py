"""What reading a run store means, whichever store it is: a station's SQLite file
(``RunStore``) or the central PostgreSQL store (``CentralStore``).  Exports, ``bench runs``
and the fleet views are written against this."""

from __future__ import annotations

import re
from typing import Any, Protocol

import numpy as np

from .model import AttachmentInfo, Event, RunInfo, StreamInfo

URL_SCHEMES = ("postgresql://", "postgres://")


def is_central_url(location: object) -> bool:
    """True for a PostgreSQL URL (the central store), False for a SQLite path."""
    return isinstance(location, str) and location.startswith(URL_SCHEMES)


def masked(url: str) -> str:
    """``url`` with any password replaced by ``***`` (for messages and records)."""
    return re.sub(r"(://[^:/@]+):[^@]*@", r"\1:***@", url)


class RunReader(Protocol):
    """The reading half of a run store."""

    @property
    def location(self) -> str: ...

    def list_runs(self, limit: int | None = None) -> list[RunInfo]: ...

    def get_run(self, run_id: str) -> RunInfo: ...

    def streams(self, run_id: str) -> dict[str, StreamInfo]: ...

    def load(self, run_id: str, stream: str) -> dict[str, np.ndarray]: ...

    def events(self, run_id: str) -> list[Event]: ...

    def attachments(self, run_id: str) -> list[AttachmentInfo]: ...

    def attachment(self, run_id: str, name: str) -> bytes: ...

    def results(self, run_id: str) -> dict[str, Any]: ...

    def chunk_sizes(self, run_id: str) -> dict[str, list[int]]: ...
