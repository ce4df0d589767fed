"""FOG frames: the simulator's encoder against the driver's decoder (written independently).

Round trips are exact for any field values; any corruption or loss pattern is detected and
counted, never mis-decoded (docs/FOG_SERIAL.md).
"""

from __future__ import annotations

import struct
import zlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from instruments.fog_decode import FRAME_BYTES, FrameDecoder, crc32
from sim.devices.fog_frames import encode_frames

INT32 = st.integers(-(2**31), 2**31 - 1)
TEMP_LSB = st.integers(-32768, 32767)  # temperatures as exact multiples of 0.01 °C
UINT16 = st.integers(0, 0xFFFF)


@st.composite
def frame_fields(draw, max_n: int = 40):
    n = draw(st.integers(1, max_n))
    first = draw(st.integers(0, 2**32 - 1))
    counts = np.array(draw(st.lists(INT32, min_size=n, max_size=n)), dtype=np.int64)
    temp_lsb = np.array(draw(st.lists(TEMP_LSB, min_size=n, max_size=n)), dtype=np.int64)
    status = np.array(draw(st.lists(UINT16, min_size=n, max_size=n)), dtype=np.int64)
    return first + np.arange(n, dtype=np.int64), counts, temp_lsb, status


def encode(fields) -> bytes:
    seq, counts, temp_lsb, status = fields
    return encode_frames(seq, counts, temp_lsb * 0.01, status)


def decode_all(data: bytes, chunks=None, start: bool = False):
    """Feed ``data`` (split at ``chunks`` boundaries) and gather the decoded frames."""
    dec = FrameDecoder()
    if start:
        dec.expect_start()
    cuts = [0, *sorted(chunks or []), len(data)]
    parts = [dec.feed(data[a:b]) for a, b in zip(cuts[:-1], cuts[1:])]
    cat = {f: np.concatenate([getattr(p, f) for p in parts])
           for f in ("sequence", "index", "count", "temperature_c", "status")}
    totals = {f: sum(getattr(p, f) for p in parts)
              for f in ("dropped", "corrupt", "resync_bytes", "out_of_order")}
    return cat, totals, dec


def test_crc_is_crc32_iso_hdlc_with_its_check_value():
    assert crc32(b"123456789") ^ 0xFFFFFFFF == 0xCBF43926
    rng = np.random.default_rng(3)
    for size in (0, 1, 16, 100):
        data = rng.integers(0, 256, size, dtype=np.uint8).tobytes()
        assert crc32(data) ^ 0xFFFFFFFF == zlib.crc32(data)


def test_frame_bytes_match_the_documented_layout():
    frame = encode_frames(np.array([7]), np.array([-3]), np.array([25.0]), np.array([0x81]))
    sync, seq, count, temp, status, crc = struct.unpack(">4sIihHI", frame)
    assert (sync, seq, count, temp, status) == (b"\xfe\x81\xff\x47", 7, -3, 2500, 0x81)
    assert crc == zlib.crc32(frame[:16]) and len(frame) == FRAME_BYTES


@settings(max_examples=150)
@given(frame_fields())
def test_round_trip_is_exact(fields):
    seq, counts, temp_lsb, status = fields
    got, totals, dec = decode_all(encode(fields))
    assert np.array_equal(got["sequence"], seq % 2**32)
    assert np.array_equal(got["index"], seq)  # unwrapped across 2**32
    assert np.array_equal(got["count"], counts)
    assert np.array_equal(np.rint(got["temperature_c"] * 100).astype(np.int64), temp_lsb)
    assert np.array_equal(got["status"], status)
    assert totals == {"dropped": 0, "corrupt": 0, "resync_bytes": 0, "out_of_order": 0}
    assert dec.pending_bytes == 0


@settings(max_examples=150)
@given(frame_fields(), st.data())
def test_reads_split_at_any_byte_boundaries_decode_each_frame_once(fields, data):
    raw = encode(fields)
    cuts = data.draw(st.lists(st.integers(0, len(raw)), max_size=12))
    whole, _, _ = decode_all(raw)
    split, totals, dec = decode_all(raw, cuts)
    for key in whole:
        assert np.array_equal(whole[key], split[key])
    assert totals["resync_bytes"] == 0 and dec.pending_bytes == 0


@given(frame_fields(max_n=60))
def test_fast_path_and_general_search_agree_on_a_clean_stream(fields):
    raw = encode(fields)
    buf = np.frombuffer(raw, dtype=np.uint8)
    dec = FrameDecoder()
    fast = dec._aligned_run(raw, buf)
    general = dec._search(buf, buf.size - FRAME_BYTES)
    assert fast is not None
    assert np.array_equal(fast[0], general[0]) and fast[2] == general[2] == 0
    assert fast[1].tobytes() == general[1].tobytes()


@st.composite
def damaged_stream(draw):
    """An encoded stream (sequence from 0) and a list of damage operations on it."""
    fields = draw(frame_fields(max_n=30))
    fields = (fields[0] - fields[0][0], *fields[1:])
    raw = encode(fields)
    ops = draw(st.lists(st.one_of(
        st.tuples(st.just("flip"), st.integers(0, len(raw) - 1), st.integers(0, 7)),
        st.tuples(st.just("drop"), st.integers(0, len(raw) - 1), st.integers(1, 25)),
        st.tuples(st.just("junk"), st.integers(0, len(raw)), st.binary(min_size=1, max_size=30)),
        st.tuples(st.just("sync"), st.integers(0, len(raw)), st.binary(max_size=18)),
    ), min_size=1, max_size=6))
    return fields, raw, ops


def apply_damage(raw: bytes, ops):
    """Apply the operations; return the damaged bytes and, per original frame, whether its
    20 bytes survive contiguous and unchanged in the result."""
    owner = list(range(len(raw)))  # original byte position of each byte, -1 for junk
    data = bytearray(raw)
    touched = set()
    for op in ops:
        kind, pos = op[0], min(op[1], len(data))
        if kind == "flip" and pos < len(data):
            data[pos] ^= 1 << op[2]
            touched.add(owner[pos])
        elif kind == "drop":
            removed = owner[pos:pos + op[2]]
            touched.update(removed)
            del data[pos:pos + op[2]], owner[pos:pos + op[2]]
        elif kind in ("junk", "sync"):
            junk = op[2] if kind == "junk" else b"\xfe\x81\xff\x47" + op[2]  # a false sync + junk
            data[pos:pos] = junk
            owner[pos:pos] = [-1] * len(junk)
    n = len(raw) // FRAME_BYTES
    where = {o: i for i, o in enumerate(owner) if o >= 0}
    intact = []
    for k in range(n):
        span = range(k * FRAME_BYTES, (k + 1) * FRAME_BYTES)
        ok = all(b in where and b not in touched for b in span)
        ok = ok and where[span[-1]] - where[span[0]] == FRAME_BYTES - 1  # nothing inserted inside
        intact.append(ok)
    return bytes(data), np.array(intact)


@settings(max_examples=300)
@given(damaged_stream(), st.data())
def test_damage_is_detected_and_counted_never_misdecoded(case, data):
    fields, raw, ops = case
    seq, counts, temp_lsb, status = fields
    damaged, intact = apply_damage(raw, ops)
    cuts = data.draw(st.lists(st.integers(0, len(damaged)), max_size=5))
    got, totals, dec = decode_all(damaged, cuts, start=True)
    # never mis-decoded: every decoded frame is the original frame of that sequence number
    idx = got["index"]
    assert np.all(np.diff(idx) > 0)
    assert np.all((idx >= 0) & (idx < seq.size))
    assert np.array_equal(got["sequence"], seq[idx])
    assert np.array_equal(got["count"], counts[idx])
    assert np.array_equal(np.rint(got["temperature_c"] * 100).astype(np.int64), temp_lsb[idx])
    assert np.array_equal(got["status"], status[idx])
    # every frame that survived unchanged is found (a full stream has no incomplete tail
    # except damaged bytes), and every frame missing before the last one found is counted
    assert set(np.flatnonzero(intact)) <= set(idx.tolist())
    if idx.size:
        assert totals["dropped"] == idx[-1] + 1 - idx.size
    # bytes: everything fed is a decoded frame, a skipped byte, or still pending
    assert FRAME_BYTES * idx.size + totals["resync_bytes"] + dec.pending_bytes == len(damaged)
    assert totals["out_of_order"] == 0


@settings(max_examples=100)
@given(frame_fields(max_n=30), st.data())
def test_a_flipped_bit_after_the_sync_word_is_a_counted_crc_failure(fields, data):
    seq, counts, temp_lsb, status = fields
    raw = bytearray(encode((seq - seq[0], counts, temp_lsb, status)))
    n = seq.size
    hit = sorted(data.draw(st.sets(st.integers(0, n - 1), min_size=1, max_size=n)))
    for k in hit:
        byte = data.draw(st.integers(4, FRAME_BYTES - 1))
        raw[k * FRAME_BYTES + byte] ^= 1 << data.draw(st.integers(0, 7))
    got, totals, _ = decode_all(bytes(raw), start=True)
    assert totals["corrupt"] == len(hit)
    assert set(got["index"].tolist()) == set(range(n)) - set(hit)
    trailing = n - 1 - max(set(range(n)) - set(hit), default=-1)  # lost after the last good one
    assert totals["dropped"] == len(hit) - trailing


def test_a_repeated_or_backward_frame_is_discarded_and_counted():
    frames = [encode_frames(np.array([s]), np.array([s * 10]), np.array([20.0]), np.array([1]))
              for s in (0, 1, 2, 1, 3, 3, 4)]
    got, totals, _ = decode_all(b"".join(frames), start=True)
    assert got["sequence"].tolist() == [0, 1, 2, 3, 4]
    assert got["count"].tolist() == [0, 10, 20, 30, 40]
    assert totals["out_of_order"] == 2 and totals["dropped"] == 0


def test_a_gap_in_the_sequence_is_counted_as_dropped_frames_and_wraps():
    seq = np.array([2**32 - 2, 2**32 - 1, 3, 4])  # 0, 1, 2 lost across the wrap
    got, totals, _ = decode_all(encode_frames(seq, np.zeros(4), np.zeros(4), np.zeros(4)))
    assert got["index"].tolist() == [2**32 - 2, 2**32 - 1, 2**32 + 3, 2**32 + 4]
    assert totals["dropped"] == 3


def test_a_forged_valid_frame_overlapping_another_is_resolved_left_to_right():
    a = encode_frames(np.array([0, 1]), np.array([5, 6]), np.zeros(2), np.zeros(2))
    junk = a[:10]  # half a frame, then a full valid copy of frame 1 overlapping nothing
    got, totals, _ = decode_all(junk + a, start=True)
    assert got["sequence"].tolist() == [0, 1] and totals["resync_bytes"] == 10


@pytest.mark.parametrize("n_frames", [1, 3])
def test_incomplete_frame_waits_for_its_remaining_bytes(n_frames):
    raw = encode_frames(np.arange(n_frames), np.arange(n_frames), np.zeros(n_frames),
                        np.zeros(n_frames))
    dec = FrameDecoder()
    first = dec.feed(raw[:-1])
    assert first.count.size == n_frames - 1 and dec.pending_bytes == FRAME_BYTES - 1
    last = dec.feed(raw[-1:])
    assert last.count.tolist() == [n_frames - 1] and dec.pending_bytes == 0
