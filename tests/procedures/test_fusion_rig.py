"""Document B's filter on the rig's own physics (table motion → MHD and LF sensor models,
no wire): it never diverges on drawn profiles within the table's limits; the tuning rule
picks what it says it picks."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import bench.analysis.fusion._sequential as fu
from bench.analysis.frf import aperture_compensate
from bench.analysis.fusion import FusionModel, SensorModel, tune_fusion
from bench.analysis.fusion._metrics import nis_check, sine_phasors, tone_noise_std, tone_residual
from instruments.angular_table import AngularLimits
from procedures.fusion import tone_demand
from sim.physics.angular_table import AngularMotion, Tone
from sim.physics.rate_sensors import LF_PRESET, MHD_PRESET, lf_sensor, mhd_sensor

RATE_HZ = 10_000.0
DEG = math.pi / 180


def rig_record(tones_hz, amplitude_dps, seed, duration_s=6.0, settle_s=2.0):
    """Reference, MHD volts and LF °/s at RATE_HZ for a multi-tone demand (limits applied as
    the fusion procedure applies them)."""
    demand = tone_demand(AngularLimits(), np.asarray(tones_hz, dtype=float), amplitude_dps)
    rng = np.random.default_rng(seed)
    motion = AngularMotion(rng=rng)
    motion.set_ramp(0.2)
    motion.start_tones(0.0, [Tone(a * DEG, f, math.radians(ph)) for a, f, ph in demand])
    t0 = 0.2 + settle_s + max(0.0, 2.0 / min(tones_hz))  # past the (whole-period) ramp
    t = t0 + np.arange(int(duration_s * RATE_HZ)) / RATE_HZ
    mhd = mhd_sensor(motion.pieces, rng, MHD_PRESET, t_origin_s=0.0)
    lf = lf_sensor(motion.pieces, rng, LF_PRESET, t_origin_s=0.0)
    dt = 1.0 / RATE_HZ
    hf_v = mhd.mean_output(t - dt / 2, dt) - MHD_PRESET.offset_v
    lf_dps = lf.mean_output(t - dt / 2, dt)
    ref = motion.rate_rad_s(t) / DEG
    return t, hf_v, lf_dps, ref


def true_models():
    hf = SensorModel("highpass", 1, MHD_PRESET.highpass_corner_hz, MHD_PRESET.sensitivity_v_per_rad_s * DEG)
    lf = SensorModel("lowpass", 2, LF_PRESET.corner_hz, LF_PRESET.gain, LF_PRESET.zeta)
    return hf, lf


@settings(max_examples=8, deadline=None)
@given(st.lists(st.floats(-1.0, 3.0), min_size=1, max_size=5, unique=True),
       st.floats(0.5, 50.0), st.integers(0, 2**31 - 1))
def test_the_filter_never_diverges_on_drawn_profiles_within_the_limits(log_f, amplitude, seed):
    tones = np.sort(10.0 ** np.asarray(log_f))
    t, hf, lf, ref = rig_record(tones, amplitude, seed, duration_s=3.0)
    hf_m, lf_m = true_models()
    model, params = fu.tune_fusion_params(hf_m, lf_m, fu.white_noise_var(hf) + 1e-12, fu.white_noise_var(lf) + 1e-12,
                                          hf, lf, 1 / RATE_HZ)
    run = fu.sequential_fusion(hf, lf, 1 / RATE_HZ, model, params)
    assert np.all(np.isfinite(run.rate))
    assert not nis_check(run.nis.sum(axis=1), 2, rate=run.rate).diverged
    # the fused rate follows the table: its error is far below the signal
    assert np.sqrt(np.mean((run.rate - ref) ** 2)) < 0.2 * np.sqrt(np.mean(ref ** 2)) + 0.5


def test_tuning_follows_its_rule_and_tries_a_fixed_r_at_every_q():
    tones = np.array([0.5, 5.0, 50.0, 500.0])
    t, hf, lf, ref = rig_record(tones, 3.0, seed=11, duration_s=4.0)
    hf_m, lf_m = true_models()
    hf_var, lf_var = fu.white_noise_var(hf), fu.white_noise_var(lf)
    model = FusionModel(hf_m, lf_m, fu.estimate_process_noise(hf, lf, 1 / RATE_HZ, FusionModel(hf_m, lf_m, 1.0),
                                                                 hf_var, lf_var))
    tuning = tune_fusion(t, hf, lf, ref, RATE_HZ, model, hf_var, lf_var, tones, q_factors=(1, 10),
                         upper_factors=(1, 10), inflates=(1, 3))
    combos = {(c.q_factor, c.upper_factor, c.inflate) for c in tuning.candidates}
    assert combos == {(1, 1, 1), (1, 10, 3), (10, 1, 1), (10, 10, 3)}
    feasible = [c for c in tuning.candidates if c.feasible]
    if feasible:
        assert tuning.chosen.rms_error == min(c.rms_error for c in feasible)
    else:
        assert tuning.chosen.excess_pct == min(c.excess_pct for c in tuning.candidates)
    assert tuning.q == pytest.approx(model.q * tuning.chosen.q_factor)
    doc = tuning.to_dict()
    assert doc["chosen"]["q_factor"] == tuning.chosen.q_factor and len(doc["candidates"]) == 4


@pytest.mark.parametrize("kwargs,fragment", [
    ({"q_factors": ()}, "q_factors"),
    ({"upper_factors": (0.5,)}, "upper_factors"),
    ({"tones_hz": [6000.0]}, "tones_hz"),
])
def test_tuning_rejects_bad_input(kwargs, fragment):
    t = np.arange(20000) / RATE_HZ
    y = np.sin(2 * np.pi * 5 * t)
    hf_m, lf_m = true_models()
    args = dict(q_factors=(1.0,), upper_factors=(1.0,), inflates=(1.0,))
    tones = kwargs.pop("tones_hz", [5.0])
    args.update(kwargs)
    with pytest.raises(ValueError, match=fragment):
        tune_fusion(t, y, y, y, RATE_HZ, FusionModel(hf_m, lf_m, 1.0), 1e-6, 1e-6, tones, **args)


@settings(max_examples=30, deadline=None)
@given(st.floats(1.0, 1500.0), st.floats(0.2, 1.0), st.floats(0, 2 * math.pi))
def test_aperture_compensation_restores_the_amplitude_of_aperture_means(f_hz, duty, phase):
    ts, ap = 1e-4, duty * 1e-4
    t = np.arange(20000) * ts
    w = 2 * np.pi * f_hz
    # exact mean of sin(w t + φ) over [t - ap/2, t + ap/2]
    y = np.sin(w * t + phase) * np.sinc(f_hz * ap)
    y_c = aperture_compensate(y, ap, ts)
    a = np.abs(sine_phasors(t[1:-1], y_c[1:-1], [f_hz]))[0]
    assert abs(a - 1) < 2e-4 + 0.02 * (w * ap) ** 4  # second-order cancellation; fourth order left
    assert abs(np.abs(sine_phasors(t, y, [f_hz]))[0] - np.sinc(f_hz * ap)) < 1e-9


def test_tone_noise_std_matches_the_spread_of_phasor_estimates():
    rng = np.random.default_rng(4)
    t = np.arange(20000) / 1000.0
    tones = np.array([3.0, 37.0])
    est, pred = [], []
    for _ in range(200):
        e = rng.standard_normal(t.size)
        noise = np.convolve(e, [1.0, 0.8, 0.5], mode="same")  # coloured
        y = np.sin(2 * np.pi * 3 * t) + 0.5 * np.cos(2 * np.pi * 37 * t) + noise
        est.append(sine_phasors(t, y, tones))
        pred.append(tone_noise_std(tone_residual(t, y[:, None], tones)[:, 0], 1000.0, tones))
    spread = np.std(np.real(np.array(est)), axis=0)
    assert np.allclose(np.mean(pred, axis=0), spread, rtol=0.2)
    with pytest.raises(ValueError, match="aperture_s"):
        aperture_compensate(np.ones(5), 2e-4, 1e-4)
