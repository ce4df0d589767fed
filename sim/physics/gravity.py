"""Normal gravity and Earth rate at the bench site (WGS-84).

Conventions: latitude in degrees (geodetic, north positive), height in metres above
the ellipsoid, the local level frame is East-North-Up (ENU).
"""

from __future__ import annotations

import math

import numpy as np

#: Standard gravity (CGPM 1901), the unit of every ``_g`` quantity in the project.
STANDARD_GRAVITY_MPS2 = 9.80665

# WGS-84 defining and derived constants (NIMA TR8350.2, 3rd ed., tables 3.1-3.4).
_A_M = 6378137.0  # semi-major axis
_F = 1.0 / 298.257223563  # flattening
_GAMMA_E_MPS2 = 9.7803253359  # normal gravity at the equator
_K_SOMIGLIANA = 0.00193185265241  # (b*gamma_p)/(a*gamma_e) - 1
_E2 = 0.00669437999013  # first eccentricity squared
_M_RATIO = 0.00344978650684  # omega^2 a^2 b / GM
EARTH_RATE_RPS = 7.292115e-5  # WGS-84 Earth rotation rate

# The second-order free-air series is good to ~1e-7 relative near the surface only.
_HEIGHT_RANGE_M = (-1000.0, 20000.0)


def _check_latitude(latitude_deg: float) -> float:
    lat = float(latitude_deg)
    if not (-90.0 <= lat <= 90.0):
        raise ValueError(f"latitude_deg={latitude_deg!r} outside the allowed range [-90, 90]")
    return lat


def local_gravity_mps2(latitude_deg: float, height_m: float = 0.0) -> float:
    """Normal gravity magnitude in m/s² at a geodetic latitude and ellipsoidal height.

    Somigliana's closed formula on the WGS-84 ellipsoid, then the second-order
    free-air correction ``γ_h = γ [1 - 2/a (1 + f + m - 2 f sin²φ) h + 3 h²/a²]``.
    ``height_m`` must lie in [-1000, 20000] m, where that series is accurate.
    """
    lat = _check_latitude(latitude_deg)
    h = float(height_m)
    lo, hi = _HEIGHT_RANGE_M
    if not (lo <= h <= hi):
        raise ValueError(f"height_m={height_m!r} outside the allowed range [{lo}, {hi}]")
    s2 = math.sin(math.radians(lat)) ** 2
    gamma = _GAMMA_E_MPS2 * (1.0 + _K_SOMIGLIANA * s2) / math.sqrt(1.0 - _E2 * s2)
    free_air = 1.0 - 2.0 / _A_M * (1.0 + _F + _M_RATIO - 2.0 * _F * s2) * h + 3.0 * h**2 / _A_M**2
    return gamma * free_air


def earth_rate_enu_rps(latitude_deg: float) -> np.ndarray:
    """Earth rotation vector in the local ENU frame, rad/s, shape (3,).

    ``(0, Ω cos φ, Ω sin φ)``: no East component, the North component is the
    horizontal part, the Up component the vertical part.
    """
    lat = math.radians(_check_latitude(latitude_deg))
    return np.array([0.0, EARTH_RATE_RPS * math.cos(lat), EARTH_RATE_RPS * math.sin(lat)])
