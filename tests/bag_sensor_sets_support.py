"""Bags of other sensor sets than lidar + IMU, written with rosbags' own Writers from
simulated data with exact truth (``tests/test_bag_sensor_sets.py``).

``write_robot_localization_bag``: what robot_localization's test bags hold, no lidar: a
ground robot on flat ground (ENU about ``ORIGIN``, z up), ``DURATION_S`` long, that stands
for 1 s, speeds up to 1 m/s and weaves (yaw rate 0.25 sin(0.4 t) rad/s), starting at ``START_YAW_DEG`` from east.
Topics:
- ``/imu/data`` (sensor_msgs/Imu, 50 Hz): gyro and specific force with white noise, and the
  orientation (ENU, REP-145) with 0.02 rad of yaw noise and that covariance stated;
- ``/odom`` (nav_msgs/Odometry, 50 Hz, frame ``odom`` -> ``base_link``): wheel odometry
  integrated from the true increments with a 0.5 % distance scale error and noise, from
  identity; its twist with a diff_drive_controller-like covariance (measured x, y, yaw;
  1e6 placeholders elsewhere);
- ``/gps/fix`` (sensor_msgs/NavSatFix, 5 Hz): the true position plus 0.5 m (horizontal) and
  1 m (vertical) noise, the covariance stated;
- ``/odometry/filtered`` (nav_msgs/Odometry, 25 Hz, frame ``odom``): an estimator's output
  (the truth with small noise): never the odometry input, never the truth;
- ``/odometry/gps`` (nav_msgs/Odometry, 5 Hz, frame ``odom``, no child frame): the fixes
  as poses;
- ``/ground_truth`` (nav_msgs/Odometry in ROS 1, frame ``world``, zero covariance;
  geometry_msgs/PoseStamped in ROS 2): the truth at 50 Hz.

``write_laser_bag``: a robot driving along a room's middle with a ``sensor_msgs/LaserScan``
(ray-cast against the room's walls) and wheel odometry; returns the scans written.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from rosbags.typesys import Stores, get_typestore

EPOCH_S = 1_700_000_000.0
ORIGIN = (48.137, 11.575, 520.0)
START_YAW_DEG = 30.0
DURATION_S = 8.0


def _speed(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Speed [m/s] and its derivative: still for 1 s, a smooth ramp to 1 m/s by 3 s."""
    u = np.clip((t - 1.0) / 2.0, 0.0, 1.0)
    speed = 0.5 * (1.0 - np.cos(np.pi * u))
    rate = np.where((t > 1.0) & (t < 3.0), 0.25 * np.pi * np.sin(np.pi * u), 0.0)
    return speed, rate


def _yaw_rate(t: np.ndarray) -> np.ndarray:
    return np.where(t > 3.0, 0.25 * np.sin(0.4 * (t - 3.0)), 0.0)


class Drive:
    """The true motion, integrated on a 1 kHz grid and interpolated."""

    def __init__(self, duration_s: float = DURATION_S) -> None:
        self.grid = np.arange(0.0, duration_s + 0.5, 1e-3)
        speed, _ = _speed(self.grid)
        yaw_rate = _yaw_rate(self.grid)
        dt = np.diff(self.grid)
        self.yaw_grid = np.deg2rad(START_YAW_DEG) + np.concatenate(
            [[0.0], np.cumsum(0.5 * (yaw_rate[1:] + yaw_rate[:-1]) * dt)]
        )
        vx, vy = speed * np.cos(self.yaw_grid), speed * np.sin(self.yaw_grid)
        self.x_grid = np.concatenate([[0.0], np.cumsum(0.5 * (vx[1:] + vx[:-1]) * dt)])
        self.y_grid = np.concatenate([[0.0], np.cumsum(0.5 * (vy[1:] + vy[:-1]) * dt)])

    def at(self, t: float) -> dict[str, float]:
        speed, acceleration = (float(v[0]) for v in _speed(np.array([t])))
        yaw_rate = float(_yaw_rate(np.array([t]))[0])
        return {
            "x": float(np.interp(t, self.grid, self.x_grid)),
            "y": float(np.interp(t, self.grid, self.y_grid)),
            "yaw": float(np.interp(t, self.grid, self.yaw_grid)),
            "speed": speed,
            "acceleration": acceleration,
            "yaw_rate": yaw_rate,
        }


class _Messages:
    """Message builders for one typestore (ROS 1 or ROS 2)."""

    def __init__(self, ros1: bool) -> None:
        self.ros1 = ros1
        self.store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
        self.T = self.store.types

    def header(self, t: float, frame: str):
        ns = int(round((EPOCH_S + t) * 1e9))
        stamp = self.T["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)
        if self.ros1:
            return self.T["std_msgs/msg/Header"](seq=0, stamp=stamp, frame_id=frame)
        return self.T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)

    def vector(self, x: float, y: float, z: float):
        return self.T["geometry_msgs/msg/Vector3"](x=float(x), y=float(y), z=float(z))

    def quaternion(self, yaw: float):
        return self.T["geometry_msgs/msg/Quaternion"](
            x=0.0, y=0.0, z=float(np.sin(0.5 * yaw)), w=float(np.cos(0.5 * yaw))
        )

    def pose(self, x: float, y: float, yaw: float):
        point = self.T["geometry_msgs/msg/Point"](x=float(x), y=float(y), z=0.0)
        return self.T["geometry_msgs/msg/Pose"](position=point, orientation=self.quaternion(yaw))

    def odometry(
        self, t, frame, child, pose, pose_cov, linear=(0, 0, 0), angular=(0, 0, 0), twist_cov=None
    ):
        T = self.T
        return T["nav_msgs/msg/Odometry"](
            header=self.header(t, frame),
            child_frame_id=child,
            pose=T["geometry_msgs/msg/PoseWithCovariance"](
                pose=pose, covariance=np.asarray(pose_cov, dtype=float).ravel()
            ),
            twist=T["geometry_msgs/msg/TwistWithCovariance"](
                twist=T["geometry_msgs/msg/Twist"](
                    linear=self.vector(*linear), angular=self.vector(*angular)
                ),
                covariance=np.zeros(36) if twist_cov is None else np.asarray(twist_cov).ravel(),
            ),
        )  # fmt: skip

    def serialize(self, message, msgtype: str) -> bytes:
        if self.ros1:
            return self.store.serialize_ros1(message, msgtype)
        return self.store.serialize_cdr(message, msgtype)


def _write(
    path: Path,
    ros1: bool,
    messages: list[tuple[str, str, float, object]],
    build,
    storage: str = "sqlite3",
) -> Path:
    """Write ``(topic, type, t, message)`` (sorted by t, logged at their stamps); ROS 2 in
    ``storage`` (sqlite3 or mcap)."""
    messages = sorted(messages, key=lambda item: item[2])
    if ros1:
        from rosbags.rosbag1 import Writer

        path = path.with_suffix(".bag")
        writer = Writer(path)
    else:
        from rosbags.rosbag2 import StoragePlugin, Writer

        plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
        writer = Writer(path, version=9, storage_plugin=plugin)
    with writer:
        connections = {}
        for topic, msgtype, t, message in messages:
            if topic not in connections:
                connections[topic] = writer.add_connection(topic, msgtype, typestore=build.store)
            writer.write(
                connections[topic],
                int(round((EPOCH_S + t) * 1e9)),
                build.serialize(message, msgtype),
            )
    return path


def write_robot_localization_bag(path: Path, ros1: bool, seed: int = 3) -> Path:
    """The bag of the module docstring; returns its path (``.bag`` added for ROS 1)."""
    from datasets.synthetic_lidar.writer import enu_to_geodetic

    rng = np.random.default_rng(seed)
    drive = Drive()
    build = _Messages(ros1)
    T = build.T
    messages = []
    gyro_sigma, accel_sigma = 2e-4 * np.sqrt(50.0), 2e-3 * np.sqrt(50.0)
    for k in range(int(DURATION_S * 50) + 1):
        t = k / 50.0
        m = drive.at(t)
        gyro = np.array([0.0, 0.0, m["yaw_rate"]]) + rng.normal(0.0, gyro_sigma, 3)
        accel = np.array([m["acceleration"], m["speed"] * m["yaw_rate"], 9.81])
        accel = accel + rng.normal(0.0, accel_sigma, 3)
        imu = T["sensor_msgs/msg/Imu"](
            header=build.header(t, "imu_link"),
            orientation=build.quaternion(m["yaw"] + rng.normal(0.0, 0.02)),
            orientation_covariance=np.diag([1e-6, 1e-6, 4e-4]).ravel(),
            angular_velocity=build.vector(*gyro),
            angular_velocity_covariance=np.eye(3).ravel() * gyro_sigma**2,
            linear_acceleration=build.vector(*accel),
            linear_acceleration_covariance=np.eye(3).ravel() * accel_sigma**2,
        )
        messages.append(("/imu/data", "sensor_msgs/msg/Imu", t, imu))
        if ros1:
            truth = build.odometry(
                t, "world", "base_link", build.pose(m["x"], m["y"], m["yaw"]), np.zeros(36)
            )
            messages.append(("/ground_truth", "nav_msgs/msg/Odometry", t, truth))
        else:
            truth = T["geometry_msgs/msg/PoseStamped"](
                header=build.header(t, "world"), pose=build.pose(m["x"], m["y"], m["yaw"])
            )
            messages.append(("/ground_truth", "geometry_msgs/msg/PoseStamped", t, truth))
    # wheel odometry: true increments, 0.5 % long, with noise, integrated from identity
    odom = np.zeros(3)
    previous = drive.at(0.0)
    pose_cov = np.diag([1e-3, 1e-3, 1e6, 1e6, 1e6, 1e-3])
    twist_cov = np.diag([2.5e-3, 2.5e-3, 1e6, 1e6, 1e6, 2.5e-3])
    for k in range(int(DURATION_S * 50) + 1):
        t = k / 50.0
        m = drive.at(t)
        if k:
            c, s = np.cos(previous["yaw"]), np.sin(previous["yaw"])
            dx, dy = m["x"] - previous["x"], m["y"] - previous["y"]
            body = np.array([c * dx + s * dy, -s * dx + c * dy]) * 1.005
            body += rng.normal(0.0, 2e-4, 2) * (m["speed"] > 0)
            dyaw = m["yaw"] - previous["yaw"] + rng.normal(0.0, 2e-4) * (m["speed"] > 0)
            c, s = np.cos(odom[2]), np.sin(odom[2])
            odom = odom + np.array([c * body[0] - s * body[1], s * body[0] + c * body[1], dyaw])
        previous = m
        linear = (m["speed"] + rng.normal(0.0, 0.01) * (m["speed"] > 0), 0.0, 0.0)
        angular = (0.0, 0.0, m["yaw_rate"])
        message = build.odometry(
            t, "odom", "base_link", build.pose(*odom), pose_cov, linear, angular, twist_cov
        )
        messages.append(("/odom", "nav_msgs/msg/Odometry", t, message))
    for k in range(int(DURATION_S * 25) + 1):
        t = k / 25.0
        m = drive.at(t)
        pose = build.pose(m["x"] + rng.normal(0, 0.02), m["y"] + rng.normal(0, 0.02), m["yaw"])
        message = build.odometry(t, "odom", "base_link", pose, np.eye(6) * 1e-2)
        messages.append(("/odometry/filtered", "nav_msgs/msg/Odometry", t, message))
    for k in range(int(DURATION_S * 5) + 1):
        t = k / 5.0
        m = drive.at(t)
        enu = np.array([m["x"], m["y"], 0.0]) + rng.normal(0.0, [0.5, 0.5, 1.0])
        lat, lon, alt = enu_to_geodetic(enu[None], ORIGIN)[0]
        status = T["sensor_msgs/msg/NavSatStatus"](status=0, service=1)
        fix = T["sensor_msgs/msg/NavSatFix"](
            header=build.header(t, "gps"),
            status=status,
            latitude=float(lat),
            longitude=float(lon),
            altitude=float(alt),
            position_covariance=np.diag([0.25, 0.25, 1.0]).ravel(),
            position_covariance_type=2,
        )
        messages.append(("/gps/fix", "sensor_msgs/msg/NavSatFix", t, fix))
        gps_pose = build.odometry(t, "odom", "", build.pose(enu[0], enu[1], 0.0), np.eye(6) * 0.25)
        messages.append(("/odometry/gps", "nav_msgs/msg/Odometry", t, gps_pose))
    return _write(path, ros1, messages, build)


ROOM_HALF_X, ROOM_HALF_Y = 4.0, 2.5
"""The room of the laser bag: walls at x = +-4 m, y = +-2.5 m about its centre."""


def room_ranges(x: float, y: float, yaw: float, angles: np.ndarray) -> np.ndarray:
    """Ranges [m] from (x, y) facing ``yaw`` along ``angles`` to the room's walls."""
    directions = yaw + angles
    c, s = np.cos(directions), np.sin(directions)
    with np.errstate(divide="ignore"):
        tx = np.where(c > 0, (ROOM_HALF_X - x) / c, np.where(c < 0, (-ROOM_HALF_X - x) / c, np.inf))
        ty = np.where(s > 0, (ROOM_HALF_Y - y) / s, np.where(s < 0, (-ROOM_HALF_Y - y) / s, np.inf))
    return np.minimum(tx, ty)


def write_laser_bag(
    path: Path, ros1: bool, seed: int = 5, scans: int = 20, storage: str = "sqlite3"
):
    """A ``/scan`` LaserScan topic (10 Hz, 361 beams over 270 deg, a few beams without return
    as +inf and NaN, per-beam time) and ``/odom`` wheel odometry (50 Hz), the robot driving
    along x at 0.3 m/s from (-1.5, 0.2); returns (path, the scans as (t, angle_min,
    angle_increment, ranges float32, range_min, range_max, time_increment))."""
    rng = np.random.default_rng(seed)
    build = _Messages(ros1)
    T = build.T
    messages, written = [], []
    angle_min, increment, beams = -0.75 * np.pi, np.deg2rad(0.75), 361
    angles = angle_min + increment * np.arange(beams)
    for k in range(scans):
        t = 0.1 * k
        x, y, yaw = -1.5 + 0.3 * t, 0.2, 0.05 * t
        ranges = (room_ranges(x, y, yaw, angles) + rng.normal(0.0, 0.005, beams)).astype(np.float32)
        ranges[7] = np.inf
        ranges[200] = np.nan
        time_increment = 0.1 / 480.0 if k % 2 == 0 else 0.0  # every other scan untimed
        scan = T["sensor_msgs/msg/LaserScan"](
            header=build.header(t, "laser"),
            angle_min=float(angle_min),
            angle_max=float(angles[-1]),
            angle_increment=float(increment),
            time_increment=float(time_increment),
            scan_time=0.1,
            range_min=0.05,
            range_max=30.0,
            ranges=ranges,
            intensities=np.zeros(0, dtype=np.float32),
        )
        messages.append(("/scan", "sensor_msgs/msg/LaserScan", t, scan))
        written.append((EPOCH_S + t, angle_min, increment, ranges, 0.05, 30.0, time_increment))
    for k in range(int(0.1 * scans * 50) + 3):
        t = k / 50.0
        x, y, yaw = 0.3 * t, 0.0, 0.05 * t  # odometry starts at identity
        twist_cov = np.diag([1e-4, 1e-4, 1e6, 1e6, 1e6, 1e-4])
        message = build.odometry(
            t, "odom", "base_link", build.pose(x, y, yaw), np.eye(6) * 1e-3, (0.3, 0, 0), (0, 0, 0.05), twist_cov
        )  # fmt: skip
        messages.append(("/odom", "nav_msgs/msg/Odometry", t, message))
    return _write(path, ros1, messages, build, storage), written
