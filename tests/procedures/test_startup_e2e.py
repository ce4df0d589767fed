"""The start-up acquisition end to end on the simulated station: procedure → drivers → TCP →
simulated instruments → run store; determinism; the abort path keeps data and leaves the
station safe."""

from __future__ import annotations

import numpy as np
import pytest

from bench.app.station import Station, builtin_sim_config
from bench.core.procedure import execute
from bench.core.store import RunStore
from procedures.common import choose_nplc
from procedures.running import alone
from procedures.startup import StartupAcquisition, StartupParameters

SHORT = dict(duration_s=240.0, rate_hz=50.0, off_wait_s=60.0, chunk_s=30.0)


def run_startup(tmp_path, seed=3, progress=None, **overrides):
    store = RunStore(tmp_path / "bench.sqlite")
    params = StartupParameters(**{**SHORT, **overrides})
    config = builtin_sim_config()
    config.simulation = {"accelerometer": {"warmup_amplitude_g": 6e-5}}  # a clear transient
    with Station(config, seed=seed, unit_serial="QA-T-1") as station:
        kwargs = {"progress": progress} if progress else {}
        outcome = execute(alone(StartupAcquisition(params)), station, store, unit_serial="QA-T-1",
                          seed=seed, **kwargs)
        sim = station.sim
        safe = {
            "outputs": [ch.output for ch in sim.supply.channels.values()],
            "dmm_states": (sim.dmm.state, sim.dmm_temp.state),
            "rates": [float(a.rate_dps(sim.world.now)) for a in sim.table.axes],
        }
        truth = sim.truth()
    return store, outcome, safe, truth


def test_startup_acquisition_records_the_whole_transient(tmp_path):
    store, outcome, safe, truth = run_startup(tmp_path)
    assert outcome.status == "passed", outcome.reason
    info = store.get_run(outcome.run_id)
    assert info.procedure == "startup" and info.unit_serial == "QA-T-1" and info.seed == 3
    out = store.load(outcome.run_id, "output")
    n_expected = int(round((SHORT["duration_s"] + 1.0) * SHORT["rate_hz"]))
    assert out["t_s"].size == n_expected
    assert np.all(np.diff(out["t_s"]) > 0)
    before, after = out["t_s"] < 0, out["t_s"] >= 0.05
    # unpowered before t = 0, ≈ 1 g (local) after
    assert np.all(np.abs(out["voltage_v"][before]) < 1e-4)
    g_local = truth["g_local_over_g0"] * truth["k1_ma_per_g"] / 1.33
    assert np.mean(out["acceleration_g"][after]) == pytest.approx(g_local, rel=1e-3)
    # the warm-up transient: early mean above late mean by about the true amplitude
    early = np.mean(out["acceleration_g"][(out["t_s"] > 0) & (out["t_s"] < 20)])
    late = np.mean(out["acceleration_g"][out["t_s"] > 200])
    assert early - late > 0.3 * truth["warmup_amplitude_g"]
    temp = store.load(outcome.run_id, "temperature")
    assert temp["temperature_c"][-1] > temp["temperature_c"][temp["t_s"] >= 0][0] + 0.5
    kinds = [e.kind for e in store.events(outcome.run_id)]
    assert kinds.index("levelled") < kinds.index("supply_off") < kinds.index("t0")
    # teardown left the station safe
    assert safe["outputs"] == [False, False, False]
    assert safe["dmm_states"] == ("IDLE", "IDLE")
    assert safe["rates"] == [0.0, 0.0]
    names = {m.name: m for m in outcome.measurements}
    assert names["readings_lost"].value == 0 and names["level_check_g"].outcome == "pass"
    station = info.station
    assert station["instruments"]["dmm"]["idn"]["model"] == "34465A"
    assert station["instruments"]["supply"]["idn"]["model"] == "E36312A"
    assert station["simulation"] == {"seed": 3, "unit_serial": "QA-T-1"}


def test_same_seed_gives_identical_bytes_and_another_seed_does_not(tmp_path):
    a = run_startup(tmp_path / "a", seed=11, duration_s=60.0)
    b = run_startup(tmp_path / "b", seed=11, duration_s=60.0)
    c = run_startup(tmp_path / "c", seed=12, duration_s=60.0)
    va = a[0].load(a[1].run_id, "output")["voltage_v"]
    vb = b[0].load(b[1].run_id, "output")["voltage_v"]
    vc = c[0].load(c[1].run_id, "output")["voltage_v"]
    assert va.tobytes() == vb.tobytes()
    assert va.size == vc.size and va.tobytes() != vc.tobytes()


def test_a_fault_mid_run_aborts_keeps_the_data_and_leaves_the_supply_off(tmp_path):
    calls = []

    def failing_progress(done, total, message=""):
        calls.append(done)
        if len(calls) == 3:
            raise ConnectionError("DMM link dropped (injected)")

    store, outcome, safe, _ = run_startup(tmp_path, progress=failing_progress)
    assert outcome.status == "aborted" and "DMM link dropped" in outcome.reason
    info = store.get_run(outcome.run_id)
    assert info.status == "aborted" and info.last_sample_t_s > 0
    kept = store.load(outcome.run_id, "output")["t_s"]
    assert kept.size > 0 and kept[-1] == pytest.approx(info.last_sample_t_s)
    assert safe["outputs"] == [False, False, False]
    assert any(a.name == "traceback.txt" for a in store.attachments(outcome.run_id))


@pytest.mark.parametrize("field,value", [("duration_s", 0.0), ("rate_hz", 1e5),
                                         ("one_g_tolerance", 2.0), ("chunk_s", float("nan"))])
def test_bad_parameters_are_refused_naming_value_and_range(field, value):
    with pytest.raises(ValueError, match=field):
        StartupAcquisition(StartupParameters(**{field: value}))


def test_nplc_choice_fits_the_interval():
    assert choose_nplc(0.01, 50.0) == 0.2     # 100 Hz: 2 × 4 ms readings fit in 10 ms
    assert choose_nplc(1.0, 60.0) == 10.0
    with pytest.raises(ValueError, match="too short"):
        choose_nplc(1e-4, 50.0)


def test_a_reading_straddling_power_on_does_not_wedge_the_world(tmp_path):
    """A slow trace (1.2 Hz) whose aperture spans the supply switching on."""
    store, outcome, safe, _ = run_startup(tmp_path, duration_s=20.0, rate_hz=1.2, off_wait_s=0.0,
                                          chunk_s=5.0)
    assert outcome.status == "passed", outcome.reason
    assert store.streams(outcome.run_id)["output"].n_rows == round(21 * 1.2)


def test_a_meter_that_stops_mid_trace_aborts_the_run_with_the_counts(tmp_path):
    """The output DMM silently stops (as a hung instrument would): the procedure must not
    wait forever; it aborts naming what it received, keeps the data, and powers down."""
    store = RunStore(tmp_path / "bench.sqlite")
    params = StartupParameters(**SHORT)
    with Station(builtin_sim_config(), seed=5, unit_serial="QA-T-2") as station:
        sim = station.sim
        sim.server.call(lambda: sim.world.schedule(150.0, sim.dmm.abort))
        outcome = execute(alone(StartupAcquisition(params)), station, store, unit_serial="QA-T-2", seed=5)
        outputs = [ch.output for ch in sim.supply.channels.values()]
    assert outcome.status == "aborted"
    assert "no readings for" in outcome.reason and "output" in outcome.reason
    kept = store.load(outcome.run_id, "output")["t_s"]
    assert 0 < kept.size < (SHORT["duration_s"] + 1) * SHORT["rate_hz"]
    assert outputs == [False, False, False]
