"""GPS position fixes as factors on the keyframe pose at the fix's time (3-D only)."""

from __future__ import annotations

import gtsam
import numpy as np

from datasets.errors import InputError
from datasets.measurements import GpsFix


def gps_factor(pose_key: int, fix: GpsFix, dimension: int) -> gtsam.NonlinearFactor:
    """``GPSFactor`` of a world position (3,) [m] with covariance (3, 3) [m^2] on the pose
    ``pose_key`` (the body origin: no lever arm); ``InputError`` on malformed fixes."""
    position = np.asarray(fix.position, dtype=float)
    covariance = np.asarray(fix.covariance, dtype=float)
    if dimension != 3 or position.shape != (3,) or covariance.shape != (3, 3):
        raise InputError(
            f"GPS fix at t={fix.t:.6f} s: expected a 3-D position and a (3, 3) covariance"
        )
    if not (np.all(np.isfinite(position)) and np.all(np.isfinite(covariance))):
        raise InputError(f"GPS fix at t={fix.t:.6f} s is not finite")
    return gtsam.GPSFactor(pose_key, position, gtsam.noiseModel.Gaussian.Covariance(covariance))
