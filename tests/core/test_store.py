"""Run store: round trips (hypothesis), life cycle, validation, recovery, concurrency, export."""

from __future__ import annotations

import math
import os
import re
import sqlite3
import subprocess
import sys
import threading
from typing import Any

import h5py
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from bench.app.export import export_csv, export_hdf5, read_csv_export, read_hdf5_export
from bench.core.store import (
    SCHEMA_VERSION,
    RunClosedError,
    RunStore,
    RunWriter,
    SchemaVersionError,
    UnknownAttachmentError,
    UnknownRunError,
    UnknownStreamError,
    liveness,
)

LINUX_PROC = os.path.exists("/proc/self/stat")


def new_run(store: RunStore, **overrides: Any) -> RunWriter:
    """A run with plausible metadata; ``overrides`` may be invalid on purpose (validation tests)."""
    kwargs: dict[str, Any] = dict(procedure="tumble_calibration", parameters={"n_positions": 6},
                  station={"name": "sim"}, unit_serial="SN-001", seed=7, code_version="0.1.0")
    kwargs.update(overrides)
    return store.create_run(**kwargs)


@pytest.fixture(scope="module")
def shared_store(tmp_path_factory):
    store = RunStore(tmp_path_factory.mktemp("store") / "bench.sqlite")
    yield store
    store.close()


@pytest.fixture
def store(tmp_path):
    store = RunStore(tmp_path / "sub" / "bench.sqlite")
    yield store
    store.close()


# -- samples round trip -----------------------------------------------------------------------
VALUE_DTYPES = [np.float64, np.float32, np.int16, np.uint64, np.bool_]


@st.composite
def chunk_sequences(draw):
    dtype = np.dtype(draw(st.sampled_from(VALUE_DTYPES)))
    lengths = draw(st.lists(st.integers(0, 40), min_size=0, max_size=8))
    chunks = []
    for n in lengths:
        t = draw(hnp.arrays(np.float64, n, elements=st.floats(allow_nan=True, allow_infinity=True)))
        v = draw(hnp.arrays(dtype, n))  # floats include NaN and ±inf by default
        chunks.append((t, v))
    return dtype, chunks


@given(data=chunk_sequences())
@settings(max_examples=60, deadline=None)
def test_load_returns_exact_concatenation_of_appended_chunks(shared_store, data):
    dtype, chunks = data
    run = new_run(shared_store)
    run.add_stream("imu", {"t_s": "s", "value": "1"}, dtypes={"value": dtype})
    run.add_stream("other", {"x_v": "V"})
    expected_last_t = None
    for t, v in chunks:
        run.append("imu", t_s=t, value=v)
        run.append("other", x_v=np.arange(2.0))  # interleaved stream must not mix in
        finite = t[np.isfinite(t)]
        if finite.size:
            previous = -np.inf if expected_last_t is None else expected_last_t
            expected_last_t = max(finite[-1], previous)
    loaded = shared_store.load(run.id, "imu")
    want_t = np.concatenate([t for t, _ in chunks] + [np.empty(0)])
    want_v = np.concatenate([v for _, v in chunks] + [np.empty(0, dtype)])
    assert list(loaded) == ["t_s", "value"]
    assert loaded["value"].dtype == dtype and loaded["t_s"].dtype == np.float64
    assert loaded["t_s"].tobytes() == want_t.tobytes()  # bit-exact, NaN payloads included
    assert loaded["value"].tobytes() == want_v.tobytes()
    info = shared_store.streams(run.id)["imu"]
    assert info.n_rows == len(want_t)
    assert info.n_chunks == sum(1 for t, _ in chunks if len(t))  # empty appends store nothing
    assert len(shared_store.load(run.id, "other")["x_v"]) == 2 * len(chunks)
    assert shared_store.get_run(run.id).last_sample_t_s == expected_last_t == run.last_sample_t_s


def test_append_casts_losslessly_and_keeps_declared_dtype(store):
    run = new_run(store)
    run.add_stream("s", {"t_s": "s", "count": "1"}, dtypes={"count": "int32"})
    run.append("s", t_s=[0, 1], count=np.array([3, 4], dtype=np.int8))  # ints into float64: safe
    run.append("s", t_s=np.array([True]), count=[5])
    out = store.load(run.id, "s")
    assert out["t_s"].tolist() == [0.0, 1.0, 1.0] and out["t_s"].dtype == np.float64
    assert out["count"].tolist() == [3, 4, 5] and out["count"].dtype == np.int32
    assert store.streams(run.id)["s"].dtypes == {"t_s": "<f8", "count": "<i4"}


@pytest.mark.parametrize(("dtype", "values", "fits"), [
    ("int32", [5, -7], True), ("int32", [2**40], False), ("int32", [1.0, 2.0], True),
    ("int32", [1.5], False), ("int32", [np.nan], False), ("uint64", [-1], False),
    ("int64", np.array([2**64 - 1], np.uint64), False), ("float32", [1.0, np.nan, -np.inf], True),
    ("float32", [0.1], False), ("float32", [2**24 + 1], False), ("bool", [0, 1], True),
    ("bool", [2], False),
])
def test_append_accepts_values_that_fit_the_declared_dtype_exactly(store, dtype, values, fits):
    run = new_run(store)
    run.add_stream("s", {"v": "1"}, dtypes={"v": dtype})
    if fits:
        run.append("s", v=values)
        got = store.load(run.id, "s")["v"]
        assert np.array_equal(got, np.asarray(values, dtype=np.float64), equal_nan=True)
    else:
        with pytest.raises(TypeError, match=f"exactly as the declared {dtype}"):
            run.append("s", v=values)


# -- events, attachments, results -------------------------------------------------------------
json_values = st.recursive(
    st.none() | st.booleans() | st.integers(-(2**70), 2**70)
    | st.floats(allow_nan=False) | st.text(max_size=10),
    lambda inner: st.lists(inner, max_size=4)
    | st.dictionaries(st.text(max_size=5), inner, max_size=4),
    max_leaves=12,
)


@given(results=st.dictionaries(st.text(min_size=1, max_size=8), json_values, max_size=5),
       events=st.lists(st.tuples(st.floats(allow_nan=False, allow_infinity=False),
                                 st.text(min_size=1, max_size=8), st.text(max_size=20),
                                 st.dictionaries(st.sampled_from(["a", "b", "c"]), json_values)),
                       max_size=5),
       blobs=st.dictionaries(st.from_regex(r"[a-z][a-z0-9_.-]{0,12}", fullmatch=True),
                             st.binary(max_size=64), max_size=3))
@settings(max_examples=30, deadline=None)
def test_events_attachments_results_round_trip(shared_store, results, events, blobs):
    run = new_run(shared_store)
    for key, value in results.items():
        run.set_result(key, value)
    for t, kind, message, data in events:
        run.event(t, kind, message, **data)
    for name, payload in blobs.items():
        run.attach(name, payload, "application/octet-stream")
    assert shared_store.results(run.id) == results
    assert shared_store.get_run(run.id).results == results
    assert [tuple(e) for e in shared_store.events(run.id)] == [tuple(e) for e in events]
    assert {a.name: a.size_bytes for a in shared_store.attachments(run.id)} == {
        n: len(p) for n, p in blobs.items()}
    for name, payload in blobs.items():
        assert shared_store.attachment(run.id, name) == payload


def test_numpy_values_and_nonfinite_metadata_are_stored_as_json(store):
    run = new_run(store, parameters={"rate_dps": np.float32(10.5), "axes": np.arange(3)})
    run.set_result("bias_dps", np.float64("nan"))
    run.set_result("bias_dps", np.float64(0.25))  # replaced, not duplicated
    run.event(1.5, "limit", "over range", value=np.int64(3), trace=np.array([1.0, np.inf]))
    info = store.get_run(run.id)
    assert info.parameters == {"rate_dps": 10.5, "axes": [0, 1, 2]}
    assert info.results == {"bias_dps": 0.25}
    (event,) = store.events(run.id)
    t_s, kind, message, data = event
    assert (t_s, kind, message, data["value"]) == (1.5, "limit", "over range", 3)
    assert data["trace"][0] == 1.0 and math.isinf(data["trace"][1])
    run.event(float("nan"), "teardown_error", "clock unreadable")  # NaN: time unknown
    assert math.isnan(store.events(run.id)[1].t_s)


# -- life cycle ---------------------------------------------------------------------------
def test_exception_in_with_block_aborts_keeps_data_and_reraises(store):
    with pytest.raises(ZeroDivisionError):
        with new_run(store) as run:
            run.add_stream("dmm", {"t_s": "s", "voltage_v": "V"})
            run.append("dmm", t_s=[0.0, 0.5], voltage_v=[1.0, 2.0])
            raise ZeroDivisionError("division by zero")
    info = store.get_run(run.id)
    assert (info.status, info.reason) == ("aborted", "ZeroDivisionError: division by zero")
    assert info.ended_utc is not None and info.last_sample_t_s == 0.5
    assert store.load(run.id, "dmm")["voltage_v"].tolist() == [1.0, 2.0]
    with pytest.raises(RunClosedError):
        run.append("dmm", t_s=[1.0], voltage_v=[3.0])


def test_keyboard_interrupt_aborts_and_normal_exit_completes(store):
    with pytest.raises(KeyboardInterrupt):
        with new_run(store) as interrupted:
            raise KeyboardInterrupt
    with new_run(store) as normal:
        pass
    with pytest.raises(RuntimeError, match="after"):
        with new_run(store) as passed:
            passed.finish("passed")
            raise RuntimeError("after finishing")
    assert (store.get_run(interrupted.id).status, store.get_run(interrupted.id).reason) == (
        "aborted", "KeyboardInterrupt")
    assert store.get_run(normal.id).status == "completed"
    assert store.get_run(passed.id).status == "passed"  # the verdict stands


def test_finish_validates_and_guards_repeats(store):
    run = new_run(store)
    with pytest.raises(ValueError, match="'running'"):
        run.finish("running")
    with pytest.raises(ValueError, match="reason"):
        run.finish("aborted")
    run.finish("failed", "bias out of limits")
    run.finish("failed", "bias out of limits")  # idempotent
    with pytest.raises(RunClosedError, match="already finished"):
        run.finish("passed")
    for call in (lambda: run.event(0.0, "x"), lambda: run.set_result("k", 1),
                 lambda: run.attach("a", b"", "text/plain")):
        with pytest.raises(RunClosedError):
            call()
    info = store.get_run(run.id)
    assert (info.status, info.reason) == ("failed", "bias out of limits")


def test_close_aborts_unfinished_writers_even_dropped_ones(tmp_path):
    store = RunStore(tmp_path / "b.sqlite")
    ids = [new_run(store).id for _ in range(2)]  # writers dropped at once
    kept = new_run(store)
    kept.finish("passed")
    store.close()
    with RunStore(tmp_path / "b.sqlite") as reopened:
        assert [reopened.get_run(i).status for i in ids] == ["aborted", "aborted"]
        assert "store closed" in reopened.get_run(ids[0]).reason
        assert reopened.get_run(kept.id).status == "passed"


def test_list_runs_newest_first_with_limit_and_ids_are_unique(store):
    ids = [new_run(store, procedure=f"p{i}").id for i in range(40)]
    listed = store.list_runs()
    assert [r.id for r in listed] == ids[::-1]
    assert [r.id for r in store.list_runs(limit=3)] == ids[::-1][:3]
    assert len(set(ids)) == 40
    assert all(re.fullmatch(r"\d{8}-\d{6}-[0-9a-f]{4}", i) for i in ids)
    assert (listed[0].status, listed[0].seed, listed[0].unit_serial) == ("running", 7, "SN-001")
    with pytest.raises(ValueError, match="limit"):
        store.list_runs(limit=0)


def test_find_runs_by_procedure_and_parameters_newest_first(store):
    a = new_run(store, procedure="static_record", parameters={"source_sha256": "aa", "n": 1}).id
    b = new_run(store, procedure="static_record", parameters={"source_sha256": "bb"}).id
    c = new_run(store, procedure="static_record", parameters={"source_sha256": "aa", "n": 2}).id
    new_run(store, procedure="tumble_record", parameters={"source_sha256": "aa"})
    assert store.find_runs("static_record", source_sha256="aa") == [c, a]
    assert store.find_runs("static_record", source_sha256="aa", n=1) == [a]
    assert store.find_runs("static_record") == [c, b, a]
    assert store.find_runs("static_record", source_sha256="zz") == [] and store.find_runs("nothing") == []


# -- errors -------------------------------------------------------------------------------
@pytest.mark.parametrize("method", ["get_run", "streams", "events", "attachments", "results"])
def test_unknown_run_id_raises_lookup_error_naming_it(store, method):
    with pytest.raises(LookupError, match="no-such-run") as err:
        getattr(store, method)("no-such-run")
    assert isinstance(err.value, UnknownRunError)


def test_unknown_stream_and_attachment_name_what_exists(store):
    run = new_run(store)
    run.add_stream("dmm", {"t_s": "s"})
    run.attach("plot.png", b"\x89PNG", "image/png")
    with pytest.raises(UnknownStreamError, match=r"'imu'.*\['dmm'\]"):
        store.load(run.id, "imu")
    with pytest.raises(UnknownAttachmentError, match=r"'log.txt'.*\['plot.png'\]"):
        store.attachment(run.id, "log.txt")
    with pytest.raises(UnknownRunError):
        store.load("nope", "dmm")
    with pytest.raises(UnknownStreamError, match="'imu'"):
        run.append("imu", t_s=[1.0])


BAD_APPENDS = [
    (dict(t_s=[1.0]), ValueError, r"missing \['voltage_v'\]"),
    (dict(t_s=[1.0], voltage_v=[1.0], z=[1.0]), ValueError, r"unknown \['z'\]"),
    (dict(t_s=[1.0, 2.0], voltage_v=[1.0]), ValueError, "equal lengths"),
    (dict(t_s=[[1.0]], voltage_v=[1.0]), ValueError, "1-D"),
    (dict(t_s=1.0, voltage_v=[1.0]), ValueError, "1-D"),
    (dict(t_s=["a"], voltage_v=[1.0]), TypeError, "<U1"),
    (dict(t_s=[1.0], voltage_v=np.array([0.1])), TypeError, "float32"),  # lossy f8 -> f4
    (dict(t_s=[1 + 1j], voltage_v=[1.0]), TypeError, "complex"),
]


@pytest.mark.parametrize(("columns", "error", "match"), BAD_APPENDS)
def test_append_validation(store, columns, error, match):
    run = new_run(store)
    run.add_stream("dmm", {"t_s": "s", "voltage_v": "V"}, dtypes={"voltage_v": "float32"})
    with pytest.raises(error, match=match):
        run.append("dmm", **columns)
    assert store.streams(run.id)["dmm"].n_rows == 0


def test_declaration_and_metadata_validation(store):
    run = new_run(store)
    run.add_stream("dmm", {"t_s": "s"})
    cases = [
        (lambda: run.add_stream("dmm", {"t_s": "s"}), ValueError, "already declared"),
        (lambda: run.add_stream("bad name", {"t_s": "s"}), ValueError, "stream name"),
        (lambda: run.add_stream("s2", {}), ValueError, "non-empty"),
        (lambda: run.add_stream("s3", {"1x": "s"}), ValueError, "identifier"),
        (lambda: run.add_stream("s4", {"x": "s"}, dtypes={"x": complex}), TypeError, "complex"),
        (lambda: run.add_stream("s5", {"x": "s"}, dtypes={"y": float}), ValueError, r"\['y'\]"),
        (lambda: run.event(float("inf"), "step"), ValueError, "finite or NaN"),
        (lambda: run.event("1.0", "step"), TypeError, "seconds"),
        (lambda: run.event(1.0, ""), ValueError, "kind"),
        (lambda: run.event(1.0, "step", obj=object()), TypeError, "not JSON-serialisable"),
        (lambda: run.attach("a/b", b"", "text/plain"), ValueError, "attachment name"),
        (lambda: run.attach("a", "text", "text/plain"), TypeError, "bytes-like"),
        (lambda: run.attach("a", b"", "plain"), ValueError, "mime"),
        (lambda: run.set_result("k", {1, 2}), TypeError, "result 'k'"),
        (lambda: new_run(store, parameters={"f": print}), TypeError, "parameters"),
        (lambda: new_run(store, seed=1.5), TypeError, "seed"),
        (lambda: new_run(store, procedure=""), ValueError, "procedure"),
    ]
    for call, error, match in cases:
        with pytest.raises(error, match=match):
            call()
    run.attach("a", b"1", "text/plain")
    with pytest.raises(ValueError, match="already exists"):
        run.attach("a", b"2", "text/plain")
    assert store.attachment(run.id, "a") == b"1"
    assert len(store.list_runs()) == 1  # rejected create_run calls left no run behind


# -- schema and pragmas --------------------------------------------------------------------
def test_schema_version_and_wal_full(store):
    assert store.schema_version() == SCHEMA_VERSION
    conn = store._db.connection()
    assert conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    assert conn.execute("PRAGMA synchronous").fetchone()[0] == 2  # FULL


def test_newer_schema_is_refused(tmp_path):
    RunStore(tmp_path / "b.sqlite").close()
    with sqlite3.connect(tmp_path / "b.sqlite") as conn:
        conn.execute("UPDATE meta SET value = '99' WHERE key = 'schema_version'")
    with pytest.raises(SchemaVersionError, match="99"):
        RunStore(tmp_path / "b.sqlite")


def test_a_foreign_sqlite_file_is_not_taken_over(tmp_path):
    with sqlite3.connect(tmp_path / "other.sqlite") as conn:
        conn.execute("CREATE TABLE customers (name TEXT)")
    with pytest.raises(SchemaVersionError, match="customers"):
        RunStore(tmp_path / "other.sqlite")


# -- recovery of runs whose writer died -------------------------------------------------------
def _set_writer(path, run_id, **columns):
    with sqlite3.connect(path) as conn:
        sets = ", ".join(f"{k} = ?" for k in columns)
        conn.execute(f"UPDATE runs SET {sets} WHERE id = ?", (*columns.values(), run_id))


@pytest.mark.skipif(not LINUX_PROC, reason="process start times come from /proc")
def test_recovery_judges_writers_by_host_pid_and_start_time(tmp_path):
    path = tmp_path / "b.sqlite"
    store = RunStore(path)
    live, reused_pid, rebooted, foreign = (new_run(store) for _ in range(4))
    me = liveness.current_process()
    boot, namespace, ticks = me.start_token.split("|")
    _set_writer(path, reused_pid.id, writer_start=f"{boot}|{namespace}|{int(ticks) + 1}")
    _set_writer(path, rebooted.id, writer_start=f"other-boot|{namespace}|{ticks}")
    _set_writer(path, foreign.id, writer_host="another-host")
    with RunStore(path) as reader:  # opening recovers automatically
        status = {r.id: (r.status, r.reason) for r in reader.list_runs()}
        assert status[live.id] == ("running", None)  # this very process: alive
        assert status[reused_pid.id] == status[rebooted.id] == ("aborted", "interrupted")
        assert status[foreign.id] == ("running", None)  # cannot be judged from here
        assert reader.recover_interrupted(include_other_hosts=True) == [foreign.id]
        assert reader.get_run(foreign.id).ended_utc is not None
    live.finish("passed")
    with pytest.raises(RunClosedError, match="interrupted"):
        reused_pid.event(1.0, "note")  # the store closed the run: its writer may not revive it
    store.close()


@pytest.mark.skipif(not LINUX_PROC or not hasattr(os, "waitid"), reason="needs /proc and waitid")
def test_a_zombie_writer_is_dead():
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    os.waitid(os.P_PID, child.pid, os.WEXITED | os.WNOWAIT)  # exited, not yet reaped
    try:
        identity = liveness.ProcessIdentity(liveness.current_process().host, child.pid,
                                            liveness._start_token(child.pid))
        assert identity.start_token is not None
        assert liveness.liveness(identity) is liveness.Liveness.DEAD
        assert liveness.liveness(liveness.current_process()) is liveness.Liveness.ALIVE
    finally:
        child.wait()


# -- concurrent readers ----------------------------------------------------------------------
def test_reader_in_another_connection_sees_only_whole_committed_chunks(tmp_path):
    path = tmp_path / "b.sqlite"
    n_chunks, chunk = 150, 64
    seen: list[int] = []
    errors: list[BaseException] = []
    done = threading.Event()
    with RunStore(path) as writer_store:
        run = new_run(writer_store)
        run.add_stream("s", {"t_s": "s", "v": "1"})

        def read() -> None:
            with RunStore(path) as reader:
                while not done.is_set() or not seen or seen[-1] < n_chunks * chunk:
                    data = reader.load(run.id, "s")
                    n = len(data["t_s"])
                    try:
                        assert len(data["v"]) == n and n % chunk == 0
                        assert np.array_equal(data["t_s"], np.arange(n, dtype=float))
                        assert np.array_equal(data["v"], -np.arange(n, dtype=float))
                    except AssertionError as exc:
                        errors.append(exc)
                        return
                    seen.append(n)

        thread = threading.Thread(target=read)
        thread.start()
        for i in range(n_chunks):
            t = np.arange(i * chunk, (i + 1) * chunk, dtype=float)
            run.append("s", t_s=t, v=-t)
        done.set()
        thread.join(timeout=60)
        run.finish("completed")
    assert not errors, errors
    assert seen == sorted(seen) and seen[-1] == n_chunks * chunk


def test_threads_sharing_one_writer_append_without_losing_chunks(store):
    run = new_run(store)
    for name in ("a", "b"):
        run.add_stream(name, {"t_s": "s"})
    errors: list[BaseException] = []

    def pump(name: str) -> None:
        try:
            for i in range(60):
                run.append(name, t_s=[float(i)])
                run.event(float(i), name)
        except BaseException as exc:
            errors.append(exc)

    threads = [threading.Thread(target=pump, args=(n,)) for n in ("a", "b")]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout=60)
    assert not errors, errors
    for name in ("a", "b"):
        assert store.load(run.id, name)["t_s"].tolist() == [float(i) for i in range(60)]
    assert len(store.events(run.id)) == 120 and run.last_sample_t_s == 59.0


# -- export round trips --------------------------------------------------------------------
@pytest.fixture
def exported_run(store):
    with new_run(store, seed=2**70) as run:
        run.add_stream("dmm", {"t_s": "s", "voltage_v": "V"}, "DMM trace")
        run.add_stream("flags", {"t_s": "s", "ok": "1", "code": "1"},
                       dtypes={"ok": bool, "code": np.uint64})
        rng = np.random.default_rng(1)
        for n in (5, 0, 7):
            t = np.cumsum(rng.random(n))
            run.append("dmm", t_s=t, voltage_v=np.r_[rng.standard_normal(n - 2), np.nan, -np.inf]
                       if n else t)
        run.append("flags", t_s=[0.0, 1.0], ok=[True, False],
                   code=np.array([0, 2**64 - 1], np.uint64))
        run.add_stream("empty", {"x_g": "g"}, dtypes={"x_g": np.float32})
        run.event(0.5, "step", "start", axis=1)
        run.event(2.0, "note", "")
        run.attach("config.json", b'{"a": 1}', "application/json")
        run.attach("raw.bin", bytes(range(256)), "application/octet-stream")
        run.set_result("bias_v", 1e-3)
        run.finish("passed")
    return store, run.id


def _assert_same_run(store, run_id, exported, exact_nan_bits):
    assert exported.run == store.get_run(run_id)
    assert exported.streams == store.streams(run_id)
    assert exported.events == store.events(run_id)
    assert {n: (i, p) for n, (i, p) in exported.attachments.items()} == {
        a.name: (a, store.attachment(run_id, a.name)) for a in store.attachments(run_id)}
    for name in store.streams(run_id):
        original = store.load(run_id, name)
        assert list(exported.data[name]) == list(original)
        for column, values in original.items():
            got = exported.data[name][column]
            assert got.dtype == values.dtype
            if exact_nan_bits:
                assert got.tobytes() == values.tobytes()
            else:
                assert np.array_equal(got, values, equal_nan=values.dtype.kind == "f")


def test_csv_export_round_trips(exported_run, tmp_path):
    store, run_id = exported_run
    paths = export_csv(store, run_id, tmp_path / "out")
    names = [p.name for p in paths]
    assert names[:4] == [f"{run_id}.{s}" for s in ("dmm.csv", "flags.csv", "empty.csv", "json")]
    assert paths[0].read_text().splitlines()[0] == "t_s,voltage_v"
    assert paths[1].read_text().splitlines()[1:] == ["0.0,1,0", "1.0,0,18446744073709551615"]
    _assert_same_run(store, run_id, read_csv_export(paths[3]), exact_nan_bits=False)
    # A file target sets the prefix instead of the run id.
    other = export_csv(store, run_id, tmp_path / "named" / "tumble.csv")
    assert other[0].name == "tumble.dmm.csv" and other[3].name == "tumble.json"
    with pytest.raises(ValueError, match=r"\.csv or \.json"):
        export_csv(store, run_id, tmp_path / "x.txt")


@pytest.mark.parametrize("compression", [None, "gzip"])
def test_hdf5_export_round_trips(exported_run, tmp_path, compression):
    store, run_id = exported_run
    path = export_hdf5(store, run_id, tmp_path / "h5" / "run.h5", compression=compression)
    _assert_same_run(store, run_id, read_hdf5_export(path), exact_nan_bits=True)

    with h5py.File(path) as f:
        assert f["streams/dmm/voltage_v"].attrs["unit"] == "V"
        assert f.attrs["status"] == "passed" and f.attrs["id"] == run_id
