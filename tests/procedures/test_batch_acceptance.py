"""Batch acceptance end to end on the simulated fixture: four sockets — a good unit, a unit out
of its bias limit, an open socket, a channel that overloads mid-batch — each to its own verdict
in its own record, the good unit's calibration recovered, and the records read by the existing
CLI and reports unchanged."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bench.app.batch import check_socket, parse_sockets, run_batch, spec_for_sockets
from bench.app.cli import main
from bench.app.station import builtin_sim_config
from bench.core.store import RunStore
from bench.testing.specs import SHORT_ACCEPTANCE_SPEC
from sim.station_fixture import Fixture

SOCKETS = {1: "QA-SIM-0003", 2: "QA-SIM-0002", 3: "QA-SIM-0004", 4: "QA-SIM-0001"}


@pytest.fixture(scope="module")
def batch(tmp_path_factory):
    folder = tmp_path_factory.mktemp("batch")
    spec_file = folder / "short.toml"
    spec_file.write_text(SHORT_ACCEPTANCE_SPEC)
    config = builtin_sim_config()
    config.simulation = {"fixture_units": {"2": {"k0_g": 6e-3}}, "fixture_open": [3]}
    store = RunStore(folder / "bench.sqlite")
    held: dict = {}

    def overload_socket_4(station) -> None:
        held["sim"] = station.sim
        daq = station.sim.fixture.daq
        real = daq.inputs[104]
        t_fault = station.sim.world.now + 100.0  # during the turn-on record
        daq.inputs[104] = lambda t, ap: np.where(t >= t_fault, 50.0, real(t, ap))
    spec = spec_for_sockets(SOCKETS, str(spec_file))
    result = run_batch(config, SOCKETS, spec, store, seed=4, report_root=folder / "reports",
                       labels={"station_id": "line-1", "lot": "L7"}, on_station=overload_socket_4)
    return result, store, held["sim"], folder


def test_each_socket_gets_its_own_verdict(batch):
    result, _, _, _ = batch
    docs = result.documents
    assert [docs[n]["unit"] for n in (1, 2, 3, 4)] == [SOCKETS[n] for n in (1, 2, 3, 4)]
    assert docs[1]["status"] == "passed"
    assert docs[2]["status"] == "failed" and "k0" in docs[2]["reason"]
    assert docs[3]["status"] == "failed"  # open lead: the level check fails, then the limits
    assert docs[4]["status"] == "aborted" and "overloaded" in docs[4]["reason"]
    assert result.exit_code == 2


def test_the_good_units_calibration_is_recovered_from_its_socket(batch):
    result, _, sim, _ = batch
    truth = sim.fixture_truth()[1]
    k1 = {m["name"]: m for m in result.documents[1]["measurements"]}["k1"]
    assert abs(k1["value"] - truth["k1_ma_per_g"]) < 5 * k1["uncertainty"] + 2e-4 * truth["k1_ma_per_g"]


def test_one_record_per_unit_readable_as_any_acceptance_run(batch, capsys):
    result, store, _, folder = batch
    runs = {r.id: r for r in store.list_runs()}
    assert len(runs) == 4
    for n, doc in result.documents.items():
        info = runs[doc["run_id"]]
        assert info.procedure == "acceptance" and info.unit_serial == SOCKETS[n]
        assert info.labels == {"station_id": "line-1", "socket": str(n), "lot": "L7"}
        kinds = [e.kind for e in store.events(doc["run_id"])]
        assert "levelled" in kinds and kinds.count("step_start") >= 1
    good = result.documents[1]
    assert {"output", "tumble", "tumble_readings", "noise"} <= set(store.streams(good["run_id"]))
    assert good["report"] and (folder / "reports" / good["run_id"] / "acceptance_report.html").is_file()
    assert main(["--store", str(store.path), "runs", "list", "--json"]) == 0
    listed = json.loads(capsys.readouterr().out)
    assert {r["id"] for r in listed} == set(runs)


@pytest.mark.parametrize(("text", "message"), [
    ("1=QA-SIM-0001,1=QA-SIM-0002", "socket 1 given twice"),
    ("9=QA-SIM-0001", "socket '9' not in 1..8"),
    ("1=QA-SIM-0001,2=QA-SIM-0001", "already in another socket"),
    ("1:QA-SIM-0001", "must be SOCKET=SERIAL"),
    ("1=", "serial '' must be"),
    ("", "no sockets given"),
])
def test_bad_socket_lists_are_named(text, message):
    with pytest.raises(ValueError, match=message):
        parse_sockets(text)


def test_one_spec_per_batch_and_a_serial_no_spec_matches_is_named():
    with pytest.raises(ValueError, match="FOG"):
        spec_for_sockets({1: "QA-SIM-0001", 2: "FOG-SIM-0001"})
    with pytest.raises(ValueError, match="no built-in spec matches unit 'XX-1'"):
        spec_for_sockets({1: "XX-1"})
    assert check_socket("2", "QA-SIM-0009", {1: "QA-SIM-0001"}) == {2: "QA-SIM-0009"}


def test_a_fixture_wired_from_another_channel_is_read_there(tmp_path):
    """``[wiring] fixture_first_channel``: the procedures read socket n on first + n − 1, and
    the simulated harness is wired there too (one setting, both sides)."""
    spec_file = tmp_path / "short.toml"
    spec_file.write_text(SHORT_ACCEPTANCE_SPEC)
    config = builtin_sim_config()
    config.wiring = {**config.wiring, "fixture_first_channel": 113}
    held: dict = {}
    sockets = {1: "QA-SIM-0003", 8: "QA-SIM-0002"}
    result = run_batch(config, sockets, spec_for_sockets(sockets, str(spec_file)),
                       RunStore(tmp_path / "b.sqlite"), seed=5, report_root=None, labels={},
                       on_station=lambda station: held.update(sim=station.sim))
    assert sorted(held["sim"].fixture.daq.inputs) == [113, 120]
    truth = held["sim"].fixture_truth()
    for n in sockets:
        k1 = {m["name"]: m for m in result.documents[n]["measurements"]}["k1"]
        assert abs(k1["value"] - truth[n]["k1_ma_per_g"]) < 5 * k1["uncertainty"] + 2e-4 * truth[n]["k1_ma_per_g"]
    with pytest.raises(ValueError, match="fixture_first_channel = 114 not in 101..113"):
        Fixture(held["sim"].world, {}, overrides={}, open_sockets=[], specific_force=lambda t: t,
                sampling_resistor_ohm=5000.0, line_pickup=None, settling_tau_s=1e-4,
                ideal_meters=True, first_channel=114)
