"""What the bag loaders read from a topic's first messages before its stream runs: the IMU's
rate and continuous-time noise densities from its first message's covariances
(``imu_rate_and_noise``), and how a lidar topic's clouds are timed, decided from its first
clouds (``bag_sweep_timing``). Broken messages are passed over here (throwaway
``ReadReport``s): the stream counts them where it meets them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from datasets.bags.bag_file import iter_messages
from datasets.bags.bag_options import BagOptions
from datasets.bags.convert import MAX_ACCEL_M_S2, MAX_GYRO_RAD_S
from datasets.bags.message_types import POINTCLOUD2
from datasets.bags.pointcloud2 import MalformedCloud, decode_pointcloud2
from datasets.bags.read_report import ReadReport
from datasets.bags.spans import lidar_sweep_period
from datasets.errors import InputError
from datasets.lidar.sweep_timing import SweepTimingDecision, decide_sweep_timing
from datasets.measurements import PointCloud


def imu_rate_and_noise(
    reader, topic: str | None, path: Path
) -> tuple[float | None, float | None, float | None]:
    """IMU rate and continuous-time noise densities from the first message's covariances
    (a discrete std sigma at rate f is a density sigma / sqrt(f)); None where unknown."""
    if topic is None:
        return None, None, None
    info = reader.topics[topic]
    duration = (reader.end_time - reader.start_time) * 1e-9
    rate = info.msgcount / duration if duration > 0 and info.msgcount > 1 else None
    # a message that does not decode is passed over here: the stream counts it
    for _, _, _, message in iter_messages(reader, path, [topic], report=ReadReport()):
        gyro_var = float(np.asarray(message.angular_velocity_covariance)[0])
        accel_var = float(np.asarray(message.linear_acceleration_covariance)[0])
        if rate is None:
            return None, None, None
        # used only when positive and below the square of the largest plausible reading: a
        # corrupted first message would otherwise set every estimator's noise
        gyro = np.sqrt(gyro_var / rate) if 0 < gyro_var <= MAX_GYRO_RAD_S**2 else None
        accel = np.sqrt(accel_var / rate) if 0 < accel_var <= MAX_ACCEL_M_S2**2 else None
        return rate, gyro, accel
    return rate, None, None


def bag_sweep_timing(
    reader, path: Path, topic: str, settings: BagOptions, max_point_time_s: float
) -> SweepTimingDecision:
    """How the clouds of ``topic`` are timed (``datasets.lidar.sweep_timing``), from its
    first ``settings.sweep.frames`` decodable, non-empty clouds in stamp order, in the lidar
    frame (before ``lidar_to_body``: azimuths are the lidar's). One sweep is the topic's
    median frame interval (``lidar_sweep_period``); none is read for ``point_times=field``.
    ``InputError`` (from ``lidar_sweep_period``) where azimuth times need a period and the
    topic gives none."""
    if settings.point_times == "field":
        return decide_sweep_timing([], 0.0, "field", settings.sweep)
    try:
        sweep_s = lidar_sweep_period(reader, path, topic)
    except InputError:
        if settings.point_times == "azimuth":
            raise
        sweep_s = 0.0  # a single cloud: nothing to compare, the decision says so
    clouds: dict[float, PointCloud] = {}
    # broken clouds are passed over here (a throwaway report): the stream counts them
    for _, msgtype, stamp, message in iter_messages(reader, path, [topic], report=ReadReport()):
        if msgtype != POINTCLOUD2 or stamp in clouds:
            continue
        where = f"{path}, topic {topic}, t={stamp:.9f}"
        try:
            cloud = decode_pointcloud2(
                message, stamp, where, settings.point_time_unit, max_point_time_s
            )
        except MalformedCloud:
            continue
        if len(cloud.points):
            clouds[stamp] = PointCloud(t=stamp, points=cloud.points, point_times=cloud.point_times)
        if len(clouds) >= settings.sweep.frames:
            break
    ordered = [clouds[stamp] for stamp in sorted(clouds)]
    return decide_sweep_timing(ordered, sweep_s, settings.point_times, settings.sweep)
