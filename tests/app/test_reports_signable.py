"""A report as a quality department files it, opened where it is read: the acceptance report in
a real browser (Debian's chromium driven by Playwright) loads nothing from outside itself and
shows every figure, its header, approval block and record digest; its PDF renders page by page
(poppler's pdftoppm) and prints the same digest. Screenshots go to
``bench-data/test-artifacts/reports/``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from playwright.sync_api import sync_playwright

from bench.app.cli import main
from bench.core.store import RunStore
from bench.core.store.forward import package
from bench.testing.operator_station import CHROMIUM
from bench.testing.reports import assert_pdf, assert_self_contained, assert_signable
from bench.testing.specs import SHORT_ACCEPTANCE_SPEC

ARTIFACTS = Path(__file__).resolve().parents[2] / "bench-data" / "test-artifacts" / "reports"


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    """One short acceptance run with its report: (run id, report folder, the run's digest)."""
    tmp = tmp_path_factory.mktemp("signable")
    spec = tmp / "short.toml"
    spec.write_text(SHORT_ACCEPTANCE_SPEC)
    store = str(tmp / "b.sqlite")
    assert main(["--store", store, "acceptance", "--unit", "QA-SIM-0003", "--spec", str(spec), "--seed", "2",
                 "--operator", "A. Tester", "--report", str(tmp / "rep"), "--json"]) in (0, 1)
    run_id = json.loads(Path(tmp / "rep").joinpath(next(p.name for p in (tmp / "rep").iterdir()),
                                                   "acceptance.json").read_text())["run_id"]
    with RunStore(store) as s:
        digest = package(s, run_id).digest
    return run_id, tmp / "rep" / run_id, digest


def test_the_report_opens_in_a_browser_with_nothing_from_outside(report):
    run_id, folder, digest = report
    page_html = (folder / "acceptance_report.html").read_text(encoding="utf-8")
    figures = assert_self_contained(page_html, figures=2)
    assert_signable(page_html, digest)
    assert CHROMIUM.exists(), f"{CHROMIUM} missing: run `make chromium` (Debian's chromium package)"
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=str(CHROMIUM), args=["--no-sandbox"])
        try:
            page = browser.new_page()
            asked: list[str] = []
            page.on("request", lambda r: asked.append(r.url) if not r.url.startswith(("data:", "file:")) else None)
            page.goto((folder / "acceptance_report.html").as_uri())
            page.wait_for_load_state("load")
            shown = page.evaluate("Array.from(document.images).map(i => i.complete && i.naturalWidth > 0)")
            assert len(shown) == figures and all(shown)  # every figure decodes from the page itself
            assert asked == []
            header = page.inner_text("table.header")
            assert "QA-SIM-0003" in header and "A. Tester" in header and "spec SHA-256" in header
            assert page.is_visible("table.sign") and "reviewed by" in page.inner_text("table.sign")
            assert digest in page.inner_text("#foot")
            assert not page.is_visible(".pdfonly")  # the PDF's page numbers stay out of the screen page
            page.screenshot(path=str(ARTIFACTS / "acceptance_report.png"), full_page=True)
        finally:
            browser.close()


def test_the_pdf_beside_it_renders_and_prints_the_digest(report):
    run_id, folder, digest = report
    pages = assert_pdf(folder / "acceptance_report.pdf", pages=2,
                       text=["QA-SIM-0003", "A. Tester", "reviewed by", digest, "page 1 of"])
    assert pages <= 8  # a short run's record files on a few pages
