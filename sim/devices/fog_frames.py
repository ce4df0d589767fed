"""The simulated FOG's binary output frame, encoded in bulk (layout: docs/FOG_SERIAL.md).

This is the *unit's* side of the wire format, written independently of the driver's
decoder (``instruments/fog_decode.py``): a property test round-trips the two, so one bug
cannot hide on both sides.  The CRC here uses the linearity of CRC-32 over a fixed-length
message — the CRC is an affine function of the bytes, so it is a constant XOR one
position-specific table entry per varying byte — where the decoder runs the usual
byte-serial table recursion.
"""

from __future__ import annotations

import zlib

import numpy as np

SYNC = b"\xfe\x81\xff\x47"
FRAME_BYTES = 20
#: bytes covered by the CRC (sync .. status)
CRC_SPAN = 16
BITS_PER_BYTE_ON_LINE = 10  # 8N1: start + 8 data + stop

# status bits (docs/FOG_SERIAL.md)
READY = 1 << 0
SUPPLY = 1 << 1
TEMPERATURE = 1 << 2
OVERRANGE = 1 << 3
BIT_FAIL = 1 << 4
WARMING_UP = 1 << 5
BOOTING = 1 << 6
LINE_OVERFLOW = 1 << 7

TEMPERATURE_LSB_C = 0.01

FRAME_DTYPE = np.dtype([("sync", "S4"), ("sequence", ">u4"), ("count", ">i4"),
                        ("temperature", ">i2"), ("status", ">u2"), ("crc", ">u4")])
assert FRAME_DTYPE.itemsize == FRAME_BYTES


def _affine_crc_tables() -> tuple[int, np.ndarray]:
    """CRC-32 of a 16-byte message = C0 ^ XOR_j T[j, byte_j] for the varying bytes 4..15.

    CRC-32 (init and final XOR all ones) is affine in the message over GF(2) for a fixed
    length: crc(a ^ b) = crc(a) ^ crc(b) ^ crc(0).  With the sync word fixed, C0 is the
    CRC of sync + zeros and T[j, v] = crc(v at position j, zeros elsewhere) ^ crc(zeros).
    """
    zeros = bytes(CRC_SPAN)
    crc_zero = zlib.crc32(zeros)
    tables = np.zeros((CRC_SPAN, 256), dtype=np.uint32)
    for j in range(len(SYNC), CRC_SPAN):
        for v in range(256):
            msg = bytearray(zeros)
            msg[j] = v
            tables[j, v] = zlib.crc32(bytes(msg)) ^ crc_zero
    c0 = zlib.crc32(SYNC + bytes(CRC_SPAN - len(SYNC)))
    return c0, tables


_C0, _TABLES = _affine_crc_tables()


def encode_frames(sequence: np.ndarray, count: np.ndarray, temperature_c: np.ndarray,
                  status: np.ndarray) -> bytes:
    """Bytes of ``n`` consecutive frames.

    ``sequence`` is taken modulo 2³²; ``count`` must fit int32 (the caller saturates);
    ``temperature_c`` is rounded to 0.01 °C and saturated to the int16 range; ``status``
    is a uint16 bit field.
    """
    sequence = np.asarray(sequence, dtype=np.int64)
    n = sequence.size
    frames = np.empty(n, dtype=FRAME_DTYPE)
    frames["sync"] = SYNC
    frames["sequence"] = (sequence & 0xFFFFFFFF).astype(np.uint32)
    counts = np.asarray(count, dtype=np.int64)
    if counts.size and (counts.min() < -(2**31) or counts.max() >= 2**31):
        raise ValueError("frame count outside the int32 range -2**31..2**31-1")
    frames["count"] = counts
    t_lsb = np.rint(np.asarray(temperature_c, dtype=np.float64) / TEMPERATURE_LSB_C)
    frames["temperature"] = np.clip(np.nan_to_num(t_lsb, nan=0.0), -32768, 32767).astype(np.int16)
    frames["status"] = np.asarray(status, dtype=np.int64) & 0xFFFF
    raw = frames.view(np.uint8).reshape(n, FRAME_BYTES)
    crc = np.full(n, _C0, dtype=np.uint32)
    for j in range(len(SYNC), CRC_SPAN):
        crc ^= _TABLES[j, raw[:, j]]
    frames["crc"] = crc
    return frames.tobytes()


def line_rate_ok(rate_hz: int, baud: int) -> bool:
    """Whether ``rate_hz`` frames per second fit a ``baud`` line (8N1)."""
    return rate_hz * FRAME_BYTES * BITS_PER_BYTE_ON_LINE <= baud


def max_rate_hz(baud: int) -> int:
    return baud // (FRAME_BYTES * BITS_PER_BYTE_ON_LINE)
