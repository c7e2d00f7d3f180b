"""Reading ROS 1 ``.bag`` files and ROS 2 bags (sqlite3 or mcap) lazily, in stamp order.

Everything goes through ``rosbags.highlevel.AnyReader`` and its type store and deserializer
(the bag's embedded definitions; ROS 1 Noetic / ROS 2 Humble definitions when a bag has
none). Messages are converted to the workbench vocabulary with their header stamps
(integer nanoseconds -> float seconds, once, here).

Order: a bag is ordered by log time, but a driver logs a cloud when its sweep ends while its
stamp is the sweep start, so stamps are not ordered across topics. A small reorder buffer
(``reorder_window_s``) re-sorts by stamp; a message whose stamp is older than one already
emitted on its topic (stamps going backwards), or older than the buffer can repair, is
skipped and counted in the ``ReadReport`` (never silently reordered beyond the window).

Time base: sensors rarely start together (an IMU driver started before the lidar records
samples before the first sweep). ``topic_spans`` reads each topic's first and last stamp from
the two ends of the bag, ``common_time_base`` intersects them (``TimeBase``), and
``read_stream`` drops, and counts in the ``ReadReport``, every message stamped outside it.

Meaning, not only form: a corrupted bag (flipped words) mostly still decodes, into numbers
that look like any others. The checks that catch what a message can show, each violation
skipped (or, for clouds with a few implausible points, repaired by dropping them) and
counted per topic in the ``ReadReport``, printed as warnings naming the topic and count, and
an ``InputError`` when a topic's skipped and repaired messages exceed
``max_skipped_fraction`` (``check_skips``):
- a message that does not deserialize (``iter_messages``);
- a header stamp that jumps by more than ``STAMP_JUMP_S`` against the bag's record time,
  compared with its topic's first message (so a constant offset between the driver's clock
  and the recorder's is fine);
- PointCloud2 layout, coordinate types, points (``datasets.bags.pointcloud2``);
- IMU samples: non-finite, or |gyro| above ``MAX_GYRO_RAD_S``, |accel| above
  ``MAX_ACCEL_M_S2``;
- ground-truth poses: non-finite, an orientation that is not a unit quaternion (within
  ``UNIT_QUATERNION_TOLERANCE``), a position beyond ``MAX_POSITION_M`` or reached from the
  previous pose faster than ``MAX_TRUTH_SPEED_M_S``;
- GPS fixes: latitude or longitude out of range.
Containers check themselves where they can: rosbags verifies an MCAP chunk's CRC when the
writer stored one (``ros2 bag record`` does; rosbags' own writer stores none), and a
mismatch is an ``InputError``; sqlite3 and ROS 1 bags carry no checksums of messages.
"""

from __future__ import annotations

import heapq
import itertools
from collections import Counter
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from datasets.bags.gps import geodetic_to_enu
from datasets.bags.laserscan import MalformedScan, decode_laserscan
from datasets.bags.pointcloud2 import ABSOLUTE_TIME_S, MalformedCloud, decode_pointcloud2
from datasets.bags.wheel_odometry import PoseSample, pose_sample
from datasets.errors import InputError, did_you_mean
from datasets.laser2d.scan import PlanarScan
from datasets.lidar.kiss_icp_odometry import pose_time
from datasets.lidar.sweep_times import point_times_for, sweep_period
from datasets.measurements import GpsFix, ImuSample, Measurement, PointCloud
from datasets.text_files import check_regular_file
from datasets.trajectory_io import MAX_POSITION_M

POINTCLOUD2 = "sensor_msgs/msg/PointCloud2"
LASERSCAN = "sensor_msgs/msg/LaserScan"
IMU = "sensor_msgs/msg/Imu"
NAVSATFIX = "sensor_msgs/msg/NavSatFix"
ODOMETRY = "nav_msgs/msg/Odometry"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
POSE_WITH_COVARIANCE_STAMPED = "geometry_msgs/msg/PoseWithCovarianceStamped"
GROUND_TRUTH_TYPES = (ODOMETRY, POSE_STAMPED, POSE_WITH_COVARIANCE_STAMPED)
POSE_TYPES = (ODOMETRY, POSE_STAMPED, POSE_WITH_COVARIANCE_STAMPED)
"""Message types with a pose: a wheel-odometry input (``odometry_topic``, differenced:
``datasets.bags.wheel_odometry``) or, when named, the ground truth."""

STAMP_JUMP_S = 10.0
"""How far [s] a header stamp may move against the record (log) time from where its
topic's first message sits: drivers stamp at capture and the recorder logs on receipt, a
fraction of a second later (a sweep later for a cloud); a jump of ten seconds is a corrupted
stamp or one from another clock."""
MAX_GYRO_RAD_S = 70.0
"""|gyro| bound [rad/s]: 4000 deg/s, the full scale of the widest-range MEMS gyros; a
larger rate is no measurement."""
MAX_ACCEL_M_S2 = 400.0
"""|accel| bound [m/s^2]: about 40 g, beyond the 16-32 g full scale of the IMUs vehicles
and handheld rigs carry."""
MAX_TRUTH_SPEED_M_S = 100.0
"""Between two ground-truth poses [m/s]: 360 km/h, faster than anything a lidar bag is
recorded on; a faster step is a corrupted pose."""
UNIT_QUATERNION_TOLERANCE = 0.01
"""A ground-truth orientation whose norm is further than this from 1 is not a rotation a
pose publisher wrote (rounding leaves 1e-7)."""


@dataclass
class ReadReport:
    """What a pass over a bag skipped, and why (mutable: filled while reading).

    Attributes:
        skipped: count per ``(topic, reason)``.
        repaired: messages kept after dropping what was implausible in them (points of a
            cloud), count per ``(topic, reason)``; they count towards
            ``max_skipped_fraction`` as skips do.
        examples: the first skip or repair of each ``(topic, reason)`` as a message naming
            the time.
        nonfinite_points: NaN/inf points dropped from clouds.
        messages: messages read per topic.
        missing: topic -> (messages read, messages its index lists) where fewer were read
            (a damaged bag whose index promises more than its chunks hold).
        trimmed: ``(topic, "before" | "after")`` -> [count, first stamp, last stamp, the
            ``TimeBase`` bound's description]: messages outside the common time base
            (not skips: they do not count towards ``max_skipped_fraction``).
    """

    skipped: Counter = field(default_factory=Counter)
    repaired: Counter = field(default_factory=Counter)
    examples: dict[tuple[str, str], str] = field(default_factory=dict)
    nonfinite_points: int = 0
    messages: Counter = field(default_factory=Counter)
    missing: dict[str, tuple[int, int]] = field(default_factory=dict)
    trimmed: dict[tuple[str, str], list] = field(default_factory=dict)

    def skip(self, topic: str, reason: str, stamp_s: float, detail: str = "") -> None:
        self._count(self.skipped, topic, reason, stamp_s, detail)

    def repair(self, topic: str, reason: str, stamp_s: float, detail: str = "") -> None:
        """Count a message kept after dropping its implausible parts."""
        self._count(self.repaired, topic, reason, stamp_s, detail)

    def _count(
        self, counter: Counter, topic: str, reason: str, stamp_s: float, detail: str
    ) -> None:
        key = (topic, reason)
        counter[key] += 1
        self.examples.setdefault(
            key, f"{topic} at t={stamp_s:.9f}: {reason}{(' (' + detail + ')') if detail else ''}"
        )

    def bad_messages(self, topic: str) -> tuple[int, int]:
        """(skipped, repaired) messages of ``topic``."""

        def of_topic(counter: Counter) -> int:
            return sum(count for (name, _), count in counter.items() if name == topic)

        return of_topic(self.skipped), of_topic(self.repaired)

    def trim(self, topic: str, stamp_s: float, time_base: TimeBase) -> None:
        """Count a message stamped outside ``time_base`` (before its start or after its end)."""
        side = "before" if stamp_s < time_base.start_s else "after"
        entry = self.trimmed.get((topic, side))
        if entry is None:
            bound = (
                f"the start of the common time base t={time_base.start_s:.9f} ({time_base.start_by})"
                if side == "before"
                else f"the end of the common time base t={time_base.end_s:.9f} ({time_base.end_by})"
            )
            self.trimmed[(topic, side)] = [1, stamp_s, stamp_s, bound]
        else:
            entry[0] += 1
            entry[1], entry[2] = min(entry[1], stamp_s), max(entry[2], stamp_s)

    def lines(self) -> list[str]:
        """One line per skip kind: ``N x topic: reason (first at t=...)``, then the
        messages trimmed to the common time base, then topics read short of their index."""
        lines = [
            f"skipped {count} x {self.examples[key]}" for key, count in sorted(self.skipped.items())
        ]
        lines += [
            f"repaired {count} x {self.examples[key]}"
            for key, count in sorted(self.repaired.items())
        ]
        lines += [
            f"trimmed {count} x {topic} at t={first:.9f}..{last:.9f}: {side} {bound}"
            for (topic, side), (count, first, last, bound) in sorted(self.trimmed.items())
        ]
        lines += [
            f"read {read} of the {indexed} messages its index lists on {topic}"
            for topic, (read, indexed) in sorted(self.missing.items())
        ]
        return lines


@dataclass(frozen=True)
class TimeBase:
    """The common interval of the streams a bag source uses: every message stamped before
    ``start_s`` or after ``end_s`` [s] is dropped and counted (``ReadReport.trimmed``).

    Attributes:
        start_s: the latest first stamp of the defining streams.
        end_s: the earliest last stamp of the defining streams.
        start_by: which stream sets the start (for messages), e.g. ``first stamp on /points``.
        end_by: which stream sets the end.
        spans: ``{stream: (first, last)}`` [s] of every defining stream.
        first_cloud_s: when the start is the front end's first pose
            (``start_at_first_pose``), the stamp of that pose's cloud (its sweep's start):
            clouds are kept from it, the other messages from ``start_s``; None otherwise.
    """

    start_s: float
    end_s: float
    start_by: str
    end_by: str
    spans: dict[str, tuple[float, float]]
    first_cloud_s: float | None = None

    def contains(self, stamp_s: float) -> bool:
        return self.start_s <= stamp_s <= self.end_s

    def keeps_cloud(self, stamp_s: float) -> bool:
        """Whether a cloud stamped ``stamp_s`` (its sweep start) is inside."""
        start = self.start_s if self.first_cloud_s is None else self.first_cloud_s
        return start <= stamp_s <= self.end_s

    def as_dict(self) -> dict:
        """JSON-ready, for a sequence's metadata."""
        return {
            "start_s": self.start_s,
            "end_s": self.end_s,
            "start_by": self.start_by,
            "end_by": self.end_by,
            "spans": {name: list(span) for name, span in self.spans.items()},
            "first_cloud_s": self.first_cloud_s,
        }


def common_time_base(path: Path, spans: dict[str, tuple[float, float]]) -> TimeBase | None:
    """``[max of the first stamps, min of the last stamps]`` of ``spans`` (None when empty);
    ``InputError`` naming every span when they do not overlap."""
    if not spans:
        return None
    start_topic = max(spans, key=lambda name: spans[name][0])
    end_topic = min(spans, key=lambda name: spans[name][1])
    start, end = spans[start_topic][0], spans[end_topic][1]
    if start > end:
        listed = "; ".join(f"{name} t={a:.3f}..{b:.3f}" for name, (a, b) in spans.items())
        raise InputError(
            f"{path}: the streams do not overlap in time ({listed}): "
            f"{start_topic} starts after {end_topic} ends"
        )
    return TimeBase(
        start_s=start,
        end_s=end,
        start_by=f"first stamp on {start_topic}",
        end_by=f"last stamp on {end_topic}",
        spans=dict(spans),
    )


@dataclass(frozen=True)
class BagTopics:
    """The topics a bag source reads (None: absent), and the pose topics it does not take as
    truth because none was named (``unnamed_truth``: listed in the run's warnings). Which
    pose topic is the wheel odometry is decided from the messages
    (``datasets.bags.topic_roles``), not here."""

    lidar: str | None
    imu: str | None = None
    ground_truth: str | None = None
    gps: str | None = None
    unnamed_truth: tuple[str, ...] = ()
    laser: str | None = None


def _default_typestore(path: Path):
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS1_NOETIC if path.suffix == ".bag" else Stores.ROS2_HUMBLE)


@contextmanager
def open_bag(path: str | Path):
    """An open ``AnyReader``; ``InputError`` naming the file for anything unreadable."""
    from rosbags.highlevel import AnyReader

    path = Path(path)
    if not path.exists():
        raise InputError(f"{path}: no such bag file or folder")
    if not path.is_dir():
        check_regular_file(path, "bag file")  # a FIFO given as a bag would block the reader
    elif not (path / "metadata.yaml").is_file():
        raise InputError(f"{path}: a ROS 2 bag folder needs its metadata.yaml, found none")
    try:
        reader = AnyReader([path], default_typestore=_default_typestore(path))
        reader.open()
    except InputError:
        raise
    except Exception as error:  # rosbags raises several types for malformed or truncated bags
        # rosbags' YAML errors span several lines: the first says what is wrong
        first = str(error).strip().splitlines()[0] if str(error).strip() else ""
        raise InputError(f"{path}: cannot open bag ({type(error).__name__}: {first})") from None
    try:
        yield reader
    finally:
        try:
            reader.close()
        except Exception:  # closing a reader of a broken file must not hide the real error
            pass


def topic_types(reader) -> dict[str, str]:
    """``{topic: message type}`` of an open reader."""
    return {connection.topic: connection.msgtype for connection in reader.connections}


def _listing(types: dict[str, str]) -> str:
    return (
        "; ".join(f"{topic} [{msgtype}]" for topic, msgtype in sorted(types.items())) or "no topics"
    )


def _option_hint(option: str) -> str:
    """How a user names a topic: ``--data KEY=TOPIC`` (any command), and the flag of
    ``workbench bag`` where it has one (the two-topic error once said ``lidar_topic=TOPIC``,
    which no command takes as written)."""
    flag = {"lidar_topic": "--lidar-topic", "imu_topic": "--imu-topic"}.get(option)
    return f"--data {option}=TOPIC" + (f" (workbench bag: {flag} TOPIC)" if flag else "")


def _choose(
    path: Path,
    types: dict[str, str],
    wanted: tuple[str, ...],
    given: str | None,
    role: str,
    option: str,
    required: bool,
) -> str | None:
    if given:
        if given not in types:
            raise InputError(
                f"{path}: no topic '{given}' ({option}){did_you_mean(given, list(types))}; "
                f"topics: {_listing(types)}"
            )
        if types[given] not in wanted:
            raise InputError(
                f"{path}: topic '{given}' is {types[given]}, not {' or '.join(wanted)} ({option})"
            )
        return given
    candidates = sorted(topic for topic, msgtype in types.items() if msgtype in wanted)
    if not candidates:
        if required:
            raise InputError(
                f"{path}: no {' or '.join(wanted)} topic for the {role}; topics: {_listing(types)}"
            )
        return None
    if len(candidates) > 1:
        listed = ", ".join(f"{topic} [{types[topic]}]" for topic in candidates)
        raise InputError(
            f"{path}: several {role} topics: {listed}; choose one with {_option_hint(option)}"
        )
    return candidates[0]


def discover_topics(
    path: Path,
    types: dict[str, str],
    lidar: str | None = None,
    imu: str | None = None,
    ground_truth: str | None = None,
    gps: str | None = None,
    laser: str | None = None,
) -> BagTopics:
    """Sensor topics by type when not given (``InputError`` with the candidates when
    ambiguous). Every sensor is optional here (a bag of IMU, wheel odometry and GPS has no
    lidar); whether what is found is enough for an estimator is the source's and the
    runner's to say. Ground truth only when named: an Odometry or PoseStamped topic may be
    wheel odometry or another estimator's output (``/odometry/filtered``), and scoring
    against it would print numbers that look like accuracy and are not."""
    truth = None
    if ground_truth:
        truth = _choose(
            path,
            types,
            GROUND_TRUTH_TYPES,
            ground_truth,
            "ground truth",
            "ground_truth_topic",
            False,
        )
    unnamed = tuple(
        sorted(topic for topic, msgtype in types.items() if msgtype in GROUND_TRUTH_TYPES)
    )
    return BagTopics(
        lidar=_choose(path, types, (POINTCLOUD2,), lidar, "lidar", "lidar_topic", False),
        imu=_choose(path, types, (IMU,), imu, "IMU", "imu_topic", False),
        ground_truth=truth,
        gps=_choose(path, types, (NAVSATFIX,), gps, "GPS", "gps_topic", False),
        unnamed_truth=() if truth else unnamed,
        laser=_choose(path, types, (LASERSCAN,), laser, "2-D laser", "laser_topic", False),
    )


def stamp_seconds(message, log_ns: int) -> float:
    """Header stamp [s] (the log time when the message has no header or a zero stamp)."""
    header = getattr(message, "header", None)
    if header is None:
        return log_ns * 1e-9
    stamp = header.stamp
    ns = int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)
    return ns * 1e-9 if ns > 0 else log_ns * 1e-9


def iter_messages(
    reader,
    path: Path,
    topics: list[str],
    start_ns: int | None = None,
    stop_ns: int | None = None,
    wanted: Callable[[str], bool] | None = None,
    report: ReadReport | None = None,
) -> Iterator[tuple[str, str, float, object]]:
    """``(topic, type, stamp [s], message)`` in log order, of log times in
    ``[start_ns, stop_ns)`` when given, and only of topics ``wanted(topic)`` accepts at the
    time (the others are passed over undecoded); rosbags failures -> ``InputError`` naming
    the file, the topic and the time of the last good message.

    With a ``report``, every message read is counted in ``report.messages``, and a message
    that does not deserialize, or whose stamp jumps by more than ``STAMP_JUMP_S`` against
    the record time (module docstring), is skipped and counted there instead of yielded;
    without one, the first is an ``InputError`` and the second is yielded."""
    clock_offsets: dict[str, float] = {}  # stamp - record time of each topic's first message
    connections = [connection for connection in reader.connections if connection.topic in topics]
    if not connections:
        return
    stream = reader.messages(connections=connections, start=start_ns, stop=stop_ns)
    last = "the start"
    while True:
        try:
            item = next(stream)
        except StopIteration:
            return
        except Exception as error:
            raise InputError(
                f"{path}: unreadable after {last} ({type(error).__name__}: {error})"
            ) from None
        connection, log_ns, raw = item
        topic = connection.topic
        if wanted is not None and not wanted(topic):
            continue
        if report is not None:
            report.messages[topic] += 1
        try:
            message = reader.deserialize(raw, connection.msgtype)
        except Exception as error:
            if report is None:
                raise InputError(
                    f"{path}: {topic} at log time {log_ns * 1e-9:.9f}: cannot deserialize {connection.msgtype} ({type(error).__name__}: {error})"
                ) from None
            detail = f"{type(error).__name__}: {error}"
            report.skip(topic, "cannot deserialize the message", log_ns * 1e-9, detail)
            continue
        stamp = stamp_seconds(message, log_ns)
        if report is not None:
            offset = stamp - log_ns * 1e-9
            jump = offset - clock_offsets.setdefault(topic, offset)
            if abs(jump) > STAMP_JUMP_S:
                report.skip(
                    topic,
                    f"header stamp more than {STAMP_JUMP_S:g} s off the record time",
                    log_ns * 1e-9,
                    f"stamp {stamp:.9f}, {jump:+.3g} s against the topic's first message",
                )
                continue
        last = f"{topic} at t={stamp:.9f}"
        yield topic, connection.msgtype, stamp, message


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


@dataclass(frozen=True)
class ReadSettings:
    """How to convert: point time unit, GPS origin and default GPS sigma, reorder window,
    the lidar-to-body extrinsic (``p_body = R p_lidar + t``), if any, and the common time
    base to trim to, if any."""

    time_unit: str = "auto"
    max_point_time_s: float = ABSOLUTE_TIME_S  # points timed further from the stamp dropped
    # point_times=azimuth: the sweep [s] over which clouds without times are timed by azimuth
    azimuth_sweep_s: float | None = None
    lidar_to_body: np.ndarray | None = None  # (4, 4) extrinsic applied to every cloud
    gps_origin: tuple[float, float, float] | None = None
    gps_sigma_m: float = 1.0
    reorder_window_s: float = 1.0
    max_missing_fraction: float = 0.01
    max_skipped_fraction: float = 0.05
    time_base: TimeBase | None = None  # messages stamped outside it are trimmed and counted
    laser_mounting: np.ndarray | None = None  # (3,) 2-D laser in the body frame: x, y, theta


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


def read_ground_truth(
    path: Path, topic: str, report: ReadReport
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All poses of a ground-truth topic: t (N,), positions (N, 3), quaternions wxyz (N, 4),
    stamp-ordered; backwards, non-finite or implausible poses (module docstring) skipped and
    counted."""
    times, positions, quats = [], [], []
    with open_bag(path) as reader:
        for _, msgtype, stamp, message in iter_messages(reader, path, [topic], report=report):
            position, quat = pose_of(message, msgtype)
            with np.errstate(over="ignore"):  # a corrupted 1e300 overflows to inf: skipped
                norm = np.linalg.norm(quat)
            if not (np.all(np.isfinite(position)) and np.isfinite(norm) and norm > 1e-9):
                report.skip(topic, "non-finite pose", stamp)
                continue
            if times and stamp <= times[-1]:
                report.skip(topic, "stamp not after the previous one", stamp)
                continue
            if abs(norm - 1.0) > UNIT_QUATERNION_TOLERANCE:
                report.skip(topic, "orientation not a unit quaternion", stamp, f"norm {norm:.6g}")
                continue
            if np.max(np.abs(position)) > MAX_POSITION_M:
                report.skip(topic, f"position beyond {MAX_POSITION_M:g} m", stamp)
                continue
            with np.errstate(over="ignore"):
                step_m = float(np.linalg.norm(position - positions[-1])) if times else 0.0
            if times and step_m > MAX_TRUTH_SPEED_M_S * (stamp - times[-1]):
                report.skip(
                    topic,
                    f"pose jumps faster than {MAX_TRUTH_SPEED_M_S:g} m/s",
                    stamp,
                    f"{step_m:.3g} m in {stamp - times[-1]:.3g} s",
                )
                continue
            times.append(stamp)
            positions.append(position)
            quats.append(quat / norm)
    return np.array(times), np.array(positions).reshape(-1, 3), np.array(quats).reshape(-1, 4)


def read_stream(
    path: Path, topics: list[str], settings: ReadSettings, report: ReadReport
) -> Iterator[tuple[str, Measurement]]:
    """``(topic, measurement)`` of the given topics, lazily, in stamp order (module docstring)."""
    heap: list[tuple[float, int, str, Measurement]] = []
    counter = itertools.count()
    last_on_topic: dict[str, float] = {}
    emitted = -np.inf
    with open_bag(path) as reader:
        for topic, msgtype, stamp, message in iter_messages(reader, path, topics, report=report):
            if stamp <= last_on_topic.get(topic, -np.inf):
                report.skip(
                    topic,
                    "stamp went backwards (or repeated)",
                    stamp,
                    f"previous {last_on_topic[topic]:.9f}",
                )
                continue
            if stamp < emitted:
                report.skip(
                    topic, "stamp older than the reorder window", stamp, f"already at {emitted:.9f}"
                )
                continue
            base = settings.time_base
            if base is not None and msgtype == POINTCLOUD2:
                outside = not base.keeps_cloud(stamp)
            else:
                outside = base is not None and not base.contains(stamp)
            if outside and msgtype == POINTCLOUD2:  # trimmed undecoded: decoding is the cost
                last_on_topic[topic] = stamp
                report.trim(topic, stamp, settings.time_base)
                continue
            # other messages are checked first, so a NaN IMU sample counts as a skip wherever
            measurement = convert(path, topic, msgtype, stamp, message, settings, report)
            last_on_topic[topic] = stamp
            if measurement is None:
                continue
            if outside:
                report.trim(topic, stamp, settings.time_base)
                continue
            heapq.heappush(heap, (stamp, next(counter), topic, measurement))
            while heap and heap[0][0] < stamp - settings.reorder_window_s:
                emitted, _, out_topic, out = heapq.heappop(heap)
                yield out_topic, out
        while heap:
            emitted, _, out_topic, out = heapq.heappop(heap)
            yield out_topic, out
        _check_counts(path, reader, topics, settings, report)
    check_skips(path, topics, settings.max_skipped_fraction, report)


def lidar_sweep_period(reader, path: Path, topic: str, frames: int = 21) -> float:
    """One sweep of ``topic`` [s] for ``point_times=azimuth``: the median interval of the
    header stamps of its first ``frames`` messages (``InputError`` when they give none)."""
    stamps = []
    for _, _, stamp, _ in iter_messages(reader, path, [topic], report=ReadReport()):
        stamps.append(stamp)
        if len(stamps) >= frames:
            break
    return sweep_period(np.array(stamps), f"{path}, topic {topic}")


POINT_TIME_SWEEPS = 1.5
"""Per-point times further from their cloud's stamp than this many sweeps are dropped: a
sweep's points lie within one sweep of its stamp (before or after it, as drivers stamp its
start or its end); half a sweep more leaves room for a driver's jitter."""


def max_point_time(reader, path: Path, topic: str) -> float:
    """How far from its stamp [s] a point of ``topic`` may be timed: ``POINT_TIME_SWEEPS``
    sweeps (``lidar_sweep_period``), at most ``ABSOLUTE_TIME_S``; ``ABSOLUTE_TIME_S`` when
    the topic gives no sweep (a single cloud)."""
    try:
        return min(POINT_TIME_SWEEPS * lidar_sweep_period(reader, path, topic), ABSOLUTE_TIME_S)
    except InputError:
        return ABSOLUTE_TIME_S


def topic_spans(
    reader,
    path: Path,
    topics: list[str],
    time_unit: str = "auto",
    azimuth_sweep_s: float | None = None,
    max_point_time_s: float = ABSOLUTE_TIME_S,
) -> dict[str, tuple[float, float]]:
    """``{topic: (first, last)}`` header stamps [s] of each topic that has messages, read
    from the two ends of the bag only: the first message of each topic in log order (what
    ``read_stream`` accepts first: a later one stamped earlier is skipped as going
    backwards), and the largest stamp among the messages logged in a last window (1 s,
    doubled until every topic has a message in it). A lidar topic's span ends where its
    last sweep ends: the last cloud's stamp plus its largest per-point time (where the
    deskewing front end stamps that frame's odometry and corners), so the IMU samples that
    sweep needs are kept.

    A message the stream will skip (an empty cloud, a NaN IMU sample) still counts here:
    that can only widen a span, never put a kept stamp before the common start."""
    counts = {
        topic: int(reader.topics[topic].msgcount) for topic in topics if topic in reader.topics
    }
    present = [topic for topic, count in counts.items() if count > 0]
    if not present:
        return {}
    first: dict[str, float] = {}
    # broken messages are passed over here (a throwaway report): the stream counts them
    for topic, _, stamp, _ in iter_messages(
        reader, path, present, wanted=lambda topic: topic not in first, report=ReadReport()
    ):
        first[topic] = stamp
        if len(first) == len(present):
            break
    end_ns, begin_ns = int(reader.end_time), int(reader.start_time)
    window_ns = 1_000_000_000
    while True:
        start_ns = max(begin_ns, end_ns - window_ns)
        last: dict[str, tuple[float, object, str]] = {}
        for topic, msgtype, stamp, message in iter_messages(
            reader, path, present, start_ns, report=ReadReport()
        ):
            if topic not in last or stamp > last[topic][0]:
                last[topic] = (stamp, message, msgtype)
        if len(last) == len(present) or start_ns <= begin_ns:
            break
        window_ns *= 2
    spans = {}
    for topic in present:
        if topic not in first or topic not in last:
            continue
        stamp, message, msgtype = last[topic]
        if msgtype == POINTCLOUD2:
            where = f"{path}, topic {topic}, t={stamp:.9f}"
            try:
                cloud = decode_pointcloud2(message, stamp, where, time_unit, max_point_time_s)
                times = point_times_for(cloud.points, cloud.point_times, azimuth_sweep_s, where)
            except InputError:  # the stream reports a broken cloud where it meets it
                times = None
            if times is not None and times.size:
                stamp += float(np.max(times))
        spans[topic] = (first[topic], stamp)
    return spans


def start_at_first_pose(
    reader,
    path: Path,
    time_base: TimeBase,
    lidar_topic: str,
    time_unit: str = "auto",
    deskew: bool = True,
    azimuth_sweep_s: float | None = None,
    max_point_time_s: float = ABSOLUTE_TIME_S,
) -> TimeBase:
    """``time_base`` starting at the front end's first pose: where the first kept sweep ends
    when it is deskewed (``datasets.lidar.kiss_icp_odometry``: a frame's pose is at its
    latest point), else at the sweep's stamp. The first kept sweep is the first decodable,
    non-empty cloud stamped at or after the common start.

    Lidar odometry says nothing about the motion before that pose, so an initial state
    earlier than it hands the estimators a pose that far before their first odometry
    increment starts: on the synthetic corridor bag (1.5 m/s, 0.1 s sweeps) every
    odometry-driven estimator carried a 0.15 m forward offset from the first step on
    (ekf-slam's pose NEES about 11 per dof throughout) while the start was the sweep's
    stamp. Without deskewing (or clouds without per-point times) the start is the first
    kept cloud's stamp, which is later than the common start when another stream sets
    that start or the first clouds are empty."""
    passed_over: dict[str, list] = {}  # why clouds gave no pose: [count, the first's detail]
    for topic, msgtype, stamp, message in iter_messages(
        reader, path, [lidar_topic], report=ReadReport()
    ):
        if msgtype != POINTCLOUD2 or stamp < time_base.start_s:
            continue
        where = f"{path}, topic {topic}, t={stamp:.9f}"
        try:
            cloud = decode_pointcloud2(message, stamp, where, time_unit, max_point_time_s)
        except MalformedCloud as error:  # the stream counts a broken cloud where it meets it
            passed_over.setdefault("malformed", [0, error.problem])[0] += 1
            continue
        if not len(cloud.points):
            detail = "; ".join(cloud.problems) or "no finite point"
            passed_over.setdefault("without a plausible point", [0, detail])[0] += 1
            continue
        times = point_times_for(cloud.points, cloud.point_times, azimuth_sweep_s, where)
        end = pose_time(stamp, times, deskew)
        if end == time_base.start_s and stamp == time_base.start_s:
            return time_base
        if end > time_base.end_s:
            break
        where = "end of the first sweep" if end > stamp else "first kept cloud"
        return TimeBase(
            start_s=end,
            end_s=time_base.end_s,
            start_by=f"{where} on {lidar_topic}, the first lidar pose",
            end_by=time_base.end_by,
            spans=time_base.spans,
            first_cloud_s=stamp,
        )
    why = "; ".join(
        f"{count} {reason}, the first: {detail}" for reason, (count, detail) in passed_over.items()
    )
    raise InputError(
        f"{path}: no cloud on {lidar_topic} sweeps inside the common time base "
        f"t={time_base.start_s:.9f}..{time_base.end_s:.9f}" + (f" ({why})" if why else "")
    )


def check_skips(path: Path, topics: list[str], max_fraction: float, report: ReadReport) -> None:
    """``InputError`` when more than ``max_fraction`` of a topic's messages were skipped or
    repaired (NaN IMU samples, non-finite poses, empty clouds, implausible values, ...): a
    few are counted warnings, most of a topic is a broken recording, not a quirk."""
    for topic in topics:
        skipped, repaired = report.bad_messages(topic)
        read = int(report.messages[topic])
        if skipped + repaired > max_fraction * read:
            what = " or ".join(
                word for word, count in (("skipped", skipped), ("repaired", repaired)) if count
            )
            keys = sorted(key for key in {*report.skipped, *report.repaired} if key[0] == topic)
            raise InputError(
                f"{path}: {skipped + repaired} of the {read} messages on {topic} {what} "
                f"(first: {report.examples[keys[0]]}); "
                f"more than max_skipped_fraction={max_fraction} (raise it to accept)"
            )


def _check_counts(path: Path, reader, topics: list[str], settings: ReadSettings, report) -> None:
    """Messages read per topic against the bag's index, once the whole bag was read: fewer
    is a warning line in ``report``, and an ``InputError`` beyond
    ``settings.max_missing_fraction`` (the reader silently skips what a damaged chunk held:
    a mcap bag with 64 KiB zeroed read 78 of its 80 clouds)."""
    for topic in topics:
        connection = reader.topics.get(topic)
        indexed = int(connection.msgcount) if connection is not None else 0
        read = int(report.messages[topic])
        if read >= indexed:
            continue
        report.missing[topic] = (read, indexed)
        if indexed - read > settings.max_missing_fraction * indexed:
            raise InputError(
                f"{path}: read {read} of the {indexed} messages its index lists on {topic} "
                f"(damaged bag?); more than max_missing_fraction={settings.max_missing_fraction}"
                " (raise it to accept)"
            )
