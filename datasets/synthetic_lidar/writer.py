"""Write the synthetic lidar world as a ROS 1 or ROS 2 bag with rosbags' own Writer.

Topics: ``/points`` (sensor_msgs/PointCloud2, organized beams x columns, NaN for misses,
per-point time field), ``/imu`` (sensor_msgs/Imu), ``/ground_truth`` (nav_msgs/Odometry in
ROS 1, geometry_msgs/PoseStamped in ROS 2, so both ground-truth types are exercised), and
optionally ``/gps`` (sensor_msgs/NavSatFix) and ``/wheel/odometry`` (nav_msgs/Odometry,
``wheel_odometry_rate_hz``). The two formats also use different point
layouts: ROS 1 Velodyne-like (``time`` float32 seconds), ROS 2 Ouster-like (``t`` uint32
nanoseconds). A cloud's header stamp is the time of its first column; it is logged at the
end of its sweep, as a driver would, so bag order and stamp order differ.

Time: stamps are ``EPOCH_S`` + seconds from the first sweep; every topic starts there,
except that ``imu_lead_s`` > 0 starts the IMU earlier (``floor(imu_lead_s * imu_rate_hz)``
extra samples at negative times, as a driver started before the lidar would record), to
exercise the bag loader's common time base (``datasets.bags.source``).

Wheel odometry (``/wheel/odometry``, frame ``odom``, child ``base_link``) is deliberately
*not* truth: the true planar increments between its samples with the distance scaled by
``1 + WHEEL_SCALE_ERROR`` (2 %), the heading drifting by ``WHEEL_YAW_DRIFT_RAD_S`` and small
seeded noise, composed from the true pose at its first stamp. It is the pose topic a loader
must not take as ground truth unless told to.

Randomness: one generator seeded with ``seed`` draws the lidar, IMU and GPS noise in log
order; the IMU's lead samples and the wheel odometry draw from their own generators
(``[seed, 1]``, ``[seed, 2]``), so the options leave every other message unchanged and the
default options write the same bytes as before they existed.

Frames: lidar = IMU = body, at ``height_m`` above the floor; world z-up.
A sidecar JSON (``sidecar_path``) next to the bag holds the exact corners and the world
polygons, so the lidar front end can score itself.
"""

from __future__ import annotations

import errno
import heapq
import json
import shutil
import sqlite3
from collections.abc import Iterator
from pathlib import Path

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from datasets.bags.pointcloud2 import encode_pointcloud2
from datasets.errors import InputError
from datasets.lidar.corner_truth import SIDECAR_FORMAT, sidecar_for
from datasets.options import parse_options
from datasets.synthetic_lidar.lidar import LidarModel, sweep
from datasets.synthetic_lidar.path import LoopPath
from datasets.synthetic_lidar.world import World, corridor_world
from datasets.trajectory_io import write_atomic

GRAVITY_M_S2 = 9.81
EPOCH_S = 1_700_000_000
LIDAR_TOPIC, IMU_TOPIC, GT_TOPIC, GPS_TOPIC = "/points", "/imu", "/ground_truth", "/gps"
WHEEL_TOPIC = "/wheel/odometry"
WHEEL_SCALE_ERROR = 0.02  # wheel odometry over-reads distance by 2 %
WHEEL_YAW_DRIFT_RAD_S = 0.01  # and its heading drifts by this rate [rad/s]
WHEEL_NOISE_M, WHEEL_NOISE_RAD = 1e-3, 5e-4  # per-increment noise std
# Sizes the options are held to (``check_bag_size``). One sweep is ray-cast at once, beams x
# columns rays against every wall, so columns are bounded (twice the densest real sensor);
# the IMU's lead adds samples the duration does not count.
MAX_COLUMNS = 4096
MAX_IMU_LEAD_S = 60.0
MAX_BAG_BYTES = 2 * 1024**3
"""The largest bag ``simulate lidar-corridor`` writes: 2 GiB (the default 8 s bag is 42 MB).
The writer keeps an index entry per message in memory and the front end reads every sweep,
so the bound keeps both to what a workstation holds."""
POINT_BYTES = 32  # one point of a cloud (``_cloud_layout``)
MESSAGE_BYTES = 1024
"""Any message but a cloud's points, with its record and index: IMU 321 B, ground truth and
wheel odometry 714 B, NavSatFix 125 B of payload, measured in a ROS 1 bag; rounded up."""


class LidarBagOptions(BaseModel):
    """Options of ``workbench simulate lidar-corridor`` (``--data key=value``)."""

    model_config = ConfigDict(extra="forbid")

    duration_s: float = Field(8.0, gt=0, description="recording length [s]")
    start_s: float = Field(
        0.0, ge=0, description="where along the loop to start, as time at speed [s]"
    )
    speed_m_s: float = Field(1.5, gt=0, description="vehicle speed [m/s] (the loop is 76.4 m)")
    beams: int = Field(16, description="lidar beams: 16 or 32")
    columns: int = Field(
        1024,
        ge=16,
        le=MAX_COLUMNS,
        description="azimuth columns per revolution (real sensors: 512 to 2048)",
    )
    lidar_rate_hz: float = Field(10.0, gt=0, description="lidar revolutions per second")
    range_sigma_m: float = Field(0.01, ge=0, description="lidar range noise std [m]")
    imu_rate_hz: float = Field(200.0, gt=0, description="IMU rate [Hz]")
    gyro_noise_density: float = Field(2e-4, ge=0, description="[rad/s/sqrt(Hz)]")
    accel_noise_density: float = Field(2e-3, ge=0, description="[m/s^2/sqrt(Hz)]")
    gt_rate_hz: float = Field(50.0, gt=0, description="ground-truth rate [Hz]")
    gps_rate_hz: float = Field(0.0, ge=0, description="NavSatFix rate [Hz] (0: no GPS topic)")
    imu_lead_s: float = Field(
        0.0,
        ge=0,
        le=MAX_IMU_LEAD_S,
        description="the IMU starts this long before the first lidar sweep [s] (extra samples "
        "at negative times at imu_rate_hz; lidar and ground-truth timing unchanged)",
    )
    wheel_odometry_rate_hz: float = Field(
        0.0,
        ge=0,
        description="/wheel/odometry (nav_msgs/Odometry, child base_link) rate [Hz] (0: none): "
        "the true pose with a 2 % distance scale error, 0.01 rad/s heading drift and seeded "
        "noise, so it is clearly not ground truth",
    )
    gps_origin: tuple[float, float, float] = Field(
        (48.137, 11.575, 520.0), description="lat [deg], lon [deg], alt [m] of the world origin"
    )
    storage: str = Field(
        "sqlite3", pattern="^(sqlite3|mcap)$", description="ROS 2 storage plugin: sqlite3 or mcap"
    )
    time_field: str = Field(
        "auto",
        pattern="^(auto|time|t|timestamp|offset_time|none)$",
        description="per-point time field (auto: time for ros1, t for ros2)",
    )


def check_bag_size(settings: LidarBagOptions) -> None:
    """``InputError`` naming the options when the bag they describe would exceed
    ``MAX_BAG_BYTES`` (2 GiB): sweeps of beams x columns points (``POINT_BYTES`` each) plus
    one ``MESSAGE_BYTES`` per message of every topic, ``duration_s * rate`` messages each
    (``datasets.simulation.assembly.check_size``, which states the bound)."""
    from datasets.simulation.assembly import SizedStream, check_size

    lidar = settings.lidar_rate_hz
    streams = [
        SizedStream(
            f"lidar_rate_hz={lidar:g} with beams={settings.beams}, columns={settings.columns}",
            lidar,
            settings.beams * settings.columns * POINT_BYTES + MESSAGE_BYTES,
        ),
        SizedStream(f"imu_rate_hz={settings.imu_rate_hz:g}", settings.imu_rate_hz, MESSAGE_BYTES),
        SizedStream(f"gt_rate_hz={settings.gt_rate_hz:g}", settings.gt_rate_hz, MESSAGE_BYTES),
    ]
    for name in ("gps_rate_hz", "wheel_odometry_rate_hz"):
        rate = getattr(settings, name)
        if rate > 0:
            streams.append(SizedStream(f"{name}={rate:g}", rate, MESSAGE_BYTES))
    check_size(
        "simulate lidar-corridor --data",
        settings.duration_s,
        f"duration_s={settings.duration_s:g}",
        streams,
        bound_bytes=MAX_BAG_BYTES,
        bounded="a simulated bag may take",
    )


def sidecar_path(bag_path: Path) -> Path:
    """The corner sidecar next to a bag: ``NAME.corners.json`` beside file or folder ``NAME``."""
    return sidecar_for(bag_path)


def _stamp(typestore, t: float):
    ns = int(round((EPOCH_S + t) * 1e9))
    return typestore.types["builtin_interfaces/msg/Time"](
        sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000
    )


def _header(typestore, ros1: bool, t: float, frame: str):
    header_type = typestore.types["std_msgs/msg/Header"]
    if ros1:
        return header_type(seq=0, stamp=_stamp(typestore, t), frame_id=frame)
    return header_type(stamp=_stamp(typestore, t), frame_id=frame)


def _cloud_layout(time_field: str) -> np.dtype:
    """Structured dtype of one point, 32 bytes with padding (as drivers write them); its
    fields become the message's PointFields."""
    fields = [("x", 0, "<f4"), ("y", 4, "<f4"), ("z", 8, "<f4"), ("intensity", 16, "<f4")]
    fields.append(("ring", 20, "<u2"))
    if time_field in ("time", "timestamp"):
        fields.append((time_field, 24, "<f8" if time_field == "timestamp" else "<f4"))
    elif time_field in ("t", "offset_time"):
        fields.append((time_field, 24, "<u4"))
    return np.dtype(
        {
            "names": [name for name, _, _ in fields],
            "formats": [numpy_type for _, _, numpy_type in fields],
            "offsets": [offset for _, offset, _ in fields],
            "itemsize": 32,
        }
    )


def _quat_yaw(yaw: float) -> tuple[float, float, float, float]:
    return float(np.cos(0.5 * yaw)), 0.0, 0.0, float(np.sin(0.5 * yaw))


def enu_to_geodetic(enu: np.ndarray, origin: tuple[float, float, float]) -> np.ndarray:
    """Local ENU [m] (N, 3) -> (lat [deg], lon [deg], alt [m]) on WGS-84 (inverse of
    ``datasets.bags.gps.geodetic_to_enu``), by ECEF and Bowring-free fixed-point latitude."""
    from datasets.bags.gps import ecef_from_geodetic, enu_rotation

    lat0, lon0, alt0 = origin
    origin_ecef = ecef_from_geodetic(np.array([[lat0, lon0, alt0]]))[0]
    ecef = origin_ecef + np.asarray(enu) @ enu_rotation(lat0, lon0)
    a, e2 = 6378137.0, 6.69437999014e-3
    x, y, z = ecef.T
    lon = np.arctan2(y, x)
    p = np.hypot(x, y)
    lat = np.arctan2(z, p * (1 - e2))
    for _ in range(8):
        n = a / np.sqrt(1 - e2 * np.sin(lat) ** 2)
        alt = p / np.cos(lat) - n
        lat = np.arctan2(z, p * (1 - e2 * n / (n + alt)))
    n = a / np.sqrt(1 - e2 * np.sin(lat) ** 2)
    alt = p / np.cos(lat) - n
    return np.column_stack([np.rad2deg(lat), np.rad2deg(lon), alt])


def _events(options: LidarBagOptions) -> Iterator[tuple[int, str, float]]:
    """(log time ns, topic, stamp s) in log-time order. A cloud is logged at its sweep end."""

    def stream(
        topic: str, rate: float, log_delay: float, through_end: bool = False, lead: int = 0
    ) -> Iterator[tuple[int, str, float]]:
        # ground truth runs through the end of the last sweep, so every frame can be scored
        count = int(np.floor(options.duration_s * rate + 1e-9)) + (1 if through_end else 0)
        for k in range(-lead, count):
            stamp = k / rate
            yield int(round((EPOCH_S + stamp + log_delay) * 1e9)), topic, stamp

    streams = [
        stream(LIDAR_TOPIC, options.lidar_rate_hz, 1.0 / options.lidar_rate_hz),
        stream(IMU_TOPIC, options.imu_rate_hz, 0.0, lead=_imu_lead_samples(options)),
        stream(GT_TOPIC, options.gt_rate_hz, 0.0, through_end=True),
    ]
    if options.gps_rate_hz > 0:
        streams.append(stream(GPS_TOPIC, options.gps_rate_hz, 0.0))
    if options.wheel_odometry_rate_hz > 0:
        streams.append(stream(WHEEL_TOPIC, options.wheel_odometry_rate_hz, 0.0))
    return heapq.merge(*streams)


def _imu_lead_samples(options: LidarBagOptions) -> int:
    """IMU samples before the first sweep: ``floor(imu_lead_s * imu_rate_hz)``."""
    return int(np.floor(options.imu_lead_s * options.imu_rate_hz + 1e-9))


def wheel_odometry(
    path: LoopPath, options: LidarBagOptions, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stamps [s] (N,), planar positions (N, 2) and yaws (N,) of ``/wheel/odometry``: the true
    increments between samples (in the previous body frame) with the distance scaled by
    ``1 + WHEEL_SCALE_ERROR``, the heading increment plus ``WHEEL_YAW_DRIFT_RAD_S * dt``, and
    seeded noise, composed from the true pose at the first stamp (module docstring)."""
    rate = options.wheel_odometry_rate_hz
    stamps = np.arange(int(np.floor(options.duration_s * rate + 1e-9))) / rate
    truth = path.sample(options.start_s + stamps)
    positions, yaws = np.zeros((len(stamps), 2)), np.zeros(len(stamps))
    if not len(stamps):
        return stamps, positions, yaws
    positions[0], yaws[0] = truth.position[0], truth.yaw[0]
    for k in range(1, len(stamps)):
        c, s = np.cos(truth.yaw[k - 1]), np.sin(truth.yaw[k - 1])
        dx, dy = truth.position[k] - truth.position[k - 1]
        body = np.array([c * dx + s * dy, -s * dx + c * dy]) * (1.0 + WHEEL_SCALE_ERROR)
        body += rng.normal(0.0, WHEEL_NOISE_M, 2)
        dyaw = np.angle(np.exp(1j * (truth.yaw[k] - truth.yaw[k - 1])))
        dyaw += WHEEL_YAW_DRIFT_RAD_S / rate + rng.normal(0.0, WHEEL_NOISE_RAD)
        c, s = np.cos(yaws[k - 1]), np.sin(yaws[k - 1])
        positions[k] = positions[k - 1] + np.array(
            [c * body[0] - s * body[1], s * body[0] + c * body[1]]
        )
        yaws[k] = yaws[k - 1] + dyaw
    return stamps, positions, yaws


def _wheel_message(types, header, xy: np.ndarray, yaw: float, height_m: float):
    """A nav_msgs/Odometry of the wheel odometry (child ``base_link``) with a stated
    covariance (pose [x, y, z, roll, pitch, yaw] as ROS orders it); twist left zero."""
    w, x, y, z = _quat_yaw(yaw)
    vec = types["geometry_msgs/msg/Vector3"]
    pose = types["geometry_msgs/msg/Pose"](
        position=types["geometry_msgs/msg/Point"](x=float(xy[0]), y=float(xy[1]), z=height_m),
        orientation=types["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w),
    )
    covariance = np.diag([0.05**2, 0.05**2, 1e-6, 1e-6, 1e-6, 0.02**2]).ravel()
    return types["nav_msgs/msg/Odometry"](
        header=header,
        child_frame_id="base_link",
        pose=types["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=covariance),
        twist=types["geometry_msgs/msg/TwistWithCovariance"](
            twist=types["geometry_msgs/msg/Twist"](
                linear=vec(x=0.0, y=0.0, z=0.0), angular=vec(x=0.0, y=0.0, z=0.0)
            ),
            covariance=np.zeros(36),
        ),
    )


def write_sidecar(
    bag_path: Path, world: World, model: LidarModel, options: LidarBagOptions
) -> Path:
    """Exact corners (world frame, at the sensor height) and the world polygons as JSON."""
    positions, normals, heights = world.corners()
    payload = {
        "format": SIDECAR_FORMAT,
        "frame": "world (the ground-truth topic's frame), z-up",
        "slab_height_m": model.height_m,
        "max_range_m": model.max_range_m,
        "corners": [
            {
                "id": int(i),
                "position": [float(p[0]), float(p[1]), model.height_m],
                "face_normals": normals[i].tolist(),
                "height_m": float(heights[i]),
            }
            for i, p in enumerate(positions)
        ],
        "polygons": [
            {
                "kind": polygon.kind,
                "height_m": polygon.height_m,
                "vertices": polygon.vertices.tolist(),
            }
            for polygon in world.polygons
        ],
        # options added later are listed only when used: default bags keep their sidecars
        "options": {
            key: value
            for key, value in options.model_dump().items()
            if key not in ("imu_lead_s", "wheel_odometry_rate_hz") or value
        },
    }
    return write_atomic(sidecar_path(bag_path), json.dumps(payload, indent=1))


def write_lidar_bag(out: Path, seed: int, fmt: str, options: dict[str, str]) -> Path:
    """``workbench simulate lidar-corridor``: write the corridor world as a bag, return its path.

    Args:
        out: ``.bag`` file (ROS 1; the suffix is added if missing) or bag folder (ROS 2);
            must not exist yet.
        seed: noise seed.
        fmt: ``ros1`` or ``ros2``.
        options: ``LidarBagOptions`` as ``key=value`` strings.
    """
    settings = parse_options(LidarBagOptions, options, "simulate lidar-corridor")
    if fmt not in ("ros1", "ros2"):
        raise InputError(f"simulate lidar-corridor: --format must be ros1 or ros2, got '{fmt}'")
    if settings.beams not in (16, 32):
        raise InputError(f"simulate lidar-corridor: beams must be 16 or 32, got {settings.beams}")
    check_bag_size(settings)
    out = Path(out)
    if fmt == "ros1" and out.suffix != ".bag":
        out = out.with_name(out.name + ".bag")
    if out.exists():
        raise InputError(f"{out}: exists already; choose a new path")
    out.parent.mkdir(parents=True, exist_ok=True)
    ros1 = fmt == "ros1"
    # Written under a temporary name and renamed when complete: an interrupted run never
    # leaves a bag that looks whole, and a failed one (a full disk) leaves nothing behind.
    temp = out.parent / f".{out.name}.partial"
    _remove(temp)
    try:
        world, model = _write_messages(temp, out, seed, ros1, settings)
        temp.rename(out)
        write_sidecar(out, world, model, settings)
    except BaseException as error:
        _remove(temp)
        _remove(out)  # it did not exist before this call (checked above)
        if isinstance(error, sqlite3.Error):  # the ROS 2 storage's own report of a full disk
            raise OSError(errno.EIO, f"cannot write the bag ({error})", str(out)) from error
        if isinstance(error, OSError) and error.filename is None:
            # a failed write() names no file: name the bag the user asked for
            raise OSError(error.errno, error.strerror, str(out)) from error
        raise
    return out


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        path.unlink(missing_ok=True)


def _write_messages(
    temp: Path, out: Path, seed: int, ros1: bool, settings: LidarBagOptions
) -> tuple[World, LidarModel]:
    """Write every message of the bag at ``temp`` (named for ``out`` inside, where ROS 2
    names files after the folder); return the world and lidar model it shows."""
    from rosbags.typesys import Stores, get_typestore

    typestore = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    time_field = settings.time_field if settings.time_field != "auto" else ("time" if ros1 else "t")
    model = LidarModel(
        beams=settings.beams,
        columns=settings.columns,
        rate_hz=settings.lidar_rate_hz,
        range_sigma_m=settings.range_sigma_m,
    )
    world, path = corridor_world(), LoopPath(speed_m_s=settings.speed_m_s)
    rng = np.random.default_rng(seed)
    serialize = typestore.serialize_ros1 if ros1 else typestore.serialize_cdr
    types = typestore.types
    dtype = _cloud_layout(time_field)

    if ros1:
        from rosbags.rosbag1 import Writer as Writer1

        writer = Writer1(temp)
    else:
        from rosbags.rosbag2 import StoragePlugin
        from rosbags.rosbag2 import Writer as Writer2

        plugin = StoragePlugin.MCAP if settings.storage == "mcap" else StoragePlugin.SQLITE3
        writer = Writer2(temp, version=9, storage_plugin=plugin)
    gt_type = "nav_msgs/msg/Odometry" if ros1 else "geometry_msgs/msg/PoseStamped"
    with writer:
        connections = {
            LIDAR_TOPIC: writer.add_connection(
                LIDAR_TOPIC, "sensor_msgs/msg/PointCloud2", typestore=typestore
            ),
            IMU_TOPIC: writer.add_connection(IMU_TOPIC, "sensor_msgs/msg/Imu", typestore=typestore),
            GT_TOPIC: writer.add_connection(GT_TOPIC, gt_type, typestore=typestore),
        }
        if settings.gps_rate_hz > 0:
            connections[GPS_TOPIC] = writer.add_connection(
                GPS_TOPIC, "sensor_msgs/msg/NavSatFix", typestore=typestore
            )
        if settings.wheel_odometry_rate_hz > 0:
            connections[WHEEL_TOPIC] = writer.add_connection(
                WHEEL_TOPIC, "nav_msgs/msg/Odometry", typestore=typestore
            )
            _, wheel_xy, wheel_yaw = wheel_odometry(
                path, settings, np.random.default_rng([seed, 2])
            )
        lead_rng = np.random.default_rng([seed, 1])  # the IMU's lead samples (module docstring)
        imu_gyro_std = settings.gyro_noise_density * np.sqrt(settings.imu_rate_hz)
        imu_accel_std = settings.accel_noise_density * np.sqrt(settings.imu_rate_hz)
        zeros9 = np.zeros(9)
        for log_ns, topic, stamp in _events(settings):
            t = settings.start_s + stamp
            frame = {GT_TOPIC: "world", WHEEL_TOPIC: "odom"}.get(topic, "base_link")
            header = _header(typestore, ros1, stamp, frame)
            if topic == LIDAR_TOPIC:
                scan = sweep(world, path, model, t, rng)
                cloud = np.zeros(scan.points.shape[:2], dtype=dtype)
                cloud["x"], cloud["y"], cloud["z"] = (scan.points[..., k] for k in range(3))
                with np.errstate(invalid="ignore"):
                    cloud["intensity"] = np.nan_to_num(100.0 / np.linalg.norm(scan.points, axis=-1))
                cloud["ring"] = scan.ring[:, None]
                offsets = np.broadcast_to(scan.column_times[None], cloud.shape)
                if time_field in ("t", "offset_time"):
                    cloud[time_field] = np.round(offsets * 1e9).astype(np.uint32)
                elif time_field == "timestamp":  # absolute seconds (Hesai-like)
                    cloud[time_field] = EPOCH_S + stamp + offsets
                elif time_field == "time":
                    cloud[time_field] = offsets
                message = encode_pointcloud2(typestore, header, cloud, is_dense=False)
            elif topic == IMU_TOPIC:
                motion = path.sample(np.array([t]))
                yaw = motion.yaw[0]
                c, s = np.cos(yaw), np.sin(yaw)
                accel_world = np.array(
                    [motion.acceleration[0, 0], motion.acceleration[0, 1], GRAVITY_M_S2]
                )
                accel_body = np.array(
                    [
                        c * accel_world[0] + s * accel_world[1],
                        -s * accel_world[0] + c * accel_world[1],
                        accel_world[2],
                    ]
                )
                noise = lead_rng if stamp < 0 else rng
                gyro = np.array([0.0, 0.0, motion.yaw_rate[0]]) + noise.normal(0, imu_gyro_std, 3)
                accel_body = accel_body + noise.normal(0, imu_accel_std, 3)
                vec = types["geometry_msgs/msg/Vector3"]
                message = types["sensor_msgs/msg/Imu"](
                    header=header,
                    orientation=types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
                    orientation_covariance=np.array([-1.0] + [0.0] * 8),
                    angular_velocity=vec(x=gyro[0], y=gyro[1], z=gyro[2]),
                    angular_velocity_covariance=zeros9 + np.eye(3).ravel() * imu_gyro_std**2,
                    linear_acceleration=vec(x=accel_body[0], y=accel_body[1], z=accel_body[2]),
                    linear_acceleration_covariance=zeros9 + np.eye(3).ravel() * imu_accel_std**2,
                )
            elif topic == GT_TOPIC:
                motion = path.sample(np.array([t]))
                w, x, y, z = _quat_yaw(motion.yaw[0])
                pose = types["geometry_msgs/msg/Pose"](
                    position=types["geometry_msgs/msg/Point"](
                        x=float(motion.position[0, 0]),
                        y=float(motion.position[0, 1]),
                        z=model.height_m,
                    ),
                    orientation=types["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w),
                )
                if ros1:
                    vec = types["geometry_msgs/msg/Vector3"]
                    speed = float(np.linalg.norm(motion.velocity[0]))
                    twist = types["geometry_msgs/msg/TwistWithCovariance"](
                        twist=types["geometry_msgs/msg/Twist"](
                            linear=vec(x=speed, y=0.0, z=0.0),
                            angular=vec(x=0.0, y=0.0, z=float(motion.yaw_rate[0])),
                        ),
                        covariance=np.zeros(36),
                    )
                    message = types["nav_msgs/msg/Odometry"](
                        header=header,
                        child_frame_id="base_link",
                        pose=types["geometry_msgs/msg/PoseWithCovariance"](
                            pose=pose, covariance=np.zeros(36)
                        ),
                        twist=twist,
                    )
                else:
                    message = types["geometry_msgs/msg/PoseStamped"](header=header, pose=pose)
            elif topic == WHEEL_TOPIC:
                k = int(round(stamp * settings.wheel_odometry_rate_hz))  # stamps are k / rate
                message = _wheel_message(
                    types, header, wheel_xy[k], float(wheel_yaw[k]), model.height_m
                )
            else:  # GPS
                motion = path.sample(np.array([t]))
                lat, lon, alt = enu_to_geodetic(
                    np.array([[motion.position[0, 0], motion.position[0, 1], model.height_m]]),
                    settings.gps_origin,
                )[0]
                status = types["sensor_msgs/msg/NavSatStatus"](status=0, service=1)
                message = types["sensor_msgs/msg/NavSatFix"](
                    header=header,
                    status=status,
                    latitude=float(lat),
                    longitude=float(lon),
                    altitude=float(alt),
                    position_covariance=np.eye(3).ravel() * 1e-4,
                    position_covariance_type=2,
                )
            writer.write(connections[topic], log_ns, serialize(message, message.__msgtype__))
    if not ros1:  # rosbag2 names its storage file after the folder
        for stored in temp.iterdir():
            if stored.name.startswith(temp.name):
                stored.rename(temp / stored.name.replace(temp.name, out.name, 1))
        metadata = temp / "metadata.yaml"
        metadata.write_text(metadata.read_text().replace(temp.name, out.name))
    return world, model


def describe() -> list[str]:
    """Option lines of ``workbench simulate lidar-corridor`` (``--data key=value``)."""
    from datasets.options import describe_model

    return describe_model(LidarBagOptions)
