"""Landmark and motion factors of the smoother: error conventions and Jacobians, checked
numerically against ``p = R^T (rho - r)`` and finite differences."""

from __future__ import annotations

import gtsam
import gtsam_unstable
import numpy as np
import pytest
from gtsam.symbol_shorthand import L, V, X

from datasets.measurements import GyroSample
from datasets.rotations import so3_exp
from smoothers import imu_graph
from smoothers.gyro_integration import GyroAccumulator
from smoothers.gyro_motion_factor import (
    constant_velocity_error,
    constant_velocity_factor,
    motion_factor_covariance,
    predict_constant_velocity,
)
from smoothers.imu_graph import ImuNoise, KeyframeImuIntegrator, combined_params
from smoothers.landmark_factors import (
    body_point_factor_2d,
    body_point_factor_3d,
    cartesian_point_factor_3d,
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
        X(0), X(1), V(0), V(1), dtheta, dt, np.array([0.1, 0.1]), 0.01, state
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


def test_gyro_only_motion_residual_covariance_matches_monte_carlo_with_gyro_noise_and_bias():
    """The motion residual at the true states has zero mean and the factor's covariance,
    over draws of a body-velocity random walk and of the gyro's white noise (200 sub-steps
    per 0.1 s keyframe; a vehicle at 1.2 m/s turning at 0.3 rad/s, a 10 mrad/s gyro bias):
    the gyro noise reaches the displacement through the midpoint heading, fully correlated
    with the rotation row. The earlier diagonal covariance reads a NEES of several per dof,
    and the earlier uncorrected midpoint heading shifts the lateral mean."""
    rng = np.random.default_rng(7)
    dt, substeps, rate, bias, density = 0.1, 200, 0.3, 0.01, 0.003
    walk = np.array([0.01, 0.005])
    step = dt / substeps
    start_velocity = np.array([1.2, 0.05])
    state = np.array([*start_velocity, bias])
    pose_k = gtsam.Pose2(2.0, -1.0, 0.7)
    heading = rate * step * (np.arange(substeps) + 0.5)  # relative heading mid sub-step
    cosine, sine = np.cos(heading), np.sin(heading)
    residuals, uncorrected = [], []
    for _ in range(4000):
        velocity = start_velocity + np.cumsum(
            walk * np.sqrt(step) * rng.standard_normal((substeps, 2)), axis=0
        )
        middle = np.vstack([start_velocity, velocity[:-1]]) + 0.5 * np.diff(
            np.vstack([start_velocity, velocity]), axis=0
        )
        displacement = step * np.array(
            [
                np.sum(cosine * middle[:, 0] - sine * middle[:, 1]),
                np.sum(sine * middle[:, 0] + cosine * middle[:, 1]),
            ]
        )
        pose_next = pose_k.compose(gtsam.Pose2(*displacement, rate * dt))
        next_state = np.array([*velocity[-1], bias])
        noise = density / np.sqrt(step) * rng.standard_normal(substeps)
        dtheta_m = float(np.sum(rate + bias + noise) * step)
        error, _ = constant_velocity_error(pose_k, pose_next, state, next_state, dtheta_m, dt)
        residuals.append(error)
        unbiased, _ = constant_velocity_error(
            pose_k, pose_next, np.array([*start_velocity, 0.0]), next_state, dtheta_m, dt
        )
        uncorrected.append(unbiased)
    residuals, uncorrected = np.array(residuals), np.array(uncorrected)
    covariance = motion_factor_covariance((rate + bias) * dt, dt, walk, density, state)
    sigma = np.sqrt(np.diag(covariance))
    standard_error = sigma / np.sqrt(len(residuals))
    assert np.all(np.abs(residuals.mean(axis=0)) < 4 * standard_error)
    nees = np.einsum("ni,ij,nj->n", residuals, np.linalg.inv(covariance), residuals) / 3
    assert nees.mean() == pytest.approx(1.0, abs=0.06)
    diagonal = np.diag(np.append(walk**2 * dt**3 / 12, density**2 * dt))
    old = np.einsum("ni,ij,nj->n", residuals, np.linalg.inv(diagonal), residuals) / 3
    assert old.mean() > 1.4  # 1.53 on this draw
    # The bias left out of the midpoint heading moves the lateral residual by about
    # bias * dt / 2 * v_x * dt (6e-5 m, 1.1 of its walk sigma), not the rotation row.
    shift = uncorrected[:, 1].mean() - residuals[:, 1].mean()
    assert abs(shift) > 20 * standard_error[1]


def test_gyro_accumulator_integrates_instantaneous_samples_exactly_for_a_linear_rate():
    """A rate ramp sampled at 10 Hz (the loop's gyro): the line between samples integrates
    it exactly, also for a keyframe between two samples (with the next one looked ahead);
    the zero-order hold is off by half the ramp times dt^2 per interval, the later sample by
    as much the other way."""

    def rate(t):
        return 0.2 + 0.5 * t

    def exact(a, b):
        return 0.2 * (b - a) + 0.25 * (b * b - a * a)

    for interval_rate, expected_error in (
        ("average", 0.0),
        ("hold", -0.5 * 0.5 * 0.1**2 * 3),
        ("latest", 0.5 * 0.5 * 0.1**2 * 3),
    ):
        gyro = GyroAccumulator(max_gap_s=1.0, interval_rate=interval_rate)
        gyro.start(0.0)
        for t in (0.0, 0.1, 0.2, 0.3):
            gyro.add(GyroSample(t=t, rate=np.array([rate(t)])))
        dtheta, dt = gyro.close(0.3)
        assert dt == pytest.approx(0.3)
        assert dtheta - exact(0.0, 0.3) == pytest.approx(expected_error, abs=1e-12)
    gyro = GyroAccumulator(max_gap_s=1.0)
    gyro.start(0.0)
    for t in (0.0, 0.1):
        gyro.add(GyroSample(t=t, rate=np.array([rate(t)])))
    gyro.lookahead = (0.2, rate(0.2))
    dtheta, _ = gyro.close(0.15)
    assert dtheta == pytest.approx(exact(0.0, 0.15), abs=1e-12)


def _preintegrated_second(bias: gtsam.imuBias.ConstantBias, rate: np.ndarray, force: np.ndarray):
    """One second of constant body ``rate`` and specific ``force``, sampled at 20 Hz and
    biased by ``bias``, preintegrated from a keyframe at 0 s to one at 1 s."""
    params = combined_params(ImuNoise(1e-3, 1e-2, 1e-5, 1e-4), 9.81)
    integrator = KeyframeImuIntegrator(params, max_gap_s=1.0)
    integrator.start(0.0, bias)
    for t in np.arange(21) / 20.0:
        integrator.add(t, rate + bias.gyroscope(), force + bias.accelerometer())
    return integrator.close(1.0)


def test_imu_preintegration_applies_the_specific_force_at_the_mid_attitude(monkeypatch):
    """GTSAM rotates a step's specific force by the start attitude (first order); the
    integrator hands it a force pre-rotated by half the step's turn, so that 20 Hz samples
    reproduce the exact integral of a constant body rate and force (reference: 20 000
    trapezoid steps of the closed-form attitude Exp(omega t)), with a non-zero bias."""
    bias = gtsam.imuBias.ConstantBias(np.array([0.05, -0.03, 0.02]), np.array([2e-3, -1e-3, 3e-3]))
    rate = np.array([0.3, -0.2, 0.5])
    force = np.array([0.5, -0.2, 9.81])
    pim = _preintegrated_second(bias, rate, force)
    times = np.linspace(0.0, 1.0, 20_001)
    accelerations = np.array([so3_exp(rate * t) @ force for t in times])
    velocity = np.concatenate(
        [np.zeros((1, 3)), np.cumsum(0.5 * (accelerations[1:] + accelerations[:-1]), 0) / 20_000]
    )
    position = np.sum(0.5 * (velocity[1:] + velocity[:-1]), axis=0) / 20_000
    velocity_error = np.linalg.norm(pim.deltaVij() - velocity[-1])
    position_error = np.linalg.norm(pim.deltaPij() - position)
    # measured: 2.1e-4 m/s and 6.7e-4 m (start-attitude rule: 0.081 m/s and 0.040 m)
    assert velocity_error < 5e-4 and position_error < 1.5e-3
    monkeypatch.setattr(imu_graph, "specific_force_at_step_start", lambda accel, *_: accel)
    held_pim = _preintegrated_second(bias, rate, force)
    # GTSAM's own start-attitude rule misses by a first-order term, ~|a| |omega| dt / 2.
    assert np.linalg.norm(held_pim.deltaVij() - velocity[-1]) > 100 * velocity_error
    assert np.linalg.norm(held_pim.deltaPij() - position) > 20 * position_error
    assert np.allclose(pim.deltaRij().matrix(), so3_exp(rate), atol=1e-9)
