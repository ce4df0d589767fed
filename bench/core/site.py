"""The bench site as the test engineer computes it: local gravity and Earth rate.

WGS-84 normal gravity (Somigliana) with the free-air correction, and the Earth's rotation
rate resolved on the local vertical. Written independently of the simulator's geodesy on
purpose (a test cross-checks the two), because a procedure never imports ``sim``.
"""

from __future__ import annotations

import math

STANDARD_GRAVITY_MPS2 = 9.80665
#: the site of a station that names none (Nanjing, where Document A's lab is; the simulated
#: station's default too)
DEFAULT_SITE = {"latitude_deg": 32.06, "height_m": 10.0}
EARTH_RATE_DPH = 15.041067  # sidereal rotation, deg/h (7.292115e-5 rad/s)
_A_M, _F = 6378137.0, 1 / 298.257223563
_GE, _GP = 9.7803253359, 9.8321849378  # normal gravity at the equator and the pole
_GM, _OMEGA = 3.986004418e14, 7.292115e-5


def _latitude(latitude_deg: float) -> float:
    if isinstance(latitude_deg, bool) or not isinstance(latitude_deg, (int, float)) \
            or not -90.0 <= latitude_deg <= 90.0:
        raise ValueError(f"latitude_deg = {latitude_deg!r} not in -90..90")
    return math.radians(latitude_deg)


def normal_gravity_mps2(latitude_deg: float, height_m: float = 0.0) -> float:
    """|g| in m/s² at geodetic latitude and ellipsoidal height (−1000..10000 m)."""
    if isinstance(height_m, bool) or not isinstance(height_m, (int, float)) \
            or not -1000.0 <= height_m <= 10000.0:
        raise ValueError(f"height_m = {height_m!r} not in -1000..10000")
    phi = _latitude(latitude_deg)
    b = _A_M * (1 - _F)
    e2 = 1 - (b / _A_M) ** 2
    k = b * _GP / (_A_M * _GE) - 1
    s2 = math.sin(phi) ** 2
    gamma0 = _GE * (1 + k * s2) / math.sqrt(1 - e2 * s2)
    m = _OMEGA**2 * _A_M**2 * b / _GM
    return gamma0 * (1 - 2 / _A_M * (1 + _F + m - 2 * _F * s2) * height_m
                     + 3 / _A_M**2 * height_m**2)


def earth_rate_vertical_dph(latitude_deg: float) -> float:
    """Earth rate along the local Up axis, deg/h (positive in the northern hemisphere)."""
    return EARTH_RATE_DPH * math.sin(_latitude(latitude_deg))


def site_gravity_mps2(site: dict) -> float:
    """Local gravity of a station's site: measured ``local_g_mps2`` if given, else normal gravity."""
    return float(site.get("local_g_mps2") or normal_gravity_mps2(site["latitude_deg"], site["height_m"]))
