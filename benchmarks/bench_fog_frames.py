"""FOG frame decoding rate, side by side with a per-frame ``struct.unpack`` reader, in one run.

    .venv/bin/python benchmarks/bench_fog_frames.py [--frames 1000000] [--seconds 600]

1. The driver's bulk decoder (``instruments.fog_decode.FrameDecoder``) on ≥ 10⁶ frames,
   in frames/s: a clean stream (the aligned fast path) and a damaged one (one junk byte
   every 1000 frames: the general sync search), beside the obvious per-frame reader —
   ``bytes.find`` for the sync word, ``struct.unpack_from`` and ``zlib.crc32`` (C) per
   frame — on the same bytes, with the ratio.  Both must decode the same frames.
2. End to end: the simulated station's gyro streaming at 2 kHz, read through pyserial's
   ``socket://`` by ``SerialGyro.read_frames`` with the bench clock's wait — frames/s of
   wall time beside the 2000 frames/s a real unit delivers (the "keeps up" ratio).
"""

from __future__ import annotations

import argparse
import struct
import time
import zlib
from collections.abc import Callable
from functools import partial
from typing import TypeVar

import numpy as np
import pyvisa
import serial
from pyvisa.resources import MessageBasedResource

from instruments.fog import SerialGyro
from instruments.fog_decode import Decoded, FrameDecoder
from sim.devices.fog_frames import encode_frames
from sim.station import SimStationConfig, SimulatedStation

REAL_TIME_FRAMES_PER_S = 2000.0
SYNC = b"\xfe\x81\xff\x47"
FRAME = struct.Struct(">4sIihHI")


def naive_decode(data: bytes) -> tuple[np.ndarray, np.ndarray]:
    """Per-frame reference reader: (sequence, count) of every frame with a valid CRC."""
    seqs, counts = [], []
    i, end = 0, len(data) - FRAME.size
    crc, unpack = zlib.crc32, FRAME.unpack_from
    while i <= end:
        if data[i:i + 4] != SYNC:
            i = data.find(SYNC, i + 1)
            if i < 0 or i > end:
                break
            continue
        _, seq, count, _, _, stored = unpack(data, i)
        if crc(data[i:i + 16]) == stored:
            seqs.append(seq)
            counts.append(count)
            i += FRAME.size
        else:
            i += 1
    return np.array(seqs, dtype=np.int64), np.array(counts, dtype=np.int64)


T = TypeVar("T")


def best_of(fn: Callable[[], T], repeats: int) -> tuple[float, T]:
    """Best time of ``repeats`` calls, and what the call returned (the same every time)."""
    def run() -> tuple[float, T]:
        t = time.perf_counter()
        out = fn()
        return time.perf_counter() - t, out

    return min((run() for _ in range(repeats)), key=lambda timed: timed[0])


def fresh_decode(data: bytes) -> Decoded:
    """The bench decoder on ``data`` from a fresh start (no tail of an earlier call)."""
    return FrameDecoder().feed(data)


def decoding(n: int) -> None:
    rng = np.random.default_rng(1)
    counts = rng.integers(-3000, 3000, n)
    clean = encode_frames(np.arange(n), counts, rng.uniform(20, 30, n), np.ones(n, dtype=int))
    damaged = b"\x00".join(clean[i:i + 20_000] for i in range(0, len(clean), 20_000))
    print(f"bulk decoding of {n} frames ({len(clean) / 1e6:.0f} MB), best of 3:")
    for label, data in (("clean stream", clean), ("1 junk byte / 1000 frames", damaged)):
        t_ours, got = best_of(partial(fresh_decode, data), 3)
        t_peer, (seq, cnt) = best_of(partial(naive_decode, data), 1)
        assert np.array_equal(got.sequence, seq) and np.array_equal(got.count, cnt) and seq.size == n
        ours, peer = n / t_ours, n / t_peer
        print(f"  {label:27s} ours {ours / 1e6:6.2f} M frames/s   per-frame struct.unpack + "
              f"zlib.crc32 {peer / 1e6:5.2f} M frames/s   ratio {ours / peer:5.1f}x")


def end_to_end(seconds: float) -> None:
    n = int(seconds * REAL_TIME_FRAMES_PER_S)
    with SimulatedStation(SimStationConfig(seed=3)) as station:
        res = station.resources()
        rm = pyvisa.ResourceManager("@py")
        supply = rm.open_resource(res["supply"], read_termination="\n", write_termination="\n")
        clock = rm.open_resource(res["sim"], read_termination="\n", write_termination="\n",
                                 timeout=600_000)
        assert isinstance(supply, MessageBasedResource) and isinstance(clock, MessageBasedResource)
        supply.write("APPL CH1,5,1")
        supply.query("OUTP ON,(@1);*OPC?")
        gyro = SerialGyro(serial.serial_for_url(res["gyro"], baudrate=921600, timeout=5), "gyro")
        gyro.start()

        def wait(s: float) -> None:
            clock.query(f"SIM:TIME:ADV {s!r};*OPC?")

        t = time.perf_counter()
        frames = gyro.read_frames(n, timeout_s=3600, wait=wait)
        wall = time.perf_counter() - t
        gyro.stop()
        gyro.close()
        supply.close()
        clock.close()
        rm.close()
    rate = len(frames) / wall
    print(f"end to end: {len(frames)} frames ({seconds:.0f} s at 2 kHz simulated) through the "
          f"gyro model, socket:// and SerialGyro.read_frames, {frames.dropped} dropped")
    print(f"  ours {rate / 1e3:7.1f} k frames/s   real unit {REAL_TIME_FRAMES_PER_S / 1e3:.1f} k "
          f"frames/s   ratio {rate / REAL_TIME_FRAMES_PER_S:6.0f}x real time (goal >= 1x)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=1_000_000)
    parser.add_argument("--seconds", type=float, default=600.0)
    args = parser.parse_args()
    if args.frames < 1_000_000:
        parser.error(f"--frames {args.frames} must be >= 1000000")
    decoding(args.frames)
    end_to_end(args.seconds)


if __name__ == "__main__":
    main()
