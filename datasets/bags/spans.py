"""What a bag's stamps say before its stream is read: each topic's first and last stamp
(``topic_spans``, which ``datasets.bags.time_base.common_time_base`` intersects), the front
end's first pose as the start of the time base (``start_at_first_pose``), and a lidar
topic's sweep period (``lidar_sweep_period``) with how far from its stamp a point may be
timed (``max_point_time``). Broken messages are passed over here (throwaway
``ReadReport``s): the stream counts them where it meets them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from datasets.bags.bag_file import iter_messages
from datasets.bags.message_types import POINTCLOUD2
from datasets.bags.pointcloud2 import ABSOLUTE_TIME_S, MalformedCloud, decode_pointcloud2
from datasets.bags.read_report import ReadReport
from datasets.bags.time_base import TimeBase
from datasets.errors import InputError
from datasets.lidar.kiss_icp_odometry import pose_time
from datasets.lidar.sweep_times import point_times_for, sweep_period


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
