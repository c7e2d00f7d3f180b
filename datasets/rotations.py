"""Rotation helpers shared by every package, in the interface conventions of DESIGN.md.

Quaternions are Hamilton, ordered (w, x, y, z), body-to-world: ``v_world = R(q) v_body``.
Rotation vectors are in radians. Arrays may carry leading batch dimensions.

The heavy lifting (batched conversions) is delegated to ``scipy.spatial.transform.Rotation``,
which stores quaternions as (x, y, z, w); the two small adapters below are the only place
that reorders components.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation


def skew(vector: np.ndarray) -> np.ndarray:
    """Cross-product matrix ``[v x]`` of a 3-vector, shape (3, 3): ``skew(a) @ b == a x b``."""
    x, y, z = np.asarray(vector, dtype=float)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def rotation_from_quat_wxyz(quat_wxyz: np.ndarray) -> Rotation:
    """scipy ``Rotation`` from quaternion(s) (w, x, y, z), shape (4,) or (N, 4)."""
    quat = np.asarray(quat_wxyz, dtype=float)
    return Rotation.from_quat(quat[..., [1, 2, 3, 0]])


def quat_wxyz_from_rotation(rotation: Rotation) -> np.ndarray:
    """Quaternion(s) (w, x, y, z) with w >= 0 from a scipy ``Rotation``."""
    quat = rotation.as_quat()[..., [3, 0, 1, 2]]
    sign = np.where(quat[..., :1] < 0.0, -1.0, 1.0)
    return quat * sign


def matrix_from_quat_wxyz(quat_wxyz: np.ndarray) -> np.ndarray:
    """Rotation matrix/matrices, shape (3, 3) or (N, 3, 3), from (w, x, y, z) quaternion(s)."""
    return rotation_from_quat_wxyz(quat_wxyz).as_matrix()


def yaw_from_quat_wxyz(quaternion: np.ndarray) -> float:
    """Yaw [rad] of a quaternion (w, x, y, z) of any nonzero norm: the angle of the body x
    axis projected on the world x-y plane, from world x towards world y."""
    rotation = matrix_from_quat_wxyz(quaternion / np.linalg.norm(quaternion))
    return float(np.arctan2(rotation[1, 0], rotation[0, 0]))


def quat_wxyz_from_matrix(matrix: np.ndarray) -> np.ndarray:
    """(w, x, y, z) quaternion(s) with w >= 0 from rotation matrix/matrices."""
    return quat_wxyz_from_rotation(Rotation.from_matrix(np.asarray(matrix, dtype=float)))


def so3_exp(rotation_vector: np.ndarray) -> np.ndarray:
    """Rodrigues: rotation matrix (3, 3) or (N, 3, 3) of rotation vector(s) [rad]."""
    return Rotation.from_rotvec(np.asarray(rotation_vector, dtype=float)).as_matrix()


def so3_log(matrix: np.ndarray) -> np.ndarray:
    """Rotation vector(s) [rad], shape (3,) or (N, 3), of rotation matrix/matrices."""
    matrix = np.asarray(matrix, dtype=float)
    if matrix.shape == (3, 3) and np.abs(matrix @ matrix.T - np.eye(3)).max() < 1e-12:
        return _so3_log_single(matrix)
    return Rotation.from_matrix(matrix).as_rotvec()


def _so3_log_single(matrix: np.ndarray) -> np.ndarray:
    """``so3_log`` of one rotation matrix (3, 3), orthogonal to rounding, in plain floats:
    the quaternion by Markley's method (the largest of the diagonal and the trace picks the
    well-conditioned formula, as scipy's ``from_matrix``), then ``2 atan2(|v|, w) v / |v|``
    with w >= 0 and a Taylor series near zero, as scipy's ``as_rotvec``. scipy's
    ``Rotation`` costs 50-300 us a call in its array-API wrapping, which the lidar front end
    pays twice a frame; this costs 2 us and agrees with it to 1e-14 rad
    (``tests/test_rotations.py``). Matrices further from orthogonal go to scipy, which
    projects them onto the nearest rotation differently."""
    (m00, m01, m02), (m10, m11, m12), (m20, m21, m22) = matrix.tolist()
    trace = m00 + m11 + m22
    largest = max(m00, m11, m22, trace)  # ties go to the first, as scipy's argmax
    if largest == m00:
        x, y, z, w = 1.0 + 2.0 * m00 - trace, m01 + m10, m02 + m20, m21 - m12
    elif largest == m11:
        x, y, z, w = m01 + m10, 1.0 + 2.0 * m11 - trace, m12 + m21, m02 - m20
    elif largest == m22:
        x, y, z, w = m02 + m20, m12 + m21, 1.0 + 2.0 * m22 - trace, m10 - m01
    else:
        x, y, z, w = m21 - m12, m02 - m20, m10 - m01, 1.0 + trace
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    if w < 0.0:
        norm = -norm
    x, y, z, w = x / norm, y / norm, z / norm, w / norm
    vector_norm = math.sqrt(x * x + y * y + z * z)
    angle = 2.0 * math.atan2(vector_norm, w)
    if angle <= 1e-3:
        squared = angle * angle
        scale = 2.0 + squared / 12.0 + 7.0 * squared * squared / 2880.0
    else:
        scale = angle / math.sin(angle / 2.0)
    return np.array([scale * x, scale * y, scale * z])


def wrap_angle(angle_rad: np.ndarray | float) -> np.ndarray | float:
    """Wrap angle(s) to [-pi, pi)."""
    return (np.asarray(angle_rad) + np.pi) % (2.0 * np.pi) - np.pi


PLANAR_GENERATOR = np.array([[0.0, -1.0], [1.0, 0.0]])
"""The generator of planar rotations, ``d rot2(a) / da = PLANAR_GENERATOR @ rot2(a)``
(``J`` or ``S`` in the papers' equations: ``J v`` is ``v`` turned by +90 degrees)."""


def rot2(angle_rad: float) -> np.ndarray:
    """Planar rotation matrix (2, 2) of an angle [rad]."""
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    return np.array([[c, -s], [s, c]])


def rot2_batch(angles_rad: np.ndarray) -> np.ndarray:
    """Planar rotation matrices, shape (N, 2, 2), of angles [rad], shape (N,)."""
    c, s = np.cos(angles_rad), np.sin(angles_rad)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)


def pose3_inverse_adjoint(rotation_vector: np.ndarray, translation: np.ndarray) -> np.ndarray:
    """Adjoint map (6, 6) of the inverse of the Pose3 increment ``U = (Exp(rotation_vector),
    translation)`` in GTSAM's [rotation, translation] tangent order: for ``T' = T U`` with
    right perturbations ``T_true = T Exp(xi)``, ``xi' = Ad(U^-1) xi + eta``.
    ``Ad(U^-1) = [[R^T, 0], [[-R^T t]x R^T, R^T]]`` (checked against GTSAM's
    ``Pose3.inverse().AdjointMap()`` in the tests)."""
    rotation_inverse = so3_exp(np.asarray(rotation_vector, dtype=float)).T
    adjoint = np.zeros((6, 6))
    adjoint[0:3, 0:3] = rotation_inverse
    adjoint[3:6, 3:6] = rotation_inverse
    adjoint[3:6, 0:3] = (
        skew(-rotation_inverse @ np.asarray(translation, dtype=float)) @ rotation_inverse
    )
    return adjoint
