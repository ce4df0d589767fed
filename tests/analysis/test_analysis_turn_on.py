"""Turn-on time and warm-up drift of a start-up record."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.analysis.turn_on import turn_on_metrics


@settings(max_examples=15, deadline=None)
@given(amp=st.floats(40e-6, 200e-6), tau=st.floats(60.0, 300.0), seed=st.integers(0, 2**16))
def test_turn_on_time_of_an_exponential_warm_up(amp, tau, seed):
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 2400.0, 0.1)
    y = 1.0 + amp * np.exp(-t / tau) + 1e-6 * rng.standard_normal(t.size)
    band, smooth = 20e-6, 10.0
    r = turn_on_metrics(t, y, band=band, smooth_s=smooth)
    # the causal average of an exponential crosses the band later than the exponential itself
    # by about half the averaging time
    exact = tau * math.log(amp / band)
    assert exact - 1.0 < r.turn_on_time_s < exact + smooth, (r.turn_on_time_s, exact)
    assert r.resolved and r.to_dict()["resolved"] is True  # a measured time, not a bound
    drift_true = amp * (math.exp(-t[-1] / tau) - math.exp(-smooth / tau))
    assert r.warmup_drift == pytest.approx(drift_true, rel=0.02, abs=3 * (r.warmup_drift_std or 0))


def test_a_record_that_never_leaves_the_band_turns_on_at_the_first_average():
    t = np.arange(0.0, 1000.0, 0.5)
    r = turn_on_metrics(t, np.ones_like(t) + 1e-7 * np.sin(t), band=1e-6, smooth_s=5.0,
                        settled_window_s=100.0)
    assert r.turn_on_time_s == pytest.approx(4.5)  # the first 5-s average ends at the 10th sample
    assert not r.resolved  # an upper bound: the unit settled sooner than the window can tell


@pytest.mark.parametrize("kwargs,message", [
    ({"band": 0.0}, "band"), ({"band": 1e-5, "smooth_s": 900.0}, "smooth_s"),
    ({"band": 1e-5, "settled_window_s": 5000.0}, "settled_window_s"),
])
def test_bad_settings_are_named(kwargs, message):
    t = np.arange(0.0, 1000.0, 1.0)
    with pytest.raises(ValueError, match=message):
        turn_on_metrics(t, np.ones_like(t), **kwargs)
