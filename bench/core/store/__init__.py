"""The run store: every run's samples, events, attachments and results in one SQLite file.

Nothing acquired is ever lost: each append is its own committed transaction (WAL journal,
``synchronous=FULL``), an aborted run keeps its data and says why it stopped, and a writer
killed at any moment leaves a consistent database whose run the next opening marks
``aborted``/``interrupted``.

    store = RunStore("bench-data/bench.sqlite")
    with store.create_run(procedure="tumble", parameters={}, station={}, unit_serial="SN1",
                          seed=1, code_version="0.1.0") as run:
        run.add_stream("dmm", {"t_s": "s", "voltage_v": "V"})
        run.append("dmm", t_s=t, voltage_v=v)
        run.finish("passed")
    store.load(run.id, "dmm")["voltage_v"]
"""

from .model import (
    FINAL_STATUSES,
    INTERRUPTED,
    STATUSES,
    AttachmentInfo,
    Event,
    RunClosedError,
    RunInfo,
    RunRecord,
    SchemaVersionError,
    StreamInfo,
    UnknownAttachmentError,
    UnknownRunError,
    UnknownStreamError,
)
from .runstore import DEFAULT_PATH, RunStore
from .schema import SCHEMA_VERSION
from .writer import RunWriter

__all__ = [
    "DEFAULT_PATH",
    "FINAL_STATUSES",
    "INTERRUPTED",
    "SCHEMA_VERSION",
    "STATUSES",
    "AttachmentInfo",
    "Event",
    "RunClosedError",
    "RunInfo",
    "RunRecord",
    "RunStore",
    "RunWriter",
    "SchemaVersionError",
    "StreamInfo",
    "UnknownAttachmentError",
    "UnknownRunError",
    "UnknownStreamError",
]
