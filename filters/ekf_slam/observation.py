"""Body-frame landmark observation of the world-centric EKF-SLAM and its inverse.

``z = R^T (l - p)`` (the workbench's landmark convention), with Jacobians for the vehicle
error state (``layout.VehicleLayout``) and the landmark:

- 2-D: ``dz/dp = -R^T``, ``dz/dtheta = -J z`` (``J`` the planar generator), ``dz/dl = R^T``;
- 3-D (left world rotation error ``R_true = Exp(dphi) R``): ``dz/dp = -R^T``,
  ``dz/dphi = R^T [l - p]x``, ``dz/dl = R^T``.

The inverse ``l = p + R z`` initialises a landmark: ``dl/dp = I``, ``dl/dtheta = J R z``
(2-D) or ``-[R z]x`` (3-D), ``dl/dz = R``.
"""

from __future__ import annotations

import numpy as np

from datasets.rotations import skew
from filters.ekf_slam.layout import VehicleLayout
from filters.ekf_slam.motion import PLANAR_J, VehicleMean


def predict_observations(
    mean: VehicleMean,
    layout: VehicleLayout,
    landmarks: np.ndarray,
    linearization_landmarks: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Predicted body-frame observations of world landmarks (m, d).

    ``linearization_landmarks`` (m, d): where the rotation column of the vehicle Jacobian is
    evaluated (the landmarks' first estimates for FEJ, Huang, Mourikis and Roumeliotis 2008,
    eq. (26)); default the landmarks themselves (the standard EKF).

    Returns:
        z (m, d), vehicle Jacobians (m, d, n_v), landmark Jacobian R^T (d, d) (the same for all).
    """
    rotation = mean.rotation_matrix()
    relative = np.asarray(landmarks, float) - mean.position
    predicted = relative @ rotation  # rows: R^T (l - p)
    lever = (
        relative
        if linearization_landmarks is None
        else np.asarray(linearization_landmarks, float) - mean.position
    )
    m, d = predicted.shape
    vehicle = np.zeros((m, d, layout.size))
    vehicle[:, :, layout.position] = -rotation.T
    if d == 2:
        vehicle[:, :, layout.rotation] = (-((lever @ rotation) @ PLANAR_J.T))[:, :, None]
    else:
        vehicle[:, :, layout.rotation] = np.einsum(
            "ij,mjk->mik", rotation.T, np.array([skew(r) for r in lever]).reshape(m, 3, 3)
        )
    return predicted, vehicle, rotation.T


def initialise_landmark(
    mean: VehicleMean, layout: VehicleLayout, point: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World position of a body-frame point and its Jacobians.

    Returns:
        l (d,), dl/d(vehicle) (d, n_v), dl/dz (d, d).
    """
    rotation = mean.rotation_matrix()
    world_offset = rotation @ np.asarray(point, float)
    d = len(world_offset)
    vehicle = np.zeros((d, layout.size))
    vehicle[:, layout.position] = np.eye(d)
    if d == 2:
        vehicle[:, layout.rotation] = (PLANAR_J @ world_offset)[:, None]
    else:
        vehicle[:, layout.rotation] = -skew(world_offset)
    return mean.position + world_offset, vehicle, rotation
