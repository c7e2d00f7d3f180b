"""Rotation helpers shared by every package, in the interface conventions of DESIGN.md.

Quaternions are Hamilton, ordered (w, x, y, z), body-to-world: ``v_world = R(q) v_body``.
Rotation vectors are in radians. Arrays may carry leading batch dimensions.

The heavy lifting (batched conversions) is delegated to ``scipy.spatial.transform.Rotation``,
which stores quaternions as (x, y, z, w); the two small adapters below are the only place
that reorders components.
"""

from __future__ import annotations

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


def quat_wxyz_from_matrix(matrix: np.ndarray) -> np.ndarray:
    """(w, x, y, z) quaternion(s) with w >= 0 from rotation matrix/matrices."""
    return quat_wxyz_from_rotation(Rotation.from_matrix(np.asarray(matrix, dtype=float)))


def so3_exp(rotation_vector: np.ndarray) -> np.ndarray:
    """Rodrigues: rotation matrix (3, 3) or (N, 3, 3) of rotation vector(s) [rad]."""
    return Rotation.from_rotvec(np.asarray(rotation_vector, dtype=float)).as_matrix()


def so3_log(matrix: np.ndarray) -> np.ndarray:
    """Rotation vector(s) [rad], shape (3,) or (N, 3), of rotation matrix/matrices."""
    return Rotation.from_matrix(np.asarray(matrix, dtype=float)).as_rotvec()


def wrap_angle(angle_rad: np.ndarray | float) -> np.ndarray | float:
    """Wrap angle(s) to [-pi, pi)."""
    return (np.asarray(angle_rad) + np.pi) % (2.0 * np.pi) - np.pi


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
