"""``bench run vibration`` end to end on the simulated station: the procedure through the
drivers, the wire and the World, the run store, and the rectified bias against the truth."""

from __future__ import annotations

import numpy as np
import pytest

from bench.app.cli import main
from bench.app.station import Station, builtin_sim_config
from bench.app.verdict import record_digest
from bench.core.procedure import execute
from bench.core.store import RunStore
from bench.testing.reports import assert_self_contained, assert_signable
from procedures.running import alone
from procedures.vibration import VibrationParameters, VibrationTest

UNIT = "FOG-SIM-0042"
#: rectification along the IA raised so a short run resolves it (tactical presets: ~0.05 °/h/g²)
RECTIFICATION_DPH_PER_G2 = 1.0
SHORT = dict(static_s=4.0, duration_s=8.0, level_grms=6.0, ramp_s=1.0, warmup_s=300.0,
             frame_rate_hz=2000)


def _station(seed: int = 5) -> Station:
    cfg = builtin_sim_config()
    cfg.simulation = {"gyro": {"vib_rectification_dph_per_g2": [RECTIFICATION_DPH_PER_G2, 0.02, 0.02]}}
    return Station(cfg, seed=seed, unit_serial=UNIT, unit_kind="gyro")


def _run(tmp_path, before=None, **overrides):
    store = RunStore(tmp_path / "runs.sqlite")
    with _station() as station:
        if before is not None:
            before(station)
        step = VibrationTest(VibrationParameters(**{**SHORT, **overrides}))
        outcome = execute(alone(step), station, store, unit_serial=UNIT, seed=5)
        sim = station.sim
        after = {"shaker_driving": sim.shaker.driving, "shaker_state": sim.shaker.state(sim.world.now),
                 "supply_on": any(ch.output for ch in sim.supply.channels.values()),
                 "truth": sim.gyro.params.vib_rectification_dph_per_g2}
    return store, outcome, after


@pytest.fixture(scope="module")
def short_run(tmp_path_factory):
    return _run(tmp_path_factory.mktemp("vib"))


def test_three_segments_every_frame_recorded(short_run):
    store, outcome, _ = short_run
    assert outcome.status == "passed", outcome.reason
    f = store.load(outcome.run_id, "gyro_frames")
    dt = np.diff(f["t_s"])
    assert np.allclose(dt, 1 / 2000, rtol=0, atol=1e-9)  # one stream, no gap between segments
    counts = {k: int(np.count_nonzero(f["segment"] == k)) for k in range(3)}
    steady = {k: int(np.count_nonzero((f["segment"] == k) & f["steady"])) for k in range(3)}
    assert steady == {0: 8000, 1: 16000, 2: 8000}
    assert counts[1] >= 16000 + 2000 and counts[2] >= 8000 + 2000  # the ramps (1 s each) too
    assert np.all(np.diff(f["segment"]) >= 0)
    # the controller's level: ~6 g rms while steady, 0 in the static segments
    assert np.all(f["level_grms"][f["segment"] == 0] == 0.0)
    assert np.mean(f["level_grms"][(f["segment"] == 1) & f["steady"]]) == pytest.approx(6.0, rel=0.02)
    kinds = [(e.kind, e.message) for e in store.events(outcome.run_id)]
    assert [m for k, m in kinds if k in ("segment", "steady")] == [
        "static before", "vibration", "vibration steady", "static after", "static after steady"]
    levels = store.load(outcome.run_id, "shaker_level")
    assert set(np.unique(levels["state"])) <= {0, 1, 2} and 2 in levels["state"]


def test_vibration_raises_noise_and_rectifies_as_simulated(short_run):
    store, outcome, after = short_run
    m = {x.name: x for x in outcome.measurements}
    assert m["vibration_rms"].value > 1.1 * m["static_noise"].value
    truth_dph = after["truth"][0] * 6.0**2  # shaker along platform z = the gyro's IA
    shift = m["vibration_bias_shift"]
    assert shift.uncertainty < 0.15 * truth_dph
    assert abs(shift.value - truth_dph) < 4 * shift.uncertainty
    assert m["vibration_level"].value == pytest.approx(6.0, rel=0.02)


def test_teardown_leaves_shaker_stopped_and_supply_off(short_run):
    _, _, after = short_run
    assert not after["shaker_driving"] and not after["supply_on"]


def test_aborted_shaker_aborts_the_run_and_keeps_the_frames(tmp_path):
    def abort_midway(station):
        # the World fires this on the server thread while the procedure reads frames
        def cut() -> None:
            station.sim.shaker.abort(station.sim.world.now)
        t_abort = 0.1 + SHORT["warmup_s"] + SHORT["static_s"] + 4.0
        station.sim.server.call(station.sim.world.schedule, t_abort, cut)

    store, outcome, after = _run(tmp_path, before=abort_midway)
    assert outcome.status == "aborted" and "shaker in ABORT" in outcome.reason
    f = store.load(outcome.run_id, "gyro_frames")
    assert np.count_nonzero(f["segment"] == 0) == 8000 and np.count_nonzero(f["segment"] == 1) > 0
    assert after["shaker_state"] == "ABORT" and not after["shaker_driving"] and not after["supply_on"]


def test_cli_runs_vibration_and_rejects_bad_options(tmp_path, capsys):
    store = str(tmp_path / "cli.sqlite")
    args = ["--store", store, "run", "vibration", "--static-s", "2", "--duration-s", "3",
            "--warmup-s", "10", "--ramp-s", "0.5", "--no-progress", "--analyze", "--report", str(tmp_path / "rep")]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "PASSED" in out and "vibration_bias_shift" in out
    # the model's report of the stored run: its PDF beside it, the run's digest at the foot
    with RunStore(store) as runs:
        run_id = runs.list_runs()[0].id
        digest = record_digest(runs, run_id)
    folder = tmp_path / "rep" / run_id
    page = (folder / "vibration_report.html").read_text(encoding="utf-8")
    assert (folder / "vibration_report.pdf").read_bytes()[:5] == b"%PDF-" and "reviewed by" in page
    assert_signable(page, digest)
    assert assert_self_contained(page, figures=4)
    assert main(["--store", store, "run", "vibration", "--level-grms", "45"]) == 2
    err = capsys.readouterr().err
    assert "level_grms = 45.0 must be a number in 0.01..30" in err and err.count("\n") == 1
