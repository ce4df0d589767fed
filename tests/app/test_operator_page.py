"""The operator page in a real browser (Debian's chromium driven by Playwright): an operator's
whole path for a batch of four — History filled on load, bad input and an unknown serial in
the operator's words, the mount prompt, live plots against time, a prompt of the spec mid-run,
a failing socket, verdicts with the spec's labels, plain units and limits on one line,
reports, the run's seed, a reload, History with its procedure column and filter, station
health, a retest of the failed socket — and an Abort mid-run with the operator's own seed that
leaves the station safe.  A screenshot of each page state is kept under
``bench-data/test-artifacts/operator/``."""

from __future__ import annotations

import json
import urllib.request
from pathlib import Path

import pytest
from playwright.sync_api import expect, sync_playwright

from bench.core.store import RunStore
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
#: the short spec with labels on two of its three measurements (k1 keeps its name)
LABELLED_SPEC = (SHORT_ACCEPTANCE_SPEC
                 .replace('name = "k0"\n', 'name = "k0"\nlabel = "Bias (K0)"\n')
                 .replace('name = "noise_density"\n', 'name = "noise_density"\nlabel = "Noise density"\n'))
ONE_LINE = """(sel) => [...document.querySelectorAll(sel)].every((el) => {
  const r = document.createRange(); r.selectNodeContents(el); return r.getClientRects().length === 1; })"""


def store_startup_run(path: Path, serial: str) -> None:
    """An engineer's `bench run startup` in the station's store: not an acceptance."""
    run = RunStore(path).create_run(procedure="startup", parameters={}, station={}, unit_serial=serial,
                                    seed=0, code_version="test")
    run.set_result("measurement.readings_lost", {"name": "readings_lost", "value": 0, "unit": "readings",
                                                 "low": 0, "high": 0, "marginal": 0, "outcome": "pass"})
    run.finish("passed")


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
    spec.write_text(LABELLED_SPEC + MID_RUN_PROMPT)
    store_startup_run(tmp_path / "bench.sqlite", "QA-SIM-0009")
    failing = {"fixture_units": {"2": {"k0_g": 6e-3}}}  # socket 2's unit: bias out of its limit
    with serve(tmp_path, spec_path=str(spec), simulation=failing) as (url, station):
        page = browser.new_page(viewport={"width": 1400, "height": 1000})
        page.goto(url)
        # History is there on load: the start-up run by its procedure and its own status, no verdict
        startup = page.locator("#history-table tbody tr").first
        expect(startup.locator(".procedure")).to_have_text("startup")
        expect(startup.locator(".result")).to_have_text("passed")
        assert page.locator("#seed-field").is_visible()  # a simulated station takes a seed
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
        page.fill("#serial-2", "XQ-17")  # a serial of no product this station tests
        page.click("#start")
        expect(page.locator("#error")).to_have_text(
            "Serial XQ-17 (socket 2) matches no product this station tests (QA-2000-SIM: serials "
            "QA-SIM-*). Check the label, or ask the test engineer to add the product.")
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
        plotted = page.locator("#plot-1")  # against time: seconds since the step's record began
        assert plotted.get_attribute("data-x-label") == "time since step start, s"
        assert (plotted.get_attribute("data-x-range") or "").startswith("0 ")
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
        assert page.text_content("#socket-2 .reason") == "out of limits: Bias (K0)"
        table = page.text_content("#socket-2 .measurements") or ""  # the spec's words, plain units
        assert all(w in table for w in ("Bias (K0)", "k1", "Noise density", "µg/√Hz", "−4 … 4", "≤ 2.2"))
        assert not any(w in table for w in ("ug/rtHz", "readings_lost", "level_check_g", "noise_density"))
        assert page.evaluate(ONE_LINE, "#sockets td.limits")  # every limit on one line
        assert page.text_content("#socket-1 .seed") == "seed 3"  # the run's seed (the station's)
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

        rows = page.locator("#history-table tbody tr")  # refreshed as the batch ended, newest first
        expect(rows).to_have_count(5)
        assert rows.first.locator(".procedure").text_content() == "acceptance QA-2000-SIM"
        assert rows.last.locator(".procedure").text_content() == "startup"
        page.fill("#history-filter", "qa-sim-0002 fail")
        expect(rows).to_have_count(1)
        assert rows.first.locator(".result").text_content() == "FAIL"
        assert rows.first.locator(".seed-cell").text_content() == "3"
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
    runs = [r for r in station.store.list_runs() if r.procedure == "acceptance"]
    assert len(runs) == 5 and sum(r.unit_serial == SERIALS[2] for r in runs) == 2
    for info in runs:  # the mid-run prompt and its answer are in every unit's record
        events = [(e.kind, e.message) for e in station.store.events(info.id)]
        assert ("operator_prompt", COVER) in events and ("operator_answer", "continue") in events


def test_abort_mid_run_leaves_the_station_safe_and_every_record_says_why(browser, tmp_path):
    with serve(tmp_path) as (url, station):  # the shipped spec: long enough to abort mid-run
        page = browser.new_page(viewport={"width": 1400, "height": 1000})
        page.goto(url)
        page.fill("#operator", "Bo")
        page.fill("#seed", "12345")  # the operator's own seed: the run can be replayed with it
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
        assert {r["seed"] for r in runs} == {12345} and page.text_content("#live-seed") == "seed 12345"
        page.close()
