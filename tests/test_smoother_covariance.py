"""GTSAM marginals -> interface covariance convention, checked by Monte Carlo with our own
rotation code (no GTSAM in the reference errors)."""

from __future__ import annotations

import gtsam
import numpy as np
from gtsam.symbol_shorthand import B, L, X

from datasets.rotations import so3_exp, so3_log
from smoothers.covariances import bias_covariances, pose_covariance
from smoothers.imu_graph import bias_prior_sigmas
from smoothers.landmark_factors import (
    body_point_factor_2d,
    cartesian_point_factor_3d,
    landmark_prior,
)


def _interface_errors_3d(true_rotation, true_translation, pose: gtsam.Pose3) -> np.ndarray:
    """[Log(R_est^T R_true), R_est^T (p_true - p_est)]: body-frame right perturbation."""
    rotation = pose.rotation().matrix()
    return np.r_[
        so3_log(rotation.T @ true_rotation), rotation.T @ (true_translation - pose.translation())
    ]


def test_pose3_marginal_is_the_interface_rotation_translation_body_covariance():
    rng = np.random.default_rng(11)
    true_rotation = so3_exp(np.array([0.2, -0.4, 1.0]))
    true_translation = np.array([2.0, -1.0, 0.5])
    truth = gtsam.Pose3(gtsam.Rot3(true_rotation), true_translation)
    landmarks = np.array([[8.0, 0.0, 0.0], [0.0, 6.0, 1.0], [-3.0, -4.0, 2.0], [4.0, 4.0, -1.0]])
    # Anisotropic noise so that a wrong block order or frame would be visible.
    covariance = np.diag([0.04, 0.0025, 0.01])
    chol = np.linalg.cholesky(covariance)
    samples, marginal = [], None
    for _ in range(300):
        graph = gtsam.NonlinearFactorGraph()
        values = gtsam.Values()
        values.insert(X(0), truth)
        for j, rho in enumerate(landmarks):
            graph.add(landmark_prior(L(j), rho, 1e-6))
            values.insert(L(j), rho)
            measured = true_rotation.T @ (rho - true_translation) + chol @ rng.normal(size=3)
            graph.add(cartesian_point_factor_3d(X(0), L(j), measured, covariance))
        result = gtsam.LevenbergMarquardtOptimizer(graph, values).optimize()
        samples.append(_interface_errors_3d(true_rotation, true_translation, result.atPose3(X(0))))
        if marginal is None:
            marginal = pose_covariance(gtsam.Marginals(graph, result).marginalCovariance(X(0)))
    errors = np.array(samples)
    nees = np.einsum("ni,ni->n", errors, np.linalg.solve(marginal, errors.T).T)
    assert 5.3 < nees.mean() < 6.7  # 6 dof, 300 samples: +/- ~0.5 at 99 %
    swapped = np.roll(np.roll(marginal, 3, axis=0), 3, axis=1)  # [translation, rotation]: wrong
    nees_swapped = np.einsum("ni,ni->n", errors, np.linalg.solve(swapped, errors.T).T)
    assert not 5.3 < nees_swapped.mean() < 6.7
    empirical = np.cov(errors.T)
    assert np.allclose(np.diag(empirical), np.diag(marginal), rtol=0.3)


def test_pose2_marginal_is_the_interface_x_y_theta_covariance():
    rng = np.random.default_rng(12)
    truth = gtsam.Pose2(1.0, -2.0, 0.8)
    rotation = truth.rotation().matrix()
    landmarks = np.array([[6.0, 0.0], [0.0, 5.0], [-4.0, -3.0]])
    covariance = np.diag([0.09, 0.01])
    samples, marginal = [], None
    for _ in range(300):
        graph = gtsam.NonlinearFactorGraph()
        values = gtsam.Values()
        values.insert(X(0), truth)
        for j, rho in enumerate(landmarks):
            graph.add(landmark_prior(L(j), rho, 1e-6))
            values.insert(L(j), rho)
            measured = rotation.T @ (rho - truth.translation()) + np.sqrt(
                np.diag(covariance)
            ) * rng.normal(size=2)
            graph.add(body_point_factor_2d(X(0), L(j), measured, covariance))
        result = gtsam.LevenbergMarquardtOptimizer(graph, values).optimize()
        estimate = result.atPose2(X(0))
        r_est = estimate.rotation().matrix()
        heading = np.arctan2(
            np.sin(truth.theta() - estimate.theta()), np.cos(truth.theta() - estimate.theta())
        )
        samples.append(np.r_[r_est.T @ (truth.translation() - estimate.translation()), heading])
        if marginal is None:
            marginal = pose_covariance(gtsam.Marginals(graph, result).marginalCovariance(X(0)))
    errors = np.array(samples)
    nees = np.einsum("ni,ni->n", errors, np.linalg.solve(marginal, errors.T).T)
    assert 2.5 < nees.mean() < 3.5


def test_bias_marginal_splits_accelerometer_first():
    graph = gtsam.NonlinearFactorGraph()
    sigmas = bias_prior_sigmas(accel_sigma_m_s2=0.2, gyro_sigma_rad_s=0.003)
    graph.add(
        gtsam.PriorFactorConstantBias(
            B(0), gtsam.imuBias.ConstantBias(), gtsam.noiseModel.Diagonal.Sigmas(sigmas)
        )
    )
    values = gtsam.Values()
    values.insert(
        B(0), gtsam.imuBias.ConstantBias(np.array([0.1, 0.0, 0.0]), np.array([0.0, 0.002, 0.0]))
    )
    result = gtsam.LevenbergMarquardtOptimizer(graph, values).optimize()
    split = bias_covariances(gtsam.Marginals(graph, result).marginalCovariance(B(0)))
    assert np.allclose(split.accel, np.eye(3) * 0.04)
    assert np.allclose(split.gyro, np.eye(3) * 0.003**2)
    # Sign convention: GTSAM's bias is measured = true + bias (correct = measured - bias).
    bias = gtsam.imuBias.ConstantBias(np.array([0.1, 0.0, 0.0]), np.array([0.0, 0.002, 0.0]))
    assert np.allclose(bias.correctGyroscope(np.array([0.0, 0.005, 0.0])), [0.0, 0.003, 0.0])
    assert np.allclose(bias.correctAccelerometer(np.array([0.3, 0.0, 9.81])), [0.2, 0.0, 9.81])
