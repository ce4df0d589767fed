"""The sample records under docs/examples/, made by the simulated station's own procedures.

    .venv/bin/python scripts/make_record_examples.py              # writes docs/examples/
    .venv/bin/python scripts/make_record_examples.py --out DIR    # somewhere else

Each kind of record ``bench analyze`` and ``bench runs import`` read (``bench.app.records``)
gets one file, written as a lab's logger would write it, with its metadata TOML beside:

* ``tumble.csv``    — every DMM reading of a 24-position tumble (``bench run tumble``);
* ``ratetable.csv`` — every gyro frame of a rate-table sequence (``bench run ratetable``);
* ``turn_on.csv``   — every frame of each turn-on's static record, timed from that power-on
  (``bench run gyro_turn_on_repeatability``, two days);
* ``thermal.csv``   — a gyro at rest over two chamber ramp cycles (``bench run gyro_thermal_ramp``),
  4-frame means.

The station run's own results go into each TOML as comments and into ``reference.json`` (what
``tests/app/test_record_examples.py`` compares the files' analyses with). The runs go to a
temporary store; the same seed gives the same bytes.
"""

from __future__ import annotations

import argparse
import json
import math
import tempfile
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bench.app.session import choose_spec, read_run, run_step
from bench.core.site import STANDARD_GRAVITY_MPS2
from bench.core.store import RunStore

OUT = Path(__file__).resolve().parents[1] / "docs" / "examples"
STATION_ID = "bench-sim"
#: the limit every sample file stays under (the docs ship them)
MAX_BYTES = 300_000

#: each record's station step and its parameters: small plans, modest simulated durations
RUNS: dict[str, tuple[str, dict[str, Any]]] = {
    "tumble": ("tumble", {"positions": 12, "planes": 2, "warmup_s": 60.0}),
    "ratetable": ("ratetable", {"rates_per_sign": 4, "warmup_s": 60.0, "frame_rate_hz": 10}),
    "turn-on": ("gyro_turn_on_repeatability", {"cycles": 6, "days": 2, "off_s": 600.0, "warmup_s": 120.0,
                                               "record_s": 150.0, "frame_rate_hz": 4}),
    "thermal": ("gyro_thermal_ramp", {"low_c": 0.0, "high_c": 50.0, "rate_1_c_per_min": 0.5,
                                      "rate_2_c_per_min": 1.0, "dwell_s": 600.0, "frame_rate_hz": 1}),
}
#: the thermal record is written as means of this many frames (1 Hz frames → one row per 4 s)
THERMAL_DECIMATION = 4


@dataclass
class Example:
    """One sample record: its CSV text, its metadata TOML text, the station's reference results."""

    name: str
    csv: str
    toml: str
    reference: dict[str, Any]


def _csv(header: Iterable[str], columns: Iterable[Iterable[str]]) -> str:
    rows = zip(*columns)
    return ",".join(header) + "\n" + "".join(",".join(row) + "\n" for row in rows)


def _fmt(values: np.ndarray, spec: str) -> list[str]:
    return [format(float(v), spec) for v in values]


def _toml_value(value: Any) -> str:
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    return str(value)


def _toml(fields: dict[str, Any], columns: dict[str, Any], parameters: dict[str, Any],
          comments: list[str], reference: dict[str, Any]) -> str:
    lines = [f"# {c}" if c else "#" for c in comments]
    lines.append("#")
    lines.append(f"# The station run's own results (seed {reference['seed']}, step {reference['step']}):")
    for name, m in reference["measurements"].items():
        unc = "" if m["uncertainty"] is None else f" ± {m['uncertainty']:.3g}"
        lines.append(f"#   {name:<22} {m['value']:.9g}{unc} {m['unit']}")
    for note in reference.get("notes", []):
        lines.append(f"#   ({note})")
    lines.append("")
    lines += [f"{k} = {_toml_value(v)}" for k, v in fields.items()]
    if columns:
        lines += ["", "[columns]"]
        for k, v in columns.items():
            if isinstance(v, dict):
                inner = ", ".join(f"{kk} = {_toml_value(vv)}" for kk, vv in v.items())
                lines.append(f"{k} = {{ {inner} }}")
            else:
                lines.append(f"{k} = {_toml_value(v)}")
    if parameters:
        lines += ["", "[parameters]"]
        lines += [f"{k} = {_toml_value(v)}" for k, v in parameters.items()]
    return "\n".join(lines) + "\n"


def _measurements(run, names: Iterable[str]) -> dict[str, dict[str, Any]]:
    found = run.measurements()
    return {n: {"value": found[n]["value"], "uncertainty": found[n]["uncertainty"], "unit": found[n]["unit"]}
            for n in names if n in found and found[n]["value"] is not None}


def _run(store: RunStore, kind: str, seed: int):
    step, params = RUNS[kind]
    outcome = run_step(step, seed=seed, store=store, labels={"station_id": STATION_ID}, **params)
    run = read_run(outcome.run_id, store=store)
    reference = {"step": step, "seed": seed, "parameters": params, "unit_serial": run.info.unit_serial,
                 "status": outcome.status}
    return outcome, run, reference


def _model(unit_serial: str) -> str:
    return choose_spec(None, unit_serial).model


def tumble(store: RunStore, seed: int) -> Example:
    outcome, run, ref = _run(store, "tumble", seed)
    _require(outcome, "tumble")
    positions = run.arrays("tumble")
    readings = run.arrays("tumble_readings")
    k = readings["position"].astype(int)
    ohm = float(run.info.station["wiring"]["sampling_resistor_ohm"])
    g_over_g0 = float(run.info.results["tumble.fit"]["g_mps2"]) / STANDARD_GRAVITY_MPS2
    ref["measurements"] = _measurements(run, ("k0", "k1", "k2", "k3", "delta_o", "delta_p", "kip", "kio",
                                              "fit_residual_rms"))
    text = _csv(["Position", "Inner [deg]", "Outer [deg]", "Vout [V]"],
                [[str(i + 1) for i in k], _fmt(positions["inner_deg"][k], ".3f"),
                 _fmt(positions["outer_deg"][k], ".3f"), _fmt(readings["voltage_v"], ".7f")])
    toml = _toml(
        {"kind": "tumble", "sensor": "accelerometer", "unit_serial": run.info.unit_serial,
         "model": _model(run.info.unit_serial), "output_unit": "V", "station_id": STATION_ID},
        {"output": "Vout"},
        {"output_unit_per_ma": ohm * 1e-3, "g_over_g0": round(g_over_g0, 9)},
        ["A tumble (IEEE 1293) of a simulated pendulous accelerometer, every DMM reading: the",
         f"{len(positions['inner_deg'])} table positions (Inner, Outer in degrees), the output voltage across the",
         f"station's {ohm:g} Ω sampling resistor (so {ohm * 1e-3:g} V per mA: output_unit_per_ma).",
         "Made by scripts/make_record_examples.py (bench run tumble on the simulated station)."],
        ref)
    return Example("tumble", text, toml, ref)


def ratetable(store: RunStore, seed: int) -> Example:
    outcome, run, ref = _run(store, "ratetable", seed)
    _require(outcome, "ratetable")
    frames = run.arrays("ratetable_frames")
    fit = run.info.results["ratetable.fit"]
    earth_dps = float(fit["earth_rate_dps"])
    ref["measurements"] = _measurements(run, ("scale_factor_error", "bias", "nonlinearity", "asymmetry"))
    t = frames["t_s"] - frames["t_s"][0]
    text = _csv(["Time [s]", "Rate [deg/s]", "Gyro [deg/s]", "Temp [degC]"],
                [_fmt(t, ".3f"), _fmt(frames["table_rate_dps"] + earth_dps, ".9f"), _fmt(frames["rate_dps"], ".7f"),
                 _fmt(frames["temperature_c"], ".3f")])
    toml = _toml(
        {"kind": "ratetable", "sensor": "gyro", "unit_serial": run.info.unit_serial,
         "model": _model(run.info.unit_serial), "output_unit": "deg/s", "station_id": STATION_ID},
        {"output": "Gyro"},
        {"full_scale_dps": float(fit["full_scale_dps"])},
        ["A rate-table sequence (IEEE 952) of a simulated fibre-optic gyro, every"
         f" {RUNS['ratetable'][1]['frame_rate_hz']} Hz frame",
         "recorded at each rate. Rate is the input rate: the table's rate plus the Earth rate's vertical",
         f"component at {float(fit['latitude_deg']):g}° latitude ({earth_dps * 3600.0:.4f} °/h); Gyro the indicated"
         " rate.",
         "Made by scripts/make_record_examples.py (bench run ratetable on the simulated station)."],
        ref)
    return Example("ratetable", text, toml, ref)


def turn_on(store: RunStore, seed: int) -> Example:
    outcome, run, ref = _run(store, "turn-on", seed)
    _require(outcome, "gyro_turn_on_repeatability")
    frames = run.arrays("turn_on_frames")
    cycles = run.arrays("turn_on_cycles")
    t_on = dict(zip(cycles["cycle"].astype(int), cycles["t_on_s"]))
    events = [e for e in run.store.events(run.run_id) if e.kind == "turn_on"]
    if len(events) != len(t_on) or any(abs(e.t_s - t_on[k]) > 1e-9 for k, e in enumerate(events)):
        raise RuntimeError("the run's turn_on events and its turn_on_cycles stream disagree")
    day = dict(zip(cycles["cycle"].astype(int), cycles["day"].astype(int)))
    c = frames["cycle"].astype(int)
    since_on = frames["t_s"] - np.array([t_on[k] for k in c])
    ref["measurements"] = _measurements(run, ("turn_on_repeatability", "turn_on_raw_sd", "day_to_day",
                                              "within_day"))
    ref["notes"] = ["the station's biases have the Earth rate's vertical part removed; the file's output "
                    "has it in (a constant: the repeatability is the same)"]
    # each cycle's bias over its whole static record, as the station takes it
    window = float(min(np.ptp(np.round(since_on[c == k], 3)) for k in t_on))
    text = _csv(["cycle", "t_s", "output", "day"],
                [[str(k + 1) for k in c], _fmt(since_on, ".3f"), _fmt(frames["rate_dps"] * 3600.0, ".4f"),
                 [str(day[k] + 1) for k in c]])
    p = RUNS["turn-on"][1]
    toml = _toml(
        {"kind": "turn-on", "sensor": "gyro", "unit_serial": run.info.unit_serial,
         "model": _model(run.info.unit_serial), "output_unit": "deg/h", "station_id": STATION_ID},
        {},
        {"settled_window_s": window},
        [f"Turn-on to turn-on bias repeatability of a simulated fibre-optic gyro: {len(t_on)} power cycles",
         f"over {p['days']} days, each a {p['record_s']:g} s static record at {p['frame_rate_hz']} Hz after a"
         f" {p['warmup_s']:g} s warm-up;",
         "t_s counts from that cycle's power-on, output is the indicated rate in °/h (Earth rate included).",
         "settled_window_s covers each whole record (the station's bias is the record's mean).",
         "Made by scripts/make_record_examples.py (bench run gyro_turn_on_repeatability on the simulated",
         "station)."],
        ref)
    return Example("turn_on", text, toml, ref)


def thermal(store: RunStore, seed: int) -> Example:
    outcome, run, ref = _run(store, "thermal", seed)
    frames = run.arrays("thermal_ramp")
    step, p = RUNS["thermal"]
    n = frames["t_s"].size // THERMAL_DECIMATION * THERMAL_DECIMATION

    def means(a: np.ndarray) -> np.ndarray:
        return a[:n].reshape(-1, THERMAL_DECIMATION).mean(axis=1)

    t = means(frames["t_s"])
    t = t - t[0]
    y_dph = frames["rate_dps"] * 3600.0
    result = run.info.results.get(f"{step}.analysis")
    if result is None:
        # the record is kept when the step's analysis fails: read the reference from the step's
        # own analysis of that record, with the step's settings, and say so
        result, how = _ramp_analysis(frames["t_s"], y_dph, frames["temperature_c"])
        ref["notes"] = [f"the run ended {outcome.status}: {outcome.reason}; {how}"]
    ref["measurements"] = {} if result is None else _ramp_reference(result)
    text = _csv(["Time [s]", "Gyro [deg/s]", "Case T [degC]"],
                [_fmt(t, ".1f"), _fmt(means(frames["rate_dps"]), ".8f"), _fmt(means(frames["temperature_c"]), ".4f")])
    toml = _toml(
        {"kind": "thermal", "sensor": "gyro", "unit_serial": run.info.unit_serial,
         "model": _model(run.info.unit_serial), "output_unit": "deg/s", "station_id": STATION_ID},
        {"output": "Gyro", "temperature_c": {"column": "Case T", "unit": "degC"}},
        # the chamber ramps up and down: the hysteresis is fitted with the lag, or the lag takes it
        {"reference_c": float(p.get("reference_c", 25.0)), "hysteresis": True},
        ["A simulated fibre-optic gyro at rest (input axis up) over two chamber ramp cycles,",
         f"{p['low_c']:g} → {p['high_c']:g} → {p['low_c']:g} °C at {p['rate_1_c_per_min']:g} then"
         f" {p['rate_2_c_per_min']:g} °C/min, {p['dwell_s']:g} s dwells;",
         "Gyro is the indicated rate (Earth rate included), Case T the gyro's own sensor.",
         f"Decimated: each row is the mean of {THERMAL_DECIMATION} consecutive {p['frame_rate_hz']} Hz frames.",
         "bias_tc below is the slope at 25 °C of the station's bias-vs-temperature curve (its analysis",
         "reads the rate in °/h; the file keeps the gyro's °/s).",
         "Made by scripts/make_record_examples.py (bench run gyro_thermal_ramp on the simulated station)."],
        ref)
    return Example("thermal", text, toml, ref)


def _ramp_reference(result: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """The ramp analysis's figures a thermal record's analysis can be held against (deg/h)."""
    curve = result["curve"]
    coef, cov = np.asarray(curve["coefficients"], float), np.asarray(curve["covariance"], float)
    slope, std = (float(coef[1]), math.sqrt(float(cov[1, 1]))) if coef.size > 1 else (0.0, 0.0)
    out = {"bias_tc": {"value": slope, "uncertainty": std, "unit": "deg/h/degC"}}
    units = {"lag_s": "s", "hysteresis": "deg/h", "rate_sensitivity": "deg/h/(degC/min)", "branch_offset": "deg/h"}
    for name, unit in units.items():
        e = result.get(name)
        if e is not None and e.get("value") is not None:
            out[name] = {"value": e["value"], "uncertainty": e.get("std"), "unit": unit}
    return out


def _ramp_analysis(t: np.ndarray, y: np.ndarray, temp: np.ndarray) -> tuple[dict[str, Any] | None, str]:
    from bench.analysis.thermal import analyze_thermal_ramp  # noqa: PLC0415 — only when the step's own failed

    p = RUNS["thermal"][1]
    try:
        r = analyze_thermal_ramp(t, y, temp, reference_c=p.get("reference_c", 25.0), block_s=p.get("block_s", 60.0))
    except ValueError as exc:
        return None, f"the ramp analysis of its record fails too ({exc}): no reference"
    return r.to_dict(), "reference: analyze_thermal_ramp on the run's stream (reference_c, block_s of the step)"


def _require(outcome, step: str) -> None:
    if outcome.status == "aborted":
        raise RuntimeError(f"bench run {step} aborted: {outcome.reason}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=OUT, help=f"folder for the files [{OUT}]")
    parser.add_argument("--seed", type=int, default=1, help="seed of the simulated world [1]")
    args = parser.parse_args(argv)
    references: dict[str, Any] = {}
    with tempfile.TemporaryDirectory(prefix="record-examples-") as tmp:
        store = RunStore(Path(tmp) / "runs.sqlite")
        examples = [make(store, args.seed) for make in (tumble, ratetable, turn_on, thermal)]
    args.out.mkdir(parents=True, exist_ok=True)
    for ex in examples:
        csv_path, toml_path = args.out / f"{ex.name}.csv", args.out / f"{ex.name}.toml"
        csv_path.write_text(ex.csv, encoding="utf-8")
        toml_path.write_text(ex.toml, encoding="utf-8")
        references[ex.name] = ex.reference
        size = csv_path.stat().st_size
        if size >= MAX_BYTES:
            raise RuntimeError(f"{csv_path}: {size} bytes, over {MAX_BYTES}: decimate or shorten the run")
        print(f"{csv_path} ({size} bytes), {toml_path}")
    ref_path = args.out / "reference.json"
    ref_path.write_text(json.dumps(references, indent=2, sort_keys=False) + "\n", encoding="utf-8")
    print(ref_path)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
