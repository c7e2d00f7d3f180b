"""NavSatFix latitude/longitude/altitude -> a local East-North-Up frame.

Method: geodetic (WGS-84) -> Earth-centred Earth-fixed (ECEF) with the exact ellipsoid
formulas, then the rotation of ECEF differences into the ENU frame tangent at an origin
(by default the first fix). Exact for any distance (no flat-earth approximation); the ENU
frame is the world frame of the GPS fixes (x east, y north, z up).
"""

from __future__ import annotations

import numpy as np

WGS84_A_M = 6378137.0
WGS84_E2 = 6.69437999014e-3  # first eccentricity squared


def ecef_from_geodetic(lat_lon_alt: np.ndarray) -> np.ndarray:
    """(N, 3) latitude [deg], longitude [deg], ellipsoidal altitude [m] -> ECEF (N, 3) [m]."""
    lat, lon = np.deg2rad(lat_lon_alt[:, 0]), np.deg2rad(lat_lon_alt[:, 1])
    alt = lat_lon_alt[:, 2]
    n = WGS84_A_M / np.sqrt(1.0 - WGS84_E2 * np.sin(lat) ** 2)
    return np.column_stack(
        [
            (n + alt) * np.cos(lat) * np.cos(lon),
            (n + alt) * np.cos(lat) * np.sin(lon),
            (n * (1.0 - WGS84_E2) + alt) * np.sin(lat),
        ]
    )


def enu_rotation(lat_deg: float, lon_deg: float) -> np.ndarray:
    """Rows east, north, up of the tangent frame at (lat, lon), in ECEF: ``enu = R @ d_ecef``."""
    lat, lon = np.deg2rad(lat_deg), np.deg2rad(lon_deg)
    return np.array(
        [
            [-np.sin(lon), np.cos(lon), 0.0],
            [-np.sin(lat) * np.cos(lon), -np.sin(lat) * np.sin(lon), np.cos(lat)],
            [np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)],
        ]
    )


def geodetic_to_enu(lat_lon_alt: np.ndarray, origin: tuple[float, float, float]) -> np.ndarray:
    """(N, 3) geodetic fixes -> (N, 3) ENU [m] about ``origin`` (lat [deg], lon [deg], alt [m])."""
    origin_ecef = ecef_from_geodetic(np.array([origin], dtype=float))[0]
    return (ecef_from_geodetic(np.asarray(lat_lon_alt, dtype=float)) - origin_ecef) @ enu_rotation(
        origin[0], origin[1]
    ).T
