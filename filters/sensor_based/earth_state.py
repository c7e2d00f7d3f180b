"""The Earth-fixed frame as non-visible features of the sensor-based filter (Guerreiro et
al. 2013, section I: "by including unobservable position and direction landmarks that
represent the reference frame in the sensor-based frame"; section V, Fig. 6: "the
Earth-fixed reference frame ... was added to the sensor-based SLAM filter as a nonvisible
landmark").

The frame is one position feature, the Earth origin in the body frame ``o = -R^T p``, and
its axes in the body frame, ``a_x = R^T e_x`` (2-D) or ``a_x, a_y`` (3-D), where ``R`` (body
to Earth) and ``p`` (body origin in Earth) are the vehicle's Earth-frame pose. They obey
the landmarks' own eq. (1) (``o_dot = -S(omega) o - v``, ``a_dot = -S(omega) a``), are never
measured, and are exactly static in the Earth frame, so they take no disturbance (neither
sigma_p nor the direction walk): their uncertainty is the gyro noise, bias and velocity
that move them, and every update corrects them through their correlation with the map, as
a robocentric EKF-SLAM's frame is corrected (Castellanos et al. 2007, the paper's [16]).
The pose is read back from them (``pose_from_frame``) with a first-order covariance
(``pose_jacobian``, world coordinates ``[dp, dphi]``: ``p_true = p + dp``,
``R_true = Exp(dphi) R``); the Earth map is ``R (l - o)`` for every body-frame landmark.

This is the paper's first route to the Earth frame; ``earth_frame`` is its second (the
closed-form alignment of its ref. [22]). ``SensorBasedConfig.earth_frame_source`` chooses;
the alignment is the default. Measured (``tests/test_sensor_based_consistency.py``, study
tier): consistent where the model holds, 2-D ``sim:guerreiro-loop`` pose ANEES 2.40 per 3
dof, 3-D ``sim:aghili-rover`` 0.95 per dof (a 3-D pose covariance the alignment does not
export); but on UTIAS with ids 1.2-1.8 times the alignment's ATE (0.100-0.218 m against
0.080-0.121 m; known limits in ``docs/estimators/sensor-based.md``).
"""

from __future__ import annotations

import numpy as np

from datasets.rotations import PLANAR_GENERATOR, rot2, skew

EARTH_ORIGIN = "earth_origin"
EARTH_AXIS = "earth_axis"
EARTH_FRAME_OWNER = -1
"""Registry owner id of the frame's features (map ids are >= 0)."""


def axis_count(dimension: int) -> int:
    """Axes the frame carries: one in 2-D (the heading), two in 3-D (the third is their cross
    product)."""
    return 1 if dimension == 2 else 2


def frame_from_pose(
    rotation: np.ndarray, position: np.ndarray, covariance: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray]:
    """The frame's features for a vehicle pose: values (1 + axes, d) ``[o, a_x(, a_y)]`` and
    their covariance (k d, k d) from the pose's (world coordinates ``[dp, dphi]``, (3, 3) or
    (6, 6); None: zero, the pose defines the frame).

    First order: ``do = -R^T dp + R^T Exp'(dphi) p``, ``da_i = -R^T (dphi x e_i)``."""
    rotation = np.asarray(rotation, dtype=float)
    position = np.asarray(position, dtype=float)
    d = rotation.shape[0]
    k = 1 + axis_count(d)
    values = np.vstack([-rotation.T @ position, rotation.T[:, : axis_count(d)].T])
    if covariance is None:
        return values, np.zeros((k * d, k * d))
    # jacobian of the features with respect to [dp, dphi]
    if d == 2:
        jacobian = np.zeros((k * d, 3))
        jacobian[:2, :2] = -rotation.T
        jacobian[:2, 2] = rotation.T @ PLANAR_GENERATOR @ position
        jacobian[2:4, 2] = -rotation.T @ PLANAR_GENERATOR @ np.array([1.0, 0.0])
    else:
        jacobian = np.zeros((k * d, 6))
        jacobian[:3, :3] = -rotation.T
        jacobian[:3, 3:] = -rotation.T @ skew(position)
        jacobian[3:6, 3:] = rotation.T @ skew(np.array([1.0, 0.0, 0.0]))
        jacobian[6:9, 3:] = rotation.T @ skew(np.array([0.0, 1.0, 0.0]))
    frame_covariance = jacobian @ np.asarray(covariance, dtype=float) @ jacobian.T
    return values, 0.5 * (frame_covariance + frame_covariance.T)


def pose_from_frame(features: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The vehicle's Earth-frame pose from the frame's features ``[o, a_x(, a_y)]``
    (1 + axes, d): rotation (d, d) body to Earth, position (d,) [m]. The axes are
    re-orthonormalised (their estimates drift off unit length and orthogonality to first
    order in their errors): 2-D ``theta = atan2(-a_y, a_x)``; 3-D the nearest rotation to
    ``[a_x, a_y, a_x x a_y]``."""
    features = np.asarray(features, dtype=float)
    origin = features[0]
    if features.shape[1] == 2:
        axis = features[1]
        rotation = rot2(float(np.arctan2(-axis[1], axis[0])))
    else:
        a_x, a_y = features[1], features[2]
        transposed = np.column_stack([a_x, a_y, np.cross(a_x, a_y)])  # R^T
        u, _, vt = np.linalg.svd(transposed)
        fix = np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt)) or 1.0])
        rotation = (u @ fix @ vt).T
    return rotation, -rotation @ origin


def pose_jacobian(features: np.ndarray) -> np.ndarray:
    """Jacobian (k, F) of the pose error ``[dp, dphi]`` (world coordinates) with respect to the
    frame's features ``[o, a_x(, a_y)]`` flattened (F = (1 + axes) d), first order at
    ``features``.

    2-D: ``dtheta = (a_y da_x - a_x da_y) / |a|^2`` and ``dp = -R do - R G o dtheta``.
    3-D: with ``u = R da_x``, ``w = R da_y`` (``R da_x = e_x x dphi``, ``R da_y = e_y x
    dphi`` for a pure rotation error), ``dphi = [-w_z, u_z, (w_x - u_y) / 2]`` (the two
    estimates of ``dphi_z`` averaged; the axes' length and skew changes are not rotations)
    and ``dp = -R do + S(R o) dphi``. Exact (to first order) at orthonormal axes; off them,
    wrong by the order of their deviation (a few per cent at 0.01,
    ``tests/test_sensor_based_earth_state.py``), the size of a first-order covariance's own
    error. 2-D: exact at any axis length."""
    features = np.asarray(features, dtype=float)
    rotation, _ = pose_from_frame(features)
    origin = features[0]
    d = features.shape[1]
    if d == 2:
        axis = features[1]
        heading_row = np.array([axis[1], -axis[0]]) / float(axis @ axis)
        jacobian = np.zeros((3, 4))
        jacobian[2, 2:] = heading_row
        jacobian[:2, :2] = -rotation
        jacobian[:2, 2:] = np.outer(-rotation @ PLANAR_GENERATOR @ origin, heading_row)
        return jacobian
    select = np.zeros((3, 6))  # dphi from [u, w]
    select[0, 5] = -1.0
    select[1, 2] = 1.0
    select[2, 3] = 0.5
    select[2, 1] = -0.5
    rotation_rows = select @ np.kron(np.eye(2), rotation)  # (3, 6): dphi from [da_x, da_y]
    jacobian = np.zeros((6, 9))
    jacobian[3:, 3:] = rotation_rows
    jacobian[:3, :3] = -rotation
    jacobian[:3, 3:] = skew(rotation @ origin) @ rotation_rows
    return jacobian


def pose_covariance(features: np.ndarray, covariance: np.ndarray) -> np.ndarray:
    """First-order covariance (k, k) of the pose (world coordinates ``[dp, dphi]``) from the
    frame features' covariance (F, F)."""
    jacobian = pose_jacobian(features)
    result = jacobian @ covariance @ jacobian.T
    return 0.5 * (result + result.T)
