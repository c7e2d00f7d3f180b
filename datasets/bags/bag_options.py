"""The ``--data`` options of ``bag:PATH`` (``BagOptions``), the lidar's mounting among them as
a matrix (``extrinsic_matrix``), and their lines for ``workbench list --verbose``
(``describe``). One set of options for every bag: the lidar bag's sequence
(``datasets.bags.source``) and the bag without a lidar (``datasets.bags.sensor_source``)
read the same ``BagOptions``.
"""

from __future__ import annotations

import numpy as np
from pydantic import ConfigDict, Field

from datasets.errors import InputError
from datasets.laser2d.frontend import Laser2dFrontEndSettings
from datasets.lidar.frontend_settings import LidarSourceOptions, describe_lidar_options
from datasets.rotations import matrix_from_quat_wxyz


class BagOptions(LidarSourceOptions):
    """``--data`` options of ``bag:PATH`` (nested ones as ``kiss.voxel_size_m=0.5``, ``corner.directions=true``)."""

    model_config = ConfigDict(extra="forbid")

    lidar_topic: str | None = Field(None, description="PointCloud2 topic (default: the only one)")
    max_missing_fraction: float = Field(
        0.01,
        ge=0,
        le=1,
        description="fewer messages read on a topic than the bag's index lists is a warning; "
        "more than this fraction missing is an error (a damaged bag)",
    )
    imu_topic: str | None = Field(None, description="Imu topic (default: the only one, if any)")
    ground_truth_topic: str | None = Field(
        None,
        description="Odometry/PoseStamped topic to score against (default: none; a pose topic "
        "is never taken as truth unless named: it may be wheel odometry or another estimator)",
    )
    max_skipped_fraction: float = Field(
        0.05,
        ge=0,
        le=1,
        description="messages skipped on a topic (NaN IMU samples, non-finite poses, empty "
        "clouds, stamps going back) are counted warnings; more than this fraction is an error",
    )
    gps_topic: str | None = Field(
        None, description="NavSatFix topic (default: the only one, if any)"
    )
    imu: bool = Field(True, description="use the IMU topic when there is one")
    imu_deskew: bool = Field(
        True,
        description="with an IMU topic, deskew clouds that carry per-point times by the "
        "gyro's rotation over the sweep (datasets.lidar.imu_deskew) instead of KISS-ICP's "
        "constant-velocity prediction; frames the IMU does not cover fall back to the latter "
        "and are counted in the warnings",
    )
    gps: bool = Field(True, description="use the NavSatFix topic when there is one")
    gps_sigma_m: float = Field(
        1.0, gt=0, description="GPS std when a fix carries no covariance [m]"
    )
    gyro_noise_density: float | None = Field(
        None, gt=0, description="[rad/s/sqrt(Hz)] (default: from the Imu covariance, else 1.7e-4)"
    )
    accel_noise_density: float | None = Field(
        None, gt=0, description="[m/s^2/sqrt(Hz)] (default: from the Imu covariance, else 2e-3)"
    )
    gyro_bias_walk: float = Field(
        2e-5,
        gt=0,
        description="gyro bias random walk [rad/s^2/sqrt(Hz)] (bags do not say; a MEMS-class value)",
    )
    accel_bias_walk: float = Field(
        3e-4, gt=0, description="accelerometer bias random walk [m/s^3/sqrt(Hz)] (bags do not say)"
    )
    gyro_bias_sigma_rad_s: float = Field(
        0.01, gt=0, description="std of the initial gyro bias [rad/s]"
    )
    accel_bias_sigma_m_s2: float = Field(
        0.1, gt=0, description="std of the initial accelerometer bias [m/s^2]"
    )
    lidar_to_body: tuple[float, float, float, float, float, float, float] | None = Field(
        None,
        description="lidar pose in the body (IMU) frame: [x, y, z, qw, qx, qy, qz]; clouds are moved into the body frame (also levels a tilted lidar for the corner slab)",
    )
    reorder_window_s: float = Field(
        1.0, ge=0, description="how far stamps may lag bag order and still be reordered [s]"
    )
    odometry_topic: str | None = Field(
        None,
        description="wheel-odometry topic (nav_msgs/Odometry, or a PoseStamped / "
        "PoseWithCovarianceStamped topic, differenced); default: decided from the bag's "
        "Odometry topics by their frames, rates, covariances, jumps and names (printed); used "
        "as input where no lidar odometry is, never as truth",
    )
    wheel_odometry: bool = Field(
        True, description="use wheel odometry (odometry_topic or the one decided) as an input"
    )
    odometry_noise: str = Field(
        "auto",
        description="wheel-odometry increment covariance: 'auto' (the messages' twist "
        "covariance on the axes where it is meaningful, else the stated default model), "
        "'twist', 'model' (datasets.bags.wheel_odometry.WHEEL_ODOMETRY_NOISE) or a YAML model "
        "file from `workbench calibrate-noise`",
    )
    odometry_max_rate_hz: float | None = Field(
        10.0,
        gt=0,
        description="wheel-odometry increments are composed to at most this rate [Hz] (the "
        "smoothers open a keyframe at each); null: one per message",
    )
    laser_topic: str | None = Field(
        None,
        description="sensor_msgs/LaserScan topic (default: the only one, if any); 'none': "
        "do not use a 2-D laser",
    )
    laser_to_body: tuple[float, float, float] | None = Field(
        None,
        description="2-D laser pose in the body frame: [x, y, theta] [m, m, rad] (default: "
        "the body frame; the bag's /tf_static is not read)",
    )
    laser: Laser2dFrontEndSettings = Field(
        default_factory=Laser2dFrontEndSettings,
        description="2-D laser front end (LaserScan bags), as laser.KEY=VALUE and "
        "laser.corner.KEY=VALUE (datasets.laser2d)",
    )


def extrinsic_matrix(pose: tuple[float, ...] | None) -> np.ndarray | None:
    """[x, y, z, qw, qx, qy, qz] -> (4, 4), or None; ``InputError`` for a zero quaternion."""
    if pose is None:
        return None
    quat = np.asarray(pose[3:], dtype=float)
    norm = np.linalg.norm(quat)
    if not norm > 1e-9:
        raise InputError(f"lidar_to_body: quaternion {list(pose[3:])} has zero length")
    matrix = np.eye(4)
    matrix[:3, :3] = matrix_from_quat_wxyz(quat / norm)
    matrix[:3, 3] = pose[:3]
    return matrix


def describe() -> list[str]:
    """Option lines for ``workbench list --verbose``."""
    return describe_lidar_options(BagOptions)
