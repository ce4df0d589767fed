"""Identify the process that writes a run, so a later reader can tell whether it still lives.

A writer is recorded as (hostname, pid, start token).  On Linux the start token is
``"<boot_id>|<pid namespace>|<start time in clock ticks since boot>"`` read from ``/proc``:
together with the pid it names one process for the lifetime of the machine, so a pid reused
by an unrelated process is not mistaken for the writer.  Elsewhere the token is ``None`` and
only the pid's existence is checked.  No timeout is involved: a writer that is merely slow is
never declared dead.
"""

from __future__ import annotations

import errno
import os
import socket
from dataclasses import dataclass
from enum import Enum


class Liveness(Enum):
    ALIVE = "alive"
    DEAD = "dead"
    UNKNOWN = "unknown"  # another host or another pid namespace: we cannot look at it


@dataclass(frozen=True)
class ProcessIdentity:
    host: str
    pid: int
    start_token: str | None


def _read(path: str) -> str | None:
    try:
        with open(path, encoding="ascii", errors="replace") as f:
            return f.read().strip()
    except OSError:
        return None


def _stat_fields(pid: int) -> list[str] | None:
    """Fields of /proc/<pid>/stat after the command name (field 3 = state is index 0)."""
    text = _read(f"/proc/{pid}/stat")
    if text is None:
        return None
    # The command name is in parentheses and may itself contain ')' or spaces.
    return text[text.rfind(")") + 2 :].split()


def _pid_namespace(pid: int | str) -> str | None:
    try:
        return os.readlink(f"/proc/{pid}/ns/pid")
    except OSError:
        return None


def _start_token(pid: int) -> str | None:
    boot_id = _read("/proc/sys/kernel/random/boot_id")
    fields = _stat_fields(pid)
    if boot_id is None or fields is None or len(fields) < 20:
        return None
    return f"{boot_id}|{_pid_namespace(pid)}|{fields[19]}"  # field 22 = starttime


def current_process() -> ProcessIdentity:
    """The identity of this process."""
    pid = os.getpid()
    return ProcessIdentity(socket.gethostname(), pid, _start_token(pid))


def _pid_exists(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except OSError as exc:
        return exc.errno == errno.EPERM  # exists, owned by someone else
    return True


def liveness(writer: ProcessIdentity) -> Liveness:
    """Judge whether ``writer`` still runs, seen from this process."""
    me = current_process()
    if writer.host != me.host:
        return Liveness.UNKNOWN
    if writer.start_token is not None and me.start_token is not None:
        boot, namespace, ticks = writer.start_token.split("|", 2)
        my_boot, my_namespace, _ = me.start_token.split("|", 2)
        if boot != my_boot:
            return Liveness.DEAD  # the machine rebooted since: every process of then is gone
        if namespace != my_namespace:
            return Liveness.UNKNOWN  # pids of another container mean nothing here
        fields = _stat_fields(writer.pid)
        if fields is None or fields[0] in ("Z", "X"):  # gone, or a zombie awaiting its reaper
            return Liveness.DEAD
        if len(fields) < 20:
            return Liveness.UNKNOWN  # an unreadable /proc entry: do not guess
        # Same pid, same start time: the very process (a reused pid starts later).
        return Liveness.ALIVE if fields[19] == ticks else Liveness.DEAD
    return Liveness.ALIVE if _pid_exists(writer.pid) else Liveness.DEAD
