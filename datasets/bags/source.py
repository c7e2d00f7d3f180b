"""Dataset ``bag:PATH``: a ROS 1/ROS 2 bag as a ``Sequence`` with the lidar front end.

Sensors: POINT_CLOUD (the clouds), IMU when the bag has an Imu topic, GPS when it has a
NavSatFix topic (local ENU about the first fix, ``datasets.bags.gps``), ODOMETRY (KISS-ICP
relative poses) and LANDMARKS (corners) from the front end. Ground truth: the poses of the
Odometry/PoseStamped topic named by ``ground_truth_topic`` (never one found by type: it may
be wheel odometry), and the true corners when a sidecar ``NAME.corners.json`` (written by
``workbench simulate lidar-corridor``) lies next to the bag, only with those poses (the
corners are in the truth topic's world frame).

Frames: the body frame is the IMU's; clouds are moved into it with the ``lidar_to_body``
option (identity by default: lidar = body). KISS-ICP then tracks the body frame and corners
are body-frame positions, as the estimators expect.

One time base: the streams are trimmed to their common interval, so nothing fails because
one sensor starts earlier (an IMU driver started before the lidar, a truth topic that
begins late). The interval runs from the latest first stamp to the earliest last stamp of
the streams the sequence is built from: the lidar (its last sweep counted to its end), the
IMU when used, and the ground-truth topic when named (``datasets.bags.spans.topic_spans``,
``common_time_base``). GPS fixes outside it are dropped too, but a sparse GPS topic does not
narrow it; topics not read (wheel odometry, an unnamed pose topic) play no part. Every
dropped message is counted in the pass's warnings (``Sequence.pass_report``: ``trimmed N x
TOPIC at t=..: before the start of the common time base t=.. (first stamp on /points)``,
once the stream has run); the interval and each stream's span are ``metadata["time_base"]``;
the initial state is at the interval's start. With lidar odometry the interval starts at the front end's
first pose (``start_at_first_pose``): where the first kept sweep ends when it is deskewed,
else at that cloud's stamp. The estimators' first odometry increment starts there, and a
deskewed first sweep is read but not emitted. The front end's odometry and corners of the
last kept cloud are stamped at its sweep end, which the lidar's span includes.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from datasets.bags.bag_file import open_bag
from datasets.bags.bag_options import BagOptions, extrinsic_matrix
from datasets.bags.convert import first_gps_origin
from datasets.bags.first_messages import bag_sweep_timing, imu_rate_and_noise
from datasets.bags.ground_truth import (
    ground_truth_from_topic,
    initial_state_from_truth,
    read_ground_truth,
)
from datasets.bags.message_types import ODOMETRY
from datasets.bags.read_report import ReadReport, ReadSettings, check_skips
from datasets.bags.reader import read_stream
from datasets.bags.sequence_sources import LidarSource
from datasets.bags.spans import max_point_time, start_at_first_pose, topic_spans
from datasets.bags.time_base import common_time_base
from datasets.bags.topic_roles import OdometryRole, choose_odometry, not_wheel_words
from datasets.bags.topics import BagTopics, SensorTopics, discover_topics, topic_types
from datasets.bags.wheel_odometry import WheelIncrements
from datasets.errors import InputError
from datasets.lidar.corner_truth import read_corner_truth, sidecar_for, with_true_corner_ids
from datasets.lidar.frontend import LidarFrontEnd
from datasets.lidar.frontend_stream import with_front_end
from datasets.measurements import Sensor
from datasets.options import build_model, nest_dotted
from datasets.pass_report import PassReport
from datasets.sequence import NoiseSpec, Sequence


def load_bag(argument: str | None, seed: int, options: dict[str, str]) -> Sequence:
    """``bag:PATH`` -> ``Sequence`` (module docstring). ``seed`` is unused (nothing random)."""
    if not argument:
        raise InputError("dataset bag needs a path: bag:PATH")
    settings = build_model(BagOptions, nest_dotted(options), f"bag:{argument}")
    sequence, source = bag_sequence(argument, settings)
    # a simulator's bag with its truth named: the true id of every corner, so that maps and
    # association are scored (datasets.lidar.corner_truth.with_true_corner_ids)
    return with_true_corner_ids(sequence, source.front_end)


def bag_sequence(argument: str, settings: BagOptions) -> tuple[Sequence, LidarSource]:
    """The sequence of bag ``argument`` and its ``LidarSource`` (front end and skip report)."""
    path = Path(argument)
    gps_note = None
    with open_bag(path) as reader:
        types = topic_types(reader)
        topics = discover_topics(
            path,
            types,
            settings.lidar_topic,
            settings.imu_topic,
            settings.ground_truth_topic,
            settings.gps_topic,
            None if settings.laser_topic == "none" else settings.laser_topic,
        )
        if topics.lidar is None:  # IMU, wheel odometry, GPS, 2-D laser (sensor_source)
            from datasets.bags.sensor_source import sensor_sequence

            return sensor_sequence(argument, path, settings, topics, reader)
        decisions, wheel = _other_inputs(reader, path, types, topics, settings)
        imu_topic = topics.imu if settings.imu else None
        gps_topic = topics.gps if settings.gps else None
        origin = first_gps_origin(reader, path, gps_topic) if gps_topic else None
        if gps_topic and origin is None:
            gps_note = f"{gps_topic} has no valid fix; GPS not used"
            gps_topic = None
        start_s = reader.start_time * 1e-9
        rates = {
            "lidar": float(
                reader.topics[topics.lidar].msgcount
                / max((reader.end_time - reader.start_time) * 1e-9, 1e-9)
            )
        }
        imu_rate, gyro_density, accel_density = imu_rate_and_noise(reader, imu_topic, path)
        if imu_rate:
            rates["imu"] = float(imu_rate)
        max_point_time_s = max_point_time(reader, path, topics.lidar)
        # per-point times: the clouds' own, or from azimuth where the sweeps are raw
        # (datasets.lidar.sweep_timing, decided from the first clouds unless stated)
        timing = bag_sweep_timing(reader, path, topics.lidar, settings, max_point_time_s)
        azimuth_sweep_s = timing.azimuth  # an AzimuthSweep (a float: one sweep [s]) or None
        spans = topic_spans(
            reader,
            path,
            [t for t in (topics.lidar, imu_topic) if t],
            settings.point_time_unit,
            azimuth_sweep_s,
            max_point_time_s,
        )
        lidar_messages = int(reader.topics[topics.lidar].msgcount)
        load_report = ReadReport()
        gt = (
            read_ground_truth(path, topics.ground_truth, load_report, reader)
            if topics.ground_truth
            else (np.zeros(0), np.zeros((0, 3)), np.zeros((0, 4)))
        )
        if topics.ground_truth:
            check_skips(path, [topics.ground_truth], settings.max_skipped_fraction, load_report)
            if len(gt[0]) < 2:
                raise InputError(
                    f"{path}: ground-truth topic {topics.ground_truth} has {len(gt[0])} "
                    "usable poses"
                )
            spans[topics.ground_truth] = (float(gt[0][0]), float(gt[0][-1]))
        time_base = common_time_base(path, spans)  # module docstring: one time base
        if time_base is not None and settings.odometry:
            time_base = start_at_first_pose(
                reader,
                path,
                time_base,
                topics.lidar,
                settings.point_time_unit,
                deskew=settings.kiss.deskew,
                azimuth_sweep_s=azimuth_sweep_s,
                max_point_time_s=max_point_time_s,
            )
    sidecar = sidecar_for(path)
    truth = read_corner_truth(sidecar) if sidecar.is_file() else None
    truth_warnings: list[str] = []
    ground_truth = ground_truth_from_topic(*gt, truth, topics.ground_truth, truth_warnings)
    read_settings = ReadSettings(
        time_unit=settings.point_time_unit,
        max_point_time_s=max_point_time_s,
        azimuth_sweep_s=azimuth_sweep_s,
        gps_origin=origin,
        gps_sigma_m=settings.gps_sigma_m,
        reorder_window_s=settings.reorder_window_s,
        lidar_to_body=extrinsic_matrix(settings.lidar_to_body),
        max_missing_fraction=settings.max_missing_fraction,
        max_skipped_fraction=settings.max_skipped_fraction,
        time_base=time_base,
    )
    front_end = LidarFrontEnd(
        settings.front_end_settings().model_copy(
            update={"imu_deskew": settings.imu_deskew and imu_topic is not None}
        ),
        # with an IMU the estimators may move by it instead of the front end's increments
        sole_motion_input=imu_topic is None,
    )
    source = LidarSource(front_end, lidar_messages)
    topic_list = [topic for topic in (topics.lidar, imu_topic, gps_topic, wheel.topic) if topic]

    # filled once the stream has run: the KISS-ICP settings used, the corner_tracking
    # figures, and the pass's warnings
    pass_report = PassReport.expecting("kiss_icp", "corner_reobservation")
    # Sequence.warnings: printed by the workbench (prefixed with the dataset's name) and
    # written to every run's metrics.json
    warnings = (
        list(timing.warnings)
        + list(load_report.lines())
        + ([gps_note] if gps_note else [])
        + truth_warnings
    )
    if topics.unnamed_truth:
        warnings.append(
            f"no ground truth: pose topic(s) {', '.join(topics.unnamed_truth)} not taken "
            "as truth unless named (--data ground_truth_topic=TOPIC, workbench bag --truth-topic)"
        )

    def stream():
        report = ReadReport()
        source.report = report
        measurements = (m for _, m in read_stream(path, topic_list, read_settings, report))
        if wheel.topic is not None:  # wheel odometry where the front end gives none
            measurements = wheel_increments(measurements, wheel, settings, time_base)
        yield from with_front_end(
            measurements,
            front_end,
            settings.point_clouds,
            settings.max_frames,
            emit_from_s=time_base.start_s if time_base else None,
        )
        pass_report.record(
            source.pass_warnings(),
            kiss_icp=front_end.resolved(),
            corner_reobservation=front_end.tracker.stats.summary(),
        )

    sensors = {Sensor.POINT_CLOUD} if settings.point_clouds else set()
    sensors |= {Sensor.IMU} if imu_topic else set()
    sensors |= {Sensor.GPS} if gps_topic else set()
    sensors |= {Sensor.ODOMETRY} if settings.odometry or wheel.topic else set()
    sensors |= {Sensor.LANDMARKS} if settings.corners else set()
    noise = NoiseSpec(
        gyro_noise_density=settings.gyro_noise_density
        or (float(gyro_density) if gyro_density else 1.7e-4)
        if imu_topic
        else None,
        accel_noise_density=settings.accel_noise_density
        or (float(accel_density) if accel_density else 2e-3)
        if imu_topic
        else None,
        gyro_bias_walk=settings.gyro_bias_walk if imu_topic else None,
        accel_bias_walk=settings.accel_bias_walk if imu_topic else None,
        gyro_bias_sigma_rad_s=settings.gyro_bias_sigma_rad_s if imu_topic else None,
        accel_bias_sigma_m_s2=settings.accel_bias_sigma_m_s2 if imu_topic else None,
        landmark_sigma_m=settings.corner.range_sigma_m,
        gps_sigma_m=settings.gps_sigma_m if gps_topic else None,
        rate_hz=rates,
    )
    return Sequence(
        name=f"bag:{argument}",
        dimension=3,
        sensors=frozenset(sensors),
        stream=stream,
        ground_truth=ground_truth,
        noise=noise,
        initial_state=initial_state_from_truth(
            time_base.start_s if time_base else start_s,
            ground_truth.pose if ground_truth else None,
        ),
        # the front end's trajectory, increment covariances and counters, filled by the pass
        front_end=front_end.report if settings.odometry else None,
        metadata={
            "source": str(path),
            # the common interval every stream is trimmed to (module docstring)
            "time_base": time_base.as_dict() if time_base else None,
            "gps_origin": list(origin) if origin else None,
            "options": settings.model_dump(mode="json"),
            "sweep_timing": timing.as_dict(),
        },
        reference_source=f"topic {topics.ground_truth}" if topics.ground_truth else None,
        warnings=tuple(warnings),
        # what the loader decided and why, to print as notes (a clear decision) beside
        # the warnings (datasets.lidar.sweep_timing)
        decisions=tuple(([timing.text] if timing.clear else []) + decisions),
        topics=SensorTopics(
            lidar=topics.lidar,
            imu=imu_topic,
            ground_truth=topics.ground_truth,
            gps=gps_topic,
            odometry=wheel.topic,
        ),
        corner_sidecar=sidecar if truth is not None else None,
        pass_report=pass_report,
    ), source


def _other_inputs(
    reader, path: Path, types: dict[str, str], topics: BagTopics, settings: BagOptions
) -> tuple[list[str], OdometryRole]:
    """Beside a lidar: the decision lines on the bag's 2-D laser and pose topics, and the
    wheel odometry to use (only where the front end gives no odometry, ``odometry=false``:
    one odometry input per sequence)."""
    decisions = []
    if topics.laser:
        decisions.append(
            f"2-D laser {topics.laser} not used: the lidar {topics.lidar} is the bag's range sensor"
        )
    if settings.odometry or not settings.wheel_odometry:
        listed = [
            topic
            for topic, msgtype in sorted(types.items())
            # a topic named as truth or an estimate would never be the wheel odometry
            if msgtype == ODOMETRY and topic != topics.ground_truth and not not_wheel_words(topic)
        ]
        if listed:
            why = (
                "the lidar front end's (KISS-ICP) is the odometry input"
                if settings.odometry
                else "wheel_odometry=false"
            )
            decisions.append(
                f"odometry: {', '.join(listed)} not used as input ({why}; --data "
                "odometry=false uses wheel odometry instead)"
            )
        return decisions, OdometryRole(None, None, "")
    role = choose_odometry(reader, path, types, settings.odometry_topic, topics.ground_truth)
    if role.text:
        decisions.append(role.text)
    if role.topic is not None:
        _, text = role.noise(settings.odometry_noise)
        decisions.append(f"odometry noise: {text}")
    return decisions, role


def wheel_increments(measurements, wheel: OdometryRole, settings: BagOptions, time_base):
    """``measurements`` with the wheel odometry's ``PoseSample`` turned into ``Odometry``
    increments (``datasets.bags.wheel_odometry``)."""
    noise, _ = wheel.noise(settings.odometry_noise)
    increments = WheelIncrements(
        noise,
        from_twist=wheel.from_twist,
        max_rate_hz=settings.odometry_max_rate_hz,
        start_s=time_base.start_s if time_base else None,
    )
    yield from increments.convert(measurements)
