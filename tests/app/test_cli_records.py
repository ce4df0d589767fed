"""Records made elsewhere: ``bench analyze tumble|ratetable|turn-on --input`` and ``bench runs import``.

Each kind's bad inputs (missing column, wrong unit, NaN, time going back, too few points) give
exit 2 and one line naming the file, the column and the line; a record written in foreign units
analyses as the same record in the bench's; an export imported into another store is the run it
was (samples, chunking, events, results, attachments — the central store's digest included); an
imported record syncs to PostgreSQL and appears in ``bench fleet``.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bench.analysis.tumble import specific_force_iapo_g
from bench.app.cli import main
from bench.app.export import export_csv, export_hdf5, read_csv_export
from bench.app.record_analysis import json_safe
from bench.app.verdict import record_digest
from bench.core.store import RunStore
from bench.core.store.forward import package
from bench.testing.reports import assert_self_contained, assert_signable


def cli(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def write(path, header: list[str], rows) -> str:
    with open(path, "w", encoding="utf-8") as f:
        f.write(",".join(header) + "\n")
        for row in rows:
            f.write(",".join(repr(float(x)) if not isinstance(x, str) else x for x in row) + "\n")
    return str(path)


def tumble_rows(seed: int = 1, k1_ma: float = 1.2, k0: float = 2e-4, sd_a: float = 2e-9):
    rng = np.random.default_rng(seed)
    rows = []
    for inner in (0.0, 90.0):
        for outer in np.arange(0.0, 360.0, 30.0):
            f = specific_force_iapo_g(np.array([inner]), np.array([outer]))[0]
            current_a = 1e-3 * k1_ma * (k0 + f[0] + 5e-5 * f[0] ** 2 + 1e-4 * f[1])
            rows += [(inner, outer, current_a + rng.normal(0, sd_a)) for _ in range(3)]
    return rows


def rate_rows(seed: int = 2):
    rng = np.random.default_rng(seed)
    return [(r, 1.0001 * r + 0.002 + rng.normal(0, 1e-3)) for r in (-100, -50, -10, 10, 50, 100.0)
            for _ in range(20)]


def thermal_rows(seed: int = 5, n: int = 2400):
    """A static gyro 4 h in a chamber ramping 25 → 60 → 0 °C, its bias 2e-3 °/s/°C of the logged
    temperature lagged by 300 s."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 6.0
    logged = np.interp(t, [0, 1800, 5400, 9000, 14400], [25, 25, 60, 0, 0])
    a = math.exp(-6.0 / 300.0)
    element = np.empty(n)
    element[0] = logged[0]
    for k in range(1, n):
        element[k] = a * element[k - 1] + (1 - a) * logged[k]
    y = 0.05 + 2e-3 * (element - 25) + 2e-3 * rng.standard_normal(n)
    return list(zip(t, y, logged))


def turn_on_rows(seed: int = 3, cycles: int = 6):
    rng = np.random.default_rng(seed)
    rows = []
    for c in range(cycles):
        b = rng.normal(0, 0.01)
        rows += [(c, t, b + 0.05 * math.exp(-t / 60) + rng.normal(0, 0.002), c // 3) for t in np.arange(0, 600.0)]
    return rows


GOOD = {
    "tumble": (["inner_deg", "outer_deg", "output"], tumble_rows),
    "ratetable": (["input_rate_dps", "output"], rate_rows),
    "turn-on": (["cycle", "t_s", "output", "day"], turn_on_rows),
    "thermal": (["t_s", "output", "temperature_c"], thermal_rows),
}


def _not_json(token: str) -> None:
    raise AssertionError(f"{token} is not JSON")


def test_json_safe_writes_non_finite_values_as_null():
    doc = {"a": math.nan, "b": [np.float64(np.inf), 1.5, np.int64(3)], "c": np.array([1.0, -np.inf])}
    assert json.loads(json.dumps(json_safe(doc), allow_nan=False)) == {"a": None, "b": [None, 1.5, 3],
                                                                       "c": [1.0, None]}


@pytest.mark.parametrize("kind", sorted(GOOD))
def test_a_good_record_is_analysed(kind, tmp_path, capsys):
    header, rows = GOOD[kind]
    path = write(tmp_path / "r.csv", header, rows())
    code, out, err = cli(capsys, "analyze", kind, "--input", path, "--json", "--report", str(tmp_path / "rep"))
    assert code == 0, err
    doc = json.loads(out, parse_constant=_not_json)  # strict JSON: no NaN or Infinity tokens
    assert doc["kind"] == kind and doc["measurements"] and doc["sha256"]
    html = (tmp_path / "rep" / f"{kind.replace('-', '_')}_report.html").read_text()
    assert assert_self_contained(html) >= 1  # one file, figures inline
    assert (tmp_path / "rep" / f"{kind.replace('-', '_')}_report.pdf").read_bytes()[:5] == b"%PDF-"
    assert_signable(html, hashlib.sha256(Path(path).read_bytes()).hexdigest())


def test_tumble_recovers_its_parameters(tmp_path, capsys):
    path = write(tmp_path / "t.csv", ["inner_deg", "outer_deg", "output"], tumble_rows())
    code, out, _ = cli(capsys, "analyze", "tumble", "--input", path, "--json")
    m = {x["name"]: x for x in json.loads(out)["measurements"]}
    for name, truth in (("k1", 1.2), ("k0", 2e-4), ("k2", 5e-5), ("delta_o", 1e-4)):
        assert abs(m[name]["value"] - truth) <= 4 * m[name]["uncertainty"], (name, m[name])


# kind -> (header, rows, message pattern)
def _bad_cases():
    th, tr = GOOD["tumble"][0], tumble_rows()
    rh, rr = GOOD["ratetable"][0], rate_rows()
    oh, orows = GOOD["turn-on"][0], turn_on_rows()
    thh, thr = GOOD["thermal"][0], thermal_rows()
    th_nan = [list(r) for r in thr]
    th_nan[7][1] = "nan"
    th_back = [list(r) for r in thr]
    th_back[20][0] = 60.0
    nan_t = [list(r) for r in tr]
    nan_t[4][2] = "nan"
    back = [list(r) for r in orows]
    back[10][1] = 5.0
    return {
        "tumble missing column": ("tumble", ["inner_deg", "output"], [(r[0], r[2]) for r in tr],
                                  r"no column 'outer_deg' \(outer-axis angle\) in the header"),
        "tumble wrong unit": ("tumble", ["inner_deg", "outer [V]", "output"], tr,
                              r"column 'outer \[V\]' \(outer_deg, a angle\) in 'V'; allowed units: deg, °, rad"),
        "tumble NaN": ("tumble", th, nan_t, r"column 'output', line 6: nan is not a finite number"),
        "tumble too few": ("tumble", th, tr[:3], r"3 rows; a tumble record needs at least 4"),
        "tumble too few positions": ("tumble", th, [(0, 0, 1e-3)] * 6,
                                     r"1 distinct table positions; a tumble needs at least 4"),
        "rate missing column": ("ratetable", ["output"], [(r[1],) for r in rr], r"no column 'input_rate_dps'"),
        "rate wrong unit": ("ratetable", ["Rate [rpm]", "output"], rr, r"in 'rpm'; allowed units: deg/s"),
        "rate out of range": ("ratetable", ["Rate [rad/s]", "output"], [(r[0] * 1e4, r[1]) for r in rr],
                              r"column 'Rate \[rad/s\]', line 2: -5.72958e\+07 deg/s outside \[-100000, 100000\]"),
        "rate too few": ("ratetable", rh, rr[:2], r"2 rows; a ratetable record needs at least 3"),
        "rate not a number": ("ratetable", rh, [("fast", 1.0)] + rr,
                              r"column 'input_rate_dps', line 2: 'fast' is not a number"),
        "turn-on time back": ("turn-on", oh, back,
                              r"column 't_s', line 12: time 5 s does not increase \(previous 9 s\) within cycle 0"),
        "turn-on negative time": ("turn-on", oh, [(r[0], r[1] - 1.0, r[2], r[3]) for r in orows],
                                  r"-1 s; time counts from power-on"),
        "turn-on one cycle": ("turn-on", oh, [r for r in orows if r[0] == 0],
                              r"1 power cycle\(s\); turn-on repeatability needs at least 2"),
        "turn-on cycle not integer": ("turn-on", oh, [(0.5, *r[1:]) for r in orows],
                                      r"column 'cycle', line 2: 0.5 is not an integer"),
        "turn-on too few": ("turn-on", oh, orows[:100], r"100 rows; a turn-on record needs at least 128"),
        "thermal missing column": ("thermal", ["t_s", "output"], [r[:2] for r in thr],
                                   r"no column 'temperature_c' \(the logged temperature\) in the header"),
        "thermal wrong unit": ("thermal", ["t_s", "output", "Temp [V]"], thr,
                               r"column 'Temp \[V\]' \(temperature_c, a temperature\) in 'V'; allowed units: degC"),
        "thermal kelvin under degC": ("thermal", ["t_s", "output", "Temp [degC]"], [(r[0], r[1], r[2] + 273.15)
                                                                                    for r in thr],
                                      r"line 2: 298.15 degC outside \[-100, 250\] \(a wrong unit\?\)"),
        "thermal NaN": ("thermal", thh, th_nan, r"column 'output', line 9: nan is not a finite number"),
        "thermal time back": ("thermal", thh, th_back, r"column 't_s', line 22: time 60 s does not increase"),
        "thermal too few": ("thermal", thh, thr[:40], r"40 rows; a thermal record needs at least 64"),
    }


BAD = _bad_cases()


@pytest.mark.parametrize("case", sorted(BAD))
def test_a_bad_record_is_named_with_its_column_and_line(case, tmp_path, capsys):
    kind, header, rows, message = BAD[case]
    path = write(tmp_path / "bad.csv", header, rows)
    code, out, err = cli(capsys, "analyze", kind, "--input", path)
    assert code == 2 and not out, (out, err)
    last = err.splitlines()[-1]  # after at most the progress line
    assert last.startswith("bench: error: ") and len(err.splitlines()) <= 2, err
    assert re.search(message, last), err


@pytest.mark.parametrize("argv, message", [
    (["--col", "t_s"], r"--col 't_s': give NAME=COLUMN"),
    (["--col", "inner=Inner"], r"'inner' is not a column of a tumble record; its columns: inner_deg, outer_deg"),
    (["--g-over-g0", "2"], r"parameter g_over_g0 = 2.0 outside \[0.95, 1.05\]"),
    (["--meta", "nowhere.toml"], r"metadata file 'nowhere.toml' not found"),
])
def test_bad_options_are_named(argv, message, tmp_path, capsys):
    path = write(tmp_path / "t.csv", ["inner_deg", "outer_deg", "output"], tumble_rows())
    code, _, err = cli(capsys, "analyze", "tumble", "--input", path, *argv)
    assert code == 2 and re.search(message, err), err


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 1000))
def test_foreign_units_analyse_as_the_bench_units(seed, tmp_path_factory, capsys):
    """The same turn-on record in ms and the same tumble in radians give the same numbers."""
    d = tmp_path_factory.mktemp("u")
    rows = turn_on_rows(seed, cycles=3)
    a = write(d / "a.csv", ["cycle", "t_s", "output"], [r[:3] for r in rows])
    b = write(d / "b.csv", ["cycle", "Time [ms]", "output"], [(r[0], r[1] * 1e3, r[2]) for r in rows])
    docs = []
    for path in (a, b):
        code, out, err = cli(capsys, "analyze", "turn-on", "--input", path, "--json")
        assert code == 0, err
        docs.append({m["name"]: m["value"] for m in json.loads(out)["measurements"]})
    for k in docs[0]:
        assert docs[0][k] == pytest.approx(docs[1][k], rel=1e-9, abs=1e-15), k
    trows = tumble_rows(seed)
    a = write(d / "ta.csv", ["inner_deg", "outer_deg", "output"], trows)
    b = write(d / "tb.csv", ["Inner [rad]", "Outer [rad]", "y [A]"],
              [(math.radians(r[0]), math.radians(r[1]), r[2]) for r in trows])
    docs = []
    for path in (a, b):
        code, out, err = cli(capsys, "analyze", "tumble", "--input", path, "--json")
        assert code == 0, err
        docs.append({m["name"]: m["value"] for m in json.loads(out)["measurements"]})
    for k in ("k0", "k1", "delta_o"):
        assert docs[0][k] == pytest.approx(docs[1][k], rel=1e-6), k


def _station_like_run(store: RunStore) -> str:
    with store.create_run(procedure="tumble", parameters={"positions": 12}, station={"name": "sim"},
                          unit_serial="QA-9", seed=7, code_version="t",
                          labels={"station_id": "ST-1", "lot": "L1"}) as run:
        run.add_stream("dmm", {"t_s": "s", "voltage_v": "V"})
        run.add_stream("flags", {"t_s": "s", "ok": "1", "count": "1"}, dtypes={"ok": "bool", "count": "uint64"})
        for k in range(3):  # three chunks of unequal size
            n = 5 + 7 * k
            run.append("dmm", t_s=np.arange(n) + 100.0 * k, voltage_v=np.linspace(0, 1, n) + k)
        run.append("flags", t_s=[0.0, 1.0], ok=[True, False], count=np.array([0, 2 ** 64 - 1], dtype=np.uint64))
        run.event(1.5, "step", "tumble started", position=3)
        run.event(float("nan"), "warning", "clock unread")
        run.attach("notes.txt", b"hello", "text/plain")
        run.set_result("measurement.k0", {"name": "k0", "value": 1e-4, "unit": "g", "low": None, "high": None,
                                          "outcome": "pass", "uncertainty": 1e-6})
        run.finish("passed")
    store.attach_analysis(run.id, "analysis/tumble/report.html", b"<html></html>", "text/html")
    return run.id


@pytest.mark.parametrize("form", ["csv", "hdf5"])
def test_an_export_imported_elsewhere_is_the_same_run(form, tmp_path, capsys):
    with RunStore(tmp_path / "a.sqlite") as a:
        run_id = _station_like_run(a)
        before = package(a, run_id)
        if form == "csv":
            paths = export_csv(a, run_id, tmp_path / "ex")
            target = next(p for p in paths if p.suffix == ".json")
        else:
            target = export_hdf5(a, run_id, tmp_path / "ex.h5")
    code, out, err = cli(capsys, "--store", str(tmp_path / "b.sqlite"), "runs", "import", str(target), "--json")
    assert code == 0, err
    assert json.loads(out)["run_id"] == run_id
    with RunStore(tmp_path / "b.sqlite") as b:
        after = package(b, run_id)
        assert after.digest == before.digest  # what the central store checks: everything, chunking included
        assert after.info == before.info and after.info.uuid == before.info.uuid
        again = export_csv(b, run_id, tmp_path / "ex2")
    first = read_csv_export(next(p for p in (export_csv(RunStore(tmp_path / "a.sqlite"), run_id, tmp_path / "ex1"))
                                 if p.suffix == ".json"))
    second = read_csv_export(next(p for p in again if p.suffix == ".json"))
    assert first.chunk_rows == second.chunk_rows == {"dmm": [5, 12, 19], "flags": [2]}
    for name in first.data:
        for col, values in first.data[name].items():
            assert second.data[name][col].tobytes() == values.tobytes()
    assert [a[0] for a in first.attachments.values()] == [a[0] for a in second.attachments.values()]
    code, _, err = cli(capsys, "--store", str(tmp_path / "b.sqlite"), "runs", "import", str(target))
    assert code == 2 and f"run {run_id} is already in" in err


def test_a_record_needs_its_kind_and_a_central_store_is_refused(tmp_path, capsys):
    path = write(tmp_path / "t.csv", ["inner_deg", "outer_deg", "output"], tumble_rows())
    code, _, err = cli(capsys, "--store", str(tmp_path / "s.sqlite"), "runs", "import", path)
    assert code == 2 and "no kind given; give one of static, startup, thermal, tumble, ratetable, turn-on" in err
    code, _, err = cli(capsys, "--store", "postgresql://u@localhost/x", "runs", "import", path, "--kind", "tumble")
    assert code == 2 and "is a central store" in err


def test_an_imported_record_is_a_run_that_syncs_and_shows_in_the_fleet(tmp_path, central_url, capsys):
    path = write(tmp_path / "t.csv", ["inner_deg", "outer_deg", "output"], tumble_rows())
    store = str(tmp_path / "s.sqlite")
    code, out, err = cli(capsys, "--store", store, "runs", "import", path, "--kind", "tumble", "--serial", "ACC-77",
                         "--station-id", "RIG-3", "--lot", "L5", "--json")
    assert code == 0, err
    run_id = json.loads(out)["run_id"]
    code, out, _ = cli(capsys, "--store", store, "runs", "show", run_id, "--json")
    doc = json.loads(out)
    assert doc["procedure"] == "tumble_record" and doc["unit_serial"] == "ACC-77"
    assert doc["streams"]["record"]["n_rows"] == 72 and doc["labels"] == {"station_id": "RIG-3", "lot": "L5"}
    assert {m["name"] for m in doc["measurements"]} >= {"k0", "k1", "delta_o"}
    other = write(tmp_path / "t2.csv", ["inner_deg", "outer_deg", "output"], tumble_rows(seed=9, k1_ma=1.21))
    code, _, err = cli(capsys, "--store", store, "runs", "import", other, "--kind", "tumble", "--serial", "ACC-78")
    assert code == 0, err
    code, out, err = cli(capsys, "--store", store, "sync", "--central", central_url)
    assert code == 0 and " 0 queued" in out, (out, err)
    code, out, _ = cli(capsys, "fleet", "trace", "ACC-77", "--central", central_url, "--json")
    assert code == 0 and "tumble_record" in out
    code, out, _ = cli(capsys, "fleet", "spc", "k1", "--central", central_url, "--json")
    assert code == 0 and "ACC-77" in out and "ACC-78" in out, out


def test_the_metadata_kind_must_agree_and_names_match_whatever_their_case(tmp_path, capsys):
    path = write(tmp_path / "t.csv", ["Inner_Deg", "OUTER_DEG", "Output [A]"], tumble_rows())
    meta = tmp_path / "t.toml"
    meta.write_text('kind = "tumble"\n', encoding="utf-8")
    code, out, err = cli(capsys, "analyze", "tumble", "--input", path, "--meta", str(meta), "--json")
    assert code == 0, err
    assert json.loads(out)["units"]["output"] == "A"
    code, _, err = cli(capsys, "analyze", "ratetable", "--input", path, "--meta", str(meta))
    assert code == 2 and "kind = 'tumble', but this is `ratetable`" in err, err


def test_import_takes_the_kinds_options_and_refuses_the_same_file_twice(tmp_path, capsys):
    path = write(tmp_path / "r.csv", ["input_rate_dps", "output"], rate_rows())
    store = str(tmp_path / "s.sqlite")
    code, out, err = cli(capsys, "analyze", "ratetable", "--input", path, "--full-scale-dps", "490", "--json")
    analysed = {m["name"]: m["value"] for m in json.loads(out)["measurements"]}
    code, out, err = cli(capsys, "--store", store, "runs", "import", path, "--kind", "ratetable",
                         "--full-scale-dps", "490", "--json")
    assert code == 0, err
    imported = {m["name"]: m["value"] for m in json.loads(out)["analysis"]["measurements"]}
    assert imported == analysed  # the same numbers, whichever command read the file
    run_id = json.loads(out)["run_id"]
    code, _, err = cli(capsys, "--store", store, "runs", "import", path, "--kind", "ratetable")
    assert code == 2 and f"is already stored as run {run_id} (same content" in err, err


def test_discover_reads_an_imported_record_in_its_own_unit(tmp_path, capsys):
    """A static gyro record in deg/h is discovered as the same record in deg/s; a unit that is
    not a rate is refused by name."""
    rng = np.random.default_rng(4)
    t = np.arange(3000) * 0.1
    y_dps = 0.01 + 0.002 * rng.standard_normal(t.size) + 0.004 * np.sin(2 * np.pi * 0.7 * t)
    store = str(tmp_path / "s.sqlite")
    ids = []
    for name, unit, scale in (("a", "deg/s", 1.0), ("b", "deg/h", 3600.0), ("c", "V", 2.0)):
        path = write(tmp_path / f"{name}.csv", ["t_s", "output"], zip(t, y_dps * scale))
        code, out, err = cli(capsys, "--store", store, "runs", "import", path, "--kind", "static", "--sensor", "gyro",
                             "--output-unit", unit, "--json")
        assert code == 0, err
        ids.append(json.loads(out)["run_id"])
    found = []
    for run_id in ids[:2]:
        code, out, err = cli(capsys, "--store", store, "discover", "--run", run_id, "--json",
                             "--out", str(tmp_path / run_id))
        assert code == 0, err
        found.append({e["id"]: e["params"]["amplitude"] for e in json.loads(out)["effects"]})
        with RunStore(store) as runs:  # the report of a stored run carries the run's digest at its foot
            digest = record_digest(runs, run_id)
        assert_signable((tmp_path / run_id / "discovery_report.html").read_text(), digest)
    assert set(found[0]) == set(found[1]) == {"sinusoidal_interference"}
    assert found[0]["sinusoidal_interference"] == pytest.approx(found[1]["sinusoidal_interference"], rel=1e-6)
    code, _, err = cli(capsys, "--store", store, "discover", "--run", ids[2])
    assert code == 2 and "the output is in 'V', not a rate a gyro gives" in err, err


def test_a_chamber_record_gives_its_coefficient_and_lag_and_a_compensation_file(tmp_path, capsys):
    path = write(tmp_path / "c.csv", ["Time [min]", "output", "Case T [K]"],
                 [(t / 60.0, y, c + 273.15) for t, y, c in thermal_rows()])
    code, out, err = cli(capsys, "analyze", "thermal", "--input", path, "--output-unit", "deg/s", "--json",
                         "--col", "temperature_c=Case T",
                         "--report", str(tmp_path / "rep"))
    assert code == 0, err
    m = {x["name"]: x for x in json.loads(out)["measurements"]}
    assert abs(m["bias_tc"]["value"] - 2e-3) <= 3 * m["bias_tc"]["uncertainty"], m["bias_tc"]
    assert abs(m["lag_s"]["value"] - 300.0) <= 3 * m["lag_s"]["uncertainty"], m["lag_s"]
    assert m["bias_tc"]["unit"] == "deg/s/degC"
    text = (tmp_path / "rep" / "compensation.toml").read_text()
    assert "element_lag_s" in text and 'temperature_source = "element"' in text
