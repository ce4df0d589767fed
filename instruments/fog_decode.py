"""Bulk decoder of the FOG's 20-byte output frames (layout: docs/FOG_SERIAL.md).

Written from the frame specification, independently of the simulator's encoder.  The hot
path has no per-frame Python loop:

1. sync candidates: one vectorised comparison of the first sync byte over the buffer,
   then the other three bytes checked at the candidates only;
2. CRC-32 of every candidate at once, column by column (byte-serial table recursion run
   on a vector of CRC registers, one byte position per step; the constant sync word's
   contribution is folded into the start value);
3. valid frames are taken non-overlapping from the left; fields are read through a
   big-endian structured view of the gathered rows;
4. sequence gaps are counted from the wrapped 32-bit counter.

Bytes of an incomplete frame at the end of a read are kept for the next one, so a frame
split across reads at any byte boundary decodes exactly once.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SYNC = bytes.fromhex("FE81FF47")
FRAME_BYTES = 20
_CRC_END = 16  # the CRC covers bytes 0..15 and sits in 16..19
_WRAP = 1 << 32
_HALF = 1 << 31

_SYNC_WORD = int.from_bytes(SYNC, "big")
_ROW = np.dtype([("sync", ">u4"), ("sequence", ">u4"), ("count", ">i4"),
                 ("temperature", ">i2"), ("status", ">u2"), ("crc", ">u4")])


def _crc32_table() -> np.ndarray:
    """Byte table of the reflected CRC-32 polynomial 0xEDB88320."""
    table = np.arange(256, dtype=np.uint32)
    for _ in range(8):
        table = np.where(table & 1, (table >> 1) ^ np.uint32(0xEDB88320), table >> 1)
    return table.astype(np.uint32)


_TABLE = _crc32_table()


def crc32(data: bytes, register: int = 0xFFFFFFFF) -> int:
    """CRC-32/ISO-HDLC register after ``data`` (no final XOR): scalar reference form."""
    for byte in data:
        register = (register >> 8) ^ int(_TABLE[(register ^ byte) & 0xFF])
    return register


_SYNC_REGISTER = crc32(SYNC)


@dataclass(frozen=True)
class Decoded:
    """Frames found by one :meth:`FrameDecoder.feed` (arrays of equal length)."""

    sequence: np.ndarray      # uint32, as sent
    index: np.ndarray         # int64, unwrapped frame number since $START
    count: np.ndarray         # int64 pulses
    temperature_c: np.ndarray
    status: np.ndarray        # uint16
    dropped: int              # frames missing from the sequence
    corrupt: int              # sync found, CRC wrong
    resync_bytes: int         # bytes discarded outside valid frames
    out_of_order: int         # valid frames whose sequence did not advance (discarded)


class FrameDecoder:
    """Incremental frame decoder: ``feed(bytes) -> Decoded``; keeps partial frames.

    ``expect_start()`` tells it the next frame is the first after ``$START`` (sequence
    0), so frames lost at the very beginning are counted too; otherwise counting starts
    at the first frame seen.
    """

    def __init__(self) -> None:
        self._tail = b""
        self._last_index: int | None = None

    def expect_start(self) -> None:
        self._last_index = -1

    def reset(self) -> None:
        """Forget partial bytes and the sequence (after a stop or a reconnection)."""
        self._tail = b""
        self._last_index = None

    @property
    def pending_bytes(self) -> int:
        return len(self._tail)

    def take_tail(self) -> bytes:
        """Hand over the kept bytes (e.g. to look for a reply after the stream ends)."""
        tail, self._tail = self._tail, b""
        return tail

    def feed(self, data: bytes) -> Decoded:
        raw = self._tail + bytes(data)
        buf = np.frombuffer(raw, dtype=np.uint8)
        last_start = buf.size - FRAME_BYTES  # candidates start at 0..last_start
        if last_start < 0:
            self._tail = raw
            return self._empty()
        found = self._aligned_run(raw, buf)
        if found is None:
            found = self._search(buf, last_start)
        good, rows, corrupt = found
        keep_from = max(int(good[-1]) + FRAME_BYTES if good.size else 0, last_start + 1)
        self._tail = raw[keep_from:]
        resync = keep_from - FRAME_BYTES * good.size
        return self._sequence(rows, corrupt, int(resync))

    @staticmethod
    def _check(block: np.ndarray) -> np.ndarray:
        """Whether each row of ``block`` (m, 20) carries the sync word and a correct CRC."""
        rows = block.view(_ROW)[:, 0]
        m = block.shape[0]
        reg = np.full(m, _SYNC_REGISTER, dtype=np.uint32)
        index = np.empty(m, dtype=np.uint32)
        entry = np.empty(m, dtype=np.uint32)
        for j in range(len(SYNC), _CRC_END):  # one byte column per step, all rows at once
            np.bitwise_xor(reg, block[:, j], out=index)
            np.bitwise_and(index, 0xFF, out=index)
            np.take(_TABLE, index, out=entry)
            np.right_shift(reg, 8, out=reg)
            np.bitwise_xor(reg, entry, out=reg)
        np.bitwise_xor(reg, 0xFFFFFFFF, out=reg)
        return (rows["sync"] == _SYNC_WORD) & (reg == rows["crc"])

    def _aligned_run(self, raw: bytes, buf: np.ndarray):
        """Fast path of an undisturbed stream: back-to-back valid frames from the first
        sync word to the end.  None if anything else is in the buffer."""
        first = raw.find(SYNC)
        if first < 0:
            return None
        k = (buf.size - first) // FRAME_BYTES
        if k == 0:
            return None
        block = buf[first:first + k * FRAME_BYTES].reshape(k, FRAME_BYTES)
        if not self._check(block).all():
            return None
        return first + FRAME_BYTES * np.arange(k), block.view(_ROW)[:, 0], 0

    def _search(self, buf: np.ndarray, last_start: int):
        """General path: every sync candidate checked, valid ones taken left to right."""
        starts = np.flatnonzero(buf[:last_start + 1] == SYNC[0])
        for j in range(1, len(SYNC)):
            starts = starts[buf[starts + j] == SYNC[j]]
        block = np.lib.stride_tricks.sliding_window_view(buf, FRAME_BYTES)[starts]
        valid = self._check(block)
        chosen = np.flatnonzero(valid)
        chosen = chosen[self._non_overlapping(starts[chosen])]
        good = starts[chosen]
        bad = starts[~valid]
        if good.size and bad.size:  # a sync pattern inside a valid frame is not a frame
            k = np.searchsorted(good, bad, side="right") - 1
            inside = (k >= 0) & (bad < good[np.maximum(k, 0)] + FRAME_BYTES)
            bad = bad[~inside]
        return good, block[chosen].view(_ROW)[:, 0], int(bad.size)

    @staticmethod
    def _non_overlapping(pos: np.ndarray) -> np.ndarray:
        """Mask of the positions taken greedily from the left without overlap."""
        if pos.size < 2 or np.all(np.diff(pos) >= FRAME_BYTES):
            return np.ones(pos.size, dtype=bool)
        taken = np.zeros(pos.size, dtype=bool)
        end = -1
        for i, p in enumerate(pos.tolist()):  # only when junk forged a frame overlapping another
            if p >= end:
                taken[i] = True
                end = p + FRAME_BYTES
        return taken

    def _sequence(self, rows: np.ndarray, corrupt: int, resync: int) -> Decoded:
        seq = rows["sequence"].astype(np.int64)
        if seq.size == 0:
            return self._empty(corrupt, resync)
        prev = self._last_index
        if prev is None:
            prev = int(seq[0]) - 1
        step = np.diff(seq, prepend=prev % _WRAP) % _WRAP
        keep: slice | np.ndarray = slice(None)
        out_of_order = 0
        if np.any((step == 0) | (step > _HALF)):
            kept, step = self._drop_out_of_order(seq, prev)
            keep, out_of_order = kept, seq.size - int(kept.sum())
        index = prev + np.cumsum(step)
        if index.size:
            self._last_index = int(index[-1])
        elif self._last_index is None:
            self._last_index = prev
        sel = rows[keep]
        return Decoded(sel["sequence"].astype(np.uint32), index.astype(np.int64),
                       sel["count"].astype(np.int64),
                       sel["temperature"].astype(np.float64) * 0.01,
                       sel["status"].astype(np.uint16), int(np.sum(step - 1)), corrupt,
                       resync, out_of_order)

    @staticmethod
    def _drop_out_of_order(seq: np.ndarray, prev: int) -> tuple[np.ndarray, np.ndarray]:
        keep = np.zeros(seq.size, dtype=bool)
        steps = []
        last = prev % _WRAP
        for i, s in enumerate(seq.tolist()):  # rare path: a repeated or backward frame
            d = (s - last) % _WRAP
            if 0 < d <= _HALF:
                keep[i] = True
                steps.append(d)
                last = s
        return keep, np.asarray(steps, dtype=np.int64)

    def _empty(self, corrupt: int = 0, resync: int = 0) -> Decoded:
        e = np.zeros(0)
        return Decoded(e.astype(np.uint32), e.astype(np.int64), e.astype(np.int64), e,
                       e.astype(np.uint16), 0, corrupt, resync, 0)
