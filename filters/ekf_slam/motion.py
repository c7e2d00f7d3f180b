"""Vehicle motion models of the world-centric EKF-SLAM: mean propagation, error-state
transition ``F`` and process noise ``Q`` on the vehicle block (layout: ``layout.VehicleLayout``).

Three models:

- ``predict_odometry_3d``: a spatial relative pose (lidar odometry), the 3-D analogue below.
- ``predict_odometry_2d``: a planar relative pose ``u = (dx, dy, dtheta)`` in the previous
  body frame (odometry increments, or ``(v dt, 0, omega dt)`` from velocity odometry):
  ``p' = p + R(theta) u_xy``, ``theta' = theta + u_theta`` (the standard EKF-SLAM
  prediction, Bailey et al. 2006 section II).
- ``predict_gyro_cv``: gyro-driven constant velocity (2-D and 3-D): ``R' = R Exp((w_m - b) dt)``,
  world velocity ``v' = M v`` with ``M = R' R^T`` (the world velocity turns
  with the body, i.e. the body-frame velocity is constant: the same motion assumption as
  the sensor-based filter) or ``M = I`` (``rotate_velocity=False``: plain world-frame
  constant velocity), ``p' = p + (v + v') dt / 2`` (second order on an arc), plus white
  acceleration noise (random-walk velocity) and a random-walk gyro bias (measured = true
  + bias). The caller passes the rate over the interval (e.g. the mean of its two samples).

Error conventions: position and velocity errors are world-frame additive; the 2-D heading
error is additive; the 3-D rotation error is world-frame (left): ``R_true = Exp(dphi) R``.
Every Jacobian is checked against finite differences in ``tests/test_ekf_slam.py``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from datasets.rotations import PLANAR_GENERATOR, rot2, skew, so3_exp, wrap_angle
from filters.ekf_slam.layout import VehicleLayout


@dataclass(frozen=True)
class VehicleMean:
    """Vehicle mean.

    Attributes:
        position: world position [m], (d,).
        rotation: 2-D heading [rad] as a float; 3-D body-to-world matrix (3, 3).
        velocity: world velocity [m/s], (d,), or None.
        gyro_bias: gyro bias [rad/s], (1,) or (3,), or None.
    """

    position: np.ndarray
    rotation: float | np.ndarray
    velocity: np.ndarray | None = None
    gyro_bias: np.ndarray | None = None

    def rotation_matrix(self) -> np.ndarray:
        """Body-to-world rotation (d, d)."""
        return (
            rot2(float(self.rotation)) if np.ndim(self.rotation) == 0 else np.asarray(self.rotation)
        )


def predict_odometry_2d(
    mean: VehicleMean, layout: VehicleLayout, increment: np.ndarray, increment_cov: np.ndarray
) -> tuple[VehicleMean, np.ndarray, np.ndarray]:
    """Compose the planar increment ``u`` (3,) with covariance (3, 3).

    Returns:
        (new mean, F (n_v, n_v), Q (n_v, n_v)).
    """
    heading = float(mean.rotation)
    rotation = rot2(heading)
    u_xy, u_theta = np.asarray(increment[:2], float), float(increment[2])
    transition = np.eye(layout.size)
    transition[layout.position, layout.rotation] = (PLANAR_GENERATOR @ rotation @ u_xy)[:, None]
    input_jacobian = np.zeros((layout.size, 3))
    input_jacobian[layout.position, 0:2] = rotation
    input_jacobian[layout.rotation, 2] = 1.0
    process = input_jacobian @ np.asarray(increment_cov, float) @ input_jacobian.T
    new = VehicleMean(
        mean.position + rotation @ u_xy,
        float(wrap_angle(heading + u_theta)),
        mean.velocity,
        mean.gyro_bias,
    )
    return new, transition, process


def compose_planar(
    first: np.ndarray, first_cov: np.ndarray, second: np.ndarray, second_cov: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The planar increment ``u = a (+) b`` of two consecutive increments (3,) with independent
    covariances (3, 3): ``u_xy = a_xy + R(a_theta) b_xy``, ``u_theta = a_theta + b_theta``
    (the heading is not wrapped), ``Sigma_u = J_a Sigma_a J_a^T + J_b Sigma_b J_b^T`` with
    ``J_a = [[I, J R(a_theta) b_xy], [0, 1]]`` and ``J_b = diag(R(a_theta), 1)`` (the
    compounding of Smith, Self and Cheeseman 1990). ``predict_odometry_2d`` with ``u`` gives
    the mean and covariance of the two predictions in turn."""
    first, second = np.asarray(first, float), np.asarray(second, float)
    rotation = rot2(float(first[2]))
    turned = rotation @ second[:2]
    first_jacobian = np.eye(3)
    first_jacobian[0:2, 2] = PLANAR_GENERATOR @ turned
    second_jacobian = np.eye(3)
    second_jacobian[0:2, 0:2] = rotation
    composed = np.array([first[0] + turned[0], first[1] + turned[1], first[2] + second[2]])
    covariance = (
        first_jacobian @ np.asarray(first_cov, float) @ first_jacobian.T
        + second_jacobian @ np.asarray(second_cov, float) @ second_jacobian.T
    )
    return composed, covariance


def predict_odometry_3d(
    mean: VehicleMean, layout: VehicleLayout, increment: np.ndarray, increment_cov: np.ndarray
) -> tuple[VehicleMean, np.ndarray, np.ndarray]:
    """Compose the spatial increment ``u = (w, t)`` (6,) (rotation vector, translation in the
    previous body frame; lidar odometry) with covariance (6, 6) in [rotation (right
    perturbation of the increment), translation] order: ``p' = p + R t``, ``R' = R Exp(w)``.

    With the filter's world-frame (left) rotation error ``R_true = Exp(dphi) R``:
    ``dp' = dp - [R t]x dphi + R dt_u`` and ``dphi' = dphi + R' dw_u``.

    Returns:
        (new mean, F (n_v, n_v), Q (n_v, n_v)).
    """
    rotation = np.asarray(mean.rotation, float)
    rotation_vector = np.asarray(increment[:3], float)
    translation = np.asarray(increment[3:], float)
    new_rotation = rotation @ so3_exp(rotation_vector)
    world_step = rotation @ translation
    transition = np.eye(layout.size)
    transition[layout.position, layout.rotation] = -skew(world_step)
    input_jacobian = np.zeros((layout.size, 6))
    input_jacobian[layout.rotation, 0:3] = new_rotation
    input_jacobian[layout.position, 3:6] = rotation
    process = input_jacobian @ np.asarray(increment_cov, float) @ input_jacobian.T
    new = VehicleMean(mean.position + world_step, new_rotation, mean.velocity, mean.gyro_bias)
    return new, transition, process


@dataclass(frozen=True)
class GyroNoise:
    """Continuous-time densities of the gyro-driven model.

    Attributes:
        gyro_density: gyro white noise [rad/s/sqrt(Hz)].
        bias_walk: gyro bias random walk [rad/s^2/sqrt(Hz)].
        velocity_walk: body-velocity random walk [m/s/sqrt(s)], a white acceleration
            driving the velocity: one value for every axis, or one per body axis (forward,
            lateral(, vertical)).
    """

    gyro_density: float
    bias_walk: float
    velocity_walk: float | np.ndarray


def predict_gyro_cv(
    mean: VehicleMean,
    layout: VehicleLayout,
    rate: np.ndarray,
    dt: float,
    noise: GyroNoise,
    rotate_velocity: bool = True,
) -> tuple[VehicleMean, np.ndarray, np.ndarray]:
    """Gyro-driven constant-velocity prediction over ``dt`` [s] with measured rate (1,)/(3,).

    Returns:
        (new mean, F (n_v, n_v), Q (n_v, n_v)).
    """
    d = layout.dimension
    rate = np.asarray(rate, float).ravel()
    bias = mean.gyro_bias if mean.gyro_bias is not None else np.zeros(layout.rotation_size)
    corrected = rate - bias
    velocity = mean.velocity if mean.velocity is not None else np.zeros(d)
    transition = np.eye(layout.size)
    # rate_jacobian: d x' / d (measured rate); the bias and gyro noise enter with its negative.
    rate_jacobian = np.zeros((layout.size, layout.rotation_size))
    if d == 2:
        increment = rot2(float(corrected[0]) * dt)
        turn = increment if rotate_velocity else np.eye(2)
        new_velocity = turn @ velocity
        rate_jacobian[layout.rotation, 0] = dt
        if rotate_velocity and layout.velocity is not None:
            rate_jacobian[layout.velocity, 0] = dt * PLANAR_GENERATOR @ new_velocity
        new_rotation: float | np.ndarray = float(
            wrap_angle(float(mean.rotation) + corrected[0] * dt)
        )
    else:
        rotation = np.asarray(mean.rotation)
        delta = so3_exp(corrected * dt)
        new_matrix = rotation @ delta
        turn = new_matrix @ rotation.T if rotate_velocity else np.eye(3)
        new_velocity = turn @ velocity
        # left world-frame rotation error: dphi' = dphi - R' dt (db + n_g) (first order in dt)
        rate_jacobian[layout.rotation, :] = new_matrix * dt
        if layout.velocity is not None and rotate_velocity:
            transition[layout.velocity, layout.rotation] = -skew(new_velocity) + turn @ skew(
                velocity
            )
            rate_jacobian[layout.velocity, :] = -new_matrix @ skew(rotation.T @ velocity) * dt
        new_rotation = new_matrix
    if layout.velocity is not None:
        transition[layout.velocity, layout.velocity] = turn
        # p' = p + (v + v') dt / 2: the position inherits half of every velocity sensitivity
        transition[layout.position, layout.velocity] = 0.5 * dt * (np.eye(d) + turn)
        transition[layout.position, layout.rotation] = (
            0.5 * dt * transition[layout.velocity, layout.rotation]
        )
        rate_jacobian[layout.position, :] = 0.5 * dt * rate_jacobian[layout.velocity, :]
    if layout.gyro_bias is not None:
        transition[:, layout.gyro_bias] += -rate_jacobian
    process = (
        rate_jacobian @ rate_jacobian.T * (noise.gyro_density**2 / max(dt, 1e-12))
        if dt > 0
        else np.zeros_like(transition)
    )
    if layout.velocity is not None and dt > 0:
        # white acceleration along the body axes (a ground vehicle accelerates along its
        # heading far more than across it), expressed in the world frame at the new attitude
        body = np.broadcast_to(np.asarray(noise.velocity_walk, dtype=float) ** 2, (d,))
        axes = rot2(float(new_rotation)) if d == 2 else np.asarray(new_rotation)
        q = (axes * body) @ axes.T
        process[layout.position, layout.position] += q * dt**3 / 3.0
        process[layout.position, layout.velocity] += q * dt**2 / 2.0
        process[layout.velocity, layout.position] += q * dt**2 / 2.0
        process[layout.velocity, layout.velocity] += q * dt
    if layout.gyro_bias is not None:
        process[layout.gyro_bias, layout.gyro_bias] += (
            np.eye(layout.rotation_size) * noise.bias_walk**2 * dt
        )
    new = VehicleMean(
        position=mean.position + 0.5 * (velocity + new_velocity) * dt,
        rotation=new_rotation,
        velocity=new_velocity if mean.velocity is not None else None,
        gyro_bias=None if mean.gyro_bias is None else mean.gyro_bias.copy(),
    )
    return new, transition, 0.5 * (process + process.T)
