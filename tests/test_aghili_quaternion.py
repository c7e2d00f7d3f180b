"""Aghili's quaternion algebra (section 2.1, eq. (39), (40c)) and its boundary to the interface."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm
from scipy.spatial.transform import Rotation

from datasets.rotations import matrix_from_quat_wxyz, skew, so3_exp
from filters.aghili import quaternion_jpl as quat


def random_quaternion(rng: np.random.Generator) -> np.ndarray:
    q = rng.normal(size=4)
    return q / np.linalg.norm(q)


def test_rotation_matrix_is_hamilton_matrix_of_the_same_numbers() -> None:
    rng = np.random.default_rng(1)
    for _ in range(10):
        q = random_quaternion(rng)
        wxyz = quat.to_interface_wxyz(q)
        np.testing.assert_allclose(quat.rotation_matrix(q), matrix_from_quat_wxyz(wxyz), atol=1e-12)
        np.testing.assert_allclose(quat.from_interface_wxyz(wxyz), q * np.sign(q[3]), atol=1e-12)


def test_product_composes_rotations_in_the_papers_order() -> None:
    rng = np.random.default_rng(2)
    q1, q2 = random_quaternion(rng), random_quaternion(rng)
    # A3 = A1 A2  <=>  q3 = q2 (x) q1
    np.testing.assert_allclose(
        quat.rotation_matrix(quat.multiply(q2, q1)),
        quat.rotation_matrix(q1) @ quat.rotation_matrix(q2),
        atol=1e-12,
    )
    np.testing.assert_allclose(quat.multiply(quat.conjugate(q1), q1), quat.IDENTITY, atol=1e-12)


@pytest.mark.parametrize("rate", [0.0, 1e-7, 0.3, 5.0])
def test_exponential_matches_expm_and_preserves_norm(rate: float) -> None:
    rng = np.random.default_rng(3)
    axis = rng.normal(size=3)
    omega = rate * axis / np.linalg.norm(axis)
    duration = 0.7
    omega_quat = np.r_[omega, 0.0]
    exact = expm(0.5 * duration * quat.product_matrix(omega_quat))
    closed = quat.exponential_matrix(omega, duration)
    np.testing.assert_allclose(closed, exact, atol=1e-12)
    np.testing.assert_allclose(closed @ closed.T, np.eye(4), atol=1e-12)


def test_printed_exponential_is_not_norm_preserving() -> None:
    omega = np.array([0.0, 0.0, np.pi])
    printed = quat.paper_printed_exponential_matrix(omega, 1.0)
    q = quat.IDENTITY
    assert abs(np.linalg.norm(printed @ q) - 1.0) > 0.1


def test_propagation_is_a_body_frame_rotation() -> None:
    """q_dot = 1/2 omega (x) q with body rate omega: A(t) = A(0) Exp(omega t)."""
    rng = np.random.default_rng(4)
    q0 = random_quaternion(rng)
    omega = np.array([0.2, -0.5, 0.9])
    q1 = quat.propagate(q0, omega, 0.4)
    np.testing.assert_allclose(
        quat.rotation_matrix(q1), quat.rotation_matrix(q0) @ so3_exp(omega * 0.4), atol=1e-12
    )


def test_error_quaternion_is_a_right_perturbation_with_half_angle() -> None:
    rng = np.random.default_rng(5)
    q_nominal = random_quaternion(rng)
    dq_v = np.array([1e-3, -2e-3, 0.5e-3])
    q = quat.apply_error(dq_v, q_nominal)
    # A(q) = Abar A(dq): rotation vector 2 dq_v (exactly 2 asin|dq_v| along dq_v)
    relative = quat.rotation_matrix(q_nominal).T @ quat.rotation_matrix(q)
    rotvec = Rotation.from_matrix(relative).as_rotvec()
    np.testing.assert_allclose(
        rotvec, 2.0 * np.arcsin(np.linalg.norm(dq_v)) * dq_v / np.linalg.norm(dq_v), atol=1e-14
    )
    np.testing.assert_allclose(relative, np.eye(3) + 2.0 * skew(dq_v), atol=2e-5)
    np.testing.assert_allclose(quat.error_vector(q, q_nominal), dq_v, atol=1e-14)


def test_oversized_correction_is_rescaled_to_a_unit_quaternion() -> None:
    q = quat.apply_error(np.array([2.0, 0.0, 0.0]), quat.IDENTITY)
    assert np.isclose(np.linalg.norm(q), 1.0) and np.all(np.isfinite(q))
