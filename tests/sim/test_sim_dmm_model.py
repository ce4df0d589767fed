"""DMM measurement physics: aperture averaging, NPLC rules, noise table, overload."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from sim.devices.dmm_model import (
    NOISE_PPM_OF_RANGE,
    OVERLOAD,
    DmmConverter,
    DmmFrontEnd,
    LinePickup,
    range_for,
    round_up_nplc,
)


@given(st.floats(1e-3, 100.0))
def test_nplc_rounds_up_to_a_supported_value(requested):
    got = round_up_nplc(requested, has_dig=True)
    assert got in NOISE_PPM_OF_RANGE and got >= requested * (1 - 1e-9)


def test_integer_nplc_rejects_line_pickup_and_fractional_does_not():
    pickup = LinePickup(amplitude_v=1e-3, nominal_hz=50.0, offset_fraction=2e-4)
    t = np.linspace(0, 10, 2001)
    residue_int = np.abs(pickup.averaged(t, 1.0 / 50.0)).max()   # 1 NPLC
    residue_frac = np.abs(pickup.averaged(t, 0.2 / 50.0)).max()  # 0.2 NPLC
    assert residue_int < 1e-3 * 1e-3  # better than 60 dB normal-mode rejection
    assert residue_frac > 0.5e-3      # a 4 ms aperture barely attenuates 50 Hz


@given(st.floats(0, 1.0), st.floats(1e-4, 0.5))
def test_aperture_average_matches_numerical_integration(t0, aperture):
    pickup = LinePickup(amplitude_v=1.0, nominal_hz=50.0)
    ts = np.linspace(t0, t0 + aperture, 20001)
    w = 2 * np.pi * 50.0 * (1 + pickup.offset_fraction)
    numeric = np.trapezoid(np.sin(w * ts + pickup.phase_rad), ts) / aperture
    assert pickup.averaged(np.array([t0]), aperture)[0] == pytest.approx(numeric, abs=1e-6)


@pytest.mark.parametrize("nplc", [0.02, 0.2, 1.0, 10.0])
def test_reading_noise_follows_the_data_sheet_table(nplc):
    conv = DmmConverter(np.random.default_rng(3))
    fe = DmmFrontEnd(range_v=10.0, autorange=False, nplc=nplc, autozero="ON")
    readings = conv.convert(np.full(20000, 6.5), fe)
    expected = NOISE_PPM_OF_RANGE[nplc] * 1e-6 * 10.0
    assert np.std(readings) == pytest.approx(expected, rel=0.05)
    assert np.mean(readings) == pytest.approx(6.5, abs=5 * expected / np.sqrt(20000))


def test_overload_reads_plus_minus_9_9e37():
    conv = DmmConverter(np.random.default_rng(0))
    fe = DmmFrontEnd(range_v=1.0, autorange=False, nplc=1.0)
    out = conv.convert(np.array([0.5, 1.3, -1.3]), fe)
    assert out[1] == OVERLOAD and out[2] == -OVERLOAD and abs(out[0] - 0.5) < 1e-4


def test_autozero_off_adds_the_zero_offset_and_doubles_nothing():
    conv = DmmConverter(np.random.default_rng(5), zero_offset_sigma_v=1e-3)
    on = DmmFrontEnd(range_v=10.0, autorange=False, nplc=100.0, autozero="ON")
    off = DmmFrontEnd(range_v=10.0, autorange=False, nplc=100.0, autozero="OFF")
    x = np.full(5000, 1.0)
    shift = conv.convert(x, off).mean() - conv.convert(x, on).mean()
    assert shift == pytest.approx(conv.zero_offset_v, abs=1e-6)
    assert on.reading_time_s > 1.9 * off.aperture_s and off.reading_time_s < 1.1 * off.aperture_s


@pytest.mark.parametrize("volts,expected", [(0.05, 0.1), (1.0, 1.0), (6.6, 10.0), (999, 1000.0)])
def test_range_selection(volts, expected):
    assert range_for(volts) == expected


def test_range_above_1000_v_is_refused():
    with pytest.raises(ValueError, match="1000"):
        range_for(1500)
