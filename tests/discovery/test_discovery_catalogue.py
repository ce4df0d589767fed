"""The catalogue as one explicit registry, and the hooks through which a new effect joins the
workflow: a new random process written as one class works in the spectral fit, the Kalman
whitening and the white-floor estimate without any of those modules changing."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import signal

from bench.discovery.data import Record
from bench.discovery.effects import CATALOGUE, Catalogue
from bench.discovery.effects_base import Effect, Param
from bench.discovery.effects_noise import (
    ComponentEstimate,
    GaussMarkov,
    RateRandomWalk,
    StateBlock,
    StochasticEffect,
)
from bench.discovery.effects_terms import (
    K2Nonlinearity,
    LinearDrift,
    ScaleFactorAsymmetry,
    TemperatureBias,
    TemperatureScaleFactor,
)
from bench.discovery.significance import white_floor
from bench.discovery.stochastic import fit_stochastic
from bench.discovery.whiten import innovations, noise_psd

# ---- the catalogue ------------------------------------------------------------------------


def test_the_catalogue_is_an_immutable_ordered_mapping_of_its_classes():
    assert list(CATALOGUE)[:3] == ["warmup_exponential", "linear_drift", "temperature_bias"]
    assert all(isinstance(e, Effect) and e.id == eid for eid, e in CATALOGUE.items())
    assert not hasattr(CATALOGUE, "__setitem__") and not hasattr(CATALOGUE, "update")
    with pytest.raises(ValueError, match="unknown effect id 'nope'; allowed: \\['warmup_exponential'"):
        CATALOGUE.effect("nope")
    with pytest.raises(ValueError, match="unknown sensor kind 'sonar'"):
        CATALOGUE.for_kind("sonar")


def test_look_alikes_are_the_catalogues_own_effects_both_ways():
    for eid, e in CATALOGUE.items():
        for other in e.competitors:
            assert other in CATALOGUE.look_alikes(eid) and eid in CATALOGUE.look_alikes(other)
        assert all(type(a) is type(CATALOGUE[a.id]) for a in e.look_alikes)
    assert CATALOGUE.look_alikes("time_delay") == ("lowpass_bandwidth",)
    assert CATALOGUE.look_alikes("linear_drift") == ()


class _Drift2(LinearDrift):
    """A new waveform effect declaring its relations to old ones on itself alone."""

    id = "drift_two"
    competitors = ("linear_drift",)
    separating = {"temperature_bias": "a recipe declared on the new effect only"}


def test_relations_declared_on_a_new_effect_hold_for_the_old_one_too():
    cat = Catalogue((LinearDrift, TemperatureBias, TemperatureScaleFactor, RateRandomWalk, _Drift2))
    assert cat.look_alikes("linear_drift") == ("drift_two",)  # LinearDrift's class was not touched
    assert cat.look_alikes("drift_two") == ("linear_drift",)
    assert cat.separating_recipe("temperature_bias", "drift_two") == "a recipe declared on the new effect only"
    assert cat.separating_recipe("drift_two", "temperature_bias") == "a recipe declared on the new effect only"
    # the look-alike enters the snr: on a record where a drift and the new effect coincide, the
    # distinct snr of the new one is nothing, its plain snr the full size
    rec = Record(t_s=np.arange(500.0), y=np.zeros(500))
    p = {"slope_per_s": 1e-8}
    assert cat["drift_two"].snr(p, rec, 1e-6) < 1e-6 * cat["drift_two"].plain_snr(p, rec, 1e-6)
    assert cat["drift_two"].plain_snr(p, rec, 1e-6) == pytest.approx(LinearDrift().snr(p, rec, 1e-6))


@pytest.mark.parametrize("classes,match", [
    ((LinearDrift, LinearDrift), "id 'linear_drift' is empty or repeated"),
    ((K2Nonlinearity,), "competitors names 'scale_factor_asymmetry'; allowed: another entry"),
    ((LinearDrift, TemperatureBias), "separating names 'rate_random_walk'"),
])
def test_a_catalogue_with_a_broken_entry_is_refused_naming_it(classes, match):
    with pytest.raises(ValueError, match=match):
        Catalogue(classes)


def test_a_recipe_given_on_both_effects_of_a_pair_is_refused():
    class _Asym(ScaleFactorAsymmetry):
        separating = {"k2_nonlinearity": "a second recipe for the same pair"}

    with pytest.raises(ValueError, match="given twice"):
        Catalogue((K2Nonlinearity, _Asym))


# ---- a new random process: one class ----------------------------------------------------------


class CornerGaussMarkov(StochasticEffect):
    """A first-order Gauss–Markov process stated by its corner frequency f_c = 1/(2π·τ) instead
    of τ: written only through the hooks (no module of the workflow knows it)."""

    id = "gauss_markov_corner"
    description = "Gauss–Markov bias noise stated by its corner frequency"
    form = "x' = −2π·corner_hz·x + w, stationary sd sigma; y += x"
    inputs = ("t",)
    main_param = "sigma"
    signature = "spectrum Lorentzian with corner corner_hz"
    competitors = ("gauss_markov",)
    n_coords = 2  # log σ², logit φ (φ = e^{−2π·f_c·dt} per sample)
    ranges = {k: (Param("sigma", "u", 1e-9, 10.0, log=True), Param("corner_hz", "Hz", 1e-6, 1e3, log=True))
              for k in ("accelerometer", "gyro", "mhd")}

    def noise(self, p, rec, rng):
        phi = math.exp(-2 * math.pi * p["corner_hz"] * rec.dt_s)
        e = rng.normal(0.0, p["sigma"] * math.sqrt(1 - phi * phi), rec.n)
        e[0] = rng.normal(0.0, p["sigma"])
        return signal.lfilter([1.0], [1.0, -phi], e)

    def snr(self, p, rec, noise_sd):
        return GaussMarkov().snr({"sigma": p["sigma"], "tau_s": 1 / (2 * math.pi * p["corner_hz"])}, rec, noise_sd)

    def spectrum(self, th, c, grad):
        s2, phi = np.exp(th[0]), 1.0 / (1.0 + np.exp(-th[1]))
        den = 1 - 2 * phi * c + phi ** 2
        level = s2 * (1 - phi ** 2) / den
        d_phi = (-2 * phi * den - (1 - phi ** 2) * (2 * phi - 2 * c)) / den ** 2
        return level, ([level, s2 * d_phi * phi * (1 - phi)] if grad else [])

    def coords(self, p, dt_s):
        phi = math.exp(-2 * math.pi * p["corner_hz"] * dt_s)
        return [math.log(p["sigma"] ** 2), math.log(phi / (1 - phi))]

    def whittle_starts(self, v):
        return [np.array([math.log(0.8 * v), math.log(b * v), math.log(phi / (1 - phi))])
                for b in (0.1, 1.0) for phi in (0.9, 0.995)]

    def estimate(self, r, th, cov, dt_s, *, alone, bootstrap):
        sigma, phi = math.exp(0.5 * th[0]), 1.0 / (1.0 + math.exp(-th[1]))
        corner = -math.log(phi) / (2 * math.pi * dt_s)
        sd = np.sqrt(np.clip(np.diag(cov), 0, None))
        d_corner = (1 - phi) / (2 * math.pi * dt_s)  # |d f_c / d logit φ|
        return ComponentEstimate({"sigma": sigma, "corner_hz": corner},
                                 {"sigma": 0.5 * sigma * sd[0], "corner_hz": d_corner * sd[1]})

    def state_space(self, p, dt_s, n):
        phi = math.exp(-2 * math.pi * p["corner_hz"] * dt_s)
        return StateBlock.diagonal((phi,), (p["sigma"] ** 2 * (1 - phi * phi),), (p["sigma"] ** 2,))


NEW = CornerGaussMarkov()
P_NEW = {"sigma": 0.6, "corner_hz": 1 / (2 * math.pi * 3.0)}  # τ = 3 s
P_GM = {"sigma": 0.6, "tau_s": 3.0}


def _record(n: int, dt: float) -> Record:
    return Record(t_s=np.arange(n) * dt, y=np.zeros(n))


def test_a_new_process_is_fitted_by_the_spectral_machinery_unchanged():
    rng = np.random.default_rng(4)
    n, dt = 8000, 0.1
    r = NEW.apply(P_NEW, _record(n, dt), np.zeros(n), rng=rng) + rng.normal(0, 1, n)
    fit = fit_stochastic(r - r.mean(), dt, NEW)
    assert fit.effect is NEW and fit.p_value < 1e-6
    for name in ("sigma", "corner_hz"):
        assert abs(fit.params[name] - P_NEW[name]) <= 3 * fit.params_std[name], name
    # the catalogue's Gauss–Markov on the same record: the same process, the same likelihood
    gm = fit_stochastic(r - r.mean(), dt, CATALOGUE["gauss_markov"])
    assert fit.lr == pytest.approx(gm.lr, rel=1e-6)
    assert 1 / (2 * math.pi * fit.params["corner_hz"]) == pytest.approx(gm.params["tau_s"], rel=1e-4)


def test_a_new_process_whitens_and_sets_the_floor_as_its_catalogue_twin_does():
    rng = np.random.default_rng(5)
    n, rate = 5000, 10.0
    r = rng.normal(0, 0.5, n) + NEW.apply(P_NEW, _record(n, 1 / rate), np.zeros(n), rng=rng)
    gm = CATALOGUE["gauss_markov"]
    np.testing.assert_allclose(innovations(r, rate, 0.5, [(NEW, P_NEW)]),
                               innovations(r, rate, 0.5, [(gm, P_GM)]), rtol=1e-9, atol=1e-12)
    f = np.linspace(0.01, 5.0, 50)
    np.testing.assert_allclose(noise_psd(f, rate, [(NEW, P_NEW)]), noise_psd(f, rate, [(gm, P_GM)]), rtol=1e-9)
    assert white_floor(r, rate, [(NEW, P_NEW)])[0] == pytest.approx(white_floor(r, rate, [(gm, P_GM)])[0],
                                                                    rel=1e-9)


def test_a_new_process_joins_a_catalogue_as_the_look_alike_of_the_old_one():
    cat = Catalogue((GaussMarkov, RateRandomWalk, CornerGaussMarkov))
    assert cat.look_alikes("gauss_markov") == ("gauss_markov_corner",)
    assert cat["gauss_markov_corner"].stochastic and not cat["gauss_markov_corner"].waveform
