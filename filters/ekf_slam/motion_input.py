"""The EKF-SLAM's motion input: which input drives the prediction, and what one sample of it
becomes before ``motion`` predicts with it.

- the input chosen from the data (``config.use_odometry``; ``choose_input``): odometry, else
  the gyro or the IMU's gyro (the accelerometer is not used);
- odometry samples as increments with their covariance (``odometry_increment``,
  ``planar_odometry_step``): relative poses, or (v, omega) turned into
  ``(v dt, 0, omega dt)``;
- gyro rate samples checked (``gyro_rate``);
- motion gaps longer than ``max_gap_s``: raised (``gap_policy=raise``, ``motion_gap``) or
  bridged by widening the pose uncertainty (``widen_for_gap``);
- the first-estimates propagation Jacobian (``first_estimate_transition``).
"""

from __future__ import annotations

import numpy as np

from datasets.errors import InputError
from datasets.measurements import GyroSample, ImuSample, Measurement, Odometry, Sensor
from datasets.odometry_noise import OdometryNoiseModel
from datasets.rotations import PLANAR_GENERATOR, skew
from datasets.sequence import Sequence
from filters.ekf_slam.config import EkfSlamConfig
from filters.ekf_slam.layout import VehicleLayout


def choose_input(config: EkfSlamConfig, sequence: Sequence) -> Sensor:
    """The motion input: odometry if wanted (``use_odometry``) and given, else gyro, else IMU."""
    available = sequence.sensors
    wanted = [Sensor.GYRO, Sensor.IMU]
    if config.use_odometry:
        wanted.insert(0, Sensor.ODOMETRY)
    for sensor in wanted:
        if sensor not in available:
            continue
        return sensor
    raise InputError(
        f"{sequence.name}: ekf-slam with use_odometry={str(config.use_odometry).lower()} "
        f"needs one of {', '.join(s.value for s in wanted)} ({sequence.dimension}-D), the "
        f"dataset has {', '.join(sorted(s.value for s in available))}"
    )


def motion_gap(config: EkfSlamConfig, name: str, t: float, dt: float) -> None:
    """A motion-input gap of ``dt`` [s] longer than ``max_gap_s`` ending at ``t``:
    ``InputError`` with ``gap_policy=raise``; with ``inflate`` the caller logs and bridges it."""
    if config.gap_policy == "raise":
        raise InputError(
            f"{name}: motion-input gap of {dt:.3f} s before t={t:.6f} s exceeds "
            f"max_gap_s={config.max_gap_s} (gap_policy=raise)"
        )


def widen_for_gap(
    process: np.ndarray, layout: VehicleLayout, config: EkfSlamConfig, dt: float
) -> np.ndarray:
    """The process noise (n_v, n_v) of a prediction across a gap of ``dt`` [s] longer than
    ``max_gap_s``: the input says nothing reliable about an unobserved stretch, so the pose
    uncertainty is widened by ``(gap_speed_m_s dt)^2`` on each position axis and
    ``(gap_rate_rad_s dt)^2`` on each rotation axis (world frame)."""
    process = process.copy()
    process[layout.position, layout.position] += (
        np.eye(layout.dimension) * (config.gap_speed_m_s * dt) ** 2
    )
    process[layout.rotation, layout.rotation] += (
        np.eye(layout.rotation_size) * (config.gap_rate_rad_s * dt) ** 2
    )
    return process


def first_estimate_transition(
    layout: VehicleLayout, transition: np.ndarray, step: np.ndarray
) -> np.ndarray:
    """The odometry transition with its rotation column evaluated at the previous
    prediction ``p_{k|k-1}`` instead of the updated ``p_{k|k}`` (Huang et al. (2008), eq.
    (25)): ``step = p' - p_{k|k-1}`` gives ``J step`` in 2-D and ``-[p' - p_{k|k-1}]x`` (the
    world-frame rotation error's column) in 3-D."""
    transition = transition.copy()
    if layout.dimension == 2:
        transition[layout.position, layout.rotation] = (PLANAR_GENERATOR @ step)[:, None]
    else:
        transition[layout.position, layout.rotation] = -skew(step)
    return transition


def gyro_rate(measurement: Measurement, rotation_size: int) -> np.ndarray:
    """The measured angular rate (1,)/(3,) [rad/s] of a gyro or IMU sample (the IMU's
    accelerometer is not used), checked."""
    if isinstance(measurement, ImuSample):
        rate = np.asarray(measurement.gyro, float).ravel()  # the accelerometer is not used
    elif isinstance(measurement, GyroSample):
        rate = np.asarray(measurement.rate, float).ravel()
    else:
        raise InputError(
            f"ekf-slam cannot use a {type(measurement).__name__} as motion input (t={measurement.t:.6f} s)"
        )
    if rate.shape != (rotation_size,) or not np.all(np.isfinite(rate)):
        raise InputError(
            f"gyro rate at t={measurement.t:.6f} s must be {rotation_size} finite values, got {rate}"
        )
    return rate


def planar_odometry_step(
    config: EkfSlamConfig, model: OdometryNoiseModel | None, odometry: Odometry, dt: float
) -> tuple[np.ndarray, np.ndarray]:
    """One planar odometry sample over ``dt`` [s] since the previous motion input: the
    increment ``(dx, dy, dtheta)`` [m, m, rad] and its covariance (3, 3), the data's (or the
    noise model's) times ``odometry_noise_scale``, plus, after a gap longer than
    ``max_gap_s``, the gap's uncertainty: ``(gap_speed_m_s dt)^2`` on each position axis and
    ``(gap_rate_rad_s dt)^2`` on the heading. Isotropic in position, so added in the
    increment's frame it is the world-frame widening the other inputs get."""
    increment, covariance = odometry_increment(odometry, dt, 2, model)
    covariance = covariance * config.odometry_noise_scale
    if dt > config.max_gap_s:
        widening = [(config.gap_speed_m_s * dt) ** 2] * 2 + [(config.gap_rate_rad_s * dt) ** 2]
        covariance = covariance + np.diag(widening)
    return increment, covariance


def odometry_increment(
    odometry: Odometry, dt: float, dimension: int, model: OdometryNoiseModel | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The increment and its covariance from relative-pose or (v, omega) odometry: planar
    (dx, dy, dtheta), or spatial (rotation vector, translation) in 3-D. A planar velocity
    sample's (v, omega) covariance has no lateral axis: when the sequence states its
    odometry noise model, the increment's covariance is the model's (with the lateral
    term), else the sample's covariance mapped through ``dt``."""
    covariance = np.asarray(odometry.covariance, float)
    size = 3 if dimension == 2 else 6
    if odometry.relative_pose is not None:
        increment = np.asarray(odometry.relative_pose, float)
        if increment.shape != (size,) or covariance.shape != (size, size):
            raise InputError(
                f"odometry at t={odometry.t:.6f} s: {dimension}-D ekf-slam takes increments ({size},) with a ({size}, {size}) covariance, got {increment.shape} and {covariance.shape}"
            )
    elif dimension == 3:
        raise InputError(
            f"odometry at t={odometry.t:.6f} s is a velocity; 3-D ekf-slam composes relative poses"
        )
    elif odometry.velocity is not None:
        speed, rate = np.asarray(odometry.velocity, float)
        step = max(dt, 0.0)
        increment = np.array([speed * step, 0.0, rate * step])
        if model is not None and step > 0.0:
            covariance = model.increment_covariance(increment, step)
        else:
            jacobian = np.array([[step, 0.0], [0.0, 0.0], [0.0, step]])
            covariance = jacobian @ covariance @ jacobian.T
    else:
        raise InputError(f"odometry at t={odometry.t:.6f} s has neither relative_pose nor velocity")
    if not np.all(np.isfinite(increment)) or not np.all(np.isfinite(covariance)):
        raise InputError(f"non-finite odometry at t={odometry.t:.6f} s")
    return increment, covariance
