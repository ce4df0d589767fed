"""Fuzz every server of a simulated station over TCP and count crashes and hangs.

    .venv/bin/python benchmarks/bench_fuzz.py [--messages 100000] [--oversize 20]
        [--timeout-s 5] [--seed 0]

One client thread per server (dmm, dmm_temp, supply, turntable, shaker, sim-control and
the gyro's serial line) sends its share of ``--messages``: valid commands and queries,
invalid headers, lexically broken messages, binary junk, blocks declared and never sent,
plus ``--oversize`` messages over the 1 MiB limit spread over the SCPI servers.  After
each message the client probes the server (``SYST:ERR?;*CLS``; ``$ID?`` on the gyro
line; the probe's expected fate comes from a reference framer, see bench/testing/fuzz_wire.py).

Prints: messages tried; crashes (a connection the server dropped, a handler exception
logged, or a server that no longer answers ``*IDN?`` at the end); hangs (a reply due and
not received within ``--timeout-s``); invalid messages answered with the standard error;
messages/s; and how many queries a well-behaved client on its own connection to the
supply got answered meanwhile (with its slowest round trip).  There is no peer library
for this figure: the counts, not the speed, are the result.  Exit status 0 only when
there were no crashes, hangs or wrong replies.
"""

from __future__ import annotations

import argparse
import logging
import random
import sys
import threading
import time

from bench.testing.fuzz_wire import GyroFuzzClient, NoReplyError, ScpiFuzzClient, Tally, gyro_line, scpi_message
from sim.station import SimulatedStation

VALID = {  # messages each server must take without an error
    "dmm": ["VOLT:NPLC 1", "VOLT:NPLC?", "TRIG:COUN 3", "TRIG:COUN?", "SAMP:COUN 5",
            "VOLT:RANG 10", "VOLT:RANG?", 'DISP:TEXT "fuzz"', "DATA:POIN?"],
    "dmm_temp": ["VOLT:NPLC 10", "VOLT:NPLC?", "TRIG:SOUR IMM", "TRIG:SOUR?"],
    "supply": ["VOLT 5,(@2)", "VOLT? (@1,2,3)", "CURR 0.5,(@2)", "CURR? (@2)", "INST:NSEL 2",
               "INST:NSEL?", "OUTP? (@1,2,3)"],
    "turntable": ["LIM:RATE 1,50", "LIM:RATE? 1", "MODE? 2", "STAT? 1", "DEM:POS? 1", "STOP 2"],
    "shaker": ["RAMP 2", "RAMP?", "LEV -3", "LEV?", "STAT?", "INT?"],
    "sim": ["SIM:TIME?", "SIM:SEED?", "SIM:INST:LIST?"],
}
COMMON = ["*IDN?", "*ESR?", "*STB?", "*OPC?", "*ESE 4", "*SRE?", "SYST:ERR?"]


class HandlerFailures(logging.Handler):
    """Counts exceptions the server logs from a client handler (each one dropped a client)."""

    def __init__(self) -> None:
        super().__init__(logging.ERROR)
        self.count = 0

    def emit(self, record: logging.LogRecord) -> None:
        self.count += 1


def _classify(exc: NoReplyError) -> tuple[int, int]:
    """(crash, hang): a connection the server closed is a crash, a silence a hang."""
    closed = "closed" in str(exc)
    return int(closed), int(not closed)


def fuzz_scpi(port: int, name: str, n: int, oversize: int, seed: int, timeout_s: float,
              out: dict) -> None:
    rng = random.Random(f"{seed}:{name}")
    valid = [(m, 1 if "?" in m else 0) for m in VALID[name] + COMMON]
    tally, crashes, hangs = Tally(), 0, 0
    big_every = max(1, n // oversize) if oversize else 0
    client = ScpiFuzzClient("127.0.0.1", port, timeout_s=timeout_s)
    for i in range(n):
        if big_every and i % big_every == big_every - 1 and i // big_every < oversize:
            message, expect, replies = (b"ZQX " + b"A" * ((1 << 20) + 1), "oversize", 0)
        else:
            message, expect, replies = scpi_message(rng, valid, big=False)
        try:
            client.send(message, expect, replies, tally)
        except NoReplyError as exc:
            c, h = _classify(exc)
            crashes, hangs = crashes + c, hangs + h
            client.conn.connect()
    client.close()
    out[name] = (tally, crashes, hangs)


def fuzz_gyro(port: int, n: int, seed: int, timeout_s: float, out: dict) -> None:
    rng = random.Random(f"{seed}:gyro")
    tally, crashes, hangs = Tally(), 0, 0
    client = GyroFuzzClient("127.0.0.1", port, timeout_s=timeout_s)
    for _ in range(n):
        line, expect = gyro_line(rng)
        try:
            client.send(line, expect, tally)
        except NoReplyError as exc:
            c, h = _classify(exc)
            crashes, hangs = crashes + c, hangs + h
            client.conn.connect()
    client.close()
    out["gyro"] = (tally, crashes, hangs)


def well_behaved(port: int, stop: threading.Event, timeout_s: float, out: dict) -> None:
    client = ScpiFuzzClient("127.0.0.1", port, timeout_s=timeout_s)
    served, failed, worst_s = 0, 0, 0.0
    while not stop.is_set():
        t0 = time.perf_counter()
        try:
            ok = client.identify().startswith(b"Keysight Technologies,E36312A,")
        except NoReplyError:
            ok = False
            client.conn.connect()
        worst_s = max(worst_s, time.perf_counter() - t0)
        served += ok
        failed += not ok
    client.close()
    out["good"] = (served, failed, worst_s)


def _still_answering(ports: dict, timeout_s: float) -> list[str]:
    dead = []
    for name in VALID:
        client = ScpiFuzzClient("127.0.0.1", ports[name], timeout_s=timeout_s)
        try:
            if client.identify().count(b",") != 3:
                dead.append(name)
        except NoReplyError:
            dead.append(name)
        client.close()
    gyro = GyroFuzzClient("127.0.0.1", ports["gyro"], timeout_s=timeout_s)
    try:
        if not gyro.identify().startswith(b"$ID,"):
            dead.append("gyro")
    except NoReplyError:
        dead.append("gyro")
    gyro.close()
    return dead


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--messages", type=int, default=100_000)
    parser.add_argument("--oversize", type=int, default=20, help="messages over 1 MiB in all")
    parser.add_argument("--timeout-s", type=float, default=5.0)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    if args.messages < 7 or args.oversize < 0 or args.timeout_s <= 0:
        parser.error("--messages >= 7, --oversize >= 0, --timeout-s > 0")
    failures = HandlerFailures()
    logging.getLogger("sim").addHandler(failures)
    logging.getLogger("sim").setLevel(logging.ERROR)

    names = list(VALID) + ["gyro"]
    counts = [args.messages // len(names) + (i < args.messages % len(names))
              for i in range(len(names))]
    big = [args.oversize // len(VALID) + (i < args.oversize % len(VALID))
           for i in range(len(VALID))]
    with SimulatedStation() as sim:
        ports = {e.name: e.port for e in sim.endpoints}
        # the supply's CH1 powers the gyro: on (the supply fuzz never switches outputs)
        sim.server.call(sim.supply.process, b"APPL CH1,5,1;:OUTP ON,(@1)")
        out: dict = {}
        stop = threading.Event()
        good = threading.Thread(target=well_behaved, args=(ports["supply"], stop, args.timeout_s, out))
        threads = [threading.Thread(target=fuzz_scpi, args=(
            ports[n], n, counts[i], big[i], args.seed, args.timeout_s, out))
            for i, n in enumerate(VALID)]
        threads.append(threading.Thread(target=fuzz_gyro, args=(
            ports["gyro"], counts[-1], args.seed, args.timeout_s, out)))
        t0 = time.perf_counter()
        good.start()
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        elapsed_s = time.perf_counter() - t0
        stop.set()
        good.join()
        dead = _still_answering(ports, args.timeout_s)

    total, crashes, hangs = Tally(), 0, 0
    print(f"{'server':<10} {'messages':>9} {'answered':>9} {'silent':>7} {'invalid':>8} "
          f"{'std error':>9} {'crashes':>8} {'hangs':>6}")
    for name in names:
        tally, c, h = out[name]
        total.add(tally)
        crashes, hangs = crashes + c, hangs + h
        print(f"{name:<10} {tally.sent:>9} {tally.answered:>9} {tally.silent:>7} {tally.invalid:>8} "
              f"{tally.invalid_standard_error:>9} {c:>8} {h:>6}")
    crashes += failures.count + len(dead)
    served, failed, worst_s = out["good"]
    print(f"messages tried: {total.sent} (of which {sum(big)} over the 1 MiB limit)")
    print(f"crashes: {crashes} (dropped connections, handler exceptions {failures.count}, "
          f"servers not answering at the end {dead or 0})")
    print(f"hangs: {hangs} (a due reply missing after {args.timeout_s:g} s)")
    print(f"invalid messages answered with the standard error: {total.invalid_standard_error} "
          f"of {total.invalid}")
    print(f"other wrong replies: {len(total.wrong)}"
          + (f", first {total.wrong[:3]}" if total.wrong else ""))
    print(f"throughput: {total.sent / elapsed_s:,.0f} messages/s ({elapsed_s:.1f} s, each with its probe)")
    print(f"well-behaved client (supply *IDN?, own connection): {served} served, {failed} failed, "
          f"slowest round trip {worst_s * 1e3:.1f} ms")
    clean = crashes == hangs == failed == len(total.wrong) == 0
    return 0 if clean and total.invalid_standard_error == total.invalid else 1


if __name__ == "__main__":
    sys.exit(main())
