"""``bag:PATH`` without a lidar: IMU, wheel odometry, GPS and 2-D laser in any combination.

``datasets.bags.source.bag_sequence`` hands a bag without a PointCloud2 topic here. What the
sequence holds is decided from the bag and printed (``Sequence.decisions``, shown by
``workbench run`` as ``note:`` and by ``workbench bag`` as ``front end:``):

- **3-D** (the default): ``ImuSample`` from the Imu topic, ``GpsFix`` from the NavSatFix
  topic (local ENU about the first fix, ``datasets.bags.gps``) and ``Odometry`` increments
  from the wheel odometry (``datasets.bags.topic_roles`` decides which pose topic that is;
  ``datasets.bags.wheel_odometry`` makes the increments and their covariance). Sensors:
  IMU, GPS, ODOMETRY, whichever the bag has.
- **2-D laser** (a ``LaserScan`` topic and wheel odometry): a planar sequence with the CARMEN
  loader's shape, odometry at each scan and the scan's corners
  (``datasets.bags.planar_sequence``). The IMU and GPS are not used (said in the decisions;
  ``--data laser_topic=none`` gives the 3-D sequence instead). A LaserScan topic without
  wheel odometry is not used: the front end needs the motion between scans.

World frame and start (``initial_state``, at the start of the common time base): with GPS,
ENU about the first fix, else the truth topic's frame when named, else the first body frame
(``datasets.bags.sensor_start``).

Time base: the common interval of the IMU, the wheel odometry, the 2-D laser and the named
truth (``datasets.bags.time_base.common_time_base``); GPS fixes outside it are dropped and
counted, as for lidar bags.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np

from datasets.bags.bag_file import iter_messages
from datasets.bags.convert import first_gps_origin
from datasets.bags.first_messages import imu_rate_and_noise
from datasets.bags.ground_truth import ground_truth_from_topic, read_ground_truth
from datasets.bags.planar_sequence import planar_sequence
from datasets.bags.read_report import ReadReport, ReadSettings, check_skips
from datasets.bags.reader import read_stream
from datasets.bags.sensor_start import sensor_bag_start
from datasets.bags.sequence_sources import SensorSource
from datasets.bags.spans import topic_spans
from datasets.bags.time_base import common_time_base
from datasets.bags.topic_roles import OdometryRole, choose_odometry
from datasets.bags.topics import BagTopics, SensorTopics, topic_types
from datasets.bags.wheel_odometry import WheelIncrements, WheelNoise
from datasets.errors import InputError
from datasets.measurements import Measurement, Sensor
from datasets.pass_report import PassReport
from datasets.sequence import NoiseSpec, Sequence


def sensor_sequence(
    argument: str, path: Path, settings, topics: BagTopics, reader
) -> tuple[Sequence, SensorSource]:
    """The sequence of a bag without a lidar (module docstring); ``settings``:
    ``datasets.bags.bag_options.BagOptions``; ``reader``: the bag, open (``open_bag``),
    read for everything the sequence needs at load (each pass opens it once again)."""
    decisions: list[str] = []
    warnings: list[str] = []
    types = topic_types(reader)
    imu_topic = topics.imu if settings.imu else None
    role = (
        choose_odometry(reader, path, types, settings.odometry_topic, topics.ground_truth)
        if settings.wheel_odometry
        else OdometryRole(None, None, "odometry: not used (wheel_odometry=false)")
    )
    if role.text:
        decisions.append(role.text)
    laser_topic = None if settings.laser_topic == "none" else topics.laser
    planar = laser_topic is not None and role.topic is not None
    if laser_topic is not None and role.topic is None:
        decisions.append(
            f"2-D laser {laser_topic} not used: the 2-D laser front end needs the motion "
            "between scans and the bag has no wheel odometry (--data odometry_topic=TOPIC)"
        )
    if planar:
        from datasets.bags.laserscan import describe_laserscan

        first_scan = next(
            (m for _, _, _, m in iter_messages(reader, path, [laser_topic], report=ReadReport())),
            None,
        )
        if first_scan is not None:
            decisions.append(describe_laserscan(laser_topic, first_scan))
        unused = [t for t in (imu_topic, topics.gps if settings.gps else None) if t]
        decisions.append(
            f"2-D: {laser_topic} with {role.topic} make a planar sequence (odometry at "
            "each scan, corners by split-and-merge, datasets.laser2d)"
            + (f"; not used in 2-D: {', '.join(unused)}" if unused else "")
            + " (--data laser_topic=none for the 3-D sequence of the other sensors)"
        )
        imu_topic = None
    gps_topic = topics.gps if settings.gps and not planar else None
    origin = first_gps_origin(reader, path, gps_topic) if gps_topic else None
    if gps_topic and origin is None:
        warnings.append(f"{gps_topic} has no valid fix; GPS not used")
        gps_topic = None
    if imu_topic is None and role.topic is None:
        listed = "; ".join(f"{t} [{m}]" for t, m in sorted(types.items())) or "no topics"
        raise InputError(
            f"{path}: no sensor an estimator can use: no {'PointCloud2'} topic, no Imu "
            f"topic{' (imu=false)' if topics.imu and not settings.imu else ''} and no "
            f"wheel odometry ({role.text or 'no nav_msgs/Odometry topic'}); topics: {listed}"
        )
    duration = max((reader.end_time - reader.start_time) * 1e-9, 1e-9)
    rates: dict[str, float] = {}
    imu_rate, gyro_density, accel_density = imu_rate_and_noise(reader, imu_topic, path)
    if imu_rate:
        rates["imu"] = float(imu_rate)
    if role.evidence is not None and role.evidence.rate_hz:
        rates["odometry"] = float(role.evidence.rate_hz)
    if gps_topic:
        rates["gps"] = float(reader.topics[gps_topic].msgcount / duration)
    if planar:
        rates["laser"] = float(reader.topics[laser_topic].msgcount / duration)
    defining = [t for t in (imu_topic, role.topic, laser_topic if planar else None) if t]
    spans = topic_spans(reader, path, defining)
    load_report = ReadReport()
    gt = (np.zeros(0), np.zeros((0, 3)), np.zeros((0, 4)))
    if topics.ground_truth:
        gt = read_ground_truth(path, topics.ground_truth, load_report, reader)
        check_skips(path, [topics.ground_truth], settings.max_skipped_fraction, load_report)
        if len(gt[0]) < 2:
            raise InputError(
                f"{path}: ground-truth topic {topics.ground_truth} has {len(gt[0])} usable poses"
            )
        spans[topics.ground_truth] = (float(gt[0][0]), float(gt[0][-1]))
    time_base = common_time_base(path, spans)
    if time_base is None:
        raise InputError(f"{path}: the sensor topics {', '.join(defining)} have no messages")
    ground_truth = ground_truth_from_topic(*gt, None, topics.ground_truth, warnings)
    if topics.unnamed_truth:
        warnings.append(
            f"no ground truth: pose topic(s) {', '.join(topics.unnamed_truth)} not taken "
            "as truth unless named (--data ground_truth_topic=TOPIC, workbench bag --truth-topic)"
        )
    noise_model: WheelNoise | None = None
    if role.topic is not None:
        noise_model, noise_text = role.noise(settings.odometry_noise)
        decisions.append(f"odometry noise: {noise_text}")
    initial, start_text = sensor_bag_start(
        reader,
        path,
        settings,
        time_base,
        imu_topic,
        gps_topic,
        origin,
        role,
        ground_truth,
        warnings,
    )
    decisions.append(start_text)
    read_settings = ReadSettings(
        gps_origin=origin,
        gps_sigma_m=settings.gps_sigma_m,
        reorder_window_s=settings.reorder_window_s,
        max_missing_fraction=settings.max_missing_fraction,
        max_skipped_fraction=settings.max_skipped_fraction,
        time_base=time_base,
        laser_mounting=np.asarray(settings.laser_to_body or (0.0, 0.0, 0.0), dtype=float),
    )
    metadata = {
        "source": str(path),
        "time_base": time_base.as_dict(),
        "gps_origin": list(origin) if origin else None,
        "options": settings.model_dump(mode="json"),
    }
    # the typed fields of the sequence besides its warnings and decisions (still growing)
    described = {
        "reference_source": f"topic {topics.ground_truth}" if topics.ground_truth else None,
        "topics": SensorTopics(
            imu=imu_topic,
            ground_truth=topics.ground_truth,
            gps=gps_topic,
            odometry=role.topic,
            laser=laser_topic if planar else None,
        ),
    }
    name = f"bag:{argument}"
    if planar:
        return planar_sequence(
            name, path, settings, read_settings, laser_topic, role, noise_model, time_base,
            ground_truth, initial, rates, metadata, described, decisions, warnings, reader,
        )  # fmt: skip
    source = SensorSource()
    topic_list = [t for t in (imu_topic, gps_topic, role.topic) if t]
    # filled once the stream has run: the increments made and composed, the pass's warnings
    pass_report = PassReport.expecting("odometry_counts")

    def stream() -> Iterator[Measurement]:
        report = ReadReport()
        source.report = report
        increments = (
            WheelIncrements(
                noise_model,
                from_twist=role.from_twist,
                max_rate_hz=settings.odometry_max_rate_hz,
                start_s=time_base.start_s,
            )
            if noise_model is not None
            else None
        )
        read = (m for _, m in read_stream(path, topic_list, read_settings, report))
        if increments is None:
            yield from read
        else:
            yield from increments.convert(read)
        counts = (
            {}
            if increments is None
            else {
                "odometry_increments": increments.emitted,
                "odometry_messages_composed": increments.composed,
            }
        )
        pass_report.record(source.pass_warnings(), odometry_counts=counts)

    sensors = {Sensor.IMU} if imu_topic else set()
    sensors |= {Sensor.GPS} if gps_topic else set()
    sensors |= {Sensor.ODOMETRY} if role.topic else set()
    if role.topic and settings.odometry_max_rate_hz and role.evidence.rate_hz:
        if role.evidence.rate_hz > settings.odometry_max_rate_hz * 1.01:
            decisions.append(
                f"odometry: {role.topic}'s increments composed from {role.evidence.rate_hz:.3g} Hz "
                f"to at most odometry_max_rate_hz={settings.odometry_max_rate_hz:g} Hz (the "
                "smoothers open a keyframe at each)"
            )
    noise = NoiseSpec(
        gyro_noise_density=(settings.gyro_noise_density or gyro_density or 1.7e-4)
        if imu_topic
        else None,
        accel_noise_density=(settings.accel_noise_density or accel_density or 2e-3)
        if imu_topic
        else None,
        gyro_bias_walk=settings.gyro_bias_walk if imu_topic else None,
        accel_bias_walk=settings.accel_bias_walk if imu_topic else None,
        gyro_bias_sigma_rad_s=settings.gyro_bias_sigma_rad_s if imu_topic else None,
        accel_bias_sigma_m_s2=settings.accel_bias_sigma_m_s2 if imu_topic else None,
        gps_sigma_m=settings.gps_sigma_m if gps_topic else None,
        odometry=noise_model.model if noise_model is not None else None,
        rate_hz=rates,
    )
    sequence = Sequence(
        name=name,
        dimension=3,
        sensors=frozenset(sensors),
        stream=stream,
        ground_truth=ground_truth,
        noise=noise,
        initial_state=initial,
        metadata=metadata,
        warnings=tuple(warnings),
        decisions=tuple(decisions),
        pass_report=pass_report,
        **described,
    )
    return sequence, source
