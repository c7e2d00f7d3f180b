"""What the sequence offers, turned into the smoother's start: the initial priors and the
motion model between keyframes.

- 3-D: IMU preintegration (``smoothers.imu_graph.ImuMotion``), gravity from the config, the
  sequence's (``Sequence.gravity_m_s2``), or 9.81 m/s^2; without an IMU, the relative poses
  of lidar odometry (``smoothers.spatial_odometry.SpatialOdometryMotion``).
- 2-D: odometry between-factors when the sequence has odometry (and ``use_odometry``),
  else the documented gyro-only constant-velocity model
  (``smoothers.planar_graph.PlanarMotion``).

Prior sigmas: the config's when set, else the sequence's stated start and noise, so the
smoother starts from what the filters it is compared with start from
(``smoothers.initialization``).
"""

from __future__ import annotations

from datasets.errors import InputError
from datasets.estimator_options import per_body_axis
from datasets.measurements import Sensor
from datasets.sequence import Sequence
from smoothers.config import SmootherConfig
from smoothers.imu_graph import ImuMotion, ImuNoise
from smoothers.motion_model import MotionModel
from smoothers.planar_graph import PlanarMotion
from smoothers.priors import InitialPriors
from smoothers.spatial_odometry import SpatialOdometryMotion

DEFAULT_GYRO_BIAS_SIGMA_RAD_S = 0.01
DEFAULT_ACCEL_BIAS_SIGMA_M_S2 = 0.1
DEFAULT_PLANAR_GYRO_BIAS_WALK = 1e-4
"""[rad/s^2/sqrt(Hz)] when the sequence states none."""


def initial_priors(config: SmootherConfig, sequence: Sequence) -> InitialPriors:
    """Sigmas of the priors on keyframe 0 (the sequence must have an initial state)."""
    c, s, n = config, sequence.initial_state, sequence.noise
    assert s is not None
    return InitialPriors(
        position_sigma_m=c.initial_position_sigma_m or s.position_sigma_m,
        rotation_sigma_rad=c.initial_rotation_sigma_rad or s.rotation_sigma_rad,
        velocity_sigma_m_s=c.initial_velocity_sigma_m_s or s.velocity_sigma_m_s,
        gyro_bias_sigma_rad_s=c.initial_gyro_bias_sigma_rad_s
        or n.gyro_bias_sigma_rad_s
        or DEFAULT_GYRO_BIAS_SIGMA_RAD_S,
        accel_bias_sigma_m_s2=c.initial_accel_bias_sigma_m_s2
        or n.accel_bias_sigma_m_s2
        or DEFAULT_ACCEL_BIAS_SIGMA_M_S2,
    )


def motion_model(config: SmootherConfig, sequence: Sequence) -> MotionModel:
    """The motion model the sequence's dimension and sensors call for (module docstring)."""
    c = config
    if sequence.dimension == 3 and Sensor.IMU not in sequence.sensors:
        if Sensor.ODOMETRY not in sequence.sensors or not c.use_odometry:
            raise InputError(
                f"{sequence.name}: the 3-D smoother needs IMU samples or odometry "
                "(use_odometry=true)"
            )
        return SpatialOdometryMotion()
    if sequence.dimension == 3:
        gravity = c.gravity_m_s2 or float(sequence.gravity_m_s2 or 9.81)
        return ImuMotion(
            ImuNoise.from_spec(sequence.noise, sequence.name),
            gravity,
            c.max_gap_s,
            c.interval_rate,
        )
    if Sensor.ODOMETRY in sequence.sensors and c.use_odometry:
        source = "odometry"
    elif Sensor.GYRO in sequence.sensors:
        source = "gyro"
    else:
        raise InputError(
            f"{sequence.name}: the planar smoother needs odometry (use_odometry=true) or a rate gyro"
        )
    gyro_density = c.gyro_noise_density_rad_s_sqrt_hz or sequence.noise.gyro_noise_density
    if source == "gyro" and not gyro_density:
        raise InputError(
            f"{sequence.name}: gyro-only planar smoother needs the gyro noise density "
            "(sequence.noise or gyro_noise_density_rad_s_sqrt_hz)"
        )
    gyro_walk = (
        c.gyro_bias_walk_rad_s_sqrt_s
        or sequence.noise.gyro_bias_walk
        or DEFAULT_PLANAR_GYRO_BIAS_WALK
    )
    return PlanarMotion(
        source,
        per_body_axis(c.velocity_walk_m_s_sqrt_s, 2, "velocity_walk_m_s_sqrt_s"),
        gyro_density or 0.0,
        gyro_walk,
        c.odometry_lateral_sigma_m_s,
        c.max_gap_s,
        c.interval_rate,
    )
