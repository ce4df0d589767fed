"""Start-up analysis on 10^6 samples: bench.analysis.analyze_startup beside the same steps in statsmodels.

    .venv/bin/python benchmarks/bench_startup_analysis.py [--samples 1000000] [--noise ar|arma]
        [--seed 7] [--repeats 3] [--sm-grid-samples 100000] [--sm-method innovations_mle]

The trace imitates a quartz-flexure accelerometer's power-on output sampled at 100 Hz:
``y = c + a·exp(-t/τ) + b·t + coloured + white`` with c = 2.5 V, a = 50 mV, τ = 600 s,
b = 1 µV/s; the coloured noise is AR(2) (φ = 0.6, -0.2) or ARMA(1,1) (φ = 0.7, θ = 0.4),
innovation σ = 1 mV, plus 0.3 mV white measurement noise; fixed seed.

Timed (design goal of the whole pipeline: < 2 s at 10^6 samples):
* ours — the full ``analyze_startup`` (denoise, trend, outliers, ACF/PACF, order grid,
  estimation, Ljung–Box), best of ``--repeats``;
* statsmodels — the same steps with statsmodels doing the time-series work, run once
  (minutes per repeat): the same wavelet denoising (PyWavelets), the trend by
  ``scipy.optimize.curve_fit`` from the same start values, statsmodels ``acf``/``pacf``,
  the same (p, q) grid fitted with ``ARIMA(...).fit()`` on the first
  ``--sm-grid-samples`` samples (the full-length grid would take tens of minutes; its
  time is extrapolated linearly and labelled so), the chosen order fitted by ``ARIMA``
  on every sample, and statsmodels' Ljung–Box.

Both sides' estimates are printed so the comparison is fair (same orders, same numbers).
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np
from scipy.signal import lfilter

from bench.analysis import analyze_startup
from bench.analysis import trend as trend_mod
from bench.analysis.denoise import wavelet_denoise

GOAL_S = 2.0
FS_HZ = 100.0


def make_trace(n: int, noise: str, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A synthetic start-up trace (module docstring): times in s, output in V."""
    rng = np.random.default_rng(seed)
    t_s = np.arange(n) / FS_HZ
    trend_v = 2.5 + 0.05 * np.exp(-t_s / 600.0) + 1e-6 * t_s
    burn = 1000  # start the coloured noise in its stationary state
    e = rng.normal(0.0, 1e-3, n + burn)
    if noise == "ar":
        coloured = lfilter([1.0], [1.0, -0.6, 0.2], e)[burn:]
    else:
        coloured = lfilter([1.0, 0.4], [1.0, -0.7], e)[burn:]
    return t_s, trend_v + coloured + rng.normal(0.0, 3e-4, n)


def time_ours(t_s: np.ndarray, y: np.ndarray, repeats: int):
    best, result = np.inf, None
    for _ in range(repeats):
        start = time.perf_counter()
        result = analyze_startup(t_s, y)
        best = min(best, time.perf_counter() - start)
    return best, result


def run_statsmodels(t_s: np.ndarray, y: np.ndarray, cells: list[tuple[int, int]], final: tuple[int, int],
                    grid_samples: int, method: str) -> dict:
    """The pipeline's steps with statsmodels (and scipy for the nonlinear trend); returns times and estimates."""
    from scipy.optimize import curve_fit
    from statsmodels.stats.diagnostic import acorr_ljungbox
    from statsmodels.tsa.arima.model import ARIMA
    from statsmodels.tsa.stattools import acf, pacf

    out: dict = {"steps": {}}
    clock = time.perf_counter()

    def lap(name: str) -> None:
        nonlocal clock
        now = time.perf_counter()
        out["steps"][name] = now - clock
        clock = now

    wavelet_denoise(y)
    lap("denoise (PyWavelets)")
    u = t_s - t_s[0]
    span = float(u[-1])
    start = trend_mod._scan(u, y, np.geomspace(u[1], 3 * span, 60))  # the same start values as ours

    def model(uu, c, a, tau, b):
        return c + a * np.exp(-uu / tau) + b * uu

    p0 = [start[0], start[1], start[2], start[-1]]
    popt, pcov = curve_fit(model, u, y, p0=p0)
    out["trend"] = popt
    z = y - model(u, *popt)
    z = (z - z.mean()) / z.std()
    lap("trend (scipy curve_fit)")
    nlags = min(max(20, int(10 * np.log10(z.size))), z.size // 4)
    acf(z, nlags=nlags, fft=True)
    pacf(z, nlags=nlags, method="ldb")
    lap("acf + pacf")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if grid_samples:
            seg = z[:grid_samples]
            table = {}
            for p, q in cells:
                res = ARIMA(seg, order=(p, 0, q), trend="n").fit(method=method)
                table[(p, q)] = (res.aic, res.bic)
            out["grid_best_bic"] = min(table, key=lambda c: table[c][1])
            lap(f"order grid ({len(cells)} cells, {grid_samples} samples)")
        res = ARIMA(z, order=(final[0], 0, final[1]), trend="n").fit(method=method)
        lap(f"ARIMA{(final[0], 0, final[1])} on all samples")
    out["params"] = np.asarray(res.params)
    lb = acorr_ljungbox(res.resid, lags=[min(max(20, sum(final) + 10), z.size // 5)], model_df=sum(final))
    out["ljung_box_p"] = float(np.asarray(lb["lb_pvalue"])[0])
    lap("Ljung-Box")
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=1_000_000)
    parser.add_argument("--noise", choices=("ar", "arma"), default="ar")
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--sm-grid-samples", type=int, default=100_000,
                        help="samples for statsmodels' order grid (0 skips it)")
    parser.add_argument("--sm-method", default="innovations_mle", choices=("innovations_mle", "statespace"),
                        help="statsmodels ARIMA fit method (statespace is about twice as slow)")
    args = parser.parse_args()
    if args.samples < 1000 or args.repeats < 1 or args.sm_grid_samples < 0:
        parser.error("--samples must be >= 1000, --repeats >= 1, --sm-grid-samples >= 0")

    t_s, y = make_trace(args.samples, args.noise, args.seed)
    print(f"trace: {args.samples} samples at {FS_HZ:g} Hz, {args.noise.upper()} coloured + white noise, "
          f"seed {args.seed}")

    ours_s, res = time_ours(t_s, y, args.repeats)
    m, tr = res.model, res.trend
    print(f"\nours   analyze_startup: {ours_s:7.3f} s (best of {args.repeats}; goal < {GOAL_S:g} s: "
          f"{'met' if ours_s < GOAL_S else 'NOT met'})")
    print(f"  trend: c = {tr.offset.value:.7g} ± {tr.offset.std:.2g}, a = {tr.exp_amplitude.value:.6g} ± "
          f"{tr.exp_amplitude.std:.2g}, tau = {tr.exp_tau_s.value:.6g} ± {tr.exp_tau_s.std:.2g} s, "
          f"b = {tr.linear_slope_per_s.value:.6g} ± {tr.linear_slope_per_s.std:.2g} /s ({tr.kind})")
    print(f"  identification: {res.identification.kind} ({res.identification.reason}); "
          f"grid best BIC {res.order_selection.best_bic}, AIC {res.order_selection.best_aic}")
    print(f"  model {m.order_label} by {m.method}: ar = {np.round(m.ar, 5).tolist()}, "
          f"ma = {np.round(m.ma, 5).tolist()}, sigma2 = {m.sigma2:.6g}; Ljung-Box p = {res.ljung_box.p_value:.3g}; "
          f"outliers {res.outliers.count}")

    cells = [(c.p, c.q) for c in res.order_selection.candidates]
    start = time.perf_counter()
    sm = run_statsmodels(t_s, y, cells, (m.p, m.q), args.sm_grid_samples, args.sm_method)
    sm_s = time.perf_counter() - start
    print(f"\nstatsmodels ({args.sm_method}) same steps: {sm_s:7.3f} s (one run)")
    for name, secs in sm["steps"].items():
        print(f"  {name:<40s} {secs:8.3f} s")
    grid_key = next((k for k in sm["steps"] if k.startswith("order grid")), None)
    if grid_key and args.sm_grid_samples < args.samples:
        full_grid_s = sm["steps"][grid_key] * args.samples / args.sm_grid_samples
        print(f"  (the grid on all {args.samples} samples would take ~{full_grid_s:.0f} s by linear extrapolation; "
              f"whole pipeline ~{sm_s - sm['steps'][grid_key] + full_grid_s:.0f} s)")
    else:
        full_grid_s = 0.0
    c, a, tau, b = sm["trend"]
    print(f"  trend: c = {c:.7g}, a = {a:.6g}, tau = {tau:.6g} s, b = {b:.6g} /s")
    if "grid_best_bic" in sm:
        print(f"  grid best BIC on the segment: {sm['grid_best_bic']}")
    prm = sm["params"]
    print(f"  ARIMA({m.p},0,{m.q}): ar = {np.round(prm[:m.p], 5).tolist()}, "
          f"ma = {np.round(prm[m.p:m.p + m.q], 5).tolist()}, sigma2 = {prm[-1]:.6g}; "
          f"Ljung-Box p = {sm['ljung_box_p']:.3g}")

    print(f"\nratio statsmodels / ours: {sm_s / ours_s:.1f}x as run"
          + (f", ~{(sm_s - sm['steps'][grid_key] + full_grid_s) / ours_s:.0f}x with the full-length grid"
             if full_grid_s else ""))


if __name__ == "__main__":
    main()
