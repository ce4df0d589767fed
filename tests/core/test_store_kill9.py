"""kill -9 at random *moments* (not only after a reported commit), repeatedly into the same
store, and through the real CLI.  tests/core/test_store_durability.py kills a plain appender
right after its N-th reported chunk; here the writer mixes every kind of write
transaction (stream, chunk, event, result, attachment) and the kill lands after a seeded
random delay, i.e. anywhere inside a transaction or between two.

After each kill: ``PRAGMA integrity_check`` is ok, the killed run is still ``running`` on
disk until a store is opened, opening marks it ``aborted``/``interrupted`` (the recovery
the store runs on open), and every chunk the writer reported committed reads back exactly.
"""

from __future__ import annotations

import json
import random
import sqlite3
import subprocess
import sys
import textwrap
import time

import numpy as np

from bench.core.store import RunStore

CHUNK = 200

# Reports "<stream> <i>" on stdout only after append() returned (i.e. committed).
WRITER = textwrap.dedent(f"""
    import sys
    import numpy as np
    from bench.core.store import RunStore

    store = RunStore(sys.argv[1])
    run = store.create_run(procedure="kill9", parameters={{"n": 1}}, station={{}},
                           unit_serial="SN-K9", seed=int(sys.argv[2]), code_version="test")
    print("RUN", run.id, flush=True)
    run.add_stream("a", {{"t_s": "s", "v": "V"}})
    i = 0
    while True:
        k = np.arange(i * {CHUNK}, (i + 1) * {CHUNK})
        run.append("a", t_s=k * 1e-3, v=np.cos(k))
        print("a", i, flush=True)
        if i == 3:
            run.add_stream("b", {{"t_s": "s", "count": "1"}})
        if i >= 3:
            run.append("b", t_s=k * 1e-3, count=k.astype(np.int64))
            print("b", i, flush=True)
        if i % 5 == 0:
            run.event(i * 0.2, "tick", f"chunk {{i}}", i=i)
        if i % 7 == 0:
            run.set_result(f"r{{i}}", i * 1.5)
        if i % 11 == 0:
            run.attach(f"blob{{i}}", bytes(range(256)) * 40, "application/octet-stream")
        i += 1
""")


def _kill_after(path, seed: int, delay_s: float) -> tuple[str | None, dict[str, int]]:
    """Run a writer, SIGKILL it ``delay_s`` after it created its run; returns (run id,
    chunks reported committed per stream)."""
    child = subprocess.Popen([sys.executable, "-c", WRITER, str(path), str(seed)],
                             stdout=subprocess.PIPE, text=True)
    out = child.stdout
    assert out is not None  # stdout=PIPE
    try:
        first = out.readline().split()
        assert first and first[0] == "RUN", first
        time.sleep(delay_s)  # the kill moment: wall time on purpose, it is what we randomise
    finally:
        child.kill()
        rest, _ = child.communicate(timeout=30)
    committed = {"a": 0, "b": 0}
    for line in rest.splitlines():
        fields = line.split()
        if len(fields) != 2 or not fields[1].isdigit():
            continue  # a line cut short by the kill reports nothing
        stream, i = fields
        committed[stream] = int(i) + 1 - (3 if stream == "b" else 0)  # b starts at chunk 3
    return first[1], committed


def _check_intact(path, run_id: str, committed: dict[str, int]) -> None:
    with sqlite3.connect(path) as conn:
        assert conn.execute("PRAGMA integrity_check").fetchall() == [("ok",)]
        assert conn.execute("SELECT status FROM runs WHERE id = ?", (run_id,)).fetchone() \
            == ("running",)  # nobody has opened a store since the kill
    with RunStore(path) as store:
        info = store.get_run(run_id)
        assert (info.status, info.reason) == ("aborted", "interrupted")
        assert info.ended_utc is not None
        assert store.recover_interrupted() == []
        streams = store.streams(run_id)
        for name, n_chunks in committed.items():
            if n_chunks == 0 and name not in streams:
                continue
            data = store.load(run_id, name)
            n = len(data["t_s"])
            # reported chunks all there and whole; at most the one in flight beyond them
            assert n % CHUNK == 0 and n_chunks * CHUNK <= n <= (n_chunks + 1) * CHUNK
            start = 0 if name == "a" else 3 * CHUNK
            k = np.arange(start, start + n)
            assert np.array_equal(data["t_s"], k * 1e-3)
            if name == "a":
                assert np.array_equal(data["v"], np.cos(k))
            else:
                assert np.array_equal(data["count"], k)
        # the other write kinds are whole too
        for event in store.events(run_id):
            if event.kind == "tick":
                assert event.message == f"chunk {event.data['i']}"
        for key, value in store.results(run_id).items():
            assert value == int(key[1:]) * 1.5
        for att in store.attachments(run_id):
            assert store.attachment(run_id, att.name) == bytes(range(256)) * 40


def test_repeated_random_kills_into_one_store(tmp_path):
    """Six writers killed one after another into the same file; every run survives."""
    rng = random.Random(20261122)
    path = tmp_path / "bench.sqlite"
    seen: dict[str, dict[str, int]] = {}
    for trial in range(6):
        run_id, committed = _kill_after(path, trial, rng.uniform(0.0, 0.4))
        _check_intact(path, run_id, committed)
        seen[run_id] = committed
    with RunStore(path) as store:
        runs = store.list_runs()
        assert {r.id for r in runs} == set(seen)
        assert all((r.status, r.reason) == ("aborted", "interrupted") for r in runs)
        for run_id, committed in seen.items():  # earlier runs untouched by later kills
            assert len(store.load(run_id, "a")["t_s"]) >= committed["a"] * CHUNK


def _store_rows(path) -> tuple[str | None, int]:
    """The newest run and its stored row count, read without recovering anything."""
    try:
        with sqlite3.connect(f"file:{path}?mode=ro", uri=True, timeout=5) as conn:
            row = conn.execute("SELECT id FROM runs ORDER BY started_utc DESC LIMIT 1").fetchone()
            if row is None:
                return None, 0
            n = conn.execute("SELECT COALESCE(SUM(n_rows), 0) FROM chunks WHERE run_id = ?",
                             row).fetchone()[0]
            return row[0], int(n)
    except sqlite3.OperationalError:  # the file or its tables do not exist yet
        return None, 0


def test_cli_run_killed_mid_run_shows_aborted_interrupted(tmp_path):
    store = tmp_path / "cli.sqlite"
    child = subprocess.Popen([sys.executable, "-m", "bench.app.cli", "--store", str(store), "run",
                              "startup", "--duration-s", "86400", "--off-wait-s", "5",
                              "--seed", "3", "--no-progress"],
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 60
        run_id, rows = None, 0
        while rows == 0:  # wait until samples are committed: the kill lands mid-acquisition
            assert child.poll() is None, "the run ended before it could be killed"
            assert time.monotonic() < deadline, "no samples committed within 60 s"
            time.sleep(0.2)
            run_id, rows = _store_rows(store)
    finally:
        child.kill()
        child.wait(30)
    show = subprocess.run([sys.executable, "-m", "bench.app.cli", "--store", str(store), "runs",
                           "show", "latest", "--json"], capture_output=True, text=True, timeout=60)
    assert show.returncode == 0, show.stderr
    doc = json.loads(show.stdout)
    assert doc["id"] == run_id
    assert (doc["status"], doc["reason"]) == ("aborted", "interrupted")
    text = subprocess.run([sys.executable, "-m", "bench.app.cli", "--store", str(store), "runs",
                           "show", run_id], capture_output=True, text=True, timeout=60).stdout
    assert "status     aborted — interrupted" in text
    with RunStore(store) as s:
        assert sum(len(s.load(run_id, name)["t_s"]) for name in s.streams(run_id)) >= rows
