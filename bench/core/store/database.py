"""The one SQLite connection a run store and its writers share: its lock and transactions.

A :class:`~bench.core.store.runstore.RunStore` owns one; each
:class:`~bench.core.store.writer.RunWriter` it hands out writes through the same one, so the
writer needs the connection, not the store (and the two modules import one way).
"""

from __future__ import annotations

import contextlib
import os
import sqlite3
import threading
from collections.abc import Iterator
from pathlib import Path

from .schema import connect


class Database:
    """An open store file: the connection, the lock every use of it takes, and the two kinds
    of transaction (an IMMEDIATE write, a consistent read snapshot)."""

    def __init__(self, path: str | os.PathLike[str], synchronous: str, busy_timeout_s: float) -> None:
        self.lock = threading.RLock()
        self._conn: sqlite3.Connection | None = connect(Path(path), synchronous, busy_timeout_s)
        self._name = os.fspath(path)

    @property
    def closed(self) -> bool:
        return self._conn is None

    def connection(self) -> sqlite3.Connection:
        """The open connection (RuntimeError once closed)."""
        if self._conn is None:
            raise RuntimeError(f"run store {self._name!r} is closed")
        return self._conn

    @contextlib.contextmanager
    def write_transaction(self) -> Iterator[sqlite3.Connection]:
        """One IMMEDIATE transaction: committed on success, rolled back on any exception."""
        with self.lock:
            conn = self.connection()
            conn.execute("BEGIN IMMEDIATE")
            try:
                yield conn
            except BaseException:
                conn.execute("ROLLBACK")
                raise
            conn.execute("COMMIT")

    @contextlib.contextmanager
    def read_snapshot(self) -> Iterator[sqlite3.Connection]:
        """A read transaction: every query inside sees the same committed state."""
        with self.lock:
            conn = self.connection()
            conn.execute("BEGIN")
            try:
                yield conn
            finally:
                conn.execute("COMMIT")

    def close(self) -> None:
        with self.lock:
            if self._conn is not None:
                self._conn.close()
                self._conn = None
