"""The angular rig on the simulated station end to end: clocks, `bench run frf` / `fusion`
through the real drivers, recovery of the drawn sensors, faults, bad input."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.analysis.fusion import SensorModel
from bench.app.cli import main
from bench.app.reports.angular_report import write_angular_report
from bench.app.station import Station, builtin_sim_config
from bench.app.verdict import record_digest
from bench.core.procedure import execute
from bench.core.store import RunStore
from bench.testing.reports import assert_self_contained, assert_signable
from instruments.angular_table import AngularLimits
from procedures.frf import FrfParameters, FrfTest, safe_amplitude_dps
from procedures.fusion import FusionParameters, FusionTest, tone_demand
from procedures.running import alone
from sim.devices.fog_serial import FogSerialDevice
from sim.station import SimStationConfig
from sim.station_angular import draw_rig

SEED = 3


def _run(tmp_path, step, seed=SEED, serial="MHD-SIM-0007", faults=None):
    store = RunStore(tmp_path / "runs.sqlite")
    with Station(builtin_sim_config(), seed=seed, unit_serial=serial, unit_kind="angular") as station:
        truth = station.sim.angular_truth()
        if faults:
            faults(station.sim)
        outcome = execute(alone(step), station, store, unit_serial=serial, seed=seed)
    return outcome, truth, store


def _values(outcome) -> dict:
    return {m["name"]: m for m in outcome.to_dict()["measurements"]}


@pytest.fixture(scope="module")
def frf_run(tmp_path_factory):
    step = FrfTest(FrfParameters(f_min_hz=0.3, f_max_hz=300.0, points_per_decade=3, min_periods=4))
    return _run(tmp_path_factory.mktemp("frf"), step)


def test_frf_recovers_the_drawn_sensors(frf_run):
    outcome, truth, _ = frf_run
    assert outcome.status == "passed", outcome.to_dict()
    v = _values(outcome)
    mhd, lf = truth["mhd"], truth["lf"]
    assert v["hf_corner"]["value"] == pytest.approx(mhd["highpass_corner_hz"], rel=0.01)
    # the MHD's sensitivity in V per deg/s; its 8 kHz pole is a ~20 µs delay in the fit
    assert v["hf_gain"]["value"] == pytest.approx(mhd["sensitivity_v_per_rad_s"] * math.pi / 180, rel=0.005)
    assert v["hf_delay"]["value"] == pytest.approx(1 / (2 * math.pi * mhd["lowpass_corner_hz"]), abs=5e-6)
    assert v["lf_corner"]["value"] == pytest.approx(lf["corner_hz"], rel=0.01)
    assert v["lf_gain"]["value"] == pytest.approx(lf["gain"], rel=0.002)
    # latency + the frame clock's drift over a dwell (≤ 1 frame period)
    assert v["lf_delay"]["value"] == pytest.approx(lf["latency_s"], abs=1e-4)


def test_frf_points_carry_uncertainties_that_cover_the_true_response(frf_run):
    outcome, truth, store = frf_run
    points = store.results(outcome.run_id)["frf.points"]
    lf = truth["lf"]
    model = SensorModel("lowpass", 2, lf["corner_hz"], lf["gain"], lf["zeta"])
    f = np.asarray(points["freq_hz"])
    z = []
    for fk, row in zip(f, points["lf"]):
        if row is None or fk > 100:  # above 100 Hz the frame clock drift within a dwell adds phase
            continue
        g = model.response(fk) * np.exp(-2j * np.pi * fk * lf["latency_s"])
        z.append((row["mag"] - abs(g)) / row["mag_std"])
    assert len(z) >= 5 and np.max(np.abs(z)) < 5


def test_frf_streams_hold_every_sample(frf_run):
    outcome, _, store = frf_run
    ref = store.load(outcome.run_id, "frf_ref")
    hf = store.load(outcome.run_id, "frf_hf")
    lf = store.load(outcome.run_id, "frf_lf")
    for d in (ref, hf, lf):
        # the clock dwell (block -1), then 10 dwells (0.3-300 Hz, 3 per decade), all stored
        assert np.all(np.diff(d["block"]) >= 0) and d["block"].min() == -1 and d["block"].max() == 9
    assert ref["t_s"].size == hf["t_s"].size
    assert np.all(np.isfinite(hf["voltage_v"]))


def test_fusion_step_fuses_the_rig(tmp_path):
    step = FusionTest(FusionParameters(f_min_hz=1.0, f_max_hz=1000.0, tones_per_decade=1, duration_s=8.0,
                                       static_s=1.0, settle_s=0.5, ramp_s=0.2, frf_points_per_decade=2))
    outcome, truth, store = _run(tmp_path, step)
    assert outcome.status == "passed", outcome.to_dict()
    v = _values(outcome)
    fused = v["rms_error_fused"]["value"]
    assert fused < v["rms_error_hf"]["value"] / 5 and fused < v["rms_error_lf"]["value"] / 5
    clock = v["lf_clock_error"]
    assert abs(clock["value"] - truth["lf"]["frame_clock_error_ppm"]) < 4 * clock["uncertainty"] + 0.5
    results = store.results(outcome.run_id)
    analysis = results["fusion.analysis"]
    assert not any(n["diverged"] for n in analysis["nis"].values())
    aligned = store.load(outcome.run_id, "fusion_aligned")
    assert {"fused_dps", "hf_alone_dps", "lf_alone_dps", "ref_dps"} <= set(aligned)
    raw = store.load(outcome.run_id, "fusion_hf")
    assert set(np.unique(raw["block"])) == {0, 1}  # static segment and profile both stored
    # the report's fusion part (its PDF is checked on the FRF run: here the page alone, cheaply)
    page = write_angular_report(results, tmp_path / "rep", {"run": outcome.run_id}, pdf=False).read_text()
    assert "Every method against the reference" in page and "Document B's claims on this run" in page
    assert "amplitude error (%) at tone (Hz)" in page and assert_self_contained(page, figures=3) == 3


def test_cli_frf_writes_the_report_and_json(tmp_path, capsys):
    code = main(["--store", str(tmp_path / "b.sqlite"), "run", "frf", "--f-min-hz", "1", "--f-max-hz", "100",
                 "--points-per-decade", "2", "--min-dwell-s", "0.5", "--report", str(tmp_path / "rep"),
                 "--no-progress", "--json"])
    doc = json.loads(capsys.readouterr().out)
    assert code == 0 and doc["status"] == "passed"
    folder = tmp_path / "rep" / doc["run_id"]
    assert (folder / "angular_report.html").exists() and (folder / "angular_frf.png").exists()
    page = (folder / "angular_report.html").read_text()
    assert "Frequency response" in page and assert_self_contained(page) >= 1
    assert (folder / "angular_report.pdf").read_bytes()[:5] == b"%PDF-" and "reviewed by" in page
    with RunStore(tmp_path / "b.sqlite") as store:  # the run's digest at the foot, as bench runs show prints it
        digest = record_digest(store, doc["run_id"])
    assert_signable(page, digest)


@pytest.mark.parametrize("args,fragment", [
    (["frf", "--f-min-hz", "0.01"], "f_min_hz"),
    (["frf", "--points-per-decade", "1", "--f-min-hz", "10", "--f-max-hz", "100"], "at least 5"),
    (["fusion", "--duration-s", "5"], "3 periods"),
    (["fusion", "--frame-rate-hz", "9000"], "frame_rate_hz"),
    (["fusion", "--f-min-hz", "1", "--f-max-hz", "10", "--duration-s", "4", "--tune-fraction", "0"], "at least 5"),
    (["frf", "--f-min-hz", "10", "--f-max-hz", "1000", "--frame-rate-hz", "100", "--points-per-decade", "2"],
     "usable"),
])
def test_bad_parameters_are_one_line_exit_2_before_the_station_opens(tmp_path, capsys, args, fragment):
    code = main(["--store", str(tmp_path / "b.sqlite"), "run", *args, "--no-progress"])
    err = capsys.readouterr().err
    assert code == 2 and fragment in err and len(err.strip().splitlines()) == 1


def test_interlock_during_the_frf_aborts_and_keeps_what_was_acquired(tmp_path):
    step = FrfTest(FrfParameters(f_min_hz=1.0, f_max_hz=100.0, points_per_decade=2))

    def trip(sim):
        sim.faults.inject("interlock", "angular_table", at_s=sim.world.now + 8.0)

    outcome, _, store = _run(tmp_path, step, faults=trip)
    assert outcome.status == "aborted" and "ABORT" in outcome.reason
    assert store.load(outcome.run_id, "frf_ref")["t_s"].size > 0


def test_lf_frame_clock_and_dmm_timebase_run_off_nominal(station_factory) -> None:
    # devices driven directly, not served
    line: FogSerialDevice = station_factory(seed=1, lf_sensor={"frame_clock_error_ppm": 100.0}).angular.lf_line
    assert line.clock_ppm == 100.0
    line.rate_hz = 1000
    line._start()
    assert line._frames_due(10.0) == math.floor(10.0 * 1000 * (1 + 100e-6))
    dmm = station_factory(seed=1, dmm_timebase_ppm=-50.0).angular.dmm
    dmm.samp_source, dmm.samp_timer_s = "TIMER", 2.0  # longer than a reading: the timer sets it
    assert dmm.interval_s == pytest.approx(2.0 * (1 - 50e-6), rel=1e-12)


@settings(max_examples=20, deadline=None)
@given(st.text(alphabet="ABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789-", min_size=1, max_size=20))
def test_a_serial_always_draws_the_same_valid_units(serial):
    a, b = draw_rig(serial), draw_rig(serial)
    assert a == b
    mhd, lf = a
    assert 0.5 < mhd.highpass_corner_hz < 5 and 20 < lf.corner_hz < 80 and lf.latency_s > 0


@pytest.mark.parametrize("kwargs,fragment", [
    ({"mhd": {"highpass_corner_hz": -1}}, "highpass_corner_hz"),
    ({"lf_sensor": {"nonsense": 1}}, "nonsense"),
    ({"mhd_serial": "a,b"}, "mhd_serial"),
    ({"dmm_timebase_ppm": 5000}, "dmm_timebase_ppm"),
])
def test_bad_rig_options_are_refused_naming_the_value(kwargs, fragment):
    with pytest.raises(ValueError, match=fragment):
        SimStationConfig(**kwargs).validate()


def test_demands_respect_the_table_limits():
    lim = AngularLimits()
    for f in (0.1, 1.0, 100.0, 1000.0):
        a = safe_amplitude_dps(lim, f, 1e6)
        w = 2 * math.pi * f
        assert a / w <= 0.5 * lim.angle_deg + 1e-12 and a * w <= 0.5 * lim.accel_dps2 + 1e-9
    tones = FusionParameters(amplitude_dps=500.0).tones_hz()
    demand = tone_demand(lim, tones, 500.0)
    w = 2 * np.pi * np.array([d[1] for d in demand])
    amp = np.array([d[0] for d in demand])
    assert np.sum(amp / w) <= 0.5 * lim.angle_deg + 1e-9 and np.sum(amp * w) <= 0.5 * lim.accel_dps2 + 1e-6


def test_lf_frames_lost_on_the_line_abort_and_every_sample_so_far_is_kept(tmp_path):
    step = FrfTest(FrfParameters(f_min_hz=1.0, f_max_hz=100.0, points_per_decade=2))

    def lossy(sim):
        sim.faults.inject("frame", "lf_gyro", at_s=sim.world.now + 25.0, loss=0.01)

    outcome, _, store = _run(tmp_path, step, faults=lossy)
    assert outcome.status == "aborted" and "dropped" in outcome.reason
    for stream in ("frf_ref", "frf_hf", "frf_lf"):
        assert store.load(outcome.run_id, stream)["t_s"].size > 0
    # the chunk with the lost frames is stored too (its frames run past the fault's instant)
    assert store.load(outcome.run_id, "frf_lf")["t_s"].max() > 25.0


def test_clipped_lf_frames_abort_the_frf(tmp_path):
    step = FrfTest(FrfParameters(f_min_hz=3.0, f_max_hz=30.0, points_per_decade=4, amplitude_dps=500.0,
                                 min_dwell_s=0.5))
    outcome, _, _ = _run(tmp_path, step)
    assert outcome.status == "aborted" and "over range" in outcome.reason


def test_a_slow_dmm_timebase_is_measured_and_removed(tmp_path):
    store = RunStore(tmp_path / "runs.sqlite")
    cfg = builtin_sim_config()
    cfg.simulation["dmm_timebase_ppm"] = 40.0
    step = FrfTest(FrfParameters(f_min_hz=1.0, f_max_hz=1000.0, points_per_decade=2, min_periods=4))
    with Station(cfg, seed=5, unit_serial="MHD-SIM-0002", unit_kind="angular") as station:
        truth = station.sim.angular_truth()
        outcome = execute(alone(step), station, store, unit_serial="MHD-SIM-0002", seed=5)
    v = _values(outcome)
    clock = v["hf_clock_error"]
    assert abs(clock["value"] - (-40.0)) < 4 * clock["uncertainty"] + 0.2  # slow by 40 = fast by −40
    assert v["hf_delay"]["value"] == pytest.approx(1 / (2 * math.pi * truth["mhd"]["lowpass_corner_hz"]), abs=5e-6)
    lf = v["lf_clock_error"]
    assert abs(lf["value"] - truth["lf"]["frame_clock_error_ppm"]) < 4 * lf["uncertainty"] + 0.5
    assert v["lf_delay"]["value"] == pytest.approx(truth["lf"]["latency_s"], abs=3e-5)
