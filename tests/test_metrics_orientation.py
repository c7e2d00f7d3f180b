"""Aghili eq. (43) orientation error against independent references."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from datasets.rotations import quat_wxyz_from_rotation
from workbench.metrics.orientation import (
    orientation_error_rad,
    planar_orientation_error_rad,
    quaternion_product_wxyz,
)


def test_equals_the_relative_rotation_angle_and_the_literal_formula() -> None:
    rng = np.random.default_rng(31)
    estimated = Rotation.random(200, random_state=rng)
    reference = Rotation.random(200, random_state=rng)
    q_est, q_ref = quat_wxyz_from_rotation(estimated), quat_wxyz_from_rotation(reference)
    angles = orientation_error_rad(q_est, q_ref)
    np.testing.assert_allclose(angles, (estimated.inv() * reference).magnitude(), atol=1e-9)
    # The paper's literal 2 asin ||vec(q_hat^* (x) q_ref)||, away from pi where asin is accurate.
    literal = 2.0 * np.arcsin(
        np.linalg.norm(quaternion_product_wxyz(q_est * [1, -1, -1, -1], q_ref)[:, 1:], axis=1)
    )
    moderate = angles < 3.0
    np.testing.assert_allclose(angles[moderate], literal[moderate], atol=1e-9)


def test_sign_of_either_quaternion_does_not_matter_and_pi_is_accurate() -> None:
    q_ref = quat_wxyz_from_rotation(Rotation.from_rotvec([0.0, 0.0, np.pi - 1e-7]))
    identity = np.array([1.0, 0.0, 0.0, 0.0])
    angle = orientation_error_rad(identity, q_ref)
    assert abs(angle - (np.pi - 1e-7)) < 1e-12
    assert orientation_error_rad(-identity, q_ref) == angle
    assert orientation_error_rad(identity, -q_ref) == angle


def test_hamilton_product_matches_scipy_composition() -> None:
    rng = np.random.default_rng(32)
    a, b = Rotation.random(random_state=rng), Rotation.random(random_state=rng)
    product = quaternion_product_wxyz(quat_wxyz_from_rotation(a), quat_wxyz_from_rotation(b))
    expected = quat_wxyz_from_rotation(a * b)
    np.testing.assert_allclose(product * np.sign(product[0]), expected, atol=1e-12)


def test_planar_error_wraps() -> None:
    np.testing.assert_allclose(
        planar_orientation_error_rad(np.array([3.1, 0.0]), np.array([-3.1, 0.5])),
        [2 * np.pi - 6.2, 0.5],
    )
