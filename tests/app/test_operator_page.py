"""The operator page in a real browser (Debian's chromium driven by Playwright): an operator's
whole path for a batch of four — bad input, the mount prompt, live plots, a prompt of the
spec mid-run, a failing socket, verdicts with reports, a reload, history, station health, a
retest of the failed socket — and an Abort mid-run that leaves the station safe.  A
screenshot of each page state is kept under ``bench-data/test-artifacts/operator/``."""

from __future__ import annotations

import json
import urllib.request
from pathlib import Path

import pytest
from playwright.sync_api import expect, sync_playwright

from bench.testing.operator_station import CHROMIUM, serve
from bench.testing.specs import SHORT_ACCEPTANCE_SPEC

ARTIFACTS = Path(__file__).resolve().parents[2] / "bench-data" / "test-artifacts" / "operator"
SERIALS = {1: "QA-SIM-0003", 2: "QA-SIM-0002", 3: "QA-SIM-0004", 4: "QA-SIM-0001"}
COVER = "Close the fixture's acoustic cover for the static record"
MID_RUN_PROMPT = f"""
[[prompts]]
before = "accelerometer_noise"
text = "{COVER}"
"""


@pytest.fixture(scope="module")
def browser():
    # a real part never skips: `make test` installs Debian's chromium first (`make chromium`)
    assert CHROMIUM.exists(), f"{CHROMIUM} missing: run `make chromium` (Debian's chromium package)"
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=str(CHROMIUM), args=["--no-sandbox"])
        yield b
        b.close()


def shot(page, name: str) -> None:
    page.screenshot(path=str(ARTIFACTS / f"{name}.png"), full_page=True)


def test_an_operators_batch_of_four_with_a_prompt_and_a_failing_socket(browser, tmp_path):
    spec = tmp_path / "short.toml"
    spec.write_text(SHORT_ACCEPTANCE_SPEC + MID_RUN_PROMPT)
    failing = {"fixture_units": {"2": {"k0_g": 6e-3}}}  # socket 2's unit: bias out of its limit
    with serve(tmp_path, spec_path=str(spec), simulation=failing) as (url, station):
        page = browser.new_page(viewport={"width": 1400, "height": 1000})
        page.goto(url)
        shot(page, "01-start")

        page.click("#start")  # nothing filled in
        expect(page.locator("#error")).to_have_text("operator name is required")
        page.fill("#operator", "Ann Operator")
        page.fill("#serial-1", "QA-SIM-0003")
        page.fill("#serial-2", "QA-SIM-0003")
        page.click("#start")
        expect(page.locator("#error")).to_contain_text("already in another socket")
        page.fill("#serial-2", "not a serial!")
        page.click("#start")
        expect(page.locator("#error")).to_contain_text("serial 'not a serial!' must be")
        shot(page, "02-bad-input")

        for n in range(1, 5):  # a barcode scanner types the serial and Enter
            page.fill(f"#serial-{n}", "")
        page.click("#serial-1")
        for n in range(1, 5):
            page.keyboard.type(SERIALS[n])
            page.keyboard.press("Enter")
        assert page.evaluate("document.activeElement.id") == "serial-5"
        page.click("#start")
        page.wait_for_selector("#prompt:not(.hidden)")
        assert "Mount the units in sockets 1, 2, 3, 4" in (page.text_content("#prompt-text") or "")
        assert page.text_content("#spec") == "spec QA-2000-SIM"
        shot(page, "03-prompt")

        page.click("#prompt-continue")
        page.wait_for_function("window.plotUpdates > 0")
        shot(page, "04-live")
        expect(page.locator("#prompt-text")).to_have_text(COVER, timeout=120_000)  # mid-run
        assert page.locator("body[data-state=running]").count() == 1
        shot(page, "04b-mid-run-prompt")
        page.click("#prompt-continue")
        page.wait_for_selector("body[data-state=done]", timeout=120_000)
        shot(page, "05-verdicts")
        verdicts = {n: page.text_content(f"#socket-{n} .verdict") for n in SERIALS}
        assert verdicts[1] in ("PASS", "PASS (marginal)") and verdicts[2] == "FAIL"
        assert page.locator("#socket-2 td.fail").first.text_content() == "FAIL"
        assert "k0" in (page.text_content("#socket-2 .reason") or "")
        href = page.get_attribute("#socket-2 .report", "href")
        assert href and href.endswith("acceptance_report.html")
        with urllib.request.urlopen(url + href) as r:
            assert SERIALS[2] in r.read().decode()

        page.reload()  # a reload (or a second browser) sees the same state
        page.wait_for_selector("#socket-2 .verdict.FAIL")
        second = browser.new_page()
        second.goto(url)
        second.wait_for_selector("#socket-1 .verdict.PASS")
        second.close()
        shot(page, "06-reload")

        page.fill("#history-serial", "QA-SIM-0002")
        page.click("#history-search")
        page.wait_for_selector("#history-table tbody tr")
        rows = page.locator("#history-table tbody tr")
        assert rows.count() == 1 and "FAIL" in (rows.first.text_content() or "")
        shot(page, "07-history")

        page.click("#doctor-run")
        page.wait_for_selector("#doctor-table tbody tr:nth-child(5)", timeout=60_000)
        health = page.text_content("#doctor-table") or ""
        assert "daq" in health and "keysight_daq970a" in health
        shot(page, "08-health")

        assert page.locator("#retest").is_visible()  # socket 2 failed: its serial, started again
        page.click("#retest")
        page.wait_for_selector("#prompt:not(.hidden)")
        assert "Mount the units in socket 2," in (page.text_content("#prompt-text") or "")
        assert page.input_value("#serial-1") == "" and page.input_value("#serial-2") == SERIALS[2]
        page.click("#prompt-continue")
        expect(page.locator("#prompt-text")).to_have_text(COVER, timeout=120_000)
        page.click("#prompt-continue")
        page.wait_for_selector("body[data-state=done]", timeout=120_000)
        assert page.locator("#sockets .card").count() == 1
        assert page.text_content("#socket-2 .verdict") == "FAIL"
        shot(page, "08b-retest")
        page.close()
    runs = station.store.list_runs()
    assert len(runs) == 5 and sum(r.unit_serial == SERIALS[2] for r in runs) == 2
    for info in runs:  # the mid-run prompt and its answer are in every unit's record
        events = [(e.kind, e.message) for e in station.store.events(info.id)]
        assert ("operator_prompt", COVER) in events and ("operator_answer", "continue") in events


def test_abort_mid_run_leaves_the_station_safe_and_every_record_says_why(browser, tmp_path):
    with serve(tmp_path) as (url, station):  # the shipped spec: long enough to abort mid-run
        page = browser.new_page(viewport={"width": 1400, "height": 1000})
        page.goto(url)
        page.fill("#operator", "Bo")
        for n in SERIALS:
            page.fill(f"#serial-{n}", SERIALS[n])
        page.click("#start")
        page.wait_for_selector("#prompt:not(.hidden)")
        page.click("#prompt-continue")
        page.wait_for_function("window.plotUpdates > 2")
        shot(page, "09-before-abort")
        page.click("#abort")
        page.wait_for_selector("body[data-state=aborted]", timeout=120_000)
        shot(page, "10-aborted")
        assert all(page.text_content(f"#socket-{n} .verdict") == "ABORTED" for n in SERIALS)
        sim = station.last_station.sim
        assert not any(sim.supply.channels[ch].output for ch in (1, 2, 3))  # the units unpowered
        assert sim.fixture.daq.state == "IDLE"                              # the scan stopped
        with urllib.request.urlopen(url + "/api/history?verdict=ABORTED") as r:
            runs = json.loads(r.read())["runs"]
        assert len(runs) == 4 and all(r["reason"] == "aborted by the operator" for r in runs)
        page.close()
