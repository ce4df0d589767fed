"""``bench analyze allan --input FILE.csv``: overlapping Allan deviation and IEEE 952 noise terms.

Reads a time column (s) and a value column from a CSV with a header row.  The sample
rate comes from the time column, which must be uniform (every interval within 1 % of
the mean interval — a dropped sample or a restart is refused, not bridged).  Prints a
table (or ``--json``: ``AllanResult.to_dict()`` plus ``source``) and with ``--report DIR``
writes the HTML report there.  ``--robust`` replaces isolated outliers first (at
``--false-alarm`` per record); the table, JSON and report show each term's check against
the curve and whether the estimate is robust.  ``--model`` also fits the record's noise model
with ``bench discover``'s estimator (its one criterion over white noise, a quantizer, Gauss–Markov,
flicker, rate random walk, angle noise and a ramp), gives N, B, K, Q and R from it and checks the
model's Allan deviation against the data's interval at every τ (``noise_model`` in the JSON).
Bad input raises ``ValueError``; ``bench`` prints it as one line ``bench: error: …`` and exits 2.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np

from bench.analysis.allan import DEFAULT_FALSE_ALARM, ONE_SIGMA, TERMS, overlapping_adev
from bench.analysis.allan._units import RATE_UNITS
from bench.app.commands.analyze import read_csv_columns
from bench.discovery.data import Record
from bench.discovery.effects import CATALOGUE
from bench.discovery.model import Model, base_model
from bench.discovery.whiten import model_avar
from bench.discovery.workflow import discover

#: What the noise model may hold: the catalogue's random processes (IEEE 952's flicker B, rate
#: random walk K and angle noise Q, and the Gauss–Markov it has no term for), a quantizer of the
#: readings and a ramp (R); white noise (N) is the model's floor.
NOISE_MODEL_IDS = ("gauss_markov", "flicker_noise", "rate_random_walk", "angle_quantization", "quantization",
                   "linear_drift")
#: IEEE 952 term ← (catalogue effect, its parameter); N is the white floor's
MODEL_TERMS = {"Q": ("angle_quantization", "q_angle"), "B": ("flicker_noise", "b"),
               "K": ("rate_random_walk", "k_per_rs"), "R": ("linear_drift", "slope_per_s")}

SAMPLING_TOLERANCE = 0.01


def register_analysis(kinds) -> None:
    """Add ``allan`` to the ``bench analyze`` subparsers."""
    p = kinds.add_parser("allan", help="overlapping Allan deviation and IEEE 952 noise terms of a static record")
    p.add_argument("--input", required=True, metavar="FILE.csv", help="CSV with a header row; time in s")
    p.add_argument("--time-col", default="t", help="time column (s) [t]")
    p.add_argument("--value-col", default="y", help="rate column (or angle with --data-type phase) [y]")
    p.add_argument("--unit", default="dps",
                   help="rate unit of the value column: dps, dph, radps, g, mg, ug, mps2 or none [dps]")
    p.add_argument("--data-type", choices=("rate", "phase"), default="rate",
                   help="rate samples, or their integral (angle, velocity) [rate]")
    p.add_argument("--taus", default="octave", help="octave, log, or comma-separated τ in s [octave]")
    p.add_argument("--points-per-decade", type=int, default=10, help="τ per decade for --taus log [10]")
    p.add_argument("--confidence", type=float, default=ONE_SIGMA, help="interval confidence [0.683]")
    p.add_argument("--terms", default=",".join(TERMS), help="noise terms the fit may use [Q,N,B,K,R]")
    p.add_argument("--robust", action="store_true",
                   help="replace isolated outliers (spikes) before the Allan variance; says how many")
    p.add_argument("--false-alarm", type=float, default=DEFAULT_FALSE_ALARM,
                   help="probability that the outlier screen flags a clean record at all [0.01]")
    p.add_argument("--model", action="store_true",
                   help="also fit the noise model with bench discover's estimator and check its curve (needs --unit)")
    p.add_argument("--alpha", type=float, default=0.05,
                   help="with --model: false-name rate of the noise model's processes [0.05]")
    p.add_argument("--json", action="store_true", help="print the results as JSON")
    p.add_argument("--report", metavar="DIR", default=None, help="write the HTML report into DIR")
    p.set_defaults(func=analyze_allan_csv)


def sample_rate_hz(t_s: np.ndarray) -> float:
    """Sample rate of a uniformly sampled time column; ``ValueError`` naming the first fault."""
    t = np.asarray(t_s, dtype=float)
    if t.size < 2:
        raise ValueError(f"the time column has {t.size} values; at least 2 are needed for a sample rate")
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise ValueError(f"time has {bad.size} non-finite values (first at sample index {bad[0]}); all must be finite")
    dt = np.diff(t)
    if np.any(dt <= 0):
        k = int(np.flatnonzero(dt <= 0)[0])
        raise ValueError(f"time is not strictly increasing at sample index {k + 1} "
                         f"({t[k]:.9g} s then {t[k + 1]:.9g} s)")
    step = float(t[-1] - t[0]) / (t.size - 1)
    deviation = np.abs(dt / step - 1.0)
    k = int(np.argmax(deviation))
    if deviation[k] > SAMPLING_TOLERANCE:
        raise ValueError(f"sampling is not uniform: the interval after sample index {k} is {dt[k]:.6g} s, "
                         f"{deviation[k]:.2%} off the mean {step:.6g} s (allowed ≤ {SAMPLING_TOLERANCE:.0%}); "
                         "Allan deviation needs a uniform record without gaps")
    return 1.0 / step


def _taus(text: str):
    if text in ("octave", "log"):
        return text
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise ValueError(f"--taus {text!r} must be 'octave', 'log' or comma-separated τ in s") from None
    if not values:
        raise ValueError(f"--taus {text!r} must be 'octave', 'log' or comma-separated τ in s")
    return np.array(values)


def _table(result) -> str:
    units = result.units
    lines = [f"{'tau (s)':>12} {'ADEV':>12} {'CI low':>12} {'CI high':>12} {'EDF':>10}  ({units['adev']}, "
             f"{result.confidence:.1%})"]
    for t, a, (lo, hi), e in zip(result.tau_s, result.adev, result.adev_ci, result.edf):
        lines.append(f"{t:12.6g} {a:12.5g} {lo:12.5g} {hi:12.5g} {e:10.4g}")
    lines.append("noise terms: fit ± 1σ | slope-line read-off | check against the curve (slope shown there)")
    for name, c in result.coefficients.items():
        fit = "not fitted" if c.fit is None else f"{c.fit:.4g} ± {'—' if c.fit_std is None else f'{c.fit_std:.2g}'}"
        ro = "—" if c.read_off is None else f"{c.read_off:.4g}"
        check = result.checks[name]
        shown = "" if check.curve_slope is None else f" (slope {check.curve_slope:+.2f} ± {check.curve_slope_sd:.2f})"
        lines.append(f"  {name} {c.label:<26} {fit:>22} | {ro:>10}  {c.unit:<14} | {check.status}{shown}")
    screen = result.outliers
    if screen is not None:
        state = "robust: outliers replaced" if result.robust else "plain estimate (--robust replaces outliers)"
        lines.append(f"{state}; {screen.n_flagged} samples ({screen.fraction:.2%}) flagged at false-alarm "
                     f"probability {screen.false_alarm:g} per record")
    return "\n".join(lines)


def noise_model(t: np.ndarray, y: np.ndarray, rate: float, unit: str | None, result, alpha: float,
                progress=None) -> dict:
    """The record's noise model by ``bench discover``'s estimator (module docstring): its effects,
    the IEEE 952 terms it implies beside the slope fit's (each in the term's customary unit), its
    Allan deviation at the result's τ (the record's unit) and where that leaves the data's
    interval."""
    kind, to_base, _ = RATE_UNITS[unit]
    if kind == "generic":
        raise ValueError("--model needs --unit (dps, dph, radps, g, mg, ug or mps2): the noise model is a gyro's "
                         "or an accelerometer's")
    if result.data_type != "rate":
        raise ValueError("--model needs --data-type rate: the noise model is fitted to rate samples")
    only = tuple(e for e in NOISE_MODEL_IDS if kind in CATALOGUE[e].kinds)
    d = discover(Record(t_s=t - t[0], y=np.asarray(y, float) * to_base), Model(base_model(kind)), only=only,
                 max_effects=len(only), alpha=alpha, progress=progress)
    m = d.final_model
    params = dict(m.effects)
    white = float(m.residual_sd())  # per sample, the readings' rounding included: white in the Allan curve
    ramp = float(params.get("linear_drift", {}).get("slope_per_s", 0.0))
    avar = model_avar(result.tau_s, rate, t.size, white, m.stochastic_effects(), ramp)
    adev = np.sqrt(avar) / to_base
    lo, hi = np.asarray(result.adev_ci, float).T
    outside = [(float(tau), "above" if a > h else "below") for tau, a, lo_, h in zip(result.tau_s, adev, lo, hi)
               if not lo_ <= a <= h]
    values = {"N": white / math.sqrt(rate)}
    values.update({k: abs(float(params[e][q])) for k, (e, q) in MODEL_TERMS.items() if e in params})
    terms = {}
    for name, v in values.items():  # base unit → the record's (÷ to_base) → the term's customary unit
        c = result.coefficients[name]
        terms[name] = {"label": c.label, "value": v * c.factor / to_base, "unit": c.unit,
                       "slope_fit": c.fit, "slope_fit_std": c.fit_std}
    return {"effects": [{"id": s.effect_id, "params": s.params, "params_std": s.params_std, "doubt": s.doubt or None}
                        for s in d.steps],
            "terms": terms, "adev": adev.tolist(), "within": len(result.tau_s) - len(outside),
            "taus": len(result.tau_s), "outside": outside, "notes": list(d.notes)}


def _model_table(nm: dict) -> str:
    lines = ["noise model (bench discover's estimator): " + (", ".join(
        f"{e['id']} (" + ", ".join(f"{k}={v:.4g}" for k, v in e["params"].items()) + ")" for e in nm["effects"])
        or "white noise only")]
    for name, tm in nm["terms"].items():
        fit = "not fitted" if tm["slope_fit"] is None else f"{tm['slope_fit']:.4g}"
        lines.append(f"  {name} {tm['label']:<26} {tm['value']:>12.4g} {tm['unit']:<14} (slope fit: {fit})")
    lines += [f"  doubted — {e['doubt']}" for e in nm["effects"] if e.get("doubt")]
    where = "; ".join(f"{tau:.4g} s ({side})" for tau, side in nm["outside"])
    lines.append(f"  its Allan deviation lies within the data's interval at {nm['within']} of {nm['taus']} τ"
                 + (f"; outside at {where}" if where else ""))
    return "\n".join(lines)


def analyze_allan_csv(args) -> int:
    """Handler of ``bench analyze allan``."""
    t, y = read_csv_columns(args.input, args.time_col, args.value_col)
    rate = sample_rate_hz(t)
    unit = None if args.unit.lower() == "none" else args.unit
    terms = tuple(s.strip() for s in args.terms.split(",") if s.strip())
    result = overlapping_adev(y, rate, _taus(args.taus), data_type=args.data_type,
                              points_per_decade=args.points_per_decade, unit=unit,
                              confidence=args.confidence, terms=terms, robust=args.robust,
                              false_alarm=args.false_alarm)
    nm = None
    if args.model:
        if not 0 < args.alpha < 1:
            raise ValueError(f"--alpha {args.alpha!r}; allowed: (0, 1)")
        nm = noise_model(t, y, rate, unit, result, args.alpha,
                         progress=lambda msg: print(f"discover: {msg}", file=sys.stderr, flush=True))
    report = None
    if args.report is not None:
        # lazy: matplotlib only when --report asks for a report (every `bench analyze` imports this module)
        from bench.app.reports.allan_plot import write_allan_report  # noqa: PLC0415 — lazy, see above

        report = write_allan_report(result, Path(args.report), {"input": args.input, "column": args.value_col})
    if args.json:
        doc = result.to_dict()
        doc["source"] = args.input
        if nm is not None:
            doc["noise_model"] = nm
        if report is not None:
            doc["report"] = str(report)
        print(json.dumps(doc, indent=2, allow_nan=False))
    else:
        print(f"Allan deviation of {args.input}: {t.size} samples at {rate:.6g} Hz "
              f"({(t[-1] - t[0]):.6g} s, {args.data_type})")
        print(_table(result))
        if nm is not None:
            print(_model_table(nm))
        for note in result.notes:
            print(f"note: {note}")
        if report is not None:
            print(f"report: {report}")
    return 0
