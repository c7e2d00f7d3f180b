"""Which topics of a bag are read: ``topic_types`` lists an open bag's topics with their
message types, ``discover_topics`` picks each sensor's topic by type where none is named
(``BagTopics``), and a named topic that is missing or of another type, or several candidates
for one sensor, is an ``InputError`` naming the topics and how a user chooses one
(``--data KEY=TOPIC``). Which pose topic is the wheel odometry is decided from the messages
(``datasets.bags.topic_roles``), not here.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path

from datasets.bags.message_types import (
    GROUND_TRUTH_TYPES,
    IMU,
    LASERSCAN,
    NAVSATFIX,
    POINTCLOUD2,
)
from datasets.errors import InputError, did_you_mean


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


@dataclass(frozen=True)
class SensorTopics:
    """The topic a bag's sequence reads in each role (``Sequence.topics``), None where it
    reads none: a topic the bag has but the sequence does not use (``imu=false``, GPS
    without a valid fix, the IMU of a 2-D laser sequence) is None too.

    Attributes:
        lidar: the PointCloud2 topic of the front end.
        imu: the Imu topic.
        ground_truth: the named truth topic (Odometry or PoseStamped).
        gps: the NavSatFix topic.
        odometry: the wheel odometry the increments are made from (``topic_roles``).
        laser: the LaserScan topic of a 2-D laser sequence.
    """

    lidar: str | None = None
    imu: str | None = None
    ground_truth: str | None = None
    gps: str | None = None
    odometry: str | None = None
    laser: str | None = None

    def as_dict(self) -> dict[str, str | None]:
        """``{role: topic}`` in the order above (printed and written in this order)."""
        return asdict(self)


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
