"""Line-direction features of the sensor-based filter (Guerreiro et al. 2013, eq. (1):
``d_dot = -S(omega_m - b) d``): the covariance of a measured unit direction and the match
of a scan's measured directions to a landmark's direction features.
"""

from __future__ import annotations

import math

import numpy as np

MAX_MATCH_ANGLE_RAD = math.radians(30.0)
"""A measured direction further than this from every predicted one is not used."""


def direction_covariance(direction: np.ndarray, sigma_rad: float) -> np.ndarray:
    """Covariance (d, d) of a measured unit direction: ``sigma^2`` across it, a small spread
    (1 % of it) along it, which keeps the block invertible."""
    unit = direction / np.linalg.norm(direction)
    along = np.outer(unit, unit)
    return sigma_rad**2 * (np.eye(len(unit)) - along) + 0.01 * sigma_rad**2 * along


def match_direction(predicted: np.ndarray, measured: np.ndarray) -> np.ndarray | None:
    """The measured unit direction (k, d) closest to ``predicted`` (d,) up to sign (a line has
    none), signed to agree with it; None when none is within ``MAX_MATCH_ANGLE_RAD``."""
    best, best_cosine = None, 0.0
    for candidate in measured:
        norm = np.linalg.norm(candidate)
        if not np.all(np.isfinite(candidate)) or norm == 0:
            continue
        cosine = float(candidate @ predicted) / (norm * max(np.linalg.norm(predicted), 1e-12))
        if abs(cosine) > abs(best_cosine):
            best, best_cosine = candidate, cosine
    if best is None or abs(best_cosine) <= math.cos(MAX_MATCH_ANGLE_RAD):
        return None
    return np.sign(best_cosine) * best / np.linalg.norm(best)
