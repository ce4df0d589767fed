"""Start-up analysis on 10^6 samples: bench.analysis.startup.analyze_startup beside the same steps in statsmodels.

    .venv/bin/python benchmarks/bench_startup_analysis.py [--samples 1000000] [--noise ar|arma]
        [--seed 7] [--repeats 3] [--sm-grid-samples 20000] [--sm-final-samples N]
        [--sm-method innovations_mle]

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
  then for an AR table ``ar_select_order`` + ``AutoReg`` on every sample (conditional
  least squares, like ours), otherwise the same (p, q) grid fitted with ``ARIMA(...).fit()`` on the first
  ``--sm-grid-samples`` samples (the full-length grid would take tens of minutes; its
  time is extrapolated linearly and labelled so), the chosen order fitted by ``ARIMA``
  on every sample (on the first ``--sm-final-samples`` when the order has more than two
  parameters — MA(5) on 10^6 samples takes over ten minutes — again extrapolated), and
  statsmodels' Ljung–Box.

Both sides' estimates are printed so the comparison is fair (same orders, same numbers).
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np
from scipy import stats
from scipy.optimize import curve_fit
from scipy.signal import lfilter

import bench.analysis.startup._trend as trend_mod
from bench.analysis.startup import analyze_startup, wavelet_denoise

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


def _ljung_box_p(resid: np.ndarray, order: tuple[int, int]) -> float:
    """statsmodels' Ljung–Box Q (``q_stat``) on its FFT ACF, dof reduced by p + q.

    ``acorr_ljungbox`` computes the ACF without FFT (O(n²): hours at 10^6 samples).
    """
    from statsmodels.tsa.stattools import acf, q_stat  # noqa: PLC0415 — the peer only when the benchmark runs

    resid = np.asarray(resid)
    lags = min(max(20, sum(order) + 10), resid.size // 5)
    q = q_stat(acf(resid, nlags=lags, fft=True)[1:], resid.size)[0][-1]
    return float(stats.chi2.sf(q, lags - sum(order)))


def run_statsmodels(t_s: np.ndarray, y: np.ndarray, cells: list[tuple[int, int]], final: tuple[int, int],
                    grid_samples: int, final_samples: int, method: str) -> dict:
    """The pipeline's steps with statsmodels (and scipy for the nonlinear trend); returns times and estimates."""
    from statsmodels.tsa.arima.model import ARIMA  # noqa: PLC0415 — the peer only when the benchmark runs
    from statsmodels.tsa.stattools import acf, acovf, levinson_durbin  # noqa: PLC0415 — the peer only when the benchmark runs

    out: dict = {"steps": {}, "samples": {}}  # step name -> seconds / samples it ran on
    clock = time.perf_counter()

    def lap(name: str, samples: int | None = None) -> None:
        nonlocal clock
        now = time.perf_counter()
        out["steps"][name] = now - clock
        out["samples"][name] = y.size if samples is None else samples
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
    # pacf(method="ldb") would call acovf without FFT (O(n²), minutes at 10^6): same
    # Levinson–Durbin on the biased FFT autocovariances instead
    levinson_durbin(acovf(z, fft=True, nlag=nlags), nlags=nlags, isacov=True)
    lap("acf + pacf")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if final[1] == 0 and all(q == 0 for _, q in cells):  # an AR table: statsmodels' AR tools, all samples
            from statsmodels.tsa.ar_model import AutoReg  # noqa: PLC0415 — the peer only when the benchmark runs

            # ar_select_order(trend="n") builds an n×n matrix for p = 0 (statsmodels bug), so
            # the same table by hand: AutoReg on a common hold-back, p = 0 as white noise
            max_p = max(p for p, _ in cells)
            zc = z[max_p:]
            bics = {0: zc.size * (np.log(2 * np.pi * np.mean(zc**2)) + 1) + np.log(zc.size)}
            for p in range(1, max_p + 1):
                bics[p] = AutoReg(z, lags=p, trend="n", hold_back=max_p).fit().bic
            out["grid_best_bic"] = (min(bics, key=bics.__getitem__), 0)
            lap(f"order grid ({len(cells)} cells, AutoReg, {z.size} samples)")
            res = AutoReg(z, lags=final[0], trend="n").fit()
            lap(f"final AutoReg({final[0]}) ({z.size} samples)")
            out["params"] = np.r_[np.asarray(res.params), res.sigma2]
            out["final_samples"] = z.size
            out["ljung_box_p"] = _ljung_box_p(res.resid, final)
            lap("Ljung-Box")
            return out
        if grid_samples:
            seg = z[:grid_samples]
            table = {}
            for p, q in cells:
                res = ARIMA(seg, order=(p, 0, q), trend="n").fit(method=method)
                table[(p, q)] = (res.aic, res.bic)
            out["grid_best_bic"] = min(table, key=lambda c: table[c][1])
            lap(f"order grid ({len(cells)} cells, {grid_samples} samples)", grid_samples)
        zf = z[:final_samples]
        res = ARIMA(zf, order=(final[0], 0, final[1]), trend="n").fit(method=method)
        lap(f"final ARIMA{(final[0], 0, final[1])} ({zf.size} samples)", zf.size)
    out["final_samples"] = zf.size
    out["params"] = np.asarray(res.params)
    out["ljung_box_p"] = _ljung_box_p(res.resid, final)
    lap("Ljung-Box")
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=1_000_000)
    parser.add_argument("--noise", choices=("ar", "arma"), default="ar")
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--sm-grid-samples", type=int, default=20_000,
                        help="samples for statsmodels' order grid (0 skips it)")
    parser.add_argument("--sm-final-samples", type=int, default=None,
                        help="samples for statsmodels' final ARIMA fit (default: all if p + q <= 2, else 100000)")
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
    final_samples = args.sm_final_samples or (args.samples if m.p + m.q <= 2 else 100_000)
    final_samples = min(final_samples, args.samples)
    sm = run_statsmodels(t_s, y, cells, (m.p, m.q), args.sm_grid_samples, final_samples, args.sm_method)
    sm_s = time.perf_counter() - start
    print(f"\nstatsmodels ({args.sm_method}) same steps: {sm_s:7.3f} s (one run)")
    for name, secs in sm["steps"].items():
        print(f"  {name:<40s} {secs:8.3f} s")
    # steps run on fewer samples than ours: extrapolate linearly (ARIMA fits are O(n))
    scaled = {}
    for name, used in sm["samples"].items():
        if 0 < used < args.samples:
            scaled[name] = sm["steps"][name] * args.samples / used
    full_s = sm_s + sum(v - sm["steps"][k] for k, v in scaled.items())
    for name, secs in scaled.items():
        print(f"  ({name} on all {args.samples} samples: ~{secs:.0f} s by linear extrapolation)")
    if scaled:
        print(f"  whole pipeline on all samples: ~{full_s:.0f} s")
    c, a, tau, b = sm["trend"]
    print(f"  trend: c = {c:.7g}, a = {a:.6g}, tau = {tau:.6g} s, b = {b:.6g} /s")
    if "grid_best_bic" in sm:
        grid_n = next(v for k, v in sm["samples"].items() if k.startswith("order grid"))
        print(f"  grid best BIC on {grid_n} samples: {sm['grid_best_bic']}")
    prm = sm["params"]
    print(f"  final ({m.p},0,{m.q}) on {sm['final_samples']} samples (no outlier replacement): "
          f"ar = {np.round(prm[:m.p], 5).tolist()}, ma = {np.round(prm[m.p:m.p + m.q], 5).tolist()}, "
          f"sigma2 = {prm[-1]:.6g}; "
          f"Ljung-Box p = {sm['ljung_box_p']:.3g}")

    print(f"\nratio statsmodels / ours: {sm_s / ours_s:.1f}x as run"
          + (f", ~{full_s / ours_s:.0f}x with every step on all samples" if scaled else ""))


if __name__ == "__main__":
    main()
