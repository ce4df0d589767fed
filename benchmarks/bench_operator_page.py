"""The operator page under a live batch: plot update rate and page latency, in Debian's chromium.

A batch of four QA-2000 units with the shipped spec (1.9 h of station time, simulated) on the
operator station served on loopback; the page is driven by Playwright.  Measured:

* live plot updates per second, per socket plot, while the batch acquires (first plot to the
  progress reading "done") and from the first plot to the verdicts (reports included); a
  redraw counts when new samples arrived; snapshots received per second (Server-Sent Events);
* the wall time from Continue to the verdicts of one unit alone and of the batch of four,
  and their ratio (the issue's < 1.5×);
* latency: ``GET /api/state`` round trip; Continue clicked → the page shows the run;
  Abort clicked → the page shows every socket aborted (the station made safe in between).

Usage: ``python benchmarks/bench_operator_page.py`` (needs ``make chromium``).
"""

from __future__ import annotations

import statistics
import tempfile
import time
import urllib.request
from pathlib import Path

from bench.testing.operator_station import CHROMIUM, serve

SERIALS = {1: "QA-SIM-0003", 2: "QA-SIM-0002", 3: "QA-SIM-0004", 4: "QA-SIM-0001"}


def main() -> None:
    from playwright.sync_api import sync_playwright  # noqa: PLC0415 — the browser driver (test extra) only when the benchmark runs

    with tempfile.TemporaryDirectory() as tmp, serve(Path(tmp)) as (url, _), sync_playwright() as p:
        browser = p.chromium.launch(executable_path=str(CHROMIUM), args=["--no-sandbox"])
        page = browser.new_page(viewport={"width": 1400, "height": 1000})
        page.goto(url)
        state_ms = []
        for _ in range(50):
            t0 = time.perf_counter()
            with urllib.request.urlopen(url + "/api/state") as r:
                r.read()
            state_ms.append(1000 * (time.perf_counter() - t0))
        page.fill("#operator", "bench")
        # one unit alone through the page: Continue → its verdict (the batch's yardstick)
        page.fill("#serial-1", SERIALS[1])
        page.click("#start")
        page.wait_for_selector("#prompt:not(.hidden)")
        t0 = time.perf_counter()
        page.click("#prompt-continue")
        page.wait_for_selector("body[data-state=done]", timeout=600_000)
        one_s = time.perf_counter() - t0
        for n, serial in SERIALS.items():
            page.fill(f"#serial-{n}", serial)
        page.click("#start")
        page.wait_for_selector("#prompt:not(.hidden)")
        t0 = time.perf_counter()
        page.click("#prompt-continue")
        page.wait_for_selector("body[data-state=running]")
        continue_ms = 1000 * (time.perf_counter() - t0)
        t_batch = t0
        page.wait_for_function("window.plotUpdates > 0", timeout=120_000)
        plots0, msgs0 = page.evaluate("window.plotUpdates"), page.evaluate("window.stateMessages")
        t_live = time.perf_counter()
        # the acquisition ends when the progress reads "done"; the reports follow
        page.wait_for_function("document.getElementById('progress-text').textContent.includes('done')",
                               timeout=600_000, polling=20)
        acquiring_s = time.perf_counter() - t_live
        acquiring_plots = page.evaluate("window.plotUpdates") - plots0
        page.wait_for_selector("body[data-state=done]", timeout=600_000)
        live_s = time.perf_counter() - t_live
        four_s = time.perf_counter() - t_batch
        plots = page.evaluate("window.plotUpdates") - plots0
        msgs = page.evaluate("window.stateMessages") - msgs0
        # a second batch, aborted once its plots move
        page.click("#start")
        page.wait_for_selector("#prompt:not(.hidden)")
        page.click("#prompt-continue")
        page.wait_for_function(f"window.plotUpdates > {page.evaluate('window.plotUpdates') + 4}",
                               timeout=120_000)
        t0 = time.perf_counter()
        page.click("#abort")
        page.wait_for_selector("body[data-state=aborted]", timeout=120_000)
        abort_ms = 1000 * (time.perf_counter() - t0)
        browser.close()
    n = len(SERIALS)
    print(f"Continue → verdicts: 1 unit {one_s:.1f} s, a batch of {n} {four_s:.1f} s: "
          f"ratio {four_s / one_s:.2f}")
    print(f"live batch of 4: {acquiring_s:.1f} s of wall time acquiring, {live_s:.1f} s to the verdicts "
          f"(reports written in {live_s - acquiring_s:.1f} s)")
    print(f"plot updates per socket plot while acquiring: {acquiring_plots / n / acquiring_s:.1f} /s; "
          f"to the verdicts: {plots / n / live_s:.1f} /s   (snapshots received: {msgs / live_s:.1f} /s)")
    print(f"GET /api/state: median {statistics.median(state_ms):.1f} ms, max {max(state_ms):.1f} ms")
    print(f"Continue → page shows the run: {continue_ms:.0f} ms")
    print(f"Abort → page shows every socket aborted (station safe): {abort_ms:.0f} ms")


if __name__ == "__main__":
    main()
