"""What the sensor-based filter starts from, built from its options and the dataset.

The process noise of eq. (10)'s model (``dynamics.ProcessNoise``: velocity walk, the paper's
gyro-bias walk sigma_br of section V unless told otherwise, landmark disturbance sigma_p,
direction walk, gyro noise density), the prior of the vehicle state ``[v, b]`` (the body
velocity is the dataset's initial velocity rotated into the body frame), and the Earth-frame
tracker's start pose with its covariance (``earth_frame``; the robocentric state itself has
no position or attitude).
"""

from __future__ import annotations

import numpy as np

from datasets.errors import InputError
from datasets.estimator_options import per_body_axis
from datasets.rotations import matrix_from_quat_wxyz, rot2
from datasets.sequence import Sequence
from filters.sensor_based.config import (
    PAPER_GYRO_BIAS_WALK_RAD_S_SQRT_S,
    SensorBasedConfig,
    landmark_disturbance,
)
from filters.sensor_based.dynamics import ProcessNoise, rate_dimension
from filters.sensor_based.earth_frame import EarthFrameTracker
from filters.sensor_based.earth_state import frame_from_pose
from filters.sensor_based.odometry import ODOMETRY_RATE_BIAS_SIGMA_RAD_S
from filters.sensor_based.state import FilterState


def _vector(values: list[float], size: int, name: str) -> np.ndarray:
    vector = np.asarray(values, dtype=float).ravel()
    if vector.size != size:
        raise InputError(f"config {name}: expected {size} values, got {vector.size}")
    return vector


def process_noise(config: SensorBasedConfig, sequence: Sequence) -> ProcessNoise:
    """The process noise: each option where given, else the dataset's stated value, else the
    paper's (the gyro-bias walk) or none (the gyro noise density)."""
    d = sequence.dimension
    density = config.gyro_noise_density_rad_s_sqrt_hz
    if density is None:
        density = sequence.noise.gyro_noise_density or 0.0
    velocity_walk = per_body_axis(config.velocity_walk_m_s_sqrt_s, d, "velocity_walk_m_s_sqrt_s")
    bias_walk = config.gyro_bias_walk_rad_s_sqrt_s
    if bias_walk is None:
        stated = sequence.noise.gyro_bias_walk
        bias_walk = PAPER_GYRO_BIAS_WALK_RAD_S_SQRT_S if stated is None else stated
    return ProcessNoise(
        velocity_m_s=velocity_walk,
        gyro_bias_rad_s=bias_walk,
        landmark_m=landmark_disturbance(config),
        direction=config.direction_walk_per_sqrt_s,
        gyro_noise_density=float(density),
    )


def vehicle_prior(
    config: SensorBasedConfig, sequence: Sequence, rate_from_odometry: bool
) -> FilterState:
    """The state with no landmarks yet: the vehicle ``[v, b]`` and its prior covariance
    (``rate_from_odometry``: the rate has no bias of its own, the bias prior is tight)."""
    d = sequence.dimension
    r = rate_dimension(d)
    start = sequence.initial_state
    velocity = np.zeros(d)
    velocity_sigma = config.initial_velocity_sigma_m_s or 2.0
    if start is not None and start.velocity is not None:
        rotation = rot2(float(start.rotation)) if d == 2 else matrix_from_quat_wxyz(start.rotation)
        velocity = rotation.T @ np.asarray(start.velocity, dtype=float)
        velocity_sigma = config.initial_velocity_sigma_m_s or start.velocity_sigma_m_s
    if config.initial_velocity_error_m_s is not None:
        velocity = velocity + _vector(
            config.initial_velocity_error_m_s, d, "initial_velocity_error_m_s"
        )
    bias = np.zeros(r)
    if config.initial_gyro_bias_rad_s is not None:
        bias = _vector(config.initial_gyro_bias_rad_s, r, "initial_gyro_bias_rad_s")
    bias_sigma = config.initial_gyro_bias_sigma_rad_s or (
        ODOMETRY_RATE_BIAS_SIGMA_RAD_S
        if rate_from_odometry
        else sequence.noise.gyro_bias_sigma_rad_s or 0.05
    )
    return FilterState(d, velocity, velocity_sigma**2 * np.eye(d), bias, bias_sigma**2 * np.eye(r))


def earth_tracker(config: SensorBasedConfig, sequence: Sequence) -> EarthFrameTracker | None:
    """The Earth-frame tracker at the dataset's initial pose (the identity without one) and
    its covariance; None with ``earth_frame=false`` or the frame in the filter's state."""
    if not config.earth_frame or config.earth_frame_source != "map_alignment":
        return None
    start_rotation, start_position, start_covariance = start_pose(config, sequence)
    return EarthFrameTracker(
        sequence.dimension, start_rotation, start_position, covariance=start_covariance
    )


def add_earth_frame(config: SensorBasedConfig, sequence: Sequence, state: FilterState) -> bool:
    """With ``earth_frame_source=filter_state``, the Earth frame's features at the dataset's
    initial pose join ``state`` (``earth_state``); returns whether they did."""
    if not config.earth_frame or config.earth_frame_source != "filter_state":
        return False
    values, covariance = frame_from_pose(*start_pose(config, sequence))
    state.add_earth_frame(values, covariance)
    return True


def start_pose(
    config: SensorBasedConfig, sequence: Sequence
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """The dataset's initial pose (the identity without one): rotation (d, d) body to Earth,
    position (d,) [m], and its covariance (world coordinates ``[dp, dphi]``; None: zero)."""
    d = sequence.dimension
    r = rate_dimension(d)
    start = sequence.initial_state
    start_rotation, start_position = np.eye(d), np.zeros(d)
    start_covariance = None
    if start is not None:
        start_rotation = (
            rot2(float(start.rotation)) if d == 2 else matrix_from_quat_wxyz(start.rotation)
        )
        start_position = np.asarray(start.position, dtype=float)
        position_sigma = config.initial_position_sigma_m or start.position_sigma_m
        rotation_sigma = config.initial_rotation_sigma_rad or start.rotation_sigma_rad
        start_covariance = np.diag([position_sigma**2] * d + [rotation_sigma**2] * r)
    return start_rotation, start_position, start_covariance
