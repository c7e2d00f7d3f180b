"""Body-frame landmark observation of the world-centric EKF-SLAM and its inverse.

``z = R^T (l - p)`` (the workbench's landmark convention), with Jacobians for the vehicle
error state (``layout.VehicleLayout``) and the landmark:

- 2-D: ``dz/dp = -R^T``, ``dz/dtheta = -J z`` (``J`` the planar generator), ``dz/dl = R^T``;
- 3-D (left world rotation error ``R_true = Exp(dphi) R``): ``dz/dp = -R^T``,
  ``dz/dphi = R^T [l - p]x``, ``dz/dl = R^T``.

The inverse ``l = p + R z`` initialises a landmark: ``dl/dp = I``, ``dl/dtheta = J R z``
(2-D) or ``-[R z]x`` (3-D), ``dl/dz = R``.

The unobservable directions of world-centric SLAM with relative (odometry) motion are a
global translation and a global rotation: with the left world rotation error, ``N`` has
the rows ``[I, J p]`` (2-D) or ``[I, -[p]x]`` (3-D) for the vehicle position, ``[0, I]``
for its rotation and ``[I, J l]`` / ``[I, -[l]x]`` for each landmark. ``H N = 0`` holds
for the Jacobians above when every block is evaluated at the same estimates; an EKF
evaluates them at different ones over time and gains spurious information along ``N``
(the heading of the whole map). ``observability_constrained`` restores ``H N = 0``.
"""

from __future__ import annotations

import numpy as np

from datasets.rotations import PLANAR_GENERATOR, skew
from filters.ekf_slam.layout import VehicleLayout
from filters.ekf_slam.motion import VehicleMean


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
        vehicle[:, :, layout.rotation] = (-((lever @ rotation) @ PLANAR_GENERATOR.T))[:, :, None]
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
        vehicle[:, layout.rotation] = (PLANAR_GENERATOR @ world_offset)[:, None]
    else:
        vehicle[:, layout.rotation] = -skew(world_offset)
    return mean.position + world_offset, vehicle, rotation


def rotation_null_rows(points: np.ndarray) -> np.ndarray:
    """The global-rotation columns of ``N`` for position-like states ``points`` (m, d):
    ``J x`` (2-D, (m, 2, 1)) or ``-[x]x`` (3-D, (m, 3, 3))."""
    points = np.asarray(points, float)
    if points.shape[1] == 2:
        return (points @ PLANAR_GENERATOR.T)[:, :, None]
    return -np.array([skew(point) for point in points])


def observability_constrained(
    layout: VehicleLayout,
    vehicle_jacobians: np.ndarray,
    landmark_jacobian: np.ndarray,
    vehicle_position: np.ndarray,
    first_landmarks: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Observability-constrained measurement Jacobians (OC-EKF: Huang, Mourikis and
    Roumeliotis, "Observability-based rules for designing consistent EKF SLAM
    estimators", IJRR 29(5), 2010): for each observation, the ``H*`` closest to ``H`` in
    the Frobenius norm with ``H* N = 0``, ``H* = H - H U (U^T U)^-1 U^T`` over its non-zero
    columns ``U = [N_vehicle; N_landmark]``. ``N`` is the unobservable subspace as the
    filter has propagated it: the vehicle entry at the latest *prediction* (the FEJ
    propagation Jacobian, kept, maps ``N`` there) and each landmark's at its *first*
    estimate (landmarks do not move). FEJ satisfies the same constraint by evaluating the
    rotation column at those points, which puts the whole correction on that column; a
    landmark first placed far off (a drifted vehicle) then gives a Jacobian far from the
    one at the current estimate. The paper's equation numbers are not checked here (the
    paper is not in the project's reference folder); the rule is its constrained
    least-squares one, tested for ``H* N = 0`` and minimality in ``tests/test_ekf_slam.py``.

    Args:
        vehicle_jacobians: (m, d, n_v) at the current estimates. landmark_jacobian: (d, d).
        vehicle_position: (d,) the latest prediction. first_landmarks: (m, d).

    Returns:
        vehicle Jacobians (m, d, n_v) and landmark Jacobians (m, d, d).
    """
    m, d, size = vehicle_jacobians.shape
    rotations = layout.rotation_size
    gauge = d + rotations  # translations and rotations
    subspace = np.zeros((m, size + d, gauge))
    subspace[:, layout.position, :d] = np.eye(d)
    subspace[:, layout.position, d:] = rotation_null_rows(np.asarray(vehicle_position)[None])
    subspace[:, layout.rotation, d:] = np.eye(rotations)
    subspace[:, size:, :d] = np.eye(d)
    subspace[:, size:, d:] = rotation_null_rows(first_landmarks)
    stacked = np.concatenate(
        [vehicle_jacobians, np.broadcast_to(landmark_jacobian, (m, d, d))], axis=2
    )
    violation = np.einsum("mij,mjk->mik", stacked, subspace)  # H U, (m, d, gauge)
    gram = np.einsum("mji,mjk->mik", subspace, subspace)  # U^T U, (m, gauge, gauge)
    projected = stacked - np.einsum(
        "mik,mkj->mij", violation, np.linalg.solve(gram, np.transpose(subspace, (0, 2, 1)))
    )
    return projected[:, :, :size], projected[:, :, size:]
