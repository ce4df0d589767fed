"""The bench's site model agrees with the simulator's independent geodesy."""

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from bench.core.site import earth_rate_vertical_dph, normal_gravity_mps2
from sim.physics.gravity import earth_rate_enu_rps, local_gravity_mps2


@given(st.floats(-90, 90), st.floats(-500, 5000))
def test_gravity_matches_the_simulator(lat, h):
    assert normal_gravity_mps2(lat, h) == pytest.approx(local_gravity_mps2(lat, h), rel=1e-7)


@given(st.floats(-90, 90))
def test_earth_rate_matches_the_simulator(lat):
    up = math.degrees(earth_rate_enu_rps(lat)[2]) * 3600
    assert earth_rate_vertical_dph(lat) == pytest.approx(up, rel=1e-5, abs=1e-9)


@pytest.mark.parametrize("lat,h", [(91, 0), (0, 20000), (True, 0)])
def test_bad_site_is_refused(lat, h):
    with pytest.raises(ValueError):
        normal_gravity_mps2(lat, h)
