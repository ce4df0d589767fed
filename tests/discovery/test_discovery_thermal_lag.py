"""thermal_lag: the element's temperature behind the logged (case) one through a first-order lag.

The discretisation against a hand-written closed form, its derivative, the nesting of
temperature_bias at short lags, what the record resolves, and recovery of the coefficients and
the lag by the fit the naming step runs (starts from ``fit_starts``, then ``CandidateFitter``)
on drawn chamber records.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.discovery.data import Record
from bench.discovery.effects import CATALOGUE
from bench.discovery.effects_terms import T_REF_C
from bench.discovery.effects_thermal import LAG_DRAW_S, element_temperature
from bench.discovery.fitting import CandidateFitter
from bench.discovery.model import BaseModel, Model

LAG = CATALOGUE["thermal_lag"]
BIAS = CATALOGUE["temperature_bias"]


def _stamps(n: int, dt: float, jitter: float, rng: np.random.Generator) -> np.ndarray:
    """n time stamps with mean interval dt, each interval within ±jitter·dt of it."""
    return np.concatenate([[0.0], np.cumsum(dt * rng.uniform(1 - jitter, 1 + jitter, n - 1))])


# ---- (a) the discretisation ------------------------------------------------------------------

@settings(max_examples=40, deadline=None, derandomize=True)
@given(lag_s=st.floats(5.0, 2000.0), jitter=st.sampled_from([0.0, 0.5]), step_c=st.floats(-40.0, 40.0),
       seed=st.integers(0, 2 ** 16))
def test_a_logged_step_reaches_one_minus_one_over_e_of_itself_one_lag_later(lag_s, jitter, step_c, seed):
    """The logged temperature steps between samples j−1 and j; linear between its samples, that is
    a ramp over h = t_j − t_{j−1}, whose first-order lag is, for t ≥ t_j (by hand):
    T_e(t) = T1 − ΔT·(lag/h)·(1 − e^(−h/lag))·e^(−(t − t_j)/lag). Uniform and non-uniform stamps."""
    if abs(step_c) < 0.1:
        step_c = 0.1
    rng = np.random.default_rng(seed)
    dt = lag_s / 40
    t = _stamps(500, dt, jitter, rng)
    j = 20
    temp = np.where(np.arange(t.size) >= j, 20.0 + step_c, 20.0)
    rec = Record(t_s=t, y=np.zeros(t.size), temp_c=temp)
    te = element_temperature(rec, lag_s)
    h = t[j] - t[j - 1]
    after = t[j:] - t[j]
    ref = np.concatenate([np.full(j, 20.0),
                          20.0 + step_c - step_c * (lag_s / h) * -math.expm1(-h / lag_s) * np.exp(-after / lag_s)])
    np.testing.assert_allclose(te, ref, rtol=0, atol=1e-10 * abs(step_c))
    # one lag after the step's middle the element has made 1 − 1/e of it (to second order in h/lag,
    # far inside a quarter interval: a sample-and-hold of either end would be half an interval off)
    frac = (te - 20.0) / step_c
    k = int(np.argmax(frac >= 1 - math.exp(-1)))
    t_cross = t[k - 1] + (1 - math.exp(-1) - frac[k - 1]) / (frac[k] - frac[k - 1]) * (t[k] - t[k - 1])
    assert abs(t_cross - (0.5 * (t[j - 1] + t[j]) + lag_s)) <= 0.25 * float(np.max(np.diff(t)))


@settings(max_examples=25, deadline=None, derandomize=True)
@given(log_lag=st.floats(math.log(0.05), math.log(1e5)), jitter=st.sampled_from([0.0, 0.9]),
       seed=st.integers(0, 2 ** 16))
def test_the_lag_gradient_is_the_derivative_of_the_recursion(log_lag, jitter, seed):
    rng = np.random.default_rng(seed)
    t = _stamps(300, 2.0, jitter, rng)
    rec = Record(t_s=t, y=np.zeros(t.size), temp_c=20 + np.cumsum(rng.normal(0, 0.3, t.size)),
                 input=rng.choice([-10.0, 0.0, 30.0], t.size))
    lag = math.exp(log_lag)
    p = {"coef_per_c": 3e-4, "sf_coef_per_c": -2e-5, "lag_s": lag}
    grads = LAG.term_gradient(p, rec, ["coef_per_c", "sf_coef_per_c", "lag_s"])
    h = 1e-4 * lag  # central difference: truncation ~1e-8, rounding ~1e-16·20 °C / h
    fd = (LAG.term(p | {"lag_s": lag + h}, rec) - LAG.term(p | {"lag_s": lag - h}, rec)) / (2 * h)
    np.testing.assert_allclose(grads[2], fd, rtol=1e-5, atol=1e-6 * float(np.max(np.abs(fd))))
    np.testing.assert_allclose(grads[0], element_temperature(rec, lag) - T_REF_C, rtol=1e-12)
    np.testing.assert_allclose(grads[1], grads[0] * rec.input, rtol=1e-12)


# ---- (c) the nesting ---------------------------------------------------------------------

@settings(max_examples=40, deadline=None, derandomize=True)
@given(log_lag=st.floats(math.log(1e-3), math.log(1e3)), coef=st.floats(-1e-4, 1e-4),
       jitter=st.sampled_from([0.0, 0.5]), seed=st.integers(0, 2 ** 16))
def test_at_short_lags_the_term_is_temperature_biass(log_lag, coef, jitter, seed):
    """The element never falls behind the logged temperature by more than lag × its fastest rate
    (exact for a first-order lag started at the logged value), so the term differs from
    temperature_bias's at the same coefficient by at most |coef|·lag·max|dT/dt| — zero as lag → 0."""
    rng = np.random.default_rng(seed)
    t = _stamps(200, 1.0, jitter, rng)
    temp = 10 + np.cumsum(rng.normal(0, 0.5, t.size))
    rec = Record(t_s=t, y=np.zeros(t.size), temp_c=temp)
    lag = math.exp(log_lag)
    ours = LAG.term({"coef_per_c": coef, "sf_coef_per_c": 0.0, "lag_s": lag}, rec)
    theirs = BIAS.term({"coef_per_c": coef, "coef_per_c2": 0.0}, rec)
    fastest = float(np.max(np.abs(np.diff(temp) / np.diff(t))))
    assert np.max(np.abs(ours - theirs)) <= abs(coef) * lag * fastest * (1 + 1e-9) + 1e-15
    if lag < 1e-2:
        np.testing.assert_allclose(ours, theirs, rtol=0, atol=abs(coef) * 1e-2 * fastest + 1e-15)


# ---- what the record resolves --------------------------------------------------------------

def _chamber(rng: np.random.Generator, hours: float = 3.0, rate_hz: float = 1.0) -> np.ndarray:
    """A chamber profile: soaks and ramps at 0.5-2 °C/min between levels in −20 … +60 °C, from a
    start near room temperature; the logged temperature quantized at 0.01 °C."""
    n = int(hours * 3600 * rate_hz)
    kt, kv = [0.0], [float(rng.uniform(15, 30))]
    while kt[-1] < n / rate_hz:
        kt.append(kt[-1] + rng.uniform(900, 2400))  # soak
        kv.append(kv[-1])
        level = float(rng.uniform(-20, 60))
        kt.append(kt[-1] + abs(level - kv[-1]) / (rng.uniform(0.5, 2.0) / 60))  # ramp
        kv.append(level)
    return np.round(np.interp(np.arange(n) / rate_hz, kt, kv), 2)


def test_free_parameters_and_what_the_record_resolves():
    rng = np.random.default_rng(11)
    temp = _chamber(rng)
    t = np.arange(temp.size, dtype=float)
    static = Record(t_s=t, y=np.zeros(t.size), temp_c=temp, input=np.ones(t.size))
    table = static.replace(input=np.where((t // 600) % 2 == 0, 50.0, -50.0))
    p = {"coef_per_c": 1e-5, "sf_coef_per_c": 0.0, "lag_s": 450.0}
    assert [q.name for q in LAG.free_params(p, "accelerometer", static)] == ["coef_per_c", "lag_s"]
    assert [q.name for q in LAG.free_params(p, "gyro", table)] == ["coef_per_c", "sf_coef_per_c", "lag_s"]
    lag_q = LAG.fit_params(static, "accelerometer")[2]
    assert (lag_q.low, lag_q.high) == (3.0, static.duration_s)
    assert LAG.drawable_range(lag_q, static, "accelerometer") == LAG_DRAW_S
    assert LAG.identifiable(p, static)
    assert not LAG.identifiable(p | {"lag_s": 0.6 * static.duration_s}, static)  # does not settle in it
    flat = static.replace(temp_c=np.full(t.size, 25.0))
    assert not LAG.applies_to(flat) and not LAG.identifiable(p, flat)
    # a temperature that barely moves: lag × its change of rate below the logged resolution
    crawl = static.replace(temp_c=25 + 1e-3 * t / t[-1])
    assert not LAG.identifiable(p, crawl)


def test_catalogue_relations_and_draws_on_a_chamber_record():
    assert CATALOGUE.look_alikes("thermal_lag") == ("temperature_bias",)
    assert "thermal_lag" in CATALOGUE.look_alikes("temperature_bias")
    assert "step" in CATALOGUE.separating_recipe("temperature_bias", "thermal_lag")
    temp = _chamber(np.random.default_rng(12))
    rec = Record(t_s=np.arange(temp.size, dtype=float), y=np.zeros(temp.size), temp_c=temp)
    for seed in range(5):
        p = LAG.draw(np.random.default_rng(seed), rec, kind="accelerometer", noise_sd=5e-6)
        assert LAG_DRAW_S[0] <= p["lag_s"] <= LAG_DRAW_S[1] and p["sf_coef_per_c"] == 0.0
        assert LAG.snr(p, rec, 5e-6) >= 15 * 0.98 and LAG.identifiable(p, rec)


# ---- (b) recovery ---------------------------------------------------------------------------

#: White noise per 1-Hz sample: a QA-2000-class accelerometer (5 µg) and a tactical FOG (3e-3
#: deg/s, the catalogue's defaults).
NOISE = {"accelerometer": 5e-6, "gyro": 3e-3}


def _recovery_case(seed: int) -> tuple[str, Record, dict, Model]:
    """A chamber record (3 h at 1 Hz) with a drawn lag of 300-600 s: even seeds a static
    accelerometer at 1 g (no SF part), odd seeds a gyro on a rate table stepping between
    −100 … +100 deg/s every 5-15 min (an SF part too)."""
    rng = np.random.default_rng([7, seed])
    temp = _chamber(rng)
    t = np.arange(temp.size, dtype=float)
    lag = float(math.exp(rng.uniform(math.log(LAG_DRAW_S[0]), math.log(LAG_DRAW_S[1]))))
    sign = rng.choice([-1.0, 1.0], 2)
    if seed % 2 == 0:
        kind = "accelerometer"
        rec = Record(t_s=t, y=np.zeros(t.size), temp_c=temp, input=np.ones(t.size))
        p = {"coef_per_c": float(sign[0] * math.exp(rng.uniform(math.log(2e-7), math.log(2e-5)))),
             "sf_coef_per_c": 0.0, "lag_s": lag}
    else:
        kind = "gyro"
        edges = np.cumsum(rng.uniform(300, 900, 40))
        levels = rng.uniform(-100, 100, edges.size + 1)
        rec = Record(t_s=t, y=np.zeros(t.size), temp_c=temp, input=levels[np.searchsorted(edges, t)])
        p = {"coef_per_c": float(sign[0] * math.exp(rng.uniform(math.log(1e-5), math.log(1e-3)))),
             "sf_coef_per_c": float(sign[1] * math.exp(rng.uniform(math.log(1e-6), math.log(1e-4)))),
             "lag_s": lag}
    base = BaseModel(kind, bias=float(rng.uniform(-1e-3, 1e-3)), scale_factor=1.0 + float(rng.normal(0, 1e-4)),
                     noise_sd=NOISE[kind])
    truth = Model(base, (("thermal_lag", p),))
    rec = rec.replace(y=truth.simulate(rec, int(rng.integers(2 ** 31))))
    return kind, rec, p, Model(BaseModel(kind, noise_sd=NOISE[kind]))


def _fit(kind: str, rec: Record, model: Model):
    """As the naming step fits a waveform: starts from fit_starts on the base model's residual,
    the first one the template, a bounded least-squares fit from each."""
    r = rec.y - model.predict(rec)
    starts = LAG.fit_starts(rec, r, kind=kind)
    f = CandidateFitter(model, rec, LAG, template=starts[0])
    return f.fit([f.pack(s, model.base.bias, model.base.scale_factor) for s in starts])


def test_a_fit_recovers_the_coefficients_and_the_lag_on_chamber_records() -> None:
    """Over 20 drawn records every truth lies within 3 stated standard errors of its estimate in
    at least 90 % of them (the sf coefficient on the gyro's half), and the estimates are not
    biased: the mean standardised error of each parameter within ±1 (3σ of a mean of 10-20 unit
    normals)."""
    z: dict[str, list[float]] = {"coef_per_c": [], "sf_coef_per_c": [], "lag_s": []}
    for seed in range(20):
        kind, rec, truth, model = _recovery_case(seed)
        fit = _fit(kind, rec, model)
        assert fit.ok
        for name in z:
            if name == "sf_coef_per_c" and not rec.varies("input"):
                assert fit.params[name] == 0.0 and name not in fit.params_std  # fixed, not fitted
                continue
            z[name].append((fit.params[name] - truth[name]) / fit.params_std[name])
        assert LAG.identifiable(fit.params, rec)
    for name, zs in z.items():
        a = np.asarray(zs)
        assert np.mean(np.abs(a) <= 3) >= 0.9, (name, a)
        assert abs(float(np.mean(a))) <= 3 / math.sqrt(a.size), (name, a)


def test_fit_starts_find_the_lag_of_a_clean_term():
    """On a noiseless residual the best start's lag is the grid point nearest the truth (17
    points over 3 s … 3 h: a factor 1.6 apart), its coefficient within 30 %."""
    temp = _chamber(np.random.default_rng(13))
    rec = Record(t_s=np.arange(temp.size, dtype=float), y=np.zeros(temp.size), temp_c=temp)
    for lag in (320.0, 580.0):
        p = {"coef_per_c": 4e-6, "sf_coef_per_c": 0.0, "lag_s": lag}
        best = LAG.fit_starts(rec, LAG.term(p, rec) + 1e-3, kind="accelerometer")[0]
        assert best["lag_s"] == pytest.approx(lag, rel=0.3) and best["coef_per_c"] == pytest.approx(4e-6, rel=0.3)
