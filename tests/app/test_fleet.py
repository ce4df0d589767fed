"""``bench sync`` and ``bench fleet`` against a real PostgreSQL server: yield by group with
Wilson intervals, control charts that flag a shifted process, a unit traced across stations (each
view's page with its PDF and the digest of its ``--json`` document at the foot),
``bench runs`` on the central store, and forwarding after a run when BENCH_CENTRAL is set."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest
from statsmodels.stats.proportion import proportion_confint

from bench.app.cli import main
from bench.app.commands.common import forward_after_run
from bench.app.commands.fleet import shown_url
from bench.core.store import RunStore
from bench.testing.reports import assert_self_contained, assert_signable

SPEC = {"model": "QA-T", "kind": "accelerometer", "source": "x.toml", "measurements": []}


def acceptance_run(store: RunStore, serial: str, k0_mg: float, station: str, lot: str) -> str:
    passed = abs(k0_mg) <= 4.0
    with store.create_run(procedure="acceptance", parameters={}, station={}, unit_serial=serial,
                          seed=1, code_version="t",
                          labels={"station_id": station, "lot": lot, "socket": "1"}) as run:
        run.add_stream("dmm", {"t_s": "s", "voltage_v": "V"})
        run.append("dmm", t_s=np.arange(10.0), voltage_v=np.full(10, k0_mg))
        run.set_result("acceptance.spec", SPEC)
        run.set_result("measurement.k0", {"name": "k0", "value": k0_mg, "unit": "mg", "low": -4.0,
                                          "high": 4.0, "marginal": 0.4,
                                          "outcome": "pass" if passed else "fail",
                                          "uncertainty": 0.01})
        run.finish("passed" if passed else "failed")
    return run.id


def assert_signable_page(html: Path, printed_json: str) -> str:
    """The page is one file with its PDF beside it, an approval block, and at its foot the SHA-256
    of the view's ``--json`` document as the command printed it; returns the page."""
    page = html.read_text(encoding="utf-8")
    assert_self_contained(page)
    assert html.with_suffix(".pdf").read_bytes()[:5] == b"%PDF-" and "reviewed by" in page
    assert_signable(page, hashlib.sha256(printed_json.encode()).hexdigest())
    return page


def cli(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.fixture
def fleet(tmp_path, central_url, capsys):
    """Two stations' runs forwarded: 30 units on ST-A (a shift after unit 20), 10 on ST-B."""
    rng = np.random.default_rng(5)
    a, b = tmp_path / "a.sqlite", tmp_path / "b.sqlite"
    with RunStore(a) as store:
        for i in range(30):
            acceptance_run(store, f"QA-{i:03d}", rng.normal(0, 1) + (4.0 if i >= 20 else 0.0),
                           "ST-A", f"L{i // 10}")
    with RunStore(b) as store:
        for i in range(10):
            acceptance_run(store, f"QA-{i:03d}", rng.normal(0, 1), "ST-B", "L9")  # re-tests
    for path in (a, b):
        code, out, _ = cli(capsys, "--store", str(path), "sync", "--central", central_url)
        assert code == 0 and " 0 queued" in out
    return central_url


def test_yield_by_station_with_wilson_intervals(fleet, capsys, tmp_path):
    code, out, _ = cli(capsys, "fleet", "yield", "--by", "station", "--central", fleet, "--json",
                       "--html", str(tmp_path / "y.html"))
    doc = json.loads(out)
    groups = {g["group"]: g for g in doc["groups"]}
    assert code == 0 and set(groups) == {"ST-A", "ST-B"}
    a = groups["ST-A"]
    assert a["passed"] + a["failed"] == 30 and a["failed"] >= 2  # shifted units fail
    low, high = proportion_confint(a["passed"], 30, method="wilson")
    assert a["yield"]["low"] == pytest.approx(low) and a["yield"]["high"] == pytest.approx(high)
    assert_signable_page(tmp_path / "y.html", out)
    code, out, _ = cli(capsys, "fleet", "yield", "--by", "lot", "--central", fleet)
    assert code == 0 and "L0" in out and "L9" in out


def test_spc_flags_the_shift_and_not_the_stable_part(fleet, capsys, tmp_path):
    code, out, _ = cli(capsys, "fleet", "spc", "k0", "--station", "ST-A", "--central", fleet,
                       "--baseline", "20", "--json", "--html", str(tmp_path / "spc.html"))
    doc = json.loads(out)
    flagged = {v["index"] for v in doc["individuals"]["violations"]}
    assert code == 0 and doc["n"] == 30 and doc["unit"] == "mg"
    assert flagged and min(flagged) >= 20  # the shift is caught, the stable units are not flagged
    assert doc["xbar"]["subgroup"] == 5 and doc["range"] is not None
    assert "Western Electric" in assert_signable_page(tmp_path / "spc.html", out)
    code, _, err = cli(capsys, "fleet", "spc", "nope", "--central", fleet)
    assert code == 2 and "measurements there: k0" in err


def test_trace_finds_a_unit_on_both_stations(fleet, capsys, tmp_path):
    code, out, _ = cli(capsys, "fleet", "trace", "QA-003", "--central", fleet, "--json",
                       "--html", str(tmp_path / "trace.html"))
    runs = json.loads(out)["runs"]
    assert "ST-B" in assert_signable_page(tmp_path / "trace.html", out)
    assert code == 0 and [r["station_id"] for r in runs] == ["ST-A", "ST-B"]
    assert all(r["measurements"][0]["name"] == "k0" for r in runs)
    # ... and its raw samples through bench runs on the central store
    code, out, _ = cli(capsys, "--store", fleet, "runs", "show", runs[1]["uuid"], "--json")
    shown = json.loads(out)
    assert code == 0 and shown["labels"]["station_id"] == "ST-B" and shown["streams"]["dmm"]["n_rows"] == 10
    code, _, err = cli(capsys, "--store", fleet, "runs", "show", runs[0]["run_id"])
    assert code == 0 or "names 2 runs" in err  # a station's id is unique here unless it collides
    code, _, err = cli(capsys, "--store", fleet, "acceptance", "--unit", "QA-SIM-0001")
    assert code == 2 and "central store" in err  # runs are written locally, then forwarded


def test_forwarding_after_a_run_and_when_the_server_is_away(tmp_path, central_url, monkeypatch, capsys):
    store = RunStore(tmp_path / "s.sqlite")
    acceptance_run(store, "QA-1", 0.5, "ST-A", "L1")
    monkeypatch.setenv("BENCH_CENTRAL", "postgresql://bench@127.0.0.1:9/bench")
    forward_after_run(str(tmp_path / "s.sqlite"))
    assert "stay queued" in capsys.readouterr().err
    assert len(store.unforwarded_run_ids()) == 1
    monkeypatch.setenv("BENCH_CENTRAL", central_url)
    forward_after_run(str(tmp_path / "s.sqlite"))
    assert "forwarded 1 run(s)" in capsys.readouterr().err
    assert store.unforwarded_run_ids() == []
    code, out, _ = cli(capsys, "--store", str(tmp_path / "s.sqlite"), "sync", "--status")
    assert code == 0 and out.startswith("0 finished run(s)")


def test_a_page_names_the_store_without_its_password():
    assert shown_url("postgresql://bench:s3cret@db.example:5433/bench?password=x") == \
        "postgresql://bench@db.example:5433/bench"
    assert shown_url("postgresql://[::1]:5432/b") == "postgresql://[::1]:5432/b"


def test_sync_needs_a_central_url(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("BENCH_CENTRAL", raising=False)
    RunStore(tmp_path / "s.sqlite").close()
    code, _, err = cli(capsys, "--store", str(tmp_path / "s.sqlite"), "sync")
    assert code == 2 and "BENCH_CENTRAL" in err
    code, _, err = cli(capsys, "--store", str(tmp_path / "s.sqlite"), "sync", "--central", "mysql://x")
    assert code == 2 and "postgresql://" in err
