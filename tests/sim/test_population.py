"""The simulated accelerometer population: units drawn by serial number."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sim.physics.accelerometer import ACCELEROMETER_SPREAD, draw_accelerometer

SHEET = {"k0_g": 4e-3, "k2_g_per_g2": 20e-6, "delta_o_rad": 70e-6, "delta_p_rad": 70e-6,
         "white_density_g_per_rthz": 2.2e-6}


@settings(max_examples=30)
@given(st.text(min_size=1, max_size=20))
def test_same_serial_same_unit(serial):
    assert draw_accelerometer(serial) == draw_accelerometer(serial)


def test_different_serials_are_different_units():
    units = {draw_accelerometer(f"QA-SIM-{i:04d}").k1_ma_per_g for i in range(50)}
    assert len(units) == 50


def test_population_spread_and_fail_fraction():
    units = [draw_accelerometer(f"QA-SIM-{i:05d}") for i in range(4000)]
    k0 = [u.k0_g for u in units]
    sigma = (sum(x * x for x in k0) / len(k0)) ** 0.5
    assert sigma == pytest.approx(ACCELEROMETER_SPREAD["k0_g"][2], rel=0.06)
    out = sum(any(abs(getattr(u, k)) > v for k, v in SHEET.items())
              or not 1.20 <= u.k1_ma_per_g <= 1.46 for u in units)
    assert 0.03 < out / len(units) < 0.15  # some fail, most pass


def test_overrides_replace_drawn_values_and_are_checked():
    assert draw_accelerometer("X", {"k1_ma_per_g": 1.3}).k1_ma_per_g == 1.3
    with pytest.raises(ValueError, match="k9"):
        draw_accelerometer("X", {"k9": 1.0})
    with pytest.raises(ValueError, match="k1_ma_per_g"):
        draw_accelerometer("X", {"k1_ma_per_g": 9.0})
    with pytest.raises(ValueError, match="serial"):
        draw_accelerometer("")
