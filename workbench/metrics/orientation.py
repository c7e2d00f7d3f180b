"""Orientation error of Aghili, "Lidar SLAM for Autonomous Driving Vehicles", eq. (43).

    Orientation Error = 2 sin^-1 || vec( q_hat^* (x) q_ref ) ||

The vector part of the error quaternion has norm |sin(theta / 2)| for a relative rotation
by theta, so the error is the angle of the relative rotation in [0, pi], independent of the
sign of either quaternion and of the product convention (Aghili's JPL-like product and
Hamilton's give error quaternions that differ only by conjugation, which keeps the norm of
the vector part). We evaluate it as ``2 atan2(||vec||, |w|)``, equal to ``2 asin(||vec||)``
for unit quaternions but accurate near pi, where asin loses half the digits.
"""

from __future__ import annotations

import numpy as np

from datasets.rotations import wrap_angle


def quaternion_product_wxyz(left: np.ndarray, right: np.ndarray) -> np.ndarray:
    """Hamilton product ``left (x) right`` of (w, x, y, z) quaternions, shapes (..., 4)."""
    w1, x1, y1, z1 = np.moveaxis(np.asarray(left, dtype=float), -1, 0)
    w2, x2, y2, z2 = np.moveaxis(np.asarray(right, dtype=float), -1, 0)
    return np.stack(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ],
        axis=-1,
    )


def orientation_error_rad(estimated_wxyz: np.ndarray, reference_wxyz: np.ndarray) -> np.ndarray:
    """Aghili eq. (43): angle [rad] in [0, pi] between estimated and reference attitudes.

    Args:
        estimated_wxyz: unit quaternions (w, x, y, z), shape (..., 4).
        reference_wxyz: unit quaternions (w, x, y, z), shape (..., 4).

    Returns:
        angles [rad], shape (...).
    """
    conjugate = np.asarray(estimated_wxyz, dtype=float) * np.array([1.0, -1.0, -1.0, -1.0])
    error = quaternion_product_wxyz(conjugate, reference_wxyz)
    return 2.0 * np.arctan2(np.linalg.norm(error[..., 1:], axis=-1), np.abs(error[..., 0]))


def planar_orientation_error_rad(
    estimated_heading: np.ndarray, reference_heading: np.ndarray
) -> np.ndarray:
    """The planar case of eq. (43): ``|wrap(theta_ref - theta_est)|`` [rad] in [0, pi]."""
    difference = np.asarray(reference_heading, dtype=float) - np.asarray(
        estimated_heading, dtype=float
    )
    return np.abs(np.asarray(wrap_angle(difference), dtype=float))
