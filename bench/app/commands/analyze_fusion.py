"""``bench analyze fusion --input FILE.csv --rate-hz FS``: every rate-fusion method side by side.

Reads columns ``t`` (s), ``hf``, ``lf`` (same rate unit) and optionally ``ref`` from a CSV
with a header row; runs :func:`bench.analysis.fusion._analysis.analyze_fusion` (with ``ref``:
every method tuned on the first ``--tune-fraction`` and judged on the rest, the recommended
one picked by that judgement); prints a summary (or ``--json``: ``FusionAnalysis.to_dict()``
plus ``source``) and with ``--output`` writes ``t`` and the recommended method's rate in a
column named after the method (e.g. ``t,complementary_smoother``; ``t`` on the reference's
clock when the record was aligned, on the HF sensor's without a reference).

Sensor models without a reference: ``--hf-model``/``--lf-model`` take
``order=2,corner_hz=3.2,zeta=0.7,gain=1,delay_ms=0.05`` (any subset with ``corner_hz``; order 1,
ζ √½, gain 1, delay 0 by default), and ``--models FILE.toml`` the same keys in tables ``[hf]``
and ``[lf]`` (the command line wins over the file; ``--hf-corner-hz``/``--lf-corner-hz`` are the
first-order shorthand).  Each value is checked against its range (:data:`MODEL_KEYS`).

The time column must step by ``1/FS`` (within 1 %).  Bad input raises ``ValueError``; ``bench``
prints it as one line ``bench: error: …`` and exits 2.
"""

from __future__ import annotations

import csv
import inspect
import json
from pathlib import Path

import numpy as np

from bench.analysis.fusion import METHODS, SensorModel, analyze_fusion
from bench.app.commands.analyze import read_csv_table
from bench.core.toml_file import read_toml

SAMPLING_TOLERANCE = 0.01
#: the part of a record with a reference that tunes every method: analyze_fusion's own default
TUNE_FRACTION = inspect.signature(analyze_fusion).parameters["tune_fraction"].default
#: a sensor model's keys on the command line and in a models file: (allowed range in words, check)
MODEL_KEYS = {
    "order": ("1 or 2", lambda v, fs: v in (1, 2)),
    "corner_hz": ("in (0, rate/2) Hz", lambda v, fs: 0 < v < fs / 2),
    "zeta": ("in (0, 10]", lambda v, fs: 0 < v <= 10),
    "gain": ("finite and non-zero", lambda v, fs: v != 0),
    "delay_ms": ("in [-1000, 1000] ms", lambda v, fs: -1000 <= v <= 1000),
}


def register_analysis(kinds) -> None:
    """Add ``fusion`` to the ``bench analyze`` subparsers."""
    p = kinds.add_parser("fusion", help="fusion of an HF (MHD) and an LF rate sensor: every method, one recommended")
    p.add_argument("--input", required=True, metavar="FILE.csv", help="CSV with columns t, hf, lf [, ref]")
    p.add_argument("--rate-hz", required=True, type=float, help="sample rate of the record (Hz)")
    p.add_argument("--tones-hz", default=None, help="comma-separated tone frequencies of ref (Hz) [detected]")
    p.add_argument("--hf-corner-hz", type=float, default=None, help="HF first-order high-pass corner [fit/2 Hz]")
    p.add_argument("--lf-corner-hz", type=float, default=None, help="LF first-order low-pass corner [fit/30 Hz]")
    p.add_argument("--hf-model", metavar="SPEC", default=None,
                   help="HF model: order=1|2,corner_hz=…[,zeta=…,gain=…,delay_ms=…] (a high-pass)")
    p.add_argument("--lf-model", metavar="SPEC", default=None,
                   help="LF model: order=1|2,corner_hz=…[,zeta=…,gain=…,delay_ms=…] (a low-pass)")
    p.add_argument("--models", metavar="FILE.toml", default=None,
                   help="both models in tables [hf] and [lf] with the keys of --hf-model")
    p.add_argument("--crossover-hz", type=float, default=None, help="complementary-filter crossover [√(fh·fl)]")
    p.add_argument("--settle-s", type=float, default=0.0,
                   help="seconds after the tuning part left out of the metrics [0]")
    p.add_argument("--tune-fraction", type=float, default=TUNE_FRACTION,
                   help=f"with ref: the first part that tunes every method; the rest judges [{TUNE_FRACTION:g}]")
    p.add_argument("--json", action="store_true", help="print the results as JSON")
    p.add_argument("--output", metavar="FUSED.csv", default=None,
                   help="write t and the recommended method's rate (its column named after it) here")
    p.set_defaults(func=analyze_fusion_csv)


def _check_time(t: np.ndarray, rate_hz: float) -> None:
    if not (np.isfinite(rate_hz) and rate_hz > 0):
        raise ValueError(f"--rate-hz {rate_hz} must be a finite value > 0")
    if t.size < 16:
        raise ValueError(f"{t.size} rows; at least 16 are needed")
    dt = np.diff(t) * rate_hz
    k = int(np.argmax(np.abs(dt - 1)))
    if abs(dt[k] - 1) > SAMPLING_TOLERANCE:
        raise ValueError(f"the time step after row {k + 2} is {dt[k] / rate_hz:.6g} s, "
                         f"not 1/rate = {1 / rate_hz:.6g} s "
                         f"(allowed ±{SAMPLING_TOLERANCE:.0%}); the record must be uniform at --rate-hz")


def _floats(text: str | None, what: str):
    if text is None:
        return None
    try:
        return np.array([float(v) for v in text.split(",") if v.strip()])
    except ValueError:
        raise ValueError(f"{what} {text!r} must be comma-separated numbers (Hz)") from None


def parse_model_spec(text: str, what: str) -> dict:
    """``key=value,…`` of a sensor model (:data:`MODEL_KEYS`) as a dict of floats."""
    out: dict = {}
    for item in (part.strip() for part in text.split(",")):
        if not item:
            continue
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep:
            raise ValueError(f"{what} {item!r} must be key=value (keys: {', '.join(MODEL_KEYS)})")
        try:
            out[key] = float(value)
        except ValueError:
            raise ValueError(f"{what} {key}={value.strip()!r} is not a number") from None
    return out


def sensor_model(values: dict, kind: str, what: str, rate_hz: float) -> tuple[SensorModel, float]:
    """The model and its delay (s) from ``values`` (keys of :data:`MODEL_KEYS`), each value checked
    against its range; an error names the value and the range."""
    unknown = sorted(set(values) - set(MODEL_KEYS))
    if unknown:
        raise ValueError(f"{what}: unknown key {unknown[0]!r}; allowed: {', '.join(MODEL_KEYS)}")
    if "corner_hz" not in values:
        raise ValueError(f"{what}: corner_hz is required (in (0, {rate_hz / 2:g}) Hz)")
    for key, value in values.items():
        allowed, ok = MODEL_KEYS[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ValueError(f"{what}: {key} {value!r} must be a number {allowed}")
        if not (np.isfinite(value) and ok(value, rate_hz)):
            raise ValueError(f"{what}: {key} {value:g} must be {allowed}".replace("rate/2", f"{rate_hz / 2:g}"))
    model = SensorModel(kind, int(values.get("order", 1)), float(values["corner_hz"]), float(values.get("gain", 1.0)),
                        float(values.get("zeta", SensorModel.__dataclass_fields__["zeta"].default)))
    return model, float(values.get("delay_ms", 0.0)) * 1e-3


def given_models(args) -> tuple[SensorModel | None, SensorModel | None, float, float]:
    """The HF and LF models (None: not given) and their delays (s) from ``--models``,
    ``--hf-model``/``--lf-model`` (which win) and the first-order corner shorthands."""
    specs: dict = {"hf": None, "lf": None}
    if args.models is not None:
        doc = read_toml(args.models, "models file")
        extra = sorted(set(doc) - {"hf", "lf"})
        if extra:
            raise ValueError(f"models file {args.models!r}: unknown table [{extra[0]}]; allowed: [hf], [lf]")
        for name in ("hf", "lf"):
            if name in doc:
                if not isinstance(doc[name], dict):
                    raise ValueError(f"models file {args.models!r}: {name} must be a table [{name}]")
                specs[name] = dict(doc[name])
    for name, spec, corner in (("hf", args.hf_model, args.hf_corner_hz), ("lf", args.lf_model, args.lf_corner_hz)):
        if spec is not None and corner is not None:
            raise ValueError(f"--{name}-model and --{name}-corner-hz both given; give one")
        if spec is not None:
            specs[name] = parse_model_spec(spec, f"--{name}-model")
        elif corner is not None:
            specs[name] = {"order": 1, "corner_hz": corner}
    out: list = []
    delays = []
    for name, kind in (("hf", "highpass"), ("lf", "lowpass")):
        what = f"--{name}-model" if getattr(args, f"{name}_model") is not None else (
            f"--{name}-corner-hz" if getattr(args, f"{name}_corner_hz") is not None else f"[{name}] of {args.models}")
        if specs[name] is None:
            out.append(None)
            delays.append(0.0)
        else:
            model, delay = sensor_model(specs[name], kind, what, args.rate_hz)
            out.append(model)
            delays.append(delay)
    return out[0], out[1], delays[0], delays[1]


def analyze_fusion_csv(args) -> int:
    """Handler of ``bench analyze fusion``."""
    data = read_csv_table(args.input, ("t", "hf", "lf"), ("ref",))
    _check_time(data["t"], args.rate_hz)
    hf_model, lf_model, hf_delay_s, lf_delay_s = given_models(args)
    analysis = analyze_fusion(data["t"], data["hf"], data["lf"], data.get("ref"), args.rate_hz, hf_model=hf_model,
                              lf_model=lf_model, tones_hz=_floats(args.tones_hz, "--tones-hz"),
                              crossover_hz=args.crossover_hz, settle_s=args.settle_s,
                              tune_fraction=args.tune_fraction, hf_delay_s=hf_delay_s, lf_delay_s=lf_delay_s)
    if args.output is not None:
        out = Path(args.output)
        try:
            with out.open("w", newline="") as fh:
                w = csv.writer(fh)
                w.writerow(["t", analysis.recommended])
                w.writerows((f"{a:.9g}", f"{b:.10g}") for a, b in zip(analysis.t_s, analysis.recommended_rate))
        except OSError as exc:
            raise ValueError(f"cannot write {out}: {exc}") from None
    if args.json:
        doc = analysis.to_dict()
        doc["source"] = args.input
        if args.output is not None:
            doc["output"] = args.output
        print(json.dumps(doc, indent=2, allow_nan=False))
        return 0
    m = analysis.model
    print(f"fusion of {args.input}: {analysis.n_samples} samples at {args.rate_hz:.6g} Hz; "
          f"models {analysis.model_source}")
    print(f"  HF {m.hf.kind} order {m.hf.order} corner {m.hf.corner_hz:.4g} Hz gain {m.hf.gain:.5g}; "
          f"LF {m.lf.kind} order {m.lf.order} corner {m.lf.corner_hz:.4g} Hz gain {m.lf.gain:.5g}")
    j = analysis.judgement
    if j is not None:
        print(f"  tuned on the first {analysis.tune_samples} samples, judged on "
              f"{analysis.n_samples - analysis.judged_from}")
        print(f"  {'method':<46} {'RMS error':>11} {'max |amp err| %':>16} {'worst excess':>20}")
        for k, meth in METHODS.items():
            mark = "*" if k == analysis.recommended else " "
            excess = f"{j.worst_excess_pct(k):+.3g} pp ({j.worst_excess_sigma(k):.3g}σ)"
            print(f" {mark}{meth.label:<46} {j.rms_error[k]:11.5g} {float(max(abs(j.amplitude_error_pct[k]))):16.4g} "
                  f"{excess:>20}")
        width = max(22, *(len(k) for k in METHODS))  # every method's whole name heads its column
        print(f"  {'f (Hz)':>10} " + " ".join(f"{k:>{width}}" for k in METHODS))
        for i, f in enumerate(j.tones_hz):
            cells = [f"{j.amplitude_error_pct[k][i]:+8.3f}% {j.phase_error_deg[k][i]:+8.3f}°" for k in METHODS]
            print(f"  {f:10.4g} " + " ".join(f"{c:>{width}}" for c in cells))
    if analysis.checks is not None:
        for key, check in analysis.checks.items():
            print(f"  check {key}: {'passed' if check.passed else 'FAILED'}: {check.reason}")
    for name, s in analysis.nis.items():
        print(f"  NIS {name}: mean {s.mean:.4g} (χ² bounds {s.lower:.4g}–{s.upper:.4g}, dof {s.dof}); "
              f"{'consistent' if s.consistent else 'inconsistent'}{', DIVERGED' if s.diverged else ''}")
    print(f"recommended: {METHODS[analysis.recommended].label} ({analysis.recommended}); "
          f"{analysis.recommendation_rule}")
    for note in analysis.notes:
        print(f"note: {note}")
    if args.output is not None:
        print(f"{analysis.recommended} rate: {args.output}")
    return 0
