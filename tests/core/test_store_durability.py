"""kill -9 of a writer at a random moment: the store stays intact and loses no committed chunk."""

from __future__ import annotations

import random
import sqlite3
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from bench.core.store import RunStore

CHUNK = 500
DT_S = 1e-3

# The writer: reports each chunk on stdout only after append() has returned (committed).
WRITER = textwrap.dedent(f"""
    import sys
    import numpy as np
    from bench.core.store import RunStore

    store = RunStore(sys.argv[1])
    print("OPEN", flush=True)
    run = store.create_run(procedure="durability", parameters={{}}, station={{}},
                           unit_serial=None, seed=None, code_version="test")
    run.add_stream("dmm", {{"t_s": "s", "voltage_v": "V"}})
    print("RUN", run.id, flush=True)
    i = 0
    while True:
        k = np.arange(i * {CHUNK}, (i + 1) * {CHUNK})
        run.append("dmm", t_s=k * {DT_S}, voltage_v=np.sin(k))
        print(i, flush=True)
        i += 1
""")


def _kill_writer_after(path, n_reported: int) -> tuple[str | None, int]:
    """Start a writer, SIGKILL it once it has reported ``n_reported`` chunks (or, for -1,
    right after it opened the store).  Returns (run id, chunks it reported committed)."""
    child = subprocess.Popen([sys.executable, "-c", WRITER, str(path)], stdout=subprocess.PIPE,
                             text=True)
    out = child.stdout
    assert out is not None  # stdout=PIPE
    run_id, committed = None, 0
    try:
        assert out.readline().strip() == "OPEN"
        if n_reported >= 0:
            words = out.readline().split()
            assert words[0] == "RUN", words
            run_id = words[1]
            while committed < n_reported:
                committed = int(out.readline()) + 1
            if n_reported > 0:
                # While the writer lives, a second opener must not take its run for dead.
                with RunStore(path) as reader:
                    assert reader.get_run(run_id).status == "running"
                    assert reader.streams(run_id)["dmm"].n_rows >= committed * CHUNK
    finally:
        child.kill()  # SIGKILL: no handler, no atexit, no flush
        rest, _ = child.communicate(timeout=30)
    for line in rest.splitlines():  # lines written to the pipe before death were committed
        if line.startswith("RUN "):
            run_id = line.split()[1]
        elif line.isdigit():
            committed = int(line) + 1
    return run_id, committed


@pytest.mark.parametrize("trial", range(5))
def test_sigkill_at_a_random_moment_loses_no_committed_chunk(tmp_path, trial):
    rng = random.Random(1000 + trial)
    path = tmp_path / "bench.sqlite"
    n_reported = -1 if trial == 0 else rng.randint(0, 30)
    run_id, committed = _kill_writer_after(path, n_reported)

    with sqlite3.connect(path) as conn:
        assert conn.execute("PRAGMA integrity_check").fetchall() == [("ok",)]
    with RunStore(path) as store:
        runs = store.list_runs()
        assert all((r.status, r.reason) == ("aborted", "interrupted") for r in runs)
        assert all(r.ended_utc is not None for r in runs)
        if run_id is None:
            return  # killed before the run existed
        data = store.load(run_id, "dmm")
        n = len(data["t_s"])
        # Every reported chunk is there, whole; at most the one in flight beyond them.
        assert n % CHUNK == 0 and committed * CHUNK <= n <= (committed + 1) * CHUNK
        k = np.arange(n)
        assert np.array_equal(data["t_s"], k * DT_S)
        assert np.array_equal(data["voltage_v"], np.sin(k))
        info = store.get_run(run_id)
        assert info.last_sample_t_s == (None if n == 0 else (n - 1) * DT_S)
        assert store.recover_interrupted() == []  # nothing left to recover
