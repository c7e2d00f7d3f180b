"""Marginal covariances from GTSAM, converted to the interface conventions of DESIGN.md.

GTSAM's conventions, and what the interface wants:
- ``Pose3``: GTSAM's tangent is [omega, v] with ``T (+) xi = T * Exp(xi)`` (right, body
  frame). The interface's 3-D pose covariance is [rotation, translation], both body-frame
  right perturbations: the same to first order, so the block is passed through (symmetrised).
- ``Pose2``: GTSAM's tangent is [x, y, theta], right perturbation: the interface's order.
- ``ConstantBias``: GTSAM's 6-vector is [accelerometer, gyroscope]; the interface has two
  blocks, ``gyro_bias`` and ``accel_bias``, same sign (measured = true + bias).
- velocity (``Vector3``) and landmarks (``Point3``/``Point2``) are world-frame vectors.

``tests/test_smoother_covariance.py`` checks all of this against Monte Carlo errors computed
with our own rotation code (no GTSAM in the reference).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np


class MarginalSource(Protocol):
    """Anything with ``marginalCovariance(key)``: ``gtsam.Marginals``, ``ISAM2``,
    ``IncrementalFixedLagSmoother``."""

    def marginalCovariance(self, key: int) -> np.ndarray: ...


def symmetric(matrix: np.ndarray) -> np.ndarray:
    """``(A + A^T) / 2`` as a float array."""
    matrix = np.asarray(matrix, dtype=float)
    return 0.5 * (matrix + matrix.T)


def pose_covariance(gtsam_covariance: np.ndarray) -> np.ndarray:
    """Interface pose covariance from GTSAM's Pose3 (6, 6) or Pose2 (3, 3) marginal."""
    return symmetric(gtsam_covariance)


@dataclass(frozen=True)
class BiasCovariances:
    """Bias covariance blocks in the interface convention.

    Attributes:
        gyro: (3, 3) [rad^2/s^2].
        accel: (3, 3) [m^2/s^4].
    """

    gyro: np.ndarray
    accel: np.ndarray


def bias_covariances(gtsam_covariance: np.ndarray) -> BiasCovariances:
    """Split GTSAM's (6, 6) ``ConstantBias`` marginal, ordered [accel, gyro]."""
    full = symmetric(gtsam_covariance)
    return BiasCovariances(gyro=full[3:6, 3:6], accel=full[0:3, 0:3])


def vector_covariance(gtsam_covariance: np.ndarray) -> np.ndarray:
    """World-frame vector (velocity, landmark): GTSAM's marginal as is, symmetrised."""
    return symmetric(gtsam_covariance)
