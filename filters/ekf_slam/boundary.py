"""Conversion of the EKF's world-frame pose error to the interface convention (DESIGN.md).

The EKF's pose error is world-frame: ``p_true = p + dp``, 2-D ``theta_true = theta + dtheta``,
3-D ``R_true = Exp(dphi) R``. The interface wants the right (body-frame) perturbation of
GTSAM: ``T_true = T Exp(xi)``. To first order

- 2-D (GTSAM Pose2 order [x, y, theta]): ``xi = [R^T dp, dtheta]``;
- 3-D (GTSAM Pose3 order [rotation, translation]): ``xi = [R^T dphi, R^T dp]``.

``tests/test_ekf_slam.py`` checks both against GTSAM's ``localCoordinates``.
"""

from __future__ import annotations

import numpy as np


def world_to_right_jacobian(rotation: np.ndarray) -> np.ndarray:
    """Jacobian (k, k) from the EKF pose error [dp, dtheta | dphi] to the interface tangent.

    Args:
        rotation: body-to-world rotation (2, 2) or (3, 3).
    """
    d = rotation.shape[0]
    if d == 2:
        jacobian = np.eye(3)
        jacobian[:2, :2] = rotation.T
        return jacobian
    jacobian = np.zeros((6, 6))
    jacobian[0:3, 3:6] = rotation.T  # rotation tangent from dphi
    jacobian[3:6, 0:3] = rotation.T  # translation tangent from dp
    return jacobian


def pose_covariance_to_interface(rotation: np.ndarray, covariance: np.ndarray) -> np.ndarray:
    """The pose block covariance (EKF order [position, rotation]) in the interface convention."""
    jacobian = world_to_right_jacobian(rotation)
    converted = jacobian @ covariance @ jacobian.T
    return 0.5 * (converted + converted.T)
