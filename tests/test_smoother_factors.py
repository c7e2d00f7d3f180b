"""Landmark and motion factors of the smoother: error conventions and Jacobians, checked
numerically against ``p = R^T (rho - r)`` and finite differences."""

from __future__ import annotations

import gtsam
import gtsam_unstable
import numpy as np
import pytest
from gtsam.symbol_shorthand import L, V, X

from datasets.rotations import so3_exp
from smoothers.landmark_factors import (
    body_point_factor_2d,
    body_point_factor_3d,
    cartesian_point_factor_3d,
)
from smoothers.planar_graph import (
    constant_velocity_error,
    constant_velocity_factor,
    predict_constant_velocity,
)


def _pose3(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, gtsam.Pose3]:
    rotation = so3_exp(rng.normal(size=3))
    translation = rng.normal(size=3) * 5.0
    return rotation, translation, gtsam.Pose3(gtsam.Rot3(rotation), translation)


def _values(pose_key, pose, landmark_key, landmark) -> gtsam.Values:
    values = gtsam.Values()
    values.insert(pose_key, pose)
    values.insert(landmark_key, landmark)
    return values


def test_3d_factors_measure_the_point_in_the_body_frame_and_agree_with_the_cartesian_mahalanobis():
    rng = np.random.default_rng(3)
    for _ in range(20):
        rotation, translation, pose = _pose3(rng)
        rho = translation + rng.normal(size=3) * 8.0
        point = rotation.T @ (rho - translation)  # p = R^T (rho - r)
        a = rng.normal(size=(3, 3))
        covariance = a @ a.T * 0.01 + np.eye(3) * 0.01
        native = body_point_factor_3d(X(0), L(0), point, covariance)
        exact = cartesian_point_factor_3d(X(0), L(0), point, covariance)
        # Zero error at the true configuration: the convention is p = R^T (rho - r).
        assert native.error(_values(X(0), pose, L(0), rho)) < 1e-18
        assert exact.error(_values(X(0), pose, L(0), rho)) < 1e-18
        # A small landmark displacement: both whitened errors equal the Cartesian
        # Mahalanobis distance of the body-frame residual to first order.
        shift = rng.normal(size=3) * 1e-3
        moved = _values(X(0), pose, L(0), rho + shift)
        residual = rotation.T @ shift
        mahalanobis = residual @ np.linalg.solve(covariance, residual)
        assert np.isclose(2.0 * exact.error(moved), mahalanobis, rtol=1e-9)
        assert np.isclose(2.0 * native.error(moved), mahalanobis, rtol=2e-2)


def test_cartesian_custom_factor_jacobians_match_finite_differences():
    rng = np.random.default_rng(5)
    _, _, pose = _pose3(rng)
    rho = pose.translation() + np.array([4.0, -2.0, 1.0])
    factor = cartesian_point_factor_3d(X(0), L(0), np.array([1.0, 2.0, 3.0]), np.eye(3))
    values = _values(X(0), pose, L(0), rho)
    jacobian = factor.linearize(values).jacobian()[0]
    numeric = np.zeros((3, 9))
    step = 1e-6
    for i in range(9):
        delta = gtsam.VectorValues()
        dx = np.zeros(9)
        dx[i] = step
        delta.insert(X(0), dx[:6])
        delta.insert(L(0), dx[6:])
        plus = factor.unwhitenedError(values.retract(delta))
        delta_minus = gtsam.VectorValues()
        delta_minus.insert(X(0), -dx[:6])
        delta_minus.insert(L(0), -dx[6:])
        minus = factor.unwhitenedError(values.retract(delta_minus))
        numeric[:, i] = (plus - minus) / (2 * step)
    assert np.allclose(jacobian, numeric, atol=1e-6)


def test_2d_delta_factor_measures_the_point_in_the_body_frame():
    pose = gtsam.Pose2(1.0, 2.0, 0.7)
    rho = np.array([4.0, -1.0])
    rotation = pose.rotation().matrix()
    point = rotation.T @ (rho - pose.translation())
    factor = body_point_factor_2d(X(0), L(0), point + np.array([0.1, 0.0]), np.eye(2))
    assert isinstance(factor, gtsam_unstable.DeltaFactor)
    assert np.allclose(
        factor.unwhitenedError(_values(X(0), pose, L(0), rho)), [-0.1, 0.0], atol=1e-12
    )


def test_gyro_only_motion_factor_jacobians_match_finite_differences():
    pose_k = gtsam.Pose2(0.3, -1.0, 0.4)
    pose_next = gtsam.Pose2(0.8, -0.7, 0.55)
    state = np.array([0.5, 0.05, 0.01])
    state_next = np.array([0.47, 0.06, 0.012])
    dtheta, dt = 0.12, 0.1
    args = [pose_k, pose_next, state, state_next]
    _, blocks = constant_velocity_error(*args, dtheta, dt)
    step = 1e-6
    for which in range(4):
        numeric = np.zeros((3, 3))
        for i in range(3):
            delta = np.zeros(3)
            delta[i] = step
            plus, minus = list(args), list(args)
            if which < 2:
                plus[which] = args[which].retract(delta)
                minus[which] = args[which].retract(-delta)
            else:
                plus[which] = args[which] + delta
                minus[which] = args[which] - delta
            e_plus, _ = constant_velocity_error(*plus, dtheta, dt)
            e_minus, _ = constant_velocity_error(*minus, dtheta, dt)
            numeric[:, i] = (e_plus - e_minus) / (2 * step)
        assert np.allclose(blocks[which], numeric, atol=1e-6), which
    # The factor wires the same error: zero at the model's own prediction.
    factor = constant_velocity_factor(
        X(0), X(1), V(0), V(1), dtheta, dt, np.array([0.1, 0.1]), 0.01
    )
    values = gtsam.Values()
    values.insert(X(0), pose_k)
    values.insert(X(1), predict_constant_velocity(pose_k, state, dtheta, dt))
    values.insert(V(0), state)
    values.insert(V(1), state)
    assert factor.error(values) < 1e-20


def test_trapezoid_displacement_error_is_independent_of_the_velocity_change():
    """Van Loan's discretisation of a velocity random walk (one axis, density q): the
    displacement measured against the mean velocity has variance q^2 dt^3 / 12 and no
    correlation with the velocity change, which is why the planar smoother's two factors
    are exact; measured against the first velocity (the old form) the correlation is 0.87."""
    from scipy.linalg import expm

    q, dt = 0.3, 0.7
    a = np.array([[0.0, 1.0], [0.0, 0.0]])  # d(p, v)/dt = (v, w)
    g = np.array([[0.0], [1.0]])
    van_loan = np.zeros((4, 4))
    van_loan[:2, :2] = -a
    van_loan[:2, 2:] = q**2 * g @ g.T
    van_loan[2:, 2:] = a.T
    block = expm(van_loan * dt)
    transition = block[2:, 2:].T
    process = transition @ block[:2, 2:]  # Cov(w_p, w_v) of one step
    trapezoid = np.array([[1.0, -dt / 2], [0.0, 1.0]])  # (w_p - w_v dt / 2, w_v)
    errors = trapezoid @ process @ trapezoid.T
    np.testing.assert_allclose(errors, np.diag([q**2 * dt**3 / 12, q**2 * dt]), atol=1e-12)
    correlation = process[0, 1] / np.sqrt(process[0, 0] * process[1, 1])
    assert correlation == pytest.approx(np.sqrt(3) / 2)
