"""The Earth frame as features of the sensor-based filter (``filters.sensor_based.earth_state``):
the pose read back from the features, and its first-order covariance checked against finite
differences of that read-back."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from filters.sensor_based.earth_state import (
    frame_from_pose,
    pose_from_frame,
    pose_jacobian,
)


def _pose(dimension: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    if dimension == 2:
        angle = rng.uniform(-np.pi, np.pi)
        c, s = np.cos(angle), np.sin(angle)
        return np.array([[c, -s], [s, c]]), rng.normal(scale=5.0, size=2)
    return Rotation.random(random_state=seed).as_matrix(), rng.normal(scale=5.0, size=3)


def _world_error(
    rotation: np.ndarray,
    position: np.ndarray,
    other_rotation: np.ndarray,
    other_position: np.ndarray,
) -> np.ndarray:
    """``[dp, dphi]`` with ``p' = p + dp``, ``R' = Exp(dphi) R``."""
    delta = other_rotation @ rotation.T
    if len(position) == 2:
        dphi = np.array([np.arctan2(delta[1, 0], delta[0, 0])])
    else:
        dphi = Rotation.from_matrix(delta).as_rotvec()
    return np.concatenate([other_position - position, dphi])


@pytest.mark.parametrize("dimension", [2, 3])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_pose_round_trip(dimension: int, seed: int) -> None:
    rotation, position = _pose(dimension, seed)
    values, covariance = frame_from_pose(rotation, position, None)
    back_rotation, back_position = pose_from_frame(values)
    np.testing.assert_allclose(back_rotation, rotation, atol=1e-12)
    np.testing.assert_allclose(back_position, position, atol=1e-12)
    assert not covariance.any()


@pytest.mark.parametrize("dimension", [2, 3])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_pose_jacobian_matches_finite_differences(dimension: int, seed: int) -> None:
    """Every feature direction, including the axes' length and skew changes the read-back
    discards; central differences of ``pose_from_frame``. 2-D also off the unit axis (a
    filter's axis drifts off unit length: exact there); 3-D at orthonormal axes (off them the
    analytic form is first order in the axes' deviation, next test)."""
    rotation, position = _pose(dimension, seed)
    values, _ = frame_from_pose(rotation, position, None)
    if dimension == 2:
        values[1] *= 1.03
    rotation, position = pose_from_frame(values)
    flat = values.ravel()
    step = 1e-6
    numeric = np.zeros((len(position) + (1 if dimension == 2 else 3), flat.size))
    for column in range(flat.size):
        plus, minus = flat.copy(), flat.copy()
        plus[column] += step
        minus[column] -= step
        up = _world_error(rotation, position, *pose_from_frame(plus.reshape(values.shape)))
        down = _world_error(rotation, position, *pose_from_frame(minus.reshape(values.shape)))
        numeric[:, column] = (up - down) / (2 * step)
    np.testing.assert_allclose(pose_jacobian(values), numeric, atol=1e-6)


@pytest.mark.parametrize("dimension", [2, 3])
def test_frame_covariance_is_the_pose_covariance_carried_there_and_back(dimension: int) -> None:
    """A pose covariance carried into the features (``frame_from_pose``) and read back
    (``pose_jacobian``) is itself: the two maps are inverse to first order."""
    rotation, position = _pose(dimension, 3)
    k = 3 if dimension == 2 else 6
    rng = np.random.default_rng(4)
    factor = rng.normal(size=(k, k))
    covariance = factor @ factor.T * 1e-3
    values, frame_covariance = frame_from_pose(rotation, position, covariance)
    jacobian = pose_jacobian(values)
    np.testing.assert_allclose(jacobian @ frame_covariance @ jacobian.T, covariance, atol=1e-12)


def test_pose_jacobian_off_orthonormal_axes_3d() -> None:
    """3-D axes 0.01 off unit length and orthogonality: the analytic Jacobian is within a few
    per cent of central differences (the deviation's order), the size of error a first-order
    covariance already carries."""
    rotation, position = _pose(3, 5)
    values, _ = frame_from_pose(rotation, position, None)
    values[1:] += np.random.default_rng(6).normal(scale=0.01, size=(2, 3))
    rotation, position = pose_from_frame(values)
    flat, step = values.ravel(), 1e-6
    numeric = np.zeros((6, 9))
    for column in range(9):
        plus, minus = flat.copy(), flat.copy()
        plus[column] += step
        minus[column] -= step
        up = _world_error(rotation, position, *pose_from_frame(plus.reshape(3, 3)))
        down = _world_error(rotation, position, *pose_from_frame(minus.reshape(3, 3)))
        numeric[:, column] = (up - down) / (2 * step)
    analytic = pose_jacobian(values)
    assert np.abs(analytic - numeric).max() < 0.05 * np.abs(numeric).max()
