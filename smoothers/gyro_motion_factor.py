"""The gyro-only planar motion model (``GyroSample``, e.g. ``sim:guerreiro-loop``): its
residual, Jacobians, covariance, ``CustomFactor`` and mean prediction, used by
``smoothers.planar_graph.PlanarMotion``.

Each keyframe k has a pose ``X_k`` and a 3-vector ``V_k = [v_x, v_y, b_omega]``: the
body-frame velocity [m/s] and the rate-gyro bias [rad/s] (measured = true + bias, as in the
sensor-based paper's state). Between keyframes, over ``dt`` with the measured rotation
increment ``dtheta_m = sum(omega_m dt_i)`` (``smoothers.gyro_integration``):

    e_trans = R_k^T (t_{k+1} - t_k) - Rot(phi) (v_k + v_{k+1}) dt / 2,  phi = (dtheta_m - b_k dt) / 2
                                      (body velocity a random walk, trapezoid, midpoint heading)
    e_rot   = wrap(theta_{k+1} - theta_k - (dtheta_m - b_k dt))    (rotation from the gyro)

with covariance ``diag(q_x^2 dt^3 / 12, q_y^2 dt^3 / 12, 0) + sigma_g^2 dt u u^T``,
``u = [-S Rot(phi) v dt / 2; -1]`` (``S`` the planar skew matrix), and a
``BetweenFactorVector`` ``V_{k+1} - V_k ~ N(0, diag(q_x^2 dt, q_y^2 dt, q_b^2 dt))``
(``q`` the velocity random-walk density per body axis, ``sigma_g`` the gyro's white
noise). Why the trapezoid: for a velocity random walk the displacement over ``dt`` and
the velocity change are correlated (``q^2 [[dt^3/3, dt^2/2], [dt^2/2, dt]]``, correlation
0.87); measured against the mean of the two velocities the displacement error is
*uncorrelated* with the velocity change and has variance ``q^2 dt^3 / 12``
(``tests/test_smoother_factors.py`` checks both against Van Loan's ``expm``), so two
independent factors are exact. The earlier form (``v_k`` alone, ``dt^3 / 3``, the
correlation ignored) made the smoothers' velocity conservative: NEES 0.64 per dof on the
calibration loop where the filters read 0.94-0.98.
The gyro's white noise ``n`` (variance ``sigma_g^2 dt`` over the interval) enters both
rows: ``e_rot`` as ``-n`` and ``e_trans`` through the midpoint heading as
``-S Rot(phi) v dt n / 2``, hence the rank-one term, fully correlated between the two
(``u`` is evaluated at the velocity and bias estimate of ``V_k`` when the factor is made).
The midpoint heading is bias-corrected like ``e_rot``. Both were missing before
(``Rot(dtheta_m / 2)`` and a diagonal covariance): on the 100 s model-matched loop, whose
lateral walk (0.0025 m/s/sqrt(s)) gives a lateral sigma of 2.3e-5 m per 0.1 s keyframe,
the uncorrected 5 mrad/s bias moved the midpoint by 2.5e-5 m, about one sigma, always
the same way, and the smoothers' NIS read 1.016 per dof against ekf-slam's 0.999 on the
same runs.
No native GTSAM factor has this form, so it is a ``CustomFactor`` with analytic
Jacobians (tested against finite differences); gyro-only scenarios are small, and
``benchmarks/bench_smoother.py`` reports its cost.
"""

from __future__ import annotations

import gtsam
import numpy as np

from datasets.rotations import PLANAR_GENERATOR, rot2, wrap_angle


def constant_velocity_error(
    pose_k: gtsam.Pose2,
    pose_next: gtsam.Pose2,
    state_k: np.ndarray,
    state_next: np.ndarray,
    dtheta_m: float,
    dt: float,
) -> tuple[np.ndarray, list[np.ndarray]]:
    """Residual (3,) of the gyro-only motion model and its Jacobians (3x3 each, with respect
    to ``X_k``, ``X_{k+1}``, ``V_k``, ``V_{k+1}``).

    See the module docstring; pose Jacobians are with respect to GTSAM's Pose2 tangent (right
    perturbation, [x, y, theta]), ``V = [v_x, v_y, b_omega]``.
    """
    rotation_k = pose_k.rotation().matrix()
    delta_world = pose_next.translation() - pose_k.translation()
    delta_body = rotation_k.T @ delta_world
    bias = float(state_k[2])
    midpoint = rot2(midpoint_angle(dtheta_m, bias, dt))
    velocity = 0.5 * (state_k[:2] + state_next[:2])
    error = np.empty(3)
    error[:2] = delta_body - midpoint @ velocity * dt
    error[2] = float(wrap_angle(pose_next.theta() - pose_k.theta() - (dtheta_m - bias * dt)))
    d_pose_k = np.zeros((3, 3))
    d_pose_k[:2, :2] = -np.eye(2)
    d_pose_k[:2, 2] = -PLANAR_GENERATOR @ delta_body
    d_pose_k[2, 2] = -1.0
    d_pose_next = np.zeros((3, 3))
    d_pose_next[:2, :2] = rotation_k.T @ pose_next.rotation().matrix()
    d_pose_next[2, 2] = 1.0
    d_state_k = np.zeros((3, 3))
    d_state_k[:2, :2] = -0.5 * midpoint * dt
    d_state_k[:2, 2] = 0.5 * dt**2 * PLANAR_GENERATOR @ midpoint @ velocity
    d_state_k[2, 2] = dt
    d_state_next = np.zeros((3, 3))
    d_state_next[:2, :2] = -0.5 * midpoint * dt
    return error, [d_pose_k, d_pose_next, d_state_k, d_state_next]


def midpoint_angle(dtheta_m: float, bias: float, dt: float) -> float:
    """Heading of the interval's midpoint relative to ``X_k`` [rad]: half the bias-corrected
    measured rotation."""
    return 0.5 * (dtheta_m - bias * dt)


def motion_factor_covariance(
    dtheta_m: float,
    dt: float,
    velocity_walk: np.ndarray,
    gyro_density: float,
    state_estimate: np.ndarray,
) -> np.ndarray:
    """Covariance (3, 3) of the gyro-only motion residual [e_x, e_y, e_theta] (module
    docstring): the velocity walk's ``q^2 dt^3 / 12`` per body axis plus the gyro noise
    ``sigma_g^2 dt u u^T`` with ``u = [-S Rot(phi) v dt / 2; -1]`` at ``state_estimate``
    ``[v_x, v_y, b]``; plus 1e-12 on the diagonal (a zero density would make the factor a
    constraint)."""
    state_estimate = np.asarray(state_estimate, dtype=float)
    phi = midpoint_angle(dtheta_m, float(state_estimate[2]), dt)
    u = np.append(-0.5 * dt * PLANAR_GENERATOR @ rot2(phi) @ state_estimate[:2], -1.0)
    covariance = gyro_density**2 * dt * np.outer(u, u)
    covariance[:2, :2] += np.diag(
        np.broadcast_to(np.asarray(velocity_walk, float), (2,)) ** 2 * dt**3 / 12.0
    )
    return covariance + 1e-12 * np.eye(3)


def constant_velocity_factor(
    pose_key: int,
    next_pose_key: int,
    state_key: int,
    next_state_key: int,
    dtheta_m: float,
    dt: float,
    velocity_walk: np.ndarray,
    gyro_density: float,
    state_estimate: np.ndarray,
) -> gtsam.CustomFactor:
    """The gyro-only motion factor between ``X_k``, ``X_{k+1}``, ``V_k`` and ``V_{k+1}``
    (module docstring); ``velocity_walk`` (2,) per body axis [forward, lateral] (variances
    floored at 1e-12: a zero density would make the factor a constraint);
    ``state_estimate`` (3,) the current ``V_k`` estimate, for the gyro noise's share of the
    displacement (``motion_factor_covariance``)."""
    noise = gtsam.noiseModel.Gaussian.Covariance(
        motion_factor_covariance(dtheta_m, dt, velocity_walk, gyro_density, state_estimate)
    )

    def error(
        factor: gtsam.CustomFactor, values: gtsam.Values, jacobians: list | None
    ) -> np.ndarray:
        keys = factor.keys()
        residual, blocks = constant_velocity_error(
            values.atPose2(keys[0]),
            values.atPose2(keys[1]),
            values.atVector(keys[2]),
            values.atVector(keys[3]),
            dtheta_m,
            dt,
        )
        if jacobians is not None:
            for index, block in enumerate(blocks):
                jacobians[index] = block
        return residual

    return gtsam.CustomFactor(noise, [pose_key, next_pose_key, state_key, next_state_key], error)


def predict_constant_velocity(
    pose_k: gtsam.Pose2, state_k: np.ndarray, dtheta_m: float, dt: float
) -> gtsam.Pose2:
    """The motion model's mean: the pose at ``k+1`` from ``X_k``, ``V_k`` and the gyro."""
    midpoint = rot2(midpoint_angle(dtheta_m, float(state_k[2]), dt))
    translation = pose_k.translation() + pose_k.rotation().matrix() @ midpoint @ state_k[:2] * dt
    return gtsam.Pose2(
        translation[0], translation[1], pose_k.theta() + dtheta_m - float(state_k[2]) * dt
    )
