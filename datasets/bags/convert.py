"""One bag message -> the workbench vocabulary (``convert``), with the checks of what each
message type can show, each violation skipped (or, for a cloud, repaired) and counted in the
``ReadReport``:
- PointCloud2 -> ``PointCloud``, points and per-point times: layout, coordinate types,
  points (``datasets.bags.pointcloud2``); times by ``datasets.lidar.sweep_times``; the
  points then moved into the body frame (``ReadSettings.lidar_to_body``);
- LaserScan -> ``PlanarScan`` (``datasets.bags.laserscan``);
- IMU samples -> ``ImuSample``: non-finite, or |gyro| above ``MAX_GYRO_RAD_S``, |accel|
  above ``MAX_ACCEL_M_S2``;
- GPS fixes (NavSatFix) -> ``GpsFix`` in local ENU about ``ReadSettings.gps_origin``
  (``datasets.bags.gps``; ``first_gps_origin`` finds the first valid fix): without a fix,
  or latitude or longitude out of range; a covariance of unknown type, non-finite or with a
  non-positive diagonal is replaced by ``gps_sigma_m``;
- Odometry, PoseStamped and PoseWithCovarianceStamped (``pose_of``: Odometry and
  PoseWithCovarianceStamped hold the pose in ``pose.pose``, PoseStamped in ``pose``) ->
  ``PoseSample`` (``datasets.bags.wheel_odometry``): non-finite, or an orientation that is
  not a unit quaternion (within ``UNIT_QUATERNION_TOLERANCE``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from datasets.bags.bag_file import iter_messages
from datasets.bags.gps import geodetic_to_enu
from datasets.bags.laserscan import MalformedScan, decode_laserscan
from datasets.bags.message_types import (
    IMU,
    LASERSCAN,
    NAVSATFIX,
    ODOMETRY,
    POINTCLOUD2,
    POSE_TYPES,
    POSE_WITH_COVARIANCE_STAMPED,
)
from datasets.bags.pointcloud2 import MalformedCloud, decode_pointcloud2
from datasets.bags.read_report import ReadReport, ReadSettings
from datasets.bags.wheel_odometry import PoseSample, pose_sample
from datasets.laser2d.scan import PlanarScan
from datasets.lidar.sweep_times import point_times_for
from datasets.measurements import GpsFix, ImuSample, Measurement, PointCloud

MAX_GYRO_RAD_S = 70.0
"""|gyro| bound [rad/s]: 4000 deg/s, the full scale of the widest-range MEMS gyros; a
larger rate is no measurement."""
MAX_ACCEL_M_S2 = 400.0
"""|accel| bound [m/s^2]: about 40 g, beyond the 16-32 g full scale of the IMUs vehicles
and handheld rigs carry."""
UNIT_QUATERNION_TOLERANCE = 0.01
"""A ground-truth orientation whose norm is further than this from 1 is not a rotation a
pose publisher wrote (rounding leaves 1e-7)."""


def _vector(v) -> np.ndarray:
    return np.array([v.x, v.y, v.z], dtype=float)


def pose_of(message, msgtype: str) -> tuple[np.ndarray, np.ndarray]:
    """Position (3,) and quaternion (w, x, y, z) (4,) of an Odometry, PoseStamped or
    PoseWithCovarianceStamped."""
    pose = (
        message.pose.pose if msgtype in (ODOMETRY, POSE_WITH_COVARIANCE_STAMPED) else message.pose
    )
    q = pose.orientation
    return _vector(pose.position), np.array([q.w, q.x, q.y, q.z], dtype=float)


def convert(
    path: Path,
    topic: str,
    msgtype: str,
    stamp: float,
    message,
    settings: ReadSettings,
    report: ReadReport,
) -> Measurement | PlanarScan | PoseSample | None:
    """One message -> measurement, or None (skipped and counted) for an empty or malformed
    cloud or laser scan, an implausible IMU sample or GPS fix, GPS without fix, a
    non-finite odometry pose (module docstring). A ``LaserScan`` becomes a ``PlanarScan``
    (``datasets.bags.laserscan``) and a pose message of the odometry topic a ``PoseSample``
    (``datasets.bags.wheel_odometry``): the bag source turns them into corners and
    increments. ``InputError`` for a cloud without x/y/z or with coordinates that are not
    floats."""
    where = f"{path}, topic {topic}, t={stamp:.9f}"
    if msgtype == LASERSCAN:
        try:
            scan, dropped = decode_laserscan(message, stamp, settings.laser_mounting)
        except MalformedScan as error:
            report.skip(topic, "malformed LaserScan", stamp, error.problem)
            return None
        if dropped:
            report.repair(topic, "beam times dropped", stamp, dropped)
        return scan
    if msgtype in POSE_TYPES:
        sample = pose_sample(message, msgtype, stamp)
        with np.errstate(over="ignore"):
            norm = float(np.linalg.norm(sample.quaternion))
        if not (np.all(np.isfinite(sample.position)) and np.isfinite(norm)) or (
            abs(norm - 1.0) > UNIT_QUATERNION_TOLERANCE
        ):
            report.skip(topic, "non-finite pose or not a unit quaternion", stamp)
            return None
        return sample
    if msgtype == POINTCLOUD2:
        try:
            cloud = decode_pointcloud2(
                message, stamp, where, settings.time_unit, settings.max_point_time_s
            )
        except MalformedCloud as error:
            report.skip(topic, "malformed PointCloud2", stamp, error.problem)
            return None
        report.nonfinite_points += cloud.nonfinite
        problems = "; ".join(cloud.problems)
        if cloud.points.shape[0] == 0:
            report.skip(topic, "empty cloud (no finite points)", stamp, problems)
            return None
        if problems:
            report.repair(topic, "implausible points dropped", stamp, problems)
        points = cloud.points
        times = point_times_for(points, cloud.point_times, settings.azimuth_sweep_s, where)
        if settings.lidar_to_body is not None:  # after the azimuths: they are the lidar's
            points = points @ settings.lidar_to_body[:3, :3].T + settings.lidar_to_body[:3, 3]
        return PointCloud(t=stamp, points=points, point_times=times)
    if msgtype == IMU:
        gyro, accel = _vector(message.angular_velocity), _vector(message.linear_acceleration)
        if not (np.all(np.isfinite(gyro)) and np.all(np.isfinite(accel))):
            report.skip(topic, "non-finite IMU sample", stamp)
            return None
        with np.errstate(over="ignore"):  # a corrupted 1e300 overflows to inf: still caught
            rate, specific_force = float(np.linalg.norm(gyro)), float(np.linalg.norm(accel))
        if rate > MAX_GYRO_RAD_S or specific_force > MAX_ACCEL_M_S2:
            report.skip(
                topic,
                f"implausible IMU sample (|gyro| over {MAX_GYRO_RAD_S:g} rad/s or |accel| over "
                f"{MAX_ACCEL_M_S2:g} m/s^2)",
                stamp,
                f"|gyro| {rate:.3g} rad/s, |accel| {specific_force:.3g} m/s^2",
            )
            return None
        return ImuSample(t=stamp, gyro=gyro, accel=accel)
    if msgtype == NAVSATFIX:
        fix = np.array([[message.latitude, message.longitude, message.altitude]], dtype=float)
        if message.status.status < 0 or not np.all(np.isfinite(fix)) or settings.gps_origin is None:
            report.skip(topic, "GPS without fix", stamp)
            return None
        if abs(fix[0, 0]) > 90.0 or abs(fix[0, 1]) > 180.0:
            detail = f"latitude {fix[0, 0]:.9g}, longitude {fix[0, 1]:.9g}"
            report.skip(topic, "GPS fix off the globe", stamp, detail)
            return None
        covariance = np.asarray(message.position_covariance, dtype=float).reshape(3, 3)
        if (
            message.position_covariance_type == 0
            or not np.all(np.isfinite(covariance))
            or np.any(np.diag(covariance) <= 0)
        ):
            covariance = np.eye(3) * settings.gps_sigma_m**2
        return GpsFix(
            t=stamp, position=geodetic_to_enu(fix, settings.gps_origin)[0], covariance=covariance
        )
    return None


def first_gps_origin(reader, path: Path, topic: str) -> tuple[float, float, float] | None:
    """Latitude, longitude, altitude of the first valid fix (the ENU origin), or None."""
    # broken messages are passed over here: the stream counts them where it meets them
    for _, _, _, message in iter_messages(reader, path, [topic], report=ReadReport()):
        values = (float(message.latitude), float(message.longitude), float(message.altitude))
        on_globe = abs(values[0]) <= 90.0 and abs(values[1]) <= 180.0
        if message.status.status >= 0 and np.all(np.isfinite(values)) and on_globe:
            return values
    return None
